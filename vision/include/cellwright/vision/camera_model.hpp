// The pinhole model of a cell camera (issue 5): intrinsics from the vertical field of view and the resolution,
// extrinsics from the camera's pose, so that image processing can go from pixels to world coordinates and back.
//
// Conventions, those MuJoCo renders with (scene.cpp writes the camera from the CameraSpec):
//  - The camera frame is MuJoCo's: the camera looks along its -z axis, image up is its +y axis, image right its +x.
//  - The vertical field of view spans the image height exactly; pixels are square; the principal point is the
//    image centre (no lens distortion: the simulated camera has none).
//  - Pixel coordinates are OpenCV's: (u, v) = (column, row from the top), the centre of the top-left pixel is
//    (0, 0), so the image spans [-0.5, width - 0.5] x [-0.5, height - 0.5]. The principal point is
//    ((width - 1) / 2, (height - 1) / 2) and the focal length, in pixels, f = (height / 2) / tan(fovy / 2).
//
// A CameraModel is an immutable value; every member is const and may be called from any thread.
#pragma once

#include <Eigen/Geometry>

#include <opencv2/core.hpp>

#include <optional>

#include "cellwright/models/cell.hpp"

namespace cellwright::vision {

// A half line in the world: origin + t * direction, t >= 0; direction is a unit vector.
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();
};

class CameraModel {
 public:
  // The camera of the cell description: its pose, resolution and field of view. Throws InternalError if the
  // resolution is not positive or the field of view is not within (0, 180) degrees (load_cell refuses those).
  explicit CameraModel(const models::CameraSpec& spec);

  // The same camera as `spec` at another resolution (the field of view still spans the height).
  CameraModel(const models::CameraSpec& spec, int width, int height);

  // A camera at `pose` (its frame in the world, MuJoCo's convention above) with vertical field of view `fovy`
  // (radians), at width x height pixels. Throws InternalError as above. (twin/render.hpp makes one from a MuJoCo
  // camera.)
  CameraModel(const Eigen::Isometry3d& pose, double fovy, int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  double fovy() const { return fovy_; }    // radians
  double focal() const { return focal_; }  // pixels
  cv::Point2d principal_point() const { return {cx_, cy_}; }
  // The camera frame in the world (MuJoCo's: looking along -z, +y up in the image).
  const Eigen::Isometry3d& pose() const { return pose_; }
  Eigen::Vector3d position() const { return pose_.translation(); }

  // The 3 x 3 intrinsic matrix K in OpenCV's form, for a camera frame looking along +z with +y down the image
  // (OpenCV's convention; camera_from_world() gives the matching extrinsics).
  Eigen::Matrix3d intrinsics() const;
  // World to OpenCV camera frame (x right, y down, z forward): the extrinsics that go with intrinsics().
  Eigen::Isometry3d camera_from_world() const;

  // Distance in front of the camera (along its viewing axis) of a world point; <= 0 behind the camera.
  double depth(const Eigen::Vector3d& world) const;

  // The pixel where a world point appears; nullopt when the point is not in front of the camera (depth at most
  // 1 mm). The pixel may lie outside the image.
  std::optional<cv::Point2d> project(const Eigen::Vector3d& world) const;

  // The ray from the camera's centre through a pixel (any pixel coordinates, also outside the image).
  Ray ray(const cv::Point2d& pixel) const;

  // Where the ray through a pixel meets the horizontal plane z = height (world); nullopt when the ray is parallel
  // to the plane or meets it behind the camera.
  std::optional<Eigen::Vector3d> on_plane(const cv::Point2d& pixel, double height) const;

  // Whether a pixel lies inside the image (its area, [-0.5, width - 0.5] x [-0.5, height - 0.5]).
  bool in_image(const cv::Point2d& pixel) const;

 private:
  Eigen::Isometry3d pose_;
  Eigen::Isometry3d world_to_camera_;
  double fovy_;
  int width_, height_;
  double focal_, cx_, cy_;
};

}  // namespace cellwright::vision
