// The safety layer (docs/faults.md section 4): below task control, in the subsumption sense. Each robot control asks
// it every period, before anything task control asked for, whether its robot must be stopped; while it says so, the
// robot stays stopped (a protective stop), whatever it was told to do.
//
// check_safety() is a pure function of what the controller senses: the robots' positions (from their drivers, in the
// environment model), the objects the safety sensor sees that are not in the cell model (EnvironmentModel::obstacles)
// and the wrist force. It stops a robot
//  - whose tool or wrist, on the straight way from where they are to where the current motion takes them, would come
//    within SafetyOptions::obstacle_distance of an obstacle;
//  - whose tool or wrist would come, on that way, within robot_distance of another robot's tool, unless both tools are
//    in the hand-over zone (within handover_zone of the cell's hand-over pose), where they meet on purpose; only the
//    robot whose motion closes the distance is stopped;
//  - whose wrist force exceeds force_limit.
//
// Threads: pure; any thread, on values it owns.
#pragma once

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/recovery.hpp"

namespace cellwright::runtime {

struct SafetyVerdict {
  bool stop = false;
  bool obstacle = false;  // the reason is an obstacle
  std::string reason;     // "obstacle obstacle_1 0.031 m from the tool", "robot melfa 0.08 m away", "wrist force ..."
};

// The points of a robot that the safety layer watches (world frame): its wrist (the frames after the last three
// joints) and its tool centre point.
std::vector<Eigen::Vector3d> watched_points(const models::KinematicChain& chain, const Eigen::Isometry3d& base,
                                            const std::vector<double>& joints);

// Distance from a point to an axis-aligned box (0 inside).
double distance_to_box(const Eigen::Vector3d& p, const Eigen::Vector3d& centre, const Eigen::Vector3d& size);

// `robot` (cell name) is at `joints` and moving to `goal_joints` (empty: standing still).
SafetyVerdict check_safety(const EnvironmentModel& model, const std::string& robot,
                           const models::KinematicChain& chain, const std::vector<double>& joints,
                           const std::vector<double>& goal_joints, const SafetyOptions& options);

}  // namespace cellwright::runtime
