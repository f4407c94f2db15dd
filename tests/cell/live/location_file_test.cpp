// A taught location written into a copy of the cell description (cell/live/location_file.hpp): the file's other
// bytes kept, the new item in the list's own style, replacing by name, refusals that leave the file as it was, and
// the round trip: the saved location's grasp pose for the robot is the taught tool pose.
#include "cellwright/cell/live/location_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "cellwright/cell/live/teach.hpp"
#include "cellwright/models/cell.hpp"
#include "scene_copy.hpp"

namespace cellwright::cell {
namespace {

using live_testing::read_text;
using live_testing::SceneCopy;
using live_testing::write_text;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t nl = text.find('\n'); nl != std::string::npos; nl = text.find('\n', start)) {
    out.push_back(text.substr(start, nl - start));
    start = nl + 1;
  }
  if (start < text.size()) out.push_back(text.substr(start));
  return out;
}

// The grasp pose robot control uses for location `loc` (from above, the fingers along its yaw).
Eigen::Isometry3d grasp_of(const models::CellDescription& cell, const models::LocationSpec& loc, const std::string& robot) {
  return models::grasp_pose(loc.pose.xyz + Eigen::Vector3d(0, 0, loc.grasp_height), models::Approach::kDown,
                            loc.pose.rpy.z(), cell.find_robot(robot)->base.transform());
}

double angle_between(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

class LocationFile : public ::testing::Test {
 protected:
  void SetUp() override {
    cell_ = models::load_cell(copy_.cell_file());
    // A pose the PUMA reaches pointing down: 3 cm beside its input pick, the fingers turned 30 degrees further.
    const models::LocationSpec& pick = *cell_.find_location("input_pick");
    taught_ = grasp_of(cell_, pick, "puma");
    taught_.translation() += Eigen::Vector3d(0.03, 0, 0.01);
    taught_.linear() = Eigen::AngleAxisd(std::numbers::pi / 6, Eigen::Vector3d::UnitZ()) * taught_.linear();
    before_ = read_text(copy_.cell_file());
  }

  SceneCopy copy_;
  models::CellDescription cell_;
  Eigen::Isometry3d taught_;
  std::string before_;
};

TEST_F(LocationFile, ANewLocationIsOneLineAddedAfterTheLastInTheListsStyle) {
  const SavedLocation s = save_location(copy_.cell_file(), "cell.yaml", "taught_a", "puma", taught_);
  EXPECT_FALSE(s.replaced);
  const std::vector<std::string> a = lines_of(before_), b = lines_of(read_text(copy_.cell_file()));
  ASSERT_EQ(b.size(), a.size() + 1);
  // Where: right after output_drop, the list's last item.
  std::size_t last = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].find("{name: output_drop") != std::string::npos) last = i;
  }
  ASSERT_GT(last, 0u);
  EXPECT_EQ(s.line, static_cast<int>(last) + 2);
  EXPECT_EQ(b[last + 1].rfind("  - {name: taught_a, pose: {xyz: [", 0), 0u) << b[last + 1];
  EXPECT_NE(b[last + 1].find("reach: [puma]}"), std::string::npos) << b[last + 1];
  // Every other line, comments included, byte for byte.
  for (std::size_t i = 0; i <= last; ++i) EXPECT_EQ(b[i], a[i]) << "line " << i + 1;
  for (std::size_t i = last + 1; i < a.size(); ++i) EXPECT_EQ(b[i + 1], a[i]) << "line " << i + 1;
  // The diff says so.
  EXPECT_EQ(s.diff.rfind("--- cell.yaml\n+++ cell.yaml\n@@ ", 0), 0u) << s.diff;
  EXPECT_NE(s.diff.find("\n+" + b[last + 1] + "\n"), std::string::npos) << s.diff;
  EXPECT_NE(s.diff.find("\n " + a[last] + "\n"), std::string::npos) << s.diff;
}

TEST_F(LocationFile, TheSavedLocationsGraspIsTheTaughtPose) {
  save_location(copy_.cell_file(), "cell.yaml", "taught_a", "puma", taught_);
  const models::CellDescription again = models::load_cell(copy_.cell_file());
  const models::LocationSpec* loc = again.find_location("taught_a");
  ASSERT_NE(loc, nullptr);
  EXPECT_EQ(loc->reach, std::vector<std::string>{"puma"});
  const Eigen::Isometry3d grasp = grasp_of(again, *loc, "puma");
  EXPECT_LT((grasp.translation() - taught_.translation()).norm(), 1e-3);
  EXPECT_LT(angle_between(grasp, taught_), std::numbers::pi / 180);
  // The cell's own locations are as they were.
  for (const models::LocationSpec& l : cell_.locations) {
    const models::LocationSpec* same = again.find_location(l.name);
    ASSERT_NE(same, nullptr) << l.name;
    EXPECT_EQ(same->pose.xyz, l.pose.xyz) << l.name;
  }
}

TEST_F(LocationFile, SavingAgainUnderTheSameNameReplacesThatLineOnly) {
  save_location(copy_.cell_file(), "cell.yaml", "taught_a", "puma", taught_);
  const std::string once = read_text(copy_.cell_file());
  Eigen::Isometry3d moved = taught_;
  moved.translation().y() += 0.02;
  const SavedLocation s = save_location(copy_.cell_file(), "cell.yaml", "taught_a", "puma", moved);
  EXPECT_TRUE(s.replaced);
  const std::vector<std::string> a = lines_of(once), b = lines_of(read_text(copy_.cell_file()));
  ASSERT_EQ(a.size(), b.size());
  int changed = 0;
  for (std::size_t i = 0; i < a.size(); ++i) changed += a[i] != b[i];
  EXPECT_EQ(changed, 1);
  EXPECT_NE(b[static_cast<std::size_t>(s.line - 1)].find("{name: taught_a"), std::string::npos);
  const models::CellDescription again = models::load_cell(copy_.cell_file());
  EXPECT_LT((grasp_of(again, *again.find_location("taught_a"), "puma").translation() - moved.translation()).norm(), 1e-3);

  // A shipped location is replaced in place too: its comment lines above stay.
  const SavedLocation pick = save_location(copy_.cell_file(), "cell.yaml", "input_pick", "puma", taught_);
  EXPECT_TRUE(pick.replaced);
  const std::vector<std::string> c = lines_of(read_text(copy_.cell_file()));
  ASSERT_EQ(c.size(), b.size());
  EXPECT_EQ(c[static_cast<std::size_t>(pick.line - 2)], b[static_cast<std::size_t>(pick.line - 2)]);
  EXPECT_EQ(c[static_cast<std::size_t>(pick.line - 2)].find("  #"), 0u) << "the comment above input_pick";
}

// A cell written in block style (each key on its own line), as a user's file may be: a location of that name is
// replaced by one in that style, in its place, its inner comment kept; every line outside it stays; the file loads
// with the taught pose.
TEST_F(LocationFile, ABlockStyleLocationIsReplacedInItsOwnStyle) {
  std::string text = before_;
  const std::string drop = "  - {name: output_drop, at: output.enter, reach: [melfa]}\n";
  const std::size_t at = text.find(drop);
  ASSERT_NE(at, std::string::npos) << "scenes/cell.yaml's output_drop line changed";
  const std::string block = "  - name: taught_a\n    at: input.leave\n    # taught at the belt's end\n"
                            "    reach:\n      - puma\n";
  text.insert(at + drop.size(), block);
  write_text(copy_.cell_file(), text);
  const SavedLocation s = save_location(copy_.cell_file(), "cell.yaml", "taught_a", "puma", taught_);
  EXPECT_TRUE(s.replaced);
  const std::string after = read_text(copy_.cell_file());
  const std::string head = text.substr(0, at + drop.size()), tail = text.substr(at + drop.size() + block.size());
  ASSERT_EQ(after.substr(0, head.size()), head);
  ASSERT_EQ(after.substr(after.size() - tail.size()), tail);
  const std::vector<std::string> item = lines_of(after.substr(head.size(), after.size() - head.size() - tail.size()));
  ASSERT_EQ(item.size(), 4u) << after.substr(head.size(), 400);
  EXPECT_EQ(item[0], "  - name: taught_a");
  EXPECT_EQ(item[1].rfind("    pose: {xyz: [", 0), 0u) << item[1];
  EXPECT_EQ(item[2], "    reach: [puma]");
  EXPECT_EQ(item[3], "    # taught at the belt's end");
  EXPECT_EQ(s.line, static_cast<int>(lines_of(head).size()) + 1);
  const models::CellDescription again = models::load_cell(copy_.cell_file());
  EXPECT_LT((grasp_of(again, *again.find_location("taught_a"), "puma").translation() - taught_.translation()).norm(),
            1e-3);
}

TEST_F(LocationFile, RefusalsLeaveTheFileByteForByte) {
  auto refused = [&](const std::string& name, const Eigen::Isometry3d& tool, const std::string& why) {
    try {
      save_location(copy_.cell_file(), "cell.yaml", name, "puma", tool);
      ADD_FAILURE() << "saved '" << name << "'";
    } catch (const LiveRefusal& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    EXPECT_EQ(read_text(copy_.cell_file()), before_) << name;
  };
  refused("9lives", taught_, "not a location name");
  refused("two words", taught_, "not a location name");
  Eigen::Isometry3d tilted = taught_;
  tilted.linear() = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()) * tilted.linear();
  refused("tilted", tilted, "away from straight down");
  Eigen::Isometry3d far = taught_;
  far.translation().x() += 3;
  refused("far", far, "the cell would not load");
  // A location written as a flow mapping over two lines: refused (edit it by hand), named with its line.
  const std::string drop = "  - {name: output_drop, at: output.enter, reach: [melfa]}\n";
  std::string two_lines = before_;
  two_lines.insert(two_lines.find(drop) + drop.size(), "  - {name: taught_c,\n     at: input.leave, reach: [puma]}\n");
  write_text(copy_.cell_file(), two_lines);
  before_ = two_lines;
  refused("taught_c", taught_, "is written in a way this cannot replace");
  // A file that no longer parses.
  const std::string broken = before_ + "\nlocations: [: :\n";
  write_text(copy_.cell_file(), broken);
  before_ = broken;
  refused("taught_b", taught_, "not YAML");
  EXPECT_FALSE(std::filesystem::exists(copy_.dir() / ".cell.yaml.teach-tmp"));
}

TEST(UnifiedDiff, OneHunkWithThreeLinesOfContext) {
  EXPECT_EQ(unified_diff("a\nb\nc\nd\ne\nf\ng\nh\n", "a\nb\nc\nd\ne\nX\nf\ng\nh\n", "f.yaml"),
            "--- f.yaml\n+++ f.yaml\n@@ -3,6 +3,7 @@\n c\n d\n e\n+X\n f\n g\n h\n");
  EXPECT_EQ(unified_diff("a\nb\n", "a\nc\n", "f"), "--- f\n+++ f\n@@ -1,2 +1,2 @@\n a\n-b\n+c\n");
  EXPECT_EQ(unified_diff("same\n", "same\n", "f"), "");
}

}  // namespace
}  // namespace cellwright::cell
