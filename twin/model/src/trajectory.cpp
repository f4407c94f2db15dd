#include "cellwright/twin/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

double quintic(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10.0 + u * (-15.0 + 6.0 * u));
}

double quintic_rate(double u) {
  if (u <= 0.0 || u >= 1.0) return 0.0;
  return 30.0 * u * u * (1.0 - u) * (1.0 - u);
}

double quintic_accel(double u) {
  if (u <= 0.0 || u >= 1.0) return 0.0;
  return 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u);
}

JointPath::JointPath(std::vector<Eigen::VectorXd> points, std::vector<double> arc)
    : points_(std::move(points)), arc_(std::move(arc)) {
  CW_CHECK(points_.size() >= 2, "a joint path needs two points, got {}", points_.size());
  const Eigen::Index n = points_.front().size();
  CW_CHECK(n > 0, "a joint path needs joints");
  for (const auto& p : points_) {
    CW_CHECK(p.size() == n, "joint path points of sizes {} and {}", n, p.size());
    CW_CHECK(p.allFinite(), "joint path point is not finite");
  }
  if (arc_.empty()) {
    arc_.resize(points_.size(), 0.0);
    for (std::size_t i = 1; i < points_.size(); ++i) {
      arc_[i] = arc_[i - 1] + (points_[i] - points_[i - 1]).cwiseAbs().maxCoeff();
    }
    const double total = arc_.back();
    for (std::size_t i = 0; i < arc_.size(); ++i) {
      // Not moving at all: any monotone parameter will do.
      arc_[i] = total > 0.0 ? arc_[i] / total : static_cast<double>(i) / static_cast<double>(arc_.size() - 1);
    }
  }
  CW_CHECK(arc_.size() == points_.size(), "{} arc values for {} points", arc_.size(), points_.size());
  CW_CHECK(arc_.front() == 0.0 && arc_.back() == 1.0, "the arc must run from 0 to 1, got {} to {}", arc_.front(),
           arc_.back());
  for (std::size_t i = 1; i < arc_.size(); ++i) {
    CW_CHECK(arc_[i] > arc_[i - 1], "the arc must rise strictly: {} then {}", arc_[i - 1], arc_[i]);
  }
  arc_.back() = 1.0;
}

double JointPath::min_duration(const Eigen::VectorXd& max_speed, double speed, double min_time) const {
  CW_CHECK(max_speed.size() == points_.front().size(), "{} speed limits for {} joints", max_speed.size(),
           points_.front().size());
  CW_CHECK((max_speed.array() > 0.0).all() && max_speed.allFinite(), "speed limits must be positive");
  CW_CHECK(speed > 0.0 && speed <= 1.0, "speed {} outside (0, 1]", speed);
  CW_CHECK(min_time >= 0.0, "min_time {} < 0", min_time);
  // Joint velocity = dq/da * da/dt, and da/dt peaks at kQuinticPeakSpeed / T.
  double t = min_time;
  for (std::size_t i = 1; i < points_.size(); ++i) {
    const Eigen::VectorXd dq_da = (points_[i] - points_[i - 1]) / (arc_[i] - arc_[i - 1]);
    const double needed = kQuinticPeakSpeed * (dq_da.cwiseAbs().array() / (max_speed.array() * speed)).maxCoeff();
    t = std::max(t, needed);
  }
  return t;
}

JointSample JointPath::sample(double t, double duration) const {
  CW_CHECK(duration > 0.0, "duration {} must be positive", duration);
  const double u = t / duration;
  const double a = quintic(u);
  const double da = quintic_rate(u) / duration;
  const double dda = quintic_accel(u) / (duration * duration);
  // The segment holding a: the last with arc_[i] <= a (the final point belongs to the last segment).
  const auto it = std::upper_bound(arc_.begin(), arc_.end(), a);
  std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - arc_.begin() - 1, 0));
  i = std::min(i, points_.size() - 2);
  const double span = arc_[i + 1] - arc_[i];
  const double f = std::clamp((a - arc_[i]) / span, 0.0, 1.0);
  const Eigen::VectorXd dq_da = (points_[i + 1] - points_[i]) / span;
  JointSample s;
  s.position = points_[i] + f * (points_[i + 1] - points_[i]);
  s.velocity = dq_da * da;
  s.acceleration = dq_da * dda;
  return s;
}

double move_duration(const Eigen::VectorXd& from, const Eigen::VectorXd& to, const Eigen::VectorXd& max_speed,
                     double speed, double min_time) {
  return JointPath({from, to}).min_duration(max_speed, speed, min_time);
}

}  // namespace cellwright::twin::sim
