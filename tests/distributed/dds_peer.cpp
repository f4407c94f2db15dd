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
//   dds_peer ros-listen DOMAIN
//       A ROS 2 subscriber of the cell (distributed/ros_publisher.hpp) as a tool would be: reads rt/joint_states,
//       rt/tf, rt/tf_static, rt/clock and rt/cellwright/events, prints "ready" once it matches a writer on each, and
//       once the events' writer has gone (the publisher is destroyed after its readers acknowledged everything) prints
//       what it read (see ros_listen below) and exits 0; 3 when nothing matches within 20 s or the writers stay 60 s.
//
// Every mode takes the liveliness lease from CW_DDS_LEASE_MS if set (the tests' 500 ms), else the default.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <iostream>
#include <mutex>
#include <random>
#include <string>

#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/ros_msgs.hpp"
#include "cellwright/distributed/ros_publisher.hpp"
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

// Output, one item a line: "joint_states SEC NANOSEC POSITION..." for each joint_states in order, "joint NAME" for
// each joint of the last one, "tf COUNT", "frame PARENT CHILD X Y Z QX QY QZ QW" for each transform of the last tf,
// "static ..." likewise for tf_static, "clock COUNT SEC NANOSEC", "event LINE" for each event in order. Numbers with 17
// significant digits (a float64 printed so reads back exactly).
int ros_listen(d::Participant& participant) {
  std::mutex mutex;
  std::uint64_t n_tf = 0, n_clock = 0;
  std::vector<d::JointState> joint_states;
  std::vector<d::TransformStamped> last_tf, statics;
  d::RosTime last_clock;
  std::vector<std::string> events;
  std::string refused;
  auto guarded = [&](auto body) {
    return [&, body](const std::vector<char>& bytes) {
      std::lock_guard lock(mutex);
      try {
        body(bytes);
      } catch (const d::WireError& e) {
        refused = e.what();
      }
    };
  };
  d::RosSubscription joints(participant, d::kJointStatesTopic, d::kJointStateTypeName,
                            guarded([&](const std::vector<char>& b) {
                              joint_states.push_back(d::decode_joint_state(b));
                            }));
  d::RosSubscription tf(participant, d::kTfTopic, d::kTfMessageTypeName, guarded([&](const std::vector<char>& b) {
                          last_tf = d::decode_tf(b);
                          ++n_tf;
                        }));
  d::RosSubscription tf_static(participant, d::kTfStaticTopic, d::kTfMessageTypeName,
                               guarded([&](const std::vector<char>& b) { statics = d::decode_tf(b); }));
  d::RosSubscription clock(participant, d::kClockTopic, d::kClockTypeName, guarded([&](const std::vector<char>& b) {
                             last_clock = d::decode_clock(b);
                             ++n_clock;
                           }));
  d::RosSubscription log(participant, d::kEventsTopic, d::kStringTypeName,
                         guarded([&](const std::vector<char>& b) { events.push_back(d::decode_string(b)); }));
  // Discovery is asynchronous and its state a value here: polled, with a deadline.
  auto until = [](auto done, std::chrono::seconds most) {
    auto deadline = std::chrono::steady_clock::now() + most;
    while (!done()) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  };
  const std::vector<d::RosSubscription*> all{&joints, &tf, &tf_static, &clock, &log};
  if (!until([&] { return std::all_of(all.begin(), all.end(), [](auto* s) { return s->writers() > 0; }); }, 20s)) {
    std::cerr << "dds_peer: no ROS publisher\n";
    return 3;
  }
  std::cout << "ready" << std::endl;
  if (!until([&] { return log.writers() == 0; }, 60s)) return 3;
  std::lock_guard lock(mutex);
  if (!refused.empty()) {
    std::cerr << "dds_peer: refused " << refused << "\n";
    return 4;
  }
  auto frame = [](const char* kind, const d::TransformStamped& t) {
    std::printf("%s %s %s %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", kind, t.header.frame_id.c_str(),
                t.child_frame_id.c_str(), t.translation.x(), t.translation.y(), t.translation.z(), t.rotation.x(),
                t.rotation.y(), t.rotation.z(), t.rotation.w());
  };
  for (const d::JointState& js : joint_states) {
    std::printf("joint_states %d %u", js.header.stamp.sec, js.header.stamp.nanosec);
    for (double p : js.position) std::printf(" %.17g", p);
    std::printf("\n");
  }
  if (!joint_states.empty()) {
    for (const std::string& name : joint_states.back().name) std::printf("joint %s\n", name.c_str());
  }
  std::printf("tf %llu\n", static_cast<unsigned long long>(n_tf));
  for (const auto& t : last_tf) frame("frame", t);
  for (const auto& t : statics) frame("static", t);
  std::printf("clock %llu %d %u\n", static_cast<unsigned long long>(n_clock), last_clock.sec, last_clock.nanosec);
  for (const std::string& e : events) std::printf("event %s\n", e.c_str());
  std::fflush(stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "ros-listen") {
    d::Participant participant({.domain = std::atoi(argv[2])}, "dds_peer");
    return ros_listen(participant);
  }
  if (argc < 6) {
    std::cerr << "usage: dds_peer echo|echo-late|crash|garbage|out-of-order DOMAIN ROBOT INDEX PROGRAM [COUNT] | "
                 "ros-listen DOMAIN\n";
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
