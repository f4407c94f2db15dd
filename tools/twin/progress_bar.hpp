// The progress line of the commands that run child processes (`twin campaign`, `twin test`), on stderr: one line
// rewritten in place on a terminal; in a log (not a terminal), a line at each tenth of the total and at the end.
#pragma once

#include <cstddef>
#include <string>

namespace cellwright::tools {

class ProgressBar {
 public:
  ProgressBar();

  // Shows `line`, the state after `done` of `total` items.
  void update(const std::string& line, std::size_t done, std::size_t total);
  // On a terminal, blanks the line so that other output can be printed; the next update() draws it again.
  void clear();
  // Ends the line on a terminal.
  void finish();

 private:
  const bool tty_;
  std::size_t width_ = 0;
  std::size_t printed_ = static_cast<std::size_t>(-1);
};

}  // namespace cellwright::tools
