// FaultyDriver: a RobotDriver decorator that makes any other driver (simulated, scripted, serial; built on DriverCore
// or not) fail on purpose, seeded and deterministic, for the tests of fault recovery. What it injects into submitted
// commands:
//  - the n-th submitted command, or the n-th of one kind (e.g. the 2nd Grip), fails with a chosen ErrorCode:
//    unreachable or timeout (the command fails, the driver stays as it was), hardware or protocol (the driver enters
//    fault), connection_lost (fault, and reset() then leaves it disconnected);
//  - or it never completes: it runs until stop(), disconnect() or a fault ends it;
//  - or the n-th of a set of kinds counted together (KindsRule: every move, joint or pose);
//  - or, with a probability, each submitted command draws one of a list of such faults from a generator seeded by
//    the plan (std::mt19937_64: the same seed and the same sequence of submissions give the same faults).
//
// HOW A FAILURE CANCELS WHAT IS BEHIND IT. The decorator keeps its own ids (1, 2, 3, ... in acceptance order, as the
// contract says) and forwards commands to the wrapped driver as they come, mapping ids both ways, until a command is
// chosen for a fault. That command and every command accepted after it are held in the decorator, never reach the
// wrapped driver, and poll as pending. The chosen command reaches the head when the last command forwarded before it
// has finished in the wrapped driver (its queue is FIFO); then it fails with its error, and every held command behind
// it fails as a real failure would make it (cancelled, "cancelled: command N before it failed"; connection_lost for a
// lost link). If a forwarded command failed first, the wrapped driver cancelled its own queue, and the held ones are
// cancelled too. An injected hardware, protocol or connection_lost error disconnects the wrapped driver (the robot
// stops) and shows fault until reset(), which connects it again (connected: home again), or for connection_lost goes
// to disconnected. So the commands behind a failure never move the robot, whatever the wrapped driver is.
//
// LIMITS (the price of wrapping any driver without reaching into it):
//  - The injected failure happens when the owner next calls the decorator after the command reached the head (the
//    decorator has no thread); the decorator then calls the notifier itself, on the owner's thread, with no lock held
//    (as stop() does in every driver). A held command never runs, so it takes no time on the wrapped driver.
//  - Held commands are checked by the contract's rules only (state, check_command(), queue depth counted over the
//    held ones); refusals particular to the wrapped driver cannot happen to them, since they never reach it.
//  - Ids of the wrapped driver show through in its messages ("cancelled: command 7 before it failed"): after the
//    first injection the two numberings differ.
//  - An injection chosen while another one is still held is not made (the command is behind it and is cancelled);
//    it is not counted.
//  - With reads_while_moving, position requests are always forwarded (they are behind nothing); otherwise they are
//    held like commands while something is held.
//
// INJECTION CALLBACK. FaultPlan::on_injection is told of each command chosen for a fault (not of one that is not made),
// inside the submit() that accepted it, so that a caller can report the injection (ScenarioRun does, as the plant's
// injected faults).
//
// THREADS. As every RobotDriver: one owner calls every method, including the counters (injected()); the callback
// runs on it. The wrapped
// driver's own threads call the notifier as before.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"

namespace cellwright::drivers {

// The kinds of Command, in the order of its alternatives.
enum class CommandKind : std::uint8_t { move_joints, move_pose, grip, set_output, wait_input };
inline constexpr std::size_t kCommandKinds = 5;
CommandKind kind_of(const Command& command);
std::string_view to_string(CommandKind kind);

// What happens to a command chosen for a fault.
struct Fault {
  ErrorCode error = ErrorCode::timeout;  // unreachable, timeout, hardware, protocol, connection_lost
  bool never_completes = false;          // true: it runs until stopped, and `error` is not used
  std::string message;                   // the failed command's message; empty: "injected <error>"
};

// The n-th command submitted (counting from 1, accepted submit() calls only; home() and request_position() do not
// count), or the n-th of `kind` when it is set.
struct FaultRule {
  std::optional<CommandKind> kind;
  std::uint64_t nth = 1;
  Fault fault;
};

// The n-th command of any of `kinds`, counted together ({move_joints, move_pose}: every move).
struct KindsRule {
  std::vector<CommandKind> kinds;
  std::uint64_t nth = 1;
  Fault fault;
};

// Told of each command chosen for a fault, on the owner's thread, inside the submit() that accepted it: its id, the
// command, the fault. It must not call the decorator.
using InjectionCallback = std::function<void(CommandId, const Command&, const Fault&)>;

struct FaultPlan {
  std::vector<FaultRule> rules;  // the first rule that matches a command decides ...
  std::vector<KindsRule> kinds_rules;  // ... then the first of these
  // Random faults: a command that no rule chose draws a fault with this probability, uniformly among `random`.
  double probability = 0.0;
  std::vector<Fault> random;
  std::uint64_t seed = 1;
  InjectionCallback on_injection;  // may be empty
};

class FaultyDriver final : public RobotDriver {
 public:
  // What the decorator did, for tests.
  struct Injected {
    std::uint64_t failed = 0;                     // commands failed by injection
    std::map<ErrorCode, std::uint64_t> by_error;  // ... by error
    std::uint64_t never_completed = 0;            // commands made to run forever
    std::uint64_t cancelled_behind = 0;           // held commands failed behind an injected or earlier failure
    std::vector<CommandId> commands;              // the ids chosen for a fault, in order
  };

  // Wraps `inner`, which must outlive the decorator and must be used only through it from now on. Throws
  // InternalError when the plan is inconsistent (an error a controller does not report, nth 0, a probability outside
  // [0, 1], or a probability without faults to draw from).
  FaultyDriver(RobotDriver& inner, FaultPlan plan);

  // ---- RobotDriver (the owner thread): see robot_driver.hpp and the notes above ----
  const Capabilities& capabilities() const override;
  DriverState state() const override;
  ErrorCode connect() override;
  void disconnect() override;
  Submitted home() override;
  ErrorCode activate() override;
  void stop() override;
  ErrorCode reset() override;
  Submitted submit(const Command& command) override;
  Submitted request_position() override;
  CommandStatus poll(CommandId id) const override;
  std::optional<PositionReading> last_position() const override;
  void set_notifier(std::function<void()> notify) override;
  void set_clock(Clock clock) override;
  std::optional<GripSense> grip_sense() const override { return inner_.grip_sense(); }
  std::optional<double> least_duration(const Command& command) const override {
    return inner_.least_duration(command);
  }

  // ---- Queries (the owner thread) ----
  const Injected& injected() const { return injected_; }

 private:
  enum class Kind : std::uint8_t { home, command, position };
  struct Held {
    CommandId id = 0;
    Kind kind = Kind::command;
  };

  // The chosen command reaches the head once the last command forwarded before it has finished. Calls the notifier
  // when something failed. Every public method starts with it.
  void update() const;
  // Fails every held command (the chosen one included unless it already failed) with `error` and `message`.
  void cancel_held(ErrorCode error, const std::string& message) const;
  void set_status(CommandId id, CommandPhase phase, ErrorCode error = ErrorCode::none, std::string message = {}) const;
  // Holds a command (the chosen one or one behind it), after the contract's checks; refuses busy when the held ones
  // fill the queue depth.
  Submitted hold(Kind kind) const;
  // Forwards an accepted inner submission: gives it an outer id.
  Submitted forwarded(const Submitted& inner, bool queued) const;
  std::optional<Fault> choose(const Command& command);
  void notify_if(bool changed) const;

  RobotDriver& inner_;
  const FaultPlan plan_;
  std::mt19937_64 rng_;
  std::uint64_t submitted_ = 0;
  std::array<std::uint64_t, kCommandKinds> submitted_by_kind_{};

  // The owner's calls of const methods move the decorator on too (update()), hence mutable.
  mutable CommandId next_id_ = 1;
  mutable std::map<CommandId, CommandId> to_inner_, to_outer_;  // forwarded commands, both ways
  mutable std::deque<CommandId> forwarded_;                     // outer ids forwarded, oldest first (retention)
  mutable CommandId last_queued_inner_ = 0;                     // the last command forwarded into the inner queue
  mutable std::optional<Fault> fault_;                          // for held_.front() while it has not started
  mutable CommandId wait_for_ = 0;  // inner id that must finish before held_.front() starts (0: none)
  mutable std::deque<Held> held_;   // the chosen command, then the ones behind it
  mutable bool stalled_ = false;    // held_.front() is running forever
  mutable bool in_fault_ = false;   // an injected fatal error; the inner driver is disconnected meanwhile
  mutable bool link_lost_ = false;  // ... and it was connection_lost
  mutable std::map<CommandId, CommandStatus> statuses_;  // of held commands
  mutable std::deque<CommandId> finished_;
  mutable Injected injected_;
  std::function<void()> notify_;
};

}  // namespace cellwright::drivers
