// The DDS transport of the runtime's queues (distributed/link.hpp), with the two ends in different processes: this
// test is task control's end (or the agent's), tests/distributed/dds_peer.cpp the other. Each test process takes a
// DDS domain of its own (from its process id), and the participants use UDP only, so no shared-memory file outlives
// a run.
#include "cellwright/distributed/link.hpp"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "../controller/runtime/scripted_cell.hpp"

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

// The tests' liveliness lease, the default (a shorter one finds a lost agent sooner, but risks a false loss on a
// loaded machine, a sanitized build or CI); the peers take it from the environment (both ends of a link must have the
// same lease).
constexpr std::chrono::milliseconds kLease{1000};

// Set before any peer starts (a peer of a test may start before the test's participant is made).
const bool kLeaseInEnvironment = [] {
  return setenv("CW_DDS_LEASE_MS", std::to_string(kLease.count()).c_str(), 1) == 0;
}();

DdsOptions dds(int domain) {
  EXPECT_TRUE(kLeaseInEnvironment);
  return DdsOptions{.domain = domain, .lease = kLease};
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

  Participant participant(dds(domain), "task_control");
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
  Participant participant(dds(domain), "task_control");
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
    EXPECT_NE(what.find("twin agent SCENARIO --robot puma --driver KIND:PORT --domain"), std::string::npos) << what;
  }
}

// The PUMA's agent end in this process, started, its command queue for the test to read.
struct PumaAgent {
  explicit PumaAgent(int domain) : participant(dds(domain), "agent") { agent.start(); }
  task::CompiledProgram program = task::compile_file(kProgram);
  Participant participant;
  runtime::MessageQueue<runtime::MotionCommand> commands{4};
  runtime::MessageQueue<runtime::RobotStatus> statuses{16};
  AgentEndpoint agent{participant, "puma", 0, program, commands, statuses};

  // The first command that gets through from a peer writing on the PUMA's command topic.
  runtime::MotionCommand first_from(const Peer& writer) {
    EXPECT_TRUE(writer.started());
    runtime::MotionCommand command;
    EXPECT_EQ(commands.pop_for(command, 20s), runtime::QueueStatus::ok);
    return command;
  }
};

TEST(Link, GarbageOnTheCommandTopicIsRefusedAndTheNextCommandStillArrives) {
  int domain = test_domain();
  PumaAgent puma(domain);
  auto& [program, participant, commands, statuses, agent] = puma;
  Peer writer({"garbage", std::to_string(domain), "puma", "0", kProgram});
  runtime::MotionCommand command = puma.first_from(writer);
  EXPECT_EQ(command.index, 0u);
  EXPECT_EQ(task::to_string(command.primitive), task::to_string(program.programs[0].primitives[0]));
  EXPECT_EQ(commands.size(), 0u);  // nothing of the garbage reached the queue
  Refusals refused = agent.refusals();
  EXPECT_EQ(refused.count, 4u);  // noise, cut short, another robot's, another program's: all before the valid one
  EXPECT_NE(refused.last.find("another program"), std::string::npos) << refused.last;
  EXPECT_EQ(writer.wait(), 0);
}

TEST(Link, ACommandDuplicatedOrAfterAGapIsRefusedNamingTheNumbers) {
  int domain = test_domain();
  PumaAgent puma(domain);
  auto& [program, participant, commands, statuses, agent] = puma;
  Peer writer({"out-of-order", std::to_string(domain), "puma", "0", kProgram});
  EXPECT_EQ(puma.first_from(writer).index, 0u);
  EXPECT_EQ(writer.wait(), 0);  // every sample acknowledged: each has reached this reader
  // The reader hands a sample on after acknowledging it: wait (with a deadline) until both refusals are counted.
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (agent.refusals().count < 2 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(5ms);
  }
  Refusals refused = agent.refusals();
  EXPECT_EQ(refused.count, 2u);  // the duplicate of 1 and 3 after 1
  EXPECT_EQ(refused.last, "command 3 after 1: command 2 is missing");
  EXPECT_EQ(commands.size(), 0u);  // neither reached the robot
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

  Participant participant(dds(domain), "task_control");
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


// The events of a run as JSON, in order.
std::vector<nlohmann::json> events_of(const runtime::EventLog& log) {
  std::vector<nlohmann::json> out;
  for (const std::string& line : log.lines()) out.push_back(nlohmann::json::parse(line));
  return out;
}

std::vector<nlohmann::json> of_type(const std::vector<nlohmann::json>& events, const std::string& type) {
  std::vector<nlohmann::json> out;
  for (const auto& e : events) {
    if (e["type"] == type) out.push_back(e);
  }
  return out;
}

// A flag set by an event observer (on the thread that logs) and waited for with a deadline.
struct Seen {
  std::mutex mutex;
  std::condition_variable changed;
  bool seen = false;
  void set() {
    {
      std::lock_guard lock(mutex);
      seen = true;
    }
    changed.notify_all();
  }
  bool wait(std::chrono::seconds timeout) {
    std::unique_lock lock(mutex);
    return changed.wait_for(lock, timeout, [&] { return seen; });
  }
};

// The exchange with the PUMA in this process (a scripted driver, robot control here) and the MELFA an agent in another
// process that is killed (SIGKILL) as it takes its second command.
struct KilledAgentCell {
  explicit KilledAgentCell(int domain) : participant(dds(domain), "task_control"), remote(participant) {
    cell.config.drivers.erase("melfa");
    cell.config.remote_robots = {"melfa"};
    cell.config.realtime_speed = 5.0;
    cell.config.limits.sim_time = std::chrono::seconds(120);
    cell.config.attach_remote = remote.attach();
    cell.config.event_observers.push_back([this](const runtime::LogEvent& e) {
      const auto now = std::chrono::steady_clock::now();
      const auto* fire = std::get_if<runtime::events::Fire>(&e);
      if (fire && fire->robot == "r2" && found == std::chrono::steady_clock::time_point{}) {
        sent = now;  // observers are called one at a time, under the log's lock
      }
      if (const auto* f = std::get_if<runtime::events::FaultDetected>(&e); f && f->symptom == "link_lost") {
        found = now;
        lost.set();
      }
    });
  }
  // Wall seconds from the last firing of the MELFA's before its agent was found lost (the command it died on was sent
  // then) to the finding: the lease and how long the agent took to take the command and die.
  double detection() const { return std::chrono::duration<double>(found - sent).count(); }
  testing::ScriptedCell cell{"exchange.task", {}, runtime::Mode::kRealtime};
  Participant participant;
  RemoteCell remote;
  Seen lost;
  std::chrono::steady_clock::time_point sent, found;  // set on the logging threads before `lost`
};

TEST(RemoteCell, AKilledAgentIsALinkLostFaultOfItsRobotAndTheCellStopsSafely) {
  int domain = test_domain();
  KilledAgentCell k(domain);
  Peer melfa({"crash", std::to_string(domain), "melfa", "1", kProgram, "1"});
  runtime::Runtime run(k.cell.config);
  ASSERT_NO_THROW(k.remote.wait_for_agents(20s));
  const auto started = std::chrono::steady_clock::now();
  runtime::RunResult result = run.run();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  EXPECT_EQ(melfa.wait(), 128 + SIGKILL);
  const auto events = events_of(run.log());
  // Stopped, not timed out: the stall is reported as one, with its cause.
  ASSERT_EQ(result.outcome, runtime::Outcome::kStopped) << result.reason << "\n" << run.log().text();
  EXPECT_NE(result.reason.find("robot r2: link_dropped: the agent of melfa was lost with primitive"),
            std::string::npos)
      << result.reason;
  EXPECT_NE(result.reason.find("no sign of life from it for its liveliness lease of 1 s"), std::string::npos)
      << result.reason;
  const auto faults = of_type(events, "fault_detected");
  ASSERT_EQ(faults.size(), 1u) << run.log().text();
  EXPECT_EQ(faults[0]["robot"], "r2");
  EXPECT_EQ(faults[0]["symptom"], "link_lost");
  const auto diagnoses = of_type(events, "diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["action"], "reset_rehome");  // the standard tree: a retry is left ...
  const auto ends = of_type(events, "recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);  // ... but this run waits for no new agent (rejoin_wait 0)
  EXPECT_EQ(of_type(events, "cell_stopped").size(), 1u);
  // The PUMA, here, was halted as the run ended.
  EXPECT_GE(k.cell.driver("puma").calls().stop, 1);
  std::cout << "killed agent: found lost " << k.detection() << " s after its last command was sent, the run ended "
            << wall << " s after it began (wall), the lease being " << kLease.count() << " ms\n";
}

TEST(RemoteCell, AnAgentStartedAgainForTheSameRobotRejoinsAndTheRunFinishes) {
  int domain = test_domain();
  KilledAgentCell k(domain);
  k.cell.config.rejoin_wait = std::chrono::seconds(60);
  const std::size_t melfa_commands = commands_of(k.cell.config.program, 1);
  Peer first({"crash", std::to_string(domain), "melfa", "1", kProgram, "1"});
  runtime::Runtime run(k.cell.config);
  ASSERT_NO_THROW(k.remote.wait_for_agents(20s));
  std::future<runtime::RunResult> result = std::async(std::launch::async, [&run] { return run.run(); });
  ASSERT_TRUE(k.lost.wait(20s)) << "the killed agent was not found lost";
  // A new agent process for the MELFA: it is sent the interrupted command again, then the rest.
  Peer second({"echo", std::to_string(domain), "melfa", "1", kProgram, std::to_string(melfa_commands - 1)});
  ASSERT_EQ(result.wait_for(60s), std::future_status::ready);
  runtime::RunResult r = result.get();
  EXPECT_EQ(first.wait(), 128 + SIGKILL);
  EXPECT_EQ(second.wait(), 0);
  ASSERT_EQ(r.outcome, runtime::Outcome::kFinished) << r.reason << "\n" << run.log().text();
  const auto events = events_of(run.log());
  const auto ends = of_type(events, "recovery_end");
  ASSERT_EQ(ends.size(), 1u) << run.log().text();
  EXPECT_EQ(ends[0]["robot"], "r2");
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_NE(ends[0]["detail"].get<std::string>().find("a new agent of melfa"), std::string::npos) << ends[0];
}

}  // namespace
}  // namespace cellwright::distributed
