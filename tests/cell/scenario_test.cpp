// The scenario loader: every field read, every kind of bad input refused with the file, line and reason, and the
// preflight (program check, reach of every place the program goes to).
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/scenario.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <numbers>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/garbage_in.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// A scenario file in a fresh directory, naming the repository's cell and programs by absolute path.
class ScenarioFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("scenario_test_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }
  // The head every scenario here shares: line 1 cell, line 2 program; the caller's lines follow from line 3.
  fs::path scenario(const std::string& rest, const std::string& program = "exchange.task") {
    return write("s.yaml", fmt::format("cell: {}/cell.yaml\nprogram: {}/{}\n{}", kScenes, kScenes, program, rest));
  }
  // Loads and expects an InputError at `line` of the scenario file whose message contains `text`.
  void expect_error(const fs::path& file, int line, const std::string& text) {
    try {
      load_scenario(file);
      ADD_FAILURE() << "no error; expected line " << line << ": " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, file.string()) << e.what();
      EXPECT_EQ(e.where().line, line) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  }

  fs::path dir_;
};

TEST_F(ScenarioFiles, ReadsEveryField) {
  const fs::path f = scenario(R"(seed: 42
drivers: {puma: sim}
robots: {r1: puma, r2: melfa}
bind: {B: output_drop}
feed: {conveyor: input, workpieces: [B, C], start: 2, period: 8}
limits: {sim_time: 90, wall_time: 30}
expect:
  A: output
  B: {at: output_drop, tolerance: 0.05}
tolerance: 0.03
options: {realtime: true, control_period: 0.02, settle_time: 0.5}
)");
  const Scenario s = load_scenario(f);
  EXPECT_EQ(s.source, f);
  EXPECT_EQ(s.cell_file, fs::path(kScenes + "/cell.yaml"));
  EXPECT_EQ(s.program.robots, (std::vector<std::string>{"r1", "r2"}));
  EXPECT_EQ(s.seed, 42u);
  EXPECT_EQ(s.robot_of("r1"), "puma");
  EXPECT_EQ(s.robot_of("r2"), "melfa");
  EXPECT_EQ(s.workpiece_of("A"), "A");  // by default, the cell object of the same name
  EXPECT_EQ(s.location_of("B"), "output_drop");
  EXPECT_EQ(s.robots[0].where.line, 5);
  ASSERT_EQ(s.drivers.size(), 2u);
  EXPECT_EQ(s.drivers[0].kind, models::DriverKind::kSim);
  ASSERT_TRUE(s.feed);
  EXPECT_EQ(s.feed->conveyor, "input");
  EXPECT_EQ(s.feed->workpieces, (std::vector<std::string>{"B", "C"}));
  EXPECT_DOUBLE_EQ(s.feed->arrival(1), 10.0);
  EXPECT_DOUBLE_EQ(s.limits.sim_time, 90);
  EXPECT_DOUBLE_EQ(s.limits.wall_time, 30);
  ASSERT_EQ(s.expect.size(), 2u);
  EXPECT_EQ(s.expect[0].workpiece, "A");
  EXPECT_EQ(s.expect[0].place, "output");
  EXPECT_DOUBLE_EQ(s.expect[0].tolerance, 0.03);
  EXPECT_EQ(s.expect[1].place, "output_drop");
  EXPECT_DOUBLE_EQ(s.expect[1].tolerance, 0.05);
  EXPECT_EQ(s.expect[1].where.line, 11);
  EXPECT_TRUE(s.options.realtime);
  EXPECT_DOUBLE_EQ(s.options.control_period, 0.02);
  EXPECT_DOUBLE_EQ(s.options.settle_time, 0.5);
}

TEST_F(ScenarioFiles, DefaultsWhenOptionalFieldsAreMissing) {
  const fs::path f = scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n");
  const Scenario s = load_scenario(f);
  EXPECT_EQ(s.seed, 1u);
  EXPECT_FALSE(s.feed);
  EXPECT_TRUE(s.expect.empty());
  EXPECT_DOUBLE_EQ(s.limits.sim_time, 300);
  EXPECT_DOUBLE_EQ(s.limits.wall_time, 0);
  EXPECT_FALSE(s.options.realtime);
  EXPECT_DOUBLE_EQ(s.options.control_period, 0.01);
}

TEST_F(ScenarioFiles, RelativePathsAreRelativeToTheScenarioFile) {
  fs::copy_file(kScenes + "/exchange.task", dir_ / "prog.task");
  const fs::path f = write("s.yaml", fmt::format("cell: {}/cell.yaml\nprogram: prog.task\nrobots: {{r1: puma, r2: "
                                                 "melfa}}\nbind: {{B: output_drop}}\n",
                                                 kScenes));
  EXPECT_EQ(load_scenario(f).program_file, dir_ / "prog.task");
}

TEST_F(ScenarioFiles, MissingScenarioFile) {
  try {
    load_scenario(dir_ / "nope.yaml");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("nope.yaml"));
    EXPECT_THAT(e.what(), HasSubstr("cannot read the scenario: no such file"));
  }
}

TEST_F(ScenarioFiles, NotYaml) {
  expect_error(write("s.yaml", "cell: x\nprogram: [unclosed\n"), 3, "not a valid YAML file");
}

TEST_F(ScenarioFiles, UnknownField) {
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nexpected: {A: output}\n"), 4,
               "unknown field 'expected' in the scenario");
}

TEST_F(ScenarioFiles, MissingProgramField) {
  expect_error(write("s.yaml", fmt::format("cell: {}/cell.yaml\nseed: 3\n", kScenes)), 1, "no field 'program'");
}

TEST_F(ScenarioFiles, MissingProgramFile) {
  expect_error(write("s.yaml", fmt::format("cell: {}/cell.yaml\nprogram: missing.task\n", kScenes)), 2,
               "field 'program' names 'missing.task'");
}

TEST_F(ScenarioFiles, MissingCellFile) {
  expect_error(write("s.yaml", fmt::format("cell: nocell.yaml\nprogram: {}/exchange.task\n", kScenes)), 1,
               "field 'cell' names 'nocell.yaml'");
}

TEST_F(ScenarioFiles, ProgramErrorsPointIntoTheProgram) {
  const fs::path prog = write("bad.task", "robot r1\nworkpiece A\nsteps\n  r1\n  Pick B\nend\n");
  try {
    load_scenario(write("s.yaml", fmt::format("cell: {}/cell.yaml\nprogram: {}\n", kScenes, prog.string())));
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.where().file, HasSubstr("bad.task"));
    EXPECT_EQ(e.where().line, 5);
  }
}

TEST_F(ScenarioFiles, TheShippedCoordinatedCarryLoadsWithItsBlockAndBindings) {
  // scenes/beam.yaml runs scenes/beam.task's coordinated block (issue 27): it loads like any scenario.
  const Scenario s = load_scenario(kScenes + "/beam.yaml");
  ASSERT_EQ(s.program.coordinated.size(), 1u);
  EXPECT_EQ(s.program.coordinated.front().master, "left");
  EXPECT_EQ(s.program.coordinated.front().follower, "right");
  ASSERT_EQ(s.robots.size(), 2u);
  EXPECT_EQ(s.robots[0].label + "=" + s.robots[0].name, "left=puma");
  EXPECT_EQ(s.robots[1].label + "=" + s.robots[1].name, "right=melfa");
  bool fix = false;
  for (const Binding& b : s.locations) fix = fix || (b.label == "FIX" && b.name == "beam_fix");
  EXPECT_TRUE(fix);
}

TEST_F(ScenarioFiles, ProgramRobotBoundToNothing) {
  // r1 and r2 are not cell robots, and no `robots` field binds them: reported at the `program` field.
  expect_error(scenario("seed: 1\n"), 2, "program robot 'r1' (exchange.task) is bound to nothing in the cell");
}

TEST_F(ScenarioFiles, RobotBoundToAMissingCellRobot) {
  expect_error(scenario("robots: {r1: puma, r2: kuka}\n"), 3, "robot 'r2' is bound to 'kuka', which is not a robot");
}

TEST_F(ScenarioFiles, BindingOfALabelTheProgramLacks) {
  expect_error(scenario("robots:\n  r1: puma\n  r3: melfa\n"), 5, "'r3', which is not a robot of the program");
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nbind:\n  Z: output_drop\n"), 5,
               "'Z', which is not a workpiece or location of the program");
}

TEST_F(ScenarioFiles, LocationBoundToNothing) {
  // B is a program location; the cell has no location named B.
  expect_error(scenario("robots: {r1: puma, r2: melfa}\n"), 2,
               "program location 'B' (exchange.task) is bound to "
               "nothing in the cell");
}

TEST_F(ScenarioFiles, LocationBoundToAMissingLocation) {
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: machine}\n"), 4,
               "location 'B' is bound to 'machine', which is not a location of the cell");
}

TEST_F(ScenarioFiles, TwoLabelsOnOneRobot) {
  expect_error(scenario("robots:\n  r1: puma\n  r2: puma\n"), 5, "are both bound to the cell robot 'puma'");
}

TEST_F(ScenarioFiles, RealDriverWithoutAPortIsRefused) {
  expect_error(scenario("drivers:\n  melfa: movemaster\nrobots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"), 4,
               "robot 'melfa' on the movemaster driver needs a serial port");
  expect_error(scenario("drivers:\n  melfa: 'movemaster:'\nrobots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"),
               4, "robot 'melfa': no port after 'movemaster:'");
  expect_error(scenario("drivers:\n  melfa: 'sim:/dev/ttyS0'\nrobots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"),
               4, "the sim driver takes no port");
}

TEST_F(ScenarioFiles, RealDriverWithAPortTakesTheProtocolsLineSettings) {
  const Scenario s = load_scenario(scenario(
      "drivers:\n  melfa: movemaster:/tmp/melfa\n  puma: val2:/tmp/puma\nrobots: {r1: puma, r2: melfa}\n"
      "bind: {B: output_drop}\n"));
  ASSERT_EQ(s.drivers.size(), 2u);
  EXPECT_TRUE(uses_real_drivers(s));
  for (const DriverChoice& d : s.drivers) {
    ASSERT_TRUE(d.serial.has_value()) << d.robot;
    if (d.robot == "melfa") {
      EXPECT_EQ(d.kind, models::DriverKind::kMovemaster);
      EXPECT_EQ(d.serial->port, "/tmp/melfa");
      EXPECT_EQ(d.serial->data_bits, 7);
      EXPECT_EQ(d.serial->parity, models::Parity::kEven);
      EXPECT_EQ(d.serial->stop_bits, 2);
    } else {
      EXPECT_EQ(d.kind, models::DriverKind::kVal2);
      EXPECT_EQ(d.serial->port, "/tmp/puma");
      EXPECT_EQ(d.serial->data_bits, 8);
      EXPECT_EQ(d.serial->parity, models::Parity::kNone);
    }
  }
}

TEST_F(ScenarioFiles, CommandLineDriverReplacesTheScenariosChoiceAndNothingElse) {
  Scenario s = load_scenario(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"));
  EXPECT_FALSE(uses_real_drivers(s));
  const std::size_t bindings = s.robots.size();
  set_driver(s, "melfa=movemaster:/dev/ttyUSB0", {"--driver", 0, 0});
  EXPECT_TRUE(uses_real_drivers(s));
  EXPECT_EQ(s.robots.size(), bindings);
  for (const DriverChoice& d : s.drivers) {
    if (d.robot == "melfa") {
      EXPECT_EQ(d.kind, models::DriverKind::kMovemaster);
      ASSERT_TRUE(d.serial.has_value());
      EXPECT_EQ(d.serial->port, "/dev/ttyUSB0");
    } else {
      EXPECT_EQ(d.kind, models::DriverKind::kSim);
    }
  }
  set_driver(s, "melfa=sim", {"--driver", 0, 0});
  EXPECT_FALSE(uses_real_drivers(s));
  const auto refused = [&](const std::string& spec, const std::string& text) {
    try {
      set_driver(s, spec, {"--driver", 0, 0});
      ADD_FAILURE() << spec << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("--driver"), std::string::npos) << e.what();
    }
  };
  refused("melfa", "write ROBOT=sim");
  refused("kuka=sim", "'kuka', which is not a robot of the cell");
  refused("melfa=fanuc:/dev/x", "must be sim, movemaster or val2");
  refused("melfa=movemaster", "needs a serial port");
}

TEST_F(ScenarioFiles, DriverUnknown) {
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\ndrivers: {melfa: mujoco}\n"), 5,
               "must be sim, movemaster or val2 (with a port after ':' for the last two), got 'mujoco'");
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\ndrivers: {kuka: sim}\n"), 5,
               "'kuka', which is not a robot of the cell");
}

// machine.task's bindings and places (as scenes/machine.yaml has them): lines 3 to 7; the caller's lines follow from 8.
const std::string kMachineHead =
    "robots: {r1: puma, r2: melfa}\nbind: {OUT: output_drop, ASIDE: aside}\nlocations:\n"
    "  - {name: aside, at: mill.fixture, offset: [0, -0.12, -0.03], yaw: 90}\n"
    "  - {name: mill_slot, at: mill.fixture, yaw: 90, grasp_height: 0.05}\n";

TEST_F(ScenarioFiles, DevicesPutEachOnTheTwinOrAModbusUnit) {
  const Scenario s =
      load_scenario(scenario(kMachineHead + "devices: {mill: 'modbus:127.0.0.1:1502/3', input: twin}\n", "machine.task"));
  ASSERT_EQ(s.devices.size(), 2u);
  EXPECT_EQ(s.devices[0].device, "mill");
  ASSERT_TRUE(s.devices[0].real());
  EXPECT_EQ(s.devices[0].modbus->host, "127.0.0.1");
  EXPECT_EQ(s.devices[0].modbus->port, 1502);
  EXPECT_EQ(s.devices[0].modbus->unit, 3);
  EXPECT_EQ(s.devices[0].where.line, 8);
  EXPECT_EQ(s.devices[1].device, "input");
  EXPECT_FALSE(s.devices[1].real());
  EXPECT_TRUE(uses_real_devices(s));
  EXPECT_EQ(find_device_choice(s, "input_eye"), nullptr);  // on the twin by default
  // Without the key every device is the twin's.
  EXPECT_FALSE(uses_real_devices(load_scenario(scenario(kMachineHead, "machine.task"))));
}

TEST_F(ScenarioFiles, DevicesErrors) {
  const auto error = [&](const std::string& devices, const std::string& text) {
    expect_error(scenario(kMachineHead + devices, "machine.task"), 8, text);
  };
  error("devices: {drill: 'modbus:127.0.0.1:1502'}\n",
        "the cell cell.yaml has no device 'drill' (its machines, conveyors and photo-eyes: mill, input, input_eye, "
        "output, output_end, output_eye)");
  error("devices: {output_end: 'modbus:127.0.0.1:1502'}\n",
        "device 'output_end' is not wired to I/O in the cell cell.yaml: photo-eye 'output_end' of conveyor 'output' "
        "needs `io: INPUT`");
  // machine.task declares every device the cell wires; exchange.task none.
  expect_error(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\ndevices: {output: 'modbus:127.0.0.1:1502'}\n",
                        "exchange.task"),
               5, "the program exchange.task does not declare device 'output'");
  error("devices: {mill: 'modbus:127.0.0.1'}\n", "'modbus:127.0.0.1': the port is missing");
  error("devices: {mill: 'modbus:127.0.0.1:1502/300'}\n", "the unit '300' is not a number within 0..247");
  error("devices: {mill: plc}\n", "device 'mill': the unit must be twin or modbus:HOST:PORT[/UNIT], got 'plc'");
  error("devices: {mill: twin, mill: twin}\n", "'mill' is given twice");
  error("devices: [mill]\n", "must be a mapping of names");
}

TEST_F(ScenarioFiles, CommandLineDeviceReplacesOrAddsToTheScenariosChoice) {
  Scenario s = load_scenario(scenario(kMachineHead + "devices: {mill: twin, input: 'modbus:10.0.0.1:502'}\n",
                                      "machine.task"));
  const SourceLocation cli{"--device", 0, 0};
  set_devices(s, {"mill=modbus:127.0.0.1:1502", "input_eye=modbus:127.0.0.1:1502/2", "input=twin"}, cli);
  ASSERT_EQ(s.devices.size(), 3u);
  ASSERT_TRUE(find_device_choice(s, "mill")->real());
  EXPECT_EQ(find_device_choice(s, "mill")->modbus->str(), "127.0.0.1:1502 unit 1");
  EXPECT_EQ(find_device_choice(s, "mill")->where.file, "--device");
  EXPECT_EQ(find_device_choice(s, "input_eye")->modbus->unit, 2);
  EXPECT_FALSE(find_device_choice(s, "input")->real());
  const auto refused = [&](const std::vector<std::string>& specs, const std::string& text) {
    try {
      set_devices(s, specs, cli);
      ADD_FAILURE() << specs.back() << " was accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, "--device");
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  };
  refused({"mill"}, "'mill': expected NAME=modbus:HOST:PORT[/UNIT] or NAME=twin");
  refused({"drill=twin"}, "'drill=twin': the cell cell.yaml has no device 'drill'");
  refused({"output_end=twin"}, "not wired to I/O");
  refused({"mill=modbus:127.0.0.1"}, "the port is missing");
  refused({"mill=twin", "mill=modbus:127.0.0.1:1"}, "device 'mill' is given twice");
  Scenario exchange = load_scenario(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n", "exchange.task"));
  try {
    set_devices(exchange, {"output=modbus:127.0.0.1:1"}, cli);
    ADD_FAILURE() << "a device exchange.task does not declare was accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("does not declare device 'output'"));
  }
}

TEST_F(ScenarioFiles, FeedErrors) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  expect_error(scenario(head + "feed: {conveyor: belt, workpieces: [A]}\n"), 5, "conveyor 'belt' is not a conveyor");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces: [A, Q]\n"), 7, "workpiece 'Q', which is not");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces:\n    - A\n    - A\n"), 9,
               "names workpiece 'A' twice (first on line 8)");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces: [A, B]\n"), 6, "but no 'period'");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces: [A, B]\n  period: -2\n"), 8,
               "must be greater than 0");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces: []\n"), 7, "must be a non-empty list");
}

TEST_F(ScenarioFiles, ShiftWithNoConveyorToCarryPartsOutIsRefused) {
  // The shipped cell without its output conveyor (and the drop point on it): the input conveyor is its only one.
  std::ifstream in(kScenes + "/cell.yaml");
  std::string cell;
  bool skipping = false;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("  - name: output")) skipping = true;
    if (skipping && line.empty()) skipping = false;
    if (skipping || line.find("output_drop") != std::string::npos) continue;
    // The robots' URDFs are named relative to scenes/.
    if (const auto at = line.find("../models/"); at != std::string::npos) line.replace(at, 2, kScenes + "/..");
    cell += line + "\n";
  }
  ASSERT_EQ(cell.find("name: output"), std::string::npos);
  write("one_belt.yaml", cell);
  const std::string head = fmt::format(
      "cell: one_belt.yaml\nprogram: {}/pipeline_single.task\n"
      "locations:\n"
      "  - {{name: mill_side_1, at: mill.fixture, offset: [0.14, -0.1, -0.03]}}\n"
      "  - {{name: mill_side_2, at: mill.fixture, offset: [0.14, 0, -0.03]}}\n"
      "  - {{name: mill_side_3, at: mill.fixture, offset: [0.14, 0.1, -0.03]}}\n"
      "robots: {{r1: puma}}\nbind: {{P1: mill_side_1, P2: mill_side_2, P3: mill_side_3}}\n",
      kScenes);
  // Three bodies fed once each need no exit; fed six times, they do.
  EXPECT_NO_THROW(load_scenario(write("s.yaml", head + "feed: {conveyor: input, workpieces: [A, B, C], period: 8}\n")));
  expect_error(write("s.yaml", head + "feed:\n  conveyor: input\n  workpieces: [A, B, C]\n  period: 8\n  count: 6\n"),
               13, "no other conveyor than 'input' to carry parts out on");
}

TEST_F(ScenarioFiles, PerceptionAndVision) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  const Scenario truth = load_scenario(scenario(head));
  EXPECT_EQ(truth.perception, runtime::Perception::kTruth);
  EXPECT_FALSE(truth.vision.has_value());
  // Vision without a `vision` entry looks through the cell's first camera, every 400 ms.
  const Scenario seen = load_scenario(scenario(head + "perception: vision\n"));
  EXPECT_EQ(seen.perception, runtime::Perception::kVision);
  ASSERT_TRUE(seen.vision.has_value());
  EXPECT_EQ(seen.vision->camera, "overhead");
  EXPECT_DOUBLE_EQ(seen.vision->period, 0.4);
  EXPECT_DOUBLE_EQ(load_scenario(scenario(head + "perception: vision\nvision: {period: 0.2}\n")).vision->period, 0.2);
  EXPECT_EQ(load_scenario(scenario(head + "perception: cad\n")).perception, runtime::Perception::kCad);

  expect_error(scenario(head + "perception: eyes\n"), 5, "must be truth, vision or cad, got 'eyes'");
  expect_error(scenario(head + "perception: cad\nvision: {camera: overhead}\n"), 6, "'perception' is not vision");
  expect_error(scenario(head + "perception: vision\nvision: {camera: side}\n"), 6,
               "camera 'side' is not a camera of the cell (cameras: overhead)");
  expect_error(scenario(head + "perception: vision\nvision: {period: 0}\n"), 6, "must be greater than 0");
  expect_error(scenario(head + "perception: vision\nvision: {period: 0.001}\n"), 6,
               "must be at least the control period");
}

TEST_F(ScenarioFiles, Perturbation) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  const Scenario s = load_scenario(scenario(head + "perturb: {workpieces: [A, C], offset: [0.01, 0.06], yaw: 20}\n"));
  ASSERT_TRUE(s.perturb.has_value());
  EXPECT_EQ(s.perturb->workpieces, (std::vector<std::string>{"A", "C"}));
  // Each part moves by between half and all of the offset along each axis, either way, and turns by up to the yaw;
  // the same seed draws the same, another seed something else.
  const auto first = draw_perturbation(*s.perturb, 7);
  ASSERT_EQ(first.size(), 2u);
  for (const auto& [name, offset] : first) {
    EXPECT_GE(std::abs(offset.translation().x()), 0.005 - 1e-12) << name;
    EXPECT_LE(std::abs(offset.translation().x()), 0.01 + 1e-12) << name;
    EXPECT_GE(std::abs(offset.translation().y()), 0.03 - 1e-12) << name;
    EXPECT_LE(std::abs(offset.translation().y()), 0.06 + 1e-12) << name;
    EXPECT_EQ(offset.translation().z(), 0.0);
    EXPECT_LE(Eigen::AngleAxisd(offset.linear()).angle(), 20 * std::numbers::pi / 180 + 1e-12);
  }
  EXPECT_TRUE(draw_perturbation(*s.perturb, 7).at("A").isApprox(first.at("A")));
  EXPECT_FALSE(draw_perturbation(*s.perturb, 8).at("A").isApprox(first.at("A")));

  expect_error(scenario(head + "perturb: {workpieces: [Q]}\n"), 5, "names workpiece 'Q', which is not in the cell");
  expect_error(scenario(head + "perturb: {workpieces: [A, A]}\n"), 5, "names workpiece 'A' twice");
  expect_error(scenario(head + "perturb: {workpieces: [A], offset: [0.1]}\n"), 5, "must be a list of 2 numbers");
  expect_error(scenario(head + "perturb: {workpieces: [A], offset: [0.1, -1]}\n"), 5, "from 0 to 0.5");
  expect_error(scenario(head + "perturb: {workpieces: [A], yaw: 270}\n"), 5, "from 0 to 180");
  expect_error(scenario(head + "perturb: {workpieces: [A], offset: [0, 0.09]}\n"), 5,
               "moves workpiece 'A' up to 0.09 m across conveyor 'input', which leaves it room for 0.072 m");
  expect_error(scenario(head + "perturb: {workpieces: [A], spin: 3}\n"), 5, "unknown field 'spin'");
}

TEST_F(ScenarioFiles, ExpectationErrors) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  expect_error(scenario(head + "expect:\n  Q: output\n"), 6, "names workpiece 'Q', which is not in the cell");
  expect_error(scenario(head + "expect:\n  A: the_moon\n"), 6,
               "expected at 'the_moon', which is not a location, conveyor or machine");
  expect_error(scenario(head + "expect:\n  A: {at: output, tolerance: 0}\n"), 6, "must be greater than 0");
  expect_error(scenario(head + "expect:\n  A: {at: output, within: 1}\n"), 6, "unknown field 'within'");
}

TEST_F(ScenarioFiles, LocationsOfTheScenarioJoinTheCell) {
  const Scenario s = load_scenario(scenario(R"(locations:
  - {name: belt_end, at: output.leave, offset: [-0.1, 0, 0], yaw: 90, approach_height: 0.05}
  - {name: spot, pose: {xyz: [0.2, 0.3, 0.4]}}
robots: {r1: puma, r2: melfa}
bind: {B: belt_end}
expect: {A: spot}
)"));
  const models::LocationSpec* end = s.cell.find_location("belt_end");
  ASSERT_NE(end, nullptr);
  const models::ConveyorSpec& out = *s.cell.find_conveyor("output");
  EXPECT_TRUE(end->pose.xyz.isApprox(out.belt_point(out.leave) + Eigen::Vector3d(-0.1, 0, 0)));
  EXPECT_NEAR(end->pose.rpy.z(), out.pose.rpy.z() + M_PI / 2, 1e-12);
  EXPECT_DOUBLE_EQ(end->approach_height, 0.05);
  EXPECT_DOUBLE_EQ(end->grasp_height, 0.02);  // the cell description's default
  EXPECT_EQ(end->where.line, 4);
  EXPECT_TRUE(s.cell.find_location("spot")->pose.xyz.isApprox(Eigen::Vector3d(0.2, 0.3, 0.4)));
  EXPECT_EQ(s.location_of("B"), "belt_end");
  EXPECT_EQ(s.expect[0].place, "spot");
}

TEST_F(ScenarioFiles, LocationErrors) {
  expect_error(scenario("locations:\n  - {name: input, at: output.enter}\n"), 4, "the name is already used");
  expect_error(scenario("locations:\n  - {name: x, at: output.middle}\n"), 4, "'at' must be <conveyor>.enter");
  expect_error(scenario("locations:\n  - {name: x}\n"), 4, "needs either 'at' or 'pose'");
  expect_error(scenario("locations:\n  - {name: x, pose: {xyz: [1, 2]}}\n"), 4, "must be a list of 3 numbers");
  expect_error(scenario("locations:\n  - {name: 9x, pose: {xyz: [1, 2, 3]}}\n"), 4, "is not valid");
  expect_error(scenario("locations: {name: x}\n"), 3, "must be a list of locations");
}

TEST_F(ScenarioFiles, NumbersOutOfRange) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  expect_error(scenario(head + "seed: -1\n"), 5, "field 'seed' of the scenario must be a whole number");
  expect_error(scenario(head + "limits: {sim_time: 0}\n"), 5, "must be greater than 0");
  expect_error(scenario(head + "options:\n  control_period: 0.0001\n"), 6, "whole multiple of the cell's simulation");
  expect_error(scenario(head + "options:\n  control_period: 0.0125\n"), 6, "whole multiple of the cell's simulation");
  expect_error(scenario(head + "options: {realtime: maybe}\n"), 5, "must be true or false");
}

// Values no cell can use are refused with the field, the value and the bound: beyond the bound they are typos (or
// would overflow the nanosecond clock), and times that end after the run cannot work.
TEST_F(ScenarioFiles, ImpossibleValuesNameFieldValueAndBound) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  expect_error(scenario(head + "limits:\n  sim_time: 1e300\n"), 6,
               "field 'sim_time' of field 'limits' must be greater than 0 and at most 1000000 s, got 1e300");
  expect_error(scenario(head + "limits:\n  wall_time: -3\n"), 6,
               "field 'wall_time' of field 'limits' must be greater than 0 and at most 1000000 s, got -3");
  expect_error(scenario(head + "options:\n  settle_time: .inf\n"), 6,
               "field 'settle_time' of field 'options' must be a finite number, got .inf");
  expect_error(scenario(head + "options:\n  control_period: 5\n"), 6,
               "field 'control_period' of field 'options' must be greater than 0 and at most 1 s, got 5");
  expect_error(scenario(head + "tolerance: 50\n"), 5,
               "field 'tolerance' of the scenario must be greater than 0 and at most 2 m, got 50");
  expect_error(scenario(head + "recovery:\n  command_timeout: 1e12\n"), 6,
               "field 'command_timeout' of field 'recovery' must be greater than 0 and at most 1000000 s, got 1e12");
  expect_error(scenario(head + "locations:\n  - {name: x, at: output.enter, yaw: 1e9}\n"), 6,
               "field 'yaw' of a location of the scenario must be within -360..360 degrees, got 1e9");
  expect_error(scenario(head + "locations:\n  - {name: x, pose: {xyz: [1, 2, 3e5]}}\n"), 6,
               "must be within -100..100 m, got 3e5");
  expect_error(scenario(head + "faults:\n  - {kind: obstacle, robot: puma, time: 1e300}\n"), 6,
               "field 'time' of the obstacle fault must be within 0..1000000 s, got 1e300");
  // Settling that outlasts the run: the run would always end in a timeout.
  expect_error(scenario(head + "limits: {sim_time: 60}\noptions:\n  settle_time: 60\n"), 7,
               "field 'settle_time' of field 'options' (simulated after the program finishes) is 60 s, but the run "
               "ends at the simulation time limit of 60 s (field 'sim_time' of field 'limits'): it cannot work");
  expect_error(scenario(head + "feed:\n  conveyor: input\n  workpieces: [B]\n  start: 400\n"), 8,
               "field 'start' of field 'feed' (the first part's arrival) is 400 s, but the run ends at the simulation "
               "time limit of 300 s (the default)");
}

// An editor's UTF-8 byte-order mark at the start of the file changes nothing, lines included.
TEST_F(ScenarioFiles, ByteOrderMarkIsAccepted) {
  const fs::path f = write("bom.yaml", fmt::format("\xEF\xBB\xBF" "cell: {}/cell.yaml\nprogram: {}/exchange.task\n"
                                                   "robots: {{r1: puma, r2: melfa}}\nbind: {{B: output_drop}}\n",
                                                   kScenes, kScenes));
  EXPECT_EQ(load_scenario(f).robot_of("r1"), "puma");
  const fs::path bad = write("bom_bad.yaml", fmt::format("\xEF\xBB\xBF" "cell: {}/cell.yaml\nprogram: {}/exchange.task\n"
                                                         "robots: {{r1: puma, r2: melfa}}\nbind: {{B: output_drop}}\n"
                                                         "tolerance: -1\n",
                                                         kScenes, kScenes));
  expect_error(bad, 5, "field 'tolerance' of the scenario must be greater than 0");
}

// --- preflight ---

TEST_F(ScenarioFiles, ExchangeScenarioPassesPreflight) {
  const Scenario s = load_scenario(kScenes + "/exchange.yaml");
  const Preflight p = preflight(s, &twin_port());
  EXPECT_TRUE(p.analysis.ok());
  EXPECT_TRUE(p.ok()) << (p.problems.empty() ? "" : p.problems.front());
  // r1 goes to A at the input stop and to the hand-over; r2 to the hand-over and to the drop point.
  std::vector<std::string> needs;
  for (const ReachNeed& n : p.needs) needs.push_back(n.robot + ": " + n.target);
  EXPECT_THAT(needs,
              ::testing::ElementsAre("puma: workpiece 'A' at location 'input_pick'", "puma: the hand-over 'exchange'",
                                     "melfa: the hand-over 'exchange'", "melfa: location 'output_drop'"));
  for (const models::ReachCheck& c : p.reach) EXPECT_TRUE(c.reachable) << c.robot << " " << c.target;
}

TEST_F(ScenarioFiles, PreflightChecksAsTwinCheckDoesWithTheReduction) {
  // The shift's loop makes a cyclic net: the reduced search applies (its weighting of the places shows it bounded),
  // with the verdict of full exploration and fewer markings.
  const Scenario s = load_scenario(kScenes + "/pipeline_shift.yaml");
  const Preflight p = preflight(s, &twin_port());
  EXPECT_TRUE(p.analysis.ok()) << petri::format_report(p.net, p.analysis);
  EXPECT_TRUE(p.analysis.reduced) << p.analysis.reduction_note;
  const petri::AnalysisResult full = petri::analyze(p.net);
  EXPECT_TRUE(full.ok());
  EXPECT_LT(p.analysis.states, full.states);
}

TEST_F(ScenarioFiles, MoveThePlanCannotMakeIsRefused) {
  // Backed off 30 cm from its side grasp at the hand-over, the MELFA's tool would be at its own base: both of its
  // moves to hand_approach(r1) (approach, and depart holding A) are refused, naming the command and its source.
  const Scenario s = load_scenario(
      scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\noptions: {handover_clearance: 0.3}\n"));
  const Preflight p = preflight(s, &twin_port());
  EXPECT_FALSE(p.ok());
  const auto approach =
      ::testing::AllOf(HasSubstr("robot 'melfa' (r2) cannot make 'move hand_approach(r1)'"),
                       HasSubstr("(exchange.task:9:14 'Get r1')"), HasSubstr("no joint configuration"));
  EXPECT_THAT(p.problems, ::testing::Contains(approach).Times(2));
  EXPECT_THAT(p.problems, ::testing::Contains(HasSubstr("holding A")));
}

TEST_F(ScenarioFiles, DeadlockingProgramFailsPreflightWithTheCheck) {
  const Scenario s = load_scenario(scenario("robots: {r1: puma, r2: melfa}\n", "deadlock.task"));
  const Preflight p = preflight(s, &twin_port());
  EXPECT_FALSE(p.ok());
  EXPECT_FALSE(p.analysis.ok());
  EXPECT_EQ(p.analysis.deadlocks, petri::analyze(p.net).deadlocks);  // the reduced search finds every dead marking
  ASSERT_EQ(p.problems.size(), 1u);
  EXPECT_THAT(p.problems[0], HasSubstr("fails the check"));
  EXPECT_THAT(p.problems[0], HasSubstr("deadlock"));
}

TEST_F(ScenarioFiles, UnreachableTargetFailsPreflightNamingRobotTargetAndCommand) {
  // The MELFA is bound to the single-robot pick-and-place: the input stop and the machine are beyond its reach.
  const Scenario s = load_scenario(scenario("robots: {r1: melfa}\nbind: {B: machine_fixture}\n", "pick_place.task"));
  const Preflight p = preflight(s, &twin_port());
  EXPECT_TRUE(p.analysis.ok());
  ASSERT_FALSE(p.ok());
  EXPECT_THAT(p.problems[0], HasSubstr("robot 'melfa' cannot reach workpiece 'A' at location 'input_pick'"));
  EXPECT_THAT(p.problems[0], HasSubstr("pick_place.task:"));
  EXPECT_THAT(p.problems[0], HasSubstr("'Pick A'"));
  EXPECT_THAT(p.problems[0], HasSubstr("maximum reach"));
}

}  // namespace
}  // namespace cellwright::cell

namespace cellwright::cell {
namespace {

class ScenarioRecovery : public ScenarioFiles {};

TEST_F(ScenarioRecovery, WithoutTheFieldRecoveryIsOnWithTheStandardTree) {
  const Scenario s = load_scenario(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"));
  EXPECT_TRUE(s.recovery.enabled);
  EXPECT_EQ(s.recovery.tree, nullptr);
  EXPECT_TRUE(s.recovery_file.empty());
}

TEST_F(ScenarioRecovery, ATreeFileAndTheWatchdogTimesAreRead) {
  write("tree.yaml", "closed_on_nothing: {cause: operator_needed, action: stop_cell}\n");
  const Scenario s = load_scenario(scenario(
      "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"
      "recovery: {tree: tree.yaml, max_attempts: 2, part_wait: 5, wait_timeout: 12.5, command_timeout: 4,\n"
      "           progress_limit: 7, progress_timeout: 45}\n"));
  ASSERT_NE(s.recovery.tree, nullptr);
  EXPECT_EQ(s.recovery_file, dir_ / "tree.yaml");
  const runtime::Diagnosis d =
      s.recovery.tree->diagnose(runtime::Symptom::closed_on_nothing, [](runtime::Question) { return true; });
  EXPECT_EQ(d.cause, "operator_needed");
  EXPECT_EQ(s.recovery.max_attempts, 2);
  EXPECT_EQ(s.recovery.part_wait, std::chrono::seconds(5));
  EXPECT_EQ(s.recovery.wait_timeout, std::chrono::milliseconds(12500));
  EXPECT_EQ(s.recovery.command_timeout, std::chrono::seconds(4));
  EXPECT_EQ(s.recovery.progress_limit, 7);
  EXPECT_EQ(s.recovery.progress_timeout, std::chrono::seconds(45));
  // The plain form names the file only.
  const Scenario plain = load_scenario(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"
                                                "recovery: tree.yaml\n"));
  EXPECT_NE(plain.recovery.tree, nullptr);
  const Scenario off = load_scenario(scenario("robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n"
                                              "recovery: {enabled: false}\n"));
  EXPECT_FALSE(off.recovery.enabled);
}

TEST_F(ScenarioRecovery, TheCarryLimitsOfTheSafetyLayerAreReadWithDefaults) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  const Scenario plain = load_scenario(scenario(head));
  EXPECT_DOUBLE_EQ(plain.safety.carry_error, runtime::SafetyOptions{}.carry_error);
  EXPECT_DOUBLE_EQ(plain.safety.squeeze_force, runtime::SafetyOptions{}.squeeze_force);
  const Scenario s =
      load_scenario(scenario(head + "safety: {carry_error: 0.004, carry_turn: 1.5, squeeze_force: 25}\n"));
  EXPECT_DOUBLE_EQ(s.safety.carry_error, 0.004);
  EXPECT_NEAR(s.safety.carry_turn, 1.5 * M_PI / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.safety.squeeze_force, 25.0);
  EXPECT_DOUBLE_EQ(s.safety.force_limit, runtime::SafetyOptions{}.force_limit);  // the rest as they were
  expect_error(scenario(head + "safety:\n  squeeze_force: -5\n"), 6,
               "field 'squeeze_force' of field 'safety' must be greater than 0 and at most 10000 N, got -5");
  expect_error(scenario(head + "safety:\n  carry_error: 2\n"), 6,
               "field 'carry_error' of field 'safety' must be greater than 0 and at most 0.5 m, got 2");
  expect_error(scenario(head + "safety: {carry_turn: 0}\n"), 5, "must be greater than 0 and at most 90 degrees");
  expect_error(scenario(head + "safety: {squeeze: 5}\n"), 5, "unknown field 'squeeze'");
}

TEST_F(ScenarioRecovery, BadRecoverySettingsNameTheFieldOrTheTreeFile) {
  const std::string head = "robots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\n";
  expect_error(scenario(head + "recovery: {tree: t.yaml, retries: 2}\n"), 5, "unknown field 'retries'");
  expect_error(scenario(head + "recovery: {max_attempts: 1.5}\n"), 5, "must be a whole number from 1 to 100");
  expect_error(scenario(head + "recovery: {part_wait: -1}\n"), 5, "part_wait");
  expect_error(scenario(head + "recovery: {progress_limit: 0}\n"), 5, "progress_limit");
  expect_error(scenario(head + "recovery: {progress_timeout: 0}\n"), 5, "progress_timeout");
  // A tree file that is missing or wrong is named itself.
  try {
    load_scenario(scenario(head + "recovery: nowhere.yaml\n"));
    ADD_FAILURE() << "no error for a missing tree file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir_ / "nowhere.yaml").string());
  }
  write("bad.yaml", "grip_lost: {cause: x, action: dance}\n");
  try {
    load_scenario(scenario(head + "recovery: bad.yaml\n"));
    ADD_FAILURE() << "no error for a bad tree file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir_ / "bad.yaml").string());
    EXPECT_EQ(e.where().line, 1);
    EXPECT_THAT(e.what(), HasSubstr("unknown action 'dance'"));
  }
}

// Seeded garbage in: the shipped scenarios with random edits are read (their cell, program and recovery files as
// they name them) or refused with an InputError naming the scenario; nothing else escapes.
TEST(ScenarioGarbageIn, MutatedScenariosAreReadOrRefusedWithAnInputError) {
  std::vector<std::string> originals;
  for (const char* name : {"exchange.yaml", "pipeline.yaml", "pipeline_shift.yaml", "single.yaml", "vision.yaml"}) {
    originals.push_back(cellwright::testing::slurp_text(fs::path(kScenes) / name));
  }
  const std::string source = kScenes + "/mutant.yaml";
  const auto counts =
      cellwright::testing::feed_garbage(originals, 300, 20261124, ":-[]{},#&*!|>'\"%@`? \n\t0123456789abcxyz_.", source,
                                        [&](const std::string& text) { (void)parse_scenario(text, source); });
  EXPECT_GT(counts.accepted, 10);
  EXPECT_GT(counts.refused, 100);
}

}  // namespace
}  // namespace cellwright::cell
