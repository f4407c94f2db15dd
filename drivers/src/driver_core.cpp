#include "cellwright/drivers/driver_core.hpp"

#include <fmt/format.h>

#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers {

namespace {

bool fatal(ErrorCode e) {
  return e == ErrorCode::hardware || e == ErrorCode::protocol || e == ErrorCode::connection_lost ||
         e == ErrorCode::unknown;
}

bool controller_error(ErrorCode e) {
  return e == ErrorCode::unreachable || e == ErrorCode::timeout || fatal(e);
}

Submitted refuse(ErrorCode error, std::string message) {
  return {0, error, std::move(message)};
}

}  // namespace

// ---- Controller ---------------------------------------------------------------------------------------------------

DriverCore::Controller::Controller(DriverCore& core) : core_(&core), lock_(core.mutex_) {}

DriverCore::Controller::Controller(Controller&& other) noexcept
    : core_(std::exchange(other.core_, nullptr)), lock_(std::move(other.lock_)) {}

DriverCore::Controller::~Controller() {
  if (core_ != nullptr && lock_.owns_lock()) core_->release_and_notify(lock_);
}

DriverState DriverCore::Controller::state() const {
  return core_->state_;
}

DriverCore::Job* DriverCore::Controller::head() {
  return core_->queue_.empty() ? nullptr : &core_->queue_.front();
}

const std::deque<DriverCore::Job>& DriverCore::Controller::queued() const {
  return core_->queue_;
}

std::deque<DriverCore::Job>& DriverCore::Controller::reads() {
  return core_->reads_;
}

bool DriverCore::Controller::start(CommandId id) {
  if (core_->queue_.empty() || core_->queue_.front().id != id) return false;
  core_->set_status(id, CommandPhase::running);
  return true;
}

bool DriverCore::Controller::complete(CommandId id) {
  DriverCore& c = *core_;
  if (!c.queue_.empty() && c.queue_.front().id == id) {
    CW_CHECK(c.queue_.front().kind != JobKind::position, "position request {} completed without a reading", id);
    if (c.queue_.front().kind == JobKind::home) c.state_ = DriverState::homed;
    c.queue_.pop_front();
    c.set_status(id, CommandPhase::done);
    c.head_changed();
    return true;
  }
  for (const Job& r : c.reads_) {
    CW_CHECK(r.id != id, "position request {} completed without a reading", id);
  }
  return false;
}

bool DriverCore::Controller::complete(CommandId id, PositionReading reading) {
  DriverCore& c = *core_;
  reading.request = id;
  if (!c.queue_.empty() && c.queue_.front().id == id) {
    CW_CHECK(c.queue_.front().kind == JobKind::position, "command {} completed with a position reading", id);
    c.queue_.pop_front();
    c.last_position_ = std::move(reading);
    c.set_status(id, CommandPhase::done);
    c.head_changed();
    return true;
  }
  for (auto it = c.reads_.begin(); it != c.reads_.end(); ++it) {
    if (it->id != id) continue;
    c.reads_.erase(it);
    c.last_position_ = std::move(reading);
    c.set_status(id, CommandPhase::done);
    return true;
  }
  return false;
}

bool DriverCore::Controller::fail(CommandId id, ErrorCode error, std::string message) {
  CW_CHECK(controller_error(error), "a controller cannot fail a command with {}", to_string(error));
  DriverCore& c = *core_;
  if (!c.queue_.empty() && c.queue_.front().id == id) {
    c.queue_.pop_front();
    c.set_status(id, CommandPhase::failed, error, std::move(message));
    if (error == ErrorCode::connection_lost) {
      c.fail_all(ErrorCode::connection_lost, "the link to the controller dropped");
      c.link_up_ = false;
    } else {
      c.fail_queue(ErrorCode::cancelled, fmt::format("cancelled: command {} before it failed", id));
      if (fatal(error)) c.fail_all(ErrorCode::cancelled, fmt::format("cancelled: command {} failed", id));
    }
  } else {
    auto it = c.reads_.begin();
    while (it != c.reads_.end() && it->id != id) ++it;
    if (it == c.reads_.end()) return false;
    c.reads_.erase(it);
    c.set_status(id, CommandPhase::failed, error, std::move(message));
    if (error == ErrorCode::connection_lost) {
      c.fail_all(ErrorCode::connection_lost, "the link to the controller dropped");
      c.link_up_ = false;
    } else if (fatal(error)) {
      c.fail_all(ErrorCode::cancelled, fmt::format("cancelled: command {} failed", id));
    }
  }
  if (fatal(error) && c.state_ != DriverState::disconnected) {
    if (auto st = c.statuses_.find(id); c.state_ != DriverState::fault && st != c.statuses_.end()) {
      c.fault_cause_ = st->second.message;
    }
    c.state_ = DriverState::fault;
  }
  return true;
}

bool DriverCore::Controller::withdraw(CommandId id, std::string message) {
  DriverCore& c = *core_;
  if (c.queue_.empty() || c.queue_.front().id != id || c.queue_.front().kind != JobKind::position) return false;
  const auto it = c.statuses_.find(id);
  if (it == c.statuses_.end() || it->second.phase != CommandPhase::pending) return false;
  c.queue_.pop_front();
  c.set_status(id, CommandPhase::failed, ErrorCode::cancelled, std::move(message));
  c.head_changed();
  return true;
}

void DriverCore::Controller::raise_fault(ErrorCode error, std::string message) {
  CW_CHECK(fatal(error), "a fault is hardware, protocol, connection_lost or unknown, not {}", to_string(error));
  DriverCore& c = *core_;
  c.fail_all(error, message);
  if (error == ErrorCode::connection_lost) c.link_up_ = false;
  if (c.state_ != DriverState::disconnected) {
    if (c.state_ != DriverState::fault) c.fault_cause_ = message;
    c.state_ = DriverState::fault;
  }
  c.changed_ = true;
}

std::chrono::nanoseconds DriverCore::Controller::stamp(std::chrono::nanoseconds own) const {
  return core_->clock_ ? core_->clock_() : own;
}

// ---- Setup --------------------------------------------------------------------------------------------------------

DriverCore::DriverCore(RunningWhen running_when) : running_when_(running_when) {}

void DriverCore::set_capabilities(Capabilities capabilities) {
  CW_CHECK(!capabilities_set_, "a driver's capabilities are set once");
  CW_CHECK(capabilities.queue_depth > 0, "queue_depth must be at least 1");
  capabilities_ = std::move(capabilities);
  capabilities_set_ = true;
}

DriverCore::Controller DriverCore::controller() {
  return Controller(*this);
}

std::unique_lock<std::mutex> DriverCore::lock() const {
  return std::unique_lock(mutex_);
}

std::unique_lock<std::mutex> DriverCore::lock(std::try_to_lock_t) const {
  return std::unique_lock(mutex_, std::try_to_lock);
}

DriverCore::Calls DriverCore::calls() const {
  std::lock_guard lock(mutex_);
  return calls_;
}

// ---- RobotDriver --------------------------------------------------------------------------------------------------

const Capabilities& DriverCore::capabilities() const {
  return capabilities_;
}

DriverState DriverCore::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

ErrorCode DriverCore::connect() {
  {
    std::lock_guard lock(mutex_);
    ++calls_.connect;
    if (state_ != DriverState::disconnected) return ErrorCode::wrong_state;
  }
  // Only the owner calls connect(), and nothing else leaves disconnected: the state cannot change meanwhile.
  const ErrorCode e = connect_hook();
  if (e != ErrorCode::none) return e;
  std::lock_guard lock(mutex_);
  state_ = DriverState::connected;
  link_up_ = true;
  return ErrorCode::none;
}

void DriverCore::disconnect() {
  {
    std::unique_lock lock(mutex_);
    ++calls_.disconnect;
    fail_all(ErrorCode::cancelled, "cancelled by disconnect()");
    halt_hook();
    state_ = DriverState::disconnected;
    link_up_ = false;
    release_and_notify(lock);
  }
  disconnect_hook();
}

Submitted DriverCore::home() {
  std::lock_guard lock(mutex_);
  ++calls_.home;
  if (state_ != DriverState::connected && state_ != DriverState::homed && state_ != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("home() is not allowed while {}", to_string(state_)));
  }
  return accept(JobKind::home, std::nullopt);
}

ErrorCode DriverCore::activate() {
  std::lock_guard lock(mutex_);
  ++calls_.activate;
  if (state_ != DriverState::homed && state_ != DriverState::stopped) return ErrorCode::wrong_state;
  for (const Job& j : queue_) {
    if (j.kind == JobKind::home) return ErrorCode::wrong_state;  // still homing
  }
  state_ = DriverState::active;
  return ErrorCode::none;
}

void DriverCore::stop() {
  std::unique_lock lock(mutex_);
  ++calls_.stop;
  fail_all(ErrorCode::cancelled, "cancelled by stop()");
  halt_hook();
  if (state_ == DriverState::active) state_ = DriverState::stopped;
  release_and_notify(lock);
}

ErrorCode DriverCore::reset() {
  std::lock_guard lock(mutex_);
  ++calls_.reset;
  if (state_ != DriverState::fault) return ErrorCode::wrong_state;
  const ErrorCode e = link_up_ ? reset_hook() : ErrorCode::connection_lost;
  CW_CHECK(e == ErrorCode::none || e == ErrorCode::connection_lost, "reset_hook returned {}", to_string(e));
  if (e == ErrorCode::connection_lost) {
    state_ = DriverState::disconnected;
    link_up_ = false;
    return ErrorCode::connection_lost;
  }
  state_ = DriverState::connected;
  return ErrorCode::none;
}

Submitted DriverCore::submit(const Command& command) {
  std::lock_guard lock(mutex_);
  ++calls_.submit;
  if (state_ != DriverState::active) {
    // In fault: what put it there, so that a command refused a moment after a failure still names its cause.
    return refuse(ErrorCode::wrong_state,
                  fmt::format("{} refused: the driver is {}, not active{}", describe(command), to_string(state_),
                              state_ == DriverState::fault && !fault_cause_.empty()
                                  ? fmt::format(" (in fault since: {})", fault_cause_)
                                  : std::string()));
  }
  if (Refusal r = check_command(command, capabilities_)) return refuse(r.error, std::move(r.message));
  if (Refusal r = check_hook(command)) return refuse(r.error, std::move(r.message));
  return accept(JobKind::command, command);
}

Submitted DriverCore::request_position() {
  std::lock_guard lock(mutex_);
  ++calls_.request_position;
  if (state_ != DriverState::connected && state_ != DriverState::homed && state_ != DriverState::active &&
      state_ != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("request_position() is not allowed while {}", to_string(state_)));
  }
  return accept(JobKind::position, std::nullopt);
}

CommandStatus DriverCore::poll(CommandId id) const {
  std::lock_guard lock(mutex_);
  ++calls_.poll;
  const auto it = statuses_.find(id);
  if (it != statuses_.end()) return it->second;
  return {id, CommandPhase::failed, ErrorCode::unknown_command,
          fmt::format("command {} was never issued or is no longer retained", id)};
}

std::optional<PositionReading> DriverCore::last_position() const {
  std::lock_guard lock(mutex_);
  ++calls_.last_position;
  return last_position_;
}

void DriverCore::set_notifier(std::function<void()> notify) {
  std::lock_guard lock(mutex_);
  ++calls_.set_notifier;
  notify_ = std::move(notify);
}

void DriverCore::set_clock(Clock clock) {
  std::lock_guard lock(mutex_);
  ++calls_.set_clock;
  clock_ = std::move(clock);
}

// ---- Bookkeeping (mutex held) -------------------------------------------------------------------------------------

Submitted DriverCore::accept(JobKind kind, std::optional<Command> command) {
  if (in_flight() >= capabilities_.queue_depth) {
    return refuse(ErrorCode::busy, fmt::format("{} command(s) already in flight (queue depth {})", in_flight(),
                                               capabilities_.queue_depth));
  }
  Job job;
  job.id = next_id_++;
  job.kind = kind;
  job.command = std::move(command);
  accept_hook(job);
  const CommandId id = job.id;
  if (kind == JobKind::position && capabilities_.reads_while_moving) {
    reads_.push_back(std::move(job));
    set_status(id, CommandPhase::running);  // answered at the next tick, whatever runs
    return {id, ErrorCode::none, {}};
  }
  queue_.push_back(std::move(job));
  set_status(
      id, queue_.size() == 1 && running_when_ == RunningWhen::at_head ? CommandPhase::running : CommandPhase::pending);
  return {id, ErrorCode::none, {}};
}

void DriverCore::set_status(CommandId id, CommandPhase phase, ErrorCode error, std::string message) {
  statuses_[id] = {id, phase, error, std::move(message)};
  if (phase != CommandPhase::done && phase != CommandPhase::failed) return;
  changed_ = true;
  finished_.push_back(id);
  while (finished_.size() > kStatusRetention) {
    statuses_.erase(finished_.front());
    finished_.pop_front();
  }
}

bool DriverCore::fail_queue(ErrorCode error, const std::string& message) {
  const bool any = !queue_.empty();
  for (const Job& j : queue_) set_status(j.id, CommandPhase::failed, error, message);
  queue_.clear();
  return any;
}

bool DriverCore::fail_all(ErrorCode error, const std::string& message) {
  // In id order, so that the retention drops the oldest first.
  std::map<CommandId, bool> ids;
  for (const Job& j : queue_) ids[j.id] = true;
  for (const Job& j : reads_) ids[j.id] = true;
  for (const auto& [id, unused] : ids) set_status(id, CommandPhase::failed, error, message);
  queue_.clear();
  reads_.clear();
  return !ids.empty();
}

void DriverCore::head_changed() {
  if (!queue_.empty() && running_when_ == RunningWhen::at_head) set_status(queue_.front().id, CommandPhase::running);
}

void DriverCore::release_and_notify(std::unique_lock<std::mutex>& lock) {
  const bool changed = std::exchange(changed_, false);
  const std::function<void()> notify = changed ? notify_ : std::function<void()>();
  lock.unlock();
  if (notify) notify();
}

}  // namespace cellwright::drivers
