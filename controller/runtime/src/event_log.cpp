#include "cellwright/runtime/event_log.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <numbers>
#include <stdexcept>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

std::string format_sim_time(SimDuration t) {
  // Integer rounding on the nanosecond count: a double would print 0.00005 s differently depending on its bits.
  const std::int64_t ns = t.count();
  const std::int64_t magnitude = ns < 0 ? -ns : ns;
  const std::int64_t ticks = (magnitude + 50'000) / 100'000;  // units of 0.1 ms, rounded half away from zero
  return fmt::format("{}{}.{:04}", ns < 0 && ticks != 0 ? "-" : "", ticks / 10'000, ticks % 10'000);
}

namespace {

// A JSON string literal. Invalid UTF-8 is replaced rather than thrown on: a log line must always be written.
std::string q(std::string_view s) {
  return nlohmann::json(std::string(s)).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string head(SimDuration t, std::string_view type) {
  return fmt::format("{{\"t\":{},\"type\":{}", format_sim_time(t), q(type));
}

}  // namespace

EventLog::EventLog(std::ostream* sink, Keep keep) : sink_(sink), keep_(keep) {
  CW_CHECK(keep == Keep::kLines || sink != nullptr,
           "an event log that keeps no lines needs a sink to write them to");
}

void EventLog::append(std::string line) {
  std::lock_guard lock(mutex_);
  if (sink_ != nullptr) {
    *sink_ << line << '\n';
    sink_->flush();  // about 5 lines per simulated second: the write calls cost nothing next to the run
  }
  ++count_;
  if (keep_ == Keep::kLines) lines_.push_back(std::move(line));
}

void EventLog::flush() const {
  std::lock_guard lock(mutex_);
  if (sink_ == nullptr) return;
  sink_->flush();
  if (!*sink_) throw std::runtime_error(fmt::format("the event log could not be written after {} lines", count_));
}

void EventLog::run_start(SimDuration t, std::string_view program, std::string_view cell, std::string_view mode,
                         SimDuration period, const std::vector<RobotName>& robots) {
  std::string list;
  for (const RobotName& r : robots) {
    if (!list.empty()) list += ',';
    list += fmt::format("{{\"robot\":{},\"cell\":{}}}", q(r.robot), q(r.cell));
  }
  append(fmt::format("{},\"program\":{},\"cell\":{},\"mode\":{},\"period\":{},\"robots\":[{}]}}", head(t, "run_start"),
                     q(program), q(cell), q(mode), format_sim_time(period), list));
}

void EventLog::fire(SimDuration t, std::string_view transition, std::string_view robot, int primitive, int line,
                    std::string_view task, std::string_view motion) {
  append(fmt::format("{},\"transition\":{},\"robot\":{},\"primitive\":{},\"line\":{},\"task\":{},\"motion\":{}}}",
                     head(t, "fire"), q(transition), q(robot), primitive, line, q(task), q(motion)));
}

void EventLog::command_start(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                             std::string_view task, std::string_view motion, std::string_view detail) {
  append(fmt::format("{},\"robot\":{},\"primitive\":{},\"command\":{},\"task\":{},\"motion\":{},\"detail\":{}}}",
                     head(t, "command_start"), q(robot), primitive, q(command), q(task), q(motion), q(detail)));
}

void EventLog::command_end(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                           bool ok, std::string_view reason) {
  append(fmt::format("{},\"robot\":{},\"primitive\":{},\"command\":{},\"ok\":{},\"reason\":{}}}",
                     head(t, "command_end"), q(robot), primitive, q(command), ok ? "true" : "false", q(reason)));
}

void EventLog::sensor(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view condition,
                      std::string_view workpiece) {
  append(fmt::format("{},\"robot\":{},\"primitive\":{},\"condition\":{},\"workpiece\":{}}}", head(t, "sensor"),
                     q(robot), primitive, q(condition), q(workpiece)));
}

void EventLog::collision(SimDuration t, std::string_view a, std::string_view b, double depth) {
  CW_CHECK(std::isfinite(depth), "collision depth {} between {} and {}", depth, a, b);
  // 6 decimals of a metre; -0.000000 would differ from 0.000000 byte-wise, so negative zero is folded.
  const double d = depth == 0.0 ? 0.0 : depth;
  append(fmt::format("{},\"a\":{},\"b\":{},\"depth\":{:.6f}}}", head(t, "collision"), q(a), q(b), d));
}

void EventLog::workpiece_arrived(SimDuration t, std::string_view workpiece, std::string_view where) {
  append(fmt::format("{},\"workpiece\":{},\"where\":{}}}", head(t, "workpiece_arrived"), q(workpiece), q(where)));
}

void EventLog::workpiece_left(SimDuration t, std::string_view workpiece, std::string_view where) {
  append(fmt::format("{},\"workpiece\":{},\"where\":{}}}", head(t, "workpiece_left"), q(workpiece), q(where)));
}

void EventLog::fault_injected(SimDuration t, std::string_view kind, std::string_view robot,
                              std::string_view workpiece, std::string_view detail) {
  append(fmt::format("{},\"kind\":{},\"robot\":{},\"workpiece\":{},\"detail\":{}}}", head(t, "fault_injected"),
                     q(kind), q(robot), q(workpiece), q(detail)));
}

void EventLog::fault_detected(SimDuration t, std::string_view robot, int primitive, std::string_view symptom,
                              std::string_view detail) {
  append(fmt::format("{},\"robot\":{},\"primitive\":{},\"symptom\":{},\"detail\":{}}}", head(t, "fault_detected"),
                     q(robot), primitive, q(symptom), q(detail)));
  std::lock_guard lock(mutex_);
  ++detections_;
}

void EventLog::physical(SimDuration t, const std::vector<Held>& held, std::size_t obstacles) {
  std::string list;
  for (const Held& h : held) {
    list += fmt::format("{}{{\"robot\":{},\"workpiece\":{}}}", list.empty() ? "" : ",", q(h.robot), q(h.workpiece));
  }
  append(fmt::format("{},\"held\":[{}],\"obstacles\":{}}}", head(t, "physical"), list, obstacles));
}

std::size_t EventLog::detections() const {
  std::lock_guard lock(mutex_);
  return detections_;
}

void EventLog::diagnosis(SimDuration t, std::string_view robot, std::string_view symptom, std::string_view cause,
                         std::string_view action, std::string_view path) {
  append(fmt::format("{},\"robot\":{},\"symptom\":{},\"cause\":{},\"action\":{},\"path\":{}}}",
                     head(t, "diagnosis"), q(robot), q(symptom), q(cause), q(action), q(path)));
}

void EventLog::recovery_end(SimDuration t, std::string_view robot, std::string_view cause, std::string_view action,
                            bool ok, std::string_view detail, SimDuration duration) {
  append(fmt::format("{},\"robot\":{},\"cause\":{},\"action\":{},\"ok\":{},\"detail\":{},\"duration\":{}}}",
                     head(t, "recovery_end"), q(robot), q(cause), q(action), ok ? "true" : "false", q(detail),
                     format_sim_time(duration)));
}

void EventLog::protective_stop(SimDuration t, std::string_view robot, std::string_view reason) {
  append(fmt::format("{},\"robot\":{},\"reason\":{}}}", head(t, "protective_stop"), q(robot), q(reason)));
}

void EventLog::protective_release(SimDuration t, std::string_view robot) {
  append(fmt::format("{},\"robot\":{}}}", head(t, "protective_release"), q(robot)));
}

void EventLog::workpiece_lost(SimDuration t, std::string_view workpiece, std::string_view reason,
                              const std::optional<Eigen::Vector3d>& last_seen) {
  const auto fixed = [](double v) {
    std::string s = fmt::format("{:.4f}", v);
    if (s.find_first_not_of("-0.") == std::string::npos && s.front() == '-') s.erase(0, 1);
    return s;
  };
  const std::string x = last_seen ? fixed(last_seen->x()) : std::string("null");
  const std::string y = last_seen ? fixed(last_seen->y()) : std::string("null");
  const std::string z = last_seen ? fixed(last_seen->z()) : std::string("null");
  append(fmt::format("{},\"workpiece\":{},\"reason\":{},\"x\":{},\"y\":{},\"z\":{}}}", head(t, "workpiece_lost"),
                     q(workpiece), q(reason), x, y, z));
}

void EventLog::skipped(SimDuration t, std::string_view robot, std::size_t primitive, std::string_view command,
                       std::string_view reason) {
  append(fmt::format("{},\"robot\":{},\"primitive\":{},\"command\":{},\"reason\":{}}}", head(t, "skipped"),
                     q(robot), primitive, q(command), q(reason)));
}

void EventLog::cell_stopped(SimDuration t, std::string_view reason) {
  append(fmt::format("{},\"reason\":{}}}", head(t, "cell_stopped"), q(reason)));
}

void EventLog::run_end(SimDuration t, std::string_view outcome, std::string_view reason, std::uint64_t firings) {
  append(fmt::format("{},\"outcome\":{},\"reason\":{},\"firings\":{}}}", head(t, "run_end"), q(outcome), q(reason),
                     firings));
}

void EventLog::vision(SimDuration t, SimDuration frame_time, const std::vector<Seen>& seen,
                      const std::vector<std::string>& not_seen, std::size_t rejected, std::string_view problem) {
  // Fixed decimals, negative zero folded: the same numbers give the same bytes.
  const auto fixed = [](double v, int decimals) {
    std::string s = fmt::format("{:.{}f}", v, decimals);
    if (s.find_first_not_of("-0.") == std::string::npos && s.front() == '-') s.erase(0, 1);
    return s;
  };
  std::string list;
  for (const Seen& p : seen) {
    CW_CHECK(p.position.allFinite() && std::isfinite(p.confidence), "vision saw {} at a non-finite pose", p.workpiece);
    if (!list.empty()) list += ',';
    list +=
        fmt::format("{{\"workpiece\":{},\"x\":{},\"y\":{},\"z\":{},\"yaw\":{},\"confidence\":{}}}", q(p.workpiece),
                    fixed(p.position.x(), 4), fixed(p.position.y(), 4), fixed(p.position.z(), 4),
                    p.yaw ? fixed(*p.yaw * 180.0 / std::numbers::pi, 2) : std::string("null"), fixed(p.confidence, 3));
  }
  std::string missing;
  for (const std::string& w : not_seen) {
    if (!missing.empty()) missing += ',';
    missing += q(w);
  }
  append(fmt::format("{},\"frame\":{},\"seen\":[{}],\"not_seen\":[{}],\"rejected\":{},\"problem\":{}}}",
                     head(t, "vision"), format_sim_time(frame_time), list, missing, rejected, q(problem)));
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
