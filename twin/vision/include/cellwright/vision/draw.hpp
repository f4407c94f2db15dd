// Pictures of what the image processing found (issue 5): the camera image with each detected workpiece's outline,
// pose and name drawn on it, for people (`twin snapshot --detections`, reports), never for the controller.
//
// Threads: draw_detections only touches the image it is given; any thread.
#pragma once

#include <opencv2/core.hpp>

#include "cellwright/vision/detector.hpp"

namespace cellwright::vision {

// Draws on a BGR image (8 bits, 3 channels; normally the image the detections were found in) for each detection:
// the fitted silhouette's outline in magenta, its pose as two 30 mm axes from the centre of its top face (x red,
// y green; a cylinder, which has no yaw, gets a white cross instead), and a label with the workpiece's name and
// confidence (moved up, with a leader line, when it would cover another label); for each rejected blob, a grey box
// with the name of its best candidate and "?". Throws InternalError if
// the image is not 8-bit BGR.
void draw_detections(cv::Mat& bgr, const DetectionResult& result);

}  // namespace cellwright::vision
