// How the simulated controller (sim_driver.hpp) plans a straight-line move and how long any of its moves takes at
// least, as pure functions: the SimDriver plans, executes and times its commands with them (least_duration), and the
// cycle-time estimate (cell/plan/estimate.hpp) predicts the moves of coordinated blocks with the same code.
//
// A straight line of the tool is followed through inverse-kinematics waypoints at most `linear_step` apart along the
// line (and kLinearAngleStep of tool rotation, orientation by slerp), each solved from the one before, the first from
// the seed; the arm's joints are interpolated between them (a JointPath whose arc is the fraction of the line). A
// line needing a jump of the arm (successive waypoints more than `max_waypoint_step` apart in some joint: a
// singularity or a change of configuration on it) or a pose without a solution cannot be followed.
//
// A move's least duration: every joint within max_speed * speed at the quintic profile's peak (JointPath::
// min_duration), at least min_time, and on a straight line the tool within max_tool_speed * speed at the peak too.
//
// Pure functions; any thread may call them.
#pragma once

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::twin::sim {

inline constexpr double kLinearAngleStep = 0.05;  // rad of tool rotation between straight-line waypoints

// A straight line of the tool as joint waypoints.
struct StraightLine {
  std::vector<Eigen::VectorXd> points;  // the seed, then the joints at each waypoint (empty when `problem` is set)
  std::vector<double> arc;              // the fraction of the line at each point, 0 to 1
  double tool_distance = 0;             // m the tool centre point travels
  std::string problem;                  // why the arm cannot follow the line, "" when it can
};

// The straight line of `chain`'s tool from where the joints `seed` put it to `goal` (base frame), solved as the
// SimDriver solves it (see the top). linear_step and max_waypoint_step > 0.
StraightLine straight_line(const models::KinematicChain& chain, const Eigen::VectorXd& seed,
                           const Eigen::Isometry3d& goal, double linear_step, double max_waypoint_step,
                           const models::IkOptions& ik);

// The least duration (seconds) of a move along `path` (see the top): `line_distance` is the metres the tool travels
// on a straight line, nullopt for a joint-interpolated move (no tool-speed limit). max_tool_speed > 0; the others as
// JointPath::min_duration.
double least_move_duration(const JointPath& path, std::optional<double> line_distance,
                           const Eigen::VectorXd& max_speed, double speed, double min_time, double max_tool_speed);

}  // namespace cellwright::twin::sim
