// The cell description: the paper's cell loads as described, every place the robots must reach is reachable, and
// each kind of bad input is reported with its file, line and problem.
#include "cellwright/models/cell.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "cellwright/models/kinematics.hpp"
#include "common/garbage_in.hpp"

namespace cellwright::twin {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = std::numbers::pi / 180.0;
const std::filesystem::path kSource = CW_SOURCE_DIR;

std::string urdf(const char* file) {
  return (kSource / "models/urdf" / file).string();
}

// A small valid cell; each error case below changes one thing in it.
std::string base_yaml() {
  return fmt::format(R"(name: test-cell
robots:
  - name: puma
    urdf: {}
    base: {{xyz: [0, 0, 0], yaw: 0}}
    home: [0, 84, -192, 0, -72, 90]
  - name: melfa
    urdf: {}
    base: {{xyz: [0.95, 0, 0.25], yaw: 180}}
    home: [0, 30, 60, 0, 60, 0]
conveyors:
  - name: belt
    pose: {{xyz: [-0.5, -0.55, 0], yaw: 0}}
    length: 1.2
    width: 0.2
    height: 0.5
    speed: 0.05
machines:
  - name: mill
    pose: {{xyz: [0.05, 0.6, 0], yaw: 0}}
    size: [0.4, 0.35, 0.4]
    fixture: {{size: [0.12, 0.12, 0.03]}}
    process_time: 5
handover:
  pose: {{xyz: [0.5, 0, 0.55], yaw: 90}}
  grasps:
    - {{robot: puma, approach: down, offset: [0, 0, 0.02]}}
    - {{robot: melfa, approach: side, offset: [0, 0, -0.02]}}
locations:
  - name: pick
    at: belt.leave
    reach: [puma]
workpieces:
  - name: A
    shape: box
    size: [0.04, 0.04, 0.06]
    mass: 0.1
    colour: [0.9, 0.1, 0.1]
    on: belt
cameras:
  - name: top
    position: [0, 0, 2.5]
    look_at: [0, 0, 0]
    resolution: [320, 240]
    fovy: 60
)",
                     urdf("puma560.urdf"), urdf("melfa_rve2.urdf"));
}

// The text with `from` (which must occur) replaced by `to`.
std::string with(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << "the base cell has no '" << from << "'";
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

// 1-based line of the first line containing `needle`.
int line_of(const std::string& text, const std::string& needle) {
  const auto pos = text.find(needle);
  EXPECT_NE(pos, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(pos), '\n'));
}

models::CellDescription parse(const std::string& text) {
  return models::parse_cell(text, "case.yaml");
}

// The InputError `text` gives; fails the test if it is accepted.
InputError error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return InputError({}, "");
}

void expect_error(const std::string& text, const std::string& fragment, int line) {
  const InputError e = error_of(text);
  EXPECT_THAT(e.what(), HasSubstr(fragment));
  EXPECT_EQ(e.where().file, "case.yaml") << e.what();
  EXPECT_EQ(e.where().line, line) << e.what();
  EXPECT_GT(e.where().column, 0) << e.what();
}

TEST(Cell, PaperCellLoadsAsDescribed) {
  const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
  EXPECT_EQ(cell.name, "yasuda-cell");
  EXPECT_TRUE(cell.source.is_absolute());
  ASSERT_EQ(cell.robots.size(), 2u);
  const models::RobotSpec& puma = *cell.find_robot("puma");
  EXPECT_EQ(puma.urdf, (kSource / "models/urdf/puma560.urdf").lexically_normal());
  ASSERT_EQ(puma.home.size(), 6u);
  EXPECT_NEAR(puma.home[2], -192 * kDeg, 1e-12);
  EXPECT_EQ(puma.driver, models::DriverKind::kSim);
  const models::RobotSpec& melfa = *cell.find_robot("melfa");
  EXPECT_NEAR(melfa.base.rpy.z(), std::numbers::pi, 1e-12);
  EXPECT_NEAR(melfa.base.xyz.z(), 0.25, 1e-12);

  const models::ConveyorSpec& input = *cell.find_conveyor("input");
  EXPECT_TRUE(input.stop);
  EXPECT_TRUE(input.belt_point(0).isApprox(Eigen::Vector3d(-1.1, -0.55, 0.5)));
  EXPECT_EQ(input.sensor, 16);  // the photo-eye at its stop
  const models::ConveyorSpec& output = *cell.find_conveyor("output");
  EXPECT_TRUE(output.stop);
  EXPECT_DOUBLE_EQ(output.speed, 0.05);
  EXPECT_EQ(output.sensor, 0);
  // The paper's I/O list (docs/cell-description.md, "io").
  EXPECT_EQ(input.run_io.address, 0);
  EXPECT_EQ(input.stop_eye_name, "input_eye");
  EXPECT_EQ(input.stop_eye_io.address, 0);
  EXPECT_TRUE(input.accumulate);
  EXPECT_EQ(output.run_io.address, 1);
  EXPECT_EQ(output.drop_eye_name, "output_eye");
  EXPECT_EQ(output.drop_eye_io.address, 1);
  EXPECT_FALSE(output.stop_eye_io.wired());  // its end eye is the belt's own
  EXPECT_TRUE(output.accumulate);
  const models::MachineSpec& mill = cell.machines.at(0);
  EXPECT_EQ(mill.start_io.address, 2);
  EXPECT_EQ(mill.busy_io.address, 2);
  EXPECT_EQ(mill.done_io.address, 3);

  // Locations resolved from the objects they are at.
  EXPECT_TRUE(cell.find_location("input_pick")->pose.xyz.isApprox(Eigen::Vector3d(0.03, -0.55, 0.5)));
  EXPECT_NEAR(cell.find_location("input_pick")->pose.rpy.z(), 90 * kDeg, 1e-12);
  EXPECT_TRUE(cell.find_location("machine_fixture")->pose.xyz.isApprox(Eigen::Vector3d(0.05, 0.6, 0.43)));
  EXPECT_TRUE(cell.find_location("output_drop")->pose.xyz.isApprox(Eigen::Vector3d(0.95, 0.405, 0.35)));

  // Parts put on the input conveyor stand in a row from its entry point, 2 cm apart, resting on the belt, the first
  // listed furthest along.
  ASSERT_EQ(cell.workpieces.size(), 4u);
  EXPECT_TRUE(cell.find_workpiece("C")->pose.xyz.isApprox(Eigen::Vector3d(-1.0, -0.55, 0.53)));
  EXPECT_TRUE(cell.find_workpiece("B")->pose.xyz.isApprox(Eigen::Vector3d(-0.94, -0.55, 0.53)));
  EXPECT_TRUE(cell.find_workpiece("A")->pose.xyz.isApprox(Eigen::Vector3d(-0.88, -0.55, 0.53)));
  EXPECT_EQ(cell.find_workpiece("A")->on, "input");
  // D waits in the machine, on its fixture.
  EXPECT_EQ(cell.find_workpiece("D")->shape, models::Shape::kCylinder);
  EXPECT_TRUE(cell.find_workpiece("D")->pose.xyz.isApprox(Eigen::Vector3d(0.05, 0.6, 0.46)));
  EXPECT_DOUBLE_EQ(cell.find_workpiece("A")->rgba[3], 1.0);

  // The overhead camera looks straight down with image up along the world's +y axis.
  const models::CameraSpec& cam = *cell.find_camera("overhead");
  EXPECT_TRUE(cam.pose.rotation().col(2).isApprox(Eigen::Vector3d::UnitZ(), 1e-9));
  EXPECT_TRUE(cam.pose.rotation().col(1).isApprox(Eigen::Vector3d::UnitY(), 1e-9));
  EXPECT_EQ(cam.width, 640);
  EXPECT_NEAR(cam.fovy, 60 * kDeg, 1e-12);

  ASSERT_TRUE(cell.handover.has_value());
  EXPECT_EQ(cell.handover->name, "exchange");
  ASSERT_EQ(cell.handover->grasps.size(), 2u);
  EXPECT_EQ(cell.handover->grasps[1].approach, models::Approach::kSide);
  EXPECT_EQ(cell.lights.size(), 2u);
}

// Every location is reachable, gripper down, by the robots that must reach it, and the hand-over by both arms: the
// joint solutions are checked with forward kinematics, independently of the solver.
TEST(Cell, EveryLocationAndTheHandoverAreReachable) {
  const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
  const std::vector<models::ReachCheck> checks = models::check_reach(cell);
  // Three locations, grasp and approach each, one robot each; the hand-over for two robots.
  ASSERT_EQ(checks.size(), 8u);
  int handover_checks = 0;
  for (const models::ReachCheck& c : checks) {
    SCOPED_TRACE(c.target + " by " + c.robot);
    ASSERT_TRUE(c.reachable) << c.reason;
    const models::RobotSpec& robot = *cell.find_robot(c.robot);
    const auto chain = models::KinematicChain::from_urdf_file(robot.urdf);
    const Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(c.q.data(), static_cast<Eigen::Index>(c.q.size()));
    EXPECT_TRUE(chain.within_limits(q));
    const Eigen::Isometry3d reached = robot.base.transform() * chain.forward(q);
    EXPECT_LT((reached.translation() - c.tcp_world.translation()).norm(), 1e-4);
    EXPECT_LT(Eigen::AngleAxisd(reached.linear().transpose() * c.tcp_world.linear()).angle(), 1e-3);
    if (c.target.find("hand-over") != std::string::npos) {
      ++handover_checks;
    } else {
      // Locations are reached with the gripper pointing down.
      EXPECT_TRUE(reached.linear().col(2).isApprox(-Eigen::Vector3d::UnitZ(), 1e-3));
    }
  }
  EXPECT_EQ(handover_checks, 2);
}

TEST(Cell, GraspPoses) {
  const Eigen::Isometry3d base(Eigen::Translation3d(1, 0, 0));
  const Eigen::Isometry3d down = models::grasp_pose({0.5, 0.2, 0.3}, models::Approach::kDown, 90 * kDeg, base);
  EXPECT_TRUE(down.linear().col(2).isApprox(-Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(down.linear().col(1).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_NEAR(down.linear().determinant(), 1.0, 1e-12);
  // From the side: the approach axis points horizontally from the robot's base to the point.
  const Eigen::Isometry3d side = models::grasp_pose({0.5, 0, 0.3}, models::Approach::kSide, 0, base);
  EXPECT_TRUE(side.linear().col(2).isApprox(-Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(side.linear().col(1).z(), 0.0, 1e-12);
  EXPECT_NEAR(side.linear().determinant(), 1.0, 1e-12);
  EXPECT_TRUE(side.translation().isApprox(Eigen::Vector3d(0.5, 0, 0.3)));
}

TEST(Cell, BaseCaseIsValid) {
  const models::CellDescription cell = parse(base_yaml());
  EXPECT_EQ(cell.robots.size(), 2u);
  EXPECT_EQ(cell.handover->name, "handover");
  // Defaults: parts enter at a tenth of the belt and leave at nine tenths.
  EXPECT_NEAR(cell.find_conveyor("belt")->enter, 0.12, 1e-12);
  EXPECT_NEAR(cell.find_conveyor("belt")->leave, 1.08, 1e-12);
  EXPECT_DOUBLE_EQ(cell.timestep, 0.002);
  EXPECT_DOUBLE_EQ(cell.robots[0].grip_force, 5.0);
}

TEST(Cell, SerialSettingsAreKept) {
  const std::string movemaster = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                      "    home: [0, 30, 60, 0, 60, 0]\n    driver: movemaster\n"
                                      "    serial: {port: /dev/ttyS1}\n");
  const models::CellDescription mcell = parse(movemaster);
  const models::RobotSpec& m = *mcell.find_robot("melfa");
  EXPECT_EQ(m.driver, models::DriverKind::kMovemaster);
  ASSERT_TRUE(m.serial.has_value());
  // The Movemaster's documented line: 9600 baud, 7 data bits, even parity, 2 stop bits, RTS and XON/XOFF.
  EXPECT_EQ(m.serial->port, "/dev/ttyS1");
  EXPECT_EQ(m.serial->baud, 9600);
  EXPECT_EQ(m.serial->data_bits, 7);
  EXPECT_EQ(m.serial->parity, models::Parity::kEven);
  EXPECT_EQ(m.serial->stop_bits, 2);
  EXPECT_TRUE(m.serial->rts_cts);
  EXPECT_TRUE(m.serial->xon_xoff);

  const std::string val2 = with(
      base_yaml(), "    home: [0, 84, -192, 0, -72, 90]\n",
      "    home: [0, 84, -192, 0, -72, 90]\n    driver: val2\n"
      "    serial: {port: /dev/ttyS0, baud: 19200, data_bits: 8, parity: none, stop_bits: 1, handshake: rtscts}\n");
  const models::CellDescription pcell = parse(val2);
  const models::RobotSpec& p = *pcell.find_robot("puma");
  EXPECT_EQ(p.driver, models::DriverKind::kVal2);
  EXPECT_EQ(p.serial->baud, 19200);
  EXPECT_EQ(p.serial->parity, models::Parity::kNone);
  EXPECT_TRUE(p.serial->rts_cts);
  EXPECT_FALSE(p.serial->xon_xoff);
}

TEST(Cell, ControllerConventionsAreSettingsWithThePagesDefaults) {
  // Left out: the defaults are today's conventions (docs/real-robots.md), so existing cells do not change.
  const models::CellDescription plain = parse(base_yaml());
  const models::RobotSpec& d = *plain.find_robot("puma");
  EXPECT_EQ(d.val2.orientation, models::Val2Conventions::Orientation::kToolDown);
  EXPECT_EQ(d.val2.line_end, models::LineEnd::kCr);
  EXPECT_EQ(d.val2.prompt, ".");
  EXPECT_EQ(d.val2.where, models::Val2Conventions::WhereLayout::kVal2);
  EXPECT_EQ(d.val2.echo, models::Val2Conventions::Echo::kMaybe);
  EXPECT_EQ(d.movemaster.line_end, models::LineEnd::kCrLf);
  EXPECT_EQ(d.movemaster.completion, models::MovemasterConventions::Completion::kEr);
  EXPECT_EQ(d.movemaster.ms_open_letter, 'O');

  const std::string text =
      with(with(base_yaml(), "    home: [0, 84, -192, 0, -72, 90]\n",
                "    home: [0, 84, -192, 0, -72, 90]\n"
                "    val2: {orientation: zyz, line_end: crlf, prompt: '>', where: as, echo: never}\n"),
           "    home: [0, 30, 60, 0, 60, 0]\n",
           "    home: [0, 30, 60, 0, 60, 0]\n    movemaster: {line_end: cr, completion: poll, ms_open_letter: C}\n");
  const models::CellDescription cell = parse(text);
  const models::RobotSpec& p = *cell.find_robot("puma");
  EXPECT_EQ(p.val2.orientation, models::Val2Conventions::Orientation::kZyz);
  EXPECT_EQ(p.val2.line_end, models::LineEnd::kCrLf);
  EXPECT_EQ(p.val2.prompt, ">");
  EXPECT_EQ(p.val2.where, models::Val2Conventions::WhereLayout::kAsTwoBlock);
  EXPECT_EQ(p.val2.echo, models::Val2Conventions::Echo::kNever);
  const models::RobotSpec& m = *cell.find_robot("melfa");
  EXPECT_EQ(m.movemaster.line_end, models::LineEnd::kCr);
  EXPECT_EQ(m.movemaster.completion, models::MovemasterConventions::Completion::kPoll);
  // Left out, the frames are the page's: the controller's world is the base link, its tool point the TCP.
  EXPECT_TRUE(p.val2.frames.world.matrix().isIdentity(0)) << p.val2.frames.world.matrix();
  EXPECT_TRUE(m.movemaster.frames.tool.matrix().isIdentity(0));
  EXPECT_EQ(m.movemaster.pitch_down_deg, -90);
  EXPECT_EQ(m.movemaster.roll_sense, 1);
  EXPECT_EQ(m.movemaster.ms_open_letter, 'C');
}

// The frames and readings of docs/real-robots.md's "Commissioning": mm and degrees in the file, metres and a
// rotation (R = Rz(yaw)·Ry(pitch)·Rx(roll)) here.
TEST(Cell, ControllerFramesAndReadingsAreRead) {
  const std::string text =
      with(with(base_yaml(), "    home: [0, 84, -192, 0, -72, 90]\n",
                "    home: [0, 84, -192, 0, -72, 90]\n"
                "    val2: {orientation: val, world_offset: [0, 0, 671.83], world_rotation: [0, 0, 90], "
                "tool_offset: [0, 0, -146]}\n"),
           "    home: [0, 30, 60, 0, 60, 0]\n",
           "    home: [0, 30, 60, 0, 60, 0]\n    movemaster: {pitch_down: 90, roll: left_hand, "
           "tool_rotation: [180, 0, 0]}\n");
  const models::CellDescription cell = parse(text);
  const models::RobotSpec& p = *cell.find_robot("puma");
  EXPECT_EQ(p.val2.orientation, models::Val2Conventions::Orientation::kVal);
  EXPECT_TRUE(p.val2.frames.world.translation().isApprox(Eigen::Vector3d(0, 0, 0.67183), 1e-12));
  EXPECT_TRUE(p.val2.frames.world.linear().col(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));  // yaw 90
  EXPECT_TRUE(p.val2.frames.tool.translation().isApprox(Eigen::Vector3d(0, 0, -0.146), 1e-12));
  const models::RobotSpec& m = *cell.find_robot("melfa");
  EXPECT_EQ(m.movemaster.pitch_down_deg, 90);
  EXPECT_EQ(m.movemaster.roll_sense, -1);
  EXPECT_TRUE(m.movemaster.frames.tool.linear().col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));  // roll 180
}

TEST(CellErrors, BadControllerConventionsNameTheLine) {
  const std::string anchor = "    home: [0, 84, -192, 0, -72, 90]\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"    val2: {line_end: crcr}\n", "must be cr, crlf or lf, got 'crcr'"},
      {"    val2: {orientation: xyz}\n", "must be tool_down, zyz or val, got 'xyz'"},
      {"    val2: {world_offset: [0, 660]}\n", "world_offset"},
      {"    val2: {world_offset: [0, 0, 66000]}\n", "world_offset"},
      {"    val2: {world_rotation: [0, 0, 400]}\n", "world_rotation"},
      {"    val2: {tool_offset: [0, 0, x]}\n", "tool_offset"},
      {"    val2: {tool_rotation: 90}\n", "tool_rotation"},
      {"    val2: {pitch_down: 90}\n", "pitch_down"},
      {"    movemaster: {pitch_down: 45}\n", "must be -90 (the page's: p = -90 points the hand straight down) or 90, got 45"},
      {"    movemaster: {roll: sideways}\n", "must be right_hand or left_hand, got 'sideways'"},
      {"    movemaster: {world_offset: [0, 0, .nan]}\n", "world_offset"},
      {"    val2: {where: kawasaki}\n", "must be val2 or as, got 'kawasaki'"},
      {"    val2: {echo: sometimes}\n", "must be maybe, always or never, got 'sometimes'"},
      {"    val2: {prompt: '. '}\n", "must be printable characters without spaces"},
      {"    val2: {baud: 9600}\n", "baud"},
      {"    movemaster: {completion: wh}\n", "must be er or poll, got 'wh'"},
      {"    movemaster: {ms_open_letter: X}\n", "must be O or C, got 'X'"},
  };
  for (const auto& [entry, fragment] : cases) {
    const std::string text = with(base_yaml(), anchor, anchor + entry);
    expect_error(text, fragment, line_of(text, entry.substr(0, entry.size() - 1)));
  }
}

TEST(CellErrors, MissingFile) {
  try {
    models::load_cell("/nonexistent/cell.yaml");
    FAIL() << "accepted a missing file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "/nonexistent/cell.yaml");
    EXPECT_EQ(e.problem(), "cannot read the cell description: no such file");
  }
}

// A folder given as the cell file, or as a robot's URDF, is called a folder, not a missing file.
TEST(CellErrors, AFolderIsCalledAFolderNotAMissingFile) {
  const std::string dir = std::filesystem::temp_directory_path().string();
  try {
    models::load_cell(dir);
    FAIL() << "accepted a folder";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, dir);
    EXPECT_EQ(e.problem(), "cannot read the cell description: is a directory, not a file");
  }
  const std::string text = with(base_yaml(), urdf("melfa_rve2.urdf"), dir);
  // The whole line: the other robot's URDF may lie under the temporary folder too (a clone in /tmp).
  expect_error(text, fmt::format("URDF file '{}' is a directory, not a file", dir),
               line_of(text, "urdf: " + dir + "\n"));
}

// The cell's own name follows the rule of every other name: it becomes the MJCF model's name and goes on the report
// page. Shown in the error cut to 64 characters, its bytes that are not printable ASCII escaped.
TEST(CellErrors, TheCellsNameFollowsTheNameRule) {
  const std::string long_name = with(base_yaml(), "name: test-cell", "name: " + std::string(100000, 'x'));
  const InputError e = error_of(long_name);
  EXPECT_THAT(e.problem(), HasSubstr("the cell's name 'xxxx"));
  EXPECT_THAT(e.problem(), HasSubstr("... (100000 characters)' is not valid"));
  EXPECT_LT(e.problem().size(), 300u);
  EXPECT_EQ(e.where().line, 1);
  const std::string markup = with(base_yaml(), "name: test-cell", "name: \"</mujoco><x a='1'>\"");
  expect_error(markup, "the cell's name '</mujoco><x a='1'>' is not valid", line_of(markup, "</mujoco>"));
  const std::string latin1 = with(base_yaml(), "name: test-cell", "name: caf\xe9");
  const InputError bytes = error_of(latin1);
  EXPECT_THAT(bytes.problem(), HasSubstr("the cell's name 'caf\\xe9' is not valid"));
  EXPECT_EQ(parse(base_yaml()).name, "test-cell");
}

TEST(CellErrors, NotYaml) {
  const std::string text = with(base_yaml(), "    length: 1.2\n", "    length: [1.2\n");
  const InputError e = error_of(text);
  EXPECT_THAT(e.what(), HasSubstr("not valid YAML"));
  EXPECT_GE(e.where().line, line_of(text, "length: [1.2"));
}

TEST(CellErrors, UnknownRobotModel) {
  const std::string text = with(base_yaml(), "melfa_rve2.urdf", "melfa_rv99.urdf");
  expect_error(text, "unknown robot model for robot 'melfa': URDF file", line_of(text, "melfa_rv99"));
}

TEST(CellErrors, UnusableUrdf) {
  // A URDF without the `tcp` link: the error points at the robot's `urdf` field and repeats the URDF's problem.
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "cellwright_cell_test";
  std::filesystem::create_directories(dir);
  std::ifstream in(urdf("melfa_rve2.urdf"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (auto pos = text.find("\"tcp\""); pos != std::string::npos; pos = text.find("\"tcp\"", pos)) {
    text.replace(pos, 5, "\"tool\"");
  }
  std::ofstream(dir / "no_tcp.urdf") << text;
  const std::string yaml = with(base_yaml(), urdf("melfa_rve2.urdf"), (dir / "no_tcp.urdf").string());
  expect_error(yaml, "robot 'melfa': its URDF cannot be used: " + (dir / "no_tcp.urdf").string(),
               line_of(yaml, "no_tcp.urdf"));
  std::filesystem::remove_all(dir);
}

TEST(CellErrors, WrongType) {
  const std::string text = with(base_yaml(), "length: 1.2", "length: long");
  expect_error(text, "field 'length' of conveyor 'belt' must be a number, got 'long'", line_of(text, "length: long"));
}

// A part-present sensor: at a stop bar, on one of the cell's 16 signals, each conveyor its own.
TEST(CellErrors, SensorWiring) {
  const std::string stop = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    stop: true\n");
  const std::string good = with(stop, "    stop: true\n", "    stop: true\n    sensor: {signal: 9}\n");
  EXPECT_EQ(parse(good).find_conveyor("belt")->sensor, 9);
  EXPECT_EQ(parse(stop).find_conveyor("belt")->sensor, 0);

  const std::string no_stop = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    sensor: {signal: 9}\n");
  expect_error(no_stop, "conveyor 'belt': a part-present sensor sits at the stop bar; set 'stop: true'",
               line_of(no_stop, "sensor:"));
  for (const char* bad : {"17", "0", "2.5", "x"}) {
    const std::string text = with(good, "signal: 9", fmt::format("signal: {}", bad));
    expect_error(text, "of the sensor of conveyor 'belt'", line_of(text, "sensor:"));
  }
  const std::string range = with(good, "signal: 9", "signal: 17");
  expect_error(range, "must be a whole number 1..16 (the cell's digital signals), got 17", line_of(range, "sensor:"));
  const std::string field = with(good, "signal: 9", "channel: 9");
  expect_error(field, "unknown field 'channel' in the sensor of conveyor 'belt'", line_of(field, "sensor:"));
  const std::string shared = with(good, "machines:\n",
                                  "  - name: belt2\n    pose: {xyz: [-0.5, 0.55, 0], yaw: 0}\n    length: 1.2\n"
                                  "    width: 0.2\n    height: 0.5\n    speed: 0.05\n    stop: true\n"
                                  "    sensor: {signal: 9}\nmachines:\n");
  expect_error(shared, "conveyor 'belt2': signal 9 is already the sensor of conveyor 'belt' (line",
               line_of(shared, "sensor: {signal: 9}\nmachines"));
}

// A belt's drive on a robot controllers' output (`run_signal`, issue 26): one of the 16 signals, a wire of its own.
TEST(CellErrors, RunSignalWiring) {
  const std::string stop = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    stop: true\n");
  const std::string good = with(stop, "    stop: true\n", "    stop: true\n    sensor: {signal: 9}\n    run_signal: 8\n");
  EXPECT_EQ(parse(good).find_conveyor("belt")->run_signal, 8);
  EXPECT_EQ(parse(stop).find_conveyor("belt")->run_signal, 0);
  const std::string range = with(good, "run_signal: 8", "run_signal: 17");
  expect_error(range, "field 'run_signal' of conveyor 'belt' must be a whole number 1..16 (the cell's digital "
               "signals), got 17", line_of(range, "run_signal"));
  const std::string on_sensor = with(good, "run_signal: 8", "run_signal: 9");
  expect_error(on_sensor, "conveyor 'belt': signal 9 is the sensor of conveyor 'belt' (line",
               line_of(on_sensor, "run_signal"));
  const std::string belt2 = "  - name: belt2\n    pose: {xyz: [-0.5, 0.55, 0], yaw: 0}\n    length: 1.2\n"
                            "    width: 0.2\n    height: 0.5\n    speed: 0.05\n    stop: true\n";
  const std::string shared = with(good, "machines:\n", belt2 + "    run_signal: 8\nmachines:\n");
  expect_error(shared, "conveyor 'belt2': signal 8 is already the run_signal of conveyor 'belt' (line",
               line_of(shared, "run_signal: 8\nmachines"));
  const std::string sensor_on_run = with(good, "machines:\n", belt2 + "    sensor: {signal: 8}\nmachines:\n");
  expect_error(sensor_on_run, "conveyor 'belt2': signal 8 is already the run_signal of conveyor 'belt' (line",
               line_of(sensor_on_run, "sensor: {signal: 8}"));
}

// Devices on the cell's I/O unit: addresses 0..65535, each signal its own, photo-eyes named in the one name space.
TEST(CellErrors, IoWiring) {
  const std::string stop = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    stop: true\n");
  const std::string good = with(with(stop, "    stop: true\n", "    stop: true\n    sensor: {io: 0}\n    io: {run: 0}\n"),
                                "    process_time: 5\n",
                                "    process_time: 5\n    io: {start: 1, busy: 1, done: 2}\n");
  const models::CellDescription cell = parse(good);
  const models::ConveyorSpec& belt = *cell.find_conveyor("belt");
  EXPECT_EQ(belt.stop_eye_name, "belt_stop");
  EXPECT_EQ(belt.stop_eye_io.address, 0);
  EXPECT_EQ(belt.sensor, 0);  // on the I/O unit, not on the robots' inputs
  EXPECT_TRUE(belt.accumulate);
  EXPECT_EQ(cell.machines[0].start_io.address, 1);
  EXPECT_EQ(cell.machines[0].done_io.address, 2);
  EXPECT_FALSE(parse(stop).find_conveyor("belt")->accumulate);

  for (const char* bad : {"-1", "65536", "2.5", "x"}) {
    const std::string text = with(good, "io: {run: 0}", fmt::format("io: {{run: {}}}", bad));
    expect_error(text, "of the io of conveyor 'belt'", line_of(text, "io: {run"));
  }
  const std::string coil = with(good, "start: 1", "start: 0");
  expect_error(coil,
               "coil 0 is wired to the start of machine 'mill' and already to the run of conveyor 'belt' (line " +
                   std::to_string(line_of(coil, "io: {run")) + ")",
               line_of(coil, "io: {start"));
  const std::string input = with(good, "busy: 1", "busy: 0");
  expect_error(input, "discrete input 0 is wired to the busy signal of machine 'mill' and already to sensor "
                      "'belt_stop'",
               line_of(input, "io: {start"));
  const std::string clash = with(good, "sensor: {io: 0}", "sensor: {io: 0, name: mill}");
  expect_error(clash, "duplicate name 'mill': already used for the sensor on line", line_of(clash, "- name: mill"));
  const std::string field = with(good, "io: {run: 0}", "io: {stop: 0}");
  expect_error(field, "unknown field 'stop' in the io of conveyor 'belt'", line_of(field, "io: {stop"));
  const std::string no_eye = with(stop, "    stop: true\n", "    stop: true\n    accumulate: true\n");
  expect_error(no_eye, "conveyor 'belt' accumulates while a part blocks the photo-eye at its stop bar, and has none",
               line_of(no_eye, "accumulate"));
  const std::string colour = with(good, "    process_time: 5\n", "    process_time: 5\n    processed_colour: [2, 0, 0]\n");
  expect_error(colour, "field 'processed_colour' of machine 'mill' must have values 0..1, got 2",
               line_of(colour, "processed_colour"));
}

// Side guides: their height above the belt, none by default; a height out of 0..0.2 m is refused at its line.
TEST(CellErrors, ConveyorGuides) {
  EXPECT_EQ(parse(base_yaml()).find_conveyor("belt")->guides, 0.0);
  const std::string guided = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    guides: 0.03\n");
  EXPECT_DOUBLE_EQ(parse(guided).find_conveyor("belt")->guides, 0.03);
  const std::string high = with(guided, "guides: 0.03", "guides: 0.5");
  expect_error(high, "is the guides' height above the belt, 0..0.2 m, got 0.5", line_of(high, "guides:"));
  const std::string negative = with(guided, "guides: 0.03", "guides: -0.01");
  expect_error(negative, "guides", line_of(negative, "guides:"));
}

TEST(CellErrors, NegativeSize) {
  const std::string text = with(base_yaml(), "size: [0.04, 0.04, 0.06]", "size: [0.04, -0.04, 0.06]");
  expect_error(text, "field 'size' of workpiece 'A' must be greater than 0", line_of(text, "size: [0.04, -0.04"));
}

TEST(CellErrors, BadColour) {
  const std::string text = with(base_yaml(), "colour: [0.9, 0.1, 0.1]", "colour: [1.5, 0.1, 0.1]");
  expect_error(text, "field 'colour' of workpiece 'A' must have values 0..1, got 1.5", line_of(text, "colour: [1.5"));
  const std::string two = with(base_yaml(), "colour: [0.9, 0.1, 0.1]", "colour: [0.9, 0.1]");
  expect_error(two, "must be [r, g, b] or [r, g, b, a]", line_of(two, "colour: [0.9, 0.1]"));
}

TEST(CellErrors, UnknownField) {
  const std::string text = with(base_yaml(), "colour:", "color:");
  expect_error(text, "unknown field 'color' in workpiece 'A' (expected one of:", line_of(text, "color:"));
}

TEST(CellErrors, MissingField) {
  const std::string text = with(base_yaml(), "    speed: 0.05\n", "");
  expect_error(text, "conveyor 'belt' has no field 'speed'", line_of(text, "- name: belt"));
}

TEST(CellErrors, FieldGivenTwice) {
  const std::string text = with(base_yaml(), "    mass: 0.1\n", "    mass: 0.1\n    mass: 0.2\n");
  expect_error(text, "field 'mass' of workpiece 'A' is given twice", line_of(text, "mass: 0.2"));
}

TEST(CellErrors, UnknownReferences) {
  const std::string on = with(base_yaml(), "on: belt", "on: tray");
  expect_error(on, "unknown reference 'tray' in workpiece 'A'", line_of(on, "on: tray"));
  const std::string at = with(base_yaml(), "at: belt.leave", "at: lathe.fixture");
  expect_error(at, "unknown reference 'lathe.fixture' in location 'pick'", line_of(at, "at: lathe"));
  const std::string point = with(base_yaml(), "at: belt.leave", "at: belt.middle");
  expect_error(point, "a conveyor point is 'belt.enter' or 'belt.leave'", line_of(point, "at: belt.middle"));
  const std::string reach = with(base_yaml(), "reach: [puma]", "reach: [puma, kuka]");
  expect_error(reach, "unknown robot 'kuka' in the 'reach' of location 'pick' (robots: puma, melfa)",
               line_of(reach, "reach: [puma, kuka]"));
  const std::string grasp = with(base_yaml(), "{robot: melfa,", "{robot: kuka,");
  expect_error(grasp, "unknown robot 'kuka' in the hand-over", line_of(grasp, "{robot: kuka"));
}

TEST(CellErrors, DuplicateName) {
  const std::string text = with(base_yaml(), "  - name: pick\n", "  - name: A\n");
  expect_error(text,
               fmt::format("duplicate name 'A': already used for the location on line {}",
                           line_of(text, "  - name: A\n    at:")),
               line_of(text, "  - name: A\n    shape:"));
}

TEST(CellErrors, LocationOutOfReach) {
  // The PUMA moved 3 m away from the belt end it must reach.
  const std::string text = with(base_yaml(), "base: {xyz: [0, 0, 0], yaw: 0}", "base: {xyz: [3, 0, 0], yaw: 0}");
  const InputError e = error_of(text);
  EXPECT_THAT(e.what(), HasSubstr("location 'pick' (grasp) is out of reach of robot 'puma'"));
  EXPECT_THAT(e.what(), HasSubstr("beyond its maximum reach of 1.161 m"));
  EXPECT_EQ(e.where().line, line_of(text, "- name: pick"));
}

TEST(CellErrors, LocationWithinReachButNotWithTheGripperDown) {
  // Half a metre straight above the MELFA's shoulder: within its reach, but not with the gripper pointing down.
  const std::string text = with(
      base_yaml(), "workpieces:", "  - name: high\n    pose: {xyz: [0.95, 0, 1.0]}\n    reach: [melfa]\nworkpieces:");
  const InputError e = error_of(text);
  EXPECT_THAT(e.what(), HasSubstr("location 'high' (grasp) is out of reach of robot 'melfa'"));
  EXPECT_THAT(e.what(), HasSubstr("but no joint configuration within the limits puts the gripper there"));
  EXPECT_EQ(e.where().line, line_of(text, "- name: high"));
}

TEST(CellErrors, HandoverOutOfReach) {
  // Raised to 0.9 m: the PUMA still reaches it from above, the MELFA cannot hold it from the side.
  const std::string text =
      with(base_yaml(), "pose: {xyz: [0.5, 0, 0.55], yaw: 90}", "pose: {xyz: [0.5, 0, 0.9], yaw: 90}");
  const InputError e = error_of(text);
  EXPECT_THAT(e.what(), HasSubstr("the hand-over 'handover' is out of reach of robot 'melfa'"));
  EXPECT_THAT(e.what(), HasSubstr("maximum reach 0.572 m"));
  EXPECT_EQ(e.where().line, line_of(text, "pose: {xyz: [0.5, 0, 0.9]"));
}

TEST(CellErrors, HomeDoesNotFitTheRobot) {
  const std::string count = with(base_yaml(), "home: [0, 30, 60, 0, 60, 0]", "home: [0, 30, 60, 0, 60]");
  expect_error(count, "robot 'melfa': 'home' has 5 angles but melfa_rve2.urdf has 6 joints",
               line_of(count, "home: [0, 30, 60, 0, 60]"));
  const std::string limit = with(base_yaml(), "home: [0, 30, 60, 0, 60, 0]", "home: [0, 30, 60, 0, 60, 250]");
  expect_error(limit, "home angle of joint6 is 250.00 deg, outside its limits -200.00..200.00 deg",
               line_of(limit, "home: [0, 30, 60, 0, 60, 250]"));
}

TEST(Cell, AParkPoseIsKeptAndChecked) {
  // Where the task language's `park` sends a robot: optional, checked like home.
  const std::string park = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                "    home: [0, 30, 60, 0, 60, 0]\n    park: [90, 30, 60, 0, 60, 0]\n");
  const models::CellDescription cell = parse(park);
  ASSERT_EQ(cell.find_robot("melfa")->park.size(), 6u);
  EXPECT_NEAR(cell.find_robot("melfa")->park[0], std::numbers::pi / 2, 1e-12);
  EXPECT_TRUE(cell.find_robot("puma")->park.empty());
  const std::string count = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                 "    home: [0, 30, 60, 0, 60, 0]\n    park: [90, 30]\n");
  expect_error(count, "robot 'melfa': 'park' has 2 angles but melfa_rve2.urdf has 6 joints",
               line_of(count, "park: [90, 30]"));
  const std::string limit = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                 "    home: [0, 30, 60, 0, 60, 0]\n    park: [0, 30, 60, 0, 60, 250]\n");
  expect_error(limit, "park angle of joint6 is 250.00 deg, outside its limits -200.00..200.00 deg",
               line_of(limit, "park: [0, 30, 60, 0, 60, 250]"));
}

TEST(CellErrors, DriversNeedTheirSettings) {
  const std::string none = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                "    home: [0, 30, 60, 0, 60, 0]\n    driver: movemaster\n");
  expect_error(none, "robot 'melfa' uses the movemaster driver and needs 'serial' settings",
               line_of(none, "- name: melfa"));
  const std::string val2 = with(base_yaml(), "    home: [0, 84, -192, 0, -72, 90]\n",
                                "    home: [0, 84, -192, 0, -72, 90]\n    driver: val2\n"
                                "    serial: {port: /dev/ttyS0}\n");
  expect_error(val2, "lack 'baud': no default is documented for VAL II controllers", line_of(val2, "serial: {port"));
  const std::string parity = with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n",
                                  "    home: [0, 30, 60, 0, 60, 0]\n    driver: movemaster\n"
                                  "    serial: {port: /dev/ttyS1, parity: mark}\n");
  expect_error(parity, "must be none, even or odd, got 'mark'", line_of(parity, "serial: {port"));
  const std::string kind =
      with(base_yaml(), "    home: [0, 30, 60, 0, 60, 0]\n", "    home: [0, 30, 60, 0, 60, 0]\n    driver: kuka\n");
  expect_error(kind, "must be sim, movemaster or val2, got 'kuka'", line_of(kind, "driver: kuka"));
}

TEST(CellErrors, PartsThatDoNotFitOnTheBelt) {
  std::string text = base_yaml();
  for (int i = 0; i < 20; ++i) {
    text += fmt::format(
        "  - {{name: P{}, shape: box, size: [0.04, 0.04, 0.04], mass: 0.1, colour: [0, 1, 0], on: "
        "belt}}\n",
        i);
  }
  text = with(text,
              "cameras:\n  - name: top\n    position: [0, 0, 2.5]\n    look_at: [0, 0, 0]\n"
              "    resolution: [320, 240]\n    fovy: 60\n",
              "");
  text += "cameras: []\n";
  expect_error(text, "the 21 parts put on conveyor 'belt' do not fit on it", line_of(text, "name: P19,"));
}

TEST(CellErrors, OutOfRangeValues) {
  const std::string speed = with(base_yaml(), "speed: 0.05", "speed: -0.05");
  expect_error(speed, "field 'speed' of conveyor 'belt' must be within 0..2 m/s", line_of(speed, "speed: -0.05"));
  const std::string fovy = with(base_yaml(), "fovy: 60", "fovy: 200");
  expect_error(fovy, "between 0 and 180 degrees", line_of(fovy, "fovy: 200"));
  const std::string res = with(base_yaml(), "resolution: [320, 240]", "resolution: [320.5, 240]");
  expect_error(res, "whole numbers of pixels", line_of(res, "resolution: [320.5"));
  const std::string leave = with(base_yaml(), "    speed: 0.05\n", "    speed: 0.05\n    enter: 0.5\n    leave: 0.4\n");
  expect_error(leave, "must leave downstream of that", line_of(leave, "leave: 0.4"));
  const std::string shape = with(base_yaml(), "shape: box", "shape: sphere");
  expect_error(shape, "must be box or cylinder, got 'sphere'", line_of(shape, "shape: sphere"));
  const std::string name = with(base_yaml(), "- name: A\n", "- name: 'A B'\n");
  expect_error(name, "workpiece name 'A B' is not valid", line_of(name, "'A B'"));
}

// Seeded garbage in: the shipped cell with random edits (YAML's punctuation, digits, cut lines) is read and its reach
// checked, or refused with an InputError naming the file; nothing else escapes, nothing crashes or hangs.
TEST(CellGarbageIn, MutatedCellsAreReadOrRefusedWithAnInputError) {
  const std::filesystem::path source = kSource / "scenes" / "mutant.yaml";
  const auto counts = cellwright::testing::feed_garbage(
      {cellwright::testing::slurp_text(kSource / "scenes" / "cell.yaml")}, 300, 20261124,
      ":-[]{},#&*!|>'\"%@`? \n\t0123456789abcxyz.eE", source.string(), [&](const std::string& text) {
        const models::CellDescription cell = models::parse_cell(text, source);
        (void)models::check_reach(cell);
      });
  // Both outcomes occur: the edits reach past the YAML parser into the checks.
  EXPECT_GT(counts.accepted, 10);
  EXPECT_GT(counts.refused, 100);
}

// Values no real cell has are refused with the field, its value and the bound, at the value's line: the numbers
// would otherwise reach the physics (a 1e300 m conveyor, a workpiece of 0.000001 g) or the clock.
TEST(CellErrors, ImpossibleValuesNameFieldValueAndBound) {
  struct Case {
    const char* from;
    const char* to;
    const char* fragment;
  };
  const Case cases[] = {
      {"length: 1.2", "length: 0", "field 'length' of conveyor 'belt' must be within 0.001..100 m, got 0"},
      {"width: 0.2", "width: -0.2", "field 'width' of conveyor 'belt' must be within 0.001..100 m, got -0.2"},
      {"height: 0.5", "height: 1e300", "field 'height' of conveyor 'belt' must be within 0.001..100 m, got 1e300"},
      {"mass: 0.1", "mass: 0", "field 'mass' of workpiece 'A' must be within 0.001..1000 kg, got 0"},
      {"mass: 0.1", "mass: -1", "field 'mass' of workpiece 'A' must be within 0.001..1000 kg, got -1"},
      {"mass: 0.1", "mass: 5e4", "field 'mass' of workpiece 'A' must be within 0.001..1000 kg, got 5e4"},
      {"mass: 0.1", "mass: .nan", "field 'mass' of workpiece 'A' must be a finite number, got .nan"},
      {"size: [0.04, 0.04, 0.06]", "size: [0.04, 0.04, 60]", "field 'size' of workpiece 'A' must be within 0.001..5 m"},
      {"size: [0.4, 0.35, 0.4]", "size: [0.4, 0.35, 400]", "field 'size' of machine 'mill' must be within 0.001..100 m"},
      {"process_time: 5", "process_time: -5",
       "field 'process_time' of machine 'mill' must be within 0..86400 s, got -5"},
      {"process_time: 5", "process_time: .inf", "field 'process_time' of machine 'mill' must be a finite number"},
      {"xyz: [0.05, 0.6, 0], yaw: 0", "xyz: [0.05, 0.6, 0], yaw: 1e9",
       "field 'yaw' of field 'pose' of machine 'mill' must be within -360..360 degrees, got 1e9"},
      {"xyz: [0.05, 0.6, 0], yaw: 0", "xyz: [5e3, 0.6, 0], yaw: 0",
       "field 'xyz' of field 'pose' of machine 'mill' must be within -100..100 m, got 5e3"},
      {"offset: [0, 0, 0.02]", "offset: [0, 0, 20]",
       "field 'offset' of a hand-over grasp must be within -2..2 m, got 20"},
      {"    reach: [puma]\n", "    reach: [puma]\n    grasp_height: 30\n",
       "field 'grasp_height' of location 'pick' must be within 0..2 m, got 30"},
      {"position: [0, 0, 2.5]", "position: [0, 0, 2500]",
       "field 'position' of camera 'top' must be within -100..100 m, got 2500"},
  };
  for (const Case& c : cases) {
    const std::string text = with(base_yaml(), c.from, c.to);
    // The line of the changed value: the last line of the replacement.
    std::string to = c.to;
    if (to.back() == '\n') to.pop_back();
    to = to.substr(to.rfind('\n') + 1);
    expect_error(text, c.fragment, line_of(text, to.substr(to.find_first_not_of(' '))));
  }
}

TEST(CellErrors, WorkpieceBelowTheFloor) {
  // Its centre above the floor, its bottom 2 cm into it.
  const std::string text = with(base_yaml(), "on: belt", "pose: {xyz: [1, 1, 0.01]}");
  expect_error(text, "workpiece 'A' reaches below the floor: its centre is at z = 0.01 m and its lowest point at "
               "z = -0.0200 m",
               line_of(text, "pose: {xyz: [1, 1, 0.01]}"));
}

// Bodies that start inside one another: refused naming both, at the line of the one listed later.
TEST(CellErrors, BodiesOverlappingAtTheStart) {
  // A part inside the machine's body (the machine at (0.05, 0.6), 0.4 x 0.35 x 0.4 m).
  const std::string inside = with(base_yaml(), "on: belt", "pose: {xyz: [0.05, 0.6, 0.2]}");
  const InputError e = error_of(inside);
  EXPECT_THAT(e.what(), HasSubstr("workpiece 'A' overlaps machine 'mill' (line 19) by 195.0 mm at the start"));
  EXPECT_EQ(e.where().file, "case.yaml");
  EXPECT_EQ(e.where().line, line_of(inside, "- name: A"));
  // A cylinder beside the machine's corner: its bounding box would cut the corner, the cylinder does not.
  const std::string corner =
      with(with(base_yaml(), "on: belt", "pose: {xyz: [0.265, 0.41, 0.03]}"), "shape: box\n    size: [0.04, 0.04, 0.06]",
           "shape: cylinder\n    size: [0.04, 0.06]");
  EXPECT_NO_THROW(parse(corner));
  // Two parts on one spot.
  const std::string twice =
      with(base_yaml(), "cameras:", "  - {name: B, shape: box, size: [0.04, 0.04, 0.06], mass: 0.1, colour: [0.1, "
                                    "0.1, 0.9], pose: {xyz: [1, 1, 0.03]}}\n  - {name: C, shape: box, size: [0.04, "
                                    "0.04, 0.06], mass: 0.1, colour: [0.1, 0.9, 0.1], pose: {xyz: [1.02, 1, 0.03]}}\n"
                                    "cameras:");
  expect_error(twice, "workpiece 'C' overlaps workpiece 'B'", line_of(twice, "name: C"));
  // A machine standing over the conveyor (the conveyor's listed first: the machine is the one put there).
  const std::string machine = with(base_yaml(), "xyz: [0.05, 0.6, 0], yaw: 0", "xyz: [-0.5, -0.55, 0], yaw: 0");
  expect_error(machine, "machine 'mill' overlaps conveyor 'belt' (line 12)", line_of(machine, "- name: mill"));
  // A part in the robot's pedestal (the MELFA stands on a 0.25 m one at (0.95, 0)).
  const std::string pedestal = with(base_yaml(), "on: belt", "pose: {xyz: [0.95, 0.1, 0.1]}");
  expect_error(pedestal, "workpiece 'A' overlaps the pedestal of robot 'melfa' (line 7)", line_of(pedestal, "- name: A"));
  // Resting on the belt, on the fixture, on the floor beside the machine: touching is not overlapping.
  const std::string touching =
      with(base_yaml(), "on: belt", "pose: {xyz: [0.27, 0.6, 0.03]}");  // against the machine's +x face (0.25)
  EXPECT_NO_THROW(parse(touching));
}

TEST(CellErrors, RobotNamesThatWouldCollideInTheScene) {
  const std::string text = with(base_yaml(), "- name: melfa", "- name: workpiece");
  expect_error(text, "robot name 'workpiece' is reserved", line_of(text, "name: workpiece"));
}

// A file saved by an editor that starts it with a UTF-8 byte-order mark reads as the same cell.
TEST(Cell, ByteOrderMarkIsAccepted) {
  const models::CellDescription cell = parse("\xEF\xBB\xBF" + base_yaml());
  EXPECT_EQ(cell.name, "test-cell");
  ASSERT_EQ(cell.workpieces.size(), 1u);
  // Positions in errors still count lines from the first.
  const std::string bad = with(base_yaml(), "speed: 0.05", "speed: -0.05");
  const InputError e = error_of("\xEF\xBB\xBF" + bad);
  EXPECT_EQ(e.where().line, line_of(bad, "speed: -0.05"));
}

}  // namespace
}  // namespace cellwright::twin
