// Lock-step across processes: the messages of a remote robot control's turn (docs/distributed.md, "Lock-step with
// agents"). In a lock-step run the turns are taken in a fixed order (runtime.hpp); a robot whose robot control is an
// agent's takes its turn in the agent's process, and the run's process waits for it:
//
//   run's process (the twin)                             agent
//   Turn{turn n, now, commands, model}  ---------------->  model := the run's; commands into its inbox
//                                       <----------------  Call{submit MoveJoints ...}     (robot control's step()
//   Result{submitted id 7}              ---------------->                                   calls its driver; the
//                                       <----------------  Call{poll 7}                     driver is the twin's,
//   Result{status running}              ---------------->                                   called here, in order)
//                                       <----------------  Done{events, statuses, model}
//   logs the events, queues the statuses, model := the agent's; the next participant's turn.
//
// Everything the agent's robot control reads or writes is carried: the whole environment model both ways (nothing
// else runs while the turn is out, so replacing the run's model by the agent's is what one process would have done),
// the driver's every call and answer (the twin's driver answers exactly as it would to a robot control in its own
// process), the turn's time, the commands task control queued, and the events and statuses the step produced, in
// order. The event log of such a run is byte-identical to the run with every robot control in one process.
//
// Types (plain CDR, XCDR1 little-endian with the encapsulation header, @final, bounded; encoded by hand with Fast CDR
// as wire.hpp's; the IDL of each is written out in turn_wire.cpp's top comment and docs/distributed.md):
//   rt/cellwright/<robot>/turn   cellwright::msg::dds_::Turn_       the run's process -> the agent (a turn, a result,
//                                                                   the end)
//   rt/cellwright/<robot>/call   cellwright::msg::dds_::TurnCall_   the agent -> the run's process (a driver call, the
//                                                                   turn done)
//
// Every message carries `sequence` (1, 2, ... in each direction, the link checks it with SequenceCheck) and the turn
// number it belongs to. decode_*() never trusts the bytes: a short or over-long sample, a string over its bound or
// without its NUL, an enum value out of range, a robot index that is not the topic's, a model whose robots or
// workpieces are not the cell's (by name, in the cell's order), a command whose primitive is not the program's at
// that index, a log line that does not decode: each is refused with a WireError saying what was wrong.
//
// Threads: pure functions, any thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/distributed/wire.hpp"
#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed {

inline constexpr const char* kTurnTypeName = "cellwright::msg::dds_::Turn_";
inline constexpr const char* kTurnCallTypeName = "cellwright::msg::dds_::TurnCall_";

// Bounds of one turn's messages (besides replica.hpp's kNameBound, kEventLineBound, kMaxJoints, kMaxWorkpieces).
inline constexpr std::size_t kMaxRobots = 16;          // robots in the model
inline constexpr std::size_t kMaxObstacles = 64;       // obstacles in the model
inline constexpr std::size_t kMaxTurnCommands = 8;     // commands queued for one turn (the inbox holds 4)
inline constexpr std::size_t kMaxTurnStatuses = 16;    // statuses of one turn
inline constexpr std::size_t kMaxTurnEvents = 64;      // events of one turn
inline constexpr std::size_t kMessageBound = 1024;     // a driver's message (Submitted, CommandStatus), cut to fit

// "rt/cellwright/<robot>/turn", "rt/cellwright/<robot>/call" (InputError for a robot name that is no ROS 2 token).
std::string turn_topic(const std::string& robot);
std::string call_topic(const std::string& robot);

// The largest encoded sample of each type, encapsulation header included.
std::size_t max_turn_size();
std::size_t max_turn_call_size();

// One call of the RobotDriver interface (robot_driver.hpp) by the agent's robot control. set_notifier and set_clock
// are not carried (the agent's stand-in driver keeps them; in lock-step nothing is notified and the clock is the
// turn's).
enum class DriverOp : std::uint8_t {
  capabilities, state, connect, disconnect, home, activate, stop, reset, submit, request_position, poll,
  last_position, grip_sense, least_duration,
};
// "capabilities", "state", ... (the member's name).
const char* to_string(DriverOp op);

struct DriverCall {
  DriverOp op = DriverOp::state;
  drivers::Command command;   // submit, least_duration: the command (every alternative of the variant and its fields)
  drivers::CommandId id = 0;  // poll: the id
};

// The answer to a DriverCall: the field of its op is set (the others keep their defaults and are not sent).
struct DriverResult {
  DriverOp op = DriverOp::state;
  drivers::Capabilities capabilities;              // capabilities
  drivers::DriverState state{};                    // state
  drivers::ErrorCode error{};                      // connect, activate, reset
  drivers::Submitted submitted;                    // home, submit, request_position (message cut to kMessageBound-1)
  drivers::CommandStatus status;                   // poll (message cut to kMessageBound - 1)
  std::optional<drivers::PositionReading> position;  // last_position
  std::optional<drivers::GripSense> grip;          // grip_sense
  std::optional<double> least;                     // least_duration
};

// The run's process -> the agent.
struct TurnMessage {
  enum class Kind : std::uint8_t {
    kTurn,    // take your turn at `now` with `commands` and `model`
    kResult,  // the answer to the agent's last DriverCall
    kEnd,     // the run is over: halt and leave (no reply)
  };
  Kind kind = Kind::kTurn;
  std::size_t robot = 0;         // program index (the topic's robot)
  std::uint64_t sequence = 0;    // 1, 2, ... of this direction
  std::uint64_t turn = 0;        // 1, 2, ...: the turn it is, or belongs to
  runtime::SimDuration now{0};   // kTurn: the simulation time of the turn
  // kTurn: the commands task control queued for this robot since its last turn, in order.
  std::vector<runtime::MotionCommand> commands;
  // kTurn: the whole environment model as the turn starts (EnvironmentModel's changing state: time, every robot's
  // state, every workpiece's, the obstacles; not the geometry, which both sides build from the same cell).
  runtime::EnvironmentModel model;
  DriverResult result;  // kResult
};

// The agent -> the run's process.
struct TurnCall {
  enum class Kind : std::uint8_t {
    kCall,  // a driver call to answer (kResult)
    kDone,  // the turn is over
  };
  Kind kind = Kind::kCall;
  std::size_t robot = 0;
  std::uint64_t sequence = 0;
  std::uint64_t turn = 0;
  DriverCall call;  // kCall
  // kDone: what robot control's step logged (each event's log line, log_event.hpp), in order; the statuses it
  // reported, in order; the environment model after the step (all of it, as TurnMessage::model); and, if its step
  // threw, the error's text (the run fails with it, naming the agent).
  std::vector<std::string> events;
  std::vector<runtime::RobotStatus> statuses;
  runtime::EnvironmentModel model;
  std::string error;
  // kDone of turn 0 (the agent's hello, turn_link.hpp): what its robot control was built with (turn_settings()),
  // string<1024>; empty otherwise.
  std::string settings;
};

// Encoders throw WireError when a value does not fit its field (more robots, workpieces, obstacles, joints, commands,
// statuses or events than the bounds; a name or line over its bound). Strings documented as cut are cut instead.
std::vector<char> encode_turn(const TurnMessage& message);
std::vector<char> encode_turn_call(const TurnCall& message);

// Decoders, for robot `robot` (program index; a sample about another robot is refused) of `program` (commands are
// rebuilt from it, as decode_command), with `cell_model` the receiver's own model of the cell (the geometry and the
// names: the decoded model is a copy of it with every changing field replaced; its robots, workpieces must be the same
// names in the same order, and `fixed` points into cell_model's geometry). Throws WireError.
TurnMessage decode_turn(const std::vector<char>& bytes, std::size_t robot, const task::CompiledProgram& program,
                        const runtime::EnvironmentModel& cell_model);
TurnCall decode_turn_call(const std::vector<char>& bytes, std::size_t robot,
                          const runtime::EnvironmentModel& cell_model);

}  // namespace cellwright::distributed
