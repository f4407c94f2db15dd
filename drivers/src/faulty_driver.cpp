#include "cellwright/drivers/faulty_driver.hpp"

#include <fmt/format.h>

#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers {

namespace {

bool fatal(ErrorCode e) {
  return e == ErrorCode::hardware || e == ErrorCode::protocol || e == ErrorCode::connection_lost ||
         e == ErrorCode::unknown;
}

void check_fault(const Fault& f) {
  if (f.never_completes) return;
  CW_CHECK(f.error == ErrorCode::unreachable || f.error == ErrorCode::timeout || fatal(f.error),
           "a controller cannot fail a command with {}", to_string(f.error));
}

Submitted refuse(ErrorCode error, std::string message) {
  return {0, error, std::move(message)};
}

}  // namespace

CommandKind kind_of(const Command& command) {
  return static_cast<CommandKind>(command.index());
}

std::string_view to_string(CommandKind kind) {
  switch (kind) {
    case CommandKind::move_joints:
      return "move_joints";
    case CommandKind::move_pose:
      return "move_pose";
    case CommandKind::grip:
      return "grip";
    case CommandKind::set_output:
      return "set_output";
    case CommandKind::wait_input:
      return "wait_input";
  }
  return "?";
}

FaultyDriver::FaultyDriver(RobotDriver& inner, FaultPlan plan)
    : inner_(inner), plan_(std::move(plan)), rng_(plan_.seed) {
  for (const FaultRule& r : plan_.rules) {
    CW_CHECK(r.nth > 0, "a fault rule counts commands from 1, got nth 0");
    check_fault(r.fault);
  }
  for (const KindsRule& r : plan_.kinds_rules) {
    CW_CHECK(r.nth > 0 && !r.kinds.empty(), "a fault rule counts commands of some kinds from 1");
    check_fault(r.fault);
  }
  CW_CHECK(plan_.probability >= 0.0 && plan_.probability <= 1.0, "fault probability {} is outside [0, 1]",
           plan_.probability);
  CW_CHECK(plan_.probability == 0.0 || !plan_.random.empty(), "a fault probability needs faults to draw from");
  for (const Fault& f : plan_.random) check_fault(f);
}

// ---- RobotDriver --------------------------------------------------------------------------------------------------

const Capabilities& FaultyDriver::capabilities() const {
  return inner_.capabilities();
}

DriverState FaultyDriver::state() const {
  update();
  return in_fault_ ? DriverState::fault : inner_.state();
}

ErrorCode FaultyDriver::connect() {
  update();
  if (in_fault_) return ErrorCode::wrong_state;
  return inner_.connect();
}

void FaultyDriver::disconnect() {
  update();
  const bool any = !held_.empty();
  cancel_held(ErrorCode::cancelled, "cancelled by disconnect()");
  in_fault_ = false;
  link_lost_ = false;
  inner_.disconnect();
  notify_if(any);
}

Submitted FaultyDriver::home() {
  update();
  const DriverState s = state();
  if (s != DriverState::connected && s != DriverState::homed && s != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("home() is not allowed while {}", to_string(s)));
  }
  if (!held_.empty()) return hold(Kind::home);
  const Submitted in = inner_.home();
  return in.accepted() ? forwarded(in, true) : in;
}

ErrorCode FaultyDriver::activate() {
  update();
  if (in_fault_) return ErrorCode::wrong_state;
  for (const Held& h : held_) {
    if (h.kind == Kind::home) return ErrorCode::wrong_state;  // a homing is still in flight
  }
  return inner_.activate();
}

void FaultyDriver::stop() {
  update();
  const bool any = !held_.empty();
  cancel_held(ErrorCode::cancelled, "cancelled by stop()");
  inner_.stop();
  notify_if(any);
}

ErrorCode FaultyDriver::reset() {
  update();
  if (!in_fault_) return inner_.reset();
  in_fault_ = false;
  if (std::exchange(link_lost_, false)) return ErrorCode::connection_lost;  // the wrapped driver is disconnected
  // The controller's error is cleared: the wrapped driver, disconnected by the injection, is connected again.
  return inner_.connect() == ErrorCode::none ? ErrorCode::none : ErrorCode::connection_lost;
}

Submitted FaultyDriver::submit(const Command& command) {
  update();
  const DriverState s = state();
  if (s != DriverState::active) {
    return refuse(ErrorCode::wrong_state,
                  fmt::format("{} refused: the driver is {}, not active", describe(command), to_string(s)));
  }
  if (Refusal r = check_command(command, capabilities())) return refuse(r.error, std::move(r.message));
  // Counted and drawn before it is known whether the command is accepted; undone if it is not, so that only
  // accepted submissions count.
  const std::mt19937_64 rng = rng_;
  const std::uint64_t submitted = submitted_;
  const std::array<std::uint64_t, kCommandKinds> by_kind = submitted_by_kind_;
  const std::optional<Fault> fault = choose(command);
  const auto undo = [&] {
    rng_ = rng;
    submitted_ = submitted;
    submitted_by_kind_ = by_kind;
  };
  if (!held_.empty() || fault) {
    const Submitted h = hold(Kind::command);
    if (!h.accepted()) {
      undo();
      return h;
    }
    if (fault && held_.size() == 1) {  // chosen, and not behind another chosen command
      fault_ = fault;
      // It waits for the wrapped driver's last command if that is still in flight; one that has ended (a stop()
      // cancelled it, say) is not in front of it, and its failure is not one this command is behind.
      wait_for_ = last_queued_inner_;
      if (wait_for_ != 0) {
        const CommandPhase before = inner_.poll(wait_for_).phase;
        if (before != CommandPhase::pending && before != CommandPhase::running) wait_for_ = 0;
      }
      injected_.commands.push_back(h.id);
      if (plan_.on_injection) plan_.on_injection(h.id, command, *fault);
      update();
    }
    return h;
  }
  const Submitted in = inner_.submit(command);
  if (!in.accepted()) {
    undo();
    return in;
  }
  return forwarded(in, true);
}

Submitted FaultyDriver::request_position() {
  update();
  const DriverState s = state();
  if (s != DriverState::connected && s != DriverState::homed && s != DriverState::active &&
      s != DriverState::stopped) {
    return refuse(ErrorCode::wrong_state, fmt::format("request_position() is not allowed while {}", to_string(s)));
  }
  const bool out_of_queue = capabilities().reads_while_moving;
  if (!held_.empty() && !out_of_queue) return hold(Kind::position);
  const Submitted in = inner_.request_position();
  return in.accepted() ? forwarded(in, !out_of_queue) : in;
}

CommandStatus FaultyDriver::poll(CommandId id) const {
  update();
  if (const auto it = statuses_.find(id); it != statuses_.end()) return it->second;
  if (const auto it = to_inner_.find(id); it != to_inner_.end()) {
    CommandStatus s = inner_.poll(it->second);
    s.id = id;
    return s;
  }
  return {id, CommandPhase::failed, ErrorCode::unknown_command,
          fmt::format("command {} was never issued or is no longer retained", id)};
}

std::optional<PositionReading> FaultyDriver::last_position() const {
  update();
  std::optional<PositionReading> r = inner_.last_position();
  if (r) {
    const auto it = to_outer_.find(r->request);
    r->request = it != to_outer_.end() ? it->second : 0;
  }
  return r;
}

void FaultyDriver::set_notifier(std::function<void()> notify) {
  notify_ = notify;
  inner_.set_notifier(std::move(notify));
}

void FaultyDriver::set_clock(Clock clock) {
  inner_.set_clock(std::move(clock));
}

// ---- Injection ----------------------------------------------------------------------------------------------------

std::optional<Fault> FaultyDriver::choose(const Command& command) {
  const auto kind = static_cast<std::size_t>(kind_of(command));
  ++submitted_;
  ++submitted_by_kind_[kind];
  std::optional<Fault> chosen;
  if (plan_.probability > 0.0) {
    // Two draws for every submission, whatever the rules decide, so that a seed gives the same stream.
    const double u = static_cast<double>(rng_() >> 11) * 0x1.0p-53;
    const std::uint64_t pick = rng_() % plan_.random.size();
    if (u < plan_.probability) chosen = plan_.random[pick];
  }
  for (const FaultRule& r : plan_.rules) {
    const bool match =
        r.kind ? static_cast<std::size_t>(*r.kind) == kind && submitted_by_kind_[kind] == r.nth : submitted_ == r.nth;
    if (match) return r.fault;
  }
  for (const KindsRule& r : plan_.kinds_rules) {
    std::uint64_t count = 0;
    bool of_kind = false;
    for (CommandKind k : r.kinds) {
      count += submitted_by_kind_[static_cast<std::size_t>(k)];
      of_kind = of_kind || static_cast<std::size_t>(k) == kind;
    }
    if (of_kind && count == r.nth) return r.fault;
  }
  return chosen;
}

void FaultyDriver::update() const {
  if (held_.empty()) return;
  if (stalled_) {
    // A fault of the wrapped driver ends the command that never completes, as it ends every command in flight.
    const DriverState s = inner_.state();
    if (s == DriverState::fault || s == DriverState::disconnected) {
      cancel_held(ErrorCode::cancelled, fmt::format("cancelled: the driver is {}", to_string(s)));
      notify_if(true);
    }
    return;
  }
  if (!fault_) return;
  if (wait_for_ != 0) {
    const CommandStatus s = inner_.poll(wait_for_);
    if (s.phase == CommandPhase::pending || s.phase == CommandPhase::running) return;
    if (s.phase == CommandPhase::failed && s.error != ErrorCode::unknown_command) {
      // The wrapped driver cancelled what was behind its failure; the held commands were behind it too.
      const auto outer = to_outer_.find(wait_for_);
      injected_.cancelled_behind += held_.size();
      cancel_held(ErrorCode::cancelled,
                  fmt::format("cancelled: command {} before it failed", outer != to_outer_.end() ? outer->second : 0));
      notify_if(true);
      return;
    }
  }
  // The chosen command is at the head now.
  const Fault fault = *fault_;
  fault_.reset();
  wait_for_ = 0;
  const CommandId id = held_.front().id;
  if (fault.never_completes) {
    stalled_ = true;
    set_status(id, CommandPhase::running);
    ++injected_.never_completed;
    return;
  }
  held_.pop_front();
  set_status(id, CommandPhase::failed, fault.error,
             fault.message.empty() ? fmt::format("injected {}", to_string(fault.error)) : fault.message);
  ++injected_.failed;
  ++injected_.by_error[fault.error];
  injected_.cancelled_behind += held_.size();
  if (fault.error == ErrorCode::connection_lost) {
    cancel_held(ErrorCode::connection_lost, "the link to the controller dropped");
  } else {
    cancel_held(ErrorCode::cancelled, fmt::format("cancelled: command {} before it failed", id));
  }
  if (fatal(fault.error)) {
    inner_.disconnect();  // the robot stops; reset() connects it again
    in_fault_ = true;
    link_lost_ = fault.error == ErrorCode::connection_lost;
  }
  notify_if(true);
}

void FaultyDriver::cancel_held(ErrorCode error, const std::string& message) const {
  for (const Held& h : held_) set_status(h.id, CommandPhase::failed, error, message);
  held_.clear();
  stalled_ = false;
  fault_.reset();
  wait_for_ = 0;
}

Submitted FaultyDriver::hold(Kind kind) const {
  const std::size_t depth = capabilities().queue_depth;
  if (held_.size() >= depth) {
    return refuse(ErrorCode::busy,
                  fmt::format("{} command(s) already in flight (queue depth {})", held_.size(), depth));
  }
  const CommandId id = next_id_++;
  held_.push_back({id, kind});
  set_status(id, CommandPhase::pending);
  return {id, ErrorCode::none, {}};
}

Submitted FaultyDriver::forwarded(const Submitted& inner, bool queued) const {
  const CommandId id = next_id_++;
  to_inner_[id] = inner.id;
  to_outer_[inner.id] = id;
  forwarded_.push_back(id);
  if (queued) last_queued_inner_ = inner.id;
  // The wrapped driver keeps kStatusRetention statuses; the mapping of older ids is of no use.
  while (forwarded_.size() > kStatusRetention) {
    const auto it = to_inner_.find(forwarded_.front());
    to_outer_.erase(it->second);
    to_inner_.erase(it);
    forwarded_.pop_front();
  }
  return {id, ErrorCode::none, {}};
}

void FaultyDriver::set_status(CommandId id, CommandPhase phase, ErrorCode error, std::string message) const {
  statuses_[id] = {id, phase, error, std::move(message)};
  if (phase != CommandPhase::done && phase != CommandPhase::failed) return;
  finished_.push_back(id);
  while (finished_.size() > kStatusRetention) {
    statuses_.erase(finished_.front());
    finished_.pop_front();
  }
}

void FaultyDriver::notify_if(bool changed) const {
  if (changed && notify_) notify_();
}

}  // namespace cellwright::drivers
