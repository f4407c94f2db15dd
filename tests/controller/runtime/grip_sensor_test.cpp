// The grip sensor's rule, shared by the twin's world and the scripted plant.
#include "cellwright/runtime/grip_sensor.hpp"

#include <gtest/gtest.h>

#include <numbers>

namespace cellwright::runtime {
namespace {

Eigen::Isometry3d at(double x, double y, double z, double yaw = 0) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(x, y, z);
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

const std::vector<PartBox> kParts = {
    {"A", at(0, 0, 0.05), {0.04, 0.04, 0.10}},
    {"B", at(0.2, 0, 0.05, std::numbers::pi / 4), {0.10, 0.02, 0.10}},
};

TEST(GripSensor, BothPadsTouchingAroundAPartNameIt) {
  EXPECT_EQ(part_between_fingers(true, true, {0, 0, 0.08}, kParts), "A");
  EXPECT_EQ(part_between_fingers(true, true, {0.2, 0, 0.05}, kParts), "B");
}

TEST(GripSensor, OnePadOrNoneTouchingHoldsNothing) {
  EXPECT_EQ(part_between_fingers(true, false, {0, 0, 0.08}, kParts), "");
  EXPECT_EQ(part_between_fingers(false, true, {0, 0, 0.08}, kParts), "");
  EXPECT_EQ(part_between_fingers(false, false, {0, 0, 0.08}, kParts), "");
}

TEST(GripSensor, TheToolMustBeInsideThePartsBoxGrownByTheMargin) {
  // A's half width is 2 cm: 2.9 cm off the axis is within the 1 cm margin, 3.1 cm is not.
  EXPECT_EQ(part_between_fingers(true, true, {0.029, 0, 0.05}, kParts), "A");
  EXPECT_EQ(part_between_fingers(true, true, {0.031, 0, 0.05}, kParts), "");
  EXPECT_EQ(part_between_fingers(true, true, {0.031, 0, 0.05}, kParts, 0.02), "A");
  EXPECT_EQ(part_between_fingers(true, true, {0, 0, 0.111}, kParts), "");  // above its top
  // B is turned by 45 degrees: its long side runs along the diagonal.
  EXPECT_EQ(part_between_fingers(true, true, {0.2 + 0.035, 0.035, 0.05}, kParts), "B");
  EXPECT_EQ(part_between_fingers(true, true, {0.2 + 0.035, -0.035, 0.05}, kParts), "");
}

TEST(GripSensor, OfOverlappingBoxesTheNearestCentreWins) {
  const std::vector<PartBox> stacked = {{"low", at(0, 0, 0.05), {0.1, 0.1, 0.1}},
                                        {"high", at(0, 0, 0.13), {0.1, 0.1, 0.1}}};
  EXPECT_EQ(part_between_fingers(true, true, {0, 0, 0.10}, stacked), "high");
  EXPECT_EQ(part_between_fingers(true, true, {0, 0, 0.08}, stacked), "low");
  EXPECT_EQ(part_between_fingers(true, true, {0, 0, 0.08}, {}), "");
}

}  // namespace
}  // namespace cellwright::runtime
