// `twin emulate --scenario SCENARIO --io modbus:HOST:PORT`: the twin's I/O served to a PLC for virtual commissioning,
// as a user starts it, driven by pymodbus's client (not our code). In lock-step a PLC program that runs the input
// conveyor until its photo-eye sees a part gets the same replies, byte for byte, and the eye at the same scan, run to
// run, and the scan is the simulated time per read of the inputs; paced, an unwired address is exception 2 and a
// client that drops and reconnects is served again; --io works with --robot; bad input exits 2 naming it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "drivers/modbus/python_peer.hpp"
#include "tools/twin_cli.hpp"

namespace {

using cellwright::testing::BackgroundTwin;
using cellwright::testing::PythonPeer;
using cellwright::testing::shell_quote;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;
using ::testing::MatchesRegex;
using namespace std::chrono_literals;

const std::string kExchange = source_path("scenes/exchange.yaml");

// `twin emulate --scenario exchange --io modbus:127.0.0.1:0...` in the background, and the port its ready line names.
struct ServedTwin {
  explicit ServedTwin(const std::vector<std::string>& extra, const std::string& unit_suffix = "") {
    std::vector<std::string> args = {"emulate", "--scenario", kExchange, "--io", "modbus:127.0.0.1:0" + unit_suffix};
    args.insert(args.end(), extra.begin(), extra.end());
    twin = std::make_unique<BackgroundTwin>(args);
    if (!twin->wait_for("Ctrl-C to stop\n", 120s)) return;
    std::smatch m;
    const std::string out = twin->output();
    if (std::regex_search(out, m, std::regex("the twin's I/O on Modbus TCP at 127\\.0\\.0\\.1:([0-9]+), unit"))) {
      port = m[1].str();
    }
  }
  std::unique_ptr<BackgroundTwin> twin;
  std::string port;  // empty: it did not say it serves
};

struct PlcRun {
  std::vector<std::string> replies;  // "SCAN TID PDU", one per reply (peer.py plc)
  std::string eye;                   // "eye at scan N"
  std::string last_read;             // the PDU of the last read of the inputs
};

// The PLC program of peer.py (`plc`): input conveyor on, scan the inputs until the input eye, conveyor off.
PlcRun run_plc(const std::string& port, int max_scans) {
  PythonPeer plc({"plc", port, std::to_string(max_scans)});
  PlcRun run;
  if (plc.first_line() != "ready") {
    run.eye = "no start: " + plc.first_line();
    return run;
  }
  for (std::string l = plc.line(); !l.empty() && l != "end"; l = plc.line()) {
    if (l.rfind("eye at", 0) == 0 || l.rfind("no eye", 0) == 0 || l.rfind("error", 0) == 0) {
      run.eye = l;
      continue;
    }
    run.replies.push_back(l);
    if (l.find(" 0201") != std::string::npos) run.last_read = l.substr(l.rfind(' ') + 1);
  }
  return run;
}

int scan_of(const std::string& eye) {
  std::smatch m;
  return std::regex_match(eye, m, std::regex("eye at scan ([0-9]+)")) ? std::stoi(m[1].str()) : -1;
}

TEST(EmulateScenarioIoCli, LockStepPlcGetsTheSameRepliesAndTheEyeAtTheSameScanRunToRun) {
  if (const std::string why = cellwright::testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  PlcRun runs[3];
  const char* scans[3] = {"0.05", "0.05", "0.1"};
  for (int i = 0; i < 3; ++i) {
    ServedTwin served({"--lockstep", "--scan", scans[i]});
    ASSERT_FALSE(served.port.empty()) << served.twin->output();
    EXPECT_THAT(served.twin->output(), HasSubstr("lock-step: " + std::string(scans[i]) + " s of simulated time"));
    runs[i] = run_plc(served.port, 2000);
    EXPECT_EQ(served.twin->stop(), 0) << served.twin->output();
  }
  // Part A rides the input belt to its stop: the eye comes on after many scans, and the read that saw it says so.
  const int eye = scan_of(runs[0].eye);
  ASSERT_GT(eye, 20) << runs[0].eye;
  EXPECT_THAT(runs[0].last_read, MatchesRegex("02010[13579bdf]")) << "input 0 on";
  // Belt stopped by the PLC, output belt still running, mill start off: coils 0..2 read 0, 1, 0.
  ASSERT_FALSE(runs[0].replies.empty());
  EXPECT_THAT(runs[0].replies.back(), HasSubstr(" 010102"));
  // Two runs: the same replies, byte for byte, and the eye at the same scan.
  EXPECT_EQ(runs[0].eye, runs[1].eye);
  EXPECT_EQ(runs[0].replies, runs[1].replies);
  // The scan is simulated time per read of the inputs: twice the scan, the eye at half as many reads (rounded up).
  EXPECT_EQ(scan_of(runs[2].eye), (eye + 1) / 2) << runs[2].eye;
}

TEST(EmulateScenarioIoCli, PacedTwinRefusesUnwiredAddressesAndServesAClientThatReconnects) {
  if (const std::string why = cellwright::testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  ServedTwin served({}, "/7");
  ASSERT_FALSE(served.port.empty()) << served.twin->output();
  EXPECT_THAT(served.twin->output(), HasSubstr("unit 7 (paced at 1x real time)"));
  {
    PythonPeer plc({"client", served.port, "7"});
    ASSERT_EQ(plc.first_line(), "ready");
    EXPECT_EQ(plc.ask("write_coil 5 1"), "exception 2");  // the cell wires coils 0..2 only
    EXPECT_EQ(plc.ask("read_inputs 2 3"), "exception 2");  // and discrete inputs 0..3
    EXPECT_EQ(plc.ask("read_coils 0 3"), "ok 1 1 0");      // the belts run from the start; the mill's start is off
    EXPECT_EQ(plc.ask("write_coil 1 0"), "ok");
  }  // the PLC drops its connection
  PythonPeer again({"client", served.port, "7"});
  ASSERT_EQ(again.first_line(), "ready");
  EXPECT_EQ(again.ask("read_coils 0 3"), "ok 1 0 0");  // served again, the output belt as the first one left it
  EXPECT_THAT(again.ask("read_inputs 0 4"), MatchesRegex("ok [01] 0 0 0"));  // D rests in the idle mill
  EXPECT_EQ(served.twin->stop(), 0) << served.twin->output();
}

TEST(EmulateScenarioIoCli, IoServedTogetherWithARobotController) {
  if (const std::string why = cellwright::testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  TwinCli cli("emulate-scenario-io-robot");
  ServedTwin served({"--robot", "puma=val2:" + (cli.dir() / "puma").string()});
  ASSERT_FALSE(served.port.empty()) << served.twin->output();
  EXPECT_THAT(served.twin->output(), HasSubstr("emulating puma (val2) at "));
  EXPECT_TRUE(std::filesystem::exists(cli.dir() / "puma"));
  PythonPeer plc({"client", served.port});
  ASSERT_EQ(plc.first_line(), "ready");
  EXPECT_EQ(plc.ask("write_coil 0 0"), "ok");
  EXPECT_EQ(plc.ask("read_coils 0 3"), "ok 0 1 0");
  EXPECT_EQ(served.twin->stop(), 0) << served.twin->output();
}

TEST(EmulateScenarioIoCli, BadIoOrScenarioIsRefusedWithExit2NamingIt) {
  TwinCli cli("emulate-scenario-io");
  const std::string exchange = shell_quote(kExchange);
  const std::string missing = (cli.dir() / "nosuch.yaml").string();
  const struct {
    std::string args;
    std::string message;
  } cases[] = {
      {"emulate --scenario " + exchange + " --io 127.0.0.1:0",
       "--io: error: '127.0.0.1:0': write modbus:HOST:PORT or modbus:HOST:PORT/UNIT"},
      {"emulate --scenario " + exchange + " --io modbus:127.0.0.1:70000",
       "--io: error: 'modbus:127.0.0.1:70000': '127.0.0.1:70000' is not HOST:PORT with a port within 0..65535"},
      {"emulate --scenario " + exchange + " --io modbus:127.0.0.1:0/300",
       "--io: error: 'modbus:127.0.0.1:0/300': the unit '300' is not a number within 0..255"},
      {"emulate --scenario " + shell_quote(missing) + " --io modbus:127.0.0.1:0",
       missing + ": error: cannot read the scenario"},
      {"emulate --scenario " + exchange + " --lockstep", "--lockstep is for the I/O: add --io"},
      {"emulate --scenario " + exchange + " --io modbus:127.0.0.1:0 --scan 0.1", "--scan is for --lockstep"},
      {"emulate --scenario " + exchange + " --io modbus:127.0.0.1:0 --lockstep --robot puma=val2:/tmp/x",
       "--lockstep serves the I/O alone"},
      {"emulate --scenario " + exchange + " --io modbus:127.0.0.1:0 --lockstep --scan 0.007",
       "the lock-step scan must be a positive whole number of the cell's timestep (0.005 s), got 0.007 s"},
      {"emulate io --listen 127.0.0.1:0 --io modbus:127.0.0.1:0", "--io is for a robot controller or --scenario"},
      {"emulate movemaster --link /tmp/x --io modbus:127.0.0.1:0", "--io is for --scenario"},
  };
  for (const auto& c : cases) {
    const auto r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << c.args;
    EXPECT_TRUE(r.out.empty()) << c.args << ": " << r.out;
  }
}

}  // namespace
