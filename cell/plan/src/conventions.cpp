// The controllers' pose conventions (conventions.hpp), from docs/real-robots.md.
#include "conventions.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

namespace cellwright::cell {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// An angle in degrees brought into (−180, 180].
double wrap(double a) {
  double r = std::remainder(a, 360.0);
  if (r <= -180.0) r += 360.0;
  return r;
}

// Rounded to `decimals`, without a negative zero.
double rounded(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  const double r = std::round(v * scale) / scale;
  return r == 0 ? 0.0 : r;
}

}  // namespace

std::optional<MovemasterPose> movemaster_pose(const Eigen::Isometry3d& tool, double yaw_tolerance_deg,
                                              std::string& why) {
  const Eigen::Vector3d point = tool.translation();
  if (std::hypot(point.x(), point.y()) < 1e-6) {
    why = "its tool point is on the base's z axis, where the 5-axis rule has no azimuth";
    return std::nullopt;
  }
  // The vertical plane through the base's z axis and the tool point: u outward, w its normal.
  const double theta = std::atan2(point.y(), point.x());
  const Eigen::Vector3d u(std::cos(theta), std::sin(theta), 0);
  const Eigen::Vector3d w(-std::sin(theta), std::cos(theta), 0);
  const Eigen::Vector3d a = tool.linear().col(2);
  const double off_plane = std::asin(std::clamp(a.dot(w), -1.0, 1.0)) / kDeg;
  if (std::abs(off_plane) > yaw_tolerance_deg) {
    why = fmt::format(
        "its approach axis leaves the arm's vertical plane by {:.1f} degrees (the 5-axis rule allows {:.1f})",
        off_plane, yaw_tolerance_deg);
    return std::nullopt;
  }
  // Pitch: a = cos p · u + sin p · z. Roll: the tool's x axis about a, from w × a (R = [w × a, w, a] · Rz(r)).
  const double p = std::atan2(a.z(), a.dot(u));
  const Eigen::Vector3d a_plane = std::cos(p) * u + std::sin(p) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d x = tool.linear().col(0);
  const double r = std::atan2(x.dot(w), x.dot(w.cross(a_plane)));
  return MovemasterPose{point.x() * 1000, point.y() * 1000, point.z() * 1000, wrap(p / kDeg), wrap(r / kDeg)};
}

std::array<double, 6> val2_trans(const Eigen::Isometry3d& tool) {
  // M = R · Rx(180°) = Rz(O)·Ry(A)·Rz(T).
  const Eigen::Matrix3d m =
      tool.linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const double sin_a = std::hypot(m(0, 2), m(1, 2));
  double o = 0, a = 0, t = 0;
  if (sin_a < 1e-9) {
    if (m(2, 2) > 0) {  // A = 0: M = Rz(O + T)
      t = std::atan2(m(1, 0), m(0, 0)) / kDeg;
    } else {  // A = 180: M = Ry(180°)·Rz(T) with O = 0
      a = 180;
      t = std::atan2(m(1, 0), m(1, 1)) / kDeg;
    }
  } else {
    o = std::atan2(m(1, 2), m(0, 2)) / kDeg;
    a = std::atan2(sin_a, m(2, 2)) / kDeg;
    t = std::atan2(m(2, 1), -m(2, 0)) / kDeg;
  }
  const Eigen::Vector3d p = tool.translation() * 1000;
  return {p.x(), p.y(), p.z(), wrap(o), wrap(a), wrap(t)};
}

std::string movemaster_number(double v) {
  return fmt::format("{:.1f}", rounded(v, 1));
}

std::string val2_number(double v) {
  std::string s = fmt::format("{:.3f}", rounded(v, 3));
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

}  // namespace cellwright::cell
