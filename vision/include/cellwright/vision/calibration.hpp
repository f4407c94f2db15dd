// A camera's pose in the cell from a calibration target of known pose (issue 26; `twin calibrate`, docs/vision.md
// "A real camera"): a checkerboard lying in the cell where the target file says, seen in one frame of the camera;
// its inner corners found (cv::findChessboardCorners, refined to a tenth of a pixel), the pose solved (cv::solvePnP)
// in the cell camera's pinhole (the frame undistorted first: camera_source.hpp), and carried into the cell through
// the target's pose.
//
// A checkerboard reads the same turned half a turn (and, square, a quarter): of the readings that fit, the one whose
// camera is nearest the camera's pose in the cell description (its nominal pose) is taken.
//
// The target file (YAML):
//     checkerboard: {corners: [7, 5], square: 0.04}    # inner corners along x and along y (not equal), side in m
//     pose: {xyz: [0.2, 0.1, 0.001], rpy: [0, 0, 0]}  # the target's frame in the cell: origin at the first inner
//                                                      # corner, x along its rows, z out of the board's face
// Threads: pure functions, any thread.
#pragma once

#include <Eigen/Geometry>

#include <opencv2/core.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "cellwright/vision/camera_model.hpp"

namespace cellwright::vision {

struct CalibrationTarget {
  cv::Size corners;  // inner corners along the target's x, along its y
  double square = 0;  // m
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // the target's frame in the cell
  std::filesystem::path source;

  // The inner corners in the target's frame, row by row (x fastest).
  std::vector<cv::Point3d> corner_points() const;
};

// Reads a target file. InputError naming the file, line and problem.
CalibrationTarget read_target(const std::filesystem::path& file);

struct CameraPoseFit {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // the camera's frame in the cell (MuJoCo's convention)
  double rms_px = 0;      // reprojection error of the corners
  std::size_t points = 0;  // corners used
};

// The pose of the camera that took `image` (8-bit BGR, in `camera`'s pinhole: its intrinsics are used, its pose is
// the nominal pose that picks among the readings of a symmetric board). Throws InputError at `where` when the target
// is not found in the image.
CameraPoseFit locate_camera(const cv::Mat& image, const CameraModel& camera, const CalibrationTarget& target,
                            const SourceLocation& where);

}  // namespace cellwright::vision
