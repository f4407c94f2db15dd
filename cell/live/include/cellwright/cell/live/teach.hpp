// Teaching in the live view (docs/live-view.md, "Teaching"): a robot's teach pose, jogged joint by joint or along
// the world's axes, with its reach and its collisions against the cell as the run has it now. The paper's "all robots
// motions are taught interactively one by one".
//
// The teach pose is a copy: joints of the robot's kinematic chain (models/robot_model.hpp robot_chain, the chain the
// cell's checks and robot control use), never written into the run. Its tool pose is the chain's forward kinematics
// placed at the robot's base (RobotSpec::base). Cartesian jogs solve the chain's inverse kinematics from the teach
// pose (KinematicChain::inverse, seeded with it: the nearest solution). Collisions are found on a scratch mjData of
// the run's compiled scene: the run's state copied (the other robots, parts and belts where the run has them), the
// taught robot's arm joints set to the teach pose, MuJoCo's kinematics and collision detection run (mj_kinematics,
// mj_comPos, mj_collision, with the scene's own filters), and each contact deeper than kTeachContactDepth between a
// geom of the taught robot and one of the fixed cell, a belt, an obstacle or another robot is reported (contacts with
// parts are not: a taught grasp touches its part).
//
// Messages (JSON, docs/live-view.md):
//   request  {"type":"teach","robot":R,"action":"begin"|"joint"|"cartesian"|"joints"|"end", "joint":I, "axis":
//            "x"|"y"|"z"|"yaw", "delta":D, "joints":[rad...]}            R: the cell's robot name (or its label)
//   reply    {"type":"teach","robot":R,"active":true,"joints":[rad],"tool":[x,y,z,qw,qx,qy,qz],"reachable":bool,
//            "at_limit":[I...],"reason":"","collisions":[{"a","b","pos":[x,y,z]}]}, or {"type":"teach","robot":R,
//            "active":false} after "end"
//
// Threads: a Teacher is used by the live loop's thread only, while the run's threads are parked (between steps).
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace cellwright::cell {

// A viewer's message the live loop will not carry out, and why (sent back to that viewer as an "error").
class LiveRefusal : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Contacts shallower than this (m) are touching, not colliding (the preflight's sweep uses the same depth).
inline constexpr double kTeachContactDepth = 0.002;

enum class TeachAction { kBegin, kJoint, kCartesian, kJoints, kEnd };

struct TeachRequest {
  std::string robot;  // as sent
  TeachAction action = TeachAction::kBegin;
  int joint = -1;         // kJoint: 0-based, base to tip
  std::string axis;       // kCartesian: "x", "y", "z" (world, m) or "yaw" (about world z, rad)
  double delta = 0;       // kJoint (rad or m), kCartesian
  std::vector<double> joints;  // kJoints
};

// Reads a "teach" message. LiveRefusal naming the field: no robot, an unknown action, a joint or delta that is not a
// number, an axis not x/y/z/yaw, joints not an array of numbers.
TeachRequest parse_teach(std::string_view json);

struct TeachContact {
  std::string a;  // the taught robot's geom: "puma link 'link3'"
  std::string b;  // what it touches: "machine 'mill' (fixture)", "melfa link 'link2'", "the floor"
  Eigen::Vector3d pos = Eigen::Vector3d::Zero();  // the contact point (world)
  double depth = 0;                                // m
};

struct TeachState {
  std::string robot;  // the cell's robot name
  bool active = false;
  Eigen::VectorXd joints;  // the teach pose (chain order, base to tip)
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();  // its tool centre point (world)
  bool reachable = true;      // false when the last jog was refused as out of reach
  std::vector<int> at_limit;  // joints at a URDF limit
  std::string reason;         // why the last jog was refused or stopped short, else ""
  std::vector<TeachContact> collisions;
};

// The "teach" reply of a state (see the top).
std::string teach_json(const TeachState& state);

class Teacher {
 public:
  // The scenario's robots' chains (InputError as robot_chain: the URDFs were read when the scenario was loaded).
  explicit Teacher(const Scenario& scenario);
  ~Teacher();
  Teacher(const Teacher&) = delete;
  Teacher& operator=(const Teacher&) = delete;

  // Carries out `request` on `world` as it is now (its robots' joints, parts and belts) and returns the robot's teach
  // state. begin: the teach pose from the robot's joints in `world`. joint: joint I moved by D, clamped at its URDF
  // limits (at_limit, reason say so). cartesian: the tool moved D m along the world axis, or turned D rad about the
  // world z axis through the tool centre point, its orientation otherwise kept; the pose found by inverse kinematics
  // from the teach pose, or, if none, the pose unchanged with reachable false and the solver's reason. joints: the
  // pose given outright (each joint within its limits). end: the robot no longer taught.
  // LiveRefusal: a robot not in the scenario; a jog, joints or end of a robot not being taught; a joint index out of
  // range; a delta or joint not finite; joints of the wrong count or outside the limits.
  TeachState apply(const TeachRequest& request, const twin::sim::World& world);

  // The robot's teach state, if it is being taught (by cell name).
  const TeachState* state(const std::string& robot) const;
  // The robots being taught, by cell name.
  std::vector<std::string> active() const;
  // The cell name of a robot named by its cell name or program label; empty if neither.
  std::string robot_name(const std::string& name_or_label) const;

 private:
  struct Robot;
  void refresh(Robot& r, TeachState& s, const twin::sim::World& world);

  const Scenario& scenario_;
  std::map<std::string, std::unique_ptr<Robot>> robots_;  // by cell name
  std::map<std::string, TeachState> states_;              // the robots being taught
  mjData* scratch_ = nullptr;                             // on the run's compiled model, made at first use
  const mjModel* scratch_model_ = nullptr;
};

}  // namespace cellwright::cell
