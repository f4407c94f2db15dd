// CellDetector: the cell's vision (detector.hpp) as the runtime's PartDetector (runtime/part_detector.hpp), so that
// the image-processing thread can use it without knowing OpenCV. Each Sightings carries the full DetectionResult in
// `detail` (for drawing saved frames).
//
// Also the two conversions between the runtime's plain Image and OpenCV's cv::Mat.
//
// Threads: as runtime::PartDetector. Constructing one turns OpenCV's own worker pool off, process-wide: the
// image-processing thread is the parallelism, so a frame costs the same whatever else runs on the shared cores, and
// no threads the runtime does not know of (and ThreadSanitizer cannot follow) touch its frames.
#pragma once

#include <opencv2/core.hpp>

#include <memory>
#include <string>
#include <vector>

#include "cellwright/runtime/part_detector.hpp"
#include "cellwright/vision/detector.hpp"

namespace cellwright::vision {

class CellDetector final : public runtime::PartDetector {
 public:
  explicit CellDetector(std::shared_ptr<const Detector> detector);

  std::vector<std::string> workpieces() const override;
  // A picture of another size than the camera's is a frame problem (the detector says so).
  runtime::Sightings detect(const runtime::Image& image,
                            const std::vector<runtime::Prediction>& predictions) const override;

  const Detector& detector() const { return *detector_; }

 private:
  std::shared_ptr<const Detector> detector_;
};

// A copy of an 8-bit, 3-channel BGR picture as a runtime Image (an empty one for an empty picture). Throws
// InternalError for another type.
runtime::Image to_image(const cv::Mat& bgr);

// A cv::Mat header over an Image's bytes (no copy): valid while the Image lives and is not changed.
cv::Mat as_mat(const runtime::Image& image);

}  // namespace cellwright::vision
