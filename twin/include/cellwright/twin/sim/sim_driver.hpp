// SimDriver: the RobotDriver (drivers/robot_driver.hpp) of a simulated robot, on its MuJoCo position servos. It is
// built on drivers::DriverCore (driver_core.hpp), which keeps the interface contract: the lifecycle table, ids 1, 2,
// 3, ..., one queue shared by home() and submit(), cancellation of everything behind a failed command, retention, the
// notifier. This file adds how a simulated controller executes the jobs.
//
// WHO CALLS WHAT
//  - The owner (one robot-control thread) calls the RobotDriver methods and the queries below (last_grip(),
//    kinematics()). They only read and change the driver's state behind the core's mutex; they never touch mjData.
//    Planning (inverse kinematics of a MovePose) happens in submit(), on the owner thread.
//  - The World (world.hpp) creates the drivers (World::add_sim_driver) and, on the simulation thread, calls step()
//    before every physics step: that is where commands start, servo targets move along their trajectories, position
//    read-backs are taken, and commands complete. So a command submitted between two World::advance calls starts at
//    the next physics step; completion is seen after the World::advance that completed it.
//  - The notifier is called on the simulation thread (inside World::advance), with no driver lock held.
//
// HOW COMMANDS EXECUTE (all times are simulation time)
//  - MoveJoints: a quintic joint trajectory from the joints' current targets to the goal (trajectory.hpp), lasting
//    long enough for every joint to stay within max_joint_speed * speed, and at least min_move_time. The servo target
//    each step is the trajectory's position plus feed-forward terms (joint damping times the trajectory's velocity,
//    and gravity and Coriolis forces, divided by the servo's stiffness), so that the arm follows the trajectory
//    without lag or sag. Done when the trajectory has ended and every joint is within joint_tolerance of the goal
//    and slower than settle_speed; failed with timeout (the errors of every joint in the message) if that has not
//    happened settle_timeout after the trajectory's end, e.g. because the arm is blocked. A goal outside the joint
//    limits fails with unreachable when the command starts.
//  - MovePose (cartesian_control and linear_motion are supported; the arms have six axes): the pose is in the
//    robot's base frame. The joint goal comes from the robot's inverse kinematics (models::KinematicChain on its
//    URDF), seeded with the goal of the motion queued before it (or the current joints), choosing the solution
//    closest to that seed; Path::joint also tries the seed with the first joint turned towards the target and keeps
//    the solution that changes the joints between the first and the last least (the closest solution may flip the
//    shoulder or elbow and swing the arm through the air).
//    Path::joint then moves like MoveJoints. Path::linear solves IK at waypoints at most
//    linear_step apart along the straight line (orientation by slerp), each seeded with the previous one, and follows
//    that polyline (straight_line, move_timing.hpp); the tool then deviates from the line by well under a
//    millimetre. It fails with unreachable when a pose has no IK solution, or a linear path would need a jump of the
//    arm (two successive waypoints more than max_waypoint_step apart in some joint: a singularity or a change of
//    configuration on the line). The duration also keeps the tool within max_tool_speed * speed
//    (least_move_duration, move_timing.hpp).
//  - A timed move (MoveJoints/MovePose::duration; Capabilities::timed_motion; robot_driver.hpp TIMED MOVES) lasts
//    its duration when that is longer than the time above: the same path, the quintic stretched. Its arm is done
//    when the trajectory has ended, every joint is slower than settle_speed and within joint_tolerance of where the
//    servo holds it under its external load: the goal plus the deflection the constraint forces on the joint (a held
//    workpiece, a second arm holding it too) give against the servo's stiffness. Two arms carrying one workpiece in
//    a coordinated segment pull each other a few milliradians off their goals, and how long that took to creep
//    under joint_tolerance differed between them (by up to 90 ms); now both are done at their trajectories' end.
//    (A blocked arm is then done once at rest against what blocks it: robot control's read-back check, its
//    position_tolerance, tells the miss.) least_duration()
//    plans the command from where the queue ends (as submit() would) and tells the time above (for a Grip, the
//    fingers' ramp from their current goal; other commands: nullopt).
//  - Grip: the finger targets move at finger_speed towards the goal (open: fully open, or `width`; close: fully
//    closed, or `width`). An open without `width` while the fingers hold a part (the last finger motion closed and
//    both pads touch something short of fully closed) is a release: the targets start from where the fingers are
//    and open them only release_clearance each beyond it, clear of the part, instead of ramping from fully closed
//    to fully open; the next open without `width` (an empty open) opens fully. The grip force (default: the robot's grip_force from the cell, also the maximum) limits the
//    squeeze: each finger's target never gets further than force / stiffness ahead of the finger, so a finger that
//    meets the part pushes on it with exactly that force. Open completes when both fingers are within
//    finger_tolerance of the goal and at rest; close completes when the finger targets have reached the goal and both
//    fingers have come to rest (on a part or at the goal). A close that ends on nothing is still done: last_grip()
//    tells whether the fingers stopped on a part, and the robot-control thread decides.
//  - SetOutput sets a signal of the SignalTable shared by the cell (signals.hpp) and completes at once. WaitInput
//    completes at the first step on which the signal has the wanted level, or fails with timeout.
//  - request_position() completes at the next step, even while a motion runs (capabilities().reads_while_moving): the
//    joints and the tool centre point's pose (base frame) of the simulation at that step, stamped with its
//    simulation time, or with the time of the clock given to set_clock() (called on the simulation thread).
//  - home() moves the arm to the cell's home configuration (home_speed) and opens the gripper; then the driver is
//    homed. connect() always succeeds (the simulated controller is always there).
//  - stop() and disconnect() cancel every command and brake the arm: from its current position and velocity the
//    targets follow a smooth deceleration to rest (within brake_time at most) and then hold still.
//  - World::advance puts every driver in fault (commands failed with hardware) if MuJoCo had to reset the
//    simulation after a numerical failure; reset() then brings it back to connected.
#pragma once

#include <mujoco/mujoco.h>
#include <Eigen/Geometry>

#include <array>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/driver_core.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/signals.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::twin::sim {

// Tuning of a simulated controller. Units: SI; times in seconds of simulation time.
struct SimDriverOptions {
  SourceLocation where;                 // the robot's entry in the cell or scenario file, for messages
  std::vector<double> max_joint_speed;  // rad/s per arm joint at speed 1; empty: the URDF joints' velocity limits
  double max_tool_speed = 0.5;          // m/s of the tool centre point at speed 1 (straight-line moves)
  double min_move_time = 0.2;           // the shortest motion
  double joint_tolerance = 0.002;       // rad: a move is done when every joint is this close to its goal ...
  double settle_speed = 0.02;           // rad/s: ... and slower than this
  double settle_timeout = 2.0;          // after the trajectory's end, before a move fails with timeout
  double linear_step = 0.005;           // m between the IK waypoints of a straight-line move
  double max_waypoint_step = 0.25;      // rad: larger joint steps between waypoints make a line unreachable
  double finger_speed = 0.05;           // m/s of each finger's target
  double finger_tolerance = 0.0005;     // m: an open is done when each finger is this close to its goal ...
  double finger_settle_speed = 0.002;   // m/s: ... and fingers slower than this count as stopped
  double release_clearance = 0.005;     // m each finger opens beyond the part it lets go of (a release); > 0
  double home_speed = 0.5;              // speed fraction of home()
  double brake_time = 0.3;              // at most, to brake to rest after stop()
  std::size_t queue_depth = 16;         // commands in flight at most
  models::IkOptions ik;                 // how hard the inverse kinematics tries
};

// The joint speeds (rad/s per arm joint at speed 1) a SimDriver of robot `spec` (kinematics `chain`) with `options`
// moves at, its capabilities().max_joint_speed: options.max_joint_speed, else the URDF's velocity limits. Throws
// InputError as the SimDriver's constructor does for them (a joint without a limit, a wrong length, a value <= 0).
std::vector<double> sim_joint_speeds(const models::RobotSpec& spec, const models::KinematicChain& chain,
                                     const SimDriverOptions& options);

// How the last completed Grip ended.
// A pad touch sensor reading above this (newtons) counts as contact.
inline constexpr double kTouchThreshold = 0.05;

struct GripOutcome {
  drivers::CommandId command = 0;
  drivers::Grip::Action action = drivers::Grip::Action::close;
  double opening = 0;                       // m between the finger pads when it completed
  std::array<bool, 2> touch{false, false};  // {left, right} pad touch sensors reading a force
  // close only: both pads touch something and the fingers stopped short of fully closed (by more than 1 mm).
  bool on_part = false;
};

class SimDriver final : public drivers::DriverCore {
 public:
  // Built by World::add_sim_driver (which validates the robot name); `robot` indexes scene.robots(). Reads the
  // robot's URDF for its kinematics and joint speed limits. Throws InputError naming options.where when
  // max_joint_speed has the wrong length or a non-positive value, or an option is out of range; InputError from
  // models::KinematicChain when the URDF cannot be read. The scene and the signal table must outlive the driver.
  SimDriver(const Scene& scene, std::size_t robot, SignalTable& signals, SimDriverOptions options);
  SimDriver(const SimDriver&) = delete;
  SimDriver& operator=(const SimDriver&) = delete;

  // The RobotDriver methods (the owner thread) come from DriverCore: see drivers/robot_driver.hpp and the notes above.
  std::optional<double> least_duration(const drivers::Command& command) const override;

  // ---- Queries (any thread) ----

  // The robot's name in the cell.
  const std::string& name() const { return name_; }
  // How the most recent Grip command that completed ended; nullopt before the first.
  std::optional<GripOutcome> last_grip() const;
  // The robot's kinematics (base_link to tcp), as used for MovePose.
  const models::KinematicChain& kinematics() const { return chain_; }

  // ---- The simulation side (the World, on the simulation thread only) ----

  // Advances the controller to simulation time `now` (the time of the physics step about to be taken): starts,
  // runs and completes commands, and writes this robot's servo targets into data->ctrl. Reads only this robot's
  // state from `data`. Calls the notifier (lock released) if a command finished.
  // `sensors_fresh`: whether data->sensordata is from the last step (the World skips MuJoCo's sensor stage on steps
  // after which nobody reads it). The fingers' touch sensors decide when a grip or open is done; on a step without
  // fresh sensors that decision waits for the next one, and a command that moves the fingers (a release looks at what
  // they hold) starts at the next one. Returns whether the next step will read them: a command that moves the
  // fingers is running or queued.
  bool step(std::chrono::nanoseconds now, const mjModel* model, mjData* data, bool sensors_fresh = true);

  // A fault injected on purpose (docs/faults.md, kind drop): the gripper loses its grip force until simulation time
  // `until`: the finger servos are driven fully open whatever the commands say (a command running meanwhile goes on
  // as the fingers let it); from `until` on the fingers obey the last command again (after a close they close, on
  // whatever is still between them). Nothing the owner reads says that it happened.
  void release_grip(std::chrono::nanoseconds until);

  // MuJoCo reset the simulation: every command fails with hardware, the driver enters fault (unless disconnected),
  // and the targets are taken from `data` as it is now. Calls the notifier.
  void fault(const std::string& message, std::chrono::nanoseconds now, const mjData* data);

 private:
  // What the driver keeps with each job.
  struct SimJob : JobData {
    // Motions (moves, home), planned when queued: the joint polyline from the planned start, its arc (straight
    // lines: uniform in tool travel; empty otherwise), the speed fraction and the tool travel. When the motion cannot
    // be made, `problem` says why and the job fails with `problem_code` when it starts.
    std::vector<Eigen::VectorXd> points;
    std::vector<double> arc;
    double speed = 1.0;
    double tool_distance = 0;
    std::optional<double> min_duration;  // a timed move's duration (seconds)
    drivers::ErrorCode problem_code = drivers::ErrorCode::none;
    std::string problem;
    // Execution (simulation side).
    bool started = false;
    std::chrono::nanoseconds start{0};
    std::chrono::nanoseconds deadline{0};  // move: end + settle timeout; wait: the timeout (0: none)
    double duration = 0;                   // arm motion, seconds
    bool moves_arm = false, moves_fingers = false;
    std::optional<std::chrono::nanoseconds> resting_since;  // fingers: when they were last seen stopped
  };

  // DriverCore hooks (the core's mutex held): plan a job when it is accepted; brake on stop() and disconnect().
  void accept_hook(Job& job) override;
  void halt_hook() override;

  // Everything below: the core's mutex held.
  // Ends the head job: done, or failed (the core cancels what is behind it; a failed motion brakes the arm).
  void finish_head(Controller& c, Job& job, drivers::ErrorCode error = drivers::ErrorCode::none,
                   std::string message = {});
  // The arm joints where everything queued will leave the arm: the seed and start of the next planned motion.
  Eigen::VectorXd queue_end_joints() const;
  // Planning at submission (owner thread).
  void plan_joints(SimJob& job, const Eigen::VectorXd& goal, double speed) const;
  void plan_pose(SimJob& job, const drivers::MovePose& move) const;
  // Plans a MoveJoints or MovePose from where the queue ends (accept_hook's planning).
  void plan_command(SimJob& job, const drivers::Command& command) const;
  // A planned motion's duration from `start` (its first point replaced): the least time at its speed, kept within
  // max_tool_speed on a straight line, at least min_move_time and its min_duration.
  double planned_duration(const SimJob& job, std::vector<Eigen::VectorXd> points) const;
  // Simulation side, per step: start the head job, check whether it has finished (true when it has, then it was
  // finished with finish_head), and write the servo targets.
  void start_head(std::chrono::nanoseconds now, Job& job, const mjModel* model, const mjData* data);
  // Whether a job moves the fingers, and so reads the touch sensors from its start (home and Grip).
  static bool reads_touch(const Job& job);
  bool check_head(Controller& c, std::chrono::nanoseconds now, const mjModel* model, const mjData* data,
                  bool sensors_fresh);
  // The position reading of the simulation at this step.
  drivers::PositionReading reading(const Controller& c, std::chrono::nanoseconds now, const mjData* data) const;
  void write_targets(std::chrono::nanoseconds now, const mjModel* model, mjData* data);
  // Starts a smooth finger motion to `goal` (finger joint value) with force limit `force`.
  void move_fingers(std::chrono::nanoseconds now, double goal, double force);
  // Where a release starts from: the fingers' mean position when they hold a part (the last finger motion closed and
  // both pads touch something short of fully closed); nullopt when they hold nothing.
  std::optional<double> holding_at(const mjModel* model, const mjData* data) const;
  // Arm and finger targets at time `now`.
  struct ArmTarget {
    Eigen::VectorXd position, velocity, acceleration;
  };
  ArmTarget arm_target(std::chrono::nanoseconds now) const;
  double finger_ramp(std::chrono::nanoseconds now, double* velocity) const;
  // Holds everything where the data says it is now (first step, after MuJoCo reset the simulation).
  void hold_here(std::chrono::nanoseconds now, const mjData* data);
  Eigen::VectorXd joints(const mjData* data) const;
  Eigen::VectorXd joint_speeds(const mjData* data) const;
  double finger_position(const mjData* data, int side) const;
  double finger_speed(const mjData* data, int side) const;
  std::array<bool, 2> touch(const mjModel* model, const mjData* data) const;
  double finger_stiffness(const mjModel* model, int side) const;
  void record_grip(const Job& job, const mjModel* model, const mjData* data);

  const RobotIds& ids_;
  SignalTable& signals_;
  const SimDriverOptions options_;
  const std::string name_;
  const models::KinematicChain chain_;
  Eigen::VectorXd max_speed_, lower_, upper_, home_;
  double grip_force_ = 0;
  double finger_closed_ = 0, finger_open_ = 0;  // finger joint travel

  // Below: under the core's mutex.
  std::optional<GripOutcome> last_grip_;
  bool brake_requested_ = false;

  // The servo targets (simulation side; under the core's mutex because submit() plans from arm_goal_).
  bool initialised_ = false;
  std::optional<JointPath> arm_path_;  // the arm follows this (held at its end) ...
  std::chrono::nanoseconds arm_start_{0};
  double arm_duration_ = 1.0;
  bool braking_ = false;  // ... or brakes from brake_q_ at brake_v_
  Eigen::VectorXd brake_q_, brake_v_;
  std::chrono::nanoseconds brake_start_{0};
  double brake_duration_ = 0;
  Eigen::VectorXd arm_goal_;      // where the arm targets come to rest
  Eigen::VectorXd arm_position_;  // the arm targets written at the last step
  Eigen::VectorXd arm_velocity_;
  double finger_from_ = 0, finger_goal_ = 0, finger_force_ = 0;
  bool finger_closing_ = false;  // the last finger motion closed (the force limit holds the fingers on a part)
  std::chrono::nanoseconds finger_start_{0};
  double finger_duration_ = 0;
  std::chrono::nanoseconds released_until_{0};  // release_grip(): the fingers are driven open before this time
};

}  // namespace cellwright::twin::sim
