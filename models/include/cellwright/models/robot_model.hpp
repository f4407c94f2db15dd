// A cell's robot as the cell mounts it: its URDF (as its maker publishes it, or one of the project's), the gripper on
// its flange, and the kinematic chain from its base link to its tool centre point. Every reader of a robot (the cell's
// checks, robot control, the twin's scene and drivers) gets the chain from here, so that all of them agree on which
// links and joints make the arm.
//
// Thread safety: the functions are reentrant (loads are serialized inside the URDF loader); a MountedRobot is
// immutable and may be shared.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "cellwright/models/cell.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/urdf.hpp"

namespace cellwright::models {

// The project's gripper as a model of its own: models_dir()/urdf/gripper.urdf (root link gripper_base, prismatic
// joints finger_left_joint and finger_right_joint, link tcp).
std::filesystem::path gripper_urdf();

struct MountedRobot {
  UrdfModel arm;                     // the robot's URDF
  std::optional<UrdfModel> gripper;  // the project's gripper, fixed to the flange link (GripperKind::kCellwright)
  // The model that holds the finger joints and the tool link: *gripper if mounted, else arm.
  const UrdfModel& hand() const { return gripper ? *gripper : arm; }
};

// Reads the robot's URDF (and the gripper's) and checks that the cell's link names fit it. Throws InputError naming
// the URDF file (and line, where one applies): as load_urdf_file; "robot 'R': the URDF has no link 'L' (its
// base_link|flange_link|tool_link)"; "robot 'R': link 'L' (the flange) is not below link 'B' (the base)"; "robot 'R':
// a gripper is mounted on 'F', so the URDF must not have a link or joint named 'N' (the gripper's)".
MountedRobot load_robot(const RobotSpec& spec);

// The robot's kinematic chain, base_link to tool link (through the mounted gripper to its tcp). Joint names are the
// URDF's own. Throws InputError as load_robot and KinematicChain::from_urdf.
KinematicChain robot_chain(const RobotSpec& spec);
KinematicChain robot_chain(const RobotSpec& spec, const MountedRobot& robot);

// The file a URDF <mesh filename="..."> names: "package://PACKAGE/PATH" is PATH under the first directory of
// spec.package_path that has a subdirectory PACKAGE; "file:///abs" and absolute paths as they are; a relative path
// is relative to the URDF's directory. Throws InputError at `where` (the URDF's file and line): "mesh 'URI': unknown
// package 'P' (package_path: ...)", "mesh 'URI': no file <path>", or "mesh 'URI': unsupported URI scheme".
std::filesystem::path resolve_mesh(const std::string& uri, const RobotSpec& spec, const std::filesystem::path& urdf,
                                   const SourceLocation& where);

}  // namespace cellwright::models
