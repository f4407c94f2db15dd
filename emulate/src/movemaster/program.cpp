// The Movemaster EX's stored program (program.hpp).
#include "movemaster/program.hpp"

#include <fmt/format.h>

#include <cctype>
#include <chrono>
#include <cstdlib>

namespace cellwright::emulate::movemaster {

bool Program::is_program_line(std::string_view line) {
  const std::size_t first = line.find_first_not_of(" \t");
  return first != std::string_view::npos && std::isdigit(static_cast<unsigned char>(line[first]));
}

std::optional<std::string> Program::store(std::string_view line) {
  std::size_t i = line.find_first_not_of(" \t");
  int number = 0;
  for (; i < line.size() && std::isdigit(static_cast<unsigned char>(line[i])); ++i) {
    number = number * 10 + (line[i] - '0');
    if (number > kLastLine) break;
  }
  if (number < kFirstLine || number > kLastLine) {
    return fmt::format("line number '{}' is not from {} to {}", line, kFirstLine, kLastLine);
  }
  const Parsed parsed = parse_command(line.substr(i));
  if (!parsed.command) return fmt::format("line {}: {}", number, parsed.error);
  if (handles(parsed.command->op)) return fmt::format("line {}: RN and NW are not program commands", number);
  lines_[number] = *parsed.command;
  return std::nullopt;
}

Executed Program::direct(const Command& command, Executor& executor, EmulatedArm& arm,
                         const std::function<void(int)>& on_line) {
  Executed out;
  if (command.op == Op::NW) {
    lines_.clear();
    return out;
  }
  auto at = command.line == 0 ? lines_.begin() : lines_.find(command.line);
  if (at == lines_.end() && command.line != 0) {
    executor.raise(kPositionError);
    out.error = fmt::format("RN: there is no line {}", command.line);
    return out;
  }
  // Jumps to line `target`, or ends the run with error 2 when there is none.
  const auto jump = [&](int target) {
    at = lines_.find(target);
    if (at != lines_.end()) return true;
    executor.raise(kPositionError);
    out.error = fmt::format("jump to line {}, which does not exist", target);
    return false;
  };
  while (at != lines_.end()) {
    const int number = at->first;
    const Command& c = at->second;
    if (on_line) on_line(number);
    switch (c.op) {
      case Op::ED:
        return out;
      case Op::GT:
        if (!jump(c.line)) return out;
        continue;
      case Op::TB: {
        const int bit = std::abs(c.bit);
        const bool on = c.bit > 0;  // the jump is taken while input `bit` is at this level
        if (c.line == number) {
          // A jump onto itself: the controller stays on this line until the input changes.
          const ArmResult r = arm.wait_input(bit, !on, std::chrono::nanoseconds(0));
          if (r.status == ArmStatus::interrupted) {
            out.interrupted = true;
            return out;
          }
          if (!r.ok()) {
            executor.raise(kHardwareError);
            out.error = fmt::format("line {}: waiting for input {}: {}", number, bit, r.message);
            return out;
          }
          ++at;
          continue;
        }
        if (arm.input(bit) == on) {
          if (!jump(c.line)) return out;
        } else {
          ++at;
        }
        continue;
      }
      default: {
        Executed done = executor.execute(c);
        if (done.interrupted || done.ignored || !done.error.empty()) {
          if (!done.error.empty()) done.error = fmt::format("line {}: {}", number, done.error);
          return done;
        }
        ++at;
      }
    }
  }
  return out;
}

}  // namespace cellwright::emulate::movemaster
