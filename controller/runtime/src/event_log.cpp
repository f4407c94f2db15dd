#include "cellwright/runtime/event_log.hpp"

#include <fmt/format.h>

#include <stdexcept>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

EventLog::EventLog(std::ostream* sink, Keep keep) : sink_(sink), keep_(keep) {
  CW_CHECK(keep == Keep::kLines || sink != nullptr, "an event log that keeps no lines needs a sink to write them to");
}

void EventLog::add_observer(std::function<void(const LogEvent&)> observer) {
  std::lock_guard lock(mutex_);
  observers_.push_back(std::move(observer));
}

void EventLog::log(const LogEvent& event) {
  std::string line = encode(event);  // outside the lock: the encoding is the event's alone
  std::lock_guard lock(mutex_);
  if (sink_ != nullptr) {
    *sink_ << line << '\n';
    sink_->flush();  // about 5 lines per simulated second: the write calls cost nothing next to the run
  }
  ++count_;
  if (std::holds_alternative<events::FaultDetected>(event)) ++detections_;
  if (keep_ == Keep::kLines) lines_.push_back(std::move(line));
  for (const auto& observer : observers_) observer(event);
}

void EventLog::flush() const {
  std::lock_guard lock(mutex_);
  if (sink_ == nullptr) return;
  sink_->flush();
  if (!*sink_) throw std::runtime_error(fmt::format("the event log could not be written after {} lines", count_));
}

void EventLog::run_start(SimDuration t, std::string_view program, std::string_view cell, std::string_view mode,
                         SimDuration period, const std::vector<RobotName>& robots) {
  log(events::RunStart{t, std::string(program), std::string(cell), std::string(mode), period, robots});
}

void EventLog::fire(SimDuration t, std::string_view transition, std::string_view robot, int primitive, int line,
                    std::string_view task, std::string_view motion) {
  log(events::Fire{t, std::string(transition), std::string(robot), primitive, line, std::string(task),
                   std::string(motion)});
}

void EventLog::command_start(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                             std::string_view task, std::string_view motion, std::string_view detail) {
  log(events::CommandStart{t, std::string(robot), primitive, std::string(command), std::string(task),
                           std::string(motion), std::string(detail)});
}

void EventLog::command_end(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                           bool ok, std::string_view reason) {
  log(events::CommandEnd{t, std::string(robot), primitive, std::string(command), ok, std::string(reason)});
}

void EventLog::sensor(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view condition,
                      std::string_view workpiece) {
  log(events::Sensor{t, std::string(robot), primitive, std::string(condition), std::string(workpiece)});
}

void EventLog::collision(SimDuration t, std::string_view a, std::string_view b, double depth) {
  log(events::Collision{t, std::string(a), std::string(b), depth});
}

void EventLog::workpiece_arrived(SimDuration t, std::string_view workpiece, std::string_view where) {
  log(events::WorkpieceArrived{t, std::string(workpiece), std::string(where)});
}

void EventLog::workpiece_left(SimDuration t, std::string_view workpiece, std::string_view where) {
  log(events::WorkpieceLeft{t, std::string(workpiece), std::string(where)});
}

void EventLog::fault_injected(SimDuration t, std::string_view kind, std::string_view robot, std::string_view workpiece,
                              std::string_view detail) {
  log(events::FaultInjected{t, std::string(kind), std::string(robot), std::string(workpiece), std::string(detail)});
}

void EventLog::fault_detected(SimDuration t, std::string_view robot, int primitive, std::string_view symptom,
                              std::string_view detail) {
  log(events::FaultDetected{t, std::string(robot), primitive, std::string(symptom), std::string(detail)});
}

void EventLog::physical(SimDuration t, const std::vector<Held>& held, std::size_t obstacles) {
  log(events::Physical{t, held, obstacles});
}

std::size_t EventLog::detections() const {
  std::lock_guard lock(mutex_);
  return detections_;
}

void EventLog::diagnosis(SimDuration t, std::string_view robot, std::string_view symptom, std::string_view cause,
                         std::string_view action, std::string_view path) {
  log(events::Diagnosis{t, std::string(robot), std::string(symptom), std::string(cause), std::string(action),
                        std::string(path)});
}

void EventLog::recovery_end(SimDuration t, std::string_view robot, std::string_view cause, std::string_view action,
                            bool ok, std::string_view detail, SimDuration duration) {
  log(events::RecoveryEnd{t, std::string(robot), std::string(cause), std::string(action), ok, std::string(detail),
                          duration});
}

void EventLog::protective_stop(SimDuration t, std::string_view robot, std::string_view reason) {
  log(events::ProtectiveStop{t, std::string(robot), std::string(reason)});
}

void EventLog::protective_release(SimDuration t, std::string_view robot) {
  log(events::ProtectiveRelease{t, std::string(robot)});
}

void EventLog::workpiece_lost(SimDuration t, std::string_view workpiece, std::string_view reason,
                              const std::optional<Eigen::Vector3d>& last_seen) {
  log(events::WorkpieceLost{t, std::string(workpiece), std::string(reason), last_seen});
}

void EventLog::skipped(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                       std::string_view reason) {
  log(events::Skipped{t, std::string(robot), primitive, std::string(command), std::string(reason)});
}

void EventLog::cell_stopped(SimDuration t, std::string_view reason) {
  log(events::CellStopped{t, std::string(reason)});
}

void EventLog::run_end(SimDuration t, std::string_view outcome, std::string_view reason, std::uint64_t firings) {
  log(events::RunEnd{t, std::string(outcome), std::string(reason), firings});
}

void EventLog::vision(SimDuration t, SimDuration frame_time, const std::vector<Seen>& seen,
                      const std::vector<std::string>& not_seen, std::size_t rejected, std::string_view problem) {
  log(events::Vision{t, frame_time, seen, not_seen, rejected, std::string(problem)});
}

std::vector<std::string> EventLog::lines() const {
  std::lock_guard lock(mutex_);
  CW_CHECK(keep_ == Keep::kLines, "lines() of an event log that streams its {} lines to a file and keeps none", count_);
  return lines_;
}

std::string EventLog::text() const {
  std::lock_guard lock(mutex_);
  CW_CHECK(keep_ == Keep::kLines, "text() of an event log that streams its {} lines to a file and keeps none", count_);
  std::string out;
  for (const auto& l : lines_) {
    out += l;
    out += '\n';
  }
  return out;
}

std::size_t EventLog::size() const {
  std::lock_guard lock(mutex_);
  return count_;
}

}  // namespace cellwright::runtime
