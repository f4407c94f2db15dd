#include "cellwright/twin/sim/grip_timing.hpp"

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::twin::sim {

double finger_ramp_duration(double from, double to, double speed) {
  CW_CHECK(speed > 0, "finger speed {}", speed);
  return std::max(kFingerMinTime, kQuinticPeakSpeed * std::abs(to - from) / speed);
}

std::optional<double> finger_ramp_time_to(double from, double to, double at, double speed) {
  CW_CHECK(speed > 0, "finger speed {}", speed);
  if (!(std::min(from, to) < at && at < std::max(from, to))) return std::nullopt;
  const double fraction = (at - from) / (to - from);  // of the ramp: quintic(u) = fraction
  double lo = 0, hi = 1;  // quintic is increasing on [0, 1]: bisect to well below a physics step
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (quintic(mid) < fraction ? lo : hi) = mid;
  }
  return hi * finger_ramp_duration(from, to, speed);
}

std::optional<double> finger_press_time(double from, double closed, double contact, double squeeze, double speed) {
  CW_CHECK(from > closed && speed > 0, "closing ramp from {} to {} at {}", from, closed, speed);
  const double press = contact - squeeze;  // the ramp's position when the blocked fingers press with the full force
  if (press <= closed || contact >= from) return std::nullopt;
  return finger_ramp_time_to(from, closed, press, speed);
}

}  // namespace cellwright::twin::sim
