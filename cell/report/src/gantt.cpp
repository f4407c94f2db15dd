// The Gantt chart of a run (gantt.hpp).
#include "cellwright/cell/gantt.hpp"

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::cell {

namespace {

// Text readable on the bar's colour.
cv::Scalar text_colour(Activity a) {
  return a == Activity::kMove || a == Activity::kBlocked ? cv::Scalar(255, 255, 255) : cv::Scalar(30, 30, 30);
}

// The marks of a workpiece's journey: green picked, purple handed over, black placed (BGR).
cv::Scalar mark_colour(JourneyStep s) {
  switch (s) {
    case JourneyStep::kPicked:
      return {115, 158, 0};
    case JourneyStep::kHandedOver:
      return {167, 121, 204};
    case JourneyStep::kPlaced:
      return {0, 0, 0};
  }
  return {0, 0, 0};
}

// What the legend says of each activity.
const char* legend_text(Activity a) {
  switch (a) {
    case Activity::kMove:
      return "move";
    case Activity::kGrip:
      return "open/close";
    case Activity::kWait:
      return "wait for a signal";
    case Activity::kPartWait:
      return "wait for the part";
    case Activity::kBlocked:
      return "blocked (done, next not started)";
  }
  return "?";
}

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kMinBlockedPx = 4;

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

// A journey mark: a triangle pointing down at x whose tip touches y.
void draw_mark(cv::Mat& img, int x, int y, JourneyStep s) {
  const std::vector<cv::Point> tri{{x - 5, y - 9}, {x + 5, y - 9}, {x, y}};
  cv::fillConvexPoly(img, tri, mark_colour(s), cv::LINE_AA);
}

// The bar's text, or a shorter form of it, if one fits in `room` px; "" if none does.
std::string fitting_label(const Bar& b, int room, double scale) {
  std::vector<std::string> candidates{b.label};
  if (const auto space = b.label.find(' '); space != std::string::npos) candidates.push_back(b.label.substr(space + 1));
  for (const std::string& c : candidates) {
    if (text_size(c, scale).width + 6 <= room) return c;
  }
  return std::string();
}

}  // namespace

cv::Scalar activity_colour(Activity a) {
  // Chosen to stay apart for colour-blind readers (Okabe-Ito): blue, orange, light grey, yellow, red-purple.
  switch (a) {
    case Activity::kMove:
      return {178, 114, 0};
    case Activity::kGrip:
      return {0, 159, 230};
    case Activity::kWait:
      return {200, 200, 200};
    case Activity::kPartWait:
      return {66, 228, 240};
    case Activity::kBlocked:
      return {120, 60, 204};
  }
  return {0, 0, 0};
}

cv::Scalar device_colour(DeviceActivity a) {
  // Okabe-Ito's colours the robots' bars leave: vermillion, bluish green, sky blue; and a dark grey.
  switch (a) {
    case DeviceActivity::kBusy:
      return {0, 94, 213};
    case DeviceActivity::kDone:
      return {115, 158, 0};
    case DeviceActivity::kRunning:
      return {233, 180, 86};
    case DeviceActivity::kOn:
      return {80, 80, 80};
  }
  return {0, 0, 0};
}

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
  CW_CHECK(options.width >= 400 && options.row_height >= 50, "Gantt chart of {} px with rows of {} px", options.width,
           options.row_height);
  const int rows = std::max<int>(1, static_cast<int>(timeline.robots.size() + timeline.devices.size()));
  const int title_h = options.title.empty() ? 15 : 50;
  // A chart with devices has a third legend line, for their states.
  const int left = 170, right = 40, axis_h = 60, legend_h = timeline.devices.empty() ? 84 : 120;
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
    // Above the bars, the journey marks; the bars below them.
    const int bar_top = y + 22, bar_bottom = y + options.row_height - 8;
    auto draw_bar = [&](const Bar& b, int min_width) {
      const int bx0 = x_of(b.start), bx1 = std::max(x_of(b.end), bx0 + min_width);
      cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, activity_colour(b.activity), cv::FILLED);
      return std::pair{bx0, bx1};
    };
    for (const Bar& b : rt.bars) {
      if (b.activity == Activity::kBlocked) continue;  // drawn last, over their neighbours
      const auto [bx0, bx1] = draw_bar(b, 1);
      if (bx1 - bx0 >= 3) cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, {255, 255, 255}, 1);
      // The command's text, or its target alone, where it fits; the legend says what the colour means.
      const double scale = 0.42;
      const std::string text = fitting_label(b, bx1 - bx0, scale);
      if (!text.empty()) {
        put_text(img, text, {bx0 + 3, (bar_top + bar_bottom + text_size(text, scale).height) / 2}, scale,
                 text_colour(b.activity));
      }
    }
    // A blocked span is drawn at least kMinBlockedPx wide so that a short one stays visible; unlabelled: what it
    // waits for is in the log.
    for (const Bar& b : rt.bars) {
      if (b.activity == Activity::kBlocked) draw_bar(b, kMinBlockedPx);
    }
    int text_end = x0;  // where the last mark's name ends: a name that would overlap it is left out
    for (const JourneyMark& m : rt.marks) {
      const int x = x_of(m.t);
      cv::line(img, {x, bar_top}, {x, bar_bottom}, mark_colour(m.step), 1);
      draw_mark(img, x, bar_top - 1, m.step);
      const cv::Size sz = text_size(m.workpiece, 0.4);
      if (x + 7 >= text_end && x + 7 + sz.width <= options.width) {
        put_text(img, m.workpiece, {x + 7, bar_top - 4}, 0.4, {0, 0, 0});
        text_end = x + 7 + sz.width + 4;
      }
    }
    cv::line(img, {0, y + options.row_height}, {options.width, y + options.row_height}, {180, 180, 180}, 1);
  }

  // The devices' rows, after the robots': a bar per span of a state that has one (a machine busy or done, labelled
  // with its part where it fits; a conveyor running; a sensor on).
  for (std::size_t i = 0; i < timeline.devices.size(); ++i) {
    const DeviceTimeline& d = timeline.devices[i];
    const std::size_t r = timeline.robots.size() + i;
    const int y = y_top + static_cast<int>(r) * options.row_height;
    if (r % 2 == 1) {
      cv::Mat band = img(cv::Rect(0, y, options.width, options.row_height));
      band -= cv::Scalar(8, 8, 8);
    }
    put_text(img, d.device, {12, y + options.row_height / 2 - 2}, 0.7, {0, 0, 0}, 2);
    put_text(img, d.kind, {12, y + options.row_height / 2 + 20}, 0.5, {90, 90, 90});
    const int bar_top = y + 22, bar_bottom = y + options.row_height - 8;
    for (const DeviceBar& b : d.bars) {
      const int bx0 = x_of(b.start), bx1 = std::max(x_of(b.end), bx0 + 1);
      cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, device_colour(b.activity), cv::FILLED);
      if (bx1 - bx0 >= 3) cv::rectangle(img, {bx0, bar_top}, {bx1, bar_bottom}, {255, 255, 255}, 1);
      const double scale = 0.42;
      const std::string text = b.workpiece.empty() ? std::string() : fmt::format("{} {}", to_string(b.activity), b.workpiece);
      for (const std::string& t : {text, b.workpiece}) {
        if (t.empty() || text_size(t, scale).width + 6 > bx1 - bx0) continue;
        put_text(img, t, {bx0 + 3, (bar_top + bar_bottom + text_size(t, scale).height) / 2}, scale,
                 b.activity == DeviceActivity::kOn ? cv::Scalar(255, 255, 255) : cv::Scalar(30, 30, 30));
        break;
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

  // Legend: the activities on one line, the journey marks on the next.
  int lx = x0;
  int ly = y_axis + axis_h + 8;
  for (Activity a : {Activity::kMove, Activity::kGrip, Activity::kWait, Activity::kPartWait, Activity::kBlocked}) {
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, activity_colour(a), cv::FILLED);
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, {60, 60, 60}, 1);
    const std::string text = legend_text(a);
    put_text(img, text, {lx + 36, ly + 16}, 0.5, {0, 0, 0});
    lx += 36 + text_size(text, 0.5).width + 30;
  }
  lx = x0;
  ly += 36;
  for (JourneyStep s : {JourneyStep::kPicked, JourneyStep::kHandedOver, JourneyStep::kPlaced}) {
    draw_mark(img, lx + 14, ly + 10, s);
    const std::string text = fmt::format("workpiece {}", to_string(s));
    put_text(img, text, {lx + 36, ly + 10}, 0.5, {0, 0, 0});
    lx += 36 + text_size(text, 0.5).width + 30;
  }
  if (!timeline.devices.empty()) {
    lx = x0;
    ly += 26;
    const std::pair<DeviceActivity, const char*> entries[] = {{DeviceActivity::kBusy, "machine busy"},
                                                              {DeviceActivity::kDone, "machine done (part to unload)"},
                                                              {DeviceActivity::kRunning, "conveyor running"},
                                                              {DeviceActivity::kOn, "sensor on"}};
    for (const auto& [a, text] : entries) {
      cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, device_colour(a), cv::FILLED);
      cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, {60, 60, 60}, 1);
      put_text(img, text, {lx + 36, ly + 16}, 0.5, {0, 0, 0});
      lx += 36 + text_size(text, 0.5).width + 30;
    }
  }
  return img;
}

}  // namespace cellwright::cell
