#include "cellwright/distributed/wire.hpp"

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <chrono>
#include <limits>

#include <fmt/format.h>

#include "cdr_io.hpp"

namespace cellwright::distributed {
namespace {

namespace cdr = eprosima::fastcdr;
using cdr_io::narrow_index;

// Room for the largest sample of either type (the status: 1060 bytes).
constexpr std::size_t kScratch = 2048;

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
  const cdr_io::CommandFields f = cdr_io::command_fields(command);
  return encode([&](cdr::Cdr& out) {
    out << f.robot << f.index << f.transition << f.sent_ns;
    put_string(out, f.primitive, kPrimitiveTextBound);
    out << sequence;
  });
}

runtime::MotionCommand decode_command(const std::vector<char>& bytes, const task::CompiledProgram& program,
                                      std::size_t robot, std::uint64_t* sequence) {
  cdr_io::CommandFields f;
  std::uint64_t number = 0;
  decode(bytes, kCommandTypeName, [&](cdr::Cdr& in) {
    in >> f.robot >> f.index >> f.transition >> f.sent_ns;
    f.primitive = get_string(in, kPrimitiveTextBound, "RobotCommand_.primitive");
    in >> number;
  });
  runtime::MotionCommand command = cdr_io::command_from_fields(f, program, robot);
  if (sequence != nullptr) *sequence = number;
  return command;
}

std::vector<char> encode_status(const runtime::RobotStatus& status, StatusStamp stamp) {
  const cdr_io::StatusFields f = cdr_io::status_fields(status);
  return encode([&](cdr::Cdr& out) {
    out << f.robot << f.index << f.outcome << f.stop_cell;
    put_string(out, f.reason, kReasonBound);
    out << f.time_ns << stamp.session << stamp.sequence;
  });
}

runtime::RobotStatus decode_status(const std::vector<char>& bytes, std::size_t robot, StatusStamp* stamp) {
  cdr_io::StatusFields f;
  StatusStamp got;
  decode(bytes, kStatusTypeName, [&](cdr::Cdr& in) {
    in >> f.robot >> f.index >> f.outcome >> f.stop_cell;
    f.reason = get_string(in, kReasonBound, "RobotStatus_.reason");
    in >> f.time_ns >> got.session >> got.sequence;
  });
  runtime::RobotStatus status = cdr_io::status_from_fields(std::move(f), robot);
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

namespace cdr_io {

CommandFields command_fields(const runtime::MotionCommand& command) {
  CommandFields f;
  f.robot = narrow_index(command.robot, "robot index");
  f.index = narrow_index(command.index, "primitive index");
  f.transition = narrow_index(command.transition, "transition");
  f.sent_ns = nanoseconds(command.sent);
  f.primitive = task::to_string(command.primitive).substr(0, kPrimitiveTextBound - 1);
  return f;
}

runtime::MotionCommand command_from_fields(const CommandFields& f, const task::CompiledProgram& program,
                                           std::size_t robot) {
  if (f.robot != robot) throw WireError(fmt::format("a command for robot {} on robot {}'s topic", f.robot, robot));
  CW_CHECK(robot < program.programs.size(), "robot index outside the program");
  const auto& primitives = program.programs[robot].primitives;
  if (f.index >= primitives.size()) {
    throw WireError(
        fmt::format("primitive {} of robot {}: its program has {}", f.index, program.robots[robot], primitives.size()));
  }
  if (f.sent_ns < 0) throw WireError(fmt::format("a command sent at {} ns, before the run began", f.sent_ns));
  const task::Primitive& primitive = primitives[f.index];
  std::string expected = task::to_string(primitive).substr(0, kPrimitiveTextBound - 1);
  if (f.primitive != expected) {
    throw WireError(fmt::format("primitive {} of robot {} is \"{}\" here, \"{}\" on the wire (another program?)",
                                f.index, program.robots[robot], expected, f.primitive));
  }
  runtime::MotionCommand command;
  command.robot = robot;
  command.index = f.index;
  command.primitive = primitive;
  command.transition = f.transition;
  command.sent = from_ns(f.sent_ns);
  return command;
}

StatusFields status_fields(const runtime::RobotStatus& status) {
  StatusFields f;
  f.robot = narrow_index(status.robot, "robot index");
  if (status.index != runtime::RobotStatus::kNoCommand) {
    f.index = static_cast<std::int64_t>(narrow_index(status.index, "primitive index"));
  }
  f.outcome = status.outcome == runtime::CommandOutcome::kDone ? 0 : 1;
  f.stop_cell = status.stop_cell;
  f.reason = status.reason;
  f.time_ns = nanoseconds(status.time);
  return f;
}

runtime::RobotStatus status_from_fields(StatusFields f, std::size_t robot) {
  if (f.robot != robot) throw WireError(fmt::format("a status of robot {} on robot {}'s topic", f.robot, robot));
  if (f.index < -1 || f.index > std::numeric_limits<std::uint32_t>::max()) {
    throw WireError(fmt::format("primitive index {} (-1 or 0..2^32-1)", f.index));
  }
  if (f.outcome > 1) throw WireError(fmt::format("outcome {} (0 done, 1 failed)", f.outcome));
  if (f.time_ns < 0) throw WireError(fmt::format("a status at {} ns, before the run began", f.time_ns));
  runtime::RobotStatus status;
  status.robot = robot;
  status.index = f.index < 0 ? runtime::RobotStatus::kNoCommand : static_cast<std::size_t>(f.index);
  status.outcome = f.outcome == 0 ? runtime::CommandOutcome::kDone : runtime::CommandOutcome::kFailed;
  status.stop_cell = f.stop_cell;
  status.reason = std::move(f.reason);
  status.time = from_ns(f.time_ns);
  return status;
}

}  // namespace cdr_io

}  // namespace cellwright::distributed
