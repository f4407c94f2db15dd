// The two controllers' pose conventions and number formats as docs/real-robots.md defines them, written for the
// post-processors apart from the drivers' and the emulators' (so that those check these).
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <optional>
#include <string>

namespace cellwright::cell {

// A Movemaster pose: tool point in mm, pitch and roll in degrees (the 5-axis rule).
struct MovemasterPose {
  double x = 0, y = 0, z = 0, p = 0, r = 0;
};

// The Movemaster pose of a tool frame in the robot's base frame (metres). None, with `why`, when the 5-axis rule
// cannot express it: the tool point on the base's z axis, or the approach axis out of the vertical plane through it by
// more than `yaw_tolerance_deg`.
std::optional<MovemasterPose> movemaster_pose(const Eigen::Isometry3d& tool, double yaw_tolerance_deg,
                                              std::string& why);

// VAL II's TRANS(x, y, z, o, a, t) of a tool frame in the base frame: mm, and the Z-Y-Z angles of
// R = Rz(O)·Ry(A)·Rz(T)·Rx(180°), each in (−180, 180]; O is 0 when A is 0 or 180.
std::array<double, 6> val2_trans(const Eigen::Isometry3d& tool);

// "12.3", "-0.5", "0.0": one decimal, no negative zero (the Movemaster's numbers).
std::string movemaster_number(double v);
// "12.25", "-0.5", "90", "0": at most three decimals, trailing zeros dropped, no negative zero (VAL II's numbers).
std::string val2_number(double v);

}  // namespace cellwright::cell
