// Fault specifications: every kind read from a scenario's `faults:` list with its defaults and its own fields, every
// kind of bad entry refused naming the file, line and field, the command-line form `KIND:key=value` read and written
// back, and `expect: {A: lost}`.
#include "cellwright/twin/faults.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cellwright/cell/scenario.hpp"
#include "common/garbage_in.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

const models::CellDescription& paper_cell() {
  static const models::CellDescription cell = models::load_cell(kScenes + "/cell.yaml");
  return cell;
}

class FaultFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("faults_test_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A scenario whose `faults:` key is on line 5, its list's first entry on line 6; `more` follows the list.
  fs::path scenario(const std::string& faults, const std::string& more = "") {
    const fs::path p = dir_ / "s.yaml";
    std::ofstream(p) << fmt::format("cell: {}/cell.yaml\nprogram: {}/exchange.task\nrobots: {{r1: puma, r2: melfa}}\nbind: {{B: output_drop}}\nfaults:\n{}{}",
                                    kScenes, kScenes, faults, more);
    return p;
  }
  void expect_error(const std::string& faults, int line, const std::string& text, const std::string& more = "") {
    const fs::path file = scenario(faults, more);
    try {
      load_scenario(file);
      ADD_FAILURE() << "no error; expected line " << line << ": " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, file.string()) << e.what();
      EXPECT_EQ(e.where().line, line) << e.what();
      EXPECT_GT(e.where().column, 0) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  }

  fs::path dir_;
};

TEST_F(FaultFiles, EveryKindWithItsDefaults) {
  const Scenario s = load_scenario(scenario(R"(  - {kind: drop, robot: puma}
  - {kind: slip, robot: melfa}
  - {kind: misplace, workpiece: A}
  - {kind: unreachable, workpiece: B}
  - {kind: missing, workpiece: C}
  - {kind: obstacle, robot: puma}
  - {kind: timeout, robot: puma}
  - {kind: garbage, robot: puma}
  - {kind: hardware, robot: puma}
  - {kind: position, robot: melfa}
  - {kind: link_lost, robot: melfa}
  - {kind: lost_signal}
  - {kind: frame_lost}
  - {kind: detection_noise}
)",
                                            "perception: vision\n"));
  ASSERT_EQ(s.faults.size(), kFaultKinds);
  for (std::size_t i = 0; i < kFaultKinds; ++i) {
    EXPECT_EQ(s.faults[i].kind, static_cast<FaultKind>(i));
    EXPECT_EQ(s.faults[i].where.line, static_cast<int>(6 + i));
  }
  const FaultSpec& drop = s.faults[0];
  EXPECT_EQ(drop.robot, "puma");
  EXPECT_EQ(drop.carry, 1u);
  EXPECT_DOUBLE_EQ(drop.after, 0.3);
  EXPECT_DOUBLE_EQ(s.faults[1].distance, 0.015);
  EXPECT_EQ(s.faults[2].workpiece, "A");
  EXPECT_DOUBLE_EQ(s.faults[2].offset[0], 0.04);
  EXPECT_DOUBLE_EQ(s.faults[2].offset[1], 0.02);
  EXPECT_DOUBLE_EQ(s.faults[2].yaw, 30);
  EXPECT_DOUBLE_EQ(s.faults[3].distance, 0.6);
  const FaultSpec& obstacle = s.faults[5];
  EXPECT_DOUBLE_EQ(obstacle.size, 0.06);
  EXPECT_DOUBLE_EQ(obstacle.ahead, 0.15);
  EXPECT_DOUBLE_EQ(obstacle.duration, 2);
  EXPECT_DOUBLE_EQ(obstacle.time, 0);
  EXPECT_EQ(s.faults[6].command, FaultCommand::move);
  EXPECT_EQ(s.faults[6].n, 1u);
  EXPECT_EQ(s.faults[11].n, 1u);
  EXPECT_EQ(s.faults[12].count, 2u);
  const FaultSpec& noise = s.faults[13];
  EXPECT_DOUBLE_EQ(noise.duration, 4);
  EXPECT_DOUBLE_EQ(noise.sigma, 0.01);
  EXPECT_DOUBLE_EQ(noise.sigma_yaw, 5);
}

TEST_F(FaultFiles, ReadsEveryFieldGiven) {
  const Scenario s = load_scenario(scenario(R"(  - {kind: slip, robot: puma, carry: 2, after: 0.5, distance: 0.02}
  - {kind: misplace, workpiece: A, offset: [0.05, 0.01], yaw: 12}
  - {kind: obstacle, robot: melfa, time: 3.5, size: 0.1, ahead: 0.2, duration: 1}
  - {kind: garbage, robot: puma, command: grip, n: 3}
  - {kind: lost_signal, n: 2}
  - {kind: frame_lost, time: 4, count: 5}
  - {kind: detection_noise, time: 1, duration: 2, sigma: 0.02, sigma_yaw: 8}
)",
                                            "perception: vision\n"));
  ASSERT_EQ(s.faults.size(), 7u);
  EXPECT_EQ(s.faults[0].carry, 2u);
  EXPECT_DOUBLE_EQ(s.faults[0].after, 0.5);
  EXPECT_DOUBLE_EQ(s.faults[0].distance, 0.02);
  EXPECT_DOUBLE_EQ(s.faults[1].offset[0], 0.05);
  EXPECT_DOUBLE_EQ(s.faults[1].yaw, 12);
  EXPECT_EQ(s.faults[2].robot, "melfa");
  EXPECT_DOUBLE_EQ(s.faults[2].time, 3.5);
  EXPECT_DOUBLE_EQ(s.faults[2].size, 0.1);
  EXPECT_DOUBLE_EQ(s.faults[2].ahead, 0.2);
  EXPECT_DOUBLE_EQ(s.faults[2].duration, 1);
  EXPECT_EQ(s.faults[3].command, FaultCommand::grip);
  EXPECT_EQ(s.faults[3].n, 3u);
  EXPECT_EQ(s.faults[4].n, 2u);
  EXPECT_EQ(s.faults[5].count, 5u);
  EXPECT_DOUBLE_EQ(s.faults[6].sigma, 0.02);
  EXPECT_DOUBLE_EQ(s.faults[6].sigma_yaw, 8);
}

TEST_F(FaultFiles, ScenariosWithoutFaultsHaveNone) {
  const fs::path p = dir_ / "s.yaml";
  std::ofstream(p) << fmt::format("cell: {}/cell.yaml\nprogram: {}/exchange.task\nrobots: {{r1: puma, r2: melfa}}\nbind: {{B: output_drop}}\n",
                                  kScenes, kScenes);
  EXPECT_TRUE(load_scenario(p).faults.empty());
}

TEST_F(FaultFiles, BadEntriesNameFileLineAndField) {
  expect_error("  kind: drop\n", 6, "field 'faults' of the scenario must be a list of faults");
  expect_error("  - {kind: drop, robot: puma}\n", 7, "must be one of drop", "  - {kind: drip}\n");
  expect_error("  - drop\n", 6, "a fault must be a mapping of fields with a 'kind'");
  expect_error("  - {robot: puma}\n", 6, "a fault has no field 'kind' (it is required)");
  expect_error("  - {kind: explode, robot: puma}\n", 6, "must be one of drop, slip,");
  expect_error("  - {kind: drop}\n", 6, "the drop fault has no field 'robot' (it is required)");
  expect_error("  - {kind: misplace}\n", 6, "has no field 'workpiece' (it is required)");
  expect_error("  - {kind: drop, robot: kuka}\n", 6, "names robot 'kuka', which is not a robot of the cell");
  expect_error("  - {kind: missing, workpiece: Z}\n", 6, "names workpiece 'Z', which is not a workpiece of the cell");
  expect_error("  - {kind: drop, robot: puma, distance: 0.01}\n", 6,
               "unknown field 'distance' in the drop fault (a drop fault takes: kind, robot, carry, every, after)");
  expect_error("  - {kind: drop, robot: puma, colour: red}\n", 6, "unknown field 'colour'");
  expect_error("  - {kind: drop, robot: puma, carry: 0}\n", 6,
               "field 'carry' of the drop fault must be a whole number from 1 up, got '0'");
  expect_error("  - {kind: drop, robot: puma, carry: 1.5}\n", 6, "must be a whole number from 1 up");
  expect_error("  - {kind: drop, robot: puma, after: soon}\n", 6, "field 'after' of the drop fault must be a number");
  expect_error("  - {kind: drop, robot: puma, after: -1}\n", 6,
               "field 'after' of the drop fault must be within 0..1000000 s, got -1");
  expect_error("  - {kind: slip, robot: puma, distance: 0.1}\n", 6, "must be at most 0.03 m");
  expect_error("  - {kind: misplace, workpiece: A, offset: [0.1]}\n", 6, "field 'offset' of the misplace fault must "
                                                                         "have 2 numbers");
  expect_error("  - {kind: misplace, workpiece: A, yaw: 200}\n", 6, "must be from 0 to 180");
  expect_error("  - {kind: timeout, robot: puma, command: wait}\n", 6, "must be move or grip, got 'wait'");
  expect_error("  - {kind: obstacle, robot: puma, size: 0}\n", 6, "must be greater than 0");
  expect_error("  - {kind: drop, robot: puma, robot: melfa}\n", 6, "given twice");
  // The second entry is the bad one.
  expect_error("  - {kind: drop, robot: puma}\n  - {kind: lost_signal, n: x}\n", 7, "field 'n' of the lost_signal");
}

TEST_F(FaultFiles, CameraFaultsNeedVision) {
  expect_error("  - {kind: frame_lost}\n", 6, "a frame_lost fault needs perception vision");
  expect_error("  - {kind: detection_noise, time: 2}\n", 6, "a detection_noise fault needs perception vision");
}

TEST_F(FaultFiles, ExpectLost) {
  const fs::path p = dir_ / "s.yaml";
  std::ofstream(p) << fmt::format(
      "cell: {}/cell.yaml\nprogram: {}/exchange.task\nrobots: {{r1: puma, r2: melfa}}\nbind: {{B: output_drop}}\nexpect: {{A: lost}}\n", kScenes,
      kScenes);
  const Scenario s = load_scenario(p);
  ASSERT_EQ(s.expect.size(), 1u);
  EXPECT_EQ(s.expect[0].workpiece, "A");
  EXPECT_EQ(s.expect[0].place, "lost");
  EXPECT_TRUE(s.expect[0].lost());
}

// ---- The command-line form ----

TEST(FaultText, ReadsEveryKindAndWritesItBack) {
  const std::vector<std::string> texts = {
      "drop:robot=puma",
      "slip:robot=melfa,carry=2,every=5,after=0.5,distance=0.02",
      "misplace:workpiece=A,offset=0.05/0.01,yaw=12",
      "unreachable:workpiece=B",
      "missing:workpiece=C",
      "obstacle:robot=puma,time=3,size=0.1,ahead=0.2,duration=1",
      "timeout:robot=puma,command=grip,n=2",
      "garbage:robot=puma",
      "hardware:robot=puma,n=4",
      "position:robot=melfa,command=move",
      "link_lost:robot=melfa,n=3",
      "lost_signal",
      "frame_lost:time=2,count=3",
      "detection_noise:time=1,sigma=0.02",
  };
  for (std::size_t i = 0; i < texts.size(); ++i) {
    const FaultSpec f = parse_fault_text(texts[i], paper_cell());
    EXPECT_EQ(f.kind, static_cast<FaultKind>(i)) << texts[i];
    EXPECT_EQ(f.where.file, "--fault");
    const std::string full = to_text(f);
    EXPECT_EQ(parse_fault_text(full, paper_cell()), f) << texts[i] << " -> " << full;
    EXPECT_EQ(to_text(parse_fault_text(full, paper_cell())), full);
  }
  EXPECT_EQ(parse_fault_text(texts[1], paper_cell()).every, 5u);  // a slip at carries 2, 7, 12, ...
  EXPECT_EQ(parse_fault_text(texts[0], paper_cell()).every, 0u);  // once only
  EXPECT_THROW(parse_fault_text("drop:robot=puma,every=0", paper_cell()), InputError);
  const FaultSpec m = parse_fault_text("misplace:workpiece=A,offset=0.05/0.01,yaw=12", paper_cell());
  EXPECT_DOUBLE_EQ(m.offset[0], 0.05);
  EXPECT_DOUBLE_EQ(m.offset[1], 0.01);
  EXPECT_EQ(to_text(m), "misplace:workpiece=A,offset=0.05/0.01,yaw=12");
  EXPECT_EQ(to_text(parse_fault_text("drop:robot=puma", paper_cell())), "drop:robot=puma,carry=1,after=0.3");
  EXPECT_EQ(to_text(parse_fault_text("lost_signal", paper_cell())), "lost_signal:n=1");
}

TEST(FaultText, ErrorsNameTheOptionAndTheText) {
  const auto expect_error = [](const std::string& text, const std::string& problem) {
    try {
      parse_fault_text(text, paper_cell(), "--fault");
      ADD_FAILURE() << "no error for " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, "--fault") << e.what();
      EXPECT_THAT(e.what(), HasSubstr(fmt::format("'{}'", text)));
      EXPECT_THAT(e.what(), HasSubstr(problem));
    }
  };
  expect_error("explode:robot=puma", "must be one of drop");
  expect_error("drop", "has no field 'robot'");
  expect_error("drop:robot", "'robot' is not key=value");
  expect_error("drop:robot=puma,,carry=1", "an empty key=value");
  expect_error("drop:robot=puma,carry=1,carry=2", "'carry' is given twice");
  expect_error("drop:robot=kuka", "which is not a robot of the cell");
  expect_error("drop:robot=puma,yaw=3", "unknown field 'yaw' in the drop fault");
  expect_error("misplace:workpiece=A,offset=0.1", "must be a list of numbers");
  expect_error("misplace:workpiece=A,offset=0.1/0.2/0.3", "must have 2 numbers, got 3");
  expect_error("timeout:robot=puma,n=0", "whole number from 1 up");
}

// Seeded garbage in: `--fault` texts with random edits are read (and written back, they read as the same spec) or
// refused with an InputError naming the option; nothing else escapes.
TEST(FaultText, MutatedTextsAreReadOrRefusedWithAnInputError) {
  const std::vector<std::string> texts = {"drop:robot=puma,carry=1,after=0.3",
                                          "slip:robot=melfa,carry=2,every=5,after=0.5,distance=0.02",
                                          "misplace:workpiece=A,offset=0.05/0.01,yaw=12",
                                          "obstacle:robot=puma,time=3,size=0.1,ahead=0.2,duration=1",
                                          "timeout:robot=puma,command=grip,n=2",
                                          "frame_lost:time=2,count=3",
                                          "detection_noise:time=1,sigma=0.02"};
  const auto counts = cellwright::testing::feed_garbage(
      texts, 5000, 20261124, ":=,/.-+0123456789eEinfa_ \t", "--fault", [](const std::string& text) {
        const FaultSpec spec = parse_fault_text(text, paper_cell());
        EXPECT_EQ(parse_fault_text(to_text(spec), paper_cell()), spec) << text << " -> " << to_text(spec);
      });
  // Most edits break a key or a number (the reader is strict); those that survive still reach the round trip.
  EXPECT_GT(counts.accepted, 50);
  EXPECT_GT(counts.refused, 1000);
}

}  // namespace
}  // namespace cellwright::cell
