// What a run did, told from its event log (runtime/event_log.hpp) and the workpieces' final poses: what the run used
// (perception, drivers, faults asked for), the robots' timelines (what the Gantt chart draws), per-robot
// busy/waiting/blocked/idle time, the devices' rows and figures (a machine's busy/done/idle time, utilisation, cycles
// and parts processed; a conveyor's running time; a sensor's on time), each workpiece's cycle time and final location against the expected outcome,
// throughput, collisions, the account of every workpiece (in place, elsewhere, held, lost, not arrived), each
// injected fault matched to its detection, diagnosis and recovery, the faults detected that no injection explains
// (unexplained faults) and the detections with nothing physically wrong (false alarms), and the verdict `twin run`
// exits with. docs/scenarios.md describes report.json field by field; docs/faults.md sections 5-6
// the account and the faults.
//
// Everything here is computed from values (the log's typed events, runtime/log_event.hpp, and the poses), so a report
// can be rebuilt from a saved events.jsonl read back through the log's one codec (runtime::decode_log, read_log), and
// tests feed it synthetic logs. A line of the log that the codec refuses (not JSON, an unknown type, a field missing
// or of the wrong type) is an InputError naming the file and the line: nothing here reads a field by its key.
//
// Thread safety: plain values and pure functions; any thread may call them.
#pragma once

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cstddef>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "cellwright/task/compiled.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// --- Timelines -------------------------------------------------------------------------------------------------------

// What a robot is doing during a bar of the Gantt chart.
enum class Activity {
  kMove,     // executing a move (from the firing that started it to the robot's report that it is done)
  kGrip,     // executing an open or close, likewise
  kWait,     // in a wait place: waiting for an event another robot signals
  kBlocked,  // its command is done but its next transition has not fired yet
  kPartWait,  // its move/open/close has started but waits for its part to arrive (a "waiting_for_part" sensor event
              // until the "part_ready" one): the robot stands still
};

// "move", "grip", "wait", "blocked", "part_wait".
const char* to_string(Activity a);

struct Bar {
  double start = 0, end = 0;  // s of simulation time, end >= start
  Activity activity = Activity::kMove;
  int primitive = -1;  // index in the robot's primitive program
  std::string label;   // the primitive ("move at(A)", "wait put9.r1>r2.ready") or, blocked, what it waits to start
  std::string task;    // the task-level command it belongs to ("Pick A")
};

// A moment of a workpiece's journey, marked on the row of the robot that did it.
enum class JourneyStep {
  kPicked,      // gripped by a Pick (the "gripped" sensor event of a close of a task "Pick ...")
  kHandedOver,  // let go by a Put to the robot that took it (the "released" sensor event of a "Put ...")
  kPlaced,      // let go by a Place (the "released" sensor event of a "Place ...")
};

// "picked", "handed over", "placed".
const char* to_string(JourneyStep s);

struct JourneyMark {
  double t = 0;  // s
  JourneyStep step = JourneyStep::kPicked;
  std::string workpiece;  // cell workpiece (as the sensor event names it)
};

struct RobotTimeline {
  std::string robot;      // program label
  std::string cell;       // cell robot name
  std::vector<Bar> bars;  // in time order, not overlapping
  std::vector<JourneyMark> marks;  // in time order
  // Seconds in each activity; idle is the rest of [0, Timeline::end] (before its first command, after its last).
  // waiting counts the wait and part_wait bars; waiting_for_part only the part_wait ones.
  double busy = 0, waiting = 0, blocked = 0, idle = 0, waiting_for_part = 0;
  std::size_t commands = 0;  // move/open/close commands started
};

// What a device of the cell is doing during a bar of its Gantt row, from the log's `device` events (a machine's,
// conveyor's or photo-eye's state as device control sees it through its I/O). The states with no bar are the gaps:
// a machine idle, a conveyor stopped, a sensor off.
enum class DeviceActivity {
  kBusy,     // a machine's cycle runs (state "busy")
  kDone,     // a machine's cycle is over and its part waits to be taken out (state "done")
  kRunning,  // a conveyor's run coil is on (state "running")
  kOn,       // a sensor's input is on (state "on")
};

// "busy", "done", "running", "on".
const char* to_string(DeviceActivity a);

struct DeviceBar {
  double start = 0, end = 0;  // s, end > start
  DeviceActivity activity = DeviceActivity::kBusy;
  std::string workpiece;  // a machine's part in it (the controller's model), "" none; "" for other devices
};

// A device's row and its figures. Before its first event a device counts as in its resting state (idle, stopped,
// off); a span still open at the run's end lasts to the end (a run that stops with the mill busy shows it busy to
// the end, its part not processed).
struct DeviceTimeline {
  std::string device;  // the cell's device name
  std::string kind;    // "machine" | "conveyor" | "sensor"
  std::vector<DeviceBar> bars;  // in time order, not overlapping
  std::string state;      // its state at the end (the last event's)
  std::string workpiece;  // a machine's part at the end, "" none
  // Machine: seconds busy, done (its processed part waiting to be taken out) and idle (the run minus both); busy
  // over the run (0 for a run of no length); cycles started (each change into busy) and finished (each change from
  // busy to done); the parts processed, in order: a part counts only when the machine went from busy to done with
  // it in (the done event's part, else the busy one's).
  double busy = 0, done = 0, idle = 0, utilisation = 0;
  std::size_t cycles_started = 0, cycles_finished = 0;
  std::vector<std::string> processed;
  // Conveyor: seconds running and stopped (the run minus running). Sensor: seconds on and off.
  double running = 0, stopped = 0, on = 0, off = 0;
  std::size_t starts = 0;  // conveyor: times it started running; sensor: times it came on
};

struct Timeline {
  double end = 0;                     // s: the run's end (run_end), else the last event's time
  std::vector<RobotTimeline> robots;  // in the order of run_start's robots (program order)
  std::vector<DeviceTimeline> devices;  // in the order of their first `device` event; none in a log without them
};

// Builds the robots' timelines from the events of a run of `program`. A primitive k of robot r spans the time from
// the firing of r's transition k (it starts the primitive) to the firing of transition k+1 (or the run's end): a
// move/open/close is a move/grip bar up to its command_end and blocked after it; a wait is a wait bar; a signal takes
// no time (a blocked bar if its next transition fired later). A move/open/close during which the robot control logged
// "waiting_for_part" is a part_wait bar up to its "part_ready" sensor event (or, without one, up to its command_end or
// the visit's end: the command ended or the run stopped before the part came) and a move/grip bar after it. The
// journey marks come from the "gripped" and "released" sensor events of Pick, Put and Place commands. The devices'
// rows come from the `device` events (DeviceTimeline). Throws InputError naming `file` and the event's line when the
// events contradict the program (an unknown robot or primitive), lack run_start, or have a fire or command event
// before it, or when a device event has a kind other than machine, conveyor or sensor, a state its kind does not
// have, or another kind than the device's first event.
Timeline build_timeline(const std::vector<runtime::LoggedEvent>& events, const task::CompiledProgram& program,
                        const std::string& file = "events.jsonl");

// One device's figures on one line, for the summary and the page: "mill (machine): busy 4.00 s (40 %), done waiting
// 1.00 s, idle 5.00 s; cycles 1 started, 1 finished; processed A", with "; busy at the end with B (not processed)"
// for a machine still busy when the run ended; a conveyor's running and stopped time, a sensor's on and off time,
// with their share of the run (`end`, s), how often each started or came on, and its state at the end.
std::string describe_device(const DeviceTimeline& device, double end);

// --- Where workpieces ended up ---------------------------------------------------------------------------------------

// A workpiece's state at the end of a run (from the runtime's environment model).
struct FinalPose {
  std::string name;                                        // cell workpiece
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // the part's centre, world
  bool present = true;                                     // false: never fed, or carried out of the cell
  std::string held_by;                                     // cell robot holding it, "" if none
};

// The cell's workpieces as the controller's environment model has them (a run with no twin: real_run.hpp): where it
// believes each part is, present or not, and which robot it believes holds it.
std::vector<FinalPose> final_poses_of(const runtime::EnvironmentModel& model);

// The named places a workpiece is at, most specific first: cell locations whose point its bottom centre is within
// `tolerance` of; the conveyor whose belt it rests on (bottom within `tolerance` of the belt's top, centre over the
// belt); the machine it rests on (its fixture or its top, likewise); "held by <robot>"; "floor" (bottom within
// `tolerance` of z = 0); "not in the cell" when it is not present. Empty when it is none of these (in the air,
// on another part, ...).
std::vector<std::string> places_of(const models::CellDescription& cell, const models::WorkpieceSpec& spec,
                                   const FinalPose& final, double tolerance);

// --- What the run used ------------------------------------------------------------------------------------------------

// The driver one program robot ran on.
struct DriverUse {
  std::string robot;  // cell robot
  std::string kind;   // "sim", "movemaster", "val2", "agent" (its robot control in another process: twin agent)
  std::string port;   // the serial port of a real driver; "" for sim; an agent's "DDS domain N"
  // A real driver whose port is a pseudo-terminal (what `twin emulate` publishes): an emulated controller, no arm.
  bool emulated = false;
  bool real() const { return kind != "sim"; }
};

// The run's effective settings (the scenario's, with the command line's overrides), carried into the report so that
// it says what the run used, not what the scenario file says.
struct RunSetup {
  std::string perception = "truth";  // "truth", "vision", "cad"
  std::vector<DriverUse> drivers;    // one per program robot, in program order
  std::vector<std::string> faults;   // the faults asked for (`--fault` text, faults.hpp to_text), in scenario order
  // The run has a twin whose physics is the truth of its simulated robots (a `twin run`): a detection of a simulated
  // robot is judged against the twin's `physical` events. false: no twin truth (every detection that no injection
  // explains is an unexplained fault).
  bool twin_truth = true;
  // Where the parts' final places come from: false, the twin's truth (where they physically are in the simulation);
  // true, the controller's environment model at the end (a run of real robots without the twin, real_run.hpp: where
  // the controller believes them, after its own commands, nothing having seen them). The report, its page and its
  // summary say which; report.json has "parts_from": "controller_model" for the latter (and no such key for the twin's
  // truth, so that a simulated run's report.json is unchanged).
  bool parts_from_model = false;
};

// The setup of a run of `scenario` as its file and bindings say: its perception, each program robot's driver (a
// real driver's port a pseudo-terminal: emulated), its faults, with a twin.
RunSetup setup_of(const Scenario& scenario);

// What the page and the summary say of where the parts' places come from: "the twin" or "the controller's model (no
// twin: nothing sensed where the parts are)".
std::string describe_parts_source(const RunSetup& setup);

// One driver for a person: "puma simulated", "melfa real movemaster on /dev/ttyUSB0", "melfa emulated movemaster on
// /tmp/melfa".
std::string describe_driver(const DriverUse& driver);

// --- The report ------------------------------------------------------------------------------------------------------

// What became of a workpiece (docs/faults.md section 5): where it physically is. A controller's declaration that it is
// lost is kept beside (WorkpieceReport::lost) and never overrides a physical state.
enum class PartStatus {
  kInPlace,     // where the scenario expects it (declared lost or not)
  kElsewhere,   // present, not where expected (or nothing is expected of it): where it is
  kHeld,        // held by a robot at the end (declared lost or not)
  kLost,        // declared lost by the controller (a workpiece_lost event names it), and neither held, in place, nor
                // never present
  kNotArrived,  // never present in the cell: a fed part never fed, a part taken out before the start
  kScrapped,    // reserved: nothing sets it yet
};

// "in_place", "elsewhere", "held", "lost", "not_arrived", "scrapped".
const char* to_string(PartStatus s);

// A workpiece_lost event: when the controller declared the part lost, why, and where it was last seen.
struct LostPart {
  double t = 0;
  std::string reason;
  std::optional<Eigen::Vector3d> last_seen;  // world, m; nullopt when it was never seen
};

struct WorkpieceReport {
  std::string name;                                    // cell workpiece
  std::string label;                                   // program label bound to it, "" if the program does not use it
  std::string final_location;                          // places_of()'s first, else "elsewhere"
  std::vector<std::string> at;                         // everything places_of() found
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // centre, world
  std::optional<std::string> expected;                 // the scenario's expectation, if any
  double tolerance = 0;                                // the one used for `at`
  std::optional<bool> ok;                              // expected is among `at`; nullopt without an expectation
  std::optional<double> pick_start;                    // the first command_start of a Pick of it
  std::optional<double> place_end;   // the end of the last Place that released it (its depart included)
  // It reached its final place: with an expectation, the expectation holds (never for one expected lost); without,
  // a Place released it last, it was not declared lost, and it rests in the cell at a named place (`at` not empty),
  // held by no robot. Picked and placed (pick_start, place_end) either way.
  bool completed = false;
  std::optional<double> cycle_time;  // place_end - pick_start, for a completed part only
  // The account (docs/faults.md section 5).
  PartStatus status = PartStatus::kElsewhere;
  std::string where;             // in_place: the expected place; held: the robot (cell name); otherwise
                                 // final_location ("not in the cell" when not present)
  std::optional<LostPart> lost;  // set when a workpiece_lost event names it (the first such event)
  bool arrived = false;          // a workpiece_arrived event names it
  // Not where it should be (it has an expectation that does not hold) and not declared lost or not arrived by the
  // controller (no workpiece_lost event names it), unless the scenario expects it lost.
  bool unaccounted = false;
};

// One injected fault (a fault_injected event) and what the controller made of it (docs/faults.md section 5).
struct FaultReport {
  std::string kind;       // "drop", "timeout", ...
  double t = 0;           // s: when it was injected
  std::string robot;      // cell robot, "" none
  std::string workpiece;  // cell workpiece, "" none
  std::string detail;
  // The first fault_detected at or after the injection not matched to an earlier fault, of the same robot when both
  // name one (or of the same robot up to two control periods before it: see make_report).
  bool detected = false;
  std::optional<double> detected_at;
  std::string detected_by;  // the detection's robot (program label, "" for the cell)
  std::string symptom;
  // The first diagnosis of that robot after the detection, and the first recovery_end after the diagnosis.
  std::string cause, action;
  // A recovery_end with ok true followed, and the cell was not stopped before it.
  bool recovered = false;
  std::optional<double> recovery_time;  // s: that recovery_end's t minus the injection's t
  // The run ended "stopped" (cell_stopped) after the injection.
  bool stopped_safely = false;
};

// A fault_detected event that no injection took, with what the controller made of it.
struct Detection {
  double t = 0;
  std::string robot;  // program label, "" for the cell: who detected it
  int primitive = -1;
  std::string symptom;
  std::string detail;
  // The first diagnosis of that robot after it, and the first recovery_end of that robot after the diagnosis.
  std::string cause, action;
  bool recovered = false;  // that recovery_end has ok true and came before the cell was stopped
  // Why it is a false alarm (what the twin's truth showed), "" for an unexplained fault.
  std::string truth;
};

// One segment of a coordinated block as the two robots ran it (docs/task-language.md, "Coordinated motion"): when
// each started its command (command_start) and ended it (command_end), and the skews between them.
struct SegmentTiming {
  std::string block;       // the coordinated block's name
  int index = 0;           // 1-based, in the block's order
  std::size_t run = 0;     // which execution of the segment (0 the first; a block in a loop runs again)
  std::string command;     // the master's primitive as written ("move above(FIX)")
  std::string master, follower;  // program labels
  double master_start = 0, follower_start = 0;
  std::optional<double> master_end, follower_end;  // nullopt when a command did not end (the run stopped)
  double start_skew = 0;                           // s: |master_start - follower_start|
  std::optional<double> end_skew;                  // s: |master_end - follower_end| when both ended
};

// A coordinated carry as the twin measured it (the `carry` events, docs/runtime.md "Coordinated blocks"): the
// samples of one workpiece held by the same two robots, period after period (a gap of more than 0.05 s, or other
// robots, begins another carry).
struct CarryReport {
  std::string workpiece;  // cell workpiece
  std::string a, b;       // cell robots (the cell's order)
  double start = 0, end = 0;  // s: the first and the last sample
  std::size_t samples = 0;
  double peak_squeeze = 0;    // N: the internal force of the largest magnitude (> 0 pushing, < 0 pulling)
  double peak_squeeze_t = 0;  // s
  double max_error = 0;       // mm: the largest relative tool error
  double max_error_t = 0;     // s
  double max_turn = 0;        // degrees: the largest relative turn
  double max_tilt = 0;        // degrees: the largest tilt of the workpiece's long axis from horizontal
  double max_tilt_t = 0;      // s
  bool operator==(const CarryReport&) const = default;
};

struct Report {
  RunSetup setup;                   // what the run used
  std::string outcome = "timeout";  // run_end's outcome: "finished", "failed", "timeout", "stopped"; "unfinished"
                                    // when the log has no run_end
  std::string reason;                          // run_end's reason
  double end_time = 0;                         // s
  std::optional<double> finished_at;           // s: when the program reached its final marking (the last firing)
  std::optional<double> estimated_cycle_time;  // s, from the estimate (estimate.hpp)
  std::uint64_t firings = 0;
  std::vector<WorkpieceReport> workpieces;  // cell order
  // parts per minute: completed parts / (last place end - first pick start) of the completed parts
  std::optional<double> throughput;
  std::size_t parts_completed = 0;  // workpieces completed (WorkpieceReport::completed)
  // The flow of parts, for programs with loops and shifts (feed count): a part is placed when a command of a "Place"
  // releases it (its open ends) and it is not picked again before it leaves the cell or is fed anew (the Place of a
  // relay that another robot picks from is no placement), fed when it arrives on the feed's conveyor, delivered when
  // it leaves the cell.
  std::vector<double> placed_at;  // s, in order
  std::size_t parts_fed = 0;
  std::size_t parts_delivered = 0;
  // Steady state: the first placement is left out (it includes the first part's arrival and the filling of the
  // pipeline); from the second to the last placement, parts per minute and seconds per part. Needs 3 placements.
  std::optional<double> steady_throughput;
  std::optional<double> steady_cycle;
  Timeline timeline;
  struct CollisionEntry {
    double t = 0;
    std::string a, b;
    double depth = 0;
  };
  std::vector<CollisionEntry> collisions;
  std::vector<CarryReport> carries;  // coordinated carries, in the order they began
  std::optional<double> stopped_at;  // s: the cell_stopped event (else run_end) of a run that ended "stopped"
  std::vector<FaultReport> faults;    // one per fault_injected event, in log order
  // fault_detected events not matched, with no fault_injected before them: a false alarm when the twin's truth shows
  // nothing physically wrong (make_report), else an unexplained fault. In log order.
  std::vector<Detection> unexplained;
  std::vector<Detection> false_alarms;
  std::vector<std::string> failures;    // why the run is not ok, one line each; empty when ok
  // Coordinated blocks: every segment both robots started, in the order the master started them, and the largest
  // skews over them (nullopt without segments; the end skew over the segments both robots ended).
  std::vector<SegmentTiming> segments;
  std::optional<double> max_start_skew, max_end_skew;

  // The run finished and every expected outcome holds (a lost part counts against it unless expected lost).
  bool ok() const { return failures.empty(); }
  // How many workpieces are unaccounted.
  std::size_t unaccounted() const;
};

// Builds the report of a run of `scenario` from its event log, the final poses of the cell's workpieces and the
// estimate made before the run (if any). Failures: the run did not finish (outcome and reason; "stopped": the cell
// was stopped), an expected workpiece is not where it should be (where it is instead), an expected workpiece has no
// final pose, a workpiece was declared lost that the scenario does not expect lost, a workpiece expected lost was
// not. Collisions and faults are reported, not counted as failures (an expectation decides what matters).
//
// The account, where each part physically is: one never present (not present and no workpiece_arrived event names
// it) is not_arrived; one held by a robot is held; one whose expectation holds is in_place; else one named by a
// workpiece_lost event is lost; the rest are elsewhere (a part that left the cell: "not in the cell"). A
// workpiece_lost event's entry is kept whatever the state. Workpieces and robots in the events may be named by their
// cell name or their program label.
//
// Faults: each fault_injected event, in log order, is matched to the first fault_detected in the log not yet matched
// that comes after it (same robot when both name one, else any) or, of the same robot, at most two control periods
// (run_start's period) before it: a driver's fault reaches the log a round after the controller saw the command fail.
// Then the first diagnosis of the detecting robot after the detection, and the first recovery_end of that robot after
// the diagnosis. A detection that no injection took and with no fault_injected before it is a false alarm only when
// the twin's truth shows nothing physically wrong: the setup has twin truth, the detecting robot is simulated (not a
// real or emulated driver, not the cell), and the first `physical` event at or after it refutes its symptom
// (grip_lost, closed_on_nothing: the robot holds a part; obstacle_seen: the safety sensor sees nothing); every other
// such detection is an unexplained fault (a driver's fault, a lost link, a timeout are always real). `setup`: what
// the run used (setup_of(scenario) when nullopt). Throws InputError as build_timeline.
Report make_report(const Scenario& scenario, const std::vector<runtime::LoggedEvent>& events,
                   const std::vector<FinalPose>& finals, std::optional<double> estimated_cycle_time,
                   const std::string& file = "events.jsonl", std::optional<RunSetup> setup = std::nullopt);
// The same from an events.jsonl read one line at a time (runtime::read_log; its errors name the file and line): what
// it holds grows with the parts, the faults and the chart's bars, not with the log, so a long shift's report never
// holds its log whole. Throws InputError also when the stream cannot be read.
Report make_report(const Scenario& scenario, std::istream& jsonl, const std::vector<FinalPose>& finals,
                   std::optional<double> estimated_cycle_time, const std::string& file = "events.jsonl",
                   std::optional<RunSetup> setup = std::nullopt);

// report.json (docs/scenarios.md). Times in seconds rounded to 4 decimals, so equal runs give equal bytes. "devices"
// (each device's figures, by kind) only when the log has device events: a run without them gives the report it gave.
nlohmann::json to_json(const Scenario& scenario, const Report& report);

// The summary printed at the end of `twin run`: the verdict, what the run used (perception, drivers, faults asked
// for), estimated vs measured cycle time, throughput, each expectation that failed and why, the account of the parts
// that are not in place, collisions, the injected faults and what became of them, the unexplained faults with their
// diagnosis, false alarms; after the robots' times, a line per device (describe_device). Ends with a newline.
std::string format_summary(const Report& report);

}  // namespace cellwright::cell
