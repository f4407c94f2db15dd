// Lock-step across processes, as a user runs it (docs/distributed.md, "Lock-step with agents"): a `twin agent` per
// robot on the twin (no --driver), and `twin run --agents remote` with the twin, each robot's turns taken by its agent
// over DDS on a domain of this test's own. The event log is byte-identical to the run with every robot control in one
// process; a killed agent is a link_lost fault that stops the cell within about its lease, nothing hanging; an agent built for another run is refused.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "tools/twin_cli.hpp"

namespace {

namespace fs = std::filesystem;
using cellwright::testing::BackgroundTwin;
using cellwright::testing::shell_quote;
using cellwright::testing::slurp;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;
using namespace std::chrono_literals;

int test_domain() {
  return 20 + static_cast<int>(::getpid() % 200);
}

std::unique_ptr<BackgroundTwin> twin_agent(const std::string& scenario, const std::string& robot, int domain,
                                           std::vector<std::string> more = {}) {
  std::vector<std::string> args{"agent", scenario, "--robot", robot, "--domain", std::to_string(domain), "--wait",
                                "60"};
  args.insert(args.end(), more.begin(), more.end());
  auto p = std::make_unique<BackgroundTwin>(args);
  EXPECT_TRUE(p->wait_for("waiting for task control", 30s)) << p->output();
  return p;
}

// Runs `scenario` in one process and with an agent for each of `robots` (`agents`: twin run's --agents); both event
// logs.
void expect_same_log_with_agents(const std::string& tag, const std::string& scenario,
                                 const std::vector<std::string>& robots, const std::string& agents_option = "remote") {
  TwinCli cli(tag);
  const std::string path = source_path(scenario);
  const auto local = cli.run("run " + shell_quote(path) + " --quiet -o " + shell_quote((cli.dir() / "one").string()));
  ASSERT_EQ(local.status, 0) << local.out << local.err;

  const int domain = test_domain();
  std::vector<std::unique_ptr<BackgroundTwin>> agents;
  for (const std::string& r : robots) agents.push_back(twin_agent(path, r, domain));
  const auto remote = cli.run("run " + shell_quote(path) + " --agents " + agents_option + " --domain " +
                              std::to_string(domain) + " -o " + shell_quote((cli.dir() / "agents").string()));
  std::string agents_out;
  for (auto& a : agents) {
    EXPECT_EQ(a->wait_exit(30s), 0) << a->output();
    agents_out += a->output();
  }
  ASSERT_EQ(remote.status, 0) << remote.out << remote.err << agents_out;
  for (const std::string& r : robots) {
    EXPECT_THAT(remote.out, HasSubstr(r + " on its agent, DDS domain " + std::to_string(domain) + " (lock-step turns)"));
  }
  EXPECT_THAT(agents_out, HasSubstr("0 samples refused"));
  const std::string one = slurp(cli.dir() / "one" / "events.jsonl");
  const std::string two = slurp(cli.dir() / "agents" / "events.jsonl");
  ASSERT_GT(one.size(), 1000u);
  EXPECT_TRUE(one == two) << "the event logs differ: " << cli.dir();
  // The report is the same run's too.
  EXPECT_EQ(slurp(cli.dir() / "one" / "report.json"), slurp(cli.dir() / "agents" / "report.json"));
}

TEST(AgentsLockstep, TheExchangeWithTwoAgentsLogsByteForByteWhatOneProcessLogs) {
  expect_same_log_with_agents("lockstep-exchange", "scenes/exchange.yaml", {"puma", "melfa"});
}

TEST(AgentsLockstep, ThePipelineWithTwoAgentsLogsByteForByteWhatOneProcessLogs) {
  expect_same_log_with_agents("lockstep-pipeline", "scenes/pipeline.yaml", {"puma", "melfa"});
}

// Some robots on agents and the others here (--agents remote:ROBOT): the same bytes again.
TEST(AgentsLockstep, TheExchangeWithTheMelfaOnAnAgentAndThePumaHereLogsByteForByteWhatOneProcessLogs) {
  expect_same_log_with_agents("lockstep-partial", "scenes/exchange.yaml", {"melfa"}, "remote:melfa");
}

TEST(AgentsLockstep, RobotsOnAgentsAreNamedAmongTheProgramsAndSomeHereIsForLockStepOnly) {
  TwinCli cli("lockstep-partial-args");
  const std::string path = shell_quote(source_path("scenes/exchange.yaml"));
  struct Case {
    std::string args, says;
  };
  for (const Case& c : std::vector<Case>{
           {"--agents remote:kuka --domain 3", "'kuka' is no robot of the program (its cell robots: puma, melfa)"},
           {"--agents remote:melfa,melfa --domain 3", "robot 'melfa' is named twice"},
           {"--agents remote:melfa --realtime --domain 3", "some robots on agents and some here is for lock-step"},
           {"--agents elsewhere --domain 3", "remote:ROBOT[,ROBOT...]"},
       }) {
    const auto r = cli.run("run " + path + " " + c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out << r.err;
    EXPECT_THAT(r.out + r.err, HasSubstr(c.says)) << c.args;
  }
}

TEST(AgentsLockstep, AKilledAgentEndsTheRunFailedNamingItAndNothingHangs) {
  TwinCli cli("lockstep-killed");
  const std::string path = source_path("scenes/pipeline.yaml");
  const int domain = test_domain();
  auto puma = twin_agent(path, "puma", domain);
  auto melfa = twin_agent(path, "melfa", domain);
  BackgroundTwin run({"run", path, "--agents", "remote", "--domain", std::to_string(domain), "-o",
                      (cli.dir() / "out").string()});
  ASSERT_TRUE(run.wait_for("melfa on its agent", 30s)) << run.output();
  // The run under way (its turns start right after the estimate is printed), the MELFA's agent dies.
  ASSERT_TRUE(run.wait_for("estimated cycle time", 30s)) << run.output();
  melfa->stop(SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  const int status = run.wait_exit(30s);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  EXPECT_EQ(status, 1) << "a failed run (-1: it hung or crashed): " << run.output();
  // Stopped safely, the lost agent a link_lost fault of its robot diagnosed by the tree, the report true.
  EXPECT_THAT(run.output(), HasSubstr("FAILED: stopped at"));
  EXPECT_THAT(run.output(), HasSubstr("link_lost by r2 (the agent of melfa was lost"));
  const std::string events = slurp(cli.dir() / "out" / "events.jsonl");
  EXPECT_THAT(events, HasSubstr("\"symptom\":\"link_lost\""));
  EXPECT_THAT(slurp(cli.dir() / "out" / "report.json"), HasSubstr("\"outcome\": \"stopped\""));
  // Found within the lease (1 s), then the cell stopped and the outputs written, the failed run's picture rendered
  // (about 3 s on an idle machine): bounded, never a hang.
  EXPECT_LT(took, 20.0) << run.output();
  std::printf("the run ended %.2f s after the MELFA's agent was killed\n", took);
  EXPECT_EQ(puma->wait_exit(30s), 0) << puma->output();  // the run told it its end
}

TEST(AgentsLockstep, AgentsWhoseRunIsKilledLeaveWithinTheLease) {
  TwinCli cli("lockstep-run-killed");
  const std::string path = source_path("scenes/pipeline.yaml");
  const int domain = test_domain();
  auto puma = twin_agent(path, "puma", domain);
  auto melfa = twin_agent(path, "melfa", domain);
  BackgroundTwin run({"run", path, "--agents", "remote", "--domain", std::to_string(domain)});
  ASSERT_TRUE(run.wait_for("firings", 30s)) << run.output();  // its turns under way
  run.stop(SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  EXPECT_EQ(puma->wait_exit(20s), 3) << puma->output();  // 3: task control lost
  EXPECT_EQ(melfa->wait_exit(20s), 3) << melfa->output();
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  EXPECT_THAT(puma->output(), HasSubstr("ended early: the run's process was lost"));
  std::printf("both agents left %.2f s after their run was killed\n", took);
  EXPECT_LT(took, 10.0);
}

TEST(AgentsLockstep, AnAgentBuiltForAnotherPerceptionIsRefusedNamingBoth) {
  TwinCli cli("lockstep-settings");
  const std::string path = source_path("scenes/exchange.yaml");
  const int domain = test_domain();
  auto puma = twin_agent(path, "puma", domain);
  auto melfa = twin_agent(path, "melfa", domain, {"--perception", "cad"});
  const auto r = cli.run("run " + shell_quote(path) + " --agents remote --domain " + std::to_string(domain) +
                         " --agent-wait 3 --quiet");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("no agent for melfa"));
  EXPECT_THAT(r.err, HasSubstr("perception cad"));
  EXPECT_THAT(r.err, HasSubstr("perception truth"));
}

TEST(AgentsLockstep, TaskControlRefusesToStartNamingTheRobotsWhoseAgentIsMissing) {
  TwinCli cli("lockstep-missing");
  const std::string path = source_path("scenes/exchange.yaml");
  const int domain = test_domain();
  auto melfa = twin_agent(path, "melfa", domain);
  const auto r = cli.run("run " + shell_quote(path) + " --agents remote --domain " + std::to_string(domain) +
                         " --agent-wait 2 --quiet -o " + shell_quote((cli.dir() / "out").string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("no agent for puma on DDS domain " + std::to_string(domain)));
  EXPECT_THAT(r.err, HasSubstr("twin agent SCENARIO --robot puma --domain " + std::to_string(domain)));
  EXPECT_FALSE(fs::exists(cli.dir() / "out" / "report.json"));
  EXPECT_EQ(melfa->wait_exit(10s), 0) << melfa->output();  // told the run's end: it does not wait for its --wait
}

TEST(AgentsLockstep, ACoordinatedBlockIsRefusedOnBothEndsNamingItsLine) {
  TwinCli cli("lockstep-beam");
  const std::string path = source_path("scenes/beam.yaml");
  const auto run = cli.run("run " + shell_quote(path) + " --agents remote --domain 3 --agent-wait 1 --quiet");
  EXPECT_EQ(run.status, 2) << run.out << run.err;
  EXPECT_THAT(run.err, HasSubstr("beam.task:"));
  EXPECT_THAT(run.err, HasSubstr("part of a coordinated block, whose robots meet in one process"));
  const auto agent = cli.run("agent " + shell_quote(path) + " --robot puma --domain 3 --wait 1");
  EXPECT_EQ(agent.status, 2) << agent.out << agent.err;
  EXPECT_THAT(agent.err, HasSubstr("part of a coordinated block"));
}

TEST(AgentsLockstep, AnAgentOnTheTwinRefusesSpeed) {
  TwinCli cli("lockstep-speed");
  const auto r = cli.run("agent " + shell_quote(source_path("scenes/exchange.yaml")) +
                         " --robot puma --domain 3 --speed 2 --wait 1");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("lock-step run sets the pace"));
}

}  // namespace
