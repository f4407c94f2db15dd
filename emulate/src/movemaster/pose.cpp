// The 5-axis pose convention (pose.hpp).
#include "movemaster/pose.hpp"

#include <cmath>
#include <numbers>

namespace cellwright::emulate::movemaster {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// u (outward in the plane) and w (the plane's normal) at the azimuth of `point`.
void plane(const Eigen::Vector3d& point, Eigen::Vector3d& u, Eigen::Vector3d& w) {
  const double theta = std::atan2(point.y(), point.x());
  u = {std::cos(theta), std::sin(theta), 0};
  w = {-std::sin(theta), std::cos(theta), 0};
}

}  // namespace

std::optional<Eigen::Isometry3d> tool_frame(const Pose5& pose) {
  const Eigen::Vector3d point(pose.x / 1000, pose.y / 1000, pose.z / 1000);
  if (std::hypot(point.x(), point.y()) < 1e-6) return std::nullopt;
  Eigen::Vector3d u, w;
  plane(point, u, w);
  const Eigen::Vector3d a = std::cos(pose.p * kDeg) * u + std::sin(pose.p * kDeg) * Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d r0;
  r0.col(0) = w.cross(a);
  r0.col(1) = w;
  r0.col(2) = a;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r0 * Eigen::AngleAxisd(pose.r * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = point;
  return t;
}

Pose5 pose_of(const Eigen::Isometry3d& tool) {
  const Eigen::Vector3d point = tool.translation();
  Eigen::Vector3d u, w;
  plane(point, u, w);
  const Eigen::Vector3d a = tool.linear().col(2);
  const double p = std::atan2(a.z(), a.dot(u));
  // The approach axis as the convention has it (projected onto the plane), and the roll of x about it.
  const Eigen::Vector3d a_in_plane = std::cos(p) * u + std::sin(p) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d x = tool.linear().col(0);
  const double r = std::atan2(x.dot(w), x.dot(w.cross(a_in_plane)));
  return {point.x() * 1000, point.y() * 1000, point.z() * 1000, p / kDeg, r / kDeg};
}

}  // namespace cellwright::emulate::movemaster
