// Finding the cell's workpieces in a camera image (issue 5; paper section 3.2, the image processing thread): where
// each part is (the centre, x y z in the world) and how it is turned about the vertical, with a confidence, for the
// environment model.
//
// METHOD (docs/vision.md has the details and the measured accuracy)
//  1. Segmentation by colour. Each workpiece's colour (its rgba in the cell description) becomes a hue interval: the
//     hues that colour takes when shaded darker or brighter, with a little white highlight and channels clipped at
//     full scale, as a renderer or a camera shows it. A pixel belongs to a colour class when its hue is in the
//     interval and it is saturated and bright enough; the cell's other objects (grey floor, arms, the dull green
//     machine, the blue-grey conveyor frames) are not. Workpieces of the same or overlapping colours share a class.
//  2. Blobs: the 8-connected components of each class's pixels, with their contour and moments.
//  3. Pose: each blob is fitted with the silhouette of the workpiece's known shape (box or cylinder, its size) seen
//     through the camera model, resting upright on a support the cell description knows: a conveyor's belt, a
//     machine's fixture or top, else the floor. The fit moves x, y and the yaw until the projected silhouette
//     (convex hull of the projected corners, or of the two end circles of a cylinder) covers the blob's pixels and
//     nothing else, with a soft edge so that the pose is found to a fraction of a pixel. This accounts for
//     perspective: a part off the image centre shows side faces that shift its blob's centroid outward by several
//     millimetres. Pixels of other workpieces' colours are ignored (another part may hide this one's side) and so
//     are pixels of the cell's known static occluders (the conveyors' stop bars). Each support under the blob is
//     tried; the best fitting one is kept.
//  4. Confidence: the soft intersection over union of the fitted silhouette and the blob, ignoring the pixels in
//     (3). Partly hidden parts, merged blobs and parts not resting on a support (lifted by an arm) fit badly: they
//     get a low confidence and are rejected with the reason, never reported with a confident wrong pose.
//  5. Matching to the model's workpieces: by colour class; when a class has several workpieces (or several blobs),
//     confident blobs go to the workpieces nearest their predicted positions, if predictions are given.
//
// THREADS. A Detector is built once and never changes; detect() is reentrant: any number of
// threads may use one Detector at the same time. Nothing here touches MuJoCo or OpenGL.
#pragma once

#include <Eigen/Geometry>

#include <opencv2/core.hpp>

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/vision/camera_model.hpp"

namespace cellwright::vision {

struct DetectorOptions {
  double min_saturation = 0.5;  // (max - min) / max of a pixel's r, g, b for it to be a part's colour
  int min_chroma = 24;          // max - min of r, g, b (0..255): darker pixels have no reliable hue
  double hue_margin = 6;        // degrees added on each side of a colour's hue interval
  int min_pixels = 6;           // smaller blobs are noise: ignored without a rejection
  double min_confidence = 0.9;  // fits below this are rejected (partly hidden, merged with another, lifted)
};

// What a part rests on, from the cell description: a horizontal rectangle at a height.
// It is also a solid block from `bottom` up to its top, which hides what is behind it.
struct Support {
  std::string name;   // "conveyor input", "machine mill fixture", "machine mill top", "floor"
  double height = 0;  // z of its top surface, m
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // of the rectangle, world x y
  double yaw = 0;                                    // of the rectangle's first side
  Eigen::Vector2d half = Eigen::Vector2d::Zero();    // half extents; the floor has +infinity
  double bottom = 0;                                 // z of the block's bottom (the floor is no block)
};

// A workpiece found in the image.
struct Detection {
  std::string workpiece;  // cell name
  models::Shape shape = models::Shape::kBox;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // the part's centre, world, m
  // Turn about the world z axis, radians, in [0, yaw_period): a box looks the same turned by yaw_period (pi/2 when
  // its footprint is square, else pi). A cylinder has no yaw: nullopt, and yaw_period is 0.
  std::optional<double> yaw;
  double yaw_period = 0;
  std::string support;               // Support::name of what it rests on
  double confidence = 0;             // in [0, 1]: how well the part's silhouette explains the blob (see METHOD 4)
  bool ambiguous = false;            // its colour class has several workpieces and no prediction told them apart
  int pixels = 0;                    // the blob's area
  cv::Point2d centroid;              // the blob's centroid (its moments), pixels
  std::vector<cv::Point> contour;    // the blob's outer contour, pixels
  std::vector<cv::Point2d> outline;  // the fitted silhouette, pixels (convex polygon)
  cv::Point2d top_centre;            // where the centre of the part's top face is in the image
  cv::Point2d axis_x, axis_y;        // image points 30 mm from the top centre along the part's x and y axes

  // The pose of the part's centre (yaw 0 when it has none).
  Eigen::Isometry3d pose() const;
};

// A blob that was not reported as a workpiece, and why.
struct Rejection {
  std::string workpiece;  // the workpiece it would be (the best candidate), "" when there is none
  cv::Rect box;           // bounding box of the blob, pixels
  int pixels = 0;
  double confidence = 0;  // of the best fit, 0 when none was tried
  std::string reason;     // e.g. "partly hidden or merged: confidence 0.42 < 0.75"
};

struct DetectionResult {
  std::vector<Detection> detections;  // confident ones only, in the cell's workpiece order
  std::vector<Rejection> rejected;
  std::vector<std::string> not_seen;  // workpieces with no detection, in the cell's workpiece order
  std::string frame_problem;          // non-empty when the image could not be used at all (wrong size or type)

  const Detection* find(std::string_view workpiece) const;
};

// Where the model expects a workpiece to be (e.g. the environment model's pose), to tell same-coloured parts apart.
struct Prediction {
  std::string workpiece;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

class Detector {
 public:
  // The cell's workpieces (shapes, sizes, colours), supports and static occluders, seen by `camera`. Throws
  // InputError naming the workpiece in the cell file when its colour is too grey to be told from the cell's
  // background (no shade of it passes options.min_saturation); the cell's other objects are not checked: they must
  // be duller than that or of other hues (docs/vision.md).
  Detector(const models::CellDescription& cell, CameraModel camera, DetectorOptions options = {});

  const CameraModel& camera() const;
  const DetectorOptions& options() const;
  const std::vector<models::WorkpieceSpec>& workpieces() const;
  const std::vector<Support>& supports() const;

  // The colour class of each pixel of a BGR image (8 bits, 3 channels, any size): 0 for none, else 1 + the class
  // index. class_workpieces() lists each class's workpieces.
  cv::Mat classify(const cv::Mat& bgr) const;
  // The workpieces (indices into workpieces()) of each colour class.
  const std::vector<std::vector<std::size_t>>& class_workpieces() const;

  struct Impl;

 private:
  friend DetectionResult detect(const Detector&, const cv::Mat&, const std::vector<Prediction>&);
  std::shared_ptr<const Impl> impl_;
};

// Finds the workpieces in a BGR image (top row first, the camera's resolution) taken by the detector's camera.
// `predictions` are optional. Never throws on image content: an image of the wrong size or type gives a result
// with frame_problem set and every workpiece not seen.
DetectionResult detect(const Detector& detector, const cv::Mat& bgr, const std::vector<Prediction>& predictions = {});

// One line describing a detection: "A at (0.512, -0.548, 0.530) m, yaw 12.3 deg, on conveyor input, confidence
// 0.96".
std::string describe(const Detection& d);

}  // namespace cellwright::vision
