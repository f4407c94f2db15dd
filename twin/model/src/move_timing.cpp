#include "cellwright/twin/sim/move_timing.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

StraightLine straight_line(const models::KinematicChain& chain, const Eigen::VectorXd& seed,
                           const Eigen::Isometry3d& goal, double linear_step, double max_waypoint_step,
                           const models::IkOptions& ik_options) {
  CW_CHECK(linear_step > 0.0 && max_waypoint_step > 0.0, "linear step {} m, waypoint step {} rad", linear_step,
           max_waypoint_step);
  StraightLine line;
  // Waypoints close enough that joint interpolation between them stays on the line.
  const Eigen::Isometry3d from = chain.forward(seed);
  const Eigen::Vector3d p0 = from.translation(), p1 = goal.translation();
  const Eigen::Quaterniond r0(from.linear()), r1(goal.linear());
  const double distance = (p1 - p0).norm();
  const double angle = r0.angularDistance(r1);
  const int steps =
      std::max(1, static_cast<int>(std::ceil(std::max(distance / linear_step, angle / kLinearAngleStep))));
  line.points = {seed};
  line.arc = {0.0};
  line.tool_distance = distance;
  for (int i = 1; i <= steps; ++i) {
    const double f = static_cast<double>(i) / steps;
    Eigen::Isometry3d waypoint = Eigen::Isometry3d::Identity();
    waypoint.linear() = r0.slerp(f, r1).toRotationMatrix();
    waypoint.translation() = p0 + f * (p1 - p0);
    const models::IkResult ik = chain.inverse(waypoint, line.points.back(), ik_options);
    if (ik.status != models::IkStatus::kOk) {
      line.problem = fmt::format(
          "straight line: no joint solution at {:.1f}% of the way, ({:.4f}, {:.4f}, {:.4f}) m: {}", 100.0 * f,
          waypoint.translation().x(), waypoint.translation().y(), waypoint.translation().z(), ik.reason);
      line.points.clear();
      return line;
    }
    const Eigen::VectorXd jump = (ik.q - line.points.back()).cwiseAbs();
    Eigen::Index worst = 0;
    if (jump.maxCoeff(&worst) > max_waypoint_step) {
      line.problem = fmt::format(
          "straight line: joint {} would jump {:.3f} rad at {:.1f}% of the way (a singularity or a change of "
          "configuration on the line)",
          worst + 1, jump[worst], 100.0 * f);
      line.points.clear();
      return line;
    }
    line.points.push_back(ik.q);
    line.arc.push_back(f);
  }
  return line;
}

double least_move_duration(const JointPath& path, std::optional<double> line_distance,
                           const Eigen::VectorXd& max_speed, double speed, double min_time, double max_tool_speed) {
  CW_CHECK(max_tool_speed > 0.0, "tool speed limit {} m/s", max_tool_speed);
  double duration = path.min_duration(max_speed, speed, min_time);
  if (line_distance) duration = std::max(duration, kQuinticPeakSpeed * *line_distance / (max_tool_speed * speed));
  return duration;
}

}  // namespace cellwright::twin::sim
