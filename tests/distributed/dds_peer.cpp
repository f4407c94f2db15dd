// A peer process for the distributed tests (tests/distributed/link_test.cpp), so that the two ends of a link are in
// different processes, as a cell's task control and its agents are.
//
//   dds_peer echo DOMAIN ROBOT INDEX PROGRAM COUNT
//       An agent's end for ROBOT (program index INDEX of the task program PROGRAM) whose robot answers every command
//       at once: a done status naming the primitive it decoded ("echo move above(A)"), at the command's time plus
//       10 ms. Exits 0 after COUNT answers have been acknowledged; 3 when task control is not found within 20 s or a
//       command does not come within 20 s.
//   dds_peer echo-late DOMAIN ROBOT INDEX PROGRAM COUNT
//       The same, with the agent slow to start: half a second between making its endpoint (which matches task control
//       meanwhile) and starting it.
//   dds_peer crash DOMAIN ROBOT INDEX PROGRAM COUNT
//       The echo agent, killed (SIGKILL, by itself: no clean-up, as a crash or `kill -9`) as it takes command
//       COUNT + 1, after answering COUNT: a robot whose agent is lost in the middle of a command.
//   dds_peer garbage DOMAIN ROBOT INDEX PROGRAM
//       Writes on ROBOT's command topic: 64 random bytes, a command cut short, a command for another robot, a command
//       whose primitive is not the program's, then one valid command (primitive 0, number 1); exits 0 once they are
//       acknowledged.
//   dds_peer out-of-order DOMAIN ROBOT INDEX PROGRAM
//       Writes on ROBOT's command topic valid commands numbered 1 (primitive 0), 1 again (a duplicate), 3 (primitive
//       2: number 2 is missing); exits 0 once they are acknowledged.
//
// Every mode takes the liveliness lease from CW_DDS_LEASE_MS if set (the tests' 500 ms), else the default.
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <thread>
#include <iostream>
#include <random>
#include <string>

#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/wire.hpp"
#include "cellwright/task/compile.hpp"

namespace d = cellwright::distributed;
namespace rt = cellwright::runtime;
using namespace std::chrono_literals;

namespace {

int echo(d::Participant& participant, const std::string& robot, std::size_t index,
         const cellwright::task::CompiledProgram& program, int count, std::chrono::milliseconds start_after,
         bool crash = false) {
  rt::MessageQueue<rt::MotionCommand> commands(4);
  rt::MessageQueue<rt::RobotStatus> statuses(16);
  d::AgentEndpoint agent(participant, robot, index, program, commands, statuses);
  std::this_thread::sleep_for(start_after);  // a test of the ready handshake, not of a race: nothing waits on it
  agent.start();
  if (!agent.wait_for_task_control(20s)) {
    std::cerr << "dds_peer: no task control for " << robot << "\n";
    return 3;
  }
  for (int i = 0; i < count + (crash ? 1 : 0); ++i) {
    rt::MotionCommand command;
    if (commands.pop_for(command, 20s) != rt::QueueStatus::ok) {
      std::cerr << "dds_peer: no command " << i << "\n";
      return 3;
    }
    if (i == count) raise(SIGKILL);
    rt::RobotStatus status;
    status.robot = command.robot;
    status.index = command.index;
    status.outcome = rt::CommandOutcome::kDone;
    status.reason = "echo " + cellwright::task::to_string(command.primitive);
    status.time = command.sent + std::chrono::milliseconds(10);
    statuses.push(status);
  }
  return agent.flush(20s) ? 0 : 3;
}

int garbage(d::Participant& participant, const std::string& robot, std::size_t index,
            const cellwright::task::CompiledProgram& program) {
  d::RawWriter writer(participant, d::command_topic(robot), d::kCommandTypeName);
  if (!writer.wait_for_reader(20s)) return 3;
  std::mt19937 random(28);
  std::vector<char> noise(64);
  for (char& c : noise) c = static_cast<char>(random() & 0xff);
  noise[0] = 0;
  noise[1] = 1;  // a CDR little-endian header, so that Fast DDS passes it on
  rt::MotionCommand command;
  command.robot = index;
  command.index = 0;
  command.primitive = program.programs[index].primitives[0];
  std::vector<char> valid = d::encode_command(command, 1);
  std::vector<char> cut(valid.begin(), valid.begin() + 14);
  rt::MotionCommand other = command;
  other.robot = index + 1;
  rt::MotionCommand foreign = command;
  foreign.primitive.kind = cellwright::task::PrimitiveKind::kOpen;
  foreign.primitive.workpiece = "nothing_here";
  for (const auto& bytes : {noise, cut, d::encode_command(other, 1), d::encode_command(foreign, 1), valid}) {
    if (!writer.write(bytes)) return 4;
  }
  return writer.flush(20s) ? 0 : 3;
}

int out_of_order(d::Participant& participant, const std::string& robot, std::size_t index,
                 const cellwright::task::CompiledProgram& program) {
  d::RawWriter writer(participant, d::command_topic(robot), d::kCommandTypeName);
  if (!writer.wait_for_reader(20s)) return 3;
  const auto command = [&](std::size_t primitive) {
    rt::MotionCommand c;
    c.robot = index;
    c.index = primitive;
    c.primitive = program.programs[index].primitives[primitive];
    return c;
  };
  for (const auto& bytes : {d::encode_command(command(0), 1), d::encode_command(command(0), 1),
                            d::encode_command(command(2), 3)}) {
    if (!writer.write(bytes)) return 4;
  }
  return writer.flush(20s) ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 6) {
    std::cerr << "usage: dds_peer echo|echo-late|garbage DOMAIN ROBOT INDEX PROGRAM [COUNT]\n";
    return 2;
  }
  std::string mode = argv[1];
  d::DdsOptions options{.domain = std::atoi(argv[2])};
  if (const char* lease = std::getenv("CW_DDS_LEASE_MS")) options.lease = std::chrono::milliseconds(std::atoi(lease));
  d::Participant participant(options, "dds_peer");
  std::string robot = argv[3];
  auto index = static_cast<std::size_t>(std::atoi(argv[4]));
  auto program = cellwright::task::compile_file(argv[5]);
  if ((mode == "echo" || mode == "echo-late") && argc == 7) {
    return echo(participant, robot, index, program, std::atoi(argv[6]), mode == "echo" ? 0ms : 500ms);
  }
  if (mode == "crash" && argc == 7) return echo(participant, robot, index, program, std::atoi(argv[6]), 0ms, true);
  if (mode == "garbage") return garbage(participant, robot, index, program);
  if (mode == "out-of-order") return out_of_order(participant, robot, index, program);
  std::cerr << "dds_peer: bad arguments\n";
  return 2;
}
