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
// check_carry() is the check of a coordinated carry (two robots holding one workpiece, docs/runtime.md "Coordinated
// blocks"), made once per period for both robots (RobotControl::watch_carry) from what the controller senses: the
// two tools' poses from the drivers' read-backs, the two wrist forces and grip readings from the sensor port. It
// stops both robots when one end is no longer held, when the follower's tool is off the grasp transform by more than
// SafetyOptions::carry_error / carry_turn (one arm lags), or when the internal force along the workpiece exceeds
// squeeze_force.
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

// One robot of a coordinated carry as the controller senses it.
struct CarryHand {
  std::string label, cell;                  // program label, cell robot
  std::optional<Eigen::Isometry3d> tcp;     // its tool (world), from its read-back; nullopt: not known
  // its wrist force sensor (N, world; the twin's reads the force the arm exerts on the hand and its load, upward
  // against their weight); nullopt: no sensor
  std::optional<Eigen::Vector3d> force;
  bool grip_lost = false;                   // its grip sensor has missed the workpiece grip_lost_periods running
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // m/s of its tool, from the last two read-backs
};

struct CarryVerdict {
  bool stop = false;
  std::string symptom;  // the fault_detected symptom: "grip_lost" (an end slipped), "protective_stop" (the rest)
  std::string cause;    // "end_slipped", "arm_lagging", "squeeze_over_limit"
  std::string reason;   // what and which arm, with the figures and the limit
  // The program label of the arm the fault is on (the one whose end slipped, the lagging one, the follower off its
  // place); "" for a squeeze, which is both arms'.
  std::string arm;
  double error = 0, turn = 0;  // m, rad: the follower's tool off the grasp transform (when both tools are known)
  std::optional<double> squeeze;  // N, > 0 pushing the ends together (when both forces are known)
};

// The check of a carry of `workpiece` by `master` and `follower` with grasp transform `grasp` (master tool ->
// follower tool), in this order: a lost end, the relative tool error (the lagging arm is the one behind along the
// tools' common motion; with both standing still the follower is named off), the squeeze ((F_master - F_follower) .
// u / 2, u the unit vector from the master's tool to the follower's: the part of the two wrist forces that cancels;
// > 0 when the hands push the ends together: the workpiece pushes each hand back, each arm pushes on).
// A grasp not known yet (nullopt: the follower measures it at the first move after both closed) skips the error.
CarryVerdict check_carry(const CarryHand& master, const CarryHand& follower,
                         const std::optional<Eigen::Isometry3d>& grasp, const std::string& workpiece,
                         const SafetyOptions& options);

// `robot` (cell name) is at `joints` and moving to `goal_joints` (empty: standing still).
SafetyVerdict check_safety(const EnvironmentModel& model, const std::string& robot,
                           const models::KinematicChain& chain, const std::vector<double>& joints,
                           const std::vector<double>& goal_joints, const SafetyOptions& options);

}  // namespace cellwright::runtime
