// The grip sensor's rule, one for every plant: the twin's MuJoCo world (its finger pad touch sensors) and the scripted
// kinematic plant of the runtime's tests judge "which part is between the fingers" the same way, so that the tests
// check the sensor production uses.
//
// A gripper holds a part when both finger pads touch something and its tool centre point is inside the part's box
// grown by `margin` on every side; of several such parts, the one whose centre is nearest the tool centre point. (A
// gripper can hold a part only around it; during a hand-over both hands hold the same part, which is why the rule
// asks where the fingers are rather than who grasped last.)
//
// Threads: pure functions.
#pragma once

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace cellwright::runtime {

// A workpiece as a box: its centre pose (world) and full extents. A cylinder is taken as its bounding box.
struct PartBox {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
};

inline constexpr double kGripMargin = 0.01;  // m

// The part between the fingers by the rule above: its name, or "" when the pads do not both touch or the tool centre
// point is in no part's grown box.
std::string part_between_fingers(bool left_touch, bool right_touch, const Eigen::Vector3d& tcp,
                                 const std::vector<PartBox>& parts, double margin = kGripMargin);

}  // namespace cellwright::runtime
