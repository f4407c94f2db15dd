#include "cellwright/drivers/scripted_driver.hpp"

#include <fmt/format.h>

#include <type_traits>

namespace cellwright::drivers {

namespace {

bool fatal(ErrorCode e) {
  return e == ErrorCode::hardware || e == ErrorCode::protocol || e == ErrorCode::connection_lost;
}

}  // namespace

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
}

const Capabilities& ScriptedDriver::capabilities() const {
  return config_.capabilities;
}

DriverState ScriptedDriver::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

ErrorCode ScriptedDriver::connect() {
  std::lock_guard lock(mutex_);
  ++calls_.connect;
  if (state_ != DriverState::disconnected) return ErrorCode::wrong_state;
  if (!connect_problem_.empty()) throw InputError(config_.where, connect_problem_);
  state_ = DriverState::connected;
  link_up_ = true;
  return ErrorCode::none;
}

void ScriptedDriver::disconnect() {
  std::unique_lock lock(mutex_);
  ++calls_.disconnect;
  const bool changed = fail_all(ErrorCode::cancelled, "cancelled by disconnect()");
  state_ = DriverState::disconnected;
  link_up_ = false;
  notify_if(changed, lock);
}

Submitted ScriptedDriver::home() {
  std::lock_guard lock(mutex_);
  ++calls_.home;
  if (state_ != DriverState::connected && state_ != DriverState::homed && state_ != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("home() is not allowed while {}", to_string(state_)));
  }
  return enqueue(JobKind::home, std::nullopt, config_.home_ticks);
}

ErrorCode ScriptedDriver::activate() {
  std::lock_guard lock(mutex_);
  ++calls_.activate;
  if (state_ != DriverState::homed && state_ != DriverState::stopped) return ErrorCode::wrong_state;
  for (const Job& j : queue_) {
    if (j.kind == JobKind::home) return ErrorCode::wrong_state;  // still homing
  }
  state_ = DriverState::active;
  return ErrorCode::none;
}

void ScriptedDriver::stop() {
  std::unique_lock lock(mutex_);
  ++calls_.stop;
  const bool changed = fail_all(ErrorCode::cancelled, "cancelled by stop()");
  if (state_ == DriverState::active) state_ = DriverState::stopped;
  notify_if(changed, lock);
}

ErrorCode ScriptedDriver::reset() {
  std::lock_guard lock(mutex_);
  ++calls_.reset;
  if (state_ != DriverState::fault) return ErrorCode::wrong_state;
  if (!link_up_) {
    state_ = DriverState::disconnected;
    return ErrorCode::connection_lost;
  }
  state_ = DriverState::connected;
  return ErrorCode::none;
}

Submitted ScriptedDriver::submit(const Command& command) {
  std::lock_guard lock(mutex_);
  ++calls_.submit;
  if (state_ != DriverState::active) {
    return refuse(ErrorCode::wrong_state,
                  fmt::format("{} refused: the driver is {}, not active", describe(command), to_string(state_)));
  }
  if (Refusal r = check_command(command, config_.capabilities)) return refuse(r.error, std::move(r.message));
  const std::uint64_t ticks = config_.ticks_for ? config_.ticks_for(command) : config_.command_ticks;
  CW_CHECK(ticks > 0, "ticks_for gave 0 ticks for {}", describe(command));
  Submitted s = enqueue(JobKind::command, command, ticks);
  if (s.accepted()) accepted_.emplace_back(s.id, command);
  return s;
}

Submitted ScriptedDriver::request_position() {
  std::lock_guard lock(mutex_);
  ++calls_.request_position;
  if (state_ != DriverState::homed && state_ != DriverState::active && state_ != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("request_position() is not allowed while {}", to_string(state_)));
  }
  return enqueue(JobKind::position, std::nullopt, config_.position_ticks);
}

CommandStatus ScriptedDriver::poll(CommandId id) const {
  std::lock_guard lock(mutex_);
  ++calls_.poll;
  const auto it = statuses_.find(id);
  if (it != statuses_.end()) return it->second;
  return {id, CommandPhase::failed, ErrorCode::unknown_command,
          fmt::format("command {} was never issued or is no longer retained", id)};
}

std::optional<PositionReading> ScriptedDriver::last_position() const {
  std::lock_guard lock(mutex_);
  ++calls_.last_position;
  return last_position_;
}

void ScriptedDriver::set_notifier(std::function<void()> notify) {
  std::lock_guard lock(mutex_);
  ++calls_.set_notifier;
  notify_ = std::move(notify);
}

void ScriptedDriver::advance(std::uint64_t ticks) {
  std::unique_lock lock(mutex_);
  bool changed = false;
  for (std::uint64_t t = 0; t < ticks; ++t) {
    ++now_;
    if (queue_.empty()) continue;
    Job& head = queue_.front();
    if (never_complete_.count(head.id) != 0) continue;
    if (head.command && std::holds_alternative<WaitInput>(*head.command)) {
      const auto& w = std::get<WaitInput>(*head.command);
      if (inputs_[static_cast<std::size_t>(w.channel - 1)] == w.on) {
        finish_head();
        changed = true;
        continue;
      }
      ++head.waited;
      if (w.timeout.count() > 0 && config_.tick * static_cast<std::int64_t>(head.waited) >= w.timeout) {
        fail_head(ErrorCode::timeout,
                  fmt::format("digital input {} stayed {} for {} ns", w.channel, w.on ? "off" : "on",
                              (config_.tick * static_cast<std::int64_t>(head.waited)).count()));
        changed = true;
      }
      continue;
    }
    if (--head.remaining > 0) continue;
    finish_head();
    changed = true;
  }
  notify_if(changed, lock);
}

std::uint64_t ScriptedDriver::now_ticks() const {
  std::lock_guard lock(mutex_);
  return now_;
}

void ScriptedDriver::fail_command(CommandId id, ErrorCode error, std::string message) {
  CW_CHECK(error == ErrorCode::unreachable || error == ErrorCode::timeout || fatal(error),
           "a controller cannot fail a command with {}", to_string(error));
  std::lock_guard lock(mutex_);
  injected_failures_[id] = {error, std::move(message)};
}

void ScriptedDriver::never_complete(CommandId id) {
  std::lock_guard lock(mutex_);
  never_complete_.insert(id);
}

void ScriptedDriver::drop_connection() {
  std::unique_lock lock(mutex_);
  if (state_ == DriverState::disconnected) return;
  fail_all(ErrorCode::connection_lost, "the link to the controller dropped");
  state_ = DriverState::fault;
  link_up_ = false;
  notify_if(true, lock);
}

void ScriptedDriver::refuse_connect(std::string problem) {
  std::lock_guard lock(mutex_);
  connect_problem_ = std::move(problem);
}

void ScriptedDriver::set_input(int channel, bool on) {
  std::lock_guard lock(mutex_);
  CW_CHECK(channel >= 1 && static_cast<std::size_t>(channel) <= inputs_.size(), "input {} outside 1..{}", channel,
           inputs_.size());
  inputs_[static_cast<std::size_t>(channel - 1)] = on;
}

bool ScriptedDriver::output(int channel) const {
  std::lock_guard lock(mutex_);
  CW_CHECK(channel >= 1 && static_cast<std::size_t>(channel) <= outputs_.size(), "output {} outside 1..{}", channel,
           outputs_.size());
  return outputs_[static_cast<std::size_t>(channel - 1)];
}

ScriptedDriver::Calls ScriptedDriver::calls() const {
  std::lock_guard lock(mutex_);
  return calls_;
}

std::vector<std::pair<CommandId, Command>> ScriptedDriver::accepted() const {
  std::lock_guard lock(mutex_);
  return accepted_;
}

std::vector<double> ScriptedDriver::joints() const {
  std::lock_guard lock(mutex_);
  return joints_;
}

Eigen::Isometry3d ScriptedDriver::tool_pose() const {
  std::lock_guard lock(mutex_);
  return pose_;
}

bool ScriptedDriver::gripper_closed() const {
  std::lock_guard lock(mutex_);
  return gripper_closed_;
}

Submitted ScriptedDriver::refuse(ErrorCode error, std::string message) {
  return {0, error, std::move(message)};
}

Submitted ScriptedDriver::enqueue(JobKind kind, std::optional<Command> command, std::uint64_t ticks) {
  if (queue_.size() >= config_.capabilities.queue_depth) {
    return refuse(ErrorCode::busy, fmt::format("{} command(s) already in flight (queue depth {})", queue_.size(),
                                               config_.capabilities.queue_depth));
  }
  const CommandId id = next_id_++;
  queue_.push_back({id, kind, std::move(command), ticks, 0});
  set_status(id, queue_.size() == 1 ? CommandPhase::running : CommandPhase::pending);
  return {id, ErrorCode::none, {}};
}

void ScriptedDriver::set_status(CommandId id, CommandPhase phase, ErrorCode error, std::string message) {
  statuses_[id] = {id, phase, error, std::move(message)};
  if (phase != CommandPhase::done && phase != CommandPhase::failed) return;
  finished_.push_back(id);
  while (finished_.size() > kStatusRetention) {
    statuses_.erase(finished_.front());
    finished_.pop_front();
  }
}

bool ScriptedDriver::fail_all(ErrorCode error, const std::string& message) {
  const bool any = !queue_.empty();
  for (const Job& j : queue_) set_status(j.id, CommandPhase::failed, error, message);
  queue_.clear();
  return any;
}

void ScriptedDriver::finish_head() {
  const auto injected = injected_failures_.find(queue_.front().id);
  if (injected == injected_failures_.end()) {
    complete_head();
    return;
  }
  auto [error, message] = injected->second;
  injected_failures_.erase(injected);
  fail_head(error, std::move(message));
}

void ScriptedDriver::complete_head() {
  const Job job = std::move(queue_.front());
  queue_.pop_front();
  switch (job.kind) {
    case JobKind::home:
      joints_ =
          config_.home_joints.empty() ? std::vector<double>(config_.capabilities.joints, 0.0) : config_.home_joints;
      pose_ = config_.home_pose;
      gripper_closed_ = false;
      state_ = DriverState::homed;
      break;
    case JobKind::position: {
      PositionReading r;
      r.request = job.id;
      r.stamp = config_.tick * static_cast<std::int64_t>(now_);
      if (config_.capabilities.reads_joints) r.joints = joints_;
      if (config_.capabilities.reads_pose) r.tool_pose = pose_;
      last_position_ = std::move(r);
      break;
    }
    case JobKind::command:
      std::visit(
          [&](const auto& c) {
            using C = std::decay_t<decltype(c)>;
            if constexpr (std::is_same_v<C, MoveJoints>) {
              joints_ = c.positions;
            } else if constexpr (std::is_same_v<C, MovePose>) {
              pose_ = c.pose;
            } else if constexpr (std::is_same_v<C, Grip>) {
              gripper_closed_ = c.action == Grip::Action::close;
            } else if constexpr (std::is_same_v<C, SetOutput>) {
              outputs_[static_cast<std::size_t>(c.channel - 1)] = c.on;
            }
          },
          *job.command);
      break;
  }
  set_status(job.id, CommandPhase::done);
  start_head();
}

void ScriptedDriver::fail_head(ErrorCode error, std::string message) {
  const CommandId id = queue_.front().id;
  queue_.pop_front();
  set_status(id, CommandPhase::failed, error, std::move(message));
  if (error == ErrorCode::connection_lost) {
    fail_all(ErrorCode::connection_lost, "the link to the controller dropped");
    link_up_ = false;
  } else {
    fail_all(ErrorCode::cancelled, fmt::format("cancelled: command {} before it failed", id));
  }
  if (fatal(error)) state_ = DriverState::fault;
}

void ScriptedDriver::start_head() {
  if (!queue_.empty()) set_status(queue_.front().id, CommandPhase::running);
}

void ScriptedDriver::notify_if(bool changed, std::unique_lock<std::mutex>& lock) {
  if (!changed) return;
  const std::function<void()> notify = notify_;
  lock.unlock();
  if (notify) notify();
}

}  // namespace cellwright::drivers
