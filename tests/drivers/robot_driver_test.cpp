#include "cellwright/drivers/robot_driver.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>

namespace cellwright::drivers {
namespace {

using ::testing::HasSubstr;

// A 6-axis arm that can do everything the interface describes.
Capabilities full_robot() {
  Capabilities c;
  c.joints = 6;
  c.joint_control = c.cartesian_control = c.linear_motion = c.full_orientation = true;
  c.gripper = c.gripper_width = c.gripper_force = true;
  c.gripper_max_width = 0.08;
  c.gripper_max_force = 40.0;
  c.digital_outputs = 8;
  c.digital_inputs = 8;
  c.queue_depth = 4;
  c.reads_joints = c.reads_pose = true;
  return c;
}

// A Movemaster-like arm: 5 axes, open/close gripper only, no digital I/O through the driver.
Capabilities small_robot() {
  Capabilities c;
  c.joints = 5;
  c.joint_control = c.cartesian_control = true;
  c.gripper = true;
  c.reads_pose = true;
  return c;
}

Eigen::Isometry3d pose_at(double x, double y, double z, double yaw) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(x, y, z);
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

TEST(DriverCheckCommand, AcceptsWellFormedCommands) {
  const Capabilities caps = full_robot();
  EXPECT_FALSE(check_command(MoveJoints{{0, 0.1, -0.2, 0.3, 0, 1}, 0.5}, caps));
  EXPECT_FALSE(check_command(MovePose{pose_at(0.3, 0.1, 0.2, 0.5), Path::linear, 1.0}, caps));
  EXPECT_FALSE(check_command(Grip{Grip::Action::close, 0.02, 10.0}, caps));
  EXPECT_FALSE(check_command(Grip{Grip::Action::open, std::nullopt, std::nullopt}, caps));
  EXPECT_FALSE(check_command(SetOutput{8, true}, caps));
  EXPECT_FALSE(check_command(WaitInput{1, false, std::chrono::seconds(2)}, caps));
}

TEST(DriverCheckCommand, RefusesWhatTheRobotCannotDoAsUnsupported) {
  const Capabilities caps = small_robot();
  auto error_of = [&](const Command& c) { return check_command(c, caps).error; };
  EXPECT_EQ(error_of(MovePose{pose_at(0.2, 0, 0.2, 0), Path::linear, 0.5}), ErrorCode::unsupported);
  EXPECT_EQ(error_of(MovePose{pose_at(0.2, 0, 0.2, 0), Path::joint, 0.5}), ErrorCode::none);
  EXPECT_EQ(error_of(Grip{Grip::Action::close, 0.01, std::nullopt}), ErrorCode::unsupported);
  EXPECT_EQ(error_of(Grip{Grip::Action::close, std::nullopt, 5.0}), ErrorCode::unsupported);
  Capabilities no_joints = caps;
  no_joints.joint_control = false;
  EXPECT_EQ(check_command(MoveJoints{{0, 0, 0, 0, 0}, 1.0}, no_joints).error, ErrorCode::unsupported);
  Capabilities no_gripper = caps;
  no_gripper.gripper = false;
  EXPECT_EQ(check_command(Grip{}, no_gripper).error, ErrorCode::unsupported);
}

TEST(DriverCheckCommand, ATimedMoveNeedsATimedRobotAndAPositiveDuration) {
  Capabilities caps = full_robot();
  MoveJoints timed{{0, 0, 0, 0, 0, 0}, 0.5, 1.25};
  MovePose timed_pose{pose_at(0.3, 0, 0.2, 0), Path::linear, 0.5, 1.25};
  // A robot whose controller times its own moves (Movemaster, VAL II) cannot promise a duration: refused, not ignored.
  EXPECT_EQ(check_command(timed, caps).error, ErrorCode::unsupported);
  EXPECT_EQ(check_command(timed_pose, caps).message, "this robot's moves cannot be given a duration");
  caps.timed_motion = true;
  EXPECT_FALSE(check_command(timed, caps));
  EXPECT_FALSE(check_command(timed_pose, caps));
  timed.duration = 0.0;
  EXPECT_EQ(check_command(timed, caps).message, "duration 0 s is not a positive time");
  timed_pose.duration = std::numeric_limits<double>::infinity();
  EXPECT_EQ(check_command(timed_pose, caps).error, ErrorCode::invalid_command);
  // The log shows the duration of a timed move; an untimed one reads as before.
  EXPECT_EQ(describe(MoveJoints{{0, 1}, 0.5, 2.0}), "move_joints [0.000000, 1.000000] speed 0.500000 duration 2.000000");
  EXPECT_EQ(describe(MoveJoints{{0, 1}, 0.5}), "move_joints [0.000000, 1.000000] speed 0.500000");
}

TEST(DriverCheckCommand, RefusesBadValuesNamingThem) {
  const Capabilities caps = full_robot();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto refusal = [&](const Command& c) {
    Refusal r = check_command(c, caps);
    EXPECT_EQ(r.error, ErrorCode::invalid_command) << describe(c);
    return r.message;
  };
  EXPECT_EQ(refusal(MoveJoints{{0, 0, 0}, 1.0}), "3 joint positions given, the robot has 6 joints");
  EXPECT_EQ(refusal(MoveJoints{{0, 0, nan, 0, 0, 0}, 1.0}), "joint 3 position is nan");
  EXPECT_EQ(refusal(MoveJoints{{0, 0, 0, 0, 0, 0}, 0.0}), "speed 0 is not a fraction in (0, 1]");
  EXPECT_EQ(refusal(MoveJoints{{0, 0, 0, 0, 0, 0}, 1.5}), "speed 1.5 is not a fraction in (0, 1]");
  EXPECT_THAT(refusal(MovePose{pose_at(0.3, 0, 0.2, 0), Path::joint, nan}), HasSubstr("speed nan"));
  Eigen::Isometry3d scaled = pose_at(0.3, 0, 0.2, 0);
  scaled.linear() *= 2.0;
  EXPECT_THAT(refusal(MovePose{scaled, Path::joint, 1.0}), HasSubstr("not a rotation"));
  Eigen::Isometry3d mirrored = pose_at(0.3, 0, 0.2, 0);
  mirrored.linear()(2, 2) = -1.0;
  EXPECT_THAT(refusal(MovePose{mirrored, Path::joint, 1.0}), HasSubstr("not a rotation"));
  Eigen::Isometry3d infinite = pose_at(0.3, 0, 0.2, 0);
  infinite.translation().x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(refusal(MovePose{infinite, Path::joint, 1.0}), "the target pose is not finite");
  EXPECT_EQ(refusal(Grip{Grip::Action::close, 0.09, std::nullopt}), "gripper width 0.09 m is outside [0, 0.08] m");
  EXPECT_EQ(refusal(Grip{Grip::Action::close, -0.01, std::nullopt}), "gripper width -0.01 m is outside [0, 0.08] m");
  EXPECT_EQ(refusal(Grip{Grip::Action::close, std::nullopt, 0.0}), "gripper force 0 N is outside (0, 40] N");
  EXPECT_EQ(refusal(SetOutput{0, true}), "digital output 0 is outside 1..8");
  EXPECT_EQ(refusal(SetOutput{9, true}), "digital output 9 is outside 1..8");
  EXPECT_EQ(refusal(WaitInput{1, true, std::chrono::nanoseconds(-1)}), "wait timeout -1 ns is negative");
  EXPECT_EQ(check_command(WaitInput{1, true, {}}, small_robot()).message, "digital input 1: this robot has none");
}

TEST(DriverDescribe, GivesOneFixedLinePerCommand) {
  EXPECT_EQ(describe(MoveJoints{{0.0, std::numbers::pi / 2, -1e-9}, 0.5}),
            "move_joints [0.000000, 1.570796, 0.000000] speed 0.500000");
  EXPECT_EQ(describe(MovePose{pose_at(0.3, -0.1, 0.25, 0.0), Path::linear, 1.0}),
            "move_pose linear xyz [0.300000, -0.100000, 0.250000] quat_wxyz [1.000000, 0.000000, 0.000000, 0.000000] "
            "speed 1.000000");
  EXPECT_EQ(describe(Grip{Grip::Action::close, 0.02, 15.0}), "grip close width 0.020000 force 15.000000");
  EXPECT_EQ(describe(Grip{Grip::Action::open, std::nullopt, std::nullopt}), "grip open");
  EXPECT_EQ(describe(SetOutput{3, false}), "set_output 3 off");
  EXPECT_EQ(describe(WaitInput{2, true, std::chrono::milliseconds(5)}), "wait_input 2 on timeout 5000000 ns");
  EXPECT_EQ(describe(WaitInput{2, true, {}}), "wait_input 2 on");
}

TEST(DriverDescribe, SameRotationGivesTheSameBytes) {
  // Rotations by +pi and -pi about z are the same rotation; Eigen's quaternions of them may differ in sign.
  const std::string a = describe(MovePose{pose_at(0.1, 0.2, 0.3, std::numbers::pi), Path::joint, 1.0});
  const std::string b = describe(MovePose{pose_at(0.1, 0.2, 0.3, -std::numbers::pi), Path::joint, 1.0});
  const std::string c = describe(MovePose{pose_at(0.1, 0.2, 0.3, std::numbers::pi - 1e-3), Path::joint, 1.0});
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

TEST(DriverNames, EveryValueHasItsOwnName) {
  std::set<std::string_view> states;
  for (int i = 0; i <= static_cast<int>(DriverState::fault); ++i) states.insert(to_string(static_cast<DriverState>(i)));
  EXPECT_EQ(states.size(), 6u);
  std::set<std::string_view> errors;
  for (int i = 0; i <= static_cast<int>(ErrorCode::unknown_command); ++i) {
    errors.insert(to_string(static_cast<ErrorCode>(i)));
  }
  EXPECT_EQ(errors.size(), 13u);
  EXPECT_FALSE(errors.contains("?"));
  EXPECT_FALSE(states.contains("?"));
  EXPECT_EQ(to_string(CommandPhase::running), "running");
  EXPECT_EQ(to_string(ErrorCode::connection_lost), "connection_lost");
}

TEST(ArmPlane, ATool5AxisArmsCanPointIsInThePlaneAndOneTurnedAboutTheVerticalIsNot) {
  // Tool point at azimuth 30 degrees; a tool pointing straight down is in every vertical plane.
  Eigen::Isometry3d down = Eigen::Isometry3d::Identity();
  down.translation() = Eigen::Vector3d(0.3 * std::cos(M_PI / 6), 0.3 * std::sin(M_PI / 6), 0.2);
  down.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_NEAR(out_of_arm_plane(down), 0.0, 1e-12);
  // Horizontal and radial (pointing outward along the azimuth): in the plane, whatever the roll about it.
  Eigen::Isometry3d radial = down;
  radial.linear() =
      (Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  EXPECT_NEAR(radial.linear().col(2).z(), 0.0, 1e-12);
  EXPECT_NEAR(out_of_arm_plane(radial), 0.0, 1e-12);
  // The same horizontal tool turned 20 degrees about the vertical leaves the plane by 20 degrees.
  Eigen::Isometry3d turned = radial;
  turned.linear() = Eigen::AngleAxisd(20 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() * radial.linear();
  EXPECT_NEAR(out_of_arm_plane(turned), 20 * M_PI / 180, 1e-9);
  // On the base's axis there is no plane.
  Eigen::Isometry3d on_axis = down;
  on_axis.translation() = Eigen::Vector3d(0, 0, 0.5);
  EXPECT_TRUE(std::isinf(out_of_arm_plane(on_axis)));
}

}  // namespace
}  // namespace cellwright::drivers
