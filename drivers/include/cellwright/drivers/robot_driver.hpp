// The one robot driver interface. Every robot in a cell is driven through it: the MuJoCo simulation driver, the
// Movemaster EX driver and the VAL II driver over RS-232, and the ScriptedDriver test double. A robot-control thread
// (paper section 3.4) owns one driver and turns motion-level commands into driver commands; nothing above it knows
// which kind of robot it talks to. The drivers implement this contract once, in DriverCore (driver_core.hpp), and add
// only what their controller needs; FaultyDriver (faulty_driver.hpp) wraps any of them to inject failures.
//
// ASYNCHRONOUS BY DESIGN. A real serial controller takes a command, acknowledges it a while later (Movemaster: the
// host asks `ER` and gets 0/1/2), executes it for seconds, and reports its position only when asked (`WH`, `WHERE`).
// So nothing here waits for the robot: submit() queues a command and returns its id at once; poll(id) tells how far
// it has got; request_position() asks for a position whose answer arrives later, stamped with the time it was taken.
// A notifier callback lets the owner sleep until something changes instead of spinning.
//
// LIFECYCLE
//
//   disconnected --connect()--> connected --home() done--> homed --activate()--> active
//                                    ^                        ^                   |  stop()
//                                    |                        +---activate()--- stopped
//                                    +--- reset() --- fault <--- controller error or lost link, from any state
//                                                              other than disconnected
//   disconnect(): any state --> disconnected
//
//   disconnected  no link to the controller.
//   connected     link open, the controller answers; its position is not trusted until the robot is homed. It can
//                 be read (request_position()): after reset() from a fault, where the controller says the arm
//                 stopped, which a recovery reads before it moves the arm (docs/faults.md, reset_rehome).
//   homed         the robot has been to its reference position (Movemaster `NT`); it is idle and not accepting
//                 motion.
//   active        accepting commands: motions, gripper, digital I/O.
//   stopped       stop() halted it: in-flight commands were cancelled; activate() resumes, home() re-homes.
//   fault         the controller reported a hardware error or one the driver does not know, the reply could not be
//                 understood, or the link dropped.
//                 Every command in flight failed. Only reset(), disconnect(), stop() and the queries work.
//
//   Which calls each state allows (anything else is refused with ErrorCode::wrong_state and changes nothing):
//
//                       disconnected  connected  homed  active  stopped  fault
//     connect()              yes          -        -      -        -       -
//     home()                  -          yes      yes     -       yes      -
//     activate()              -           -       yes     -       yes      -
//     submit()                -           -        -     yes       -       -
//     request_position()      -          yes      yes    yes      yes      -
//     reset()                 -           -        -      -        -      yes
//     stop(), disconnect(), poll(), state(), capabilities(), last_position(), set_notifier(), set_clock(): every
//     state.
//
// COMMANDS execute one after another in the order accepted (home(), submit() and request_position() share one
// queue, as on a serial controller), at most capabilities().queue_depth in flight at once (further ones are refused
// with ErrorCode::busy). When a command fails, every command queued behind it is cancelled (ErrorCode::cancelled),
// so that a failed grasp is never followed by the move that assumed it.
//
// POSITION READS WHILE MOVING. When capabilities().reads_while_moving is true (a simulation can read its joints at
// any time), request_position() does not queue behind the motions: it is answered at the controller's next tick (a
// simulation step), even while a command runs, and is not cancelled when a command fails (it was behind nothing); it
// still counts towards queue_depth and is cancelled by stop(), disconnect() and a fault. Ids keep their acceptance
// order, but such a request may then complete before commands with smaller ids. When it is false (a Movemaster
// answers `WH` only between commands), the request takes its place in the one queue like any command.
//
// POSITION READS ON A LINE (capabilities().read_time > 0: a serial controller, whose answer holds the line). A read
// never delays a command that is ready to go: a request that has not gone on the wire when a command is queued
// behind it is withdrawn (failed with ErrorCode::cancelled, "overtaken by command N"; only the read, nothing behind
// it), and the command goes first. A read already on the wire is finished first (the controller cannot be
// interrupted): a command waits at most one read_time for it. Ask again after the command if the position is still
// wanted. The runtime paces its periodic reads by read_time (runtime/robot_control.hpp, docs/real-robots.md
// "The serial line").
//
// COMPLETION AND ERRORS. Accepted commands get ids 1, 2, 3, ... in acceptance order (never 0, never reused for the
// driver's life). poll(id) returns pending (queued), running (being executed), done, or failed with an ErrorCode and a
// message naming the values involved. Drivers keep the status of at least the kStatusRetention most recent commands;
// older or never-issued ids poll as failed/unknown_command. Errors of the controller: unreachable or timeout fail the
// command only; hardware, protocol, connection_lost and unknown also put the driver in fault.
//
// THREADS. The robot-control thread that owns the driver is the only caller of every method. A serial driver runs
// its own communication thread, the only one that touches the port (paper section 4: one pair of threads per port);
// the simulation driver is advanced by the simulation thread. Those internal threads update command statuses; the
// owner sees the updates through poll(), state() and last_position(), and is told of them through the notifier.
//
// ERRORS OF SETUP vs ERRORS IN CONTROL CYCLES. connect() throws cellwright::InputError when the configuration cannot
// work (a serial port that does not exist, a robot model the driver does not know), naming the configuration file,
// line and problem. Every other call returns a status and never throws for anything the robot or the caller did;
// InternalError (CW_CHECK) is kept for the driver's own bugs.
#pragma once

#include <Eigen/Geometry>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace cellwright::drivers {

enum class DriverState : std::uint8_t { disconnected, connected, homed, active, stopped, fault };

// Why a call was refused or a command failed.
enum class ErrorCode : std::uint8_t {
  none,             // accepted / succeeded
  wrong_state,      // refused: the call is not allowed in the driver's current state (table above)
  invalid_command,  // refused: malformed values (wrong joint count, NaN, speed outside (0, 1], bad channel)
  unsupported,      // refused: this robot cannot do it (see Capabilities)
  busy,             // refused: capabilities().queue_depth commands are already in flight
  unreachable,      // failed: outside the workspace or the joint limits (Movemaster ER answer 2)
  timeout,          // failed: a wait-for-input ran out, or the controller did not answer in time
  cancelled,        // failed: stop(), disconnect() or an earlier failure cancelled it before it finished; or a
                    // position read not yet on the wire that a command overtook (read_time > 0, see above)
  hardware,         // failed: the controller reported a hardware error (Movemaster ER answer 1); driver in fault
  protocol,         // failed: the controller's reply could not be understood; driver in fault
  connection_lost,  // failed: the link dropped; driver in fault
  // failed: the controller reported an error this driver does not know (words or a code outside its list; the
  // message quotes them); driver in fault, as for hardware: what the arm is doing cannot be told
  unknown,
  unknown_command,  // poll() of an id never issued or no longer retained
};

enum class CommandPhase : std::uint8_t { pending, running, done, failed };

using CommandId = std::uint64_t;  // 0 means "no command" (a refused submission)

// Drivers keep at least this many most recent command statuses for poll().
inline constexpr std::size_t kStatusRetention = 1024;

// UNITS everywhere in this interface: metres, radians (prismatic joints: metres), newtons, seconds. Drivers convert
// to their controller's own units and conventions (Movemaster: mm and degrees; VAL II: mm and degrees in locations).
// Digital channels are numbered from 1, as on the controllers.

// Joint-interpolated move to joint positions, in the robot's joint order (the order of its URDF). Joint-level
// control: VAL II `MOVE #PPOINT(...)`. The Movemaster driver has none (its `MJ` is relative and `WH` reports no
// joints: docs/real-robots.md).
//
// TIMED MOVES (MoveJoints::duration, MovePose::duration): a move given a duration takes that long when it is longer
// than the driver's own time for the move (the driver stretches its profile to it, the path unchanged); a shorter one
// is no constraint. Two robots that must start and stop together (a coordinated block, docs/task-language.md) are
// each given the longer of their two least times (RobotDriver::least_duration), as ABB MultiMove's synchronised moves
// do. Only a driver with Capabilities::timed_motion takes a duration; the others refuse it (unsupported).
struct MoveJoints {
  std::vector<double> positions;
  double speed = 1.0;  // fraction of the robot's maximum speed, in (0, 1]
  std::optional<double> duration{};  // seconds, > 0: take at least this long (TIMED MOVES); nullopt: the driver's time
};

enum class Path : std::uint8_t {
  joint,   // joint-interpolated: Movemaster `MP`, VAL II `MOVE`
  linear,  // straight line of the tool centre point: Movemaster `MS`, VAL II `MOVES`
};

// Move of the tool centre point (the flange plus the tool length the driver was configured with) to `pose`, given in
// the robot's base frame. A 5-axis arm (capabilities().full_orientation false, e.g. Movemaster: `MP x,y,z,p,r`
// sets pitch and roll only) cannot choose the yaw, which follows from the position: a pose whose yaw disagrees
// fails with unreachable.
struct MovePose {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Path path = Path::joint;
  double speed = 1.0;  // fraction of the robot's maximum speed, in (0, 1]
  std::optional<double> duration{};  // seconds, > 0: take at least this long (TIMED MOVES); nullopt: the driver's time
};

// Opens or closes the gripper. Without a width it opens or closes fully (Movemaster `GO`/`GC`, VAL II
// `OPENI`/`CLOSEI`); with one it moves the fingers to that opening (VAL II `CLOSEI width`). A force limits the grip
// (Movemaster `GP`, VAL II `GRASP`).
struct Grip {
  enum class Action : std::uint8_t { open, close };
  Action action = Action::close;
  std::optional<double> width;  // metres between the fingers, in [0, capabilities().gripper_max_width]
  std::optional<double> force;  // newtons, in (0, capabilities().gripper_max_force]
};

// Sets a digital output (VAL II `SIGNAL n` / `SIGNAL -n`). Completes when the controller has set it.
struct SetOutput {
  int channel = 1;  // 1..capabilities().digital_outputs
  bool on = true;
};

// Waits until a digital input has the given level (VAL II `WAIT SIG(n)`), holding back the commands behind it. Fails
// with timeout when `timeout` (if not zero) passes first. This is how robots synchronise through signals.
struct WaitInput {
  int channel = 1;  // 1..capabilities().digital_inputs
  bool on = true;
  std::chrono::nanoseconds timeout{0};  // zero: wait as long as it takes
};

using Command = std::variant<MoveJoints, MovePose, Grip, SetOutput, WaitInput>;

// What a robot and its driver can do. Fixed for the driver's life.
struct Capabilities {
  std::size_t joints = 0;               // length of MoveJoints::positions and of read-back joints
  bool joint_control = false;           // MoveJoints accepted
  bool cartesian_control = false;       // MovePose with Path::joint accepted
  bool linear_motion = false;           // MovePose with Path::linear accepted
  bool full_orientation = false;        // any tool orientation reachable (6 axes); false: yaw follows position
  bool gripper = false;                 // Grip accepted
  bool gripper_width = false;           // Grip::width accepted
  bool gripper_force = false;           // Grip::force accepted
  double gripper_max_width = 0.0;       // m
  double gripper_max_force = 0.0;       // N
  std::size_t digital_outputs = 0;      // SetOutput channels 1..n
  std::size_t digital_inputs = 0;       // WaitInput channels 1..n
  std::vector<double> max_joint_speed;  // per joint at speed 1.0 (rad/s, or m/s for prismatic joints)
  double max_tool_speed = 0.0;          // m/s of the tool centre point at speed 1.0
  std::size_t queue_depth = 1;          // commands in flight at most (queued in the driver or the controller)
  bool reads_joints = false;            // request_position() reports joint positions
  bool reads_pose = false;              // request_position() reports the tool pose (Movemaster `WH`: pose only)
  bool reads_while_moving = false;      // request_position() is answered at the next tick, not behind the motions
  // How long one position read holds the controller's line: the request and a typical answer at the line's rate plus
  // the controller's processing time (a serial driver's estimate from its line settings). Zero: reads cost nothing
  // (a simulation). See POSITION READS ON A LINE above.
  std::chrono::nanoseconds read_time{0};
  // The controller's native command space: true for a Cartesian controller (Movemaster `MP`/`MS`, VAL II locations),
  // which should be sent tool poses (MovePose) rather than joint targets it would have to emulate; false for one
  // that takes joint targets directly (the simulation's servos).
  bool prefers_pose = false;
  // grip_sense() tells the gripper's state (a jaw switch or finger encoder the controller reports). The Movemaster EX
  // and VAL II drivers cannot: neither controller's protocol, as far as it is known here, has a query of the hand's
  // state (docs/real-robots.md).
  bool senses_grip = false;
  // Moves may be given a duration (TIMED MOVES) and least_duration() tells a move's least time: a simulation, whose
  // trajectory is its own. The Movemaster EX and VAL II drivers cannot (their controllers time their own moves).
  bool timed_motion = false;
};

// What a gripper's own sensor tells (RobotDriver::grip_sense()).
enum class GripSense : std::uint8_t {
  open,            // the fingers are open
  closed_empty,    // closed and shut: nothing between them
  closed_on_part,  // closed and stopped before shutting: something is between them (the sensor cannot say what)
};

// The answer to home(), submit() or request_position().
struct Submitted {
  CommandId id = 0;                   // the new command's id when accepted, 0 when refused
  ErrorCode error = ErrorCode::none;  // none when accepted; otherwise why it was refused
  std::string message;                // when refused: what was wrong, with the values
  bool accepted() const { return error == ErrorCode::none; }
};

struct CommandStatus {
  CommandId id = 0;
  CommandPhase phase = CommandPhase::pending;
  ErrorCode error = ErrorCode::none;  // set when phase is failed
  std::string message;                // set when phase is failed: the controller's complaint or the driver's
};

// The answer to a request_position(), as the controller reported it.
struct PositionReading {
  CommandId request = 0;                       // the request_position() this answers
  std::chrono::nanoseconds stamp{0};           // when the controller took it, on the clock given to set_clock() (the
                                               // runtime's); without one, the driver's own (see each driver)
  std::vector<double> joints;                  // empty unless capabilities().reads_joints
  std::optional<Eigen::Isometry3d> tool_pose;  // set only if capabilities().reads_pose
};

class RobotDriver {
 public:
  virtual ~RobotDriver() = default;

  // What this robot can do. Any state.
  virtual const Capabilities& capabilities() const = 0;

  // The lifecycle state now (a fault raised by the driver's internal thread shows here at once). Any state.
  virtual DriverState state() const = 0;

  // Opens the link and checks the controller answers: disconnected -> connected. Returns none, or wrong_state when not
  // disconnected. Throws InputError when the configuration cannot work (e.g. the serial port does not exist).
  virtual ErrorCode connect() = 0;

  // Closes the link: any state -> disconnected. Commands in flight fail with cancelled. Never fails.
  virtual void disconnect() = 0;

  // Queues homing (Movemaster `NT`): allowed in connected, homed and stopped; when the command is done the driver is
  // homed. A failed homing leaves the state unchanged (or fault, for hardware/protocol/link errors).
  virtual Submitted home() = 0;

  // homed or stopped -> active. Returns none, or wrong_state in other states and while a home() is still in flight.
  virtual ErrorCode activate() = 0;

  // Halts the robot (it decelerates to rest) and cancels every command not finished. active -> stopped; other states
  // keep their state (so stop() is always safe to call, e.g. on shutdown). Never fails.
  virtual void stop() = 0;

  // Clears a fault: fault -> connected (the controller's error is reset; home again, since the position may be lost).
  // If the link itself is down, goes to disconnected and returns connection_lost (connect() again). Returns none,
  // connection_lost, or wrong_state when not in fault.
  virtual ErrorCode reset() = 0;

  // Queues a command (active only). Refusals: wrong_state, invalid_command, unsupported, busy (see check_command()).
  virtual Submitted submit(const Command& command) = 0;

  // Queues a position read-back (connected, homed, active, stopped). When the request is done, last_position() holds
  // its answer.
  virtual Submitted request_position() = 0;

  // The status of command `id` now. Never blocks; any state.
  virtual CommandStatus poll(CommandId id) const = 0;

  // The most recent completed position read-back, if any. Any state.
  virtual std::optional<PositionReading> last_position() const = 0;

  // `notify` is called whenever a command reaches done or failed or the driver enters fault, from whichever thread
  // made it happen (often the driver's own), with no driver lock held. It must be short and must not block or call
  // the driver: set an event (runtime::Event) and let the owner poll. Pass {} to remove it.
  virtual void set_notifier(std::function<void()> notify) = 0;

  // The clock that stamps position readings from now on (PositionReading::stamp): the runtime's clock, so that
  // readings compare with everything else the runtime times. It is called from whichever thread takes a reading
  // (often the driver's own, with the driver's lock held): it must be cheap, must not block and must not call the
  // driver. Pass {} to go back to the driver's own time. Any state.
  using Clock = std::function<std::chrono::nanoseconds()>;
  virtual void set_clock(Clock clock) = 0;

  // The gripper's state as its own sensor last reported it, when capabilities().senses_grip; nullopt when the driver
  // cannot tell (no such sensor, not read yet, no link). ANY THREAD (the runtime's sensor port reads it on the
  // simulation thread, runtime/sensors.hpp): a reading the driver keeps, never a request to the controller; it must
  // not block. The default: cannot tell.
  virtual std::optional<GripSense> grip_sense() const { return std::nullopt; }

  // How long `command` would take if it were submitted now (behind whatever is queued), in seconds: for a move, the
  // least time of its trajectory at its speed (its duration, if it has one and that is longer); for the gripper, its
  // ramp. nullopt when the driver cannot tell (no Capabilities::timed_motion, not active, or the move could not be
  // planned: submit() then says why). Owner thread; it plans but changes nothing. The default: cannot tell.
  virtual std::optional<double> least_duration(const Command& /*command*/) const { return std::nullopt; }
};

// Why a call was refused, if it was.
struct Refusal {
  ErrorCode error = ErrorCode::none;
  std::string message;
  explicit operator bool() const { return error != ErrorCode::none; }
};

// The checks every driver applies to a command before accepting it, against the robot's capabilities: unsupported
// when the robot lacks what the command needs, invalid_command when a value is out of range or not finite (the
// message names the field and the value). Returns a Refusal that is false when the command is acceptable.
Refusal check_command(const Command& command, const Capabilities& capabilities);

// The 5-axis rule of a robot without full orientation (Capabilities::full_orientation false): its yaw follows its
// position, so the tool's approach axis (its z axis) must lie in the vertical plane through the base's z axis and the
// tool point. How far (radians) `pose` (base frame) leaves that plane; infinity for a tool point on the base's z axis
// (it has no plane). A caller choosing among poses for such a robot keeps those within its driver's tolerance.
double out_of_arm_plane(const Eigen::Isometry3d& pose);

// Names for logs and messages: "active", "unreachable", "running", ...
std::string_view to_string(DriverState state);
std::string_view to_string(ErrorCode error);
std::string_view to_string(CommandPhase phase);

// One line describing a command, for the event log and messages. The format is fixed (six decimals; of the two
// quaternions of a rotation, the one whose first printed non-zero component is positive), so the same command always
// gives the same bytes: e.g. "move_joints [0.000000, 1.570796] speed 0.500000".
std::string describe(const Command& command);

}  // namespace cellwright::drivers
