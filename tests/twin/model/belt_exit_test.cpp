// Where a part leaves the cell on an exit conveyor of a shift: the plant takes parts out by this rule and the
// cycle-time estimate times a body's ride by it, so it is tested once, here, on a conveyor turned and moved in the
// world.
#include "cellwright/twin/sim/belt_exit.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cellwright::twin::sim {
namespace {

// The shipped cell's output conveyor: running +y, its upstream end near the MELFA, a stop bar at its end.
models::ConveyorSpec output(bool stop) {
  models::ConveyorSpec c;
  c.name = "output";
  c.pose.xyz = Eigen::Vector3d(0.95, 0.875, 0);
  c.pose.rpy = Eigen::Vector3d(0, 0, M_PI / 2);
  c.length = 1.0;
  c.width = 0.2;
  c.height = 0.35;
  c.speed = 0.05;
  c.enter = 0.03;
  c.leave = 0.95;
  c.stop = stop;
  return c;
}

// A part's centre 3 cm above the belt, `s` along it from its upstream end and `across` to its left.
Eigen::Vector3d part_at(const models::ConveyorSpec& c, double s, double across = 0) {
  return c.belt_point(s) + Eigen::Vector3d(-across, 0, 0.03);  // the belt runs +y: its left is -x
}

TEST(BeltExit, MeasuresAlongTheBeltFromItsUpstreamEnd) {
  const models::ConveyorSpec c = output(true);
  const BeltExit e(c);
  EXPECT_EQ(&e.conveyor(), &c);
  // The upstream end is at y = 0.875 - 0.5 = 0.375 in the world.
  EXPECT_NEAR(*e.along(Eigen::Vector3d(0.95, 0.405, 0.38)), 0.03, 1e-12);
  EXPECT_NEAR(*e.along(part_at(c, 0.5)), 0.5, 1e-12);
  EXPECT_NEAR(*e.along(part_at(c, 0.5, 0.14)), 0.5, 1e-12);  // within half the width + 5 cm across
}

TEST(BeltExit, PointsOffTheBeltsLineAreNotOnIt) {
  const models::ConveyorSpec c = output(true);
  const BeltExit e(c);
  EXPECT_FALSE(e.along(part_at(c, 0.5, 0.16)));                            // beside it
  EXPECT_FALSE(e.along(part_at(c, -0.01)));                                // before its upstream end
  EXPECT_TRUE(e.along(part_at(c, 1.49)));                                  // falling off its end ...
  EXPECT_FALSE(e.along(part_at(c, 1.51)));                                 // ... not further
  EXPECT_FALSE(e.along(c.belt_point(0.5) - Eigen::Vector3d(0, 0, 0.36)));  // under the floor
}

TEST(BeltExit, APartLeavesFiveCentimetresBeforeAStopBarOrAtTheLeavePoint) {
  const models::ConveyorSpec with_stop = output(true), without = output(false);
  const BeltExit stop(with_stop), end(without);
  EXPECT_DOUBLE_EQ(stop.out_at(), 0.90);
  EXPECT_DOUBLE_EQ(end.out_at(), 0.95);
  EXPECT_FALSE(stop.left(part_at(with_stop, 0.89)));
  EXPECT_TRUE(stop.left(part_at(with_stop, 0.91)));
  EXPECT_FALSE(end.left(part_at(without, 0.94)));
  EXPECT_TRUE(end.left(part_at(without, 0.96)));
  EXPECT_TRUE(end.left(part_at(without, 1.3)));         // fallen off the end, still on its line
  EXPECT_FALSE(end.left(part_at(without, 0.96, 0.3)));  // beside the belt: not on it
}

}  // namespace
}  // namespace cellwright::twin::sim
