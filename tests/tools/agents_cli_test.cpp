// Robot control in processes of its own, as a user runs it (docs/distributed.md): `twin agent` per robot, on its
// controller (the VAL II and Movemaster EX emulators on pseudo-terminals, 4 times faster than real time), and `twin
// run --agents remote` for task control, all separate processes linked over DDS on a domain of this test's own. The
// exchange ends as it does in one process (A handed over and placed on the output, every command done, the report
// true); a missing agent is refused naming it; bad arguments are refused before anything connects. Failures: task
// control killed (the agents halt their robots within the lease), an agent killed and replaced (--rejoin-wait), and,
// where network namespaces can be made, task control and the agents in namespaces of their own, the link between
// them cut mid-run (docs/distributed.md, "Failure behaviour").
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
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

// `twin agent` for `robot` (`prefix`: the command it runs under, as `ip netns exec NAME`), once it waits.
std::unique_ptr<BackgroundTwin> agent(const fs::path& scenario, const std::string& robot, const std::string& driver,
                                      int domain, const std::vector<std::string>& prefix = {}) {
  auto p = std::make_unique<BackgroundTwin>(
      std::vector<std::string>{"agent", scenario.string(), "--robot", robot, "--driver", driver, "--domain",
                               std::to_string(domain), "--speed", "4", "--wait", "60"},
      false, prefix);
  EXPECT_TRUE(p->wait_for("waiting for task control", 30s)) << p->output();
  return p;
}

// `twin run --agents remote --no-twin` (task control alone: the failures below are task control's and the agents',
// the twin following them is the exchange's test) started in the background, its outputs in `out`, with `extra`
// options.
std::unique_ptr<BackgroundTwin> task_control(const fs::path& scenario, int domain, const fs::path& out,
                                             const std::vector<std::string>& extra = {},
                                             const std::vector<std::string>& prefix = {}) {
  std::vector<std::string> args{"run",   scenario.string(), "--agents", "remote", "--domain", std::to_string(domain),
                                "--speed", "4",            "--no-twin", "--quiet", "-o",      out.string()};
  args.insert(args.end(), extra.begin(), extra.end());
  return std::make_unique<BackgroundTwin>(args, false, prefix);
}

// The events of a log file, whole lines only (a line still being written is left out).
std::vector<nlohmann::json> events_in(const fs::path& file) {
  std::vector<nlohmann::json> events;
  std::istringstream lines(slurp(file));
  for (std::string line; std::getline(lines, line);) {
    if (lines.eof()) break;  // no newline yet
    if (!line.empty()) events.push_back(nlohmann::json::parse(line));
  }
  return events;
}

// The events task control has logged so far (the log it streams into `out` as it runs, renamed at its end).
std::vector<nlohmann::json> events_so_far(const fs::path& out) {
  const fs::path streamed = out / "events.jsonl.part";
  return events_in(fs::exists(streamed) ? streamed : out / "events.jsonl");
}

// Waits, reading task control's streamed log every 20 ms, until an event `match` takes is logged; false when
// `timeout` passes first.
bool wait_for_event(const fs::path& out, const std::function<bool(const nlohmann::json&)>& match,
                    std::chrono::milliseconds timeout) {
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < until) {
    for (const nlohmann::json& e : events_so_far(out)) {
      if (match(e)) return true;
    }
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

bool is(const nlohmann::json& e, const std::string& type, const std::string& robot) {
  return e["type"] == type && e.contains("robot") && e["robot"] == robot;
}

// Seconds from `since` until each process says `text` (read as they say it), -1 for one that did not within
// `timeout`.
std::vector<double> seconds_until(const std::vector<BackgroundTwin*>& processes, const std::string& text,
                                  std::chrono::steady_clock::time_point since, std::chrono::milliseconds timeout) {
  std::vector<double> seconds(processes.size(), -1.0);
  const auto until = std::chrono::steady_clock::now() + timeout;
  for (bool waiting = true; waiting && std::chrono::steady_clock::now() < until;) {
    waiting = false;
    for (std::size_t i = 0; i < processes.size(); ++i) {
      if (seconds[i] >= 0) continue;
      if (processes[i]->wait_for(text, 10ms)) {
        seconds[i] = std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
      } else {
        waiting = true;
      }
    }
  }
  return seconds;
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

// The exchange's run in `out` finished as in one process: the report true, A placed on the output (by the twin, whose
// copies of the robots followed the agents', or without the twin by the controller's model, which the agents' updates
// wrote), every command of each robot's program started and ended in task control's log (robot control's events,
// logged in the agents' processes; exchange.task: r1 7 commands, r2 9).
void expect_the_exchange_finished(const fs::path& out, bool twin = false) {
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "finished");
  if (twin) {
    EXPECT_FALSE(report.contains("parts_from")) << report.dump();  // the twin's
  } else {
    EXPECT_EQ(report["parts_from"], "controller_model");
  }
  bool placed = false;
  for (const nlohmann::json& a : report["account"]) {
    if (a["workpiece"] == "A") placed = a["status"] == "in_place" && a["where"] == "output";
  }
  EXPECT_TRUE(placed) << report["account"].dump();
  const std::map<std::string, int> n = count_by_type_and_robot(slurp(out / "events.jsonl"));
  EXPECT_EQ(n.at("command_end r1"), 7);
  EXPECT_EQ(n.at("command_end r2"), 9);
  EXPECT_EQ(n.at("command_start r1"), 7);
}

// The exchange's cell as separate processes in `cli`'s directory: both emulated controllers, an agent per robot (run
// under `agents_in`, e.g. `ip netns exec NAME`) and task control (under `task_control_in`, with `extra` options,
// outputs in out), started in that order, each once it is ready.
struct CellProcesses {
  CellProcesses(const TwinCli& cli, const std::vector<std::string>& extra = {},
                const std::vector<std::string>& agents_in = {}, const std::vector<std::string>& task_control_in = {})
      : scenario(exchange_at_the_stop(cli.dir())),
        out(cli.dir() / "out"),
        melfa_driver("movemaster:" + (cli.dir() / "melfa").string()),
        puma_controller(emulator("val2", cli.dir() / "puma")),
        melfa_controller(emulator("movemaster", cli.dir() / "melfa")),
        puma(agent(scenario, "puma", "val2:" + (cli.dir() / "puma").string(), domain, agents_in)),
        melfa(agent(scenario, "melfa", melfa_driver, domain, agents_in)),
        tc(task_control(scenario, domain, out, extra, task_control_in)) {}
  std::string outputs() const { return tc->output() + puma->output() + melfa->output(); }
  // Waits until the MELFA (r2) has started its first command: the run is under way, both robots busy.
  bool under_way() const {
    return wait_for_event(out, [](const nlohmann::json& e) { return is(e, "command_start", "r2"); }, 60s);
  }

  const int domain = test_domain();
  const fs::path scenario, out;
  const std::string melfa_driver;
  std::unique_ptr<BackgroundTwin> puma_controller, melfa_controller, puma, melfa, tc;
};

TEST(AgentsCli, TheExchangeWithTwoAgentsInProcessesOfTheirOwnEndsAsInOneProcess) {
  TwinCli cli("agents-exchange");
  const fs::path scenario = exchange_at_the_stop(cli.dir());
  const int domain = test_domain();
  auto puma_controller = emulator("val2", cli.dir() / "puma");
  auto melfa_controller = emulator("movemaster", cli.dir() / "melfa");
  auto puma = agent(scenario, "puma", "val2:" + (cli.dir() / "puma").string(), domain);
  auto melfa = agent(scenario, "melfa", "movemaster:" + (cli.dir() / "melfa").string(), domain);

  // With the twin here (the default): its copies of the arms follow the agents' robots, and the report's parts are
  // where the twin has them: A is there only if the copies picked it, handed it over and put it on the output.
  const auto r = cli.run("run " + shell_quote(scenario.string()) + " --agents remote --domain " +
                         std::to_string(domain) + " --speed 4 --quiet -o " + shell_quote((cli.dir() / "out").string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err << puma->output() << melfa->output();
  EXPECT_THAT(r.out, HasSubstr("puma on its agent, DDS domain " + std::to_string(domain)));
  EXPECT_THAT(r.out, HasSubstr("followed in the twin"));
  EXPECT_THAT(r.out, HasSubstr(" 0 missed"));
  EXPECT_TRUE(fs::exists(cli.dir() / "out" / "final.png"));
  expect_the_exchange_finished(cli.dir() / "out", true);
  const std::map<std::string, int> n = count_by_type_and_robot(slurp(cli.dir() / "out" / "events.jsonl"));
  EXPECT_EQ(n.at("command_start r2"), 9);
  EXPECT_EQ(n.count("fault_detected r1") + n.count("fault_detected r2"), 0u);

  // Task control has gone: each agent halts its robot and exits, having refused nothing and read the other's updates.
  for (BackgroundTwin* p : {puma.get(), melfa.get()}) {
    EXPECT_EQ(p->wait_exit(20s), 0) << p->output();
    EXPECT_THAT(p->output(), HasSubstr(" 0 samples refused"));
    EXPECT_THAT(p->output(), ::testing::Not(HasSubstr(" 0 updates of the other robots applied")));
  }
}

// Task control killed mid-run (SIGKILL: no goodbye on the wire): each agent finds it lost by the lease (1 s: its
// participant dropped by discovery; Fast DDS's default participant lease would take 20 s), halts its robot and exits 3.
TEST(AgentsCli, AnAgentWhoseTaskControlIsKilledHaltsItsRobotWithinTheLease) {
  TwinCli cli("agents-tc-killed");
  CellProcesses c(cli);
  BackgroundTwin *tc = c.tc.get(), *puma = c.puma.get(), *melfa = c.melfa.get();
  ASSERT_TRUE(c.under_way()) << c.outputs();

  const auto killed = std::chrono::steady_clock::now();
  tc->stop(SIGKILL);
  const std::vector<double> halted = seconds_until({puma, melfa}, "task control lost", killed, 30s);
  for (std::size_t i = 0; i < halted.size(); ++i) {
    BackgroundTwin& p = i == 0 ? *puma : *melfa;
    std::printf("[ figure ] agent %s halted its robot and said why %.3f s after task control was killed (lease 1 s)\n",
                i == 0 ? "puma" : "melfa", halted[i]);
    ASSERT_GE(halted[i], 0.0) << p.output();
    EXPECT_LT(halted[i], 2.5) << "the lease is 1 s";  // its matches would have taken 20 s
    EXPECT_EQ(p.wait_exit(10s), 3) << p.output();
    EXPECT_THAT(p.output(), HasSubstr("no sign of life from task control for the lease of 1 s"));
    EXPECT_THAT(p.output(), HasSubstr("the robot was halted"));
  }
}

// The MELFA's agent killed as it takes its first command, found lost by its lease, and a new one started on the same
// controller: with --rejoin-wait, task control waits for it, the new agent brings the arm up (homes it) and is sent
// the interrupted command, and the run finishes as in one process.
TEST(AgentsCli, AKilledAgentReplacedByANewOneRejoinsAndTheRunFinishes) {
  TwinCli cli("agents-rejoin");
  CellProcesses c(cli, {"--rejoin-wait", "30"});
  const fs::path& out = c.out;
  auto& tc = c.tc;
  auto& puma = c.puma;
  auto& melfa = c.melfa;
  ASSERT_TRUE(c.under_way()) << c.outputs();
  melfa->stop(SIGKILL);
  // Task control finds it lost by its lease (the PUMA's agent living on), then a new agent comes.
  ASSERT_TRUE(wait_for_event(
      out, [](const nlohmann::json& e) { return is(e, "fault_detected", "r2") && e["symptom"] == "link_lost"; }, 30s))
      << tc->output();
  melfa = agent(c.scenario, "melfa", c.melfa_driver, c.domain);

  ASSERT_EQ(tc->wait_exit(90s), 0) << c.outputs();
  expect_the_exchange_finished(out);
  // The log: the loss, its diagnosis (re-home), then the new agent taking over.
  const std::vector<nlohmann::json> log = events_in(out / "events.jsonl");
  std::size_t lost = log.size(), rejoined = log.size();
  for (std::size_t i = 0; i < log.size(); ++i) {
    if (is(log[i], "fault_detected", "r2") && log[i]["symptom"] == "link_lost" && lost == log.size()) lost = i;
    if (is(log[i], "recovery_end", "r2") && rejoined == log.size()) rejoined = i;
  }
  ASSERT_LT(lost, log.size()) << slurp(out / "events.jsonl");
  ASSERT_LT(rejoined, log.size()) << slurp(out / "events.jsonl");
  EXPECT_LT(lost, rejoined);
  EXPECT_THAT(log[lost]["detail"].get<std::string>(), HasSubstr("no sign of life from it for its liveliness lease"));
  std::printf("[ figure ] rejoin: %s; %s after %s s of the run's time\n", log[lost]["detail"].dump().c_str(),
              log[rejoined]["detail"].dump().c_str(), log[rejoined]["duration"].dump().c_str());
  EXPECT_EQ(log[rejoined]["ok"], true) << log[rejoined].dump();
  EXPECT_THAT(log[rejoined]["detail"].get<std::string>(), HasSubstr("a new agent of melfa"));
  EXPECT_EQ(puma->wait_exit(20s), 0) << puma->output();
  EXPECT_EQ(melfa->wait_exit(20s), 0) << melfa->output();
}

// Runs a shell command; its exit status, and its output in `said`.
int shell(const std::string& command, std::string* said = nullptr) {
  std::FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (p == nullptr) return -1;
  std::string text;
  char buf[512];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) text.append(buf, n);
  const int raw = ::pclose(p);
  if (said != nullptr) *said = text;
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

// Two network namespaces of this test process's own, one for task control and one for the agents, linked by a veth
// pair (10.77.0.1/24 and 10.77.0.2/24, each end with a route for multicast, which DDS's discovery uses), removed with
// it. Where namespaces cannot be made (not root, no CAP_SYS_ADMIN, no `ip`), why_not() says why.
class LinkedNamespaces {
 public:
  LinkedNamespaces() {
    const std::string id = std::to_string(::getpid());
    task_control_ = "cwtc" + id;
    agents_ = "cwag" + id;
    const std::string veth_tc = "cwvt" + id, veth_ag = "cwva" + id;
    cut_ = "ip -n " + task_control_ + " link set " + veth_tc + " down";
    for (const std::string& c : std::vector<std::string>{
             "ip netns add " + task_control_,
             "ip netns add " + agents_,
             "ip link add " + veth_tc + " netns " + task_control_ + " type veth peer name " + veth_ag + " netns " +
                 agents_,
             "ip -n " + task_control_ + " addr add 10.77.0.1/24 dev " + veth_tc,
             "ip -n " + agents_ + " addr add 10.77.0.2/24 dev " + veth_ag,
             "ip -n " + task_control_ + " link set lo up",
             "ip -n " + agents_ + " link set lo up",
             "ip -n " + task_control_ + " link set " + veth_tc + " up",
             "ip -n " + agents_ + " link set " + veth_ag + " up",
             "ip -n " + task_control_ + " route add 224.0.0.0/4 dev " + veth_tc,
             "ip -n " + agents_ + " route add 224.0.0.0/4 dev " + veth_ag,
         }) {
      std::string said;
      if (shell(c, &said) != 0) {
        why_not_ = "`" + c + "` failed: " + said;
        return;
      }
    }
  }
  ~LinkedNamespaces() {
    // Deleting a namespace deletes its end of the veth pair, and the pair with it.
    (void)shell("ip netns del " + task_control_);
    (void)shell("ip netns del " + agents_);
  }
  LinkedNamespaces(const LinkedNamespaces&) = delete;
  LinkedNamespaces& operator=(const LinkedNamespaces&) = delete;

  const std::string& why_not() const { return why_not_; }
  std::vector<std::string> in_task_control() const { return {"ip", "netns", "exec", task_control_}; }
  std::vector<std::string> in_agents() const { return {"ip", "netns", "exec", agents_}; }
  // Takes task control's end of the link down (the agents' loses its carrier): no packet passes either way.
  bool cut() const { return shell(cut_) == 0; }

 private:
  std::string task_control_, agents_, cut_, why_not_;
};

// Task control in one network namespace and the agents in another, linked only by a veth pair (the shared-memory
// transport, which would cross namespaces through /dev/shm, is off: participants use UDPv4 only): the exchange ends as
// in one process.
TEST(AgentsCli, AcrossNetworkNamespacesTheExchangeEndsAsInOneProcess) {
  LinkedNamespaces ns;
  if (!ns.why_not().empty()) GTEST_SKIP() << "cannot make network namespaces here: " << ns.why_not();
  TwinCli cli("agents-netns");
  CellProcesses c(cli, {}, ns.in_agents(), ns.in_task_control());
  auto& puma = c.puma;
  auto& melfa = c.melfa;
  ASSERT_EQ(c.tc->wait_exit(60s), 0) << c.outputs();
  expect_the_exchange_finished(c.out);
  EXPECT_EQ(puma->wait_exit(20s), 0) << puma->output();
  EXPECT_EQ(melfa->wait_exit(20s), 0) << melfa->output();
}

// The link between the namespaces cut mid-run: task control finds its agents lost within the lease and stops the cell
// (link_lost), and each agent finds task control lost within the lease and halts its robot.
TEST(AgentsCli, TheNetworkCutMidRunStopsTheCellAndHaltsTheRobotsWithinTheLease) {
  LinkedNamespaces ns;
  if (!ns.why_not().empty()) GTEST_SKIP() << "cannot make network namespaces here: " << ns.why_not();
  TwinCli cli("agents-netns-cut");
  CellProcesses c(cli, {}, ns.in_agents(), ns.in_task_control());
  const fs::path& out = c.out;
  BackgroundTwin *tc = c.tc.get(), *puma = c.puma.get(), *melfa = c.melfa.get();
  ASSERT_TRUE(c.under_way()) << c.outputs();

  const auto cut = std::chrono::steady_clock::now();
  ASSERT_TRUE(ns.cut());
  ASSERT_TRUE(wait_for_event(out, [](const nlohmann::json& e) { return e["type"] == "fault_detected"; }, 30s))
      << tc->output();
  const double found = std::chrono::duration<double>(std::chrono::steady_clock::now() - cut).count();
  const std::vector<double> halted = seconds_until({puma, melfa}, "task control lost", cut, 30s);
  EXPECT_EQ(tc->wait_exit(30s), 1) << tc->output();
  const double ended = std::chrono::duration<double>(std::chrono::steady_clock::now() - cut).count();
  std::printf("[ figure ] network cut: task control logged link_lost %.3f s after (its run ended %.3f s after); "
              "agents puma and melfa halted their robots %.3f and %.3f s after (lease 1 s)\n",
              found, ended, halted[0], halted[1]);
  EXPECT_LT(found, 2.5) << "the lease is 1 s";
  for (std::size_t i = 0; i < halted.size(); ++i) {
    BackgroundTwin& p = i == 0 ? *puma : *melfa;
    ASSERT_GE(halted[i], 0.0) << p.output();
    EXPECT_LT(halted[i], 2.5) << "the lease is 1 s";
    EXPECT_EQ(p.wait_exit(10s), 3) << p.output();
  }
  // The first fault is a lost link, and the run ended stopped with it.
  const std::vector<nlohmann::json> log = events_in(out / "events.jsonl");
  for (const nlohmann::json& e : log) {
    if (e["type"] != "fault_detected") continue;
    EXPECT_EQ(e["symptom"], "link_lost") << e.dump();
    EXPECT_THAT(e["detail"].get<std::string>(), HasSubstr("no sign of life from it for its liveliness lease"));
    break;
  }
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "stopped") << report.dump();
}

TEST(AgentsCli, TaskControlRefusesToStartNamingTheRobotsWhoseAgentIsMissing) {
  TwinCli cli("agents-missing");
  const fs::path scenario = exchange_at_the_stop(cli.dir());
  const auto r = cli.run("run " + shell_quote(scenario.string()) + " --agents remote --realtime --domain " +
                         std::to_string(test_domain()) + " --agent-wait 1 --quiet -o " +
                         shell_quote((cli.dir() / "out").string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("no agent for robots puma, melfa"));
  EXPECT_THAT(r.err, HasSubstr("twin agent SCENARIO --robot puma --driver KIND:PORT"));
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
           {"run " + s + " --rejoin-wait 5", "add --agents remote"},
           {"run " + s + " --agents remote --domain " + domain + " --rejoin-wait -1", "--rejoin-wait"},
           {"run " + s + " --agents everywhere --domain " + domain, "--agents"},
           {"run " + s + " --agents remote --realtime --domain " + domain + " --ros-domain " + domain,
            "not published yet"},
           {"run " + s + " --no-twin", "add --agents remote"},
           {"run " + s + " --agents remote --domain " + domain + " --no-twin", "add --realtime"},
           {"run " + s + " --agents remote --realtime --domain " + domain + " --perception truth",
            "do not share it"},
       }) {
    const auto r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out << r.err;
    EXPECT_THAT(r.out + r.err, HasSubstr(c.says)) << c.args;
  }
}

}  // namespace
