// CarryMeter: the twin's measurement of a coordinated carry (issue 27; docs/runtime.md, "Coordinated blocks"): while
// two robots hold one workpiece, every control period, how hard they squeeze or pull it, how far their tools have
// drifted from each other, and how far it tilts. It measures the simulation (the twin is the instrument here); the
// controller never reads it: its own safety check (safety.hpp, check_carry) works from its drivers and sensors.
//
// A hold by two hands begins in the first period the grip sensor rule (runtime/grip_sensor.hpp) finds the same
// workpiece between the fingers of two robots; its grasp transform (robot a's tool to robot b's tool, a before b in
// the cell's robot order) is taken then; the hold ends in the first period one of them no longer has it (a new hold
// takes the transform anew). Each period of a hold gives one sample (runtime::events::Carry):
//  - squeeze: the internal force along the workpiece, from the two wrist force/torque sensors (the MuJoCo force
//    sensors at each flange, in the world frame, which is what a real cell's wrist F/T sensors measure; MuJoCo's
//    reading is the force the arm exerts on the hand and what it holds, upward against their weight): the part of
//    the two forces that cancels, ((F_a - F_b) . u) / 2 with u the unit vector from a's tool to b's, positive when
//    the hands push the ends together (the beam pushes each hand back, each arm pushes its hand on towards the
//    other), negative when they pull it apart. The shares of the workpiece's weight along
//    u cancel in the difference (each hand carries its share), and so do the grippers' own weights and inertia when
//    both grippers are alike and move together (the twin's are).
//  - error, turn: the transform from a's tool to b's now compared with the grasp transform: how far b's tool is from
//    where it should be (mm), and the angle of the rotation between them (degrees).
//  - tilt: the angle of the workpiece's long axis (its largest dimension) from horizontal (degrees).
//
// Threads: the simulation thread (WorldPlant::advance) only.
#pragma once

#include <Eigen/Geometry>

#include <map>
#include <string>
#include <vector>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/log_event.hpp"

namespace cellwright::twin::sim {

// One robot's hand as the twin has it in a period.
struct CarryHand {
  std::string robot;                                     // cell robot name
  Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity(); // tool centre point, world
  std::string held;                                      // the workpiece between its fingers, "" none
  Eigen::Vector3d wrist_force = Eigen::Vector3d::Zero(); // N, world frame: the wrist sensor's (see squeeze above)
};

// One workpiece as the twin has it in a period.
struct CarryPart {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // centre, world
  Eigen::Vector3d size = Eigen::Vector3d::Zero();          // box extents along its own axes, m
};

class CarryMeter {
 public:
  // The samples of the period ending at `t`, one per workpiece two hands hold (in the order of `parts`). `hands` in
  // the cell's robot order. A workpiece held by three or more hands is measured for its first two.
  std::vector<runtime::events::Carry> measure(runtime::SimDuration t, const std::vector<CarryHand>& hands,
                                              const std::vector<CarryPart>& parts);

 private:
  struct Hold {
    std::string a, b;
    Eigen::Isometry3d grasp = Eigen::Isometry3d::Identity();  // a's tool -> b's tool when the hold began
  };
  std::map<std::string, Hold> holds_;  // by workpiece
};

}  // namespace cellwright::twin::sim
