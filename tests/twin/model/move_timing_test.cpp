// How the simulated controller plans a straight line and times a move (move_timing.hpp): the waypoints lie on the
// line, and the least duration is the joints' or, on a line, the tool's speed limit, whichever needs longer.
#include "cellwright/twin/sim/move_timing.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "cellwright/models/cell.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::twin::sim {
namespace {

// The PUMA of the shipped beam cell, at its home joints.
struct Puma {
  models::CellDescription cell = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/beam_cell.yaml");
  models::KinematicChain chain = models::robot_chain(*cell.find_robot("puma"));
  Eigen::VectorXd home = Eigen::Map<const Eigen::VectorXd>(cell.find_robot("puma")->home.data(), 6);
};

TEST(StraightLine, ItsWaypointsLieOnTheLineAtMostOneStepApart) {
  const Puma puma;
  const Eigen::Isometry3d from = puma.chain.forward(puma.home);
  Eigen::Isometry3d to = from;
  to.translation() += Eigen::Vector3d(0.05, 0.1, -0.08);
  const StraightLine line = straight_line(puma.chain, puma.home, to, 0.005, 0.25, {});
  ASSERT_TRUE(line.problem.empty()) << line.problem;
  const double length = (to.translation() - from.translation()).norm();
  EXPECT_NEAR(line.tool_distance, length, 1e-12);
  ASSERT_EQ(line.points.size(), static_cast<std::size_t>(std::ceil(length / 0.005)) + 1);
  EXPECT_EQ(line.points.front(), puma.home);
  EXPECT_DOUBLE_EQ(line.arc.back(), 1.0);
  for (std::size_t i = 0; i < line.points.size(); ++i) {
    const Eigen::Vector3d expected = from.translation() + line.arc[i] * (to.translation() - from.translation());
    EXPECT_LT((puma.chain.forward(line.points[i]).translation() - expected).norm(), 1e-4) << "waypoint " << i;
  }
}

TEST(StraightLine, ALineTheArmCannotFollowIsAProblemNamingWhereOnIt) {
  const Puma puma;
  Eigen::Isometry3d to = puma.chain.forward(puma.home);
  to.translation() += Eigen::Vector3d(3.0, 0, 0);
  const StraightLine line = straight_line(puma.chain, puma.home, to, 0.005, 0.25, {});
  // (Here the wrist would flip on the way out, before the line leaves the arm's reach.)
  EXPECT_THAT(line.problem, ::testing::HasSubstr("% of the way"));
  EXPECT_TRUE(line.points.empty());
}

TEST(LeastMoveDuration, AStraightLineIsHeldToTheToolSpeedTooAJointMoveIsNot) {
  const Puma puma;
  Eigen::Isometry3d to = puma.chain.forward(puma.home);
  to.translation() += Eigen::Vector3d(0, 0, 0.1);
  const StraightLine line = straight_line(puma.chain, puma.home, to, 0.005, 0.25, {});
  ASSERT_TRUE(line.problem.empty()) << line.problem;
  const JointPath path(line.points, line.arc);
  const Eigen::VectorXd fast = Eigen::VectorXd::Constant(6, 100.0);  // the joints never limit it
  // A slow tool: the quintic's peak at the tool's limit, 15/8 * 0.1 m / (0.2 m/s * 0.5).
  EXPECT_NEAR(least_move_duration(path, line.tool_distance, fast, 0.5, 0.2, 0.2), 1.875, 1e-12);
  // A fast tool: the shortest motion; joint-interpolated, the tool's limit does not count.
  EXPECT_DOUBLE_EQ(least_move_duration(path, line.tool_distance, fast, 0.5, 0.2, 100.0), 0.2);
  EXPECT_DOUBLE_EQ(least_move_duration(path, std::nullopt, fast, 0.5, 0.2, 0.2), 0.2);
  // Slow joints: the joints' limit, as JointPath::min_duration has it.
  const Eigen::VectorXd slow = Eigen::VectorXd::Constant(6, 0.1);
  EXPECT_DOUBLE_EQ(least_move_duration(path, line.tool_distance, slow, 0.5, 0.2, 100.0),
                   path.min_duration(slow, 0.5, 0.2));
}

}  // namespace
}  // namespace cellwright::twin::sim
