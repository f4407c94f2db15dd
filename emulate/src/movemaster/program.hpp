// The Movemaster EX's stored program (docs/real-robots.md, "Robot programs"): lines received as `n COMMAND` are
// stored, not executed; `RN` runs them, in line-number order, through the same Executor as the serial line's
// commands, with the program commands' flow (TB, GT, ED) done here; `NW` deletes them.
//
// A run goes from the first line (or RN's) to ED or past the last line. It ends early when a line fails (the register
// set as the command sets it, or a jump to a line that does not exist: error 2), when a line is ignored because the
// controller is halted, or when the arm is interrupted. `L TB -n,L` (a test-bit jump onto its own line) waits for the
// input with the arm's wait_input rather than spinning.
//
// Threads: the emulator's thread only.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "cellwright/emulate/emulated_arm.hpp"
#include "movemaster/command.hpp"
#include "movemaster/executor.hpp"

namespace cellwright::emulate::movemaster {

class Program {
 public:
  // Whether `line` is a program line: it starts (after spaces) with a digit.
  static bool is_program_line(std::string_view line);
  // Whether this command is the program's to carry out (RN, NW) rather than the executor's.
  static bool handles(Op op) { return op == Op::RN || op == Op::NW; }

  // Stores a program line ("n COMMAND", n 1–2048; a line with the number of a stored one replaces it). Returns why it
  // could not (a number out of range, a command that does not parse, RN or NW in a program), or nullopt when stored.
  std::optional<std::string> store(std::string_view line);

  // Carries out RN or NW. RN runs the program (see the top), calling `on_line` with each line's number before it
  // runs (it may be empty); its result is the failing line's, or an empty one when the program ended.
  Executed direct(const Command& command, Executor& executor, EmulatedArm& arm,
                  const std::function<void(int)>& on_line);

  std::size_t size() const { return lines_.size(); }

 private:
  std::map<int, Command> lines_;
};

}  // namespace cellwright::emulate::movemaster
