// The VAL II monitor's language as parsed values (val2_emulator.hpp says what is accepted), kept apart from carrying
// it out (executor.hpp): a monitor line and, later, a stored program's line parse to the same Instruction, which one
// function executes.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace cellwright::emulate::val2 {

// The error lines the monitor prints (docs/real-robots.md, "Errors").
inline constexpr std::string_view kUnknownInstruction = "*Unknown instruction*";
inline constexpr std::string_view kSyntaxError = "*Syntax error*";
inline constexpr std::string_view kInvalidArgument = "*Invalid argument*";
inline constexpr std::string_view kIllegalValue = "*Illegal value*";
inline constexpr std::string_view kLocationOutOfRange = "*Location out of range*";
inline constexpr std::string_view kServoError = "*Servo error*";
inline constexpr std::string_view kArmPowerOff = "*Arm power off*";
inline constexpr std::string_view kInvalidFormat = "*Invalid format*";  // only from the `unknown` misbehaviour
// `*Joint n limit stop*`, n from 1.
std::string joint_limit_stop(int joint);

struct Location {
  enum class Kind : std::uint8_t { trans, precision_point };
  Kind kind = Kind::trans;
  // trans: x, y, z (mm), o, a, t (degrees); precision point: the six joint angles (degrees).
  std::array<double, 6> values{};
};

enum class Op : std::uint8_t {
  nothing,      // an empty line
  where,        // WHERE (monitor only)
  ready,        // READY
  move,         // MOVE loc
  moves,        // MOVES TRANS(...)
  open_hand,    // OPENI
  close_hand,   // CLOSEI
  speed,        // SPEED n
  signal,       // SIGNAL n[,n...]
  wait_signal,  // WAIT SIG(n)
};

struct Instruction {
  Op op = Op::nothing;
  Location location;         // move, moves
  double speed = 0;          // speed: percent, [1, 100]
  std::vector<int> signals;  // signal: ±1..±32, each; wait_signal: one, ±1001..±1032
};

// An instruction, or the error line to print instead.
struct Parsed {
  Instruction instruction;
  std::string error;  // empty when parsed
  bool ok() const { return error.empty(); }
};

// One line typed at the monitor (without its line end): empty, `DO instruction`, `SPEED n`, `WHERE`.
Parsed parse_monitor_line(std::string_view line);
// One instruction, as after DO (and, later, as a program's step).
Parsed parse_instruction(std::string_view text);

}  // namespace cellwright::emulate::val2
