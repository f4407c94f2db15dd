// Robot control in processes of its own, as a user runs it (docs/distributed.md): `twin agent` per robot, on its
// controller (the VAL II and Movemaster EX emulators on pseudo-terminals, 4 times faster than real time), and `twin
// run --agents remote` for task control, all separate processes linked over DDS on a domain of this test's own. The
// exchange ends as it does in one process (A handed over and placed on the output, every command done, the report
// true); a missing agent is refused naming it; bad arguments are refused before anything connects.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
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

// The exchange with A already at the input conveyor's stop bar (task control without the twin has no part sensor, as
// tests/tools/real_only_check.sh), written into `dir`; its path.
fs::path exchange_at_the_stop(const fs::path& dir) {
  std::string cell = slurp(source_path("scenes/cell.yaml"));
  const std::string on_belt = "colour: [0.85, 0.1, 0.1], on: input}";
  const std::size_t a = cell.find(on_belt);
  EXPECT_NE(a, std::string::npos);
  cell.replace(a, on_belt.size(), "colour: [0.85, 0.1, 0.1], pose: {xyz: [0.03, -0.55, 0.53], yaw: 0}}");
  for (std::size_t at = cell.find("../models/"); at != std::string::npos; at = cell.find("../models/", at + 1)) {
    cell.replace(at, 2, CW_SOURCE_DIR);
  }
  std::ofstream(dir / "cell.yaml") << cell;
  fs::copy_file(source_path("scenes/exchange.yaml"), dir / "exchange.yaml");
  fs::copy_file(source_path("scenes/exchange.task"), dir / "exchange.task");
  return dir / "exchange.yaml";
}

// An emulated controller of the exchange's arms on a pseudo-terminal at `link`, homed where the cell says.
std::unique_ptr<BackgroundTwin> emulator(const std::string& language, const fs::path& link) {
  const std::string home = language == "val2" ? "0,84,-192,0,-72,90" : "-90,30,60,0,60,0";
  auto p = std::make_unique<BackgroundTwin>(std::vector<std::string>{
      "emulate", language, "--link", link.string(), "--time-scale", "0.25", "--home", home});
  EXPECT_TRUE(p->wait_for("Ctrl-C to stop", 20s)) << p->output();
  return p;
}

std::unique_ptr<BackgroundTwin> agent(const fs::path& scenario, const std::string& robot, const std::string& driver,
                                      int domain) {
  auto p = std::make_unique<BackgroundTwin>(std::vector<std::string>{
      "agent", scenario.string(), "--robot", robot, "--driver", driver, "--domain", std::to_string(domain), "--speed",
      "4", "--wait", "60"});
  EXPECT_TRUE(p->wait_for("waiting for task control", 30s)) << p->output();
  return p;
}

std::map<std::string, int> count_by_type_and_robot(const std::string& jsonl) {
  std::map<std::string, int> n;
  std::istringstream lines(jsonl);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    const nlohmann::json e = nlohmann::json::parse(line);
    ++n[e["type"].get<std::string>() + (e.contains("robot") ? " " + e["robot"].get<std::string>() : "")];
  }
  return n;
}

TEST(AgentsCli, TheExchangeWithTwoAgentsInProcessesOfTheirOwnEndsAsInOneProcess) {
  TwinCli cli("agents-exchange");
  const fs::path scenario = exchange_at_the_stop(cli.dir());
  const int domain = test_domain();
  auto puma_controller = emulator("val2", cli.dir() / "puma");
  auto melfa_controller = emulator("movemaster", cli.dir() / "melfa");
  auto puma = agent(scenario, "puma", "val2:" + (cli.dir() / "puma").string(), domain);
  auto melfa = agent(scenario, "melfa", "movemaster:" + (cli.dir() / "melfa").string(), domain);

  const auto r = cli.run("run " + shell_quote(scenario.string()) + " --agents remote --domain " +
                         std::to_string(domain) + " --speed 4 --quiet -o " + shell_quote((cli.dir() / "out").string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err << puma->output() << melfa->output();
  EXPECT_THAT(r.out, HasSubstr("puma on its agent, DDS domain " + std::to_string(domain)));

  // The report: finished, A placed on the output by the controller's model (which the agents' updates wrote).
  const nlohmann::json report = nlohmann::json::parse(slurp(cli.dir() / "out" / "report.json"));
  EXPECT_EQ(report["outcome"], "finished");
  EXPECT_EQ(report["parts_from"], "controller_model");
  bool placed = false;
  for (const nlohmann::json& a : report["account"]) {
    if (a["workpiece"] == "A") placed = a["status"] == "in_place" && a["where"] == "output";
  }
  EXPECT_TRUE(placed) << report["account"].dump();

  // Robot control's events, logged in the agents' processes, are in task control's log: every command of each robot's
  // program started and ended, as in one process (exchange.task: r1 7 commands, r2 9).
  const std::map<std::string, int> n = count_by_type_and_robot(slurp(cli.dir() / "out" / "events.jsonl"));
  EXPECT_EQ(n.at("command_start r1"), 7);
  EXPECT_EQ(n.at("command_end r1"), 7);
  EXPECT_EQ(n.at("command_start r2"), 9);
  EXPECT_EQ(n.at("command_end r2"), 9);
  EXPECT_EQ(n.count("fault_detected r1") + n.count("fault_detected r2"), 0u);

  // Task control has gone: each agent halts its robot and exits, having refused nothing and read the other's updates.
  for (BackgroundTwin* p : {puma.get(), melfa.get()}) {
    EXPECT_EQ(p->wait_exit(20s), 0) << p->output();
    EXPECT_THAT(p->output(), HasSubstr(" 0 samples refused"));
    EXPECT_THAT(p->output(), ::testing::Not(HasSubstr(" 0 updates of the other robots applied")));
  }
}

TEST(AgentsCli, TaskControlRefusesToStartNamingTheRobotsWhoseAgentIsMissing) {
  TwinCli cli("agents-missing");
  const fs::path scenario = exchange_at_the_stop(cli.dir());
  const auto r = cli.run("run " + shell_quote(scenario.string()) + " --agents remote --realtime --domain " +
                         std::to_string(test_domain()) + " --agent-wait 1 --quiet -o " +
                         shell_quote((cli.dir() / "out").string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("no agent for robots puma, melfa"));
  EXPECT_THAT(r.err, HasSubstr("twin agent --robot puma"));
  EXPECT_FALSE(fs::exists(cli.dir() / "out" / "report.json"));
}

TEST(AgentsCli, BadArgumentsAreRefusedSayingWhy) {
  TwinCli cli("agents-args");
  const fs::path scenario = exchange_at_the_stop(cli.dir());
  const std::string s = shell_quote(scenario.string());
  const std::string domain = std::to_string(test_domain());
  struct Case {
    std::string args, says;
  };
  for (const Case& c : std::vector<Case>{
           {"agent " + s + " --robot kuka --driver val2:/dev/null --domain " + domain, "'kuka' is not a robot"},
           {"agent " + s + " --robot r1 --domain " + domain, "the agent is named by its cell robot: --robot puma"},
           {"agent " + s + " --robot puma --driver val2:/dev/null --domain " + domain + " --perception cad",
            "it is for a robot on the twin"},
           {"agent " + s + " --robot puma --driver val2:/dev/null", "--domain is required"},
           {"agent " + s + " --robot puma --driver val2:" + (cli.dir() / "none").string() + " --domain 300",
            "DDS domain 300"},
           {"run " + s + " --agents remote", "give it with --domain N"},
           {"run " + s + " --domain " + domain, "add --agents remote"},
           {"run " + s + " --agents everywhere --domain " + domain, "--agents"},
           {"run " + s + " --agents remote --realtime --domain " + domain + " --ros-domain " + domain,
            "not published yet"},
       }) {
    const auto r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out << r.err;
    EXPECT_THAT(r.out + r.err, HasSubstr(c.says)) << c.args;
  }
}

}  // namespace
