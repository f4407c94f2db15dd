// The run's event log: JSON Lines, one object per line, written in the order events happen. Each event is a typed
// value (log_event.hpp: one struct per type, their fields, the one codec that writes and reads their lines); the log
// encodes each as it is logged, so the bytes are fixed by the events alone (fixed key order, fixed number formatting,
// no wall-clock time, no addresses), and two lock-step runs of the same scenario and seed give byte-identical logs,
// which tests and CI compare with a plain diff.
//
// Every line starts with "t" (simulation time in seconds, exactly 4 decimals, e.g. 1.2300) and "type". The types and
// their keys, in this order (log_event.hpp has each one's struct):
//   run_start         program, cell, mode ("lockstep"|"realtime"), period (s, 4 decimals), robots [{robot, cell}]
//   fire              transition (id), robot (label, "" for a transition of no robot), primitive (index, -1 none),
//                     line, task, motion
//   command_start     robot, primitive (index), command ("move at(A)"), task, motion, detail (what was sent to the
//                     driver, drivers::describe(); "" when nothing was sent yet)
//   command_end       robot, primitive, command, ok (true|false), reason ("" when ok)
//   sensor            robot, primitive, condition ("gripped" | "closed_on_nothing" | "closed_on_wrong_part" |
//                     "grip_not_sensed" | "released" | "position_reached" | "position_missed" | "waiting_for_part" |
//                     "part_ready" | "bound": a workpiece class of the command now means this part), workpiece ("" if
//                     none)
//   collision         a, b, depth (m, 6 decimals)
//   workpiece_arrived workpiece, where
//   workpiece_left    workpiece, where (the conveyor it was carried off): the part left the cell, delivered
//   vision            frame (its sim time, 4 decimals), seen [{workpiece, x, y, z (m, 4 decimals), yaw (degrees, 2
//                     decimals, null for a cylinder), confidence (3 decimals)}], not_seen [names], rejected (count),
//                     problem ("" if none)
//   fault_injected    kind, robot (cell name, "" none), workpiece ("" none), detail: a fault the rig (the twin) injected
//                     on purpose, logged by the rig (docs/faults.md); for the campaign's accounting, never read by the controller
//   fault_detected    robot (label, "" for the cell), primitive (-1 none), symptom, detail: something the controller
//                     sensed went wrong
//   diagnosis         robot, symptom, cause, action, path (the decision tree's answers, "part_seen=yes part_at_rest=no")
//   recovery_end      robot, cause, action, ok (true|false), detail, duration (s, 4 decimals, since fault_detected)
//   protective_stop   robot, reason: the safety layer stopped the robot
//   protective_release robot: ... and released it
//   workpiece_lost    workpiece, reason, x, y, z (m, 4 decimals: where it was last seen; null when never seen)
//   skipped           robot, primitive, command, reason: a command not carried out (its workpiece is lost)
//   cell_stopped      reason: nothing else applied; every robot was stopped
//   physical          held [{robot (cell name), workpiece ("" none)}] (the robots whose plant can tell what is between
//                     their fingers), obstacles (how many objects the safety sensor sees): the plant's physical state,
//                     logged by the simulation thread in the period after a fault_detected, so that a report can tell
//                     a detection with nothing physically wrong (a false alarm) from a real fault
//   carry             workpiece, a, b (cell robots), squeeze (N), error (mm), turn (degrees), tilt (degrees), 2 decimals
//                     for N and mm, 3 for degrees: one period of a coordinated carry as the twin measures it, logged
//                     by the plant every period while both hands hold the workpiece (docs/runtime.md, "Coordinated
//                     blocks")
//   run_end           outcome ("finished"|"failed"|"timeout"|"stopped"), reason, firings
// Strings are JSON-escaped. Numbers other than "t", period, duration, depth, x/y/z, the vision event's and the carry
// event's are integers.
//
// Typed observers: add_observer() registers a function that is handed each event as it is logged (the value, not
// its line), e.g. RunConfig::event_observers. It is called on the thread that logs, under the log's lock, in log
// order: it must be quick and must not log.
//
// Memory: a log that keeps its lines (Keep::kLines, the default) grows with the run, about 130 bytes per event. A log
// that streams them (a sink and Keep::kNothing) holds only a count: a shift of a thousand parts costs no more memory
// than one part, and whoever needs the events reads the sink's file back (cell::make_report on an istream, through
// read_log).
//
// Threads: every member may be called from any thread; each call appends one whole line under a mutex, so lines never
// interleave. (Determinism of the order is the lock-step scheduler's job, not the log's.)
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/log_event.hpp"

namespace cellwright::runtime {

class EventLog {
 public:
  enum class Keep {
    kLines,    // every line stays in memory: lines() and text() give them
    kNothing,  // only the sink has them; lines() and text() are not available (an invariant check fails)
  };
  // If `sink` is not null, each line is written to it as it is logged, followed by '\n', and flushed: a process
  // that dies leaves every line logged before in the file. The sink must outlive the log. Keep::kNothing needs a
  // sink (an invariant check).
  explicit EventLog(std::ostream* sink = nullptr, Keep keep = Keep::kLines);
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;

  // Logs one event: encodes it (log_event.hpp), writes the line, then hands the value to the observers.
  void log(const LogEvent& event);
  // Registers a typed observer (see the top). Before the run: not while events are being logged by other threads.
  void add_observer(std::function<void(const LogEvent&)> observer);

  // One method per type, for the call sites: each builds the event (log_event.hpp) and logs it.
  using RobotName = events::RobotName;
  void run_start(SimDuration t, std::string_view program, std::string_view cell, std::string_view mode,
                 SimDuration period, const std::vector<RobotName>& robots);
  void fire(SimDuration t, std::string_view transition, std::string_view robot, int primitive, int line,
            std::string_view task, std::string_view motion);
  void command_start(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                     std::string_view task, std::string_view motion, std::string_view detail);
  void command_end(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command, bool ok,
                   std::string_view reason);
  void sensor(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view condition,
              std::string_view workpiece);
  void collision(SimDuration t, std::string_view a, std::string_view b, double depth);
  void workpiece_arrived(SimDuration t, std::string_view workpiece, std::string_view where);
  void workpiece_left(SimDuration t, std::string_view workpiece, std::string_view where);
  void fault_injected(SimDuration t, std::string_view kind, std::string_view robot, std::string_view workpiece,
                      std::string_view detail);
  void fault_detected(SimDuration t, std::string_view robot, int primitive, std::string_view symptom,
                      std::string_view detail);
  void diagnosis(SimDuration t, std::string_view robot, std::string_view symptom, std::string_view cause,
                 std::string_view action, std::string_view path);
  void recovery_end(SimDuration t, std::string_view robot, std::string_view cause, std::string_view action, bool ok,
                    std::string_view detail, SimDuration duration);
  void protective_stop(SimDuration t, std::string_view robot, std::string_view reason);
  void protective_release(SimDuration t, std::string_view robot);
  void workpiece_lost(SimDuration t, std::string_view workpiece, std::string_view reason,
                      const std::optional<Eigen::Vector3d>& last_seen);
  void skipped(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
               std::string_view reason);
  void cell_stopped(SimDuration t, std::string_view reason);
  using Held = events::Held;  // a cell robot and the cell workpiece between its fingers, "" none
  void physical(SimDuration t, const std::vector<Held>& held, std::size_t obstacles);
  void run_end(SimDuration t, std::string_view outcome, std::string_view reason, std::uint64_t firings);

  // One camera frame processed by the image-processing thread: taken at `frame_time`, what it saw (each part's
  // centre, yaw when it has one, confidence), what it did not, how many blobs it rejected, and a problem that made
  // the frame unusable ("" if none). Positions are written to 0.1 mm, angles to 0.01 degree.
  using Seen = events::Seen;  // workpiece, position (m), yaw (radians, none for a cylinder), confidence
  void vision(SimDuration t, SimDuration frame_time, const std::vector<Seen>& seen,
              const std::vector<std::string>& not_seen, std::size_t rejected, std::string_view problem);

  // Every line so far, without the newline. Keep::kLines only.
  std::vector<std::string> lines() const;
  // Every line so far, each followed by '\n' (the file's content). Keep::kLines only.
  std::string text() const;
  // How many lines were logged (either Keep).
  std::size_t size() const;
  // How many fault_detected lines were logged.
  std::size_t detections() const;
  bool keeps_lines() const { return keep_ == Keep::kLines; }
  // Flushes the sink, so that a reader of its file sees every line logged so far. Throws std::runtime_error if the
  // sink has failed (a write error, a full disk): lines were lost.
  void flush() const;

 private:
  mutable std::mutex mutex_;
  std::vector<std::function<void(const LogEvent&)>> observers_;
  std::ostream* sink_;
  Keep keep_;
  std::vector<std::string> lines_;
  std::size_t count_ = 0;
  std::size_t detections_ = 0;
};

}  // namespace cellwright::runtime
