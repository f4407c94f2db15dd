// The DDS transport of the runtime's queues (distributed/link.hpp), with the two ends in different processes: this
// test is task control's end (or the agent's), tests/distributed/dds_peer.cpp the other. Each test process takes a
// DDS domain of its own (from its process id), and the participants use UDP only, so no shared-memory file outlives
// a run.
#include "cellwright/distributed/link.hpp"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "cellwright/distributed/wire.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"

extern char** environ;

namespace cellwright::distributed {
namespace {

using namespace std::chrono_literals;

const std::string kProgram = std::string(CW_SOURCE_DIR) + "/scenes/exchange.task";

int test_domain() {
  return 20 + static_cast<int>(getpid() % 200);
}

// A child process running dds_peer with `args`; wait() gives its exit status.
class Peer {
 public:
  explicit Peer(std::vector<std::string> args) {
    args.insert(args.begin(), CW_DDS_PEER);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, CW_DDS_PEER, nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
  }
  ~Peer() {
    if (pid_ > 0 && !waited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  int wait() {
    int status = 0;
    waitpid(pid_, &status, 0);
    waited_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
  bool waited_ = false;
};

// An agent that starts at once, and one slow to start (its endpoint matched task control half a second before it
// started: it must not say it is ready before, or the first command is taken and dropped and its status never comes).
class RoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(RoundTrip, CommandsAndTheirStatusesMakeTheRoundTripToAnAgentInAnotherProcessInOrder) {
  int domain = test_domain();
  auto program = task::compile_file(kProgram);
  const std::size_t r2 = 1;
  const auto& primitives = program.programs[r2].primitives;
  const std::size_t count = primitives.size();
  Peer agent({GetParam(), std::to_string(domain), "melfa", "1", kProgram, std::to_string(count)});
  ASSERT_TRUE(agent.started());

  Participant participant({.domain = domain}, "task_control");
  runtime::MessageQueue<runtime::MotionCommand> commands(4);
  runtime::MessageQueue<runtime::RobotStatus> statuses(64);
  RemoteRobot melfa(participant, "melfa", r2, commands, statuses);
  ASSERT_NO_THROW(wait_for_agents({&melfa}, domain, 20s));
  melfa.start();
  for (std::size_t i = 0; i < count; ++i) {
    runtime::MotionCommand command;
    command.robot = r2;
    command.index = i;
    command.primitive = primitives[i];
    command.sent = std::chrono::milliseconds(100 * i);
    ASSERT_EQ(commands.push(command), runtime::QueueStatus::ok);
  }
  for (std::size_t i = 0; i < count; ++i) {
    runtime::RobotStatus status;
    ASSERT_EQ(statuses.pop_for(status, 20s), runtime::QueueStatus::ok) << "status " << i;
    EXPECT_EQ(status.robot, r2);
    EXPECT_EQ(status.index, i);
    EXPECT_EQ(status.outcome, runtime::CommandOutcome::kDone);
    EXPECT_EQ(status.reason, "echo " + task::to_string(primitives[i]));
    EXPECT_EQ(status.time, std::chrono::milliseconds(100 * i + 10));
  }
  EXPECT_EQ(agent.wait(), 0);
  EXPECT_EQ(melfa.refusals().count, 0u);
}

INSTANTIATE_TEST_SUITE_P(Link, RoundTrip, ::testing::Values("echo", "echo-late"),
                         [](const ::testing::TestParamInfo<const char*>& p) {
                           return std::string(p.param) == "echo" ? "AgentStartingAtOnce" : "AgentSlowToStart";
                         });

TEST(Link, TaskControlRefusesToStartNamingTheRobotWhoseAgentIsMissing) {
  int domain = test_domain();
  Participant participant({.domain = domain}, "task_control");
  runtime::MessageQueue<runtime::MotionCommand> puma_commands(4), melfa_commands(4);
  runtime::MessageQueue<runtime::RobotStatus> statuses(64);
  RemoteRobot puma(participant, "puma", 0, puma_commands, statuses);
  RemoteRobot melfa(participant, "melfa", 1, melfa_commands, statuses);
  try {
    wait_for_agents({&puma, &melfa}, domain, 300ms);
    FAIL() << "started with no agents";
  } catch (const InputError& e) {
    std::string what = e.what();
    EXPECT_NE(what.find("no agent for robots puma, melfa on DDS domain " + std::to_string(domain)), std::string::npos)
        << what;
    EXPECT_NE(what.find("twin agent --robot puma --domain"), std::string::npos) << what;
  }
}

TEST(Link, GarbageOnTheCommandTopicIsRefusedAndTheNextCommandStillArrives) {
  int domain = test_domain();
  auto program = task::compile_file(kProgram);
  Participant participant({.domain = domain}, "agent");
  runtime::MessageQueue<runtime::MotionCommand> commands(4);
  runtime::MessageQueue<runtime::RobotStatus> statuses(16);
  AgentEndpoint agent(participant, "puma", 0, program, commands, statuses);
  agent.start();
  Peer writer({"garbage", std::to_string(domain), "puma", "0", kProgram});
  ASSERT_TRUE(writer.started());
  runtime::MotionCommand command;
  ASSERT_EQ(commands.pop_for(command, 20s), runtime::QueueStatus::ok);
  EXPECT_EQ(command.index, 0u);
  EXPECT_EQ(task::to_string(command.primitive), task::to_string(program.programs[0].primitives[0]));
  EXPECT_EQ(commands.size(), 0u);  // nothing of the garbage reached the queue
  Refusals refused = agent.refusals();
  EXPECT_EQ(refused.count, 4u);  // noise, cut short, another robot's, another program's: all before the valid one
  EXPECT_NE(refused.last.find("another program"), std::string::npos) << refused.last;
  EXPECT_EQ(writer.wait(), 0);
}

TEST(Link, ARobotNameThatCannotNameATopicIsRefused) {
  EXPECT_EQ(command_topic("melfa"), "rt/cellwright/melfa/command");
  EXPECT_EQ(status_topic("r_2"), "rt/cellwright/r_2/status");
  EXPECT_THROW(command_topic("my-robot"), InputError);
  EXPECT_THROW(command_topic("2nd"), InputError);
  EXPECT_THROW(Participant({.domain = 233}, "x"), InputError);
}

}  // namespace
}  // namespace cellwright::distributed

namespace cellwright::distributed {
namespace {

// The number of commands task control sends robot `robot` in one run of `program` (moves, opens and closes; signals,
// waits and loops are the net's own).
std::size_t commands_of(const task::CompiledProgram& program, std::size_t robot) {
  std::size_t n = 0;
  for (const task::Primitive& p : program.programs[robot].primitives) {
    n += p.kind == task::PrimitiveKind::kMove || p.kind == task::PrimitiveKind::kOpen ||
         p.kind == task::PrimitiveKind::kClose;
  }
  return n;
}

// The runtime's side of a remote robot (RunConfig::remote_robots) is tested in-process, its refusals too, in
// tests/controller/runtime/runtime_test.cpp (RuntimeRemote); here with DDS links to agents in other processes.
TEST(RemoteCell, TaskControlRunsTheExchangeToItsEndWithBothRobotsAgentsInOtherProcesses) {
  int domain = test_domain();
  runtime::RunConfig config;
  config.program = task::compile_file(kProgram);
  config.net = task::to_net(config.program);
  config.cell = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml");
  config.binding.robots = {{"r1", {"puma", {}}}, {"r2", {"melfa", {}}}};
  config.binding.objects = {{"B", {"output_drop", {}}}};
  config.mode = runtime::Mode::kRealtime;
  config.realtime_speed = 20.0;
  config.perception = runtime::Perception::kCad;
  config.limits.sim_time = std::chrono::seconds(60);
  config.remote_robots = {"puma", "melfa"};
  Peer puma({"echo", std::to_string(domain), "puma", "0", kProgram, std::to_string(commands_of(config.program, 0))});
  Peer melfa({"echo", std::to_string(domain), "melfa", "1", kProgram, std::to_string(commands_of(config.program, 1))});

  Participant participant({.domain = domain}, "task_control");
  RemoteCell remote(participant);
  config.attach_remote = remote.attach();
  runtime::Runtime run(config);
  ASSERT_NO_THROW(remote.wait_for_agents(20s));
  runtime::RunResult result = run.run();
  EXPECT_EQ(result.outcome, runtime::Outcome::kFinished) << result.reason << "\n" << run.log().text();
  EXPECT_EQ(puma.wait(), 0);
  EXPECT_EQ(melfa.wait(), 0);
  // Every transition of the exchange fired: the net's final marking was reached on the agents' statuses alone.
  EXPECT_TRUE(config.net.is_final(result.final_marking));
  EXPECT_TRUE(result.finished_at.has_value());
}

}  // namespace
}  // namespace cellwright::distributed
