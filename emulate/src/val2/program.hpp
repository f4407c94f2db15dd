// VAL II's stored programs and locations (docs/real-robots.md, "Robot programs"), as a host loads them at the monitor:
// `.PROGRAM name` ... `.END` stores a program's steps, `.LOCATIONS` ... `.END` named locations (`name x y z o a t`),
// and `EXECUTE name` runs the program step by step through the same Executor as the monitor's `DO` lines.
//
// Steps: `;` comments (no-ops), every instruction parse_instruction() takes, and `MOVE name` / `MOVES name` to a
// named location (looked up when the step runs). A step that does not parse is answered with its error line and the
// program being defined is not stored (its `.END` answers `*Program not stored*`). A run ends after the last step
// (`Program completed`), at the first step whose instruction prints an error line (that line, then
// `Program stopped at step n`), or when the arm is interrupted.
//
// Threads: the emulator's thread only.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "val2/executor.hpp"
#include "val2/instruction.hpp"

namespace cellwright::emulate::val2 {

class Programs {
 public:
  // Takes a monitor line if it is the programs' business (a line inside `.PROGRAM`/`.LOCATIONS`, those keywords,
  // `.END`, `EXECUTE name`): stores or runs it and says what to print. nullopt for any other line. `on_step` is called
  // with each step's number (from 1) before it runs; it may be empty.
  std::optional<Outcome> take(std::string_view line, Executor& executor, const std::function<void(int)>& on_step);

 private:
  struct Step {
    std::string text;
    bool comment = false;
    Instruction instruction;    // when not a comment
    std::string location_name;  // MOVE/MOVES to a named location (upper case), else empty
  };
  enum class Mode { monitor, program, locations };

  Outcome run(const std::string& name, Executor& executor, const std::function<void(int)>& on_step);
  std::optional<std::string> define_step(std::string_view text);  // error line, or nullopt when stored

  Mode mode_ = Mode::monitor;
  std::string defining_;  // the program being defined
  std::vector<Step> steps_;
  bool defining_failed_ = false;
  std::map<std::string, std::vector<Step>> programs_;       // by upper-case name
  std::map<std::string, std::array<double, 6>> locations_;  // by upper-case name: x, y, z, o, a, t
};

}  // namespace cellwright::emulate::val2
