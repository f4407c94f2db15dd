#include "cellwright/drivers/scripted_driver.hpp"

#include <cmath>

#include <fmt/format.h>

#include <type_traits>

namespace cellwright::drivers {

ScriptedDriver::ScriptedDriver(ScriptedDriverConfig config)
    : config_(std::move(config)),
      inputs_(config_.capabilities.digital_inputs, false),
      outputs_(config_.capabilities.digital_outputs, false),
      joints_(config_.home_joints.empty() ? std::vector<double>(config_.capabilities.joints, 0.0)
                                          : config_.home_joints),
      pose_(config_.home_pose) {
  CW_CHECK(config_.tick.count() > 0, "scripted driver tick must be positive, got {} ns", config_.tick.count());
  CW_CHECK(config_.home_ticks > 0 && config_.position_ticks > 0 && config_.command_ticks > 0,
           "scripted driver durations must be at least one tick (home {}, position {}, command {})", config_.home_ticks,
           config_.position_ticks, config_.command_ticks);
  CW_CHECK(config_.capabilities.queue_depth > 0, "queue_depth must be at least 1");
  CW_CHECK(joints_.size() == config_.capabilities.joints, "home_joints has {} values for {} joints", joints_.size(),
           config_.capabilities.joints);
  set_capabilities(config_.capabilities);
}

ErrorCode ScriptedDriver::connect_hook() {
  const auto l = lock();
  if (!connect_problem_.empty()) throw InputError(config_.where, connect_problem_);
  return ErrorCode::none;
}

void ScriptedDriver::accept_hook(Job& job) {
  auto work = std::make_unique<Work>();
  switch (job.kind) {
    case JobKind::home:
      work->remaining = config_.home_ticks;
      break;
    case JobKind::position:
      work->remaining = config_.position_ticks;
      break;
    case JobKind::command:
      work->remaining = command_ticks(*job.command);
      accepted_.emplace_back(job.id, *job.command);
      break;
  }
  job.data = std::move(work);
}

void ScriptedDriver::advance(std::uint64_t ticks) {
  Controller c = controller();
  for (std::uint64_t t = 0; t < ticks; ++t) {
    ++now_;
    tick_head(c);
    tick_reads(c);
  }
}

void ScriptedDriver::tick_head(Controller& c) {
  Job* head = c.head();
  if (head == nullptr || never_complete_.count(head->id) != 0) return;
  Work& work = head->as<Work>();
  if (head->command && std::holds_alternative<WaitInput>(*head->command)) {
    const auto& w = std::get<WaitInput>(*head->command);
    if (inputs_[static_cast<std::size_t>(w.channel - 1)] == w.on) {
      finish(c, *head);
      return;
    }
    ++work.waited;
    const std::chrono::nanoseconds waited = config_.tick * static_cast<std::int64_t>(work.waited);
    if (w.timeout.count() > 0 && waited >= w.timeout) {
      c.fail(head->id, ErrorCode::timeout,
             fmt::format("digital input {} stayed {} for {} ns", w.channel, w.on ? "off" : "on", waited.count()));
    }
    return;
  }
  if (--work.remaining > 0) return;
  finish(c, *head);
}

void ScriptedDriver::tick_reads(Controller& c) {
  std::vector<CommandId> over;
  for (Job& r : c.reads()) {
    if (never_complete_.count(r.id) == 0 && --r.as<Work>().remaining == 0) over.push_back(r.id);
  }
  for (const CommandId id : over) {
    for (Job& r : c.reads()) {
      if (r.id == id) {
        finish(c, r);  // a fatal injected failure may clear the reads: look each one up again
        break;
      }
    }
  }
}

void ScriptedDriver::finish(Controller& c, Job& job) {
  const CommandId id = job.id;
  const auto injected = injected_failures_.find(id);
  if (injected != injected_failures_.end()) {
    auto [error, message] = std::move(injected->second);
    injected_failures_.erase(injected);
    c.fail(id, error, std::move(message));
    return;
  }
  switch (job.kind) {
    case JobKind::home:
      joints_ =
          config_.home_joints.empty() ? std::vector<double>(config_.capabilities.joints, 0.0) : config_.home_joints;
      pose_ = config_.home_pose;
      gripper_closed_ = false;
      c.complete(id);
      return;
    case JobKind::position:
      c.complete(id, reading(c));
      return;
    case JobKind::command:
      std::visit(
          [&](const auto& cmd) {
            using C = std::decay_t<decltype(cmd)>;
            if constexpr (std::is_same_v<C, MoveJoints>) {
              joints_ = cmd.positions;
            } else if constexpr (std::is_same_v<C, MovePose>) {
              pose_ = cmd.pose;
            } else if constexpr (std::is_same_v<C, Grip>) {
              gripper_closed_ = cmd.action == Grip::Action::close;
            } else if constexpr (std::is_same_v<C, SetOutput>) {
              outputs_[static_cast<std::size_t>(cmd.channel - 1)] = cmd.on;
            }
          },
          *job.command);
      c.complete(id);
      return;
  }
}

PositionReading ScriptedDriver::reading(const Controller& c) const {
  PositionReading r;
  r.stamp = c.stamp(config_.tick * static_cast<std::int64_t>(now_));
  if (config_.capabilities.reads_joints) r.joints = joints_;
  if (config_.capabilities.reads_pose) r.tool_pose = pose_;
  return r;
}

std::uint64_t ScriptedDriver::now_ticks() const {
  const auto l = lock();
  return now_;
}

void ScriptedDriver::fail_command(CommandId id, ErrorCode error, std::string message) {
  CW_CHECK(error == ErrorCode::unreachable || error == ErrorCode::timeout || error == ErrorCode::hardware ||
               error == ErrorCode::protocol || error == ErrorCode::connection_lost || error == ErrorCode::unknown,
           "a controller cannot fail a command with {}", to_string(error));
  const auto l = lock();
  injected_failures_[id] = {error, std::move(message)};
}

void ScriptedDriver::never_complete(CommandId id) {
  const auto l = lock();
  never_complete_.insert(id);
}

void ScriptedDriver::drop_connection() {
  Controller c = controller();
  if (c.state() == DriverState::disconnected) return;
  c.raise_fault(ErrorCode::connection_lost, "the link to the controller dropped");
}

void ScriptedDriver::refuse_connect(std::string problem) {
  const auto l = lock();
  connect_problem_ = std::move(problem);
}

void ScriptedDriver::set_input(int channel, bool on) {
  const auto l = lock();
  CW_CHECK(channel >= 1 && static_cast<std::size_t>(channel) <= inputs_.size(), "input {} outside 1..{}", channel,
           inputs_.size());
  inputs_[static_cast<std::size_t>(channel - 1)] = on;
}

bool ScriptedDriver::output(int channel) const {
  const auto l = lock();
  CW_CHECK(channel >= 1 && static_cast<std::size_t>(channel) <= outputs_.size(), "output {} outside 1..{}", channel,
           outputs_.size());
  return outputs_[static_cast<std::size_t>(channel - 1)];
}

std::vector<std::pair<CommandId, Command>> ScriptedDriver::accepted() const {
  const auto l = lock();
  return accepted_;
}

std::vector<double> ScriptedDriver::joints() const {
  const auto l = lock();
  return joints_;
}

Eigen::Isometry3d ScriptedDriver::tool_pose() const {
  const auto l = lock();
  return pose_;
}

bool ScriptedDriver::gripper_closed() const {
  const auto l = lock();
  return gripper_closed_;
}

void ScriptedDriver::set_grip_sense(std::optional<GripSense> sense) {
  const auto l = lock();
  grip_sense_ = sense;
}

std::uint64_t ScriptedDriver::command_ticks(const Command& command) const {
  const std::uint64_t own = config_.ticks_for ? config_.ticks_for(command) : config_.command_ticks;
  CW_CHECK(own > 0, "ticks_for gave 0 ticks for {}", describe(command));
  std::optional<double> duration;
  if (const auto* m = std::get_if<MoveJoints>(&command)) duration = m->duration;
  if (const auto* m = std::get_if<MovePose>(&command)) duration = m->duration;
  if (!duration) return own;
  const double tick = std::chrono::duration<double>(config_.tick).count();
  // The least whole number of ticks that lasts the duration (a hair of rounding below a whole tick is that tick).
  const auto stretched = static_cast<std::uint64_t>(std::ceil(*duration / tick - 1e-9));
  return std::max(own, stretched);
}

std::optional<double> ScriptedDriver::least_duration(const Command& command) const {
  if (!config_.capabilities.timed_motion || state() != DriverState::active) return std::nullopt;
  if (check_command(command, config_.capabilities)) return std::nullopt;
  return static_cast<double>(command_ticks(command)) * std::chrono::duration<double>(config_.tick).count();
}

std::optional<GripSense> ScriptedDriver::grip_sense() const {
  const auto l = lock();
  return grip_sense_;
}

}  // namespace cellwright::drivers
