// How long the simulated gripper takes: the finger ramp the SimDriver drives the fingers along and the rules by which
// it ends a grip, as durations. The SimDriver moves its fingers with finger_ramp_duration(); the cycle-time estimate
// (cell/plan/estimate.hpp) uses the same functions to predict open and close commands.
//
// A grip moves both fingers' targets along a quintic ramp (trajectory.hpp) from where the ramp last stopped to the
// goal. An open (or a close on nothing) is done when the ramp is over and the fingers are at the goal and still; a
// close on a part is done once the fingers are blocked on it and the ramp has run `squeeze` past them (the fingers
// then press with the grip force: squeeze = grip force / finger stiffness). Either way the fingers must then stay
// still for kFingerRestWindow.
//
// Pure functions; any thread may call them.
#pragma once

#include <optional>

namespace cellwright::twin::sim {

inline constexpr double kFingerRestWindow = 0.02;  // s the fingers must stay stopped for a grip to be done
inline constexpr double kFingerMinTime = 0.1;      // s, the shortest finger motion

// Seconds the finger ramp takes from `from` to `to` (m, each finger's position) with its peak speed at `speed` m/s
// (> 0): at least kFingerMinTime.
double finger_ramp_duration(double from, double to, double speed);

// Seconds from the start of the finger ramp from `from` to `to` (speed > 0) until it passes `at`: nullopt unless `at`
// is strictly between them. (An open lets go of a part when its ramp passes the part's faces.)
std::optional<double> finger_ramp_time_to(double from, double to, double at, double speed);

// Seconds from the start of a closing ramp from `from` down to `closed` until the ramp passes `contact - squeeze`: when
// fingers blocked by a part at `contact` start pressing it. nullopt when the ramp never gets there (contact - squeeze
// <= closed, or contact >= from: the part is not between the fingers as they close). `from` > `closed`; speed > 0.
std::optional<double> finger_press_time(double from, double closed, double contact, double squeeze, double speed);

}  // namespace cellwright::twin::sim
