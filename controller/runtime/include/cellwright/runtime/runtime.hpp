// Runtime: the paper's multithreaded control structure (Fig. 2) running one task program on one cell.
//
// Threads, started by run() (or the first step()):
//   simulation     advances the Plant by one control period, reads the sensors (RunConfig::sensors, sensors.hpp)
//                  and writes their readings into the environment model (as much as RunConfig::perception allows;
//                  never the robots' positions, which robot control reads from the drivers), logs collisions and
//                  arrivals, captures a camera frame every vision period and queues it for image processing (without
//                  vision, a plain one for RunConfig::camera_frames' on_frame), decides the end of the run (program
//                  finished + settle time, failure, sim time limit). With no plant (no simulation) it keeps the
//                  clock, reads the sensors and decides the end;
//   image processing  with Perception::kVision only: ImageProcessing::step (image_processing.hpp), then wakes task
//                  and robot control;
//   task control   TaskControl::step (task_control.hpp);
//   device control with device commands in the program (or devices declared): DeviceHub::step (device_hub.hpp): the
//                  devices' commands on the cell's I/O units (RunConfig::io_units), their states in the log;
//   robot control  one per program robot, RobotControl::step (robot_control.hpp); for a remote robot (its robot
//                  control an agent's, RunConfig::remote_robots) the thread watches its link instead
//                  (remote_watch.hpp: a lost agent is a link_lost fault).
// The main thread (the caller) builds everything, checks the input, starts and joins the threads.
//
// LOCK-STEP mode: the threads' work is done in turns through a LockstepScheduler in the fixed order simulation, image
// processing, task control, robot 1..n, once per control period; each turn runs to quiescence without blocking.
// Simulation time is a VirtualClock advanced by the simulation turn. Nothing depends on wall-clock time or the OS
// scheduler, so the event log is byte-identical from run to run and on one core or many. Turns cost no thread switch
// and idle participants no turn (clock.hpp): by default the simulation thread takes every participant's turn
// (RunConfig::lockstep_threads), image processing sleeps until the simulation queues a frame for it, and task control
// until a robot leaves a status in its inbox (or, while a robot waits for an event with recovery on, every period: the
// wait watchdog is a time). Robots take every turn (they read where their arm is and watch their sensors every
// period). Neither choice changes the order of the turns that run, so neither changes the log.
// REAL-TIME mode: the same threads run freely. The simulation thread paces itself to the wall clock (RealtimePacer,
// at `realtime_speed`); task control and robot control sleep on an Event until a message or a driver notification
// arrives, or at most one control period (the period at which they watch sensor conditions).
// HOLDING a real-time run (go(), hold(), wait_held(): `twin serve --realtime`): the simulation thread parks at the
// start of a control period, as it does between lock-step steps. Simulation time stops there, so the twin is frozen:
// nothing moves, and for task and robot control (which keep running, at the frozen time) no time passes, so no
// watchdog, settle time or simulation-time limit counts the hold; the wall-time limit does not count it either, and the
// pacer does not catch up on it afterwards. Task control may still fire on what had arrived before the hold.
//
// Input errors (InputError naming the scenario entry, or the program): a program robot with no binding, a binding to
// a cell robot, workpiece or location that does not exist, a label bound twice to the same cell robot, a cell robot
// without a driver, a move to a hand-over target in a cell without a hand-over or by a robot with no grasp there.
// They are all found by the constructor, before any thread starts.
//
// Threads: a Runtime is used by one thread (the caller), but request_stop() (any thread). run() and step() block until
// their answer is ready; go() and hold() do not wait, and wait_held() waits at most as long as it is told.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/device_hub.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/frame_source.hpp"
#include "cellwright/runtime/image_processing.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/plant.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "cellwright/runtime/sensors.hpp"
#include "cellwright/runtime/task_control.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

// Program labels -> cell names, as the scenario gives them. `where` is the scenario entry, for error messages.
struct Binding {
  struct Entry {
    std::string name;  // cell name
    SourceLocation where;
  };
  std::map<std::string, Entry> robots;   // every program robot label -> a cell robot (required)
  // workpiece/location/device label -> cell workpiece/location/device; absent: same name
  std::map<std::string, Entry> objects;
  SourceLocation where;                  // the scenario itself (for "robot r3 is not bound")
};

enum class Mode { kLockstep, kRealtime };

// Lock-step: which threads take the participants' turns. The order of the turns, hence the log, is the same either way.
enum class LockstepThreads {
  kShared,  // the simulation thread takes every turn: no thread switch between turns (the default)
  kOwn,     // each participant on a thread of its own, as in real time: every turn handed to another thread is a wake
};

// "lockstep", "realtime".
const char* to_string(Mode mode);


struct Limits {
  SimDuration sim_time = std::chrono::seconds(120);  // the run stops with kTimeout at this simulation time
  SimDuration settle{0};  // after the program finished, the simulation runs on this long (parts come to rest)
  // The run stops with kTimeout once it has run this long on the wall clock (0: no limit), checked every control
  // period; time parked between steps (Runtime::step) does not count. A guard for runs that take too long, so it
  // is the one limit that depends on the machine: a run it ends is not repeatable.
  std::chrono::steady_clock::duration wall_time{0};
};

// What an observer is shown: the simulation time, the transitions fired so far, task control's view of each robot
// as of its last step (the command it is on; empty unless the observer asked for it) and the environment model (the
// robots' joints, the parts: copy what you need in a short read(), as robot control writes it meanwhile).
struct Observation {
  SimDuration time{0};
  std::uint64_t firings = 0;
  const std::vector<RobotView>& robots;  // task.robots
  const SharedEnvironment& environment;
  // With RunObserver::robots: task control's view after its last step (marking, last firings, robots), and robot
  // control's view of each robot of this process after its last step (program order, remote robots left out), as
  // StepState has them; empty otherwise.
  const TaskView& task;
  const std::vector<RobotControlView>& controls;
};

// A watcher of the run (`twin run`'s progress line, a video): called by the simulation thread at each multiple of
// `every` of simulation time (in the first period that reaches it, after the plant has advanced and the period's
// events are logged). It must not change the plant or call the Runtime; it may block (a video encoder that is
// behind), and the time it takes does not count towards limits.wall_time, so that a run ends where it would without
// it and the event log is the same. Not called when `every` is zero.
struct RunObserver {
  SimDuration every{0};
  bool robots = false;  // wants Observation::robots, task and controls (the views are copied after each step)
  std::function<void(const Observation&)> observe;
};

// What a link knows of its agent (RemoteLink::state), as of the moment it is asked.
struct LinkState {
  bool present = true;        // an agent is there: it said it is ready and its liveliness holds
  std::uint64_t session = 0;  // which agent process it is or was last (a new process for the robot: a new number)
  std::uint64_t losses = 0;   // how many times this robot's agent was lost so far (gone, or replaced by a new one)
  std::string lost_detail;    // how the last loss was noticed ("" before any)
  int in_flight = -1;         // the primitive of the command sent to the agent and not answered, -1 none
  std::string holding;        // the workpiece the arm holds as far as the link knows ("" none): a close on it was
                              // answered done, or is in flight, with no open answered since
};

// The carrier of a robot whose robot control runs in another process (an agent: docs/distributed.md; the DDS one is
// distributed::RemoteRobot). The runtime knows only this: it hands the robot's command queue and the status queue to
// RunConfig::attach_remote, starts the link as the run starts and stops it as the run ends (main thread both), and,
// in between, asks its state every control period on the remote robot's own thread (the link's watcher,
// remote_watch.hpp): a lost agent is a `link_lost` fault of its robot, diagnosed by the decision tree.
class RemoteLink {
 public:
  virtual ~RemoteLink() = default;
  virtual void start() = 0;
  virtual void stop() = 0;
  // Any thread. A link that cannot tell says its agent is always present.
  virtual LinkState state() const { return {}; }
  // Sends the command in flight again (to the agent that took over after a loss). false: none in flight, or no agent.
  virtual bool resend() { return false; }
  // Called once, right after the link is made (main thread, before start()): the run's environment model and event
  // log, which the remote robot control writes into in its own process. A link that carries those writes (the DDS
  // one: the robot's environment-model updates and its events) applies them here, from its own threads (both are
  // thread-safe). The default carries nothing.
  virtual void share(SharedEnvironment& environment, EventLog& log) {
    (void)environment;
    (void)log;
  }

  // LOCK-STEP (docs/distributed.md, "Lock-step with agents"). Whether the link carries the robot's turns: a lock-step
  // run refuses a remote robot whose link does not (InputError naming it). The default carries none.
  virtual bool takes_turns() const { return false; }
  // Lock-step, in the robot's turn, on the thread taking it: the remote robot control's step at `now`, returning when
  // it is over, as RobotControl::step would in this process. Meanwhile the link takes the commands task control put
  // into the robot's command queue, answers the remote robot control's calls of its driver on `driver` (the robot's
  // driver in this process: the twin's), and when the step is over logs its events into the log share() gave, pushes
  // its statuses into the status queue and writes the environment model as it left it. When its agent is lost (gone,
  // silent, or answering what cannot be taken) it returns with state() saying so (not present, a loss counted, the
  // command in flight): the runtime's watch makes that a link_lost fault in the same turn (remote_watch.hpp), and
  // later turns do nothing (no new agent can take over: the robot control's state went with it). Throws InternalError
  // when the remote robot control itself failed (a bug). Only called by links that take turns.
  virtual void take_turn(SimDuration now, drivers::RobotDriver& driver) {
    (void)now;
    (void)driver;
    CW_CHECK(false, "a link that takes no turns was given one");
  }
};

// Makes the link of program robot `index` (cell robot `cell`) over its command queue and the status queue, which
// outlive the link. May throw InputError (the agent is not there).
using AttachRemote = std::function<std::unique_ptr<RemoteLink>(std::size_t index, const std::string& cell,
                                                               MessageQueue<MotionCommand>& commands,
                                                               MessageQueue<RobotStatus>& statuses)>;

struct RunConfig {
  task::CompiledProgram program;  // compiled and checked
  petri::Net net;                 // task::to_net(program)
  models::CellDescription cell;
  Binding binding;
  // The driver of each cell robot the program uses, by cell robot name. Not owned: the drivers (and the plant that
  // advances them) must outlive the Runtime.
  std::map<std::string, drivers::RobotDriver*> drivers;
  // Cell robots whose robot control runs in another process (an agent): this process builds no RobotControl and needs
  // no driver for them in real time; `attach_remote` carries their queues. In lock-step their links must take turns
  // (RemoteLink::takes_turns; InputError naming the robot otherwise) and `drivers` must have their drivers (the twin's:
  // the agent's robot control calls them through the link in its turns; the runtime connects and halts them as it
  // would a local robot's). What their robot control writes into its environment model and logs reaches this
  // process's model and log only as their link carries it (RemoteLink::share, take_turn; docs/distributed.md).
  std::vector<std::string> remote_robots;
  AttachRemote attach_remote;
  // A remote robot whose agent is lost with work in hand (a `link_lost` fault, remote_watch.hpp) and whose diagnosis
  // is to recover (the standard tree's reset_rehome) waits this long for a new agent before the cell is stopped. 0
  // (the default): the cell is stopped at once, the other robots halted.
  SimDuration rejoin_wait{0};
  // The simulation the simulation thread steps; not owned. nullptr for a cell with no simulation (every robot on a
  // driver that runs by itself, e.g. a serial controller): the first thread then keeps the clock and reads the sensors.
  Plant* plant = nullptr;
  // The sensors the rig wires (sensors.hpp; not owned, they must outlive the Runtime): a simulated plant's (the
  // ScriptedPlant's or the twin's TruthSensors), a real robot's driver's (DriverGripSensor), or none. A robot with no
  // grip sensor has its closes taken as done; with no part sensor the model keeps what it knows of the parts (or
  // what vision tells it). Every name must be a cell robot's (InternalError otherwise).
  Sensors sensors;
  // Where the model's knowledge of the workpieces comes from (environment_model.hpp). kVision needs `vision` and
  // `detector`.
  Perception perception = Perception::kTruth;
  std::optional<VisionOptions> vision;
  std::shared_ptr<const PartDetector> detector;  // for the vision camera
  // Where vision's frames come from (frame_source.hpp: a real camera or a recording of one); not owned, it must
  // outlive the Runtime. Unset: the plant renders the vision camera (Plant::capture).
  FrameSource* camera = nullptr;
  // Called on the image-processing thread after each frame (e.g. to save it). Must not call the Runtime.
  std::function<void(const VisionFrame&)> on_frame;
  // Without vision perception (ignored with it): the camera and period of plain frames, captured by the simulation
  // thread and handed to on_frame there, with no sightings and no predictions (twin run --save-frames without vision).
  // Capturing tells the controller nothing: the event log is the same with and without. Needs a plant.
  std::optional<VisionOptions> camera_frames;
  Mode mode = Mode::kLockstep;
  SimDuration period = std::chrono::milliseconds(10);  // control period: one lock-step round
  double realtime_speed = 1.0;                         // real-time mode: simulation time per wall time
  LockstepThreads lockstep_threads = LockstepThreads::kShared;
  // Lock-step: pass over participants with nothing to do (image processing without a frame, task control without a
  // status; see the top). false gives every participant every turn, as before, for comparisons: the log is the same.
  bool lockstep_skip_idle = true;
  Limits limits;
  MotionOptions motion;
  std::ostream* log_stream = nullptr;  // the event log is also written here (JSONL), if set
  // false: the log keeps no lines in memory, only log_stream has them (needs log_stream): a long shift's memory stays
  // flat, and log().text() is not available.
  bool keep_log = true;
  // Who watches the run as it goes (a progress line, a video): the runtime calls each observer and knows nothing of
  // what it does (RunObserver below).
  std::vector<RunObserver> observers;
  // Who is handed each event of the log as a typed value as it is logged (EventLog::add_observer: on the thread that
  // logs, in log order, under the log's lock: each must be quick and must not call the Runtime or log).
  std::vector<std::function<void(const LogEvent&)>> event_observers;
  // The cell's I/O units and the devices wired on each (device_hub.hpp; the DigitalIo objects are not owned and must
  // outlive the Runtime): the twin's I/O image for simulated devices, a Modbus TCP unit for real ones. Every device
  // the program declares must be on one. Device limits left 0 are set from the cell and `motion.recovery`.
  std::vector<IoUnit> io_units;
  // Where a fired signal goes on its way to its event (task_control.hpp's SignalFilter): called by task control for
  // every signal it fires; false drops the event. Unset: every event is delivered.
  SignalFilter signal_filter;
  // Task control fires these transitions, in this order, and nothing else (TaskControl::follow: a counterexample's
  // replay, `twin serve`). Empty: the usual choice.
  std::vector<petri::TransitionId> firing_order;
};

// The program's labels bound to cell names as the Runtime binds them (its robots, workpieces, locations and workpiece
// classes; not the devices' machines), checked as the Runtime's constructor checks them: InputError for a robot with no
// binding, a binding to nothing in the cell, a robot that is neither remote nor on a driver. For a robot control built
// outside a Runtime (a robot's agent, docs/distributed.md).
NameMap resolve_names(const RunConfig& config);

enum class Outcome { kFinished, kFailed, kTimeout, kStopped };

// "finished", "failed", "timeout", "stopped" (the cell was stopped safely: recovery found nothing else to do).
const char* to_string(Outcome outcome);

struct RobotTime {
  std::string robot;  // program label
  std::string cell;   // cell robot name
  ActivityTime time;  // adds up to RunResult::end_time
};

// What taking turns cost in a lock-step run (all zero in real time).
struct LockstepStats {
  std::uint64_t rounds = 0;    // control periods
  std::uint64_t turns = 0;     // turns taken, all participants together
  std::uint64_t skipped = 0;   // turns passed over: a participant asleep with nothing to do
  std::uint64_t handoffs = 0;  // turns handed to another thread: each a wake of that thread and a thread switch
  std::uint64_t pauses = 0;    // stepping (Runtime::step): the simulation thread parked and handed back to the caller
};

struct RunResult {
  Outcome outcome = Outcome::kTimeout;
  std::string reason;                      // kFailed/kTimeout: why; kFinished: ""
  SimDuration end_time{0};                 // simulation time when the run stopped
  std::optional<SimDuration> finished_at;  // when the program reached its final marking
  petri::Marking final_marking;
  std::uint64_t firings = 0;
  std::vector<RobotTime> robots;      // program order
  std::vector<Collision> collisions;  // every collision logged, in order
  EnvironmentModel environment;       // the environment model at the end
  LockstepStats lockstep;
};

// The state `twin step` shows after each step.
struct StepState {
  bool ended = false;  // the run is over (then `result` is set)
  SimDuration time{0};
  TaskView task;                         // marking, last firings, per-robot activity as task control sees it
  std::vector<RobotControlView> robots;  // per robot: its command and phase as robot control sees it
  std::optional<RunResult> result;
};

// Where a real-time run let go holds again (Runtime::go): the first control period that starts after a transition
// fired (`firing`), or at or after simulation time `time`, whichever comes first. Neither: it runs to its end.
struct HoldAt {
  bool firing = false;
  std::optional<SimDuration> time;
};

class Runtime {
 public:
  // Checks the configuration (see the top) and builds the threads' objects; starts nothing, calls no driver.
  // Throws InputError for bad input, InternalError for an inconsistent config (no plant, net not of the program,
  // period not positive).
  explicit Runtime(RunConfig config);
  // Stops and joins any threads still running.
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

  // Connects the drivers (InputError when one cannot work), starts the threads if not started, runs to the end and
  // joins them. After step(), runs on from where stepping stopped. Returns the result (also after a run has ended:
  // the same result again).
  RunResult run();

  // Lock-step mode: runs until the next control period in which a transition fires,
  // or to the end, then returns with the threads parked, so that state and plant can be inspected. The first call
  // connects the drivers and starts the threads. With `until`: also returns at the first control period that starts
  // at or after that simulation time, if no transition fired before (`twin serve`'s run to a time).
  // Real-time mode: the same, as go({.firing = true, .time = until}) then wait_held() with no limit.
  StepState step(std::optional<SimDuration> until = std::nullopt);

  // Real-time mode only (InternalError otherwise; see HOLDING at the top). Lets the run go without waiting: the first
  // call connects the drivers and starts the threads (InputError as run()); later ones release a hold. It holds again
  // where `at` says, or when hold() asks. Nothing after the end.
  void go(HoldAt at = {});
  // Real-time mode only: asks a run that goes to hold at the start of the next control period. Does not wait
  // (wait_held() does). Nothing when it is held, has not started, or has ended.
  void hold();
  // Real-time mode only, after the first go(): waits at most `wait` for the run to be held or to end, and returns its
  // state then (as step()'s: held, the views are task and robot control's after their last step, but
  // task.last_fired is every transition fired since the last go(), at most the last 1000; ended, the threads are
  // joined and `result` is set), or nullopt if it still goes. While it is held, plant() may be read, until the
  // next go() or the Runtime's end.
  std::optional<StepState> wait_held(std::chrono::steady_clock::duration wait);

  // Any thread (e.g. one that caught SIGINT): asks the run to stop at the next control period, as a cell stopped
  // safely: the robots are halted, the outcome is kStopped with `reason`, and run()/step() return the result with the
  // log complete up to then. Does nothing after the end.
  void request_stop(const std::string& reason);

  // Before the run starts (InternalError after): how lock-step turns are taken (RunConfig::lockstep_threads and
  // lockstep_skip_idle), for a caller that did not build the config itself (a ScenarioRun), e.g. to compare them.
  void set_lockstep(LockstepThreads threads, bool skip_idle);

  // The event log (complete once run() has returned).
  const EventLog& log() const { return *log_; }
  // The same log, for the rig to write its own events into (the faults it injects, docs/faults.md), from the threads
  // the run calls it on (the plant's advance() on the simulation thread, a signal filter on task control's), so that
  // their order is fixed in lock-step. EventLog's members are thread-safe.
  EventLog& log() { return *log_; }
  // The plant, for snapshots: only between steps, while held, or after the run (the simulation thread is parked or
  // gone).
  // InternalError for a run without one.
  Plant& plant() {
    CW_CHECK(config_.plant != nullptr, "this run has no plant");
    return *config_.plant;
  }
  const RunConfig& config() const { return config_; }

 private:
  // Connects the drivers, logs run_start and starts the threads.
  void start();
  // Joins the threads and builds the result (once); rethrows an exception a thread died of.
  RunResult finish();

  struct Impl;
  RunConfig config_;
  std::unique_ptr<EventLog> log_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::runtime
