// Helpers the task-language tests share: compiling program text, finding a robot's program, an error's position.
#pragma once

#include <stdexcept>
#include <string>

#include "cellwright/task/compile.hpp"

namespace cellwright::task::test {

// Parses and compiles `text` as the file "t.task".
inline CompiledProgram compile_text(const std::string& text) {
  return compile(parse_program(text, "t.task"));
}

// The compiled program of `robot`; std::runtime_error if there is none.
inline const RobotProgram& program_of(const CompiledProgram& c, const std::string& robot) {
  for (const RobotProgram& p : c.programs) {
    if (p.robot == robot) return p;
  }
  throw std::runtime_error("no program for " + robot);
}

// Where an InputError pointed, and its problem.
struct Failure {
  int line = 0;
  int column = 0;
  std::string problem;
};

}  // namespace cellwright::task::test
