#include "cellwright/distributed/wire.hpp"

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <chrono>
#include <limits>

#include <fmt/format.h>

namespace cellwright::distributed {
namespace {

namespace cdr = eprosima::fastcdr;

// Room for the largest sample of either type (the status: 1060 bytes).
constexpr std::size_t kScratch = 2048;

std::uint32_t narrow_index(std::size_t value, const char* field) {
  if (value > std::numeric_limits<std::uint32_t>::max()) {
    throw WireError(fmt::format("{} {} does not fit the wire's 32 bits", field, value));
  }
  return static_cast<std::uint32_t>(value);
}

// A bounded CDR string: its length with the NUL, its bytes, the NUL.
void put_string(cdr::Cdr& out, const std::string& text, std::size_t bound) {
  std::string cut = text.substr(0, bound - 1);
  out << cut;
}

std::string get_string(cdr::Cdr& in, std::size_t bound, const char* field) {
  std::uint32_t length = 0;
  in >> length;
  if (length == 0) throw WireError(fmt::format("{}: a string of length 0 (CDR counts its NUL)", field));
  if (length > bound) throw WireError(fmt::format("{}: {} bytes, over its bound of {}", field, length, bound));
  std::string text(length, '\0');
  in.deserializeArray(text.data(), length);
  if (text.back() != '\0') throw WireError(fmt::format("{}: no terminating NUL", field));
  text.pop_back();
  if (text.find('\0') != std::string::npos) throw WireError(fmt::format("{}: a NUL inside the text", field));
  return text;
}

std::int64_t to_ns(runtime::SimDuration d) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
}

runtime::SimDuration from_ns(std::int64_t ns) {
  return std::chrono::duration_cast<runtime::SimDuration>(std::chrono::nanoseconds(ns));
}

template <typename Write>
std::vector<char> encode(Write write) {
  std::vector<char> buffer(kScratch);
  cdr::FastBuffer fast(buffer.data(), buffer.size());
  cdr::Cdr out(fast, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR);
  out.serialize_encapsulation();
  write(out);
  buffer.resize(out.getSerializedDataLength());
  return buffer;
}

// Runs `read` over the bytes; the CDR library's own refusals (too short, a bad encapsulation) become WireErrors, and
// more than 3 bytes left over (a sample may be padded to 4) is one too.
template <typename Read>
void decode(const std::vector<char>& bytes, const char* type, Read read) {
  if (bytes.size() < 4) throw WireError(fmt::format("{}: {} bytes, shorter than its header", type, bytes.size()));
  std::vector<char> copy(bytes);  // the CDR reader wants a mutable buffer
  cdr::FastBuffer fast(copy.data(), copy.size());
  cdr::Cdr in(fast, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR);
  try {
    in.read_encapsulation();
    read(in);
  } catch (const cdr::exception::Exception& e) {
    throw WireError(fmt::format("{}: {} ({} bytes)", type, e.what(), bytes.size()));
  }
  std::size_t used = in.getSerializedDataLength();
  if (bytes.size() > used + 3) {
    throw WireError(fmt::format("{}: {} bytes after the message's {}", type, bytes.size() - used, used));
  }
}

}  // namespace

std::vector<char> encode_command(const runtime::MotionCommand& command, std::uint64_t sequence) {
  std::uint32_t robot = narrow_index(command.robot, "robot index");
  std::uint32_t index = narrow_index(command.index, "primitive index");
  std::uint32_t transition = narrow_index(command.transition, "transition");
  return encode([&](cdr::Cdr& out) {
    out << robot << index << transition << to_ns(command.sent);
    put_string(out, task::to_string(command.primitive), kPrimitiveTextBound);
    out << sequence;
  });
}

runtime::MotionCommand decode_command(const std::vector<char>& bytes, const task::CompiledProgram& program,
                                      std::size_t robot, std::uint64_t* sequence) {
  std::uint32_t robot_on_wire = 0, index = 0, transition = 0;
  std::int64_t sent = 0;
  std::uint64_t number = 0;
  std::string text;
  decode(bytes, kCommandTypeName, [&](cdr::Cdr& in) {
    in >> robot_on_wire >> index >> transition >> sent;
    text = get_string(in, kPrimitiveTextBound, "RobotCommand_.primitive");
    in >> number;
  });
  if (robot_on_wire != robot) {
    throw WireError(fmt::format("a command for robot {} on robot {}'s topic", robot_on_wire, robot));
  }
  CW_CHECK(robot < program.programs.size(), "robot index outside the program");
  const auto& primitives = program.programs[robot].primitives;
  if (index >= primitives.size()) {
    throw WireError(
        fmt::format("primitive {} of robot {}: its program has {}", index, program.robots[robot], primitives.size()));
  }
  if (sent < 0) throw WireError(fmt::format("a command sent at {} ns, before the run began", sent));
  const task::Primitive& primitive = primitives[index];
  std::string expected = task::to_string(primitive).substr(0, kPrimitiveTextBound - 1);
  if (text != expected) {
    throw WireError(fmt::format("primitive {} of robot {} is \"{}\" here, \"{}\" on the wire (another program?)", index,
                                program.robots[robot], expected, text));
  }
  runtime::MotionCommand command;
  command.robot = robot;
  command.index = index;
  command.primitive = primitive;
  command.transition = transition;
  command.sent = from_ns(sent);
  if (sequence != nullptr) *sequence = number;
  return command;
}

std::vector<char> encode_status(const runtime::RobotStatus& status, StatusStamp stamp) {
  std::uint32_t robot = narrow_index(status.robot, "robot index");
  std::int64_t index = -1;
  if (status.index != runtime::RobotStatus::kNoCommand) {
    index = static_cast<std::int64_t>(narrow_index(status.index, "primitive index"));
  }
  std::uint8_t outcome = status.outcome == runtime::CommandOutcome::kDone ? 0 : 1;
  return encode([&](cdr::Cdr& out) {
    out << robot << index << outcome << status.stop_cell;
    put_string(out, status.reason, kReasonBound);
    out << to_ns(status.time) << stamp.session << stamp.sequence;
  });
}

runtime::RobotStatus decode_status(const std::vector<char>& bytes, std::size_t robot, StatusStamp* stamp) {
  std::uint32_t robot_on_wire = 0;
  StatusStamp got;
  std::int64_t index = 0, time = 0;
  std::uint8_t outcome = 0;
  bool stop_cell = false;
  std::string reason;
  decode(bytes, kStatusTypeName, [&](cdr::Cdr& in) {
    in >> robot_on_wire >> index >> outcome >> stop_cell;
    reason = get_string(in, kReasonBound, "RobotStatus_.reason");
    in >> time >> got.session >> got.sequence;
  });
  if (robot_on_wire != robot) {
    throw WireError(fmt::format("a status of robot {} on robot {}'s topic", robot_on_wire, robot));
  }
  if (index < -1 || index > std::numeric_limits<std::uint32_t>::max()) {
    throw WireError(fmt::format("primitive index {} (-1 or 0..2^32-1)", index));
  }
  if (outcome > 1) throw WireError(fmt::format("outcome {} (0 done, 1 failed)", outcome));
  if (time < 0) throw WireError(fmt::format("a status at {} ns, before the run began", time));
  runtime::RobotStatus status;
  status.robot = robot;
  status.index = index < 0 ? runtime::RobotStatus::kNoCommand : static_cast<std::size_t>(index);
  status.outcome = outcome == 0 ? runtime::CommandOutcome::kDone : runtime::CommandOutcome::kFailed;
  status.stop_cell = stop_cell;
  status.reason = std::move(reason);
  status.time = from_ns(time);
  if (stamp != nullptr) *stamp = got;
  return status;
}

std::vector<char> encode_agent_state(std::size_t robot, AgentState state) {
  std::uint32_t index = narrow_index(robot, "robot index");
  return encode([&](cdr::Cdr& out) { out << index << state.ready << state.session; });
}

AgentState decode_agent_state(const std::vector<char>& bytes, std::size_t robot) {
  std::uint32_t robot_on_wire = 0;
  AgentState state;
  decode(bytes, kAgentStateTypeName, [&](cdr::Cdr& in) { in >> robot_on_wire >> state.ready >> state.session; });
  if (robot_on_wire != robot) {
    throw WireError(fmt::format("the state of robot {}'s agent on robot {}'s topic", robot_on_wire, robot));
  }
  if (state.session == 0) throw WireError("an agent state of session 0 (sessions are numbered from 1)");
  return state;
}

std::size_t max_agent_state_size() {
  return encode_agent_state(0, {true, 1}).size();
}

void SequenceCheck::accept(std::uint64_t n, const char* what) {
  if (n <= last_) {
    throw WireError(fmt::format("{} {} again, the last taken being {}: a duplicate, or a stale one", what, n, last_));
  }
  if (n != last_ + 1) {
    throw WireError(n == last_ + 2 ? fmt::format("{} {} after {}: {} {} is missing", what, n, last_, what, last_ + 1)
                                   : fmt::format("{} {} after {}: {}s {} to {} are missing", what, n, last_, what,
                                                 last_ + 1, n - 1));
  }
  last_ = n;
}

std::size_t max_command_size() {
  // From the end of the 4-byte header (XCDR1 aligns from there): robot, index, transition, padding to 8, sent_ns:
  // 24 bytes; the string's length (4) and at most kPrimitiveTextBound bytes with its NUL; the sequence aligned to 8.
  const std::size_t string_end = 24 + 4 + kPrimitiveTextBound;
  return 4 + (string_end + 7) / 8 * 8 + 8;
}

std::size_t max_status_size() {
  runtime::RobotStatus status;
  status.reason.assign(kReasonBound - 1, 'x');
  return encode_status(status, {1, 1}).size();
}

}  // namespace cellwright::distributed
