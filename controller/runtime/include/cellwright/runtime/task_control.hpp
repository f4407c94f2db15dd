// TaskControl: the task-control thread's work (paper section 3.3): it executes the checked Petri net of the task
// program, fires transitions, arbitrates conflicts (petri::choose / fire_chosen with the fair Arbiter), sends
// motion-level commands to the robot-control threads and learns of their completion from their status messages.
//
// One turn, step():
//   1. drain the status inbox: a done command marks its place completed; a failed one ends the run (kFailed, with
//      the robot's reason);
//   2. fire until quiescent: the `allowed` mask admits a transition when every robot place among its inputs has
//      completed (move/open/close: the robot reported done; signal/wait/loop: at once, they never go to a robot;
//      start places: always), and a loop leader's again/exit as its iteration count says (task::LoopControl). choose() picks a conflict-free set, fire_chosen() fires it; for each fired transition, in
//      ascending id order, a `fire` event is logged and, if it starts a move/open/close, the MotionCommand goes to
//      that robot's queue (try_push: the queue has room, each robot has at most one command in flight); a device
//      primitive (a machine's start, a belt's run, waiting for a photo-eye) goes to device control's queue instead,
//      with the robot whose program ordered it, and device control reports its end like a robot (RobotStatus);
//   3. detect the end: the final marking (every robot done) -> kFinished; a dead marking that is not final -> kFailed
//      with "deadlock" and the marked places (the net was checked, so this should not happen, but it never hangs);
//   4. watch the waits (with recovery enabled): a robot waiting longer than RecoveryOptions::wait_timeout for an
//      event is a symptom (wait_timeout); task control knows from its own firings whether the event was signalled
//      (tokens put on its place minus tokens taken exceed the tokens there): then the event was lost on the way and
//      is delivered again (resignal, by the decision tree), else the cell is stopped;
//   5. a robot that reports stop_cell (RobotStatus::stop_cell) stops the run as kStopped;
//   6. account time: the time since the previous step is added to each robot's activity as classified at the end of
//      the previous step (busy / waiting / blocked / idle, see RobotActivity).
//
// Threads: TaskControl is used by its task-control participant only (step(), and the accessors between steps): in
// real time its own thread; in lock-step the thread the runtime gives it (runtime.hpp), in its turn. The
// queues it holds are shared with the robot-control threads. view() may be read by another thread only while task
// control is not running (in lock-step: outside its turn, e.g. while the runtime is paused in Runtime::step()).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/task/compiled.hpp"
#include "cellwright/task/loop_control.hpp"

namespace cellwright::runtime {

// What a robot is doing, as task control sees it after its turn.
enum class RobotActivity {
  kIdle,     // not started, or its program is done
  kBusy,     // executing a move/open/close (sent, not reported done yet)
  kWaiting,  // in a wait place: waiting for an event another robot signals
  kBlocked,  // its command completed but the next transition is not enabled or was not chosen
};

// "idle", "busy", "waiting", "blocked".
const char* to_string(RobotActivity activity);

// Time spent in each activity.
struct ActivityTime {
  SimDuration busy{0}, waiting{0}, blocked{0}, idle{0};
  SimDuration total() const { return busy + waiting + blocked + idle; }
};

// One robot as task control sees it.
struct RobotView {
  std::string robot;  // program label
  RobotActivity activity = RobotActivity::kIdle;
  int primitive = -1;   // the primitive its token is at (-1: start or done)
  std::string command;  // that primitive as text ("move at(A)"), "" when none
  std::string place;    // id of the place holding its token
  bool done = false;    // its program has finished
};

struct TaskView {
  SimDuration time{0};  // when the last step ran
  petri::Marking marking;
  std::vector<std::string> last_fired;  // transition ids fired in the last step, in firing order
  std::uint64_t firings = 0;            // transitions fired so far
  std::vector<RobotView> robots;        // program order
};

// A signal task control fires, on its way to its event's place.
struct SignalSent {
  SimDuration time{0};
  std::string robot;        // program label of the robot that signals
  std::string event;        // the event it signals
  std::uint64_t count = 0;  // the signals task control has fired so far, this one included (over all robots, from 1)
};

// A hook on the signal path, the runtime's one port between a signal and its event (RunConfig::signal_filter): true
// delivers the event, false drops it (its token never reaches the event's place; recovery's wait watchdog finds
// the wait that is never signalled, step 4 above). Called by task control in its turn, as the signal fires, right
// after its `fire` line is logged, for an event whose place exists and holds the token just put there. Whoever wires
// it (a rig that injects a lost signal) logs what it does itself.
using SignalFilter = std::function<bool(const SignalSent&)>;

class TaskControl {
 public:
  enum class State { kRunning, kFinished, kFailed, kStopped };

  // `net` must be to_net(program) (same robots, transitions starting primitives of the program): checked here,
  // InternalError otherwise. robot_inboxes[r] is robot r's command queue, `status_inbox` the queue robots report
  // into; `log` records the firings; `device_inbox` is device control's command queue (nullptr: the program has no
  // device commands; InternalError at the first one). All must outlive the TaskControl.
  TaskControl(const petri::Net& net, const task::CompiledProgram& program,
              std::vector<MessageQueue<MotionCommand>*> robot_inboxes, MessageQueue<RobotStatus>& status_inbox,
              EventLog& log, RecoveryOptions recovery = {}, SignalFilter signal_filter = {},
              MessageQueue<MotionCommand>* device_inbox = nullptr);

  // Scripts the firings (a counterexample's replay, docs/live-view.md): from now on, only order[k] may fire as the
  // k-th firing (after those of this script already fired), one at a time, in this order; once the script is done,
  // nothing more fires (the run ends at its dead marking, or stays where the script left it). Each transition must
  // still be enabled and allowed as in step 2 above: the script only narrows the choice. Before the first step;
  // ids must be the net's (InternalError otherwise). An empty order leaves the choice to petri::choose.
  void follow(std::vector<petri::TransitionId> order);
  // How many firings of the script have fired.
  std::size_t followed() const { return script_pos_; }

  // One turn at simulation time `now` (see the top). Non-blocking. Returns the state after the turn; once not
  // kRunning it stays so and further steps only account time (all activities idle).
  State step(SimDuration now);

  // Adds the time up to `now` to the activities as classified by the last step (the run's end).
  void account_until(SimDuration now);

  State state() const { return state_; }
  // kFailed, kStopped: why. kFinished: "".
  const std::string& reason() const { return reason_; }
  // When the final marking was reached (kFinished only).
  std::optional<SimDuration> finished_at() const { return finished_at_; }

  const petri::Marking& marking() const { return marking_; }
  std::uint64_t firings() const { return firings_; }
  // Per robot, program order.
  const std::vector<ActivityTime>& activity_time() const { return time_; }
  // A copy of the view after the last step.
  TaskView view() const;
  // Whether some robot waits for an event after the last step (view()'s kWaiting, without building the view: the
  // lock-step runtime asks every turn).
  bool any_waiting() const;

 private:
  void drain_statuses(SimDuration now);
  void fire_until_quiescent(SimDuration now);
  void detect_end(SimDuration now);
  void classify(SimDuration now);
  // `dead`: no transition can fire: only a wait whose event was lost is taken up, at once.
  void watch_waits(SimDuration now, bool dead);
  std::vector<bool> allowed() const;

  const petri::Net& net_;
  const task::CompiledProgram& program_;
  std::vector<MessageQueue<MotionCommand>*> inboxes_;
  MessageQueue<MotionCommand>* device_inbox_;
  MessageQueue<RobotStatus>& statuses_;
  EventLog& log_;

  petri::Marking marking_;
  petri::Arbiter arbiter_;
  task::LoopControl loops_;  // which of a loop's again/exit transitions the iteration count allows
  // Per place: the primitive it stands for (robot, index), or none; and whether that primitive has completed.
  struct PlaceInfo {
    bool command = false;  // a robot's primitive place
    std::size_t robot = 0;
    std::size_t index = 0;
  };
  std::vector<PlaceInfo> places_;
  std::vector<bool> completed_;
  std::vector<bool> in_flight_;  // per robot: a command sent and not reported
  State state_ = State::kRunning;
  std::string reason_;
  std::optional<SimDuration> finished_at_;
  std::uint64_t firings_ = 0;
  std::vector<std::string> last_fired_;
  std::vector<RobotActivity> activity_;
  std::vector<ActivityTime> time_;
  SimDuration last_step_{0};
  SimDuration accounted_{0};

  const RecoveryOptions recovery_;
  SignalFilter signal_filter_;  // RunConfig::signal_filter
  std::vector<petri::TransitionId> script_;  // follow()'s order, empty when not scripted
  std::size_t script_pos_ = 0;               // the next of script_ to fire
  std::uint64_t signals_fired_ = 0;
  std::vector<std::int64_t> expected_tokens_;            // per place: initial + put by firings - taken by firings
  std::vector<std::optional<SimDuration>> wait_since_;   // per robot: since when it waits (kWaiting)
};

}  // namespace cellwright::runtime
