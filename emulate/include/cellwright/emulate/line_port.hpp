// LinePort: the serial port an emulated controller serves, as lines. It publishes a pseudo-terminal (pty.hpp) at a
// path, hands the controller the lines the host sends one at a time, writes the controller's answers, can hang up and
// publish a fresh pseudo-terminal at the same path (a `drop` misbehaviour), and makes every wait end at once when
// stop() is called from another thread. Not tied to one controller's language: the Movemaster EX and VAL II
// emulators can both serve through it.
//
// Lines: a line ends at CR, at LF, or at CR LF (one end, also when the LF arrives in a later read). The end is not
// part of the line; an empty line is returned as one (VAL II answers it with a prompt; Movemaster skips it). XON and
// XOFF bytes (0x11, 0x13: a host's software handshake) are dropped. A line longer than max_line bytes is cut there:
// the bytes up to its end are thrown away and the line is returned with `overlong` set, for the controller to reject.
//
// Threads: one thread (the emulator's) calls everything but stop(), stopped(), publications() and
// wait_published(), which any thread may call.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "cellwright/common/pty.hpp"
#include "cellwright/emulate/line_pace.hpp"

namespace cellwright::emulate {

struct ReceivedLine {
  std::string text;       // without its end
  bool overlong = false;  // cut at max_line; the rest was thrown away
};

class LinePort {
 public:
  // Publishes nothing yet. `pace`: the pseudo-terminal paced as a serial line at that rate (line_pace.hpp; baud 0:
  // not paced). Throws InputError if the process is out of descriptors (for the eventfd) or the rate is wrong.
  explicit LinePort(std::size_t max_line = 256, LineRate pace = {});
  ~LinePort();
  LinePort(const LinePort&) = delete;
  LinePort& operator=(const LinePort&) = delete;

  // Publishes a fresh pseudo-terminal at `link` (hanging up the previous one, if any, and replacing a stale link left
  // there) and forgets every byte not yet returned. Throws InputError as PseudoTerminal does.
  void publish(const std::filesystem::path& link);
  // Hangs up and removes the link: a host reading gets end-of-file or an error, and the path is gone until the next
  // publish() (as an unplugged adapter). Unread bytes are forgotten.
  void hang_up();
  // The pseudo-terminal's slave (/dev/pts/N), empty when none is published.
  std::string slave_path() const;

  // The next line the host sent (paced: once its last byte would have arrived); waits as long as it takes. nullopt
  // once stop() has been called (or with nothing published).
  std::optional<ReceivedLine> next_line();
  // Writes all of `bytes` (paced: a character time apart; waiting while the host does not read). False if stop() came
  // first or nothing is published.
  bool write(std::string_view bytes);
  // Waits `duration`; false if stop() came first (at once).
  bool wait(std::chrono::nanoseconds duration);

  // Ends every wait, now and later. Any thread; idempotent.
  void stop();
  bool stopped() const;
  // How many pseudo-terminals have been published so far. Any thread.
  std::uint64_t publications() const;
  // Waits until at least `count` pseudo-terminals have been published (and the last is ready for a host), or until
  // `timeout`, or until stop(). True if there were. Any thread.
  bool wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const;

 private:
  // Waits until the master is ready for `events`; false on stop().
  bool wait_master(short events) const;
  // Splits bytes read into lines_.
  void take(const char* bytes, std::size_t count);

  const std::size_t max_line_;
  int stop_fd_ = -1;  // an eventfd, readable once stop() was called
  std::unique_ptr<PseudoTerminal> pty_;
  std::deque<ReceivedLine> lines_;  // complete lines not yet returned
  ReceivedLine partial_;            // the line being received
  bool skip_lf_ = false;            // the last line ended with CR: an LF next is its end too
  LinePace pace_;
  LinePace::Clock::time_point arrived_{};  // paced: the bytes read so far have crossed the line by then

  mutable std::mutex mutex_;
  mutable std::condition_variable published_;
  std::uint64_t publications_ = 0;
  bool stopped_ = false;
};

}  // namespace cellwright::emulate
