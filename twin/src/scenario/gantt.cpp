// The Gantt chart of a run (gantt.hpp).
#include "cellwright/twin/scenario/gantt.hpp"

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::scenario {

namespace {

// Colours (BGR) chosen to stay apart for colour-blind readers: blue, orange, light grey, red-purple.
cv::Scalar colour(Activity a) {
  switch (a) {
    case Activity::kMove:
      return {178, 114, 0};  // blue
    case Activity::kGrip:
      return {0, 159, 230};  // orange
    case Activity::kWait:
      return {200, 200, 200};  // grey
    case Activity::kBlocked:
      return {120, 60, 204};  // red-purple
  }
  return {0, 0, 0};
}

// Text readable on the bar's colour.
cv::Scalar text_colour(Activity a) {
  return a == Activity::kWait || a == Activity::kGrip ? cv::Scalar(30, 30, 30) : cv::Scalar(255, 255, 255);
}

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void put_text(cv::Mat& img, const std::string& text, cv::Point at, double scale, const cv::Scalar& c, int thick = 1) {
  cv::putText(img, text, at, kFont, scale, c, thick, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, double scale, int thick = 1) {
  int base = 0;
  return cv::getTextSize(text, kFont, scale, thick, &base);
}

std::string seconds_label(double t, double step) {
  // As many decimals as the step needs: 0.5 -> 1 decimal, 2 -> none.
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  return fmt::format("{:.{}f}", t, decimals);
}

}  // namespace

double tick_step(double span, int max_ticks) {
  CW_CHECK(span > 0 && max_ticks > 0, "tick_step({}, {})", span, max_ticks);
  double power = std::pow(10.0, std::floor(std::log10(span / max_ticks)));
  for (;;) {
    for (double m : {1.0, 2.0, 5.0}) {
      if (span / (m * power) <= max_ticks + 1e-9) return m * power;
    }
    power *= 10;
  }
}

cv::Mat draw_gantt(const Timeline& timeline, const GanttOptions& options) {
  CW_CHECK(options.width >= 400 && options.row_height >= 30, "Gantt chart of {} px with rows of {} px", options.width,
           options.row_height);
  const int rows = std::max<int>(1, static_cast<int>(timeline.robots.size()));
  const int title_h = options.title.empty() ? 15 : 50;
  const int left = 170, right = 40, axis_h = 60, legend_h = 50;
  const int height = title_h + rows * options.row_height + axis_h + legend_h;
  cv::Mat img(height, options.width, CV_8UC3, cv::Scalar(255, 255, 255));

  const double span = std::max(1.0, timeline.end);
  const double step = tick_step(span, 20);
  const double axis_end = std::ceil(span / step - 1e-9) * step;
  const int x0 = left, x1 = options.width - right;
  auto x_of = [&](double t) { return x0 + static_cast<int>(std::lround((x1 - x0) * t / axis_end)); };
  const int y_top = title_h;
  const int y_axis = title_h + rows * options.row_height;

  if (!options.title.empty()) put_text(img, options.title, {x0, 32}, 0.75, {0, 0, 0}, 2);

  // Grid lines at each tick, under the bars.
  for (double t = 0; t <= axis_end + step / 2; t += step) {
    cv::line(img, {x_of(t), y_top}, {x_of(t), y_axis}, {232, 232, 232}, 1);
  }

  for (std::size_t r = 0; r < timeline.robots.size(); ++r) {
    const RobotTimeline& rt = timeline.robots[r];
    const int y = y_top + static_cast<int>(r) * options.row_height;
    if (r % 2 == 1) {
      cv::Mat band = img(cv::Rect(0, y, options.width, options.row_height));
      band -= cv::Scalar(8, 8, 8);
    }
    put_text(img, rt.robot, {12, y + options.row_height / 2 - 2}, 0.7, {0, 0, 0}, 2);
    put_text(img, rt.cell, {12, y + options.row_height / 2 + 20}, 0.5, {90, 90, 90});
    const int bar_top = y + options.row_height / 6, bar_bottom = y + options.row_height * 5 / 6;
    for (const Bar& b : rt.bars) {
      const int bx0 = x_of(b.start), bx1 = std::max(x_of(b.end), bx0 + 1);
      cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, colour(b.activity), cv::FILLED);
      if (bx1 - bx0 >= 3) cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, {255, 255, 255}, 1);
      // The command's text when it fits (blocked bars stay unlabelled: they say what they wait for only in the log).
      if (b.activity == Activity::kBlocked) continue;
      const double scale = 0.42;
      const std::string text = b.label;
      const cv::Size sz = text_size(text, scale);
      if (sz.width + 6 <= bx1 - bx0) {
        put_text(img, text, {bx0 + 3, (bar_top + bar_bottom + sz.height) / 2}, scale, text_colour(b.activity));
      }
    }
    cv::line(img, {0, y + options.row_height}, {options.width, y + options.row_height}, {180, 180, 180}, 1);
  }

  // Time axis: a line, ticks and their labels, and the axis title.
  cv::line(img, {x0, y_axis}, {x1, y_axis}, {0, 0, 0}, 2);
  cv::line(img, {x0, y_top}, {x0, y_axis}, {0, 0, 0}, 1);
  for (double t = 0; t <= axis_end + step / 2; t += step) {
    const int x = x_of(t);
    cv::line(img, {x, y_axis}, {x, y_axis + 8}, {0, 0, 0}, 1);
    const std::string label = seconds_label(t, step);
    const cv::Size sz = text_size(label, 0.5);
    put_text(img, label, {x - sz.width / 2, y_axis + 12 + sz.height}, 0.5, {0, 0, 0});
  }
  {
    const std::string label = "simulation time (s)";
    const cv::Size sz = text_size(label, 0.55);
    put_text(img, label, {(x0 + x1 - sz.width) / 2, y_axis + 52}, 0.55, {0, 0, 0});
  }

  // Legend.
  int lx = x0;
  const int ly = y_axis + axis_h + 12;
  for (Activity a : {Activity::kMove, Activity::kGrip, Activity::kWait, Activity::kBlocked}) {
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, colour(a), cv::FILLED);
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, {60, 60, 60}, 1);
    const std::string text = to_string(a);
    put_text(img, text, {lx + 36, ly + 16}, 0.55, {0, 0, 0});
    lx += 36 + text_size(text, 0.55).width + 40;
  }
  return img;
}

}  // namespace cellwright::twin::scenario
