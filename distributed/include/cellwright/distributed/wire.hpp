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
//       uint64 sequence;       // 1, 2, 3, ... the commands sent to one agent (one session, below) in order
//     };
//     @final struct RobotStatus_ {
//       uint32 robot;
//       int64 index;           // -1: no command (bring-up failed), RobotStatus::kNoCommand
//       uint8 outcome;         // 0 done, 1 failed
//       boolean stop_cell;
//       string<1024> reason;
//       int64 time_ns;         // simulation time it ended, ns
//       uint64 session;        // the agent that sent it (AgentState_.session)
//       uint64 sequence;       // 1, 2, 3, ... the statuses of that session in order
//     };
//     @final struct AgentState_ {  // rt/cellwright/<robot>/agent: reliable, transient local, keep last 1
//       uint32 robot;
//       boolean ready;         // the agent's command reader and status writer both see task control
//       uint64 session;        // this agent process (a number drawn as it starts, never 0): a new process for the
//                              // same robot is a new session, and numbers its statuses and takes commands from 1
//     };
//   }; }; };
//
// Sequence numbers: each direction of a link numbers its samples from 1 within one agent session (SequenceCheck
// below); a gap (a sample lost on the way) or a duplicate (one delivered twice, or a stale one from an agent that was
// replaced) is refused with a reason naming the numbers. DDS's reliable QoS should make both impossible: the check is
// the end-to-end proof that it did, and the guard against a peer that numbers wrongly.
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

// Encodes a command as the `sequence`-th sent to its agent; the primitive's text is task::to_string(command.primitive),
// cut to kPrimitiveTextBound - 1. Throws WireError for a value that does not fit its field (an index over 2^32 - 1).
std::vector<char> encode_command(const runtime::MotionCommand& command, std::uint64_t sequence);

// Decodes a command sent to robot `robot` (its index in `program`), rebuilding the primitive from the program: the
// text on the wire must be the program's primitive at that index. Its sequence number into `*sequence` if given (the
// number is not checked here: SequenceCheck). Throws WireError.
runtime::MotionCommand decode_command(const std::vector<char>& bytes, const task::CompiledProgram& program,
                                      std::size_t robot, std::uint64_t* sequence = nullptr);

// Which agent sent a status, and its number among that agent's statuses.
struct StatusStamp {
  std::uint64_t session = 0;
  std::uint64_t sequence = 0;
};

// Encodes a status; a reason longer than kReasonBound - 1 bytes is cut (the whole reason stays in the agent's log).
std::vector<char> encode_status(const runtime::RobotStatus& status, StatusStamp stamp);

// Decodes a status that must be about robot `robot`; its stamp into `*stamp` if given. Throws WireError.
runtime::RobotStatus decode_status(const std::vector<char>& bytes, std::size_t robot, StatusStamp* stamp = nullptr);

// The agent's state: whether robot `robot`'s agent is ready, and its session (decode refuses another robot's state,
// and a session of 0). Throws WireError.
struct AgentState {
  bool ready = false;
  std::uint64_t session = 0;
};
std::vector<char> encode_agent_state(std::size_t robot, AgentState state);
AgentState decode_agent_state(const std::vector<char>& bytes, std::size_t robot);

// The order of one stream of numbered samples (one direction of a link, within one agent session): the first must be
// 1, each next one more than the last. accept() throws WireError, naming `what` ("command", "status") and the
// numbers, for a duplicate (a number already taken: `n` at or below the last) or a gap (numbers missing before `n`),
// and takes nothing then: after a gap every later sample is refused too (what was lost is not coming; the link's
// owner must act). restart() begins a new session's stream. Not thread-safe: one reader.
class SequenceCheck {
 public:
  void accept(std::uint64_t n, const char* what);
  void restart() { last_ = 0; }
  std::uint64_t last() const { return last_; }

 private:
  std::uint64_t last_ = 0;
};

}  // namespace cellwright::distributed
