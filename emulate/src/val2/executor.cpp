// The VAL II instruction executor (executor.hpp).
#include "val2/executor.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdlib>
#include <numbers>

namespace cellwright::emulate::val2 {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// The doc's WHERE header (docs/real-robots.md).
constexpr std::string_view kWhereHeader = "     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND";

// An angle in degrees, brought into (−180, 180].
double wrap_degrees(double a) {
  double r = std::remainder(a, 360.0);
  if (r <= -180.0) r += 360.0;
  return r;
}

// `v` rounded to `decimals`, without a negative zero (so that WHERE never prints -0.000).
double printable(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  const double r = std::round(v * scale) / scale;
  return r == 0 ? 0.0 : r;
}

// Below this sin(A) the Z-Y-Z angles are taken as degenerate (A = 0 or 180): the solver's answers are within 1 µrad
// of a commanded A of 0, and 1e-5 rad is far below WHERE's 0.001°.
constexpr double kDegenerateSinA = 1e-5;

}  // namespace

Eigen::Matrix3d oat_rotation(double o, double a, double t) {
  using Eigen::AngleAxisd;
  using Eigen::Vector3d;
  return (AngleAxisd(o * kDeg, Vector3d::UnitZ()) * AngleAxisd(a * kDeg, Vector3d::UnitY()) *
          AngleAxisd(t * kDeg, Vector3d::UnitZ()) * AngleAxisd(std::numbers::pi, Vector3d::UnitX()))
      .toRotationMatrix();
}

std::array<double, 3> oat_angles(const Eigen::Matrix3d& r, const std::array<double, 3>& near) {
  // M = Rz(O)·Ry(A)·Rz(T): the rotation without the tool's turn about x (Rx(180°) is its own inverse).
  const Eigen::Matrix3d m = r * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const double sin_a = std::hypot(m(0, 2), m(1, 2));
  const double near_o = wrap_degrees(near[0]);
  if (sin_a < kDegenerateSinA) {
    if (m(2, 2) > 0) {  // A = 0: M = Rz(O + T); O is kept
      const double sum = std::atan2(m(1, 0), m(0, 0)) / kDeg;
      return {near_o, 0.0, wrap_degrees(sum - near_o)};
    }
    // A = 180: M = Ry(180°)·Rz(T − O); O is kept
    const double diff = std::atan2(m(1, 0), m(1, 1)) / kDeg;
    return {near_o, 180.0, wrap_degrees(near_o + diff)};
  }
  const double o = std::atan2(m(1, 2), m(0, 2)) / kDeg;
  const double a = std::atan2(sin_a, m(2, 2)) / kDeg;
  const double t = std::atan2(m(2, 1), -m(2, 0)) / kDeg;
  const std::array<double, 3> first{wrap_degrees(o), wrap_degrees(a), wrap_degrees(t)};
  const std::array<double, 3> second{wrap_degrees(o + 180), wrap_degrees(-a), wrap_degrees(t + 180)};
  const auto distance = [&](const std::array<double, 3>& x) {
    double d = 0;
    for (int i = 0; i < 3; ++i) d += std::abs(wrap_degrees(x[i] - near[i]));
    return d;
  };
  return distance(second) < distance(first) ? second : first;
}

Eigen::Matrix3d val_oat_rotation(double o, double a, double t) {
  const double so = std::sin(o * kDeg), co = std::cos(o * kDeg);
  const double sa = std::sin(a * kDeg), ca = std::cos(a * kDeg);
  const Eigen::Vector3d approach(so * ca, -co * ca, -sa);  // Rz(O)·(0, −cos A, −sin A)
  const Eigen::Vector3d fingers0(co, so, 0.0);             // the finger line at T = 0, horizontal
  const Eigen::Vector3d normal0 = fingers0.cross(approach);
  const Eigen::Vector3d fingers = fingers0 * std::cos(t * kDeg) - normal0 * std::sin(t * kDeg);
  Eigen::Matrix3d r;
  r.col(0) = fingers.cross(approach);
  r.col(1) = fingers;
  r.col(2) = approach;
  return r;
}

std::array<double, 3> val_oat_angles(const Eigen::Matrix3d& r, const std::array<double, 3>& near) {
  const Eigen::Vector3d approach = r.col(2);
  const double horizontal = std::hypot(approach.x(), approach.y());
  const double a = std::atan2(-approach.z(), horizontal) / kDeg;
  // Pointing straight up or down, O and T turn about the same axis: O is kept and T takes the rest.
  const double o = horizontal < kDegenerateSinA ? wrap_degrees(near[0]) : std::atan2(approach.x(), -approach.y()) / kDeg;
  const Eigen::Vector3d fingers0(std::cos(o * kDeg), std::sin(o * kDeg), 0.0);
  const Eigen::Vector3d normal0 = fingers0.cross(approach);
  const double t = std::atan2(-r.col(1).dot(normal0), r.col(1).dot(fingers0)) / kDeg;
  const std::array<double, 3> first{wrap_degrees(o), wrap_degrees(a), wrap_degrees(t)};
  if (horizontal < kDegenerateSinA) return first;
  // The other set: the approach axis seen from the other side, O + 180, A → 180 − A, T + 180.
  const std::array<double, 3> second{wrap_degrees(o + 180), wrap_degrees(180 - a), wrap_degrees(t + 180)};
  const auto distance = [&](const std::array<double, 3>& x) {
    double d = 0;
    for (int i = 0; i < 3; ++i) d += std::abs(wrap_degrees(x[i] - near[i]));
    return d;
  };
  return distance(second) < distance(first) ? second : first;
}

Executor::Executor(EmulatedArm& arm, double speed, Conventions conventions)
    : arm_(arm), speed_(speed), conventions_(std::move(conventions)) {}

Outcome Executor::execute(const Instruction& in) {
  switch (in.op) {
    case Op::nothing:
      return {};
    case Op::where:
      return where();
    case Op::ready: {
      const std::vector<double> home = arm_.home();
      return move_to(Eigen::Map<const Eigen::VectorXd>(home.data(), static_cast<Eigen::Index>(home.size())), false);
    }
    case Op::move:
    case Op::moves:
      return move_to_location(in.location, in.op == Op::moves);
    case Op::open_hand:
    case Op::close_hand: {
      const ArmResult r = arm_.grip(in.op == Op::close_hand);
      Outcome out;
      if (r.status == ArmStatus::interrupted) {
        out.interrupted = true;
      } else if (!r.ok()) {
        out.lines.emplace_back(kServoError);
        out.failure = r.message;
      }
      return out;
    }
    case Op::speed:
      speed_ = in.speed;
      return {};
    case Op::signal:
      for (const int s : in.signals) arm_.set_output(std::abs(s), s > 0);
      return {};
    case Op::wait_signal: {
      const int s = in.signals.at(0);
      const ArmResult r = arm_.wait_input(std::abs(s) - 1000, s > 0, std::chrono::nanoseconds(0));
      Outcome out;
      if (r.status == ArmStatus::interrupted) {
        out.interrupted = true;
      } else if (!r.ok()) {  // a timeout cannot come (no deadline); anything else is the arm's
        out.lines.emplace_back(kServoError);
        out.failure = r.message;
      }
      return out;
    }
  }
  return {};
}

Outcome Executor::move_to(const Eigen::VectorXd& q, bool linear) {
  const std::vector<double> target(q.data(), q.data() + q.size());
  const ArmResult r = arm_.move(target, speed_ / 100.0, linear);
  Outcome out;
  switch (r.status) {
    case ArmStatus::ok:
      break;
    case ArmStatus::interrupted:
      out.interrupted = true;
      break;
    case ArmStatus::unreachable:
      out.lines.emplace_back(kLocationOutOfRange);
      out.failure = r.message;
      break;
    case ArmStatus::failed:
    case ArmStatus::timeout:
      out.lines.emplace_back(kServoError);
      out.failure = r.message;
      break;
  }
  return out;
}

Outcome Executor::move_to_location(const Location& location, bool linear) {
  const models::KinematicChain& chain = arm_.chain();
  const auto& v = location.values;
  if (location.kind == Location::Kind::precision_point) {
    Eigen::VectorXd q(6);
    for (int j = 0; j < 6; ++j) {
      q[j] = v[static_cast<std::size_t>(j)] * kDeg;
      const models::JointLimit& l = chain.limits()[static_cast<std::size_t>(j)];
      if (q[j] < l.lower || q[j] > l.upper) return Outcome{{joint_limit_stop(j + 1)}, false, {}};
    }
    return move_to(q, linear);
  }
  Eigen::Isometry3d given = Eigen::Isometry3d::Identity();
  given.translation() = Eigen::Vector3d(v[0], v[1], v[2]) / 1000.0;
  given.linear() = conventions_.val_orientation ? val_oat_rotation(v[3], v[4], v[5]) : oat_rotation(v[3], v[4], v[5]);
  // The location is the monitor's tool point in its world: the arm's TCP in its base frame is world · location ·
  // tool⁻¹.
  const Eigen::Isometry3d target = conventions_.world * given * conventions_.tool.inverse();
  const std::vector<double> now = arm_.joints();
  models::IkOptions options;
  // Tight enough that WHERE (0.01 mm, 0.001°) reads the location back as written.
  options.position_tolerance = 1e-6;
  options.orientation_tolerance = 1e-6;
  const models::IkResult ik = chain.inverse(
      target, Eigen::Map<const Eigen::VectorXd>(now.data(), static_cast<Eigen::Index>(now.size())), options);
  if (ik.status != models::IkStatus::kOk) return Outcome{{std::string(kLocationOutOfRange)}, false, ik.reason};
  Outcome out = move_to(ik.q, linear);
  if (!out.interrupted && out.lines.empty()) oat_ = {v[3], v[4], v[5]};
  return out;
}

Outcome Executor::where() const {
  const std::vector<double> q = arm_.joints();
  const Eigen::Isometry3d tcp =
      arm_.chain().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
  const Eigen::Isometry3d pose = conventions_.world.inverse() * tcp * conventions_.tool;
  const Eigen::Vector3d p = pose.translation() * 1000.0;
  const std::array<double, 3> oat =
      conventions_.val_orientation ? val_oat_angles(pose.linear(), oat_) : oat_angles(pose.linear(), oat_);
  Outcome out;
  out.lines.emplace_back(kWhereHeader);
  out.lines.push_back(fmt::format("{:10.2f}{:11.2f}{:11.2f}{:11.3f}{:11.3f}{:11.3f}{:11.3f}", printable(p.x(), 2),
                                  printable(p.y(), 2), printable(p.z(), 2), printable(oat[0], 3), printable(oat[1], 3),
                                  printable(oat[2], 3), printable(arm_.gripper_opening() * 1000.0, 3)));
  std::string joints;
  for (std::size_t j = 0; j < q.size(); ++j) {
    const double deg = printable(q[j] / kDeg, 3);
    joints += j == 0 ? fmt::format("{:10.3f}", deg) : fmt::format("{:11.3f}", deg);
  }
  out.lines.push_back(std::move(joints));
  return out;
}

}  // namespace cellwright::emulate::val2
