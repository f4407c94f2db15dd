// The Movemaster EX commands the emulator understands, parsed from one line (docs/real-robots.md, "Movemaster EX").
// Parsing only: what a command does is the executor's (executor.hpp), so that a stored program's lines can later be
// parsed once and run by the same executor.
//
// What a line may look like: the mnemonic's letters in either case, spaces before, after and between the fields, and
// numbers with or without a sign, a leading zero, a point and decimals (`+.5`, `-0.5`, `12`, `12.25`). Whole-number
// fields (position, points, speed level, grip force and time) take a number with a zero fraction too (`5.0`).
// Anything else is a format error; so is a value outside its range.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace cellwright::emulate::movemaster {

// MO, OB, TB, GT, ED, RN, NW are the program commands (docs/real-robots.md, "Robot programs"; movemaster/program.hpp).
enum class Op : std::uint8_t { NT, MP, PD, MS, GO, GC, GP, SP, TL, WH, ER, RS, MO, OB, TB, GT, ED, RN, NW };

// A pose in the controller's terms: the tool point in mm, pitch and roll in degrees (the 5-axis rule, pose.hpp).
struct Pose5 {
  double x = 0, y = 0, z = 0, p = 0, r = 0;
};

inline constexpr int kFirstPosition = 1;
inline constexpr int kLastPosition = 629;
inline constexpr int kFirstLine = 1;  // program line numbers
inline constexpr int kLastLine = 2048;
inline constexpr int kLastBit = 16;  // I/O bits 1–16 (assumed)

struct Command {
  Op op = Op::NT;
  Pose5 pose;                 // MP, PD
  int position = 0;           // PD, MS, MO: 1–629
  int points = 0;             // MS: intermediate points, 0–99
  std::optional<bool> open;   // MS, MO: the gripper letter (O open, C closed); none given: the gripper stays
  int bit = 0;                // OB, TB: ±1–16, the sign says on (+) or off (−)
  int line = 0;               // TB, GT: the line to jump to; RN: the first line to run (0: the program's first)
  int level = 0;              // SP: 0–9
  std::optional<bool> high;   // SP: H (true) or L (false), if given
  std::array<int, 3> grip{};  // GP: starting force 0–15, retained force 0–15, starting time 0–99 (x 0.1 s)
  double tool_length = 0;     // TL: mm, 0–300
};

struct Parsed {
  std::optional<Command> command;  // none: a format error
  std::string error;               // why, for the log
};

// Parses one line, without its end. Empty lines are the caller's business (they are not commands).
Parsed parse_command(std::string_view line);

}  // namespace cellwright::emulate::movemaster
