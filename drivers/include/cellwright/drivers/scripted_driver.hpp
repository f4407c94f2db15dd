// ScriptedDriver: a RobotDriver test double with a virtual controller behind it. It is built on DriverCore
// (driver_core.hpp), which gives it the interface's rules (lifecycle, refusals, one queue, cancellation, fault
// handling, call counts); it executes commands on virtual time that the test (or the runtime's simulation thread)
// advances tick by tick, and fails on request: a chosen command with a chosen error, the link dropping, a command that
// never completes, a port that is not there.
//
// The scripted robot has no kinematics: after a MoveJoints its joints are the target; after a MovePose its tool pose
// is the target; homing puts both at the configured home values. Position read-backs report those, stamped with the
// virtual time at which they complete (or, after set_clock(), with the clock's time then).
//
// A timed move (capabilities.timed_motion, robot_driver.hpp TIMED MOVES) takes at least the ticks that last its
// duration; least_duration() tells a command's ticks times the tick.
//
// Time: advance(n) runs n ticks. On each tick the command at the head of the queue (the running one) does one tick of
// work; a command of duration d completes on the d-th tick after it reached the head, and the next one becomes
// running at once but starts working on the following tick. A WaitInput instead checks its input on each tick, and
// fails when its timeout (converted at config.tick per tick) has passed. With capabilities.reads_while_moving, a
// position request does not queue: it counts its position_ticks from the next tick whatever the queue holds, and
// reports the scripted robot as it is at the end of the tick that completes it (the head command's work for that tick
// done first).
//
// Threads: the owner calls the RobotDriver methods; advance() and the test controls may be called from any thread
// (e.g. the runtime's simulation thread), as the communication thread of a serial driver would run. All state is
// behind the core's mutex; the notifier is called with it released.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/driver_core.hpp"

namespace cellwright::drivers {

struct ScriptedDriverConfig {
  SourceLocation where;       // the robot's entry in the cell file: connect() failures name it
  Capabilities capabilities;  // what the double claims to be able to do (reads_while_moving included)
  std::chrono::nanoseconds tick{std::chrono::milliseconds(1)};  // virtual time per tick (stamps, wait timeouts)
  std::uint64_t home_ticks = 10;                                // duration of home(), >= 1
  std::uint64_t position_ticks = 1;                             // duration of request_position(), >= 1
  std::uint64_t command_ticks = 5;                              // duration of a submitted command, >= 1 ...
  std::function<std::uint64_t(const Command&)> ticks_for;       // ... unless this is set: then it decides (>= 1)
  std::vector<double> home_joints;                              // joints after homing; empty means all zero
  Eigen::Isometry3d home_pose = Eigen::Isometry3d::Identity();  // tool pose after homing
};

class ScriptedDriver final : public DriverCore {
 public:
  // Throws InternalError when the configuration is inconsistent (a duration of 0, a tick <= 0, queue_depth 0,
  // home_joints of the wrong length): the test is wrong, not the robot.
  explicit ScriptedDriver(ScriptedDriverConfig config);

  // The RobotDriver methods and calls() come from DriverCore.

  // ---- The virtual controller (any thread) ----

  // Runs the controller for `ticks` ticks of virtual time.
  void advance(std::uint64_t ticks = 1);
  // Ticks run so far.
  std::uint64_t now_ticks() const;

  // ---- Fault injection (any thread) ----

  // When command `id` (the id-th command accepted, counting home(), submit() and request_position()) would
  // complete, it fails with `error` and `message` instead. `error` must be one a controller reports: unreachable,
  // timeout, hardware, protocol, connection_lost or unknown (the last four also put the driver in fault).
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
  // Every command accepted by submit(), with its id, in order.
  std::vector<std::pair<CommandId, Command>> accepted() const;
  // Where the scripted robot is now (see the note at the top).
  std::vector<double> joints() const;
  Eigen::Isometry3d tool_pose() const;
  // Whether the gripper was last closed (false after homing or an open).
  bool gripper_closed() const;

  // ---- The gripper's sensor (any thread) ----
  // What grip_sense() reports from now on (a test's jaw switch; capabilities.senses_grip says whether the double
  // claims one). nullopt (the start): cannot tell.
  void set_grip_sense(std::optional<GripSense> sense);
  std::optional<GripSense> grip_sense() const override;
  // With capabilities.timed_motion: the command's ticks (below) times the tick.
  std::optional<double> least_duration(const Command& command) const override;

 private:
  // A command's ticks: ticks_for or command_ticks; a timed move (MoveJoints/MovePose::duration) at least as many as
  // last its duration.
  std::uint64_t command_ticks(const Command& command) const;
  struct Work : JobData {
    std::uint64_t remaining = 0;  // ticks of work left
    std::uint64_t waited = 0;     // ticks a WaitInput has waited
  };

  // DriverCore hooks.
  ErrorCode connect_hook() override;
  void accept_hook(Job& job) override;

  // One tick of the head job and of the reads (session held).
  void tick_head(Controller& c);
  void tick_reads(Controller& c);
  // Job `id`'s work is over: it fails if a failure was injected for it, else completes with its effect.
  void finish(Controller& c, Job& job);
  PositionReading reading(const Controller& c) const;

  const ScriptedDriverConfig config_;
  // Below: under the core's mutex (lock() or a Controller session).
  std::string connect_problem_;
  std::uint64_t now_ = 0;
  std::map<CommandId, std::pair<ErrorCode, std::string>> injected_failures_;
  std::set<CommandId> never_complete_;
  std::vector<bool> inputs_;
  std::vector<bool> outputs_;
  std::vector<double> joints_;
  Eigen::Isometry3d pose_;
  bool gripper_closed_ = false;
  std::optional<GripSense> grip_sense_;
  std::vector<std::pair<CommandId, Command>> accepted_;
};

}  // namespace cellwright::drivers
