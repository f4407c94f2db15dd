// Forward kinematics, Jacobian and the damped-least-squares inverse kinematics of a KinematicChain.
#include "cellwright/models/kinematics.hpp"

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::models {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;

// Deterministic and platform-independent restarts (std::uniform_real_distribution is not specified bit for bit).
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  // Uniform in [0, 1).
  double next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_;
};

// Range sampled for restarts; continuous joints get one turn.
JointLimit sampling_range(const JointLimit& l) {
  constexpr double kPi = std::numbers::pi;
  return {std::isfinite(l.lower) ? l.lower : -kPi, std::isfinite(l.upper) ? l.upper : kPi};
}

double clamp_to(double v, const JointLimit& l) {
  if (!std::isfinite(v)) {
    const JointLimit r = sampling_range(l);
    return 0.5 * (r.lower + r.upper);
  }
  return std::clamp(v, l.lower, l.upper);
}

// Position error and rotation vector (base frame) taking `reached` to `target`.
Vector6d pose_error(const Eigen::Isometry3d& reached, const Eigen::Isometry3d& target) {
  Vector6d e;
  e.head<3>() = target.translation() - reached.translation();
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(target.linear() * reached.linear().transpose()));
  e.tail<3>() = aa.angle() * aa.axis();
  return e;
}

// Paden-Kahan subproblem 1: the angle turning p into q about the unit axis w (through the origin).
double subproblem1(const Eigen::Vector3d& w, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  const Eigen::Vector3d u = p - w * w.dot(p), v = q - w * w.dot(q);
  return std::atan2(w.dot(u.cross(v)), u.dot(v));
}

// Paden-Kahan subproblem 2: the angle pairs (t1, t2) with exp(w1 t1) exp(w2 t2) p = q, for non-parallel unit axes
// through the origin; none, one or two pairs.
std::vector<std::pair<double, double>> subproblem2(const Eigen::Vector3d& w1, const Eigen::Vector3d& w2,
                                                   const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  const double c = w1.dot(w2), den = c * c - 1;
  const double alpha = (c * w2.dot(p) - w1.dot(q)) / den;
  const double beta = (c * w1.dot(q) - w2.dot(p)) / den;
  const Eigen::Vector3d n = w1.cross(w2);
  double gamma2 = (p.squaredNorm() - alpha * alpha - beta * beta - 2 * alpha * beta * c) / n.squaredNorm();
  if (gamma2 < -1e-12) return {};
  gamma2 = std::max(gamma2, 0.0);
  std::vector<std::pair<double, double>> out;
  for (double sign : {1.0, -1.0}) {
    // z = exp(w2 t2) p = exp(-w1 t1) q
    const Eigen::Vector3d z = alpha * w1 + beta * w2 + sign * std::sqrt(gamma2) * n;
    out.emplace_back(subproblem1(w1, z, q), subproblem1(w2, p, z));
    if (gamma2 == 0) break;
  }
  return out;
}

Eigen::Matrix3d rotation(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
}

struct Attempt {
  Eigen::VectorXd q;
  double position_error = std::numeric_limits<double>::infinity();
  double orientation_error = std::numeric_limits<double>::infinity();
  bool converged = false;
};

}  // namespace

bool KinematicChain::within_limits(const Eigen::VectorXd& q) const {
  if (static_cast<std::size_t>(q.size()) != dof()) return false;
  for (std::size_t i = 0; i < dof(); ++i) {
    const double v = q[static_cast<Eigen::Index>(i)];
    if (std::isnan(v) || v < limits_[i].lower || v > limits_[i].upper) return false;
  }
  return true;
}

Eigen::Isometry3d KinematicChain::forward(const Eigen::VectorXd& q) const {
  CW_CHECK(static_cast<std::size_t>(q.size()) == dof(), "forward: q has {} entries, the chain {} joints", q.size(),
           dof());
  return partial_forward(q, dof()) * tip_offset_;
}

Jacobian KinematicChain::jacobian(const Eigen::VectorXd& q) const {
  CW_CHECK(static_cast<std::size_t>(q.size()) == dof(), "jacobian: q has {} entries, the chain {} joints", q.size(),
           dof());
  Jacobian jac(6, static_cast<Eigen::Index>(dof()));
  std::vector<Eigen::Vector3d> axes(dof()), origins(dof());
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Joint& j = joints_[i];
    const double qi = q[static_cast<Eigen::Index>(i)];
    t = t * j.origin;
    // The axis is the same before and after the joint's own motion, and a revolute joint does not move its origin.
    axes[i] = t.linear() * j.axis;
    origins[i] = t.translation();
    if (j.prismatic) {
      t.translate(qi * j.axis);
    } else {
      t.rotate(Eigen::AngleAxisd(qi, j.axis));
    }
  }
  const Eigen::Vector3d tip = (t * tip_offset_).translation();
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    if (joints_[i].prismatic) {
      jac.col(c) << axes[i], Eigen::Vector3d::Zero();
    } else {
      jac.col(c) << axes[i].cross(tip - origins[i]), axes[i];
    }
  }
  return jac;
}

void KinematicChain::Joint::advance(Eigen::Isometry3d& t, double q) const {
  t = t * origin;
  if (prismatic) {
    t.translate(q * axis);
  } else {
    t.rotate(Eigen::AngleAxisd(q, axis));
  }
}

Eigen::Isometry3d KinematicChain::partial_forward(const Eigen::VectorXd& q, std::size_t count) const {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < count; ++i) joints_[i].advance(t, q[static_cast<Eigen::Index>(i)]);
  return t;
}

std::vector<Eigen::Isometry3d> KinematicChain::frames(const Eigen::VectorXd& q) const {
  CW_CHECK(static_cast<std::size_t>(q.size()) == dof(), "frames: q has {} entries, the chain {} joints", q.size(),
           dof());
  std::vector<Eigen::Isometry3d> out;
  out.reserve(dof() + 1);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < dof(); ++i) {
    joints_[i].advance(t, q[static_cast<Eigen::Index>(i)]);
    out.push_back(t);
  }
  out.push_back(t * tip_offset_);
  return out;
}

void KinematicChain::find_spherical_wrist() {
  wrist_ = Wrist{};
  if (dof() != 6 || joints_[3].prismatic || joints_[4].prismatic || joints_[5].prismatic) return;
  // The wrist axes at q = 0, in the base frame.
  Eigen::Vector3d point[3], dir[3];
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < 6; ++i) {
    t = t * joints_[i].origin;
    if (i >= 3) {
      point[i - 3] = t.translation();
      dir[i - 3] = t.linear() * joints_[i].axis;
    }
  }
  if (dir[0].cross(dir[1]).norm() < 1e-6 || dir[1].cross(dir[2]).norm() < 1e-6) return;
  // The point nearest all three lines; the wrist is spherical if it lies on each of them.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    const Eigen::Matrix3d proj = Eigen::Matrix3d::Identity() - dir[k] * dir[k].transpose();
    a += proj;
    b += proj * point[k];
  }
  const Eigen::Vector3d centre = a.ldlt().solve(b);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d off = centre - point[k];
    if ((off - dir[k] * dir[k].dot(off)).norm() > 1e-9) return;
  }
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(6);
  const Eigen::Isometry3d arm = partial_forward(zero, 3), tip = forward(zero);
  wrist_.present = true;
  wrist_.centre_in_arm = arm.inverse() * centre;
  wrist_.centre_in_tip = tip.inverse() * centre;
  for (int k = 0; k < 3; ++k) wrist_.axis[k] = arm.linear().transpose() * dir[k];
  wrist_.tip_rotation = arm.linear().transpose() * tip.linear();
}

std::vector<Eigen::VectorXd> KinematicChain::wrist_solutions(const Eigen::Isometry3d& target,
                                                             const Eigen::VectorXd& seed, bool& complete) const {
  std::vector<Eigen::VectorXd> out;
  const Eigen::Vector3d centre = target * wrist_.centre_in_tip;

  // Joints 1-3 put the wrist centre in place: at most a few isolated solutions (four for these arms), found by
  // Levenberg-Marquardt from the seed and from starts spread over the joint space, limits ignored, duplicates
  // dropped. The starts are stratified (joint 1 in quarter turns, joints 2 and 3 in half turns, a fixed pseudo-random
  // point in each cell) because the solutions' basins can be very unequal near the joint 1 axis.
  constexpr int kCells[3] = {4, 2, 2};
  constexpr int kArmStarts = 1 + kCells[0] * kCells[1] * kCells[2];
  constexpr double kArmTolerance = 1e-11;
  std::vector<Eigen::Vector3d> arms;
  SplitMix64 rng(0x7772697374ULL);
  // Three joints place a point in at most four ways (a quartic), so the search can stop at four.
  constexpr std::size_t kMaxArmSolutions = 4;
  bool isolated = true;
  for (int s_i = 0; s_i < kArmStarts && arms.size() < kMaxArmSolutions; ++s_i) {
    Eigen::VectorXd q = seed;
    for (int i = 0, cell = s_i - 1; s_i > 0 && i < 3; cell /= kCells[i], ++i) {
      const auto k = static_cast<std::size_t>(i);
      const JointLimit r =
          joints_[k].prismatic ? sampling_range(limits_[k]) : JointLimit{-std::numbers::pi, std::numbers::pi};
      const double width = (r.upper - r.lower) / kCells[i];
      q[i] = r.lower + width * ((cell % kCells[i]) + rng.next());
    }
    bool converged = false;
    Eigen::Matrix3d jac;
    for (int it = 0; it < 100; ++it) {
      const Eigen::Isometry3d arm = partial_forward(q, 3);
      const Eigen::Vector3d c = arm * wrist_.centre_in_arm, e = centre - c;
      Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
      for (std::size_t i = 0; i < 3; ++i) {
        t = t * joints_[i].origin;
        const Eigen::Vector3d w = t.linear() * joints_[i].axis;
        jac.col(static_cast<Eigen::Index>(i)) =
            joints_[i].prismatic ? w : Eigen::Vector3d(w.cross(c - t.translation()));
        const double qi = q[static_cast<Eigen::Index>(i)];
        if (joints_[i].prismatic) {
          t.translate(qi * joints_[i].axis);
        } else {
          t.rotate(Eigen::AngleAxisd(qi, joints_[i].axis));
        }
      }
      if (e.norm() < kArmTolerance) {
        converged = true;
        break;
      }
      Eigen::Matrix3d h = jac.transpose() * jac;
      h.diagonal().array() += e.squaredNorm() + 1e-12;
      const Eigen::Vector3d dq = h.ldlt().solve(jac.transpose() * e);
      for (Eigen::Index i = 0; i < 3; ++i) {
        // Prismatic joints cannot wrap round: keep them within their travel.
        q[i] = joints_[static_cast<std::size_t>(i)].prismatic
                   ? clamp_to(q[i] + dq[i], limits_[static_cast<std::size_t>(i)])
                   : q[i] + dq[i];
      }
    }
    if (!converged) continue;
    Eigen::Vector3d arm = q.head<3>();
    for (Eigen::Index i = 0; i < 3; ++i) {
      if (!joints_[static_cast<std::size_t>(i)].prismatic) arm[i] = std::remainder(arm[i], 2 * std::numbers::pi);
    }
    auto same = [&](const Eigen::Vector3d& other) {
      for (Eigen::Index i = 0; i < 3; ++i) {
        double d = arm[i] - other[i];
        if (!joints_[static_cast<std::size_t>(i)].prismatic) d = std::remainder(d, 2 * std::numbers::pi);
        if (std::abs(d) > 1e-6) return false;
      }
      return true;
    };
    if (std::none_of(arms.begin(), arms.end(), same)) arms.push_back(arm);
    // At a singular arm pose the solutions form a continuum (e.g. the wrist centre on joint 1's axis), so four
    // found ones are not all of them.
    isolated = isolated && Eigen::JacobiSVD<Eigen::Matrix3d>(jac).singularValues().minCoeff() > 1e-6;
  }

  complete = arms.size() == kMaxArmSolutions && isolated;

  // Joints 4-6 then turn the tip into place: exp(w4 q4) exp(w5 q5) exp(w6 q6) = wanted, in joint 3's moving frame.
  const Eigen::Vector3d& w4 = wrist_.axis[0];
  const Eigen::Vector3d& w5 = wrist_.axis[1];
  const Eigen::Vector3d& w6 = wrist_.axis[2];
  const Eigen::Vector3d across = w6.unitOrthogonal();
  for (const Eigen::Vector3d& arm : arms) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(6);
    q.head<3>() = arm;
    const Eigen::Matrix3d wanted =
        partial_forward(q, 3).linear().transpose() * target.linear() * wrist_.tip_rotation.transpose();
    // Joint 6 does not move its own axis, so joints 4 and 5 alone must carry w6 to wanted * w6.
    for (const auto& [q4, q5] : subproblem2(w4, w5, w6, wanted * w6)) {
      const Eigen::Matrix3d rest = rotation(w5, -q5) * rotation(w4, -q4) * wanted;
      q[3] = q4;
      q[4] = q5;
      q[5] = subproblem1(w6, across, rest * across);
      out.push_back(q);
    }
  }
  return out;
}

IkResult KinematicChain::inverse(const Eigen::Isometry3d& target, const Eigen::VectorXd& q_seed,
                                 const IkOptions& options) const {
  CW_CHECK(static_cast<std::size_t>(q_seed.size()) == dof(), "inverse: q_seed has {} entries, the chain {} joints",
           q_seed.size(), dof());
  CW_CHECK(options.position_tolerance > 0 && options.orientation_tolerance > 0 && options.max_iterations > 0 &&
               options.restarts >= 0,
           "inverse: invalid IkOptions (tolerances {} m, {} rad, {} iterations, {} restarts)",
           options.position_tolerance, options.orientation_tolerance, options.max_iterations, options.restarts);
  const auto n = static_cast<Eigen::Index>(dof());

  Eigen::VectorXd seed(n);
  for (Eigen::Index i = 0; i < n; ++i) seed[i] = clamp_to(q_seed[i], limits_[static_cast<std::size_t>(i)]);

  auto unreachable = [&](std::string reason, const Attempt* best) {
    IkResult r{IkStatus::kUnreachable, seed, std::numeric_limits<double>::infinity(),
               std::numeric_limits<double>::infinity(), std::move(reason)};
    if (best != nullptr && best->q.size() == n) {
      r.q = best->q;
      r.position_error = best->position_error;
      r.orientation_error = best->orientation_error;
    }
    return r;
  };

  if (!target.matrix().allFinite()) return unreachable("the target pose is not finite", nullptr);
  const Eigen::Matrix3d r = target.linear();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 || r.determinant() < 0) {
    return unreachable("the target's rotation part is not a rotation matrix", nullptr);
  }
  const double distance = (target.translation() - first_joint_origin_).norm();
  if (distance > max_reach_ + options.position_tolerance) {  // the tolerance: a stretched arm is exactly at max_reach
    return unreachable(fmt::format("out of reach: {:.3f} m from {}'s origin > max reach {:.3f} m", distance,
                                   names_.front(), max_reach_),
                       nullptr);
  }

  // Levenberg-Marquardt with the damping tied to the squared error (Sugihara 2011): fast near a solution, stable near
  // singularities. Orientation errors are weighted as if at a 0.3 m lever arm so both error kinds count alike for an
  // arm of this size; the tolerances decide convergence.
  Vector6d weights;
  weights << 1, 1, 1, 0.09, 0.09, 0.09;
  constexpr double kDampingBias = 1e-8;
  constexpr int kStallIterations = 15;

  auto solve_from = [&](Eigen::VectorXd q) {
    Attempt a;
    double best_cost = std::numeric_limits<double>::infinity();
    int since_improvement = 0;
    for (int it = 0;; ++it) {
      const Vector6d e = pose_error(forward(q), target);
      a.q = q;
      a.position_error = e.head<3>().norm();
      a.orientation_error = e.tail<3>().norm();
      const bool within =
          a.position_error <= options.position_tolerance && a.orientation_error <= options.orientation_tolerance;
      // Polish well below the tolerances so an answer from here is as exact as one from the wrist decomposition.
      if (within && a.position_error <= 1e-3 * options.position_tolerance &&
          a.orientation_error <= 1e-3 * options.orientation_tolerance) {
        a.converged = true;
        return a;
      }
      const double cost = e.dot(weights.cwiseProduct(e));
      if (cost < best_cost * (1 - 1e-6)) {
        best_cost = cost;
        since_improvement = 0;
      } else {
        ++since_improvement;
      }
      if (since_improvement >= kStallIterations || it >= options.max_iterations) {
        // Stuck (typically pressed against a limit: a restart does better than more iterations) or out of time.
        a.converged = within;
        return a;
      }
      const Jacobian jac = jacobian(q);
      const Eigen::MatrixXd jt_w = jac.transpose() * weights.asDiagonal();
      Eigen::MatrixXd h = jt_w * jac;
      h.diagonal().array() += cost + kDampingBias;
      const Eigen::VectorXd dq = h.ldlt().solve(jt_w * e);
      for (Eigen::Index i = 0; i < n; ++i) q[i] = clamp_to(q[i] + dq[i], limits_[static_cast<std::size_t>(i)]);
    }
  };

  // Brings revolute joints within their limits by whole turns, choosing the turn nearest the seed; reports the first
  // joint that cannot be brought in.
  constexpr double kTurn = 2 * std::numbers::pi;
  auto fit_limits = [&](Eigen::VectorXd& q) -> std::string {
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (!joints_[k].prismatic && std::isfinite(limits_[k].lower) && std::isfinite(limits_[k].upper)) {
        const double first = q[i] + kTurn * std::ceil((limits_[k].lower - q[i]) / kTurn);
        double chosen = std::numeric_limits<double>::quiet_NaN();
        for (double v = first; v <= limits_[k].upper; v += kTurn) {
          if (std::isnan(chosen) || std::abs(v - seed[i]) < std::abs(chosen - seed[i])) chosen = v;
        }
        if (!std::isnan(chosen)) q[i] = chosen;
      } else if (!joints_[k].prismatic) {
        q[i] += kTurn * std::round((seed[i] - q[i]) / kTurn);  // continuous joint
      }
      if (!(q[i] >= limits_[k].lower && q[i] <= limits_[k].upper)) {
        return fmt::format("{} = {:.3f} outside [{:.3f}, {:.3f}]", names_[k], std::remainder(q[i], kTurn),
                           limits_[k].lower, limits_[k].upper);
      }
    }
    return {};
  };

  // Every candidate found, brought within limits where possible; the accepted one is the nearest to the seed whose
  // forward kinematics really reaches the target.
  std::vector<Eigen::VectorXd> candidates;
  std::vector<std::string> violations;
  int solutions_ignoring_limits = 0;
  bool all_solutions_known = false;
  if (wrist_.present) {
    for (Eigen::VectorXd q : wrist_solutions(target, seed, all_solutions_known)) {
      ++solutions_ignoring_limits;
      std::string violation = fit_limits(q);
      if (violation.empty()) {
        candidates.push_back(std::move(q));
      } else {
        violations.push_back(std::move(violation));
      }
    }
  }
  Attempt best = solve_from(seed);
  if (best.converged) {
    fit_limits(best.q);  // whole turns only; the solver kept it within limits
    candidates.push_back(best.q);
  }

  auto pick = [&]() -> std::optional<IkResult> {
    std::optional<IkResult> chosen;
    double best_distance = std::numeric_limits<double>::infinity();
    for (const Eigen::VectorXd& q : candidates) {
      if (!within_limits(q)) continue;
      const Vector6d e = pose_error(forward(q), target);
      const double pe = e.head<3>().norm(), oe = e.tail<3>().norm();
      if (pe > options.position_tolerance || oe > options.orientation_tolerance) continue;
      const double d = (q - seed).squaredNorm();
      if (d < best_distance) {
        best_distance = d;
        chosen = IkResult{IkStatus::kOk, q, pe, oe, {}};
      }
    }
    return chosen;
  };
  if (auto found = pick()) return *found;

  // Nothing yet: pseudo-random restarts (the only search for chains without a spherical wrist, a safety net for the
  // others unless their solutions are all known to lie outside the limits).
  SplitMix64 rng(0x43656c6c77726967ULL);  // fixed: the same call always gives the same answer
  for (int r_i = 0; r_i < options.restarts && !all_solutions_known; ++r_i) {
    Eigen::VectorXd start(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const JointLimit range = sampling_range(limits_[static_cast<std::size_t>(i)]);
      start[i] = range.lower + rng.next() * (range.upper - range.lower);
    }
    Attempt a = solve_from(start);
    if (a.converged) {
      fit_limits(a.q);
      candidates.push_back(a.q);
      if (auto found = pick()) return *found;
    } else if (a.position_error + 0.3 * a.orientation_error < best.position_error + 0.3 * best.orientation_error) {
      best = std::move(a);
    }
  }

  if (wrist_.present && solutions_ignoring_limits > 0) {
    return unreachable(fmt::format("outside the joint limits: the pose has {} joint solution(s) ignoring limits and "
                                   "none within them (e.g. {})",
                                   solutions_ignoring_limits, violations.empty() ? std::string("?") : violations[0]),
                       &best);
  }
  if (wrist_.present) {
    return unreachable(fmt::format("the wrist centre ({:.3f}, {:.3f}, {:.3f}) m cannot be reached by joints {}, {}, {}",
                                   (target * wrist_.centre_in_tip).x(), (target * wrist_.centre_in_tip).y(),
                                   (target * wrist_.centre_in_tip).z(), names_[0], names_[1], names_[2]),
                       &best);
  }
  return unreachable(fmt::format("no joint solution within limits: the best of {} starts misses by {:.3g} m and "
                                 "{:.3g} rad (tolerances {:g} m, {:g} rad)",
                                 options.restarts + 1, best.position_error, best.orientation_error,
                                 options.position_tolerance, options.orientation_tolerance),
                     &best);
}

}  // namespace cellwright::models
