// Pictures of what the image processing found (issue 5): the camera image with each detected workpiece's outline,
// pose and name drawn on it, for people (`twin snapshot --detections`, reports), never for the controller.
//
// Threads: draw_detections only touches the image it is given; any thread.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "cellwright/vision/camera_model.hpp"
#include "cellwright/vision/detector.hpp"

namespace cellwright::vision {

// Draws on a BGR image (8 bits, 3 channels; normally the image the detections were found in) for each detection:
// the fitted silhouette's outline in magenta, its pose as two 30 mm axes from the centre of its top face (x red,
// y green; a cylinder, which has no yaw, gets a white cross instead), and a label with the workpiece's name and
// confidence (moved up, with a leader line, when it would cover another label); for each rejected blob, a grey box
// with the name of its best candidate and "?". Throws InternalError if
// the image is not 8-bit BGR.
void draw_detections(cv::Mat& bgr, const DetectionResult& result);

// Where the controller's environment model had a part when a frame was taken, before the frame corrected it.
struct PredictedPart {
  std::string workpiece;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world, m
};

// What a saved frame tells beyond the detections: a band along the top with the frame's simulation time
// ("t = 12.400 s") and the parts the image processing did not see ("not seen: B, C"); for each prediction a yellow
// cross at its position as `camera` projects it (those behind the camera or outside the image are left out), named
// in yellow, and circled in red with "not seen" when the part is among `not_seen`. Throws InternalError if the image
// is not 8-bit BGR.
void draw_frame_overlay(cv::Mat& bgr, double sim_time, const CameraModel& camera,
                        const std::vector<PredictedPart>& predictions, const std::vector<std::string>& not_seen);

}  // namespace cellwright::vision
