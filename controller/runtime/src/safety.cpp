#include "cellwright/runtime/safety.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace cellwright::runtime {

namespace {

Eigen::VectorXd to_eigen(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// Points along the straight ways from `from` to `to` (pairwise), every 2 cm, ends included.
std::vector<Eigen::Vector3d> sweep(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to) {
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector3d& a = from[i];
    const Eigen::Vector3d& b = i < to.size() ? to[i] : from[i];
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / 0.02)));
    for (int k = 0; k <= n; ++k) out.push_back(a + (b - a) * (static_cast<double>(k) / n));
  }
  return out;
}

double min_distance(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& q) {
  double d = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p : points) d = std::min(d, (p - q).norm());
  return d;
}

}  // namespace

std::vector<Eigen::Vector3d> watched_points(const models::KinematicChain& chain, const Eigen::Isometry3d& base,
                                            const std::vector<double>& joints) {
  std::vector<Eigen::Vector3d> out;
  if (joints.size() != chain.dof()) return out;
  const std::vector<Eigen::Isometry3d> frames = chain.frames(to_eigen(joints));
  const std::size_t first = chain.dof() > 3 ? chain.dof() - 2 : 1;  // joint frames count from 1
  for (std::size_t k = first; k <= chain.dof(); ++k) out.push_back(base * frames[k - 1].translation());
  out.push_back(base * frames.back().translation());
  return out;
}

double distance_to_box(const Eigen::Vector3d& p, const Eigen::Vector3d& centre, const Eigen::Vector3d& size) {
  const Eigen::Vector3d d = ((p - centre).cwiseAbs() - size / 2).cwiseMax(0.0);
  return d.norm();
}

SafetyVerdict check_safety(const EnvironmentModel& model, const std::string& robot,
                           const models::KinematicChain& chain, const std::vector<double>& joints,
                           const std::vector<double>& goal_joints, const SafetyOptions& options) {
  SafetyVerdict v;
  if (!options.enabled) return v;
  const RobotState* self = model.find_robot(robot);
  if (self == nullptr) return v;
  if (self->wrist_force && self->wrist_force->norm() > options.force_limit) {
    v.stop = true;
    v.reason = fmt::format("wrist force {:.0f} N over the limit of {:.0f} N", self->wrist_force->norm(),
                           options.force_limit);
    return v;
  }
  const std::vector<Eigen::Vector3d> now = watched_points(chain, self->base(), joints);
  if (now.empty()) return v;
  const bool moving = goal_joints.size() == joints.size() && goal_joints != joints;
  const std::vector<Eigen::Vector3d> path =
      moving ? sweep(now, watched_points(chain, self->base(), goal_joints)) : now;
  for (const ObstacleState& o : model.obstacles) {
    double d = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : path) d = std::min(d, distance_to_box(p, o.centre, o.size));
    if (d < options.obstacle_distance) {
      v.stop = true;
      v.obstacle = true;
      v.reason = fmt::format("obstacle {} {:.3f} m from the arm's way (limit {:.3f} m)", o.name, d,
                             options.obstacle_distance);
      return v;
    }
  }
  if (!moving) return v;
  const Eigen::Vector3d& tool = now.back();
  const bool has_handover = model.geometry->handover.has_value();
  const Eigen::Vector3d handover = has_handover ? model.geometry->handover->pose.xyz : Eigen::Vector3d::Zero();
  for (const RobotState& other : model.robots) {
    if (other.name == robot || !other.tcp) continue;
    const Eigen::Vector3d q = other.tcp->translation();
    if (has_handover && (q - handover).norm() < options.handover_zone &&
        ((tool - handover).norm() < options.handover_zone || (path.back() - handover).norm() < options.handover_zone)) {
      continue;  // a hand-over: the hands meet on purpose
    }
    const double d = min_distance(path, q);
    // Only the robot whose motion closes the distance stops: the other may move away.
    if (d < options.robot_distance && d < min_distance(now, q) - 1e-6) {
      v.stop = true;
      v.reason = fmt::format("robot {} {:.3f} m from the arm's way (limit {:.3f} m)", other.name, d,
                             options.robot_distance);
      return v;
    }
  }
  return v;
}

CarryVerdict check_carry(const CarryHand& master, const CarryHand& follower,
                         const std::optional<Eigen::Isometry3d>& grasp, const std::string& workpiece,
                         const SafetyOptions& options) {
  CarryVerdict v;
  const auto name = [](const CarryHand& h) { return fmt::format("{} ({})", h.label, h.cell); };
  for (const CarryHand* h : {&master, &follower}) {
    if (!h->grip_lost) continue;
    v.stop = true;
    v.symptom = "grip_lost";
    v.cause = "end_slipped";
    v.reason = fmt::format("{}'s end of {} slipped: its grip sensor no longer has it", name(*h), workpiece);
    v.arm = h->label;
    return v;
  }
  if (master.tcp && follower.tcp && grasp) {
    const Eigen::Isometry3d expected = *master.tcp * *grasp;
    const Eigen::Isometry3d off = expected.inverse() * *follower.tcp;
    v.error = off.translation().norm();
    v.turn = Eigen::AngleAxisd(off.linear()).angle();
    if (v.error > options.carry_error || v.turn > options.carry_turn) {
      v.stop = true;
      v.symptom = "protective_stop";
      v.cause = "arm_lagging";
      const Eigen::Vector3d ahead = follower.tcp->translation() - expected.translation();  // the follower's lead
      const Eigen::Vector3d motion = master.velocity + follower.velocity;
      std::string who;
      if (motion.norm() > 1e-3 && std::abs(ahead.dot(motion.normalized())) > 0.5 * v.error) {
        const bool follower_lags = ahead.dot(motion) < 0;
        const CarryHand& lagging = follower_lags ? follower : master;
        who = fmt::format("{} lags {}", name(lagging), name(follower_lags ? master : follower));
        v.arm = lagging.label;
      } else {
        who = fmt::format("{} is off its place next to {}", name(follower), name(master));
        v.arm = follower.label;
      }
      v.reason = fmt::format("{} carrying {}: relative tool error {:.1f} mm, {:.2f} degrees (limits {:.1f} mm, {:.2f} degrees)",
                             who, workpiece, v.error * 1000.0, v.turn * 180.0 / std::numbers::pi, options.carry_error * 1000.0,
                             options.carry_turn * 180.0 / std::numbers::pi);
      return v;
    }
  }
  if (master.tcp && follower.tcp && master.force && follower.force) {
    const Eigen::Vector3d between = follower.tcp->translation() - master.tcp->translation();
    if (between.norm() > 1e-9) {
      v.squeeze = (*master.force - *follower.force).dot(between.normalized()) / 2.0;
      if (std::abs(*v.squeeze) > options.squeeze_force) {
        v.stop = true;
        v.symptom = "protective_stop";
        v.cause = "squeeze_over_limit";
        v.reason = fmt::format("{} and {} {} {}: internal force {:.2f} N over the limit of {} N", name(master),
                               name(follower), *v.squeeze > 0 ? "squeeze" : "pull apart", workpiece,
                               std::abs(*v.squeeze), options.squeeze_force);
      }
    }
  }
  return v;
}

}  // namespace cellwright::runtime
