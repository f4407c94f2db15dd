// ScriptedDriver: a RobotDriver test double with a virtual controller behind it. It follows the interface's rules
// exactly (lifecycle, refusals, one queue, cancellation, fault handling), executes commands on virtual time that the
// test (or the runtime's simulation thread) advances tick by tick, counts every call, and fails on request: a chosen
// command with a chosen error, the link dropping, a command that never completes, a port that is not there.
//
// The scripted robot has no kinematics: after a MoveJoints its joints are the target; after a MovePose its tool pose
// is the target; homing puts both at the configured home values. Position read-backs report those, stamped with the
// virtual time at which they complete.
//
// Time: advance(n) runs n ticks. On each tick the command at the head of the queue (the running one) does one tick of
// work; a command of duration d completes on the d-th tick after it reached the head, and the next one becomes
// running at once but starts working on the following tick. A WaitInput instead checks its input on each tick, and
// fails when its timeout (converted at config.tick per tick) has passed.
//
// Threads: the owner calls the RobotDriver methods; advance() and the test controls may be called from any thread
// (e.g. the runtime's simulation thread), as the communication thread of a serial driver would run. All state is
// behind one mutex; the notifier is called with it released.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/robot_driver.hpp"

namespace cellwright::drivers {

struct ScriptedDriverConfig {
  SourceLocation where;       // the robot's entry in the cell file: connect() failures name it
  Capabilities capabilities;  // what the double claims to be able to do
  std::chrono::nanoseconds tick{std::chrono::milliseconds(1)};  // virtual time per tick (stamps, wait timeouts)
  std::uint64_t home_ticks = 10;                                // duration of home(), >= 1
  std::uint64_t position_ticks = 1;                             // duration of request_position(), >= 1
  std::uint64_t command_ticks = 5;                              // duration of a submitted command, >= 1 ...
  std::function<std::uint64_t(const Command&)> ticks_for;       // ... unless this is set: then it decides (>= 1)
  std::vector<double> home_joints;                              // joints after homing; empty means all zero
  Eigen::Isometry3d home_pose = Eigen::Isometry3d::Identity();  // tool pose after homing
};

class ScriptedDriver final : public RobotDriver {
 public:
  // Throws InternalError when the configuration is inconsistent (a duration of 0, a tick <= 0, queue_depth 0,
  // home_joints of the wrong length): the test is wrong, not the robot.
  explicit ScriptedDriver(ScriptedDriverConfig config);

  // RobotDriver: see robot_driver.hpp.
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

  // ---- The virtual controller (any thread) ----

  // Runs the controller for `ticks` ticks of virtual time.
  void advance(std::uint64_t ticks = 1);
  // Ticks run so far.
  std::uint64_t now_ticks() const;

  // ---- Fault injection (any thread) ----

  // When command `id` (the id-th command accepted, counting home(), submit() and request_position()) would
  // complete, it fails with `error` and `message` instead. `error` must be one a controller reports: unreachable,
  // timeout, hardware, protocol or connection_lost (the last three also put the driver in fault).
  void fail_command(CommandId id, ErrorCode error, std::string message);
  // Command `id` never completes: it runs until stop(), disconnect() or a fault ends it.
  void never_complete(CommandId id);
  // The link drops now: every command in flight fails with connection_lost and the driver enters fault; reset()
  // then leaves it disconnected. Nothing happens when already disconnected.
  void drop_connection();
  // While `problem` is not empty, connect() throws InputError(config.where, problem), as a missing serial port
  // would. An empty string lets connect() succeed again.
  void refuse_connect(std::string problem);

  // ---- Digital I/O of the virtual controller (any thread) ----
  void set_input(int channel, bool on);  // channel 1..digital_inputs
  bool output(int channel) const;        // channel 1..digital_outputs; false until a SetOutput sets it

  // ---- What happened (any thread) ----
  struct Calls {
    int connect = 0, disconnect = 0, home = 0, activate = 0, stop = 0, reset = 0, submit = 0, request_position = 0,
        poll = 0, last_position = 0, set_notifier = 0;
  };
  Calls calls() const;
  // Every command accepted by submit(), with its id, in order.
  std::vector<std::pair<CommandId, Command>> accepted() const;
  // Where the scripted robot is now (see the note at the top).
  std::vector<double> joints() const;
  Eigen::Isometry3d tool_pose() const;
  // Whether the gripper was last closed (false after homing or an open).
  bool gripper_closed() const;

 private:
  enum class JobKind : std::uint8_t { home, command, position };
  struct Job {
    CommandId id = 0;
    JobKind kind = JobKind::command;
    std::optional<Command> command;
    std::uint64_t remaining = 0;  // ticks of work left
    std::uint64_t waited = 0;     // ticks a WaitInput has waited
  };

  // All below: mutex_ held.
  Submitted refuse(ErrorCode error, std::string message);
  Submitted enqueue(JobKind kind, std::optional<Command> command, std::uint64_t ticks);
  void set_status(CommandId id, CommandPhase phase, ErrorCode error = ErrorCode::none, std::string message = {});
  // Fails every queued job from the front with `error` and `message`; returns whether there was any.
  bool fail_all(ErrorCode error, const std::string& message);
  // The head job's work is over: it fails if a failure was injected for it, else completes.
  void finish_head();
  // Completes the head job successfully, applying its effect.
  void complete_head();
  // Fails the head job with `error`; the rest are cancelled (or lose the link too); fatal errors enter fault.
  void fail_head(ErrorCode error, std::string message);
  // Marks the new head (if any) running.
  void start_head();
  // Calls the notifier (outside the lock) if `changed`.
  void notify_if(bool changed, std::unique_lock<std::mutex>& lock);

  const ScriptedDriverConfig config_;
  mutable std::mutex mutex_;
  DriverState state_ = DriverState::disconnected;
  bool link_up_ = false;
  std::string connect_problem_;
  std::uint64_t now_ = 0;
  CommandId next_id_ = 1;
  std::deque<Job> queue_;
  std::map<CommandId, CommandStatus> statuses_;
  std::deque<CommandId> finished_;  // terminal ids, oldest first, for retention
  std::map<CommandId, std::pair<ErrorCode, std::string>> injected_failures_;
  std::set<CommandId> never_complete_;
  std::function<void()> notify_;
  std::vector<bool> inputs_;
  std::vector<bool> outputs_;
  std::vector<double> joints_;
  Eigen::Isometry3d pose_;
  bool gripper_closed_ = false;
  std::optional<PositionReading> last_position_;
  std::vector<std::pair<CommandId, Command>> accepted_;
  mutable Calls calls_;
};

}  // namespace cellwright::drivers
