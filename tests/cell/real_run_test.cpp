// The rig's run of a cell of real robots with no twin (real_run.hpp), over pseudo-terminals: the exchange on the two
// controllers emulated with the project's kinematics behind them (emulate/), 4 times faster than real time. Nothing is
// simulated: no plant, no sensor but what the drivers have (neither driver senses its grip), and the parts end where
// the controller's model puts them.
#include "cellwright/cell/real_run.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <thread>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/emulate/cell_io_emulator.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/modbus_server.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cell/real_exchange.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;

const std::string kExchange = std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml";


// An emulator serving `link` on a thread of its own until the end of the scope.
template <typename Emulator>
struct Serving {
  Serving(emulate::KinematicArm& arm, fs::path where) : emulator(arm, {}), link(std::move(where)) {
    thread = std::thread([this] { emulator.serve(link); });
    EXPECT_TRUE(emulator.wait_published(1, std::chrono::seconds(10)));
  }
  ~Serving() {
    emulator.stop();
    thread.join();
  }
  Emulator emulator;
  fs::path link;
  std::thread thread;
};

class RealRunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Its own directory: ctest runs the tests of this file as separate processes at once.
    dir_ = fs::temp_directory_path() /
           fmt::format("cw_real_run_{}_{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Scenario exchange_at_the_stop() { return test_real::exchange_at_the_stop(dir_); }
  // Puts the scenario's robots on the emulators at `puma` and `melfa`; its preflight, expected to pass.
  static Preflight on_emulators(Scenario& s, const fs::path& puma, const fs::path& melfa) {
    set_driver(s, "puma=val2:" + puma.string(), {"--driver", 0, 0});
    set_driver(s, "melfa=movemaster:" + melfa.string(), {"--driver", 0, 0});
    Preflight pre = preflight(s, nullptr);
    EXPECT_TRUE(pre.ok()) << (pre.problems.empty() ? std::string() : pre.problems.front());
    return pre;
  }
  fs::path dir_;
};

TEST_F(RealRunTest, EveryRobotOfTheProgramNeedsARealDriver) {
  Scenario s = load_scenario(kExchange);
  set_driver(s, "melfa=movemaster:/dev/null", {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  try {
    RealRun run(s, pre.net);
    FAIL() << "a simulated robot was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--driver puma=movemaster:PORT"), std::string::npos) << e.what();
  }
}

// Issue 25: parts the feed puts on a belt while the run goes would be taken where the cell description has them, and
// nothing real sees them arrive: the run is refused before anything connects (the ports here do not exist), naming
// the feed.
TEST_F(RealRunTest, AFeedIsRefusedBeforeAnythingConnects) {
  Scenario s = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/pipeline.yaml");
  set_driver(s, "puma=val2:" + (dir_ / "no-puma").string(), {"--driver", 0, 0});
  set_driver(s, "melfa=movemaster:" + (dir_ / "no-melfa").string(), {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  try {
    RealRun run(s, pre.net);
    FAIL() << "a real run of a feed was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(fs::path(e.where().file).filename(), "pipeline.yaml") << e.what();
    EXPECT_EQ(e.where().line, 10) << e.what();  // feed: {conveyor: input, ...}
    EXPECT_NE(std::string(e.what()).find("the feed is the twin putting parts on conveyor 'input'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("run the feed on the twin"), std::string::npos) << e.what();
  }
}

TEST_F(RealRunTest, ExchangeRunsOnTwoEmulatedControllersWithNoPlantAndTheModelsParts) {
  emulate::KinematicArm puma_arm = test_real::arm_at_home("/urdf/puma560.urdf", test_real::kPumaHome);
  emulate::KinematicArm melfa_arm = test_real::arm_at_home("/urdf/melfa_rve2.urdf", test_real::kMelfaHome);
  Serving<emulate::Val2Emulator> puma(puma_arm, dir_ / "puma");
  Serving<emulate::MovemasterEmulator> melfa(melfa_arm, dir_ / "melfa");
  Scenario s = exchange_at_the_stop();
  const Preflight pre = on_emulators(s, puma.link, melfa.link);
  ASSERT_TRUE(pre.ok());

  RealRunOptions options;
  options.speed = 4;
  RealRun run(s, pre.net, options);
  EXPECT_EQ(run.runtime().config().plant, nullptr);
  EXPECT_TRUE(run.runtime().config().sensors.grip.empty());  // neither driver senses its grip
  EXPECT_EQ(run.runtime().config().sensors.parts, nullptr);
  ASSERT_EQ(run.robots().size(), 2u);
  EXPECT_EQ(run.robots()[0].robot, "puma");
  EXPECT_EQ(run.robots()[0].driver, "val2 on " + puma.link.string());
  EXPECT_FALSE(run.robots()[0].senses_grip);
  EXPECT_EQ(describe_sensing(run.robots()[1]), "no grip sensor (a close is taken as done), no wrist force sensor");

  const runtime::RunResult& result = run.run();
  ASSERT_EQ(result.outcome, runtime::Outcome::kFinished) << result.reason;
  RunSetup setup = setup_of(s);
  setup.parts_from_model = true;
  setup.twin_truth = false;
  const Report report = make_report(s, runtime::decode_log(run.runtime().log().text(), "events.jsonl"),
                                    final_poses_of(run.model()), std::nullopt, "events.jsonl", setup);
  EXPECT_TRUE(report.ok()) << format_summary(report);
  ASSERT_FALSE(report.workpieces.empty());
  EXPECT_EQ(report.workpieces.front().where, "output");
  EXPECT_NE(format_summary(report).find("parts: where the controller's model"), std::string::npos);
  EXPECT_EQ(to_json(s, report)["parts_from"], "controller_model");
}

// The program's devices need real I/O, since a run without the twin has no twin I/O image: machine.task declares the
// mill, the input conveyor and its photo-eye; each not on a Modbus unit is refused, named, before anything connects
// (the drivers' ports here do not exist).
TEST_F(RealRunTest, EveryDeviceOfTheProgramNeedsRealIo) {
  Scenario s = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/machine.yaml");
  set_driver(s, "puma=val2:" + (dir_ / "no-puma").string(), {"--driver", 0, 0});
  set_driver(s, "melfa=movemaster:" + (dir_ / "no-melfa").string(), {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  const auto refused = [&](const std::string& text) {
    try {
      RealRun run(s, pre.net);
      ADD_FAILURE() << "a device on the twin's I/O was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  refused("device 'mill' of the program machine.task is on the twin's I/O, and a run without the twin has no twin "
          "I/O: give it --device mill=modbus:HOST:PORT[/UNIT]");
  set_devices(s, {"mill=modbus:127.0.0.1:1", "input_eye=modbus:127.0.0.1:1"}, {"--device", 0, 0});
  refused("give it --device input=modbus:HOST:PORT[/UNIT]");
}

// The machine's cycle with no twin: the PUMA sets D aside, loads the mill with A (at the input conveyor's stop: no
// belt here), starts the mill on a Modbus unit (the project's emulated PLC, at 4 times real time as the arms) and
// waits for it, unloads A and hands it to the MELFA, which puts it on the output conveyor.
TEST_F(RealRunTest, AProgramWithAMillOnModbusRunsWithNoTwin) {
  emulate::KinematicArm puma_arm = test_real::arm_at_home("/urdf/puma560.urdf", test_real::kPumaHome);
  emulate::KinematicArm melfa_arm = test_real::arm_at_home("/urdf/melfa_rve2.urdf", test_real::kMelfaHome);
  Serving<emulate::Val2Emulator> puma(puma_arm, dir_ / "puma");
  Serving<emulate::MovemasterEmulator> melfa(melfa_arm, dir_ / "melfa");
  emulate::CellIoEmulatorOptions plc_options;
  plc_options.process_time = 5.0 / 4;  // the mill's 5 s at 4 times real time
  plc_options.take_out_after = 0.5;
  emulate::CellIoEmulator plc(plc_options);
  emulate::ModbusServer server(plc, emulate::ModbusServerOptions{});
  server.start();

  (void)test_real::exchange_at_the_stop(dir_);  // the cell with A at the stop, written into dir_
  std::string yaml = read_file(fs::path(CW_SOURCE_DIR) / "scenes/machine.yaml");
  yaml.replace(yaml.find("program: machine.task"), 21, "program: mill_only.task");
  yaml += fmt::format("devices: {{mill: 'modbus:127.0.0.1:{}'}}\n", server.port());
  write_file_atomically(dir_ / "mill_only.yaml", yaml);
  write_file_atomically(dir_ / "mill_only.task", R"(# machine.task without the belt and its eye: A waits at the stop.
robot r1 r2
workpiece A D
location OUT ASIDE
machine mill

steps
  r1             | r2
  Pick D         |
  Place ASIDE    |
  Pick A         |
  Place mill     |
  start mill     |
  wait mill      |
  Pick A from mill |
  Put r2         | Get r1
                 | Place OUT
end
)");
  Scenario s = load_scenario(dir_ / "mill_only.yaml");
  const Preflight pre = on_emulators(s, puma.link, melfa.link);
  ASSERT_TRUE(pre.ok());

  RealRunOptions options;
  options.speed = 4;
  RealRun run(s, pre.net, options);
  ASSERT_EQ(run.devices().size(), 1u);
  EXPECT_EQ(run.devices()[0].device, "mill");
  EXPECT_EQ(run.devices()[0].unit, fmt::format("modbus 127.0.0.1:{} unit 1", server.port()));
  const runtime::RunResult& result = run.run();
  ASSERT_EQ(result.outcome, runtime::Outcome::kFinished) << result.reason;
  EXPECT_EQ(plc.cycles(), 1);
  const std::string log = run.runtime().log().text();
  EXPECT_NE(log.find(fmt::format(R"("detail":"modbus 127.0.0.1:{} unit 1 mill")", server.port())), std::string::npos);
  EXPECT_NE(log.find(R"("device":"mill","kind":"machine","state":"done")"), std::string::npos);
  RunSetup setup = setup_of(s);
  setup.parts_from_model = true;
  setup.twin_truth = false;
  const Report report = make_report(s, runtime::decode_log(log, "events.jsonl"), final_poses_of(run.model()),
                                    std::nullopt, "events.jsonl", setup);
  EXPECT_TRUE(report.ok()) << format_summary(report);
  server.stop();
}

}  // namespace
}  // namespace cellwright::cell
