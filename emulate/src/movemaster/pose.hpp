// The Movemaster EX pose convention (docs/real-robots.md, "Pose convention (the 5-axis rule)"): x, y, z of the tool
// point in mm, pitch p and roll r in degrees, in the robot's base frame. The approach axis (the tool's z) lies in the
// vertical plane through the base's z axis and the tool point; θ = atan2(y, x), u = (cos θ, sin θ, 0),
// w = (−sin θ, cos θ, 0), a = cos p · u + sin p · ẑ, and the tool's rotation is R = [w × a, w, a] · Rz(r).
#pragma once

#include <Eigen/Geometry>

#include <optional>

#include "movemaster/command.hpp"

namespace cellwright::emulate::movemaster {

// The tool frame of `pose` (metres). None when the tool point is on the base's z axis (closer than 1 µm): it has no
// azimuth.
std::optional<Eigen::Isometry3d> tool_frame(const Pose5& pose);

// The pose of a tool frame. The azimuth is the tool point's (0 on the z axis); pitch is the approach axis's elevation
// in that plane and roll the angle of the tool's x axis about the approach axis from w × a, both in (−180, 180]. A
// frame whose approach axis leaves the plane is projected onto it.
Pose5 pose_of(const Eigen::Isometry3d& tool);

}  // namespace cellwright::emulate::movemaster
