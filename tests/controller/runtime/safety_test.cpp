// The safety layer (safety.hpp, docs/faults.md section 4) as a pure function: a hand-built environment model of the
// paper's cell (scenes/cell.yaml) with obstacles, the other robot's tool and wrist forces put where each test needs
// them, and the PUMA's kinematics.
#include "cellwright/runtime/safety.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::paper_cell;
using ::testing::HasSubstr;

Eigen::VectorXd to_eigen(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// Distance from q to the straight segment a-b.
double to_segment(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((q - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - q).norm();
}

class SafetyTest : public ::testing::Test {
 protected:
  SafetyTest()
      : cell_(paper_cell()),
        puma_(models::KinematicChain::from_urdf_file(cell_.find_robot("puma")->urdf)),
        melfa_(models::KinematicChain::from_urdf_file(cell_.find_robot("melfa")->urdf)),
        model_(make_environment_model(cell_)) {
    home_ = model_.find_robot("puma")->joints;
    goal_ = home_;
    goal_[0] += 0.6;  // the waist turns: the tool sweeps sideways
    goal_[1] += 0.2;
  }

  // The PUMA's tool centre point (world) at `joints`.
  Eigen::Vector3d tool(const std::vector<double>& joints) const {
    return (model_.find_robot("puma")->base() * puma_.forward(to_eigen(joints))).translation();
  }
  // Half way along the tool's straight way from home to the goal.
  Eigen::Vector3d midway() const { return (tool(home_) + tool(goal_)) / 2; }

  void add_obstacle(const std::string& name, const Eigen::Vector3d& centre, double edge = 0.02) {
    model_.obstacles.push_back({name, centre, Eigen::Vector3d::Constant(edge)});
  }
  void put_melfa_tool_at(const Eigen::Vector3d& p) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.translation() = p;
    model_.find_robot("melfa")->tcp = t;
  }

  SafetyVerdict check(const std::vector<double>& goal, const SafetyOptions& options = {}) const {
    return check_safety(model_, "puma", puma_, home_, goal, options);
  }

  models::CellDescription cell_;
  const models::KinematicChain puma_, melfa_;
  EnvironmentModel model_;
  std::vector<double> home_, goal_;
};

// ---- distance_to_box and watched_points ----

TEST(RuntimeSafety, DistanceToABox) {
  const Eigen::Vector3d c(1, 2, 3), size(0.2, 0.4, 0.6);
  EXPECT_DOUBLE_EQ(distance_to_box(c, c, size), 0.0);                                  // the centre
  EXPECT_DOUBLE_EQ(distance_to_box(c + Eigen::Vector3d(0.05, 0.1, -0.2), c, size), 0.0);  // inside
  EXPECT_NEAR(distance_to_box(c + Eigen::Vector3d(0.1, 0, 0), c, size), 0.0, 1e-12);     // on a face
  EXPECT_NEAR(distance_to_box(c + Eigen::Vector3d(0.3, 0, 0), c, size), 0.2, 1e-12);      // off a face
  EXPECT_NEAR(distance_to_box(c + Eigen::Vector3d(0, -0.5, 0), c, size), 0.3, 1e-12);
  EXPECT_NEAR(distance_to_box(c + Eigen::Vector3d(0, 0, 0.4), c, size), 0.1, 1e-12);
  // Off a corner: the distance to the corner.
  EXPECT_NEAR(distance_to_box(c + Eigen::Vector3d(0.4, 0.5, 0.5), c, size), std::sqrt(0.09 + 0.09 + 0.04), 1e-12);
  // A box of no size is a point.
  EXPECT_NEAR(distance_to_box(Eigen::Vector3d(3, 4, 0), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()), 5.0, 1e-12);
}

TEST_F(SafetyTest, TheWatchedPointsAreTheWristAndTheTool) {
  const RobotState& r = *model_.find_robot("puma");
  const std::vector<Eigen::Vector3d> points = watched_points(puma_, r.base(), home_);
  ASSERT_EQ(points.size(), 4u);  // the frames after joints 4, 5, 6 and the tool centre point
  EXPECT_TRUE(points.back().isApprox(tool(home_), 1e-12));
  for (std::size_t k = 4; k <= 6; ++k) {
    EXPECT_TRUE(points[k - 4].isApprox((r.base() * puma_.joint_frame(to_eigen(home_), k)).translation(), 1e-12)) << k;
  }
  // Joints that do not fit the chain give nothing to watch.
  EXPECT_TRUE(watched_points(puma_, r.base(), {0.0, 0.0}).empty());
}

// ---- Obstacles ----

TEST_F(SafetyTest, AnObstacleOnTheWayStopsTheRobotNamingIt) {
  ASSERT_GT((tool(goal_) - tool(home_)).norm(), 0.2) << "the test's move must go somewhere";
  add_obstacle("box_1", midway());
  const SafetyVerdict v = check(goal_);
  EXPECT_TRUE(v.stop);
  EXPECT_TRUE(v.obstacle);
  EXPECT_THAT(v.reason, HasSubstr("obstacle box_1"));
  EXPECT_THAT(v.reason, HasSubstr("limit 0.050 m"));
}

TEST_F(SafetyTest, AnObstacleAtTheGoalStopsTheRobot) {
  add_obstacle("box_1", tool(goal_) + Eigen::Vector3d(0, 0, 0.03));
  const SafetyVerdict v = check(goal_);
  EXPECT_TRUE(v.stop);
  EXPECT_TRUE(v.obstacle);
}

TEST_F(SafetyTest, AnObstacleOffTheWayDoesNotStopTheRobot) {
  // Half a metre beside the middle of the tool's way, and below it: far from every watched point's way.
  const Eigen::Vector3d side = (tool(goal_) - tool(home_)).cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d where = midway() + 0.5 * side;
  const RobotState& r = *model_.find_robot("puma");
  const auto a = watched_points(puma_, r.base(), home_), b = watched_points(puma_, r.base(), goal_);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_GT(to_segment(where, a[i], b[i]), 0.2) << i;
  add_obstacle("box_2", where);
  const SafetyVerdict v = check(goal_);
  EXPECT_FALSE(v.stop) << v.reason;
  EXPECT_FALSE(v.obstacle);
  EXPECT_EQ(v.reason, "");
}

TEST_F(SafetyTest, ARobotStandingStillNextToAnObstacleBeyondTheDistanceIsNotStopped) {
  // 8 cm from the tool (the box's edge 6 cm from it): farther than the 5 cm.
  add_obstacle("box_3", tool(home_) + Eigen::Vector3d(0.08, 0, 0));
  EXPECT_FALSE(check({}).stop);
  EXPECT_FALSE(check(home_).stop);  // a goal where it stands is standing still
  // Moved onto the way of a move, it stops the move.
  model_.obstacles[0].centre = midway();
  EXPECT_TRUE(check(goal_).stop);
}

TEST_F(SafetyTest, ARobotStandingStillTooCloseToAnObstacleIsStopped) {
  add_obstacle("box_4", tool(home_) + Eigen::Vector3d(0.03, 0, 0));  // the box's edge 2 cm from the tool
  const SafetyVerdict v = check({});
  EXPECT_TRUE(v.stop);
  EXPECT_TRUE(v.obstacle);
  EXPECT_THAT(v.reason, HasSubstr("obstacle box_4 0.020 m"));
}

TEST_F(SafetyTest, TheObstacleDistanceIsAnOption) {
  add_obstacle("box_5", tool(home_) + Eigen::Vector3d(0.08, 0, 0));  // the box's edge 7 cm from the tool
  SafetyOptions wide;
  wide.obstacle_distance = 0.1;
  EXPECT_TRUE(check({}, wide).stop);
  EXPECT_FALSE(check({}).stop);
}

// ---- The other robot ----

TEST_F(SafetyTest, TheOtherRobotsToolOnTheWayStopsTheMovingRobot) {
  put_melfa_tool_at(midway() + Eigen::Vector3d(0, 0, 0.05));
  ASSERT_GT((midway() - model_.geometry->handover->pose.xyz).norm(), 0.3) << "not in the hand-over zone";
  const SafetyVerdict v = check(goal_);
  EXPECT_TRUE(v.stop);
  EXPECT_FALSE(v.obstacle);
  EXPECT_THAT(v.reason, HasSubstr("robot melfa"));
  EXPECT_THAT(v.reason, HasSubstr("limit 0.100 m"));
}

TEST_F(SafetyTest, TheOtherRobotsToolIsNoReasonToStopStandingStill) {
  put_melfa_tool_at(tool(home_) + Eigen::Vector3d(0, 0, 0.05));
  EXPECT_FALSE(check({}).stop);
}

TEST_F(SafetyTest, OnlyTheRobotWhoseMotionClosesTheDistanceIsStopped) {
  // The other robot's tool 6 cm from the PUMA's tool, on the side away from where the PUMA goes: moving away is fine.
  const Eigen::Vector3d away = (tool(home_) - tool(goal_)).normalized();
  put_melfa_tool_at(tool(home_) + 0.06 * away);
  const SafetyVerdict leaving = check(goal_);
  EXPECT_FALSE(leaving.stop) << leaving.reason;
  // Coming back from the goal towards it closes the distance: stopped.
  const SafetyVerdict coming = check_safety(model_, "puma", puma_, goal_, home_, SafetyOptions{});
  EXPECT_TRUE(coming.stop);
  EXPECT_THAT(coming.reason, HasSubstr("robot melfa"));
}

TEST_F(SafetyTest, ToolsThatMeetInTheHandOverZoneAreNotStopped) {
  // The hand-over where the PUMA's move ends; the other robot's tool 4 cm from there.
  models::CellDescription cell = cell_;
  ASSERT_TRUE(cell.handover.has_value());
  cell.handover->pose.xyz = tool(goal_);
  model_ = make_environment_model(cell);
  put_melfa_tool_at(tool(goal_) + Eigen::Vector3d(0.04, 0, 0));
  const SafetyVerdict v = check(goal_);
  EXPECT_FALSE(v.stop) << v.reason;
  // Without a hand-over there, the same meeting stops the PUMA.
  cell.handover->pose.xyz = tool(goal_) + Eigen::Vector3d(1.0, 1.0, 0);
  model_ = make_environment_model(cell);
  put_melfa_tool_at(tool(goal_) + Eigen::Vector3d(0.04, 0, 0));
  const SafetyVerdict outside = check(goal_);
  EXPECT_TRUE(outside.stop);
  EXPECT_THAT(outside.reason, HasSubstr("robot melfa"));
}

TEST_F(SafetyTest, TheOtherRobotFarAwayDoesNotStopTheMove) {
  put_melfa_tool_at(midway() + Eigen::Vector3d(0, 0, 0.5));
  EXPECT_FALSE(check(goal_).stop);
}

// ---- Force ----

TEST_F(SafetyTest, AWristForceOverTheLimitStopsTheRobot) {
  model_.find_robot("puma")->wrist_force = Eigen::Vector3d(0, 180, -240);  // 300 N
  const SafetyVerdict v = check({});
  EXPECT_TRUE(v.stop);
  EXPECT_FALSE(v.obstacle);
  EXPECT_THAT(v.reason, HasSubstr("wrist force 300 N over the limit of 250 N"));
  EXPECT_TRUE(check(goal_).stop);
}

TEST_F(SafetyTest, AWristForceUnderTheLimitDoesNotStopTheRobot) {
  model_.find_robot("puma")->wrist_force = Eigen::Vector3d(0, 0, -200);
  EXPECT_FALSE(check(goal_).stop);
  SafetyOptions tight;
  tight.force_limit = 150;
  EXPECT_TRUE(check(goal_, tight).stop);
}

// ---- Off ----

TEST_F(SafetyTest, DisabledItStopsNothing) {
  add_obstacle("box_1", midway());
  put_melfa_tool_at(midway());
  model_.find_robot("puma")->wrist_force = Eigen::Vector3d(0, 0, 1000);
  SafetyOptions off;
  off.enabled = false;
  const SafetyVerdict v = check(goal_, off);
  EXPECT_FALSE(v.stop);
  EXPECT_FALSE(v.obstacle);
  EXPECT_EQ(v.reason, "");
  EXPECT_TRUE(check(goal_).stop);  // on, the same scene stops it
}

TEST_F(SafetyTest, ARobotTheModelDoesNotKnowIsNotStopped) {
  add_obstacle("box_1", midway());
  EXPECT_FALSE(check_safety(model_, "kuka", puma_, home_, goal_, SafetyOptions{}).stop);
}

// ---- check_carry: a coordinated carry (two robots holding one beam) ----

// The master's tool at the origin pointing down, the follower's 0.68 m along x (the grasp transform), both moving
// along +y at 0.1 m/s.
struct Carry {
  CarryHand master, follower;
  Eigen::Isometry3d grasp = Eigen::Isometry3d(Eigen::Translation3d(0.68, 0, 0));
  Carry() {
    master = {"left", "puma", Eigen::Isometry3d::Identity(), Eigen::Vector3d(0, 0, 20), false,
              Eigen::Vector3d(0, 0.1, 0)};
    follower = {"right", "melfa", grasp, Eigen::Vector3d(0, 0, 20), false, Eigen::Vector3d(0, 0.1, 0)};
  }
};

TEST(CarrySafety, BothToolsOnTheGraspTransformWithNoInternalForcePass) {
  const Carry c;
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_FALSE(v.stop) << v.reason;
  EXPECT_NEAR(v.error, 0.0, 1e-12);
  ASSERT_TRUE(v.squeeze.has_value());
  EXPECT_NEAR(*v.squeeze, 0.0, 1e-12);  // the two weights are vertical: nothing along the beam
}

TEST(CarrySafety, AnEndTheGripSensorLostStopsNamingThatArm) {
  Carry c;
  c.follower.grip_lost = true;
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(v.stop);
  EXPECT_EQ(v.symptom, "grip_lost");
  EXPECT_EQ(v.cause, "end_slipped");
  EXPECT_THAT(v.reason, HasSubstr("right (melfa)'s end of beam slipped"));
  EXPECT_EQ(v.arm, "right");  // the fault is the follower's, whichever robot watched the carry
}

TEST(CarrySafety, AFollowerBehindAlongTheMotionLags) {
  Carry c;
  c.follower.tcp->translation().y() -= 0.015;  // 15 mm behind, the pair moving along +y
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(v.stop);
  EXPECT_EQ(v.cause, "arm_lagging");
  EXPECT_NEAR(v.error, 0.015, 1e-9);
  EXPECT_THAT(v.reason, HasSubstr("right (melfa) lags left (puma)"));
  EXPECT_EQ(v.arm, "right");
  EXPECT_THAT(v.reason, HasSubstr("relative tool error 15.0 mm"));
  EXPECT_THAT(v.reason, HasSubstr("limits 10.0 mm"));
}

TEST(CarrySafety, AFollowerAheadMeansTheMasterLags) {
  Carry c;
  c.follower.tcp->translation().y() += 0.02;
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(v.stop);
  EXPECT_THAT(v.reason, HasSubstr("left (puma) lags right (melfa)"));
  EXPECT_EQ(v.arm, "left");
}

TEST(CarrySafety, AnErrorUnderTheLimitOrWithoutAGraspPasses) {
  Carry c;
  c.follower.tcp->translation().y() -= 0.008;
  EXPECT_FALSE(check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{}).stop);
  c.follower.tcp->translation().y() -= 0.1;
  EXPECT_FALSE(check_carry(c.master, c.follower, std::nullopt, "beam", SafetyOptions{}).stop);  // not measured yet
  SafetyOptions tight;
  tight.carry_error = 0.005;
  c.follower.tcp->translation().y() += 0.1;
  EXPECT_TRUE(check_carry(c.master, c.follower, c.grasp, "beam", tight).stop);
}

TEST(CarrySafety, ATurnedFollowerToolIsARelativeError) {
  Carry c;
  c.follower.tcp->linear() = Eigen::AngleAxisd(0.07, Eigen::Vector3d::UnitZ()).toRotationMatrix();  // 4 degrees
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(v.stop);
  EXPECT_NEAR(v.turn, 0.07, 1e-9);
  EXPECT_THAT(v.reason, HasSubstr("4.01 degrees"));
}

TEST(CarrySafety, TheInternalForceAlongTheBeamOverTheLimitStopsWithItsFigures) {
  Carry c;
  // The beam pushes the master's hand back (-x) and the follower's (+x), so the arms push them on (+x, -x): the hands
  // push the ends together with 45 N, on top of the same extra 30 N sideways on both (carried, not internal).
  c.master.force = Eigen::Vector3d(45, 30, 20);
  c.follower.force = Eigen::Vector3d(-45, 30, 20);
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(v.stop);
  EXPECT_EQ(v.cause, "squeeze_over_limit");
  ASSERT_TRUE(v.squeeze.has_value());
  EXPECT_NEAR(*v.squeeze, 45.0, 1e-9);
  EXPECT_THAT(v.reason, HasSubstr("squeeze beam: internal force 45.00 N over the limit of 40 N"));
  EXPECT_EQ(v.arm, "");  // both arms'

  // Pulling it apart is as bad.
  std::swap(c.master.force, c.follower.force);
  const CarryVerdict pull = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_TRUE(pull.stop);
  EXPECT_NEAR(*pull.squeeze, -45.0, 1e-9);
  EXPECT_THAT(pull.reason, HasSubstr("pull apart beam"));
}

TEST(CarrySafety, NoWristForceSensorsNoSqueezeCheck) {
  Carry c;
  c.master.force.reset();
  const CarryVerdict v = check_carry(c.master, c.follower, c.grasp, "beam", SafetyOptions{});
  EXPECT_FALSE(v.stop);
  EXPECT_FALSE(v.squeeze.has_value());
}

}  // namespace
}  // namespace cellwright::runtime
