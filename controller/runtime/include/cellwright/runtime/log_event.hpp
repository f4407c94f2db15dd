// The run's events as typed values, and their one JSON Lines codec. The runtime logs these values (EventLog builds
// one per event and encodes it); whoever reads a log back (the report, the Gantt chart, the page, tests) decodes
// each line into the same value and works with its fields, never with JSON keys. A line is an event's fields and
// nothing else, so encode(decode(line)) gives the line back, byte for byte.
//
// THE VALUES. One struct per event type, named after it (run_start: RunStart), with exactly the fields its line has,
// in its order; LogEvent is the variant of them all. Every event has `t`, the simulation time it happened. Field
// meanings (program label vs cell name, "" for none, -1 for no primitive) are listed with each struct; what the events
// mean to a run is in docs/runtime.md ("The event log").
//
// THE BYTES. encode() writes one JSON object on one line (no newline), fixed by the value alone, so two lock-step runs
// that log the same values give byte-identical logs:
//  - keys in a fixed order: "t", "type", then the struct's fields in declaration order (nested lists of objects
//    likewise);
//  - times (t, period, frame, duration) in seconds with exactly 4 decimals, rounded half away from zero on the
//    nanosecond count (format_sim_time);
//  - lengths with fixed decimals: a collision's depth 6 decimals, positions (x, y, z) 4 decimals; a vision sighting's
//    yaw in degrees with 2 decimals (radians in the value) and its confidence with 3; a number that prints as zero is
//    written without a minus sign; a missing position or yaw is null;
//  - counts and indices as integers, flags as true/false, strings JSON-escaped (invalid UTF-8 replaced by U+FFFD).
// A time or length finer than its decimals is rounded: decoding gives the value as written (a time on the 0.1 ms grid),
// which encodes to the same bytes again.
//
// READING BACK. decode() reads one line; decode_log() and read_log() a whole log (blank lines skipped). Every field
// of the event's type is required and must have its type: a missing key, a number where a string belongs, a
// negative count, a fraction where an integer belongs, a position with some coordinates null, an unknown "type" or
// a line that is not a JSON object is an InputError naming the file, the line and the key ("events.jsonl:12: error:
// command_end event has no \"ok\""). Keys a type does not have are ignored. Reading is linear in the log's size.
//
// Thread safety: plain values and pure functions; any thread may call them.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "cellwright/runtime/clock.hpp"

namespace cellwright::runtime {

namespace events {

// A program robot and the cell robot bound to it (run_start).
struct RobotName {
  std::string robot;  // program label
  std::string cell;   // cell robot name
  bool operator==(const RobotName&) const = default;
};

// The run began: what runs, where, how, and the program's robots.
struct RunStart {
  static constexpr std::string_view kType = "run_start";
  SimDuration t{0};
  std::string program;            // the program's file
  std::string cell;               // the cell's name
  std::string mode;               // "lockstep" | "realtime"
  SimDuration period{0};          // the control period
  std::vector<RobotName> robots;  // program order
  bool operator==(const RunStart&) const = default;
};

// Task control fired a transition.
struct Fire {
  static constexpr std::string_view kType = "fire";
  SimDuration t{0};
  std::string transition;  // its id ("r1.t3", "r1.again12")
  std::string robot;       // program label, "" for a transition of no robot
  int primitive = -1;      // the primitive it starts, -1 none
  int line = 0;            // the program line
  std::string task;        // the task-level command ("Pick A"), "" none
  std::string motion;      // the motion it belongs to, "" none
  bool operator==(const Fire&) const = default;
};

// A robot's primitive command started.
struct CommandStart {
  static constexpr std::string_view kType = "command_start";
  SimDuration t{0};
  std::string robot;          // program label
  std::size_t primitive = 0;  // index in the robot's program
  std::string command;        // the primitive as written ("move at(A)")
  std::string task;
  std::string motion;
  std::string detail;  // what was sent to the driver (drivers::describe()), "" when nothing was sent yet
  bool operator==(const CommandStart&) const = default;
};

// ... and ended.
struct CommandEnd {
  static constexpr std::string_view kType = "command_end";
  SimDuration t{0};
  std::string robot;
  std::size_t primitive = 0;
  std::string command;
  bool ok = false;
  std::string reason;  // "" when ok
  bool operator==(const CommandEnd&) const = default;
};

// What robot control sensed about its command.
struct Sensor {
  static constexpr std::string_view kType = "sensor";
  SimDuration t{0};
  std::string robot;
  std::size_t primitive = 0;
  // "gripped" | "closed_on_nothing" | "closed_on_wrong_part" | "grip_not_sensed" | "released" | "position_reached" |
  // "position_missed" | "waiting_for_part" | "part_ready" | "bound" (a workpiece class of the command now means this
  // part)
  std::string condition;
  std::string workpiece;  // "" if none
  bool operator==(const Sensor&) const = default;
};

// Two bodies of the cell touched.
struct Collision {
  static constexpr std::string_view kType = "collision";
  SimDuration t{0};
  std::string a, b;  // the bodies
  double depth = 0;  // penetration, m (>= 0)
  bool operator==(const Collision&) const = default;
};

// A part came into the cell (fed on a conveyor, or there at the start).
struct WorkpieceArrived {
  static constexpr std::string_view kType = "workpiece_arrived";
  SimDuration t{0};
  std::string workpiece;
  std::string where;
  bool operator==(const WorkpieceArrived&) const = default;
};

// A part left the cell, delivered: carried off the end of a conveyor.
struct WorkpieceLeft {
  static constexpr std::string_view kType = "workpiece_left";
  SimDuration t{0};
  std::string workpiece;
  std::string where;  // the conveyor
  bool operator==(const WorkpieceLeft&) const = default;
};

// One part the vision system saw in a frame.
struct Seen {
  std::string workpiece;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // its centre, world, m
  std::optional<double> yaw;                           // radians; none for a cylinder
  double confidence = 0;
  bool operator==(const Seen&) const = default;
};

// One camera frame processed by the image-processing thread.
struct Vision {
  static constexpr std::string_view kType = "vision";
  SimDuration t{0};
  SimDuration frame{0};  // when the frame was taken
  std::vector<Seen> seen;
  std::vector<std::string> not_seen;  // parts expected in view and not found
  std::size_t rejected = 0;           // blobs rejected
  std::string problem;                // what made the frame unusable, "" if none
  bool operator==(const Vision&) const = default;
};

// A fault the plant or the runtime injected on purpose (docs/faults.md): for the report's accounting, never read by
// the controller.
struct FaultInjected {
  static constexpr std::string_view kType = "fault_injected";
  SimDuration t{0};
  std::string kind;       // "drop", "timeout", ...
  std::string robot;      // cell robot name, "" none
  std::string workpiece;  // cell workpiece, "" none
  std::string detail;
  bool operator==(const FaultInjected&) const = default;
};

// Something the controller sensed went wrong.
struct FaultDetected {
  static constexpr std::string_view kType = "fault_detected";
  SimDuration t{0};
  std::string robot;   // program label, "" for the cell
  int primitive = -1;  // -1 none
  std::string symptom;
  std::string detail;
  bool operator==(const FaultDetected&) const = default;
};

// The decision tree's answers for a detection.
struct Diagnosis {
  static constexpr std::string_view kType = "diagnosis";
  SimDuration t{0};
  std::string robot;
  std::string symptom;
  std::string cause;
  std::string action;
  std::string path;  // the questions and answers, "part_seen=yes part_at_rest=no"
  bool operator==(const Diagnosis&) const = default;
};

// A recovery ended.
struct RecoveryEnd {
  static constexpr std::string_view kType = "recovery_end";
  SimDuration t{0};
  std::string robot;
  std::string cause;
  std::string action;
  bool ok = false;
  std::string detail;
  SimDuration duration{0};  // since its fault_detected
  bool operator==(const RecoveryEnd&) const = default;
};

// The safety layer stopped a robot ...
struct ProtectiveStop {
  static constexpr std::string_view kType = "protective_stop";
  SimDuration t{0};
  std::string robot;
  std::string reason;
  bool operator==(const ProtectiveStop&) const = default;
};

// ... and released it.
struct ProtectiveRelease {
  static constexpr std::string_view kType = "protective_release";
  SimDuration t{0};
  std::string robot;
  bool operator==(const ProtectiveRelease&) const = default;
};

// The controller declared a part lost.
struct WorkpieceLost {
  static constexpr std::string_view kType = "workpiece_lost";
  SimDuration t{0};
  std::string workpiece;
  std::string reason;
  std::optional<Eigen::Vector3d> last_seen;  // world, m ("x", "y", "z"); none (nulls) when never seen
  bool operator==(const WorkpieceLost&) const = default;
};

// A command not carried out (its workpiece is lost).
struct Skipped {
  static constexpr std::string_view kType = "skipped";
  SimDuration t{0};
  std::string robot;
  std::size_t primitive = 0;
  std::string command;
  std::string reason;
  bool operator==(const Skipped&) const = default;
};

// Nothing else applied: every robot was stopped.
struct CellStopped {
  static constexpr std::string_view kType = "cell_stopped";
  SimDuration t{0};
  std::string reason;
  bool operator==(const CellStopped&) const = default;
};

// What a robot's plant says is between its fingers.
struct Held {
  std::string robot;      // cell robot name
  std::string workpiece;  // cell workpiece, "" none
  bool operator==(const Held&) const = default;
};

// The plant's physical state, logged by the simulation thread in the period after a fault_detected, so that a
// report can tell a detection with nothing physically wrong (a false alarm) from a real fault.
struct Physical {
  static constexpr std::string_view kType = "physical";
  SimDuration t{0};
  std::vector<Held> held;     // the robots whose plant can tell what they hold
  std::size_t obstacles = 0;  // objects the safety sensor sees
  bool operator==(const Physical&) const = default;
};

// One control period of two robots holding one workpiece together (a coordinated carry, issue 27), as the twin
// measures it (logged by the plant every period while both hands hold it; never read by the controller). `a` and `b`
// in the cell's robot order.
struct Carry {
  static constexpr std::string_view kType = "carry";
  SimDuration t{0};
  std::string workpiece;  // cell workpiece
  std::string a, b;       // cell robot names
  double squeeze = 0;     // N, the internal force along the workpiece's axis: > 0 pushing the ends together
  double error = 0;       // mm, how far b's tool is from where a's tool and the grasp transform put it
  double turn = 0;        // degrees, the rotation between the two (the same comparison)
  double tilt = 0;        // degrees, the workpiece's long axis from horizontal
  bool operator==(const Carry&) const = default;
};

// The run ended.
struct RunEnd {
  static constexpr std::string_view kType = "run_end";
  SimDuration t{0};
  std::string outcome;  // "finished" | "failed" | "timeout" | "stopped"
  std::string reason;
  std::uint64_t firings = 0;
  bool operator==(const RunEnd&) const = default;
};

// A device of the cell changed state (issue 26: machines, conveyors, photo-eyes), as device control sees it through
// the device's I/O (the twin's I/O image or a real unit): logged by device control when an input it reads or a coil
// it writes changes, so that the same events come from the twin and from real I/O.
struct Device {
  static constexpr std::string_view kType = "device";
  SimDuration t{0};
  std::string device;     // the cell's device name (a machine, conveyor or sensor)
  std::string kind;       // "machine" | "conveyor" | "sensor"
  // machine: "idle" | "busy" | "done" (from its busy and done inputs); conveyor: "running" | "stopped" (its run
  // coil); sensor: "on" | "off" (its input)
  std::string state;
  std::string workpiece;  // machine: the cell workpiece the model has in it ("" none); others ""
  bool operator==(const Device&) const = default;
};

}  // namespace events

// Any event of the log.
using LogEvent = std::variant<events::RunStart, events::Fire, events::CommandStart, events::CommandEnd, events::Sensor,
                              events::Collision, events::WorkpieceArrived, events::WorkpieceLeft, events::Vision,
                              events::FaultInjected, events::FaultDetected, events::Diagnosis, events::RecoveryEnd,
                              events::ProtectiveStop, events::ProtectiveRelease, events::WorkpieceLost, events::Skipped,
                              events::CellStopped, events::Physical, events::Carry, events::RunEnd, events::Device>;

// The event's time and its "type" ("run_start", ...).
SimDuration time_of(const LogEvent& e);
std::string_view type_of(const LogEvent& e);

// Simulation time as the log writes it: seconds with exactly 4 decimals, rounded half away from zero on the
// nanosecond count (integer arithmetic, so the same time always gives the same text): 1234567890 ns -> "1.2346".
std::string format_sim_time(SimDuration t);

// The event's line, without the newline. A non-finite length is an invariant failure (InternalError).
std::string encode(const LogEvent& e);

// The event of one line (line_no counts from 1, for the error). Throws InputError naming `file`, the line and the
// problem (see the top).
LogEvent decode(std::string_view line, const std::string& file, int line_no);

// An event read from a log, with the line it was on.
struct LoggedEvent {
  int line = 0;  // 1-based
  LogEvent event;
};

// Every event of a log's text, in order; blank lines are skipped (a trailing '\r' is ignored). Throws as decode().
std::vector<LoggedEvent> decode_log(std::string_view jsonl, const std::string& file);

// The same from a stream, one line at a time, handing each event to `each` as it is read: what it holds is one
// line, however long the log. Throws as decode(), and InputError when the stream cannot be read.
void read_log(std::istream& jsonl, const std::string& file, const std::function<void(const LoggedEvent&)>& each);

}  // namespace cellwright::runtime
