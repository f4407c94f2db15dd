// SerialPort: one RS-232 port (or a pseudo-terminal standing in for one), opened and configured with POSIX termios,
// every read and write bounded by a deadline through poll(). docs/real-robots.md says why termios rather than a
// library, and what the line settings of each controller are.
//
// The port is opened non-blocking, without becoming the controlling terminal; it is set raw (no echo, no line
// editing, no character translation) with the given rate, data bits, parity, stop bits and handshake, and whatever the
// controller sent before is discarded. Nothing here knows a protocol: bytes go out as given and come in as they
// arrive.
//
// Errors: the constructor throws InputError (naming `where`, the port and errno's text) when the port does not exist,
// cannot be opened or cannot be configured. After that, calls return an PortStatus and never throw.
//
// Threads: not synchronised. One thread (a serial driver's communication thread) owns the port.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>
#include <string_view>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers {

enum class Parity : std::uint8_t { none, even, odd };

// The line settings of one port. The defaults are the Movemaster EX's (docs/real-robots.md).
struct SerialLine {
  std::string port;  // e.g. /dev/ttyUSB0, or an emulator's published pseudo-terminal
  int baud = 9600;   // 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600 or 115200
  int data_bits = 7;
  Parity parity = Parity::even;
  int stop_bits = 2;
  bool rts_cts = true;
  bool xon_xoff = true;

  // Bits on the wire per character: start bit, data bits, parity bit (if any), stop bits.
  int bits_per_character() const { return 1 + data_bits + (parity == Parity::none ? 0 : 1) + stop_bits; }
  // The time `characters` take on the wire at this rate.
  std::chrono::nanoseconds wire_time(std::size_t characters) const;
};

enum class PortStatus : std::uint8_t {
  ok,
  timeout,  // the deadline passed first
  closed,   // the other end hung up (end of file, POLLHUP, EIO): the link dropped
  error,    // another system error (the message says which)
};

class SerialPort {
 public:
  using Clock = std::chrono::steady_clock;

  // Opens and configures `line.port`. Throws InputError(where, ...) naming the port and the reason.
  SerialPort(const SerialLine& line, const SourceLocation& where);
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  const SerialLine& line() const { return line_; }

  // Writes all of `bytes` before `deadline`. On anything but ok, `*message` says what happened (errno's text).
  PortStatus write(std::string_view bytes, Clock::time_point deadline, std::string* message);
  // Appends to `*buffer` the bytes that arrive, waiting until at least one has arrived or `deadline` passes. Returns
  // ok when it appended something.
  PortStatus read_some(std::string* buffer, Clock::time_point deadline, std::string* message);
  // Discards bytes received and not yet read.
  void discard_input();
  // Makes the read or write in progress (and every later one) return closed at once, "interrupted": the way another
  // thread ends a wait on the port before closing it. The one call here that any thread may make.
  void interrupt();
  // The time spent blocked in poll() since the port was opened (the host waiting for the line), for timing reports.
  std::chrono::nanoseconds waited() const { return waited_; }

 private:
  // Waits in poll() until the port is ready for `events` (POLLIN or POLLOUT), the deadline passes (timeout, no
  // message), interrupt() is called or the other end hangs up (closed), or poll fails (error).
  PortStatus wait_until_ready(short events, Clock::time_point deadline, std::string* message);

  SerialLine line_;
  int fd_ = -1;
  int interrupt_fd_ = -1;  // an eventfd, readable once interrupt() was called
  std::chrono::nanoseconds waited_{0};
};

}  // namespace cellwright::drivers
