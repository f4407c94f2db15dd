// Errors shared by every area.
//
// Policy (see DEVELOPERS.md):
//  - InputError: a user's input is wrong (program, YAML, URDF, PNML, serial reply). It names the file, the line and
//    column where known, and the problem with the offending values. Tools print what() and exit non-zero.
//  - CW_CHECK: an always-on invariant check for our own bugs. It throws InternalError naming the expression, the
//    source position and a message; it is never compiled out.
//  - Inside control cycles, functions return status enums instead of throwing (see drivers/ and twin/).
#pragma once

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <utility>

namespace cellwright {

// Where in a user's file something is. line and column are 1-based; 0 means "not known".
struct SourceLocation {
  std::string file;
  int line = 0;
  int column = 0;

  // "file:line:column", dropping the parts that are not known.
  std::string str() const {
    std::string s = file.empty() ? std::string("<input>") : file;
    if (line > 0) s += fmt::format(":{}", line);
    if (line > 0 && column > 0) s += fmt::format(":{}", column);
    return s;
  }
};

// Bad user input. what() is "file:line:col: error: problem" so that editors can jump to it.
class InputError : public std::runtime_error {
 public:
  InputError(SourceLocation where, std::string problem)
      : std::runtime_error(fmt::format("{}: error: {}", where.str(), problem)),
        where_(std::move(where)),
        problem_(std::move(problem)) {}

  const SourceLocation& where() const { return where_; }
  const std::string& problem() const { return problem_; }

 private:
  SourceLocation where_;
  std::string problem_;
};

// A broken invariant: a bug in Cellwright, not in the user's input.
class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

}  // namespace cellwright

// Always-on invariant check: CW_CHECK(n < size, "place {} out of range {}", n, size);
#define CW_CHECK(cond, ...)                                                                                   \
  do {                                                                                                        \
    if (!(cond)) {                                                                                            \
      throw ::cellwright::InternalError(::fmt::format("{}:{}: internal check failed: {}: {}", __FILE__,     \
                                                      __LINE__, #cond, ::fmt::format(__VA_ARGS__)));        \
    }                                                                                                         \
  } while (false)
