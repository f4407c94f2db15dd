// The targets of coordinated segments (segment_target.hpp).
#include "cellwright/runtime/segment_target.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "cellwright/models/robot_model.hpp"

namespace cellwright::runtime {

MotionTarget resolve_segment_target(const EnvironmentModel& m, const task::Target& target, const task::Segment& seg,
                                    const SegmentMove& move, CarryTargets& carry, const TargetOptions& options,
                                    bool* linear) {
  const bool master = move.is_master;
  MotionTarget out;
  out.resolution = MotionTarget::Resolution::kFail;
  const std::string what = task::to_string(target);
  const RobotState* self = m.find_robot(move.robot);
  const RobotState* lead = m.find_robot(move.master);
  if (self == nullptr || lead == nullptr) {
    out.reason = fmt::format("{} or {} is not a robot of the cell", move.robot, move.master);
    return out;
  }
  const WorkpieceState* w = m.find_workpiece(target.object);
  const bool holding = self->hold.has_value();
  const Eigen::Isometry3d& tcp = move.tool;
  *linear = true;
  auto one = [&](const Eigen::Isometry3d& pose, const char* how) {
    out.resolution = MotionTarget::Resolution::kOk;
    out.poses = {pose};
    out.rank = {0};
    const Eigen::Vector3d p = pose.translation();
    out.description = fmt::format("{} ({}): tool at ({:.3f}, {:.3f}, {:.3f})", what, how, p.x(), p.y(), p.z());
    return out;
  };
  if (w != nullptr && !holding) {
    // Before the grasp: this robot's end of the workpiece's long axis (the master's end is the one nearer its base),
    // at the heights the workpiece's own targets have, the fingers closing across the axis.
    task::Target at = target;
    at.kind = task::TargetKind::kAt;
    task::Target above = target;
    above.kind = task::TargetKind::kAbove;
    const MotionTarget r_at = resolve_target(m, move.robot, at, options);
    const MotionTarget r_above = resolve_target(m, move.robot, above, options);
    if (r_at.resolution != MotionTarget::Resolution::kOk) return r_at;
    if (r_above.resolution != MotionTarget::Resolution::kOk) return r_above;
    carry.approach = r_above.poses.front().translation().z() - r_at.poses.front().translation().z();
    Eigen::Index k = 0;
    const double length = w->size().maxCoeff(&k);
    const Eigen::Vector3d axis = w->pose.linear().col(k);
    const Eigen::Vector3d centre = w->pose.translation();
    const double half = length / 2.0;
    const double reach = half - std::min(0.06, half / 2.0);  // from the centre to a grasp point
    const double toward_master = axis.dot(lead->base().translation() - centre) >= 0.0 ? 1.0 : -1.0;
    const Eigen::Vector3d point_xy = centre + (master ? toward_master : -toward_master) * reach * axis;
    const double z = (target.kind == task::TargetKind::kAt ? r_at : r_above).poses.front().translation().z();
    const Eigen::Vector3d point(point_xy.x(), point_xy.y(), z);
    const double yaw = std::atan2(axis.y(), axis.x()) + std::numbers::pi / 2.0;
    const Eigen::Isometry3d first = models::grasp_pose(point, models::Approach::kDown, yaw, self->base());
    Eigen::Isometry3d turned = first;
    turned.linear() = first.linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
    out.resolution = MotionTarget::Resolution::kOk;
    out.poses = {first, turned};
    out.rank = {0, 0};
    out.description = fmt::format("{} ({} end): tool at ({:.3f}, {:.3f}, {:.3f})", what,
                                  master ? "master's" : "follower's", point.x(), point.y(), point.z());
    *linear = target.kind == task::TargetKind::kAt;  // the first approach comes from anywhere
    return out;
  }
  if (!master) {
    // The master's target composed with the grasp transform, measured once both hold the workpiece.
    if (!move.master_target) {
      out.reason = fmt::format("{} posted no target for segment {}", seg.master, seg.index);
      return out;
    }
    if (!carry.grasp) {
      if (!holding || !move.master_tool || !lead->hold) {
        out.reason = fmt::format("the grasp transform between {} and {} is not known: both must hold {}", seg.master,
                                 seg.follower, holding ? self->hold->workpiece : target.object);
        return out;
      }
      carry.grasp = move.master_tool->inverse() * tcp;
    }
    return one(*move.master_target * *carry.grasp, "following the master");
  }
  // The master while carrying, or departing after the put-down: a translation of its tool.
  Eigen::Isometry3d goal = tcp;
  if (w != nullptr) {  // the lift: straight up by the pick's approach height
    goal.translation().z() += carry.approach;
    return one(goal, "lift");
  }
  const CellLocation* l = m.find_location(target.object);
  if (l == nullptr) {
    out.reason = fmt::format("{} is neither a workpiece nor a location of the cell", target.object);
    return out;
  }
  const double raise = target.kind == task::TargetKind::kAbove ? l->approach_height : 0.0;
  if (!holding) {  // after the put-down: straight up from where the hand opened
    goal.translation().z() += l->approach_height;
    return one(goal, "depart");
  }
  const WorkpieceState* held = m.find_workpiece(self->hold->workpiece);
  const Eigen::Isometry3d part = tcp * self->hold->in_hand;
  // The part's half height along the world's vertical, so that its bottom lands on the location.
  const Eigen::Vector3d up_in_part = part.linear().transpose() * Eigen::Vector3d::UnitZ();
  const double half_height =
      0.5 * up_in_part.cwiseAbs().dot(held != nullptr ? held->size() : Eigen::Vector3d::Zero());
  const Eigen::Vector3d landing = l->pose.translation() + Eigen::Vector3d(0, 0, half_height + raise);
  goal.translation() += landing - part.translation();
  return one(goal, "carry");
}

}  // namespace cellwright::runtime
