// The twin's measurement of a coordinated carry (carry_meter.hpp): hands and a beam put where each test needs them;
// what the report will show: the grasp transform taken when both hands first hold it, the relative tool error and
// turn against it, the squeeze along the beam from the two wrist forces (its sign), the tilt, and a new hold anew.
#include "cellwright/twin/sim/carry_meter.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <vector>

namespace cellwright::twin::sim {
namespace {

using std::chrono::milliseconds;

Eigen::Isometry3d at(double x, double y, double z) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, y, z));
}

class CarryMeterTest : public ::testing::Test {
 protected:
  std::vector<CarryHand> hands_ = {{"puma", at(0.51, -0.2, 0.45), "beam", Eigen::Vector3d(0, 0, 15)},
                                   {"melfa", at(1.19, -0.2, 0.45), "beam", Eigen::Vector3d(0, 0, 15)},
                                   {"kuka", at(0, 1, 1), "", Eigen::Vector3d::Zero()}};
  std::vector<CarryPart> parts_ = {{"beam", at(0.85, -0.2, 0.42), Eigen::Vector3d(0.8, 0.04, 0.04)},
                                   {"box", at(0, 0, 0), Eigen::Vector3d(0.05, 0.05, 0.05)}};
  CarryMeter meter_;
};

TEST_F(CarryMeterTest, NothingWhileOneHandHoldsTheBeam) {
  hands_[1].held.clear();
  EXPECT_TRUE(meter_.measure(milliseconds(10), hands_, parts_).empty());
}

TEST_F(CarryMeterTest, TheFirstPeriodBothHoldTakesTheGraspLaterOnesCompareWithIt) {
  const auto first = meter_.measure(milliseconds(10), hands_, parts_);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].workpiece, "beam");
  EXPECT_EQ(first[0].a, "puma");
  EXPECT_EQ(first[0].b, "melfa");
  EXPECT_EQ(first[0].t, milliseconds(10));
  EXPECT_NEAR(first[0].error, 0.0, 1e-9);
  EXPECT_NEAR(first[0].squeeze, 0.0, 1e-9);
  EXPECT_NEAR(first[0].tilt, 0.0, 1e-9);
  // Both lifted 10 cm together: no error. Then the melfa 12 mm behind along y and turned 2 degrees about z.
  for (CarryHand& h : hands_) h.tcp.translation().z() += 0.1;
  EXPECT_NEAR(meter_.measure(milliseconds(20), hands_, parts_).at(0).error, 0.0, 1e-9);
  hands_[1].tcp.translation().y() -= 0.012;
  hands_[1].tcp.linear() = Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto off = meter_.measure(milliseconds(30), hands_, parts_);
  EXPECT_NEAR(off.at(0).error, 12.0, 1e-6);
  EXPECT_NEAR(off.at(0).turn, 2.0, 1e-6);
}

TEST_F(CarryMeterTest, TheSqueezeIsTheForceAlongTheBeamThatCancelsPositivePushing) {
  // Pushing the ends together: the beam pushes puma's hand back (-x), so the puma's arm pushes it on (+x), and the
  // other way round for the melfa; both hold up 20 N of weight and push a common 3 N sideways, which cancel.
  hands_[0].wrist_force = Eigen::Vector3d(12, 3, 20);
  hands_[1].wrist_force = Eigen::Vector3d(-12, 3, 20);
  EXPECT_NEAR(meter_.measure(milliseconds(10), hands_, parts_).at(0).squeeze, 12.0, 1e-9);
  std::swap(hands_[0].wrist_force, hands_[1].wrist_force);
  EXPECT_NEAR(meter_.measure(milliseconds(20), hands_, parts_).at(0).squeeze, -12.0, 1e-9);
}

TEST_F(CarryMeterTest, TheTiltIsTheLongAxisFromHorizontal) {
  parts_[0].pose.linear() = Eigen::AngleAxisd(5.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_NEAR(meter_.measure(milliseconds(10), hands_, parts_).at(0).tilt, 5.0, 1e-9);
  // Turned about its long axis it is still level.
  parts_[0].pose.linear() = Eigen::AngleAxisd(30.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_NEAR(meter_.measure(milliseconds(20), hands_, parts_).at(0).tilt, 0.0, 1e-9);
}

TEST_F(CarryMeterTest, ANewHoldTakesTheGraspAnew) {
  meter_.measure(milliseconds(10), hands_, parts_);
  hands_[1].held.clear();
  EXPECT_TRUE(meter_.measure(milliseconds(20), hands_, parts_).empty());
  hands_[1].held = "beam";
  hands_[1].tcp.translation().x() -= 0.05;  // grasped 5 cm further in
  EXPECT_NEAR(meter_.measure(milliseconds(30), hands_, parts_).at(0).error, 0.0, 1e-9);
}

}  // namespace
}  // namespace cellwright::twin::sim
