// scenes/machine.yaml as a user runs it (issue 26): the PUMA runs the input belt, clears the mill, loads it with A,
// starts its cycle, waits for it, unloads A and hands it over; the MELFA puts it on the stopped output belt, runs it
// and waits for the drop eye. On the twin's devices in lock-step; with the mill, and with the mill and both belts, on
// Modbus TCP against `twin emulate io` (the emulated PLC, a process of its own) in real time; a mill that never
// finishes stops the cell, and a device that cannot be used is refused before anything runs.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <utility>
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

std::vector<nlohmann::json> events_of(const fs::path& file, const std::string& type) {
  std::vector<nlohmann::json> out;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] == type) out.push_back(std::move(e));
  }
  return out;
}

// The mill's states in order, "busy:A" etc.
std::vector<std::string> mill_states(const fs::path& file) {
  std::vector<std::string> out;
  for (const auto& e : events_of(file, "device")) {
    if (e["device"] == "mill") out.push_back(e["state"].get<std::string>() + ":" + e["workpiece"].get<std::string>());
  }
  return out;
}

// A device's states in order ("stopped", "running", ...).
std::vector<std::string> states_of(const fs::path& file, const std::string& device) {
  std::vector<std::string> out;
  for (const auto& e : events_of(file, "device")) {
    if (e["device"] == device) out.push_back(e["state"].get<std::string>());
  }
  return out;
}

// The time of a robot's command `command`'s start, and the unit its detail names; -1 and "" when it never started.
std::pair<double, std::string> command_started(const fs::path& file, const std::string& command) {
  for (const auto& e : events_of(file, "command_start")) {
    if (e["command"] == command) return {e["t"].get<double>(), e["detail"].get<std::string>()};
  }
  return {-1, ""};
}

// `twin emulate io` on a free port: the mill busy `process` seconds, its part taken out 1 s after done; `more`: further
// options (a photo-eye's changes).
struct EmulatedPlc {
  explicit EmulatedPlc(const std::string& process, const std::vector<std::string>& more = {})
      : twin(with(more, {"emulate", "io", "--listen", "127.0.0.1:0", "--process-time", process, "--take-out-after",
                         "1"})) {
    EXPECT_TRUE(twin.wait_for("Ctrl-C to stop\n", 20s)) << twin.output();
    std::smatch m;
    const std::string out = twin.output();
    EXPECT_TRUE(std::regex_search(out, m, std::regex("at 127\\.0\\.0\\.1:([0-9]+), unit 1"))) << out;
    port = m[1].str();
  }
  static std::vector<std::string> with(const std::vector<std::string>& more, std::vector<std::string> args) {
    args.insert(args.end(), more.begin(), more.end());
    return args;
  }
  BackgroundTwin twin;
  std::string port;
};

const std::string kScenario = source_path("scenes/machine.yaml");

// scenes/machine.yaml written into `dir` with the cell and program by absolute path and `extra` lines added at its end
// (line 27 on).
fs::path machine_with(const fs::path& dir, const std::string& extra) {
  std::string yaml = slurp(kScenario);
  yaml.replace(yaml.find("cell: cell.yaml"), 15, "cell: " + source_path("scenes/cell.yaml"));
  yaml.replace(yaml.find("program: machine.task"), 21, "program: " + source_path("scenes/machine.task"));
  const fs::path file = dir / "machine_devices.yaml";
  std::ofstream(file) << yaml << extra;
  return file;
}

TEST(MachineCli, InLockStepTheMillProcessesAAndEveryDeviceStateIsLogged) {
  TwinCli cli("machine-lockstep");
  const fs::path out = cli.dir() / "out";
  const auto r = cli.run("run " + shell_quote(kScenario) + " -o " + shell_quote(out.string()) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("ok   A: expected output, is output"));
  EXPECT_THAT(r.out, HasSubstr("ok   D: expected aside, is aside"));
  const fs::path log = out / "events.jsonl";
  // The cycle as the mill's I/O shows it: A is in it while busy and done, then taken out.
  EXPECT_EQ(mill_states(log), (std::vector<std::string>{"idle:", "busy:A", "done:A", "idle:"}));
  // The program's start and wait are the PUMA's commands, on the twin's I/O.
  bool started = false;
  for (const auto& e : events_of(log, "command_start")) {
    if (e["command"] == "device mill start") {
      started = true;
      EXPECT_EQ(e["robot"], "r1");
      EXPECT_EQ(e["detail"], "twin mill");
    }
  }
  EXPECT_TRUE(started);
  // The mill is busy for its process_time (5 s) of simulated time.
  double busy = -1, done = -1;
  for (const auto& e : events_of(log, "device")) {
    if (e["device"] == "mill" && e["state"] == "busy") busy = e["t"].get<double>();
    if (e["device"] == "mill" && e["state"] == "done") done = e["t"].get<double>();
  }
  EXPECT_NEAR(done - busy, 5.0, 0.02);
  EXPECT_TRUE(events_of(log, "fault_detected").empty());
  // Both belts are the program's: stopped until it runs them. The input belt runs first (and stops itself once A
  // rests at its stop); the output belt only after the MELFA has put A down on it, and the drop eye then sees A.
  const auto run_input = command_started(log, "device input accumulate");
  const auto run_output = command_started(log, "device output accumulate");
  const auto output_eye = command_started(log, "device output_eye await on");
  EXPECT_EQ(run_input.second, "twin input");
  EXPECT_EQ(run_output.second, "twin output");
  EXPECT_GT(run_output.first, done);
  EXPECT_GT(output_eye.first, run_output.first);
  EXPECT_EQ(states_of(log, "output"), (std::vector<std::string>{"stopped", "running"}));
  // Every belt is stopped at the start (the program's net has it stopped); the input belt is run in the program's
  // first round (0.01 s).
  EXPECT_EQ(run_input.first, 0.01);
  EXPECT_EQ(states_of(log, "input"), (std::vector<std::string>{"stopped", "running"}));
  EXPECT_THAT(states_of(log, "output_eye"), ::testing::Contains("on"));
  // The same bytes again.
  const fs::path again = cli.dir() / "again";
  ASSERT_EQ(cli.run("run " + shell_quote(kScenario) + " -o " + shell_quote(again.string()) + " --quiet").status, 0);
  EXPECT_EQ(slurp(log), slurp(again / "events.jsonl"));
}

TEST(MachineCli, WithTheMillOnModbusAgainstAnEmulatedPlcTheRunFinishesTheSame) {
  // At 4x real time, the emulated mill's 1.25 s are the cell's 5 s.
  EmulatedPlc plc("1.25");
  ASSERT_FALSE(plc.port.empty());
  TwinCli cli("machine-modbus");
  const fs::path out = cli.dir() / "out";
  const auto r = cli.run("run " + shell_quote(kScenario) + " --realtime --speed 4 --device mill=modbus:127.0.0.1:" +
                         plc.port + " -o " + shell_quote(out.string()) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("ok   A: expected output, is output"));
  const fs::path log = out / "events.jsonl";
  const auto states = mill_states(log);
  ASSERT_GE(states.size(), 3u);
  EXPECT_EQ(states[1], "busy:A");
  EXPECT_EQ(states[2], "done:A");
  bool on_modbus = false;
  for (const auto& e : events_of(log, "command_start")) {
    if (e["command"] == "device mill await done") {
      on_modbus = e["detail"] == "modbus 127.0.0.1:" + plc.port + " unit 1 mill";
    }
  }
  EXPECT_TRUE(on_modbus);
  EXPECT_EQ(plc.twin.stop(), 0) << plc.twin.output();
}

// What a user checks of a run with devices on a Modbus unit at `port`: it passed, A processed and on the output belt,
// D aside, each device in `on_modbus` commanded on the unit (the command's detail names it), and the twin's belts
// followed the unit's coils (the output belt ran only once the program ran it).
void expect_cell_done_on_modbus(const cellwright::testing::Outcome& r, const fs::path& log, const std::string& port,
                                const std::vector<std::pair<std::string, std::string>>& on_modbus) {
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("ok   A: expected output, is output"));
  EXPECT_THAT(r.out, HasSubstr("ok   D: expected aside, is aside"));
  EXPECT_THAT(r.out, HasSubstr("1 finished; processed A")) << r.out;
  for (const auto& [command, device] : on_modbus) {
    EXPECT_EQ(command_started(log, command).second, "modbus 127.0.0.1:" + port + " unit 1 " + device) << command;
  }
  EXPECT_THAT(states_of(log, "output"), ::testing::Contains("running"));
  EXPECT_TRUE(events_of(log, "fault_detected").empty());
}

TEST(MachineCli, WithTheMillAndBothBeltsOnModbusAgainstAnEmulatedPlcTheRunFinishesTheSame) {
  EmulatedPlc plc("1.25");
  ASSERT_FALSE(plc.port.empty());
  TwinCli cli("machine-belts-modbus");
  const fs::path out = cli.dir() / "out";
  const std::string unit = "=modbus:127.0.0.1:" + plc.port;
  const auto r = cli.run("run " + shell_quote(kScenario) + " --realtime --speed 4 --device mill" + unit +
                         " --device input" + unit + " --device output" + unit + " -o " + shell_quote(out.string()) +
                         " --quiet");
  const fs::path log = out / "events.jsonl";
  expect_cell_done_on_modbus(r, log, plc.port,
                             {{"device mill start", "mill"},
                              {"device input accumulate", "input"},
                              {"device output accumulate", "output"}});
  // The emulated PLC's coils start off: the output belt, read from it, is stopped until the MELFA runs it (the input
  // belt is run in the program's first round: whether device control reads it before is the wall clock's).
  EXPECT_EQ(states_of(log, "output"), (std::vector<std::string>{"stopped", "running"}));
  EXPECT_EQ(plc.twin.stop(), 0) << plc.twin.output();
}

TEST(MachineCli, AMillOnModbusThatNeverFinishesStopsTheCellNamingIt) {
  EmulatedPlc plc("1000");
  ASSERT_FALSE(plc.port.empty());
  TwinCli cli("machine-never");
  const fs::path out = cli.dir() / "out";
  const auto r = cli.run("run " + shell_quote(kScenario) + " --realtime --speed 4 --device mill=modbus:127.0.0.1:" +
                         plc.port + " -o " + shell_quote(out.string()) + " --quiet");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("device_timeout: device mill: done (input 3) not seen within 15.000 s"));
  const fs::path log = out / "events.jsonl";
  const auto faults = events_of(log, "fault_detected");
  ASSERT_EQ(faults.size(), 1u);
  EXPECT_EQ(faults[0]["symptom"], "device_timeout");
  const auto end = events_of(log, "run_end");
  ASSERT_EQ(end.size(), 1u);
  EXPECT_EQ(end[0]["outcome"], "stopped");
  EXPECT_EQ(mill_states(log).back(), "busy:A");  // it never finished
}

TEST(MachineCli, ADeviceThatCannotBeUsedIsRefusedBeforeAnythingRuns) {
  TwinCli cli("machine-bad");
  const std::string run = "run " + shell_quote(kScenario) + " ";
  const struct {
    std::string args;
    std::string message;
  } cases[] = {
      {run + "--device mill=modbus:127.0.0.1:1502", "a real device runs on the wall clock"},
      {run + "--realtime --device drill=modbus:127.0.0.1:1502", "has no device 'drill'"},
      {run + "--realtime --device output_end=modbus:127.0.0.1:1502", "is not wired to I/O"},
      {run + "--realtime --device mill=modbus:127.0.0.1", "modbus:127.0.0.1"},
      {run + "--realtime --device mill", "expected NAME=modbus:HOST:PORT[/UNIT]"},
      {run + "--realtime --device mill=modbus:127.0.0.1:1 --device mill=modbus:127.0.0.1:1", "given twice"},
      // machine.task declares every device the cell wires; exchange.task none.
      {"run " + shell_quote(source_path("scenes/exchange.yaml")) + " --realtime --device output=modbus:127.0.0.1:1",
       "does not declare device 'output'"},
      {run + "--realtime --device mill=modbus:127.0.0.1:1", "cannot be reached"},
  };
  for (const auto& c : cases) {
    const auto r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << c.args;
  }
}

// The scenario's own `devices:` key does what --device does: the mill on the emulated PLC, its commands on Modbus.
TEST(MachineCli, TheScenariosDevicesKeyPutsTheMillOnModbus) {
  EmulatedPlc plc("1.25");
  ASSERT_FALSE(plc.port.empty());
  TwinCli cli("machine-devices-key");
  const fs::path scenario = machine_with(cli.dir(), "devices: {mill: 'modbus:127.0.0.1:" + plc.port + "'}\n");
  // Lock-step is refused, at the key's line.
  const auto lockstep = cli.run("run " + shell_quote(scenario.string()) + " --quiet");
  EXPECT_EQ(lockstep.status, 2) << lockstep.out << lockstep.err;
  const std::string shipped = slurp(kScenario);
  const std::string key_line = std::to_string(std::count(shipped.begin(), shipped.end(), '\n') + 1);
  EXPECT_THAT(lockstep.err, HasSubstr("machine_devices.yaml:" + key_line + ":"));
  EXPECT_THAT(lockstep.err, HasSubstr("device 'mill' is on real I/O (modbus 127.0.0.1:" + plc.port +
                                      " unit 1): a real device runs on the wall clock"));
  const fs::path out = cli.dir() / "out";
  const auto r = cli.run("run " + shell_quote(scenario.string()) + " --realtime --speed 4 -o " +
                         shell_quote(out.string()) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("ok   A: expected output, is output"));
  const fs::path log = out / "events.jsonl";
  bool on_modbus = false;
  for (const auto& e : events_of(log, "command_start")) {
    if (e["command"] == "device mill start") on_modbus = e["detail"] == "modbus 127.0.0.1:" + plc.port + " unit 1 mill";
  }
  EXPECT_TRUE(on_modbus);
  const auto states = mill_states(log);
  ASSERT_GE(states.size(), 3u);
  EXPECT_EQ(states[2], "done:A");
  // --device puts it back on the twin, lock-step as the scene is.
  const auto twin = cli.run("run " + shell_quote(scenario.string()) + " --device mill=twin --quiet");
  EXPECT_EQ(twin.status, 0) << twin.out << twin.err;
  EXPECT_EQ(plc.twin.stop(), 0) << plc.twin.output();
}

// `--dry` reads every input of each device on real I/O and writes no output: the mill's busy and done, the eye's
// input (on: the emulated PLC's photo-eye is on from the start).
TEST(MachineCli, DryReadsEveryInputOfEachRealDevice) {
  EmulatedPlc plc("1000", {"--input", "0:0=1"});
  ASSERT_FALSE(plc.port.empty());
  TwinCli cli("machine-dry");
  const std::string unit = "modbus:127.0.0.1:" + plc.port;
  const auto r = cli.run("run " + shell_quote(kScenario) + " --dry --device mill=" + unit +
                         " --device input_eye=" + unit + " --device input=" + unit);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("mill on modbus 127.0.0.1:" + plc.port + " unit 1\n  read busy (input 2): off\n"
                               "  read done (input 3): off\n"));
  EXPECT_THAT(r.out, HasSubstr("input on modbus 127.0.0.1:" + plc.port + " unit 1\n  read run (coil 0): off\n"));
  EXPECT_THAT(r.out, HasSubstr("input_eye on modbus 127.0.0.1:" + plc.port + " unit 1\n  read part seen (input 0): on\n"));
  EXPECT_THAT(r.out, HasSubstr("every device's unit answered; nothing was moved but homing; no output was written"));
  EXPECT_EQ(plc.twin.stop(), 0) << plc.twin.output();
}

TEST(MachineCli, DryFailsOnADeadUnitNamingTheDeviceAndTheUnit) {
  TwinCli cli("machine-dry-dead");
  const auto r = cli.run("run " + shell_quote(kScenario) + " --dry --device mill=modbus:127.0.0.1:1");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("PROBLEM: device mill on modbus 127.0.0.1:1 unit 1: cannot reach it: "));
  EXPECT_THAT(r.out, HasSubstr("dry run: problems above"));
}

}  // namespace
