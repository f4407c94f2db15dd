// The preflight's motion sweep (sweep.hpp): a move through a fixed obstacle, and two arms whose moves cross while the
// net lets them run at once, are refused with the robots, the bodies and the program lines named; the same moves one
// after the other pass; every shipped scenario passes.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/sweep.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cellwright/task/to_net.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

const std::string kSource = CW_SOURCE_DIR;

// Two PUMAs facing each other across a 1.3 m gap. Each picks parts from its own side; M lies in the middle, where
// both can put a part down. `extra` is appended to the cell (more machines).
std::string two_arm_cell(const std::string& extra = "") {
  return fmt::format(R"(name: two-pumas
timestep: 0.005
robots:
  - name: r1
    urdf: {0}/models/urdf/puma560.urdf
    base: {{xyz: [0, 0, 0], yaw: 0}}
    home: [0, 84, -192, 0, -72, 90]
  - name: r2
    urdf: {0}/models/urdf/puma560.urdf
    base: {{xyz: [1.3, 0, 0], yaw: 180}}
    home: [0, 84, -192, 0, -72, 90]
locations:
  - {{name: pick_a, pose: {{xyz: [0.35, -0.4, 0.4], yaw: 0}}, reach: [r1]}}
  - {{name: pick_c, pose: {{xyz: [0.35, 0.4, 0.4], yaw: 0}}, reach: [r1]}}
  - {{name: pick_b, pose: {{xyz: [0.95, 0.4, 0.4], yaw: 0}}, reach: [r2]}}
  - {{name: M, pose: {{xyz: [0.65, 0, 0.4], yaw: 0}}, reach: [r1, r2]}}
workpieces:
  - {{name: A, shape: box, size: [0.04, 0.04, 0.06], mass: 0.1, colour: [0.85, 0.1, 0.1], on: pick_a}}
  - {{name: B, shape: box, size: [0.04, 0.04, 0.06], mass: 0.1, colour: [0.1, 0.3, 0.85], on: pick_b}}
  - {{name: C, shape: box, size: [0.04, 0.04, 0.06], mass: 0.1, colour: [0.15, 0.7, 0.2], on: pick_c}}
{1})",
                     kSource, extra);
}

// Both arms carry a part to M on line 7 (r1's Place M at column 3, r2's at column 13).
const char* const kAtOnce = R"(robot r1 r2
workpiece A B C
location M
steps
  r1      | r2
  Pick A  | Pick B
  Place M | Place M
  Pick C  |
end
)";
// The same moves, r2's on a line of its own after r1 has gone on to pick C.
const char* const kOneAfterTheOther = R"(robot r1 r2
workpiece A B C
location M
steps
  r1      | r2
  Pick A  | Pick B
  Place M |
  Pick C  |
          | Place M
end
)";

class Sweep : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("sweep_test_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }
  // Writes the cell, the program and a scenario naming both, and runs the preflight.
  Preflight check(const std::string& cell, const std::string& program) {
    write("cell.yaml", cell);
    write("p.task", program);
    return preflight(load_scenario(write("s.yaml", "cell: cell.yaml\nprogram: p.task\n")), &twin_port());
  }

  fs::path dir_;
};

// r1 alone carries A to M (line 7).
const char* const kOneArm = R"(robot r1
workpiece A
location M
steps
  r1
  Pick A
  Place M
end
)";

TEST_F(Sweep, AMoveThroughAFixedObstacleIsRefusedNamingBoth) {
  const std::string program = kOneArm;
  // Without the pillar the program passes ...
  const Preflight clear = check(two_arm_cell(), program);
  EXPECT_TRUE(clear.problems.empty()) << fmt::format("{}", fmt::join(clear.problems, "\n"));
  EXPECT_THAT(clear.collisions, IsEmpty()) << fmt::format("{}", fmt::join(clear.collisions, "\n"));
  EXPECT_TRUE(clear.ok());

  // ... with a pillar standing between A and M, the swing from A to M runs into it.
  const Preflight blocked = check(two_arm_cell(R"(machines:
  - name: pillar
    pose: {xyz: [0.55, -0.22, 0], yaw: 0}
    size: [0.08, 0.08, 0.9]
    fixture: {size: [0.04, 0.04, 0.01]}
    process_time: 0
)"),
                                  program);
  EXPECT_TRUE(blocked.ok(/*allow_collisions=*/true)) << fmt::format("{}", fmt::join(blocked.problems, "\n"));
  ASSERT_THAT(blocked.collisions, Not(IsEmpty()));
  EXPECT_FALSE(blocked.ok());
  EXPECT_EQ(blocked.problems.size(), blocked.collisions.size());  // each collision is a reason to refuse
  bool named = false;
  for (const std::string& c : blocked.collisions) {
    // The robot, the obstacle and the program line of the command (p.task line 7: Place M).
    named = named || (c.find("robot 'r1'") != std::string::npos && c.find("machine 'pillar'") != std::string::npos &&
                      c.find("p.task:7:") != std::string::npos);
  }
  EXPECT_TRUE(named) << fmt::format("{}", fmt::join(blocked.collisions, "\n"));
}

// A wall 1 cm thin across the swing from A to M, standing on the radius of r1's first joint: the arm passes through
// it between two poses unless the sampling is fine enough.
TEST_F(Sweep, AOneCentimetreWallIsCaught) {
  const Preflight pre = check(two_arm_cell(R"(machines:
  - name: wall
    pose: {xyz: [0.502, -0.224, 0], yaw: -24}
    size: [0.3, 0.01, 0.9]
    fixture: {size: [0.02, 0.005, 0.005]}
    process_time: 0
)"),
                              kOneArm);
  EXPECT_TRUE(pre.ok(/*allow_collisions=*/true)) << fmt::format("{}", fmt::join(pre.problems, "\n"));
  bool named = false;
  for (const std::string& c : pre.collisions) {
    named = named || (c.find("robot 'r1' hits machine 'wall'") != std::string::npos &&
                      c.find("p.task:7:3 'Place M'") != std::string::npos);
  }
  EXPECT_TRUE(named) << fmt::format("{}", fmt::join(pre.collisions, "\n"));
}

// Both arms carry a part to M on the same line: the net lets the two moves run at once, and they meet at M.
TEST_F(Sweep, ConcurrentMovesThatCrossAreRefusedNamingBothLines) {
  const Preflight pre = check(two_arm_cell(), kAtOnce);
  EXPECT_TRUE(pre.ok(/*allow_collisions=*/true)) << fmt::format("{}", fmt::join(pre.problems, "\n"));
  ASSERT_THAT(pre.collisions, Not(IsEmpty()));
  EXPECT_FALSE(pre.ok());
  bool named = false;
  for (const std::string& c : pre.collisions) {
    // Line 7, column 3 is r1's Place M; column 13 is r2's.
    named = named || (c.find("robots 'r1' and 'r2' collide") != std::string::npos &&
                      c.find("p.task:7:3 'Place M'") != std::string::npos &&
                      c.find("p.task:7:13 'Place M'") != std::string::npos);
  }
  EXPECT_TRUE(named) << fmt::format("{}", fmt::join(pre.collisions, "\n"));
}

// The same two moves on successive lines, r1 gone to pick C before r2 comes: the net never runs them at once.
TEST_F(Sweep, TheSameMovesOnSuccessiveLinesPass) {
  const Preflight pre = check(two_arm_cell(), kOneAfterTheOther);
  EXPECT_TRUE(pre.problems.empty()) << fmt::format("{}", fmt::join(pre.problems, "\n"));
  EXPECT_THAT(pre.collisions, IsEmpty()) << fmt::format("{}", fmt::join(pre.collisions, "\n"));
  EXPECT_TRUE(pre.ok());
  EXPECT_THAT(pre.sweep_summary, HasSubstr("reachable markings"));
}

// The sweep itself: what it explored, and that a finer resolution samples more poses.
TEST_F(Sweep, SamplesFinelyEnoughAndExploresTheNet) {
  write("cell.yaml", two_arm_cell());
  write("p.task", kOneAfterTheOther);
  const Scenario s = load_scenario(write("s.yaml", "cell: cell.yaml\nprogram: p.task\n"));
  const petri::Net net = task::to_net(s.program);
  const MotionPlan plan = plan_motions(s, net, runtime::TargetOptions{});
  SweepOptions coarse;
  coarse.resolution = 0.02;
  SweepOptions fine;
  fine.resolution = 0.005;
  const SweepReport a = sweep_motions(s, net, plan, coarse);
  const SweepReport b = sweep_motions(s, net, plan, fine);
  EXPECT_TRUE(a.exhaustive);
  EXPECT_GT(a.states, 1u);
  EXPECT_EQ(a.motions, b.motions);
  EXPECT_GT(a.motions, 5u);
  EXPECT_GT(b.samples, a.samples);
  EXPECT_TRUE(b.ok());
}

TEST(SweepShipped, EveryShippedScenarioPasses) {
  int checked = 0;
  for (const fs::path& dir : {fs::path(kSource) / "scenes", fs::path(kSource) / "scenes" / "soak"}) {
    for (const auto& entry : fs::directory_iterator(dir)) {
      if (entry.path().extension() != ".yaml" || entry.path().filename() == "cell.yaml" ||
          entry.path().filename() == "relay_cell.yaml" || entry.path().filename() == "beam_cell.yaml" ||
          entry.path().filename() == "recovery.yaml") {
        continue;
      }
      SCOPED_TRACE(entry.path().string());
      const Preflight pre = preflight(load_scenario(entry.path()), &twin_port());
      EXPECT_TRUE(pre.problems.empty()) << fmt::format("{}", fmt::join(pre.problems, "\n"));
      EXPECT_THAT(pre.collisions, IsEmpty()) << fmt::format("{}", fmt::join(pre.collisions, "\n"));
      EXPECT_FALSE(pre.sweep_summary.empty());
      ++checked;
    }
  }
  EXPECT_GE(checked, 6);
}

}  // namespace
}  // namespace cellwright::cell
