// RobotControl: one robot-control thread's work (paper section 3.4). It takes motion-level commands from its inbox,
// turns them into target motions with the environment model and the robot's kinematics, drives the robot through the
// one driver interface, watches the sensor condition of the command's place, and reports done or failed.
//
// WHERE THE ROBOT IS comes from its driver, never from a simulation: every MotionOptions::position_period (and once
// after every completed move) robot control asks request_position(); for a driver whose reads hold a serial line
// (Capabilities::read_time), paced to the line: at least read_time / MotionOptions::read_line_share apart and never
// while a command is in the driver (docs/real-robots.md, "The serial line"). When the answer arrives it writes it
// into the environment model (RobotState::joints from a joint read-back; RobotState::tcp from a tool-pose read-back,
// the joints then being the last commanded ones). A simulation driver answers at its next step; a serial controller
// answers when its turn in the queue comes. Grip success comes from the robot's grip sensor (RobotState::grip, written
// from the sensor port, sensors.hpp: the twin's finger pad sensors, or a real gripper's jaw switch through its driver,
// which says "on something" without naming it: taken as the part expected); without one (nullopt: no sensor wired, or
// it cannot tell) a close is taken as done (the "grip_not_sensed" condition).
//
// Bring-up: the Runtime calls connect() on the main thread before any thread starts (a configuration that cannot work
// is refused there, as an InputError). In its first turns robot control homes the driver (if not homed yet) and
// activates it; a refusal or failure there is reported as a RobotStatus with index kNoCommand.
//
// A command, turn by turn (step()):
//  - move: resolve the target (environment_model.hpp resolve_target; the program's labels are first mapped to cell
//    names through the binding). kWait (a part still moving or absent) keeps the command pending and re-resolves next
//    turn (a `sensor` event "waiting_for_part" is logged once); kFail fails it. Poses are solved with the robot's
//    inverse kinematics seeded from its current joints; the reachable solution closest to them wins; none reachable
//    fails with the solver's reason. The command fits the robot: MoveJoints at MotionOptions::speed to a driver that
//    prefers joint targets (Capabilities::prefers_pose false and joint_control), else MovePose in the base frame, with
//    Path::linear for a straight approach, grasp or lift (at(X) right after above(X) or the reverse, hand_grasp right
//    after hand_approach or the reverse) when the driver moves linearly. home goes straight to the home joints.
//  - open/close: Grip open/close (with the robot's grip force if the driver takes a force).
//  - COORDINATED BLOCKS (a primitive with a task::Segment; docs/runtime.md "Coordinated blocks"; the targets are
//    resolve_segment_target's, segment_target.hpp, which the motion plan shares): the master's tool target is its
//    grasp point on the workpiece (the end of its long axis nearer the master's base, fingers across it) before it
//    holds it, and while carrying a pure translation of its tool (the workpiece keeps its orientation: it is not
//    twisted): up by the pick's approach height for the lift, to where the workpiece's centre lands on (or approach
//    height above) a location, straight up from the put-down. The follower takes the other end before the
//    grasp; once both hold, its target is the master's target composed with the grasp transform measured then
//    (master tool -> own tool). Both post to the Coordination board and submit with the agreed (longest) duration;
//    every move after the first approach is a straight line (MovePose linear) where the driver has one. A driver
//    that cannot time its moves (Capabilities::timed_motion) fails the segment, naming itself.
//  - A driver that is busy (its queue full, e.g. with a position read) is asked again next turn.
//  - The command is then polled each turn. When the driver reports done, the place's sensor condition is checked:
//      move:  position reached, on a position read-back requested after the driver said done: every joint within
//             position_tolerance of the goal (joint read-back), or the tool within pose_tolerance (tool-pose
//             read-back); a driver that reads back neither cannot tell ("position_not_sensed", taken as reached);
//      close: the workpiece named by the primitive is between the fingers (when the grip sensor can tell; a close
//             that names no workpiece passes) -> the robot holds it (held_by/hold in the environment model); otherwise
//             the command fails ("closed on nothing" / "closed on B, expected A");
//      open:  the robot releases what it held.
//    A condition that holds completes the command: command_end ok, status kDone. A driver failure, a refusal or a
//    condition that does not hold fails it: command_end with the reason, status kFailed.
//
// WHEN THINGS GO WRONG (docs/faults.md). With MotionOptions::recovery.enabled, a symptom (a driver failure, a close on
// nothing, a held part lost from the fingers or shifted in them, a part misplaced, a part that does not arrive, an
// unreachable target, a missed position, a protective stop) does not fail the command: it is logged
// (fault_detected), diagnosed with the decision tree (diagnosis: cause and action, recovery.hpp) and the action is
// taken while the command's place stays marked: retry it; reset, re-home and retry; pick the part again where it is
// seen (recovery steps: open, above, at, close, above — synthetic primitives executed and checked like the program's)
// and retry; adopt the shifted hold; wait for the safety layer's release and retry; set the part aside as lost
// (workpiece_lost; every command about it is then skipped, logged as `skipped`, and reported done); or stop the cell
// (reported as a failure with RobotStatus::stop_cell). recovery_end closes each recovery when the command is done.
// reset_rehome reads where the arm stopped before it moves it, refuses to home an arm that holds a part (the cell
// stops: rehome()), and starts its steps over when one fails, at most max_attempts times. A position read-back that
// fails while nothing else would report it (idle) is a symptom at once, recovered before the next command.
// A robot that makes no progress is a symptom of its own (no_progress, diagnosed by the same tree): the
// RecoveryOptions::progress_limit-th interruption of one command (the same protective stop, force trip or retry again
// and again), or a wait of progress_timeout for a part that is never ready (a class whose part was set aside
// upstream: the tree's part_lost then skips the work for it, as set_aside does).
// The safety layer (safety.hpp) is asked every period before any command is sent: while it says stop, the driver is
// stopped (protective_stop) and nothing is sent; the command is done again once it releases.
//
// Threads: step() runs on one thread at a time: its robot-control participant's (real time: its own thread; lock-step:
// the thread the runtime gives the participant, by default the simulation thread, in its turn; runtime.hpp), except
// connect() (main thread, before the threads start) and view() (another thread, only while this one is not running: in lock-step outside its
// turn). It shares the environment model (Guarded), its inbox and the status queue.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/runtime/coordination.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/segment_target.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

struct MotionOptions {
  double speed = 0.5;                // fraction of the robot's maximum speed for moves, (0, 1]
  double position_tolerance = 0.01;  // rad: "position reached" when every joint is this close to the goal
  double pose_tolerance = 0.005;     // m: the same for a tool-pose read-back (tool centre point distance to the goal)
  // rad: for a robot without full orientation (a 5-axis arm, Capabilities::full_orientation false), only target poses
  // whose approach axis is this close to the arm's vertical plane are chosen (drivers::out_of_arm_plane).
  double arm_plane_tolerance = 0.004;
  // How often robot control asks its driver where the arm is (a read already in flight is waited for first).
  SimDuration position_period = std::chrono::milliseconds(10);
  // The most of its line's time a robot's periodic reads may take when each read holds the line
  // (Capabilities::read_time > 0 and no reads_while_moving: a serial controller). Its periodic reads are then at
  // least read_time / read_line_share apart (0.25: 4 read times; a VAL II `WHERE` at 9600 baud holds the line about
  // 0.27 s, so about one read a second), and none is asked while a command is in the driver (it would wait behind it
  // and then delay the read that checks it); the read after a move that checks it is always asked. 0 turns this
  // pacing off (position_period alone, reads asked behind commands: how it was, for the comparison of
  // tools/bench/polling_bench.cpp).
  double read_line_share = 0.25;
  TargetOptions targets;
  models::IkOptions ik;
  // Each step, move the part this robot holds with its hand in the environment model (Hold::in_hand): the runtime
  // sets this when nothing else measures held parts (Perception other than kTruth).
  bool track_held_parts = false;
  RecoveryOptions recovery;  // fault detection and recovery (recovery.hpp, docs/faults.md)
  SafetyOptions safety;      // the safety layer (safety.hpp)
};

// Program labels -> cell names, resolved and checked by the Runtime (runtime.hpp Binding).
struct NameMap {
  std::map<std::string, std::string> robots;   // program robot label -> cell robot
  std::map<std::string, std::string> objects;  // program workpiece/location label -> cell workpiece/location
  // Program workpiece class label -> the cell location its parts arrive at (task/compiled.hpp WorkpieceClass). Robot
  // control binds a class to one cell workpiece at a time: at the move to a part of the class it does not have yet,
  // the part at that location nearest to it that no robot holds or has claimed (it claims it:
  // WorkpieceState::claimed_by); at a close that takes a part of the class out of another robot's hand, that part. The
  // class then means that part until the open that releases it.
  std::map<std::string, std::string> classes;
};

enum class RobotPhase {
  kBringUp,    // homing/activating the driver
  kReady,      // no command
  kResolving,  // a move waiting for its target to be ready (a part still moving)
  kExecuting,  // a command submitted, polling the driver
  kFailed,     // bring-up or a command failed; no further commands are taken
};

// "bring_up", "ready", "resolving", "executing", "failed".
const char* to_string(RobotPhase phase);

struct RobotControlView {
  std::string robot;  // program label
  std::string cell;   // cell robot name
  RobotPhase phase = RobotPhase::kBringUp;
  std::optional<std::size_t> primitive;  // the command being executed
  std::string command;                   // "move at(A)"
  std::string detail;                    // the driver command sent, or why it waits
  drivers::DriverState driver = drivers::DriverState::disconnected;
};

class RobotControl {
 public:
  // `index` is the robot's index in the program (its RobotStatus::robot); `label` its program label, `cell_name` its
  // cell robot; `chain` its kinematics (base_link..tcp); `grip_force` the cell's grip force (N). The driver, queues,
  // environment and log must outlive the RobotControl.
  // `coordination`: the board shared with the other robots, which a program with coordinated blocks needs (nullptr:
  // a segment of a block fails, naming it).
  // `await_fresh_truth`: check a completed command's sensor condition only on an environment model updated after the
  // completion was seen. Real-time mode needs it (the simulation thread may not have written the step's truth yet);
  // in lock-step the simulation's turn always precedes the robot's, so the model is fresh and the check is immediate.
  RobotControl(std::size_t index, std::string label, std::string cell_name, drivers::RobotDriver& driver,
               models::KinematicChain chain, double grip_force, NameMap names, SharedEnvironment& environment,
               MessageQueue<MotionCommand>& inbox, MessageQueue<RobotStatus>& status_out, EventLog& log,
               MotionOptions options = {}, bool await_fresh_truth = false, Coordination* coordination = nullptr);

  // Main thread, before the threads start: connects a disconnected driver. Throws InputError when the driver's
  // configuration cannot work, InternalError if the driver refuses for another reason.
  void connect();

  // One turn at simulation time `now`: bring-up, take a command, advance the current one as far as it goes without
  // waiting. Non-blocking. The robot-control thread only.
  void step(SimDuration now);

  // Halts the robot (driver stop()): called by the robot-control thread when the run ends.
  void halt();

  RobotPhase phase() const { return phase_; }
  RobotControlView view() const;

 private:
  struct Current {
    MotionCommand command;
    std::optional<task::Primitive> step;  // a recovery step being executed instead of the command
    drivers::CommandId id = 0;                   // 0 until submitted
    std::vector<double> goal;                    // move: the joint goal
    std::optional<Eigen::Isometry3d> goal_pose;  // move: the tool goal in the base frame
    std::optional<SimDuration> done_seen;        // when the driver was first seen done
    std::uint64_t reads_at_done = 0;             // position reads asked for by then
    bool pose_command = false;                   // move: sent as MovePose (the driver chose the configuration)
    std::optional<task::Target> target;          // move: its target, bound to cell names
    std::string detail;
    bool start_logged = false;  // command_start written
    bool wait_logged = false;   // the "waiting_for_part" sensor event written
    bool ready_logged = false;  // the "part_ready" sensor event written (the command was sent after that wait)
    std::string waiting_for;    // why the target is not ready yet (for view(); the log's detail is the driver's)
    std::optional<SimDuration> waiting_since;  // when the wait for its target began
    int attempts = 0;                          // recoveries of this command so far
    SimDuration submitted_at{0};               // when the active primitive was sent to the driver
    bool seen_running = false;                 // the driver reported the active primitive running
    std::uint64_t reads_at_submit = 0;         // position reads asked for when it was sent
    bool baseline_taken = false;               // the arm and wrist force when the command was first sent:
    std::vector<double> joints_at_start;       // what Question::motion_blocked compares with
    std::optional<Eigen::Vector3d> force_at_start;
    std::optional<SimDuration> stalled_since;  // since when it has waited for its part (no_progress)
    // A coordinated segment (COORDINATED BLOCKS above): its command, prepared and posted, waiting for the agreement.
    std::optional<drivers::Command> prepared;
  };
  // A recovery under way for the current command (docs/faults.md).
  struct Recovery {
    Diagnosis diagnosis;
    SimDuration detected{0};
    std::string workpiece;                // the part concerned ("" none)
    std::deque<task::Primitive> steps;    // to execute before the command is done again
    bool rehome = false;                  // reset (connect), home and activate first
    bool wait_clear = false;              // wait for the safety layer's release first
    bool skip = false;                    // after the steps, the command completes as skipped
    bool settle = false;                  // the diagnosis waits for the part to come to rest (a drop)
    std::string detail;                   // the symptom's detail (for a deferred diagnosis)
    // Re-homing (rehome()): the attempts at reset, read-back, homing and activation (at most max_attempts), a reset
    // made, the read-back of where the arm stopped (asked when, done), the home command (0: none in flight, cleared
    // whenever a new one must be issued), and the last step's failure (the driver's message).
    int tries = 0;
    bool reset_done = false;
    drivers::CommandId read_id = 0;
    std::optional<SimDuration> read_asked;
    bool position_read = false;
    drivers::CommandId home_id = 0;
    std::string last_failure;
    bool motion_blocked = false;          // Question::motion_blocked, as sensed when the symptom came
    bool waiting = false;                 // Question::waiting_for_part, as sensed when the symptom came
  };

  void bring_up(SimDuration now);
  // Writes a position read-back that arrived into the model. A read that failed while no command of this robot
  // would report the failure itself (idle, a move done and waiting for its read-back, or a command cancelled behind
  // the read) is a symptom at once, with the driver's message (docs/faults.md section 2).
  // Takes the position read-back in flight if it has ended. Returns true when its failure was reported (a symptom,
  // or the robot failed).
  bool collect_position(SimDuration now);
  // Writes the driver's newest reading into the model if it is newer than the last one written.
  void adopt_reading();
  // Bring-up, then the commands: take, submit, poll, check.
  void run_commands(SimDuration now);
  // Asks the driver for a position now (if none is in flight and the driver takes one); true when one is in flight.
  bool request_position(SimDuration now);
  // Whether the periodic read is due (position_period; paced to the line by MotionOptions::read_line_share).
  bool periodic_read_due(SimDuration now) const;
  // Checks a completed move against the read-back; false (the command failed) when the position was missed.
  bool check_position(SimDuration now);
  // With MotionOptions::track_held_parts, moves the part the robot holds with its tool in the model.
  void track_held_part();
  // The robot's tool centre point in the world: the model's (from the last read-back), else from its joints.
  Eigen::Isometry3d tool_in_world(const RobotState& r) const;
  void start_next(SimDuration now);
  // Resolves and submits the current command; false when it must wait for its target.
  bool submit_current(SimDuration now);
  // Open or close, with the robot's grip force where the driver takes one.
  drivers::Command grip_command(task::PrimitiveKind kind) const;
  // A segment of a coordinated block: prepares its command and posts it (once), then gives it with the agreed
  // duration once the partner has posted too; nullopt while it waits (or when it failed).
  std::optional<drivers::Command> segment_command(SimDuration now);
  // The tool target (world poses, alternatives) of a coordinated segment's move, and whether it goes straight
  // (resolve_segment_target, segment_target.hpp, on the model, this robot's carry of the block and the master's tool).
  MotionTarget segment_target(const task::Target& target, const task::Segment& segment,
                              const std::optional<Eigen::Isometry3d>& master_target, bool* linear);
  void poll_current(SimDuration now);
  void complete(SimDuration now);
  void fail(SimDuration now, std::string reason);
  void report(SimDuration now, CommandOutcome outcome, std::string reason);
  void log_start(SimDuration now);
  std::string bound(const std::string& label) const;
  // Binds the class the active primitive names, if it is unbound (see NameMap::classes); false while no part of it
  // is there to take (the command waits).
  bool bind_class(SimDuration now, const task::Primitive& p);
  // The robot let go of `part` (cell workpiece): a class bound to it is unbound and the part unclaimed.
  void unbind_part(const std::string& part);

  // ---- Faults (docs/faults.md) ----
  // The primitive being executed: a recovery step, else the command's.
  const task::Primitive& active() const;
  // Forgets what was sent for the active primitive, so that it is resolved and submitted again.
  void reset_submission();
  // A symptom was sensed: logs it, diagnoses it (or defers that until the part concerned is at rest) and starts the
  // action; without recovery, fails the command.
  void symptom(SimDuration now, Symptom s, std::string detail, std::string workpiece);
  void diagnose_and_act(SimDuration now);
  bool answer(Question q) const;
  // Advances a recovery under way (re-homing, waiting for the release, a deferred diagnosis); false while it holds
  // the command back.
  bool advance_recovery(SimDuration now);
  // reset_rehome's steps, in order: reset (connect again after a lost link), read where the arm stopped (its answer
  // awaited for command_timeout) into the model, refuse to home an arm that holds a part while another robot is in
  // the cell (the cell stops: nothing here can check the way home), home, activate. A step that fails (or a fault
  // on the way) starts them over, at most RecoveryOptions::max_attempts times in all; then the cell stops, naming the
  // last failure. True once the driver is active again.
  bool rehome(SimDuration now);
  // The command is done after its recovery: logs recovery_end.
  void end_recovery(SimDuration now, bool ok, const std::string& detail);
  // Marks a workpiece lost in the model and logs it.
  void set_aside(SimDuration now, const std::string& workpiece, const std::string& reason);
  // Whether the current command is about a lost part (or comes while carrying one): it is then skipped.
  bool about_lost_part() const;
  void skip_current(SimDuration now, const std::string& reason);
  void stop_cell(SimDuration now, const std::string& reason);
  // The watches run every period: grip (a held part lost or shifted) and the safety layer.
  void watch_grip(SimDuration now);
  void watch_safety(SimDuration now);
  // The carry's safety watch (COORDINATED BLOCKS; safety.hpp check_carry): at the start of the turn, before this
  // robot's read-back of the period is written (so that both tools are those of the same read-backs), the first robot
  // of the pair to take its turn in a period checks the pair; a trip, or a stop the partner recorded, stops this
  // robot (stop_carry).
  void watch_carry(SimDuration now);
  // Stops this robot for its carry of `block`: protective_stop, then (`detected`: this robot found it) fault_detected
  // and diagnosis of the arm the fault is on (`arm`, a program label; this robot when "" or its own), then the cell
  // stops. Both robots of the carry come here in the same period (lock-step).
  void stop_carry(SimDuration now, const std::string& block, const std::string& reason, const std::string& symptom,
                  const std::string& cause, bool detected, const std::string& arm = "");
  // After a move, with the robot standing still: a held part far from where the hold puts it is part_shifted.
  // A part no longer between the fingers is grip_lost; true when that interrupted the command.
  bool check_shift(SimDuration now);
  // A symptom that need not interrupt the command (a shifted hold, an obstacle seen): diagnosed at once; an action
  // other than adopt_hold/go_on interrupts the command like symptom().
  // True when it interrupted the command.
  bool note(SimDuration now, Symptom s, const std::string& detail, const std::string& workpiece);
  // A part to be picked resting off its place: part_misplaced (once per part).
  void check_misplaced(SimDuration now, const task::Target& target);
  // The command waits for its part (`why`): no_progress once it has waited RecoveryOptions::progress_timeout.
  void watch_wait(SimDuration now, const std::string& why);
  // Question::motion_blocked for the active primitive, before its submission is forgotten.
  bool motion_blocked() const;
  // Whether some pose of `target` is reachable (IK, the 5-axis rule), from the model now.
  bool reachable(const task::Target& target) const;
  // The best IK solution among a resolved target's poses; nullopt with *why when none is reachable.
  struct Goal {
    std::vector<double> joints;
    Eigen::Isometry3d pose_in_base = Eigen::Isometry3d::Identity();
  };
  std::optional<Goal> choose_goal(const MotionTarget& target, const std::vector<double>& joints,
                                  const Eigen::Isometry3d& base, std::string* why) const;
  // The driver command of a move to `goal` (MovePose, straight when `linear`, or MoveJoints), noted in current_.
  drivers::Command move_command(const Goal& goal, bool pose_command, bool linear, const task::Target& target);

  const std::size_t index_;
  const std::string label_, cell_;
  drivers::RobotDriver& driver_;
  const models::KinematicChain chain_;
  const double grip_force_;
  const NameMap names_;
  SharedEnvironment& env_;
  MessageQueue<MotionCommand>& inbox_;
  MessageQueue<RobotStatus>& status_out_;
  EventLog& log_;
  const MotionOptions options_;
  const bool await_fresh_truth_;

  RobotPhase phase_ = RobotPhase::kBringUp;
  drivers::CommandId home_id_ = 0;
  std::optional<Current> current_;
  // Position read-backs: the request in flight (0: none), when the last one was asked, the newest answer.
  drivers::CommandId position_request_ = 0;
  std::optional<SimDuration> last_request_;
  std::optional<drivers::PositionReading> reading_;
  std::uint64_t reads_asked_ = 0;     // position reads asked for so far
  std::uint64_t reading_number_ = 0;  // which of them reading_ answers (1 = the first)
  std::string last_failure_;          // the last read-back failure the driver reported (its error and message)
  // The target of this robot's previous move (a straight approach follows from it).
  std::optional<task::Target> last_target_;

  std::map<std::string, std::string> instances_;  // class label -> the cell workpiece it means now (bind_class)
  std::string hand_peer_;  // cell robot whose hand this robot's last hand-approach or hand-grasp move went to

  // Coordinated blocks: the board, the segments of each block this robot has submitted (its occurrence counter),
  // and per block under way its carry: the grasp transform (follower: master tool -> own tool, measured once both
  // hold) and the approach height at the pick.
  Coordination* coordination_ = nullptr;
  std::map<std::string, std::uint64_t> segments_submitted_;
  struct Carry {
    CarryTargets targets;  // the follower's grasp transform and the pick's approach height (segment_target.hpp)
    // The pair (program labels, cell robots), and what watch_carry keeps between its checks: how many checks running
    // each grip sensor has missed the workpiece, and the tools where the last check saw them.
    std::string master, follower, master_cell, follower_cell;
    int grip_missing[2] = {0, 0};
    std::optional<SimDuration> seen_at;
    Eigen::Vector3d seen[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  };
  std::map<std::string, Carry> carry_;

  std::optional<Recovery> recovery_;
  std::string carrying_lost_;  // the lost part this robot would be carrying: skip until the open that releases it
  std::vector<std::string> excused_;  // lost parts this robot set aside or skipped work for (Question::part_lost)
  int grip_missing_ = 0;       // periods the grip sensor has missed the held part
  bool shift_reported_ = false;  // part_shifted logged for the current hold
  std::vector<std::string> misplace_checked_;  // parts checked for misplacement
  bool protective_ = false;    // the safety layer holds the robot
  std::optional<SimDuration> clear_since_;
  SimDuration protective_since_{0};
  std::string protective_reason_;
  std::vector<double> protective_goal_;  // the joints the stopped motion was going to, watched until its way is clear
  int protective_stops_ = 0;  // of the current command
  bool halted_ = false;
  std::uint64_t symptoms_ = 0;  // symptoms sensed so far
  std::vector<std::string> obstacles_seen_;  // obstacles the safety sensor reported, noted once       // halt() was called: the run is over, failures are final
};

}  // namespace cellwright::runtime
