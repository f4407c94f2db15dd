// The runtime's messages on the wire (docs/distributed.md): a robot's command (task control -> robot control) and
// its status (robot control -> task control) as DDS samples, encoded as plain CDR (XCDR1, @final types, the
// encapsulation header first), the encoding ROS 2's rmw_fastrtps uses, so that a ROS 2 tool given the message
// definitions can read them. Their IDL, with bounded strings (a sample has a known largest size):
//
//   module cellwright { module msg { module dds_ {
//     @final struct RobotCommand_ {
//       uint32 robot;          // index of the robot in the program (MotionCommand::robot)
//       uint32 index;          // primitive index in that robot's program
//       uint32 transition;     // the transition whose firing sent it
//       int64 sent_ns;         // simulation time it was sent, ns
//       string<256> primitive; // the primitive as text ("move at(A)"): the agent refuses a command whose text is not
//                              // its own program's primitive at that index (another program)
//     };
//     @final struct RobotStatus_ {
//       uint32 robot;
//       int64 index;           // -1: no command (bring-up failed), RobotStatus::kNoCommand
//       uint8 outcome;         // 0 done, 1 failed
//       boolean stop_cell;
//       string<1024> reason;
//       int64 time_ns;         // simulation time it ended, ns
//     };
//     @final struct AgentState_ {  // rt/cellwright/<robot>/agent: reliable, transient local, keep last 1
//       uint32 robot;
//       boolean ready;         // the agent's command reader and status writer both see task control
//     };
//   }; }; };
//
// decode_*() never trusts the bytes: a short or over-long sample, a string over its bound or without its
// terminating NUL, an outcome that is not 0 or 1, a primitive index outside the program, a robot index that is not
// the topic's robot: each is refused with a WireError saying what was wrong. Nothing here touches DDS.
//
// Threads: pure functions, any thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "cellwright/runtime/messages.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed {

// A sample that is not a valid message (the reason says what was wrong, with the values).
class WireError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr std::size_t kPrimitiveTextBound = 256;
inline constexpr std::size_t kReasonBound = 1024;

// DDS type names, as ROS 2 names a message `cellwright/msg/RobotCommand` on the wire.
inline constexpr const char* kCommandTypeName = "cellwright::msg::dds_::RobotCommand_";
inline constexpr const char* kStatusTypeName = "cellwright::msg::dds_::RobotStatus_";
inline constexpr const char* kAgentStateTypeName = "cellwright::msg::dds_::AgentState_";

// The largest encoded sample of each type, encapsulation header included (the DDS type's maximum size).
std::size_t max_command_size();
std::size_t max_status_size();
std::size_t max_agent_state_size();

// Encodes a command; the primitive's text is task::to_string(command.primitive), cut to kPrimitiveTextBound - 1.
// Throws WireError for a value that does not fit its field (an index over 2^32 - 1).
std::vector<char> encode_command(const runtime::MotionCommand& command);

// Decodes a command sent to robot `robot` (its index in `program`), rebuilding the primitive from the program: the
// text on the wire must be the program's primitive at that index. Throws WireError.
runtime::MotionCommand decode_command(const std::vector<char>& bytes, const task::CompiledProgram& program,
                                      std::size_t robot);

// Encodes a status; a reason longer than kReasonBound - 1 bytes is cut (the whole reason stays in the agent's log).
std::vector<char> encode_status(const runtime::RobotStatus& status);

// Decodes a status that must be about robot `robot`. Throws WireError.
runtime::RobotStatus decode_status(const std::vector<char>& bytes, std::size_t robot);

// The agent's state: whether robot `robot`'s agent is ready (decode refuses another robot's state). Throws WireError.
std::vector<char> encode_agent_state(std::size_t robot, bool ready);
bool decode_agent_state(const std::vector<char>& bytes, std::size_t robot);

}  // namespace cellwright::distributed
