// The finger ramp's timing, which the SimDriver drives the fingers by and the cycle-time estimate predicts grips with.
#include "cellwright/twin/sim/grip_timing.hpp"

#include <gtest/gtest.h>

#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::twin::sim {
namespace {

// Where the ramp from `from` to `to` at `speed` stands `t` seconds after it began.
double ramp_at(double from, double to, double speed, double t) {
  return from + (to - from) * quintic(t / finger_ramp_duration(from, to, speed));
}

TEST(FingerRamp, IsTimedByItsPeakSpeedAndAtLeastTheShortestMotion) {
  EXPECT_DOUBLE_EQ(finger_ramp_duration(0.0, 0.04, 0.05), kQuinticPeakSpeed * 0.04 / 0.05);
  EXPECT_DOUBLE_EQ(finger_ramp_duration(0.04, 0.0, 0.05), kQuinticPeakSpeed * 0.04 / 0.05);
  EXPECT_DOUBLE_EQ(finger_ramp_duration(0.04, 0.04, 0.05), kFingerMinTime);
}

TEST(FingerRamp, PassesAPointWhereTheRampStandsThen) {
  // An open from closed lets go of a 40 mm part (faces 20 mm from the centre) halfway through: the ramp is symmetric.
  const double full = finger_ramp_duration(0.0, 0.04, 0.05);
  EXPECT_NEAR(*finger_ramp_time_to(0.0, 0.04, 0.02, 0.05), full / 2, 1e-12);
  for (double at : {0.001, 0.01, 0.03, 0.039}) {
    const double t = *finger_ramp_time_to(0.0, 0.04, at, 0.05);
    EXPECT_NEAR(ramp_at(0.0, 0.04, 0.05, t), at, 1e-9) << at;
    // Closing, the same point is passed as long before the end as opening passes it after the start.
    EXPECT_NEAR(*finger_ramp_time_to(0.04, 0.0, at, 0.05), full - t, 1e-9) << at;
  }
  // Not between the ends: never passed.
  EXPECT_FALSE(finger_ramp_time_to(0.0, 0.04, 0.0, 0.05));
  EXPECT_FALSE(finger_ramp_time_to(0.0, 0.04, 0.05, 0.05));
  EXPECT_FALSE(finger_ramp_time_to(0.01, 0.04, 0.005, 0.05));
}

TEST(FingerRamp, AClosePressesWhenTheRampHasRunTheSqueezePastThePart) {
  const double t = *finger_press_time(0.04, 0.0, 0.02, 0.002, 0.05);
  EXPECT_NEAR(ramp_at(0.04, 0.0, 0.05, t), 0.018, 1e-9);
  EXPECT_FALSE(finger_press_time(0.04, 0.0, 0.041, 0.002, 0.05));  // wider than the open fingers
  EXPECT_FALSE(finger_press_time(0.04, 0.0, 0.001, 0.002, 0.05));  // too thin to press
}

}  // namespace
}  // namespace cellwright::twin::sim
