// What the distributed library's hand-written CDR codecs share (not installed): wire.cpp, replica.cpp and
// turn_wire.cpp. A writer and a reader of plain CDR (XCDR1, the encapsulation header first) whose reader turns every
// surprise of the bytes into a WireError naming the type, and the conversions of a command's and a status's fields
// to and from RobotCommand_/RobotStatus_ (wire.hpp), which a lock-step turn (turn_wire.hpp) carries too.
//
// Threads: plain values; a writer or reader is used by one thread.
#pragma once

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>
#include <fastcdr/exceptions/NotEnoughMemoryException.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cellwright/distributed/wire.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed::cdr_io {

namespace cdr = eprosima::fastcdr;

inline std::int64_t nanoseconds(std::chrono::nanoseconds d) {
  return d.count();
}

inline runtime::SimDuration from_ns(std::int64_t ns) {
  return std::chrono::duration_cast<runtime::SimDuration>(std::chrono::nanoseconds(ns));
}

// A count or index as the wire's uint32; WireError naming `field` when it does not fit.
inline std::uint32_t narrow_index(std::size_t value, const char* field) {
  if (value > std::numeric_limits<std::uint32_t>::max()) {
    throw WireError(fmt::format("{} {} does not fit the wire's 32 bits", field, value));
  }
  return static_cast<std::uint32_t>(value);
}

// A CDR writer into a buffer of `room` bytes, zeroed (padding is zeros: the same message, the same bytes). Writing
// past the room throws the CDR library's NotEnoughMemoryException (encode_growing() starts again with more room).
class Out {
 public:
  explicit Out(std::size_t room)
      : buffer_(room, '\0'),
        fast_(buffer_.data(), buffer_.size()),
        cdr_(fast_, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR) {
    cdr_.serialize_encapsulation();
  }
  cdr::Cdr& cdr() { return cdr_; }
  // A bounded string; WireError naming `field` when it (with its NUL) is over `bound`.
  void text(const std::string& s, std::size_t bound, const char* field) {
    if (s.size() + 1 > bound)
      throw WireError(fmt::format("{}: {} bytes, over its bound of {}", field, s.size(), bound));
    cdr_ << s;
  }
  std::vector<char> take() {
    buffer_.resize(cdr_.getSerializedDataLength());
    return std::move(buffer_);
  }

 private:
  std::vector<char> buffer_;
  cdr::FastBuffer fast_;
  cdr::Cdr cdr_;
};

// The bytes `write` writes into a writer of type W (Out or one derived from it), made with `room` bytes and made
// again with twice as many while the sample does not fit.
template <typename W, typename Write>
std::vector<char> encode_growing(std::size_t room, Write write) {
  for (;;) {
    W out(room);
    try {
      write(out);
      return out.take();
    } catch (const cdr::exception::NotEnoughMemoryException&) {
      room *= 2;
    }
  }
}

// A CDR reader over a sample's bytes that refuses what does not fit the type (`type`: its DDS name, for the errors).
class In {
 public:
  In(const std::vector<char>& bytes, const char* type)
      : bytes_(bytes),
        fast_(bytes_.data(), bytes_.size()),
        cdr_(fast_, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR),
        type_(type) {
    if (bytes.size() < 4) throw WireError(fmt::format("{}: {} bytes, shorter than its header", type, bytes.size()));
    guarded([&] { cdr_.read_encapsulation(); });
  }
  template <typename F>
  void guarded(F f) {
    try {
      f();
    } catch (const cdr::exception::Exception& e) {
      throw WireError(fmt::format("{}: {} ({} bytes)", type_, e.what(), bytes_.size()));
    }
  }
  template <typename T>
  T get() {
    T v{};
    guarded([&] { cdr_ >> v; });
    return v;
  }
  // A bounded string: its length with the NUL in 1..bound, the NUL last and nowhere else.
  std::string text(std::size_t bound, const char* field) {
    const auto length = get<std::uint32_t>();
    if (length == 0 || length > bound) {
      throw WireError(fmt::format("{}: a string of {} bytes with its NUL (1..{})", field, length, bound));
    }
    std::string s(length, '\0');
    guarded([&] { cdr_.deserializeArray(s.data(), length); });
    if (s.back() != '\0' || s.find('\0') != length - 1) throw WireError(fmt::format("{}: a misplaced NUL", field));
    s.pop_back();
    return s;
  }
  double number(const char* field) {
    const double v = get<double>();
    if (!std::isfinite(v)) throw WireError(fmt::format("{}: {} is not a finite number", field, v));
    return v;
  }
  // A sequence's length, refused over `bound`.
  std::uint32_t count(std::size_t bound, const char* field) {
    const auto n = get<std::uint32_t>();
    if (n > bound) throw WireError(fmt::format("{}: {} elements, over the bound of {}", field, n, bound));
    return n;
  }
  // The sample must end here (a sample may be padded to 4).
  void end() {
    const std::size_t used = cdr_.getSerializedDataLength();
    if (bytes_.size() > used + 3) {
      throw WireError(fmt::format("{}: {} bytes after the message's {}", type_, bytes_.size() - used, used));
    }
  }

 private:
  std::vector<char> bytes_;  // the CDR reader wants a mutable buffer
  cdr::FastBuffer fast_;
  cdr::Cdr cdr_;
  const char* type_;
};

// A MotionCommand's fields as RobotCommand_ has them (wire.hpp), the sequence aside; `primitive` is the text, cut to
// kPrimitiveTextBound - 1.
struct CommandFields {
  std::uint32_t robot = 0, index = 0, transition = 0;
  std::int64_t sent_ns = 0;
  std::string primitive;
};
// Throws WireError for an index over 32 bits.
CommandFields command_fields(const runtime::MotionCommand& command);
// The command for robot `robot` of `program` (the topic's): refused (WireError) when it is about another robot, its
// index is outside the program, it was sent before the run began, or its text is not the program's primitive there.
runtime::MotionCommand command_from_fields(const CommandFields& fields, const task::CompiledProgram& program,
                                           std::size_t robot);

// A RobotStatus's fields as RobotStatus_ has them (wire.hpp), the stamp aside: index -1 for kNoCommand, outcome 0 done
// and 1 failed; the reason whole (the caller cuts or bounds it).
struct StatusFields {
  std::uint32_t robot = 0;
  std::int64_t index = -1;
  std::uint8_t outcome = 0;
  bool stop_cell = false;
  std::string reason;
  std::int64_t time_ns = 0;
};
// Throws WireError for an index over 32 bits.
StatusFields status_fields(const runtime::RobotStatus& status);
// The status of robot `robot` (the topic's); WireError for another robot's, an index, outcome or time out of range.
runtime::RobotStatus status_from_fields(StatusFields fields, std::size_t robot);

}  // namespace cellwright::distributed::cdr_io
