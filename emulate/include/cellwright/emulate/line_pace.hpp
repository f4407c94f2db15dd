// LinePace: makes a pseudo-terminal, which passes bytes at once, behave like a serial line at a baud rate, for an
// emulated controller that serves it (the `pace` option of both emulators; `twin emulate --pace`). A real line
// carries one character every bits_per_character / baud seconds, each way. Without pacing a pseudo-terminal delivers
// an answer of 230 bytes at once, where at 9600 baud it takes 0.24 s: figures of how a driver shares its line
// (tools/bench/polling_bench.cpp) would not be honest.
//
// OUTPUT. write() hands the bytes to the host as they would arrive: byte i of a block (from 1) no sooner than i
// character times after the transmitter was free (the end of the previous block, or now when the line is idle).
// INPUT. The host's bytes come at once; received() gives the time the last of them would have arrived (they follow
// the bytes received before them, one character time each), and the emulator takes the line they end only then.
//
// A pace of 0 baud is no pacing: write() writes at once and received() returns `now`. One thread (the emulator's).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <string_view>

namespace cellwright::emulate {

struct LineRate {
  int baud = 0;                 // characters per second times bits_per_character; 0: not paced
  int bits_per_character = 10;  // start + data + parity + stop: 10 for 8N1 (VAL II), 11 for 7E2 (Movemaster EX)
};

class LinePace {
 public:
  using Clock = std::chrono::steady_clock;

  // Throws InputError when the baud is negative or the bits per character are outside 7..12.
  explicit LinePace(LineRate rate = {});

  bool paced() const { return character_.count() > 0; }
  // One character's time on the line (0 when not paced).
  std::chrono::nanoseconds character_time() const { return character_; }

  // Writes `bytes` through `write_some` (which writes a prefix of what it is given and returns how many bytes it took,
  // or 0 to give up: the line is gone or stopping), each byte once its time has come, waiting with `wait` (false: stop
  // at once). True when every byte was written.
  bool write(std::string_view bytes, const std::function<std::size_t(std::string_view)>& write_some,
             const std::function<bool(Clock::time_point)>& wait_until);
  // `count` bytes were read from the host at `now`: when the last of them would have arrived.
  Clock::time_point received(std::size_t count, Clock::time_point now);
  // Forgets the line's state (a fresh pseudo-terminal).
  void reset();

 private:
  std::chrono::nanoseconds character_{0};
  Clock::time_point output_free_{};  // the transmitter is busy until then
  Clock::time_point input_free_{};   // the host's bytes received so far have all arrived by then
};

}  // namespace cellwright::emulate
