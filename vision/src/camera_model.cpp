// The pinhole camera model (camera_model.hpp).
#include "cellwright/vision/camera_model.hpp"

#include <cmath>
#include <numbers>

#include "cellwright/common/error.hpp"

namespace cellwright::vision {

namespace {
constexpr double kMinDepth = 1e-3;  // m: points closer to the camera's plane than this do not project
}  // namespace

CameraModel::CameraModel(const Eigen::Isometry3d& pose, double fovy, int width, int height)
    : pose_(pose), world_to_camera_(pose.inverse()), fovy_(fovy), width_(width), height_(height) {
  CW_CHECK(width > 0 && height > 0, "camera resolution {}x{} is not positive", width, height);
  CW_CHECK(fovy > 0 && fovy < std::numbers::pi, "camera field of view {} rad outside (0, pi)", fovy);
  focal_ = 0.5 * height / std::tan(0.5 * fovy);
  cx_ = 0.5 * (width - 1);
  cy_ = 0.5 * (height - 1);
}

CameraModel::CameraModel(const models::CameraSpec& spec) : CameraModel(spec, spec.width, spec.height) {}

CameraModel::CameraModel(const models::CameraSpec& spec, int width, int height)
    : CameraModel(spec.pose.transform(), spec.fovy, width, height) {}

Eigen::Matrix3d CameraModel::intrinsics() const {
  Eigen::Matrix3d k;
  k << focal_, 0, cx_, 0, focal_, cy_, 0, 0, 1;
  return k;
}

Eigen::Isometry3d CameraModel::camera_from_world() const {
  // OpenCV's camera frame is MuJoCo's turned half a turn about x: y down, z forward.
  Eigen::Isometry3d flip = Eigen::Isometry3d::Identity();
  flip.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
  return flip * world_to_camera_;
}

double CameraModel::depth(const Eigen::Vector3d& world) const {
  return -(world_to_camera_ * world).z();
}

std::optional<cv::Point2d> CameraModel::project(const Eigen::Vector3d& world) const {
  const Eigen::Vector3d c = world_to_camera_ * world;
  const double d = -c.z();
  if (d <= kMinDepth) return std::nullopt;
  return cv::Point2d(cx_ + focal_ * c.x() / d, cy_ - focal_ * c.y() / d);
}

Ray CameraModel::ray(const cv::Point2d& pixel) const {
  const Eigen::Vector3d in_camera((pixel.x - cx_) / focal_, -(pixel.y - cy_) / focal_, -1.0);
  return Ray{pose_.translation(), (pose_.linear() * in_camera).normalized()};
}

std::optional<Eigen::Vector3d> CameraModel::on_plane(const cv::Point2d& pixel, double height) const {
  const Ray r = ray(pixel);
  if (std::abs(r.direction.z()) < 1e-12) return std::nullopt;
  const double t = (height - r.origin.z()) / r.direction.z();
  if (t <= 0) return std::nullopt;
  return Eigen::Vector3d(r.origin + t * r.direction);
}

bool CameraModel::in_image(const cv::Point2d& pixel) const {
  return pixel.x >= -0.5 && pixel.y >= -0.5 && pixel.x <= width_ - 0.5 && pixel.y <= height_ - 0.5;
}

}  // namespace cellwright::vision
