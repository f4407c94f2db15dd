// Drawing detections on camera images (draw.hpp).
#include "cellwright/vision/draw.hpp"

#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::vision {

namespace {

// Sub-pixel drawing: OpenCV takes fixed-point coordinates with kShift fractional bits.
constexpr int kShift = 4;
constexpr double kScale = 1 << kShift;

cv::Point fixed(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kScale)), static_cast<int>(std::lround(p.y * kScale))};
}

const cv::Scalar kWhite(255, 255, 255), kBlack(0, 0, 0), kRed(0, 0, 255), kGreen(0, 200, 0), kGrey(160, 160, 160);
const cv::Scalar kMagenta(255, 0, 255);  // outlines: no part, belt or fixture has this colour

constexpr double kFontScale = 0.4;

// Labels placed so far: a label that would cover one moves up until it is clear (parts stand side by side).
class Labels {
 public:
  explicit Labels(cv::Mat& image) : image_(image) {}

  // Text with a dark rim, readable on any background, its baseline starting at `at` or above; a leader line from
  // `anchor` when it had to move.
  void put(const std::string& text, cv::Point at, const cv::Scalar& colour, cv::Point anchor) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, kFontScale, 3, &baseline);
    cv::Rect box(at.x, at.y - size.height, size.width, size.height + baseline);
    const cv::Point start = at;
    for (int tries = 0; tries < 20 && clashes(box); ++tries) box.y -= size.height + 2;
    at.y = box.y + size.height;
    if (at != start) cv::line(image_, anchor, cv::Point(at.x, at.y - size.height / 2), colour, 1, cv::LINE_AA);
    cv::putText(image_, text, at, cv::FONT_HERSHEY_SIMPLEX, kFontScale, kBlack, 3, cv::LINE_AA);
    cv::putText(image_, text, at, cv::FONT_HERSHEY_SIMPLEX, kFontScale, colour, 1, cv::LINE_AA);
    placed_.push_back(box);
  }

 private:
  bool clashes(const cv::Rect& box) const {
    for (const cv::Rect& r : placed_) {
      if ((r & box).area() > 0) return true;
    }
    return false;
  }
  cv::Mat& image_;
  std::vector<cv::Rect> placed_;
};

}  // namespace

void draw_detections(cv::Mat& bgr, const DetectionResult& result) {
  CW_CHECK(!bgr.empty() && bgr.type() == CV_8UC3, "draw_detections needs an 8-bit BGR image");
  Labels labels(bgr);
  for (const Rejection& r : result.rejected) {
    cv::rectangle(bgr, r.box, kGrey, 1);
    labels.put(r.workpiece + "?", r.box.tl() + cv::Point(0, -3), kGrey, r.box.tl());
  }
  for (const Detection& d : result.detections) {
    std::vector<cv::Point> outline;
    for (const auto& p : d.outline) outline.push_back(fixed(p));
    if (!outline.empty()) cv::polylines(bgr, outline, true, kMagenta, 1, cv::LINE_AA, kShift);
    const cv::Point centre = fixed(d.top_centre);
    if (d.yaw) {
      cv::line(bgr, centre, fixed(d.axis_x), kRed, 1, cv::LINE_AA, kShift);
      cv::line(bgr, centre, fixed(d.axis_y), kGreen, 1, cv::LINE_AA, kShift);
    } else {
      const double r = std::hypot(d.axis_x.x - d.top_centre.x, d.axis_x.y - d.top_centre.y) / 2;
      cv::line(bgr, fixed(d.top_centre + cv::Point2d(-r, 0)), fixed(d.top_centre + cv::Point2d(r, 0)), kWhite, 1,
               cv::LINE_AA, kShift);
      cv::line(bgr, fixed(d.top_centre + cv::Point2d(0, -r)), fixed(d.top_centre + cv::Point2d(0, r)), kWhite, 1,
               cv::LINE_AA, kShift);
    }
    // The label to the right of the outline, level with its top.
    double right = d.top_centre.x, top = d.top_centre.y;
    for (const auto& p : d.outline) {
      right = std::max(right, p.x);
      top = std::min(top, p.y);
    }
    labels.put(fmt::format("{} {:.2f}", d.workpiece, d.confidence),
               cv::Point(static_cast<int>(right) + 3, static_cast<int>(top) + 8), kWhite,
               cv::Point(static_cast<int>(right), static_cast<int>(top)));
  }
}

void draw_frame_overlay(cv::Mat& bgr, double sim_time, const CameraModel& camera,
                        const std::vector<PredictedPart>& predictions, const std::vector<std::string>& not_seen) {
  CW_CHECK(bgr.type() == CV_8UC3, "draw_frame_overlay needs an 8-bit BGR image");
  const cv::Scalar yellow(0, 220, 255), red(0, 0, 230);
  for (const PredictedPart& p : predictions) {
    const std::optional<cv::Point2d> px = camera.project(p.position);
    if (!px || px->x < 0 || px->y < 0 || px->x >= bgr.cols || px->y >= bgr.rows) continue;
    const cv::Point at(static_cast<int>(std::lround(px->x)), static_cast<int>(std::lround(px->y)));
    cv::drawMarker(bgr, at, yellow, cv::MARKER_CROSS, 14, 2, cv::LINE_AA);
    const bool missed = std::find(not_seen.begin(), not_seen.end(), p.workpiece) != not_seen.end();
    if (missed) cv::circle(bgr, at, 12, red, 2, cv::LINE_AA);
    cv::putText(bgr, missed ? p.workpiece + " not seen" : p.workpiece + " predicted", at + cv::Point(9, 16),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, missed ? red : yellow, 1, cv::LINE_AA);
  }
  std::string text = fmt::format("t = {:.3f} s", sim_time);
  if (!not_seen.empty()) {
    text += "   not seen:";
    for (std::size_t i = 0; i < not_seen.size(); ++i) text += (i == 0 ? " " : ", ") + not_seen[i];
  }
  cv::rectangle(bgr, {0, 0}, {bgr.cols - 1, std::min(bgr.rows - 1, 21)}, {0, 0, 0}, cv::FILLED);
  cv::putText(bgr, text, {6, 15}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {255, 255, 255}, 1, cv::LINE_AA);
}

}  // namespace cellwright::vision
