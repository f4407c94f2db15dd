// The post-processors: a small program's exact text in both languages, the same bytes every time, poses that read
// back (with the doc's conventions, written again here) to the tool poses the motion plan gives, and the refusals.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/robot_programs.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include "cellwright/common/files.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/cell/estimate.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using cell::Scenario;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";
constexpr double kDeg = std::numbers::pi / 180;

class RobotProgramsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("robot_programs_test_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A scenario on the repository's cell (or `cell`) running `program` (written as prog.task), r1 the PUMA on VAL II
  // and r2 the MELFA on the Movemaster.
  Scenario load(const std::string& program, const std::string& extra = "",
                const std::string& cell = kScenes + "/cell.yaml") {
    std::ofstream(dir_ / "prog.task") << program;
    std::ofstream(dir_ / "s.yaml") << fmt::format(
        "cell: {}\nprogram: prog.task\nrobots: {{r1: puma, r2: "
        "melfa}}\n{}",
        cell, extra);
    Scenario s = cell::load_scenario(dir_ / "s.yaml");
    set_language(s, "puma=val2", {"test", 0, 0});
    set_language(s, "melfa=movemaster", {"test", 0, 0});
    return s;
  }

  // Expects generate_robot_programs to refuse with `text`, at `file`:`line` (the preflight without the collision
  // sweep when `sweep` is false, as `twin compile` in a build without the simulator).
  void expect_refused(const Scenario& s, const std::string& file, int line, const std::string& text,
                      bool sweep = true) {
    try {
      generate_robot_programs(s, sweep ? cell::preflight(s, &twin_port()) : cell::preflight(s, nullptr));
      ADD_FAILURE() << "not refused; expected: " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(fs::path(e.where().file).filename().string(), file) << e.what();
      EXPECT_EQ(e.where().line, line) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  }

  fs::path dir_;
};

// r1 picks A off the input conveyor (the conveyor's stop: the cell's input_pick), then tells r2, which waits for it.
constexpr const char* kSmall = R"(robot r1 r2
workpiece A
semaphore go
sequence r1
  Pick A
  signal go
end
sequence r2
  wait go
end
)";

TEST_F(RobotProgramsTest, SmallProgramExactText) {
  const Scenario s = load(kSmall);
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  ASSERT_EQ(p.robots.size(), 2u);
  ASSERT_EQ(p.channels.size(), 1u);
  EXPECT_EQ(p.channels[0].channel, 1);
  EXPECT_EQ(p.channels[0].event, "go");
  EXPECT_EQ(p.channels[0].from, "r1");
  EXPECT_EQ(p.channels[0].to, "r2");

  const RobotProgram& puma = p.robots[0];
  EXPECT_EQ(puma.file_name, "puma.val2");
  EXPECT_EQ(puma.text, fmt::format(R"(.PROGRAM puma
; puma (r1), VAL II: written by twin compile --robot-language; do not edit
; program: prog.task
; scenario: s.yaml
; cell: yasuda-cell (cell.yaml), robot puma as r1
; net: {}
; poses: the tool in the robot's base frame, mm and degrees (TRANS x,y,z,o,a,t)
; I/O 1: SIGNAL 1 = go to melfa (r2)
; I/O 16: WAIT SIG(1016) = a part at the stop of conveyor input (its sensor)
  SPEED 50
  SIGNAL -1
; prog.task:5:3 Pick A
  OPENI
  WAIT SIG(1016)
  MOVE above.A
  MOVE at.A
  CLOSEI
  MOVE above.A
; prog.task:6:3 signal go
  SIGNAL 1
; end
.END
.LOCATIONS
above.A 30 -550 630 0 0 0
at.A 30 -550 550 0 0 0
.END
)",
                                   p.check));
  // Steps count from 1 after .PROGRAM: 8 header comments, SPEED, SIGNAL -1, a comment, then the Pick, whose first
  // move waits for A to rest at the input conveyor's stop (its sensor, the cell's input 16).
  EXPECT_THAT(puma.primitive_line, ::testing::ElementsAre(12, 14, 15, 16, 17, 19));
  EXPECT_EQ(puma.host_lines.front(), ".PROGRAM puma");
  EXPECT_EQ(puma.host_lines.size(), 26u);  // every line of the file

  const RobotProgram& melfa = p.robots[1];
  EXPECT_EQ(melfa.file_name, "melfa.movemaster");
  EXPECT_EQ(melfa.text,
            fmt::format(R"(' melfa (r2), Movemaster EX: written by twin compile --robot-language; do not edit
' program: prog.task
' scenario: s.yaml
' cell: yasuda-cell (cell.yaml), robot melfa as r2
' net: {}
' poses: the tool in the robot's base frame, mm and degrees (x,y,z,p,r, the 5-axis rule)
' I/O 1: TB -1 = go from puma (r1)
' a host sends the numbered lines (not these comments), then RN
10 SP 4
20 TB -1,20
30 ED
)",
                        p.check));
  EXPECT_THAT(melfa.primitive_line, ::testing::ElementsAre(20));
  EXPECT_THAT(melfa.host_lines, ::testing::ElementsAre("10 SP 4", "20 TB -1,20", "30 ED"));
  EXPECT_THAT(p.check, HasSubstr("deadlock-free"));
}

TEST_F(RobotProgramsTest, SameInputSameBytes) {
  const Scenario s = cell::load_scenario(kScenes + "/exchange.yaml");
  Scenario a = s;
  set_language(a, "puma=val2", {"test", 0, 0});
  set_language(a, "melfa=movemaster", {"test", 0, 0});
  const RobotPrograms first = generate_robot_programs(a, cell::preflight(a, &twin_port()));
  const RobotPrograms second = generate_robot_programs(a, cell::preflight(a, &twin_port()));
  ASSERT_EQ(first.robots.size(), second.robots.size());
  for (std::size_t i = 0; i < first.robots.size(); ++i) EXPECT_EQ(first.robots[i].text, second.robots[i].text);

  write_robot_programs(first, dir_ / "out");
  EXPECT_EQ(read_file(dir_ / "out" / "puma.val2"), first.robots[0].text);
  EXPECT_EQ(read_file(dir_ / "out" / "melfa.movemaster"), first.robots[1].text);
}

// The numbers of a line after its command word: "PD 3,1.0,..." -> {3, 1, ...}; "above.A 30 -550 ..." -> {30, ...}.
std::vector<double> numbers_after(const std::string& line, char separator) {
  std::vector<double> v;
  std::stringstream in(line.substr(line.find(' ') + 1));
  std::string field;
  while (std::getline(in, field, separator)) v.push_back(std::stod(field));
  return v;
}

// Every move of the exchange, read back from the programs with the doc's conventions, is the tool pose the motion plan
// gives, within the languages' resolution.
TEST_F(RobotProgramsTest, PosesReadBackToThePlan) {
  Scenario s = cell::load_scenario(kScenes + "/exchange.yaml");
  set_language(s, "puma=val2", {"test", 0, 0});
  set_language(s, "melfa=movemaster", {"test", 0, 0});
  const cell::Preflight pre = cell::preflight(s, &twin_port());
  const RobotPrograms p = generate_robot_programs(s, pre);
  ASSERT_TRUE(pre.plan.has_value());
  const cell::MotionPlan& plan = *pre.plan;  // the preflight's plan, which the programs follow

  for (std::size_t r = 0; r < 2; ++r) {
    const RobotProgram& rp = p.robots[r];
    const models::RobotSpec& spec = *s.cell.find_robot(rp.cell_robot);
    const auto chain = models::KinematicChain::from_urdf_file(spec.urdf, "base_link", "tcp");
    std::map<std::string, Eigen::Isometry3d> located;  // location name / position number -> frame
    std::map<int, std::string> line_text;              // line number or step -> its text
    int step = 0;
    bool in_program = false, in_locations = false;
    for (const std::string& l : rp.host_lines) {
      if (rp.language == models::DriverKind::kMovemaster) {
        const int n = std::stoi(l);
        const std::string text = l.substr(l.find(' ') + 1);
        line_text[n] = text;
        if (text.starts_with("PD ")) {
          const std::vector<double> v = numbers_after(text, ',');
          // The 5-axis rule: a = cos p u + sin p z, R = [w x a, w, a] Rz(r).
          const double th = std::atan2(v[2], v[1]);
          const Eigen::Vector3d u(std::cos(th), std::sin(th), 0), w(-std::sin(th), std::cos(th), 0);
          const Eigen::Vector3d a = std::cos(v[4] * kDeg) * u + std::sin(v[4] * kDeg) * Eigen::Vector3d::UnitZ();
          Eigen::Matrix3d m;
          m << w.cross(a), w, a;
          Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
          f.linear() = m * Eigen::AngleAxisd(v[5] * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
          f.translation() = Eigen::Vector3d(v[1], v[2], v[3]) / 1000;
          located[fmt::format("{}", static_cast<int>(v[0]))] = f;
        }
        continue;
      }
      if (l.starts_with(".PROGRAM")) {
        in_program = true;
      } else if (l == ".LOCATIONS") {
        in_locations = true;
      } else if (l == ".END") {
        in_program = false;
      } else if (in_program) {
        line_text[++step] = l.substr(l.find_first_not_of(' '));
      } else if (in_locations) {
        const std::vector<double> v = numbers_after(l, ' ');
        Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
        f.linear() = (Eigen::AngleAxisd(v[3] * kDeg, Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(v[4] * kDeg, Eigen::Vector3d::UnitY()) *
                      Eigen::AngleAxisd(v[5] * kDeg, Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()))
                         .toRotationMatrix();
        f.translation() = Eigen::Vector3d(v[0], v[1], v[2]) / 1000;
        located[l.substr(0, l.find(' '))] = f;
      }
    }
    const auto& prims = s.program.programs[r].primitives;
    ASSERT_EQ(rp.primitive_line.size(), prims.size());
    int moves = 0;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      const std::string& text = line_text.at(rp.primitive_line[k]);
      if (prims[k].kind != task::PrimitiveKind::kMove) {
        EXPECT_FALSE(text.starts_with("MO")) << text;
        continue;
      }
      ++moves;
      ASSERT_TRUE(text.starts_with("MO")) << text;
      const Eigen::Isometry3d& f = located.at(text.substr(text.find(' ') + 1));
      const std::vector<double>& goal = plan.commands[r][k].goal;
      const Eigen::Isometry3d want =
          chain.forward(Eigen::Map<const Eigen::VectorXd>(goal.data(), static_cast<Eigen::Index>(goal.size())));
      EXPECT_LT((f.translation() - want.translation()).norm(), 1e-4) << rp.robot << " " << k << " " << text;
      EXPECT_LT(Eigen::AngleAxisd(f.linear().transpose() * want.linear()).angle(), 0.15 * kDeg)
          << rp.robot << " " << k << " " << text;
    }
    EXPECT_GT(moves, 2);
  }
}

TEST_F(RobotProgramsTest, RefusesARobotOnTheSimDriver) {
  const Scenario s = cell::load_scenario(kScenes + "/exchange.yaml");  // drivers: {puma: sim, melfa: sim}
  expect_refused(s, "exchange.yaml", 8, "robot 'puma' (r1) runs on the sim driver");
}

// The cell file `source`, copied into `dir` as cell.yaml with `from` replaced by `to` and its URDF paths (written
// relative as `urdf`, e.g. "../models/urdf/") made absolute; returns the copy's text.
std::string copy_cell_with(const std::string& source, const fs::path& dir, const std::string& from,
                           const std::string& to, const std::string& urdf) {
  std::string text = read_file(source);
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  const std::size_t up = urdf.size() - std::string("models/urdf/").size();  // the "../" parts
  for (std::size_t p = text.find(urdf); p != std::string::npos; p = text.find(urdf, p)) {
    text.replace(p, up, std::string(CW_SOURCE_DIR) + "/");
  }
  std::ofstream(dir / "cell.yaml") << text;
  return text;
}

// The cell's cell.yaml, copied into the test's directory with `from` replaced by `to`.
std::string cell_with(const fs::path& dir, const std::string& from, const std::string& to) {
  return copy_cell_with(kScenes + "/cell.yaml", dir, from, to, "../models/urdf/");
}

int line_of(const std::string& text, const std::string& needle) {
  return 1 + static_cast<int>(
                 std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(text.find(needle)), '\n'));
}

TEST_F(RobotProgramsTest, RefusesAPartComingOnAConveyorWithoutSensor) {
  const std::string cell = cell_with(dir_, "    sensor: {signal: 16, name: input_eye, io: 0}\n", "");
  const Scenario s = load(kSmall, "", (dir_ / "cell.yaml").string());
  expect_refused(s, "cell.yaml", line_of(cell, "- name: input"),
                 "robot 'puma' (r1) goes to workpiece 'A' (prog.task:5:3 'Pick A') before it has ridden conveyor "
                 "'input' to its stop");
  expect_refused(s, "cell.yaml", line_of(cell, "- name: input"), "the conveyor has no part-present sensor");
}

// A part of a class that the feed brings (review of 643c69d: the estimate's feed net took these moves out of the
// arrival gates, and the programs lost their sensor wait): the move that takes each fed part waits for the sensor.
// kSmall with A a part of a class that arrives at IN.
std::string class_program() {
  std::string p = kSmall;
  p.replace(p.find("workpiece A"), 11, "workpiece part from IN\nlocation IN");
  p.replace(p.find("Pick A"), 6, "Pick part");
  return p;
}

constexpr const char* kFeed = "bind: {IN: input_pick}\nfeed: {conveyor: input, workpieces: [A], start: 0, period: 4}\n";

TEST_F(RobotProgramsTest, AFedPartOfAClassIsWaitedForAtTheSensor) {
  const Scenario s = load(class_program(), kFeed);
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  const RobotProgram& puma = p.robots.at(0);
  EXPECT_THAT(puma.text, HasSubstr("  OPENI\n  WAIT SIG(1016)\n  MOVE above."));
}

TEST_F(RobotProgramsTest, RefusesAFedPartOfAClassOnAConveyorWithoutSensor) {
  const std::string cell = cell_with(dir_, "    sensor: {signal: 16, name: input_eye, io: 0}\n", "");
  const Scenario s = load(class_program(), kFeed, (dir_ / "cell.yaml").string());
  expect_refused(s, "cell.yaml", line_of(cell, "- name: input"),
                 "robot 'puma' (r1) goes to the next part the feed brings (prog.task:6:3 'Pick part')");
}

// Issue 25: a third robot takes the parts the output conveyor brings to its stop (tests/data/third): its program went
// to the pick right after the upstream robot's signal that the part was down on the belt, with the part still riding.
// Every move that takes a part of a class arriving on a belt now waits for the belt's sensor (the cell's input 15).
const std::string kThird = std::string(CW_SOURCE_DIR) + "/tests/data/third";

// The third robot's cell (tests/data/third/cell.yaml), copied into `dir` with `from` replaced by `to`; the scenario
// s.yaml beside it runs third.task with r3 (p3) in `language`.
Scenario third_robot(const fs::path& dir, const std::string& from, const std::string& to, const std::string& language,
                     std::string* cell_text = nullptr) {
  const std::string text = copy_cell_with(kThird + "/cell.yaml", dir, from, to, "../../../models/urdf/");
  std::string scenario = read_file(kThird + "/third.yaml");
  scenario.replace(scenario.find("program: third.task"), 19, "program: " + kThird + "/third.task");
  std::ofstream(dir / "s.yaml") << scenario;
  if (cell_text != nullptr) *cell_text = text;
  Scenario s = cell::load_scenario(dir / "s.yaml");
  set_language(s, "puma=val2", {"test", 0, 0});
  set_language(s, "melfa=movemaster", {"test", 0, 0});
  set_language(s, "p3=" + language, {"test", 0, 0});
  return s;
}

TEST_F(RobotProgramsTest, AThirdRobotWaitsForThePartTheBeltBringsInVal2) {
  const Scenario s = third_robot(dir_, "", "", "val2");
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  const RobotProgram& p3 = p.robots.at(2);
  ASSERT_EQ(p3.cell_robot, "p3");
  // After the MELFA's signal that the part is down, the sensor at the output conveyor's stop, then the move.
  EXPECT_THAT(p3.text, HasSubstr("  WAIT SIG(1001)\n; third.task:20:3 Pick part\n  OPENI\n  WAIT SIG(1015)\n"
                                 "  MOVE above.part\n"));
  EXPECT_THAT(p3.text, HasSubstr("; I/O 15: WAIT SIG(1015) = a part at the stop of conveyor output (its sensor)\n"));
  // The PUMA still waits for its own belt's sensor, once.
  EXPECT_THAT(p.robots.at(0).text, HasSubstr("  OPENI\n  WAIT SIG(1016)\n  MOVE above.A\n"));
}

TEST_F(RobotProgramsTest, AThirdRobotWaitsForThePartTheBeltBringsInMovemaster) {
  const Scenario s = third_robot(dir_, "", "", "movemaster");
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  const RobotProgram& p3 = p.robots.at(2);
  ASSERT_EQ(p3.language, models::DriverKind::kMovemaster);
  // Line 60 waits for the MELFA's output 1, line 70 opens, line 80 jumps onto itself until input 15 is on, then the
  // move to the pick.
  EXPECT_THAT(p3.text, HasSubstr("\n60 TB -1,60\n70 GO\n80 TB -15,80\n90 MO 1\n"));
}

TEST_F(RobotProgramsTest, RefusesAPartABeltBringsToAStopWithoutSensor) {
  std::string cell;
  const Scenario s = third_robot(dir_, "    sensor: {signal: 15}\n", "", "val2", &cell);
  expect_refused(s, "cell.yaml", line_of(cell, "- name: output"),
                 "robot 'p3' (r3) goes to the next part of class 'part' at output_pick (third.task:20:3 'Pick part') "
                 "before it has ridden conveyor 'output' to its stop: its controller must wait for the part, but the "
                 "conveyor has no part-present sensor");
}

TEST_F(RobotProgramsTest, RefusesAPartTakenFromABeltAwayFromItsStop) {
  // The class's location 0.3 m upstream of the stop: the belt carries parts past it, and no sensor is there.
  std::string cell;
  const Scenario s = third_robot(dir_, "at: output.leave, offset: [0, -0.02, 0]", "at: output.leave, offset: [0, -0.3, 0]",
                                 "val2", &cell);
  expect_refused(s, "cell.yaml", line_of(cell, "name: output_pick"),
                 "robot 'p3' (r3) takes a part of class 'part' at output_pick (third.task:20:3 'Pick part'), which "
                 "lies on conveyor 'output' 0.30 m before its stop bar");
}

TEST_F(RobotProgramsTest, RefusesTakingANamedPartAfterItWasLetGoOfOnARunningBelt) {
  // The MELFA puts A down on the output conveyor and the third robot takes it, named, where the belt stops it: the
  // preflight plans it there (docs/scenarios.md, "Relaying a part between robots"), but no sensor tells a generated
  // program when A has come. (third.task with A for its class.)
  std::string program = read_file(kThird + "/third.task");
  program.replace(program.find("workpiece part from T3"), 22, "# no class");
  program.replace(program.find("Pick part"), 9, "Pick A");
  std::ofstream(dir_ / "prog.task") << program;
  std::string scenario = read_file(kThird + "/third.yaml");
  scenario.replace(scenario.find("cell: cell.yaml"), 15, "cell: " + kThird + "/cell.yaml");
  scenario.replace(scenario.find("program: third.task"), 19, "program: prog.task");
  std::ofstream(dir_ / "s.yaml") << scenario;
  Scenario s = cell::load_scenario(dir_ / "s.yaml");
  set_language(s, "puma=val2", {"test", 0, 0});
  set_language(s, "melfa=movemaster", {"test", 0, 0});
  set_language(s, "p3=val2", {"test", 0, 0});
  expect_refused(s, "prog.task", 20,
                 "robot 'p3' (r3) goes to workpiece 'A' ('Pick A') after prog.task:14:14 'Place OUT' let go of it on "
                 "conveyor 'output', which carries it on: no sensor tells the program when it has come to rest");
}

TEST_F(RobotProgramsTest, RefusesASensorOnAnEventWire) {
  const std::string cell = cell_with(dir_, "sensor: {signal: 16,", "sensor: {signal: 1,");
  const Scenario s = load(kSmall, "", (dir_ / "cell.yaml").string());
  expect_refused(s, "cell.yaml", line_of(cell, "sensor: {signal: 1,"),
                 "input 1 is the part-present sensor of conveyor 'input', but the program's events need the wires "
                 "1..1");
}

TEST_F(RobotProgramsTest, RefusesARegionSharedByTwoControllers) {
  const Scenario s = load(
      "robot r1 r2\nregion zone\nsequence r1\n  enter zone\n  leave zone\nend\n"
      "sequence r2\n  enter zone\n  leave zone\nend\n");
  expect_refused(s, "prog.task", 2, "region 'zone' is shared by puma and melfa");
}

TEST_F(RobotProgramsTest, ARegionOfOneRobotNeedsNoWire) {
  const Scenario s = load("robot r1 r2\nregion zone\nsequence r1\n  enter zone\n  leave zone\nend\n");
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  EXPECT_TRUE(p.channels.empty());
  EXPECT_THAT(p.robots[0].primitive_line, ::testing::ElementsAre(-1, -1));
  EXPECT_THAT(p.robots[0].text, HasSubstr("regions used by this robot alone, no wire needed: zone"));
}

TEST_F(RobotProgramsTest, RefusesACountedSemaphore) {
  const Scenario s = load(
      "robot r1 r2\nsemaphore s\nsequence r1\n  signal s\n  signal s\nend\n"
      "sequence r2\n  wait s\n  wait s\nend\n");
  expect_refused(s, "prog.task", 2, "semaphore 's' (initial 0, signalled 2 times, waited on 2 times");
}

TEST_F(RobotProgramsTest, RefusesAProgramThatFailsThePreflight) {
  const Scenario s = load(read_file(kScenes + "/deadlock.task"));
  expect_refused(s, "s.yaml", 0, "must pass the preflight");
}

// Issue 26: device commands in a generated program. tests/data/eye: the cell wires the input belt's drive to the
// controllers' output 15 (`run_signal`) and its photo-eye to their input 16; eye.task runs the belt, waits for the
// eye, picks A and hands it over.
const std::string kEye = std::string(CW_SOURCE_DIR) + "/tests/data/eye";

// eye.task on tests/data/eye's cell (or `cell`), r1 (the PUMA) in `puma`, r2 (the MELFA) in `melfa`.
Scenario eye_scenario(const fs::path& dir, const std::string& puma, const std::string& melfa,
                      const std::string& program = read_file(kEye + "/eye.task"),
                      const std::string& cell = kEye + "/cell.yaml") {
  std::ofstream(dir / "eye.task") << program;
  std::ofstream(dir / "s.yaml") << fmt::format("cell: {}\nprogram: eye.task\nrobots: {{r1: puma, r2: melfa}}\n{}", cell,
                                               program.find("location B") != std::string::npos
                                                   ? "bind: {B: output_drop}\n"
                                                   : "");
  Scenario s = cell::load_scenario(dir / "s.yaml");
  set_language(s, "puma=" + puma, {"test", 0, 0});
  set_language(s, "melfa=" + melfa, {"test", 0, 0});
  return s;
}

// tests/data/eye's cell, copied into `dir` as cell.yaml with `from` replaced by `to`; returns the copy's text.
std::string eye_cell_with(const fs::path& dir, const std::string& from, const std::string& to) {
  return copy_cell_with(kEye + "/cell.yaml", dir, from, to, "../../../models/urdf/");
}

// The program's lines from the first after the set-up (VAL II: after `SIGNAL -...`; Movemaster: from `line`).
std::string from_line(const std::string& text, const std::string& line) {
  const std::size_t at = text.find(line);
  EXPECT_NE(at, std::string::npos) << line << " in\n" << text;
  return at == std::string::npos ? std::string() : text.substr(at);
}

TEST_F(RobotProgramsTest, AWaitForAPhotoEyeWiredToTheControllerIsAWaitOnItsInputInVal2) {
  const Scenario s = eye_scenario(dir_, "val2", "movemaster");
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  const RobotProgram& puma = p.robots.at(0);
  // The header names both wires; the set-up turns the belt's output off (the net's belt starts stopped); `accumulate
  // input` sets output 15, `wait input_eye` waits on input 16, and the Pick right after it does not wait again.
  EXPECT_THAT(puma.text, HasSubstr("; I/O 16: WAIT SIG(1016) = a part at the stop of conveyor input (its sensor)\n"
                                   "; I/O 15: SIGNAL 15 / SIGNAL -15 = run / stop conveyor input (its drive)\n"));
  const std::string program = from_line(puma.text, "  SPEED 50\n");
  // (The steps table's lines end in barriers: the events 1..11.)
  EXPECT_EQ(program.substr(0, program.find(".LOCATIONS")), R"(  SPEED 50
  SIGNAL -1,-3,-5,-7,-9,-10,-15
; eye.task:13:3 accumulate input
  SIGNAL 15
; eye.task:13:3 end of step 1
  SIGNAL 1
  WAIT SIG(1002)
; eye.task:14:3 wait input_eye
  WAIT SIG(1016)
; eye.task:14:3 end of step 2
  SIGNAL 3
  WAIT SIG(1004)
; eye.task:15:3 Pick A
  OPENI
  MOVE above.A
  MOVE at.A
  CLOSEI
  MOVE above.A
; eye.task:15:3 end of step 3
  SIGNAL 5
  WAIT SIG(1006)
; eye.task:16:3 Put r2
  MOVE hover.r2
  SIGNAL 7
  WAIT SIG(1008)
  OPENI
  SIGNAL 9
; eye.task:16:3 end of step 4
  SIGNAL 10
  WAIT SIG(1011)
; end
.END
)");
  // The device primitives' lines: accumulate (step of SIGNAL 15) and the eye's wait.
  const auto& prims = s.program.programs[0].primitives;
  for (std::size_t k = 0; k < prims.size(); ++k) {
    if (prims[k].kind == task::PrimitiveKind::kDevice) {
      EXPECT_GT(puma.primitive_line[k], 0) << k;
    }
  }
}

TEST_F(RobotProgramsTest, AWaitForAPhotoEyeWiredToTheControllerIsAWaitOnItsInputInMovemaster) {
  const Scenario s = eye_scenario(dir_, "movemaster", "val2");
  const RobotPrograms p = generate_robot_programs(s, cell::preflight(s, &twin_port()));
  const RobotProgram& puma = p.robots.at(0);
  ASSERT_EQ(puma.language, models::DriverKind::kMovemaster);
  EXPECT_THAT(puma.text, HasSubstr("' I/O 16: TB -16 = a part at the stop of conveyor input (its sensor)\n"
                                   "' I/O 15: OB +15 / OB -15 = run / stop conveyor input (its drive)\n"));
  // After the positions: the speed, the event outputs and the belt's output 15 off, the belt run, the barrier of the
  // table's first line, the jump onto its own line while input 16 is off, the next barrier, then the Pick.
  EXPECT_THAT(puma.text, HasSubstr("\n40 SP 4\n50 OB -1\n60 OB -3\n70 OB -5\n80 OB -7\n90 OB -9\n100 OB -10\n"
                                   "110 OB -15\n120 OB +15\n130 OB +1\n140 TB -2,140\n150 TB -16,150\n160 OB +3\n"
                                   "170 TB -4,170\n180 GO\n190 MO 1\n"));
}

// The refusals, each at the command's line, saying what a generated program does and how to run it instead.
TEST_F(RobotProgramsTest, RefusesARunOfABeltWiredToNoControllerOutput) {
  // The shipped cell: the input belt runs by coil 0 of the cell's I/O unit only.
  const Scenario s = eye_scenario(dir_, "val2", "movemaster", read_file(kEye + "/eye.task"), kScenes + "/cell.yaml");
  expect_refused(s, "eye.task", 13,
                 "robot 'puma' (r1): 'accumulate input' cannot be written as a VAL II program: conveyor 'input' has "
                 "no drive wired to a robot controller output (it runs by coil 0 of the cell's I/O unit); a generated "
                 "program waits for a photo-eye wired to its controller's input");
  expect_refused(s, "eye.task", 13, "Wire its drive to an output (`run_signal: n` in cell.yaml), or run the program "
                                    "with twin run");
}

TEST_F(RobotProgramsTest, RefusesAWaitForAPhotoEyeWiredToNoControllerInput) {
  // The eye without its input; no part is picked (a Pick of A would wait for the sensor: refused as before).
  eye_cell_with(dir_, "{signal: 16, name: input_eye", "{name: input_eye");
  const Scenario s = eye_scenario(dir_, "movemaster", "val2",
                                  "robot r1 r2\nconveyor input\nsensor input_eye on input\nsequence r1\n"
                                  "  accumulate input\n  wait input_eye\nend\n",
                                  (dir_ / "cell.yaml").string());
  expect_refused(s, "eye.task", 6,
                 "robot 'puma' (r1): 'wait input_eye' cannot be written as a Movemaster EX program: photo-eye "
                 "'input_eye' is wired to no robot controller input; a generated program waits for");
}

TEST_F(RobotProgramsTest, RefusesAWaitForADropEye) {
  // The output conveyor's drop eye (output_eye) is on the cell's I/O unit only, and no drop eye can be on a wire.
  // (Its belt's drive on output 14, so that the program can run it.)
  eye_cell_with(dir_, "    io: {run: 1} ", "    run_signal: 14\n    io: {run: 1} ");
  std::string program = read_file(kEye + "/eye.task");
  program.replace(program.find("conveyor input\nsensor input_eye on input"), 40,
                  "conveyor output\nsensor output_eye on output");
  program.replace(program.find("accumulate input"), 16, "run output      ");
  program.replace(program.find("wait input_eye  "), 16, "wait output_eye ");
  const Scenario s = eye_scenario(dir_, "val2", "movemaster", program, (dir_ / "cell.yaml").string());
  expect_refused(s, "eye.task", 14,
                 "'wait output_eye' cannot be written as a VAL II program: photo-eye 'output_eye' is wired to no "
                 "robot controller input (only a stop eye can be)");
}

TEST_F(RobotProgramsTest, RefusesAMachineCycle) {
  // The PUMA puts A into the mill (D taken out of the cell) and starts it: the mill's start coil, busy and done are
  // the cell's I/O unit's.
  eye_cell_with(dir_, "  - {name: D, shape: cylinder", "  # - {name: D, shape: cylinder");
  const Scenario s = eye_scenario(dir_, "val2", "movemaster",
                                  "robot r1 r2\nworkpiece A\nmachine mill\nconveyor input\nsensor input_eye on input\n"
                                  "sequence r1\n  accumulate input\n  wait input_eye\n  Pick A\n  Place mill\n"
                                  "  start mill\nend\n",
                                  (dir_ / "cell.yaml").string());
  expect_refused(s, "eye.task", 11,
                 "robot 'puma' (r1): 'start mill' cannot be written as a VAL II program: machine 'mill' is started "
                 "and watched through the cell's I/O unit (its start coil, its busy and done inputs), which no robot "
                 "controller drives");
  expect_refused(s, "eye.task", 11, "Run the program with twin run (`--device mill=modbus:...` for the real machine)");
}

TEST_F(RobotProgramsTest, RefusesABeltRunByTwoControllers) {
  const Scenario s = eye_scenario(dir_, "val2", "movemaster",
                                  "robot r1 r2\nconveyor input\nsemaphore go\nsequence r1\n  run input\n"
                                  "  signal go\nend\nsequence r2\n  wait go\n  stop input\nend\n");
  expect_refused(s, "eye.task", 10,
                 "robot 'melfa' (r2): 'stop input': conveyor 'input' is also run or stopped by robot 'puma' (r1)");
}

TEST_F(RobotProgramsTest, RefusesABeltDriveOnAnEventWire) {
  const std::string cell = eye_cell_with(dir_, "    run_signal: 15 ", "    run_signal: 1  ");
  const Scenario s = eye_scenario(dir_, "val2", "movemaster", read_file(kEye + "/eye.task"),
                                  (dir_ / "cell.yaml").string());
  expect_refused(s, "cell.yaml", line_of(cell, "    run_signal: 1  "),
                 "output 1 runs conveyor 'input', but the program's events need the wires 1..");
}

TEST_F(RobotProgramsTest, SetLanguageRefusesBadSpecs) {
  Scenario s = load(kSmall);
  EXPECT_THROW(set_language(s, "puma", {"x", 0, 0}), InputError);
  EXPECT_THROW(set_language(s, "puma=cobol", {"x", 0, 0}), InputError);
  EXPECT_THROW(set_language(s, "kuka=val2", {"x", 0, 0}), InputError);
  set_language(s, "puma=sim:/dev/ttyS0", {"x", 0, 0});
  expect_refused(s, "x", 0, "robot 'puma' (r1) runs on the sim driver");
}

}  // namespace
}  // namespace cellwright::cell
