#include "cellwright/vision/cell_detector.hpp"

#include <opencv2/core/utility.hpp>

#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::vision {

CellDetector::CellDetector(std::shared_ptr<const Detector> detector) : detector_(std::move(detector)) {
  CW_CHECK(detector_ != nullptr, "CellDetector needs a detector");
  cv::setNumThreads(0);
}

std::vector<std::string> CellDetector::workpieces() const {
  std::vector<std::string> names;
  for (const models::WorkpieceSpec& w : detector_->workpieces()) names.push_back(w.name);
  return names;
}

runtime::Sightings CellDetector::detect(const runtime::Image& image,
                                        const std::vector<runtime::Prediction>& predictions) const {
  std::vector<Prediction> p;
  p.reserve(predictions.size());
  for (const runtime::Prediction& q : predictions) p.push_back({q.workpiece, q.position});
  DetectionResult found = vision::detect(*detector_, as_mat(image), p);
  runtime::Sightings s;
  for (const Detection& d : found.detections) s.seen.push_back({d.workpiece, d.pose(), d.yaw, d.confidence});
  s.not_seen = found.not_seen;
  s.rejected = found.rejected.size();
  s.frame_problem = found.frame_problem;
  s.detail = std::move(found);
  return s;
}

runtime::Image to_image(const cv::Mat& bgr) {
  runtime::Image image;
  if (bgr.empty()) return image;
  CW_CHECK(bgr.type() == CV_8UC3, "an image of OpenCV type {} is not 8-bit BGR", bgr.type());
  image.width = bgr.cols;
  image.height = bgr.rows;
  image.bgr.resize(static_cast<std::size_t>(bgr.cols) * static_cast<std::size_t>(bgr.rows) * 3);
  cv::Mat view(bgr.rows, bgr.cols, CV_8UC3, image.bgr.data());
  bgr.copyTo(view);
  return image;
}

cv::Mat as_mat(const runtime::Image& image) {
  if (image.empty()) return {};
  CW_CHECK(image.bgr.size() == static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3,
           "an image of {}x{} pixels has {} bytes", image.width, image.height, image.bgr.size());
  // OpenCV's header takes a non-const pointer; the Mat is only read.
  return cv::Mat(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.bgr.data()));
}

}  // namespace cellwright::vision
