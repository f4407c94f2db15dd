// The targets of coordinated segments (segment_target.hpp): each arm's end of the beam before the grasp, the master's
// translations while carrying, and the follower's target made from the master's with the grasp transform.
#include "cellwright/runtime/segment_target.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "cellwright/models/cell.hpp"

namespace cellwright::runtime {
namespace {

using ::testing::HasSubstr;

// The shipped beam cell: the puma (master) and the melfa (follower) facing each other over a 0.8 m beam.
const models::CellDescription& beam_cell() {
  static const models::CellDescription cell =
      models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/beam_cell.yaml");
  return cell;
}

const task::Segment kSegment{"carry", 2, 9, "left", "right"};

SegmentMove move_of(const EnvironmentModel& m, const std::string& robot, const Eigen::Isometry3d& tool) {
  SegmentMove move;
  move.robot = robot;
  move.master = "puma";
  move.is_master = robot == "puma";
  move.tool = tool;
  move.master_tool = m.find_robot("puma")->tcp;
  return move;
}

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(x, y, z);
  return p;
}

TEST(SegmentTarget, BeforeTheGraspEachArmGoesToItsOwnEndOfTheBeam) {
  const EnvironmentModel m = make_environment_model(beam_cell());
  const WorkpieceState& beam = *m.find_workpiece("beam");
  const Eigen::Vector3d centre = beam.pose.translation();
  bool linear = true;
  CarryTargets master_carry, follower_carry;
  const task::Target above{task::TargetKind::kAbove, "beam"};
  const MotionTarget lead = resolve_segment_target(m, above, kSegment, move_of(m, "puma", at(0, 0, 1)), master_carry,
                                                   {}, &linear);
  ASSERT_EQ(lead.resolution, MotionTarget::Resolution::kOk) << lead.reason;
  EXPECT_FALSE(linear);  // the first approach comes from anywhere
  ASSERT_EQ(lead.poses.size(), 2u);  // the fingers either way round
  const MotionTarget follow = resolve_segment_target(m, above, kSegment, move_of(m, "melfa", at(0, 0, 1)),
                                                     follower_carry, {}, &linear);
  ASSERT_EQ(follow.resolution, MotionTarget::Resolution::kOk) << follow.reason;
  // Along the beam's long axis (x), 6 cm in from each end: the master's end is the one nearer its base (x = 0).
  const Eigen::Vector3d l = lead.poses.front().translation(), f = follow.poses.front().translation();
  EXPECT_NEAR(l.x(), centre.x() - 0.34, 1e-9);
  EXPECT_NEAR(f.x(), centre.x() + 0.34, 1e-9);
  EXPECT_NEAR(l.y(), centre.y(), 1e-9);
  EXPECT_NEAR(f.y(), centre.y(), 1e-9);
  // Pointing down, the fingers (tool y) across the beam; at the height of the beam's own `above` target.
  EXPECT_NEAR(lead.poses.front().linear().col(2).z(), -1.0, 1e-9);
  EXPECT_NEAR(std::abs(lead.poses.front().linear().col(1).y()), 1.0, 1e-9);
  const MotionTarget own = resolve_target(m, "puma", above);
  EXPECT_NEAR(l.z(), own.poses.front().translation().z(), 1e-9);
  // The pick's approach height is kept for the lift; the grasp itself goes straight down.
  const MotionTarget own_at = resolve_target(m, "puma", {task::TargetKind::kAt, "beam"});
  EXPECT_NEAR(master_carry.approach, l.z() - own_at.poses.front().translation().z(), 1e-12);
  resolve_segment_target(m, {task::TargetKind::kAt, "beam"}, kSegment, move_of(m, "puma", at(0, 0, 1)), master_carry,
                         {}, &linear);
  EXPECT_TRUE(linear);
}

// Both arms hold the beam: the master's tool at `master_tool`, the follower's at `follower_tool`.
EnvironmentModel holding(const Eigen::Isometry3d& master_tool, const Eigen::Isometry3d& follower_tool) {
  EnvironmentModel m = make_environment_model(beam_cell());
  WorkpieceState& beam = *m.find_workpiece("beam");
  m.find_robot("puma")->tcp = master_tool;
  m.find_robot("melfa")->tcp = follower_tool;
  m.find_robot("puma")->hold = Hold{"beam", models::Approach::kDown, 0.02, master_tool.inverse() * beam.pose};
  m.find_robot("melfa")->hold = Hold{"beam", models::Approach::kDown, 0.02, follower_tool.inverse() * beam.pose};
  beam.held_by = "melfa";
  return m;
}

TEST(SegmentTarget, TheFollowerComposesTheMastersTargetWithTheGraspTransformMeasuredOnce) {
  Eigen::Isometry3d master_tool = at(0.5, -0.2, 0.45);
  master_tool.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  Eigen::Isometry3d follower_tool = at(1.18, -0.2, 0.45);
  follower_tool.linear() = master_tool.linear() * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ());
  EnvironmentModel m = holding(master_tool, follower_tool);
  CarryTargets carry;
  bool linear = false;
  const task::Target up{task::TargetKind::kAbove, "beam"};
  SegmentMove move = move_of(m, "melfa", follower_tool);
  // Without the master's target there is nothing to follow.
  const MotionTarget none = resolve_segment_target(m, up, kSegment, move, carry, {}, &linear);
  EXPECT_EQ(none.resolution, MotionTarget::Resolution::kFail);
  EXPECT_THAT(none.reason, HasSubstr("left posted no target for segment 2"));
  // The master lifts by 0.1 m: the follower's target is the same lift of its own tool, as a straight line.
  move.master_target = at(0, 0, 0.1) * master_tool;
  const MotionTarget lift = resolve_segment_target(m, up, kSegment, move, carry, {}, &linear);
  ASSERT_EQ(lift.resolution, MotionTarget::Resolution::kOk) << lift.reason;
  EXPECT_TRUE(linear);
  ASSERT_TRUE(carry.grasp.has_value());
  EXPECT_TRUE(carry.grasp->isApprox(master_tool.inverse() * follower_tool, 1e-12));
  ASSERT_EQ(lift.poses.size(), 1u);
  EXPECT_TRUE(lift.poses.front().isApprox(at(0, 0, 0.1) * follower_tool, 1e-12));
  // Measured once: later segments use the same transform, wherever the tools are read then.
  move.tool = at(0.01, 0, 0) * follower_tool;
  move.master_target = at(0.3, 0.4, 0.1) * master_tool;
  const MotionTarget carried = resolve_segment_target(m, up, kSegment, move, carry, {}, &linear);
  EXPECT_TRUE(carried.poses.front().isApprox(at(0.3, 0.4, 0.1) * follower_tool, 1e-12));
  // A follower whose master holds nothing cannot measure the transform.
  EnvironmentModel loose = holding(master_tool, follower_tool);
  loose.find_robot("puma")->hold.reset();
  CarryTargets fresh;
  EXPECT_THAT(resolve_segment_target(loose, up, kSegment, move, fresh, {}, &linear).reason,
              HasSubstr("the grasp transform between left and right is not known"));
}

TEST(SegmentTarget, TheMasterTranslatesItsToolToLiftCarryAndDepart) {
  Eigen::Isometry3d master_tool = at(0.5, -0.2, 0.45);
  master_tool.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EnvironmentModel m = holding(master_tool, at(1.18, -0.2, 0.45));
  CarryTargets carry;
  carry.approach = 0.12;
  bool linear = false;
  const SegmentMove move = move_of(m, "puma", master_tool);
  const MotionTarget lift =
      resolve_segment_target(m, {task::TargetKind::kAbove, "beam"}, kSegment, move, carry, {}, &linear);
  EXPECT_TRUE(linear);
  EXPECT_TRUE(lift.poses.front().isApprox(at(0, 0, 0.12) * master_tool, 1e-12));
  // To the fixture: the beam's bottom on the location (its centre half its height above), the tool's orientation
  // kept; `above` the location's approach height higher.
  const CellLocation& fix = *m.find_location("beam_fix");
  const Eigen::Isometry3d beam_now = master_tool * m.find_robot("puma")->hold->in_hand;
  const MotionTarget put = resolve_segment_target(m, {task::TargetKind::kAt, "beam_fix"}, kSegment, move, carry, {},
                                                  &linear);
  ASSERT_EQ(put.resolution, MotionTarget::Resolution::kOk) << put.reason;
  const Eigen::Vector3d beam_there = put.poses.front() * (master_tool.inverse() * beam_now.translation());
  EXPECT_TRUE(beam_there.isApprox(fix.pose.translation() + Eigen::Vector3d(0, 0, 0.02), 1e-9));
  EXPECT_TRUE(put.poses.front().linear().isApprox(master_tool.linear()));
  const MotionTarget over = resolve_segment_target(m, {task::TargetKind::kAbove, "beam_fix"}, kSegment, move, carry,
                                                   {}, &linear);
  EXPECT_NEAR(over.poses.front().translation().z() - put.poses.front().translation().z(), fix.approach_height, 1e-12);
  // Let go of: straight up by the approach height.
  m.find_robot("puma")->hold.reset();
  const MotionTarget depart = resolve_segment_target(m, {task::TargetKind::kAbove, "beam_fix"}, kSegment, move, carry,
                                                     {}, &linear);
  EXPECT_TRUE(depart.poses.front().isApprox(at(0, 0, fix.approach_height) * master_tool, 1e-12));
}

}  // namespace
}  // namespace cellwright::runtime
