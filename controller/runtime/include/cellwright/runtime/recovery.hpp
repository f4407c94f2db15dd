// Fault diagnosis and recovery (paper section 3.4: "Once the cause of the error has been determined by searching a
// decision tree, the appropriate remedial action is taken"). docs/faults.md is the user's page: the symptoms, the
// questions, the actions and the file format.
//
// A DecisionTree is data: for each symptom the controller can sense, a tree whose inner nodes ask a question the
// controller can answer from what it senses, and whose leaves name the cause and the remedial action. It is read from
// a YAML file (scenes/recovery.yaml is the default, which a scenario may replace with `recovery: FILE`):
//
//     grip_lost:                      # symptom
//       ask: part_seen                # question
//       yes:
//         ask: part_reachable
//         yes: {cause: dropped, action: pick_again}
//         no: {cause: dropped_out_of_reach, action: set_aside}
//       no: {cause: dropped_unseen, action: set_aside}
//
// diagnose() walks the tree of a symptom, asking each question of a callback, and returns the leaf with the path of
// answers. A symptom the file does not list gets {cause: unknown, action: stop_cell}.
//
// RecoveryOptions and SafetyOptions are the tunables of recovery and of the safety layer (safety.hpp); robot control
// and task control read them from MotionOptions.
//
// Threads: a DecisionTree is immutable once loaded and may be shared by every thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/runtime/clock.hpp"

namespace cellwright::runtime {

// What the controller can sense going wrong (docs/faults.md section 2).
enum class Symptom : std::uint8_t {
  grip_lost,             // a held part left the fingers during a move or a wait
  closed_on_nothing,     // a close that should grip a part gripped nothing
  closed_on_wrong_part,  // ... gripped another part
  part_shifted,          // a held part moved in the fingers
  part_misplaced,        // a part to be picked rests off its place
  part_not_arrived,      // waited too long for a part to arrive
  target_unreachable,    // no grasp of the target is reachable
  driver_timeout,        // the controller did not answer a command in time
  driver_fault,          // the controller reported a hardware or protocol error: the driver is in fault
                         // (an error the driver does not know is unknown_error)
  link_lost,             // the link to the controller was lost
  position_refused,      // the controller refused a position (unreachable for it)
  position_missed,       // the arm did not arrive where it was sent
  protective_stop,       // the safety layer stopped the robot
  wait_timeout,          // a robot waited too long for an event
  frame_lost,            // the camera delivered no frame
  obstacle_seen,         // the safety sensor sees an object that is not in the cell model
  // a robot makes no progress: one command interrupted RecoveryOptions::progress_limit times (the same protective
  // stop, force trip or retry again and again), or waiting progress_timeout for a part that is never ready
  no_progress,
  // the controller reported an error its driver does not know (ErrorCode::unknown: words or a code outside the
  // driver's list); the driver is in fault and what the arm is doing cannot be told
  unknown_error,
  io_failed,             // a request to a device's I/O unit failed (timeout, Modbus exception, link lost, garbled)
  device_timeout,        // a device's awaited input did not come in time (a machine never done, an eye never on)
  device_contradiction,  // a real photo-eye sees a part where the environment model has none
};
inline constexpr std::size_t kSymptoms = 21;
std::string_view to_string(Symptom s);
std::optional<Symptom> symptom_from(std::string_view name);

// The questions a tree may ask (docs/faults.md section 3).
enum class Question : std::uint8_t {
  part_seen,        // the model knows where the part is (present, not lost)
  part_at_rest,     // it is not moving
  part_upright,     // it stands upright (a grasp from above fits it)
  part_reachable,   // the robot reaches a grasp of it
  part_in_hand,     // the grip sensor has it between the fingers
  driver_in_fault,  // the driver is in fault
  retries_left,     // the command has been recovered fewer than max_attempts times
  obstacle_near,    // the safety sensor sees an object near the robot
  signal_fired,     // the event waited for was signalled (and so was lost on the way)
  // the command that did not end is held back by something: the controller took it (its driver reported it running)
  // and still answers position requests, and what the robot senses shows the motion blocked (the arm moved and
  // stands short of its goal, or the wrist force changed by more than RecoveryOptions::contact_force since the
  // command was first sent: fingers pressing on something); a silent controller shows neither
  motion_blocked,
  waiting_for_part,  // the command waits for its part and was never sent to the driver
  part_lost,         // a part was declared lost (set aside) for which this robot has skipped no work yet
};
std::string_view to_string(Question q);
std::optional<Question> question_from(std::string_view name);

// The remedial actions (docs/faults.md section 3).
enum class Action : std::uint8_t {
  retry,         // do the interrupted command again
  reset_rehome,  // reset the driver (connect again if the link was lost), home, activate, then retry
  pick_again,    // open, pick the part where it is seen, then do the interrupted command again
  adopt_hold,    // take the part's seen place in the hand as the new hold
  go_on,         // nothing to do
  wait_clear,    // stay stopped until the safety layer releases, then retry
  set_aside,     // the part is lost: skip every command about it
  resignal,      // deliver the lost event again
  stop_cell,     // stop every robot; the run ends as stopped
};
std::string_view to_string(Action a);
std::optional<Action> action_from(std::string_view name);

struct Diagnosis {
  Symptom symptom = Symptom::driver_fault;
  std::string cause;
  Action action = Action::stop_cell;
  std::string path;  // the answers on the way: "part_seen=yes part_reachable=no"
};

class DecisionTree {
 public:
  struct Node {
    std::optional<Question> ask;  // set: an inner node
    int yes = -1, no = -1;        // children (indices into nodes), inner nodes only
    std::string cause;            // a leaf
    Action action = Action::stop_cell;
  };

  // Reads a tree from YAML text; `source` names it in errors. Throws InputError naming the file, line, column and
  // field: not YAML, not a mapping, an unknown symptom, question or action, a node that is neither {ask, yes, no} nor
  // {cause, action}, a field missing or unknown.
  static DecisionTree parse(std::string_view yaml_text, const std::string& source);
  static DecisionTree load(const std::filesystem::path& file);
  // The built-in tree (the same as scenes/recovery.yaml; a test keeps them equal).
  static const DecisionTree& standard();
  static std::string_view standard_text();

  // Walks the symptom's tree; `answer` answers each question asked. A symptom with no tree: cause "unknown",
  // stop_cell.
  Diagnosis diagnose(Symptom symptom, const std::function<bool(Question)>& answer) const;

  bool has(Symptom s) const { return roots_.count(s) != 0; }

 private:
  std::vector<Node> nodes_;
  std::map<Symptom, int> roots_;
};

struct RecoveryOptions {
  bool enabled = true;  // false: the first fault fails the run (the behaviour before recovery existed)
  std::shared_ptr<const DecisionTree> tree;  // nullptr: DecisionTree::standard()
  int max_attempts = 3;                      // recoveries of one command before retries_left says no
  SimDuration part_wait = std::chrono::seconds(20);  // part_not_arrived when a part waited for is absent this long
  SimDuration wait_timeout = std::chrono::seconds(60);  // wait_timeout after waiting this long for an event
  // driver_timeout when a command has not ended this long after it was sent (the driver's own deadlines come first:
  // a serial driver fails a command its controller does not answer; this catches one that never ends)
  SimDuration command_timeout = std::chrono::seconds(8);
  SimDuration clear_wait = std::chrono::seconds(20);    // wait_clear gives up (stop_cell) after this long
  int grip_lost_periods = 3;       // grip_lost when the grip sensor misses the part this many periods running
  double shift_tolerance = 0.008;  // m: part_shifted when a held part is this far from where the hold puts it
  // m: part_misplaced when a part rests this far from its place (on a belt: this far to the side; along it, the
  // stop and the part before it decide) ...
  double misplace_offset = 0.02;
  double misplace_yaw = 0.1745;    // rad: ... or turned this much (10 degrees; a box's quarter turns are alike)
  // no_progress (docs/faults.md section 2): the progress_limit-th interruption of one command (a symptom sensed while
  // it runs or recovers) is reported as no_progress instead of its own symptom; with max_attempts below it, the
  // trees that ask retries_left have given up before. A command that has waited progress_timeout for its part (a
  // class with no part at its location, a part that is there but never ready) is no_progress too; a part absent from
  // the cell is part_not_arrived after part_wait first.
  int progress_limit = 5;
  SimDuration progress_timeout = std::chrono::seconds(30);
  // N: a change of the wrist force this large during a command that does not end is something pressing on the hand
  // (Question::motion_blocked)
  double contact_force = 3.0;
  // device_contradiction when a real photo-eye has seen a part the model does not have for this long (a part on its
  // way to the eye is seen a little earlier or later than the model says)
  SimDuration contradiction_time = std::chrono::seconds(1);
  // How long an awaited device input may take (device_timeout): a machine's busy after its start and its done after
  // `wait M` began: its process_time times machine_time_factor plus machine_time_margin; a photo-eye: sensor_wait.
  double machine_time_factor = 2.0;
  SimDuration machine_time_margin = std::chrono::seconds(5);
  SimDuration sensor_wait = std::chrono::seconds(60);
};

struct SafetyOptions {
  bool enabled = true;
  double obstacle_distance = 0.05;  // m: a tool or wrist this close to an obstacle along its motion stops the robot
  double robot_distance = 0.10;     // m: ... this close to another robot's tool or wrist, outside a hand-over
  double handover_zone = 0.30;      // m: both tools this close to the hand-over pose are in a hand-over
  double force_limit = 250.0;       // N: wrist force beyond this stops the robot
  // A coordinated carry (two robots holding one workpiece; safety.hpp check_carry) stops both robots when ...
  double carry_error = 0.01;        // m: ... the follower's tool is this far from where the master's and the grasp put it
  double carry_turn = 0.0524;       // rad (3 degrees): ... or turned this much from it
  double squeeze_force = 40.0;      // N: ... or the internal force along the workpiece is beyond this, pushing or pulling
  SimDuration clear_time = std::chrono::milliseconds(200);  // clear this long before the stop is released
};

}  // namespace cellwright::runtime
