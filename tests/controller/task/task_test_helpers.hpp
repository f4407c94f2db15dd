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

// Two sequences relaying parts over a stand S in loops with one decision (`repeat COUNT with ...`): r1 puts each part
// on the stand once it is free and says so (full); r2 takes it from there, frees the stand and puts the part down.
// They meet only at the stand. with_loops() fills in the loop lines.
inline constexpr const char* kStandRelay = R"(robot r1 r2
workpiece part from IN
workpiece held from S
location IN S OUT
semaphore free = 1
semaphore full
sequence r1
  LOOP1
    Pick part
    wait free
    Place S
    signal full
  end
end
sequence r2
  LOOP2
    wait full
    Pick held
    signal free
    Place OUT
  end
end
)";

// kStandRelay with its two `repeat` lines.
inline std::string stand_relay(const std::string& loop1, const std::string& loop2) {
  std::string s = kStandRelay;
  s.replace(s.find("LOOP1"), 5, loop1);
  s.replace(s.find("LOOP2"), 5, loop2);
  return s;
}

// Where an InputError pointed, and its problem.
struct Failure {
  int line = 0;
  int column = 0;
  std::string problem;
};

}  // namespace cellwright::task::test
