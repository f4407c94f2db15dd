// The targets of coordinated segments (docs/runtime.md, "Coordinated blocks"): the tool target of one robot's move in
// a segment of a coordinated block, as robot control resolves it (RobotControl::segment_target) and the motion plan
// predicts it (cell/plan estimate.hpp, plan_motions), one function for both.
//  - before the robot holds the workpiece: its own end of the workpiece's long axis (the master's end the one nearer
//    the master's base; the grasp point 6 cm in from the end, at most a quarter of the length), at the height of the
//    workpiece's own at/above target (environment_model.hpp resolve_target), pointing down with the fingers across
//    the axis; two poses (the fingers turned half a turn). The first approach (above) comes from anywhere (not
//    straight); the grasp goes straight.
//  - the follower, once it holds the workpiece: the master's target composed with the grasp transform (master tool
//    -> follower tool), measured at its first such move from the two tools then (the master must hold the workpiece
//    too) and kept in `carry`.
//  - the master, holding it: a translation of its tool (the workpiece keeps its orientation): up by the pick's
//    approach height (kept in `carry` by the moves before the grasp) for the lift; to where the held part's bottom
//    lands on a location (approach height above it for `above`) for the carry and the put-down.
//  - the master after the put-down (holding nothing, target a location): straight up by the location's approach
//    height.
// Every target but the first approach is a straight line of the tool (`*linear` true).
//
// Thread safety: a pure function (it reads the model and its arguments and writes only `carry` and `*linear`); any
// thread may call it on values it owns.
#pragma once

#include <Eigen/Geometry>

#include <optional>
#include <string>

#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

// What one robot of a block keeps between the segments of a carry.
struct CarryTargets {
  double approach = 0.08;                  // m: the pick's approach height (set by the moves before the grasp)
  std::optional<Eigen::Isometry3d> grasp;  // the follower's grasp transform, once measured
};

// One robot's segment move.
struct SegmentMove {
  std::string robot;                                       // this robot (cell name)
  std::string master;                                      // the block's master (cell name)
  bool is_master = false;                                  // this robot is the master
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();  // this robot's tool now (world)
  std::optional<Eigen::Isometry3d> master_tool;            // the master's tool now (world; nullopt: not known)
  std::optional<Eigen::Isometry3d> master_target;          // the follower: the master's target of this segment (world)
};

// The target of `move` in `segment` (see the top). `target` is bound to cell names; `segment` names the block's
// robots by their program labels (for the reasons). kFail with the reason when it cannot be resolved (a follower
// without the master's target, a grasp transform that cannot be measured yet, a target that names nothing); kWait or
// kFail from resolve_target for a workpiece not ready.
MotionTarget resolve_segment_target(const EnvironmentModel& model, const task::Target& target,
                                    const task::Segment& segment, const SegmentMove& move, CarryTargets& carry,
                                    const TargetOptions& options, bool* linear);

}  // namespace cellwright::runtime
