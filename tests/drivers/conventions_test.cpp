// A controller's conventions as settings (docs/real-robots.md, "Commissioning"): VAL's published O, A, T reading, the
// world frame and tool point (controller_frames.hpp), the Movemaster's pitch and roll reading. Each conversion is
// checked against the published description and round-tripped on seeded random poses, per setting.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <random>

#include "cellwright/drivers/controller_frames.hpp"
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/drivers/val2/val2_protocol.hpp"

namespace cellwright::drivers {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Isometry3d random_pose(std::mt19937_64& rng, double reach) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized().toRotationMatrix();
  p.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng)) * reach;
  return p;
}

double turn_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

// VAL's instruction set (1977): "with all three angles zero, the hand points in the negative Y direction with the
// fingers in a horizontal plane; the orientation vector from one finger tip to the other is aligned along the X axis;
// O specifies a rotation of the orientation vector about a vertical direction".
TEST(ValOrientation, AllZeroPointsTheHandAlongMinusYWithTheFingersAlongX) {
  const Eigen::Matrix3d r = val2::oat_rotation(0, 0, 0, val2::Orientation::val);
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12)) << r;  // the approach axis
  EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12)) << r;   // the finger line (the TCP's y)
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  // O turns the hand about the vertical, still horizontal: at O = 90 it points along +X.
  const Eigen::Matrix3d o90 = val2::oat_rotation(90, 0, 0, val2::Orientation::val);
  EXPECT_TRUE(o90.col(2).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12)) << o90;
  EXPECT_NEAR(o90.col(1).z(), 0.0, 1e-12);
  // A tilts it about the finger line: A = 90 points it straight down (the project's reading of A's sense).
  EXPECT_TRUE(val2::oat_rotation(0, 90, 0, val2::Orientation::val).col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  // T turns the fingers about the approach axis, which stays put.
  const Eigen::Matrix3d t30 = val2::oat_rotation(0, 0, 30, val2::Orientation::val);
  EXPECT_TRUE(t30.col(2).isApprox(r.col(2), 1e-12));
  EXPECT_NEAR(turn_between(t30, r), 30 * kDeg, 1e-12);
}

TEST(ValOrientation, EveryPoseRoundTripsThroughALocationInEachConvention) {
  std::mt19937_64 rng(25);
  for (const val2::Orientation o : {val2::Orientation::tool_down, val2::Orientation::zyz, val2::Orientation::val}) {
    for (int i = 0; i < 500; ++i) {
      const Eigen::Isometry3d pose = random_pose(rng, 1.0);
      const val2::Location l = val2::to_location(pose, o);
      const Eigen::Isometry3d back = val2::to_pose(l, o);
      ASSERT_LT(turn_between(back.linear(), pose.linear()), 1e-9) << static_cast<int>(o) << " pose " << i;
      ASSERT_LT((back.translation() - pose.translation()).norm(), 1e-12);
      if (o == val2::Orientation::val) {
        ASSERT_LE(std::abs(l.a), 90.0);
      }
    }
  }
  // Straight down (A = 90, where O and T turn about one axis) round-trips too.
  for (const double o : {-120.0, 0.0, 45.0, 180.0}) {
    const Eigen::Matrix3d r = val2::oat_rotation(o, 90, 0, val2::Orientation::val);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = r;
    const val2::Location l = val2::to_location(pose, val2::Orientation::val);
    EXPECT_NEAR(l.a, 90.0, 1e-9);
    EXPECT_LT(turn_between(val2::to_pose(l, val2::Orientation::val).linear(), r), 1e-9) << o;
  }
}

TEST(ControllerFrames, IdentityLeavesPosesBitForBit) {
  const ControllerFrames none;
  std::mt19937_64 rng(7);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Isometry3d p = random_pose(rng, 1.0);
    EXPECT_EQ(none.to_controller(p).matrix(), p.matrix());
    EXPECT_EQ(none.from_controller(p).matrix(), p.matrix());
  }
}

TEST(ControllerFrames, AShoulderWorldMovesTheNumbersDownAndBackAndEveryFrameRoundTrips) {
  ControllerFrames shoulder;
  shoulder.world.translation() = Eigen::Vector3d(0, 0, 0.67183);
  Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();
  tcp.translation() = Eigen::Vector3d(0.45, 0.1, 0.8);
  EXPECT_TRUE(shoulder.to_controller(tcp).translation().isApprox(Eigen::Vector3d(0.45, 0.1, 0.8 - 0.67183), 1e-12));
  // A tool point at the flange, 146 mm behind the TCP along its approach axis.
  ControllerFrames flange;
  flange.tool.translation() = Eigen::Vector3d(0, 0, -0.146);
  tcp.linear() = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();  // pointing down
  EXPECT_TRUE(flange.to_controller(tcp).translation().isApprox(Eigen::Vector3d(0.45, 0.1, 0.8 + 0.146), 1e-12));

  std::mt19937_64 rng(11);
  for (int i = 0; i < 200; ++i) {
    ControllerFrames f;
    f.world = random_pose(rng, 2.0);
    f.tool = random_pose(rng, 0.3);
    const Eigen::Isometry3d p = random_pose(rng, 1.0);
    const Eigen::Isometry3d back = f.from_controller(f.to_controller(p));
    ASSERT_LT((back.translation() - p.translation()).norm(), 1e-12);
    ASSERT_LT(turn_between(back.linear(), p.linear()), 1e-9);
  }
}

// The Movemaster's p and r as a controller that reads them otherwise writes them: the same map both ways, and the
// pose it stands for is the page's pose with the hand mirrored in pitch, turned the other way in roll.
TEST(MovemasterAngleReading, EachSettingRoundTripsAndPitchDownPositivePointsDownAtNinety) {
  const movemaster::Xyzpr page{300, 50, 200, -90, 30};
  const movemaster::Xyzpr flipped = movemaster::with_angle_reading(page, 90, -1);
  EXPECT_EQ(flipped, (movemaster::Xyzpr{300, 50, 200, 90, -30}));
  EXPECT_EQ(movemaster::with_angle_reading(page, -90, 1), page);
  // With pitch_down 90, p = +90 points straight down.
  const Eigen::Isometry3d down =
      movemaster::to_pose(movemaster::with_angle_reading(movemaster::Xyzpr{300, 0, 200, 90, 0}, 90, 1));
  EXPECT_TRUE(down.linear().col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));

  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> mm(-500, 500), deg(-179, 179);
  for (const double pitch_down : {-90.0, 90.0}) {
    for (const int roll : {1, -1}) {
      for (int i = 0; i < 200; ++i) {
        movemaster::Xyzpr v{mm(rng), mm(rng), mm(rng), deg(rng), deg(rng)};
        if (std::hypot(v.x, v.y) < 1) v.x += 10;
        const Eigen::Isometry3d pose = movemaster::to_pose(movemaster::with_angle_reading(v, pitch_down, roll));
        std::string why;
        const auto page_v = movemaster::to_xyzpr(pose, 0.5, &why);
        ASSERT_TRUE(page_v.has_value()) << why;
        const movemaster::Xyzpr back = movemaster::with_angle_reading(*page_v, pitch_down, roll);
        ASSERT_NEAR(back.x, v.x, 1e-9);
        ASSERT_NEAR(back.z, v.z, 1e-9);
        ASSERT_LT(turn_between(movemaster::to_pose(movemaster::with_angle_reading(back, pitch_down, roll)).linear(),
                               pose.linear()),
                  1e-9);
      }
    }
  }
}

}  // namespace
}  // namespace cellwright::drivers
