// LinePace (line_pace.hpp): a pseudo-terminal paced to a serial line's character time.
#include "cellwright/emulate/line_pace.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "cellwright/common/error.hpp"

namespace cellwright::emulate {

LinePace::LinePace(LineRate rate) {
  const SourceLocation where{"line pace", 0, 0};
  if (rate.baud < 0) throw InputError(where, fmt::format("the baud rate {} is negative", rate.baud));
  if (rate.bits_per_character < 7 || rate.bits_per_character > 12) {
    throw InputError(where, fmt::format("{} bits per character is outside 7..12", rate.bits_per_character));
  }
  if (rate.baud > 0) {
    character_ = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 * rate.bits_per_character / rate.baud));
  }
}

void LinePace::reset() {
  output_free_ = {};
  input_free_ = {};
}

bool LinePace::write(std::string_view bytes, const std::function<std::size_t(std::string_view)>& write_some,
                     const std::function<bool(Clock::time_point)>& wait_until) {
  if (!paced()) {
    while (!bytes.empty()) {
      const std::size_t n = write_some(bytes);
      if (n == 0) return false;
      bytes.remove_prefix(n);
    }
    return true;
  }
  const Clock::time_point start = std::max(Clock::now(), output_free_);
  output_free_ = start + character_ * static_cast<std::int64_t>(bytes.size());
  std::size_t done = 0;
  while (done < bytes.size()) {
    // The bytes whose last bit has crossed the line by now.
    const auto crossed = static_cast<std::size_t>((Clock::now() - start) / character_);
    const std::size_t due = std::min(bytes.size(), crossed);
    if (due <= done) {
      if (!wait_until(start + character_ * static_cast<std::int64_t>(done + 1))) return false;
      continue;
    }
    const std::size_t n = write_some(bytes.substr(done, due - done));
    if (n == 0) return false;
    done += n;
  }
  return true;
}

LinePace::Clock::time_point LinePace::received(std::size_t count, Clock::time_point now) {
  if (!paced()) return now;
  input_free_ = std::max(now, input_free_) + character_ * static_cast<std::int64_t>(count);
  return input_free_;
}

}  // namespace cellwright::emulate
