// The Gantt chart of a run: one row per robot, one bar per command coloured by what the robot does (move, grip,
// wait for a signal, wait for the part, blocked), then one row per device of the log's device events (a machine's
// busy and done spans told apart and labelled with its part, a conveyor's running spans, a sensor's on spans; the
// legend gets a line for them; a chart without devices is what it was), the workpieces' journeys marked on the rows of the robots that
// picked, handed over and placed them (a triangle with the workpiece's name above the bar; a row per workpiece would
// repeat the robots' rows and grow with a shift's parts), a time axis with ticks and labels in seconds, and a legend
// of the colours and marks. Drawn with OpenCV from a Timeline
// (report.hpp), so it shows exactly the times report.json states.
//
// Thread safety: pure functions; any thread may call them.
#pragma once

#include <opencv2/core.hpp>

#include <string>

#include "cellwright/cell/report.hpp"

namespace cellwright::cell {

struct GanttOptions {
  int width = 1600;     // px of the whole image
  int row_height = 80;  // px per robot or device row (its bars and, above a robot's, the journey marks)
  std::string title;    // drawn above the chart; empty: none
};

// The chart as a BGR image. The time axis runs from 0 to timeline.end (at least 1 s) with "nice" tick steps (1, 2 or
// 5 times a power of ten, about 10-20 ticks); bars wide enough carry their command's text (or its target alone when
// only that fits); blocked spans are drawn at least 4 px wide, over their neighbours, so that short ones stay
// visible; a mark's name is left out where it would overlap the previous one. InternalError if the width
// is under 400 px or the row height under 50 px.
cv::Mat draw_gantt(const Timeline& timeline, const GanttOptions& options = {});

// The colour (BGR) of an activity's bars and legend entry.
cv::Scalar activity_colour(Activity a);

// The colour (BGR) of a device's bars and legend entry: a machine busy vermillion, done bluish green; a conveyor
// running sky blue; a sensor on dark grey.
cv::Scalar device_colour(DeviceActivity a);

// The tick step draw_gantt uses for an axis of `span` seconds (> 0): the smallest of 1, 2, 5 x 10^k giving at most
// `max_ticks` intervals.
double tick_step(double span, int max_ticks = 20);

}  // namespace cellwright::cell
