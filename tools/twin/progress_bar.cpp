// The progress line on stderr (progress_bar.hpp).
#include "progress_bar.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace cellwright::tools {

ProgressBar::ProgressBar() : tty_(isatty(STDERR_FILENO) == 1) {}

void ProgressBar::update(const std::string& line, std::size_t done, std::size_t total) {
  if (tty_) {
    std::fprintf(stderr, "\r%-*s", static_cast<int>(std::max(width_, line.size())), line.c_str());
    width_ = line.size();
  } else {
    const std::size_t every = std::max<std::size_t>(1, total / 10);
    if (done == printed_ || (done % every != 0 && done != total)) return;
    std::fprintf(stderr, "%s\n", line.c_str());
    printed_ = done;
  }
  std::fflush(stderr);
}

void ProgressBar::clear() {
  if (!tty_ || width_ == 0) return;
  std::fprintf(stderr, "\r%*s\r", static_cast<int>(width_), "");
  std::fflush(stderr);
  width_ = 0;
}

void ProgressBar::finish() {
  if (tty_ && width_ > 0) std::fprintf(stderr, "\n");
  width_ = 0;
}

}  // namespace cellwright::tools
