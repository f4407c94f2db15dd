// ControllerFrames: where a serial controller's numbers live, relative to the project's (docs/real-robots.md,
// "Commissioning"). The driver interface speaks of the tool centre point (TCP) in the robot's base frame (the URDF's
// base_link, robot_driver.hpp); a controller speaks of its own tool point in its own world frame. The two differ by a
// rigid transform on each side, both settings of the robot's cell entry (`val2:` / `movemaster:`, models'
// ControllerFrames):
//   world  the controller's world frame in the base frame (a PUMA's VAL world sits at the shoulder, 0.672 m above a
//          base link on the floor: world.translation() = (0, 0, 0.672));
//   tool   the controller's tool point and axes in the TCP frame (a controller with no tool set reports its flange).
// A TCP pose P in the base frame is, to the controller, C = world⁻¹ · P · tool; a controller pose C is P = world · C ·
// tool⁻¹. Both identities (the defaults) leave poses as they are, bit for bit. The orientation conventions (VAL II's
// O, A, T; the Movemaster's pitch and roll) apply to C, in the controller's frame, and are each driver's.
//
// Threads: a value; any thread.
#pragma once

#include <Eigen/Geometry>

namespace cellwright::drivers {

struct ControllerFrames {
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();

  bool identity() const {
    return world.matrix() == Eigen::Matrix4d::Identity() && tool.matrix() == Eigen::Matrix4d::Identity();
  }
  // A TCP pose in the base frame as the controller's pose (its tool point in its world).
  Eigen::Isometry3d to_controller(const Eigen::Isometry3d& tcp_in_base) const {
    return identity() ? tcp_in_base : Eigen::Isometry3d(world.inverse() * tcp_in_base * tool);
  }
  // A controller's pose as the TCP's in the base frame.
  Eigen::Isometry3d from_controller(const Eigen::Isometry3d& controller) const {
    return identity() ? controller : Eigen::Isometry3d(world * controller * tool.inverse());
  }
};

}  // namespace cellwright::drivers
