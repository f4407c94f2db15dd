// SerialPort (serial_port.hpp): termios configuration, poll()-bounded reads and writes.
#include "cellwright/drivers/serial/serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace cellwright::drivers {

namespace {

speed_t baud_constant(int baud) {
  switch (baud) {
    case 300:
      return B300;
    case 600:
      return B600;
    case 1200:
      return B1200;
    case 2400:
      return B2400;
    case 4800:
      return B4800;
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    default:
      return B0;
  }
}

tcflag_t size_flag(int bits) {
  switch (bits) {
    case 5:
      return CS5;
    case 6:
      return CS6;
    case 7:
      return CS7;
    case 8:
      return CS8;
    default:
      return 0;
  }
}

// tcsetattr(TCSANOW). A pseudo-terminal keeps 8 bits and no parity whatever it is asked; glibc reports EINVAL when a
// request changed nothing the kernel kept (the second open of a pseudo-terminal set to 7E2: a reconnect to an
// emulator), so there the result is checked instead: everything but the character format must have taken.
bool set_attributes(int fd, const termios& want) {
  if (tcsetattr(fd, TCSANOW, &want) == 0) return true;
  struct stat st {};
  termios got{};
  const bool pty_slave = errno == EINVAL && fstat(fd, &st) == 0 && S_ISCHR(st.st_mode) && major(st.st_rdev) >= 136 &&
                         major(st.st_rdev) <= 143;  // UNIX98 pseudo-terminal slaves
  if (!pty_slave || tcgetattr(fd, &got) != 0) {
    errno = EINVAL;
    return false;
  }
  const tcflag_t format = CSIZE | PARENB | PARODD;
  const bool took = (got.c_cflag & ~format) == (want.c_cflag & ~format) && got.c_iflag == want.c_iflag &&
                    got.c_oflag == want.c_oflag && got.c_lflag == want.c_lflag && got.c_cc[VMIN] == want.c_cc[VMIN] &&
                    got.c_cc[VTIME] == want.c_cc[VTIME];
  if (!took) errno = EINVAL;
  return took;
}

// Milliseconds until `deadline` for poll(), rounded up, at least 0.
int poll_timeout(SerialPort::Clock::time_point deadline) {
  const auto left = deadline - SerialPort::Clock::now();
  if (left <= SerialPort::Clock::duration::zero()) return 0;
  return static_cast<int>(std::chrono::ceil<std::chrono::milliseconds>(left).count());
}

}  // namespace

std::chrono::nanoseconds SerialLine::wire_time(std::size_t characters) const {
  const double seconds = static_cast<double>(characters) * bits_per_character() / static_cast<double>(baud);
  return std::chrono::nanoseconds(static_cast<std::int64_t>(seconds * 1e9));
}

SerialPort::SerialPort(const SerialLine& line, const SourceLocation& where) : line_(line) {
  const speed_t speed = baud_constant(line.baud);
  const tcflag_t size = size_flag(line.data_bits);
  if (speed == B0)
    throw InputError(where, fmt::format("serial port {}: unsupported baud rate {}", line.port, line.baud));
  if (size == 0)
    throw InputError(where, fmt::format("serial port {}: {} data bits (5 to 8)", line.port, line.data_bits));
  if (line.stop_bits != 1 && line.stop_bits != 2) {
    throw InputError(where, fmt::format("serial port {}: {} stop bits (1 or 2)", line.port, line.stop_bits));
  }
  if (line.port.empty()) throw InputError(where, "no serial port given");
  fd_ = ::open(line.port.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    throw InputError(where, fmt::format("cannot open serial port {}: {}", line.port, std::strerror(errno)));
  }
  termios t{};
  if (tcgetattr(fd_, &t) != 0) {
    const int e = errno;
    ::close(fd_);
    throw InputError(
        where, fmt::format("serial port {} cannot be configured (is it a terminal?): {}", line.port, std::strerror(e)));
  }
  cfmakeraw(&t);
  t.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | PARODD | CSTOPB | CRTSCTS);
  t.c_cflag |= size | CLOCAL | CREAD;
  if (line.parity != Parity::none) t.c_cflag |= PARENB;
  if (line.parity == Parity::odd) t.c_cflag |= PARODD;
  if (line.stop_bits == 2) t.c_cflag |= CSTOPB;
  if (line.rts_cts) t.c_cflag |= CRTSCTS;
  t.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  if (line.xon_xoff) t.c_iflag |= IXON | IXOFF;
  // VMIN 1: with O_NONBLOCK an empty input queue reads as EAGAIN. With VMIN 0 and VTIME 0 the tty driver returns 0
  // instead, which read_some() would take for the end of file (a hang-up).
  t.c_cc[VMIN] = 1;
  t.c_cc[VTIME] = 0;
  if (cfsetispeed(&t, speed) != 0 || cfsetospeed(&t, speed) != 0 || !set_attributes(fd_, t)) {
    const int e = errno;
    ::close(fd_);
    throw InputError(where, fmt::format("serial port {} cannot be configured: {}", line.port, std::strerror(e)));
  }
  interrupt_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (interrupt_fd_ < 0) {
    const int e = errno;
    ::close(fd_);
    throw InputError(where,
                     fmt::format("serial port {}: cannot make an event descriptor: {}", line.port, std::strerror(e)));
  }
  discard_input();
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);
  if (interrupt_fd_ >= 0) ::close(interrupt_fd_);
}

void SerialPort::interrupt() {
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(interrupt_fd_, &one, sizeof one);
}

PortStatus SerialPort::wait_until_ready(short events, Clock::time_point deadline, std::string* message) {
  pollfd fds[2] = {{fd_, events, 0}, {interrupt_fd_, POLLIN, 0}};
  const auto before = Clock::now();
  const int r = ::poll(fds, 2, poll_timeout(deadline));
  waited_ += Clock::now() - before;
  if (r > 0 && (fds[1].revents & POLLIN) != 0) {
    *message = "interrupted: the driver is closing the port";
    return PortStatus::closed;
  }
  if (r == 0) return PortStatus::timeout;
  if (r < 0) {
    if (errno == EINTR) return PortStatus::ok;  // try again
    *message = std::strerror(errno);
    return PortStatus::error;
  }
  // A hang-up with bytes still to read is read first; the read then sees the end.
  if ((fds[0].revents & events) == 0 && (fds[0].revents & (POLLHUP | POLLERR)) != 0) {
    *message = "the other end hung up";
    return PortStatus::closed;
  }
  return PortStatus::ok;
}

PortStatus SerialPort::write(std::string_view bytes, Clock::time_point deadline, std::string* message) {
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + sent, bytes.size() - sent);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN) {
      *message = std::strerror(errno);
      return errno == EIO ? PortStatus::closed : PortStatus::error;
    }
    if (const PortStatus s = wait_until_ready(POLLOUT, deadline, message); s != PortStatus::ok) {
      if (s == PortStatus::timeout)
        *message = fmt::format("{} of {} bytes written before the deadline", sent, bytes.size());
      return s;
    }
  }
  return PortStatus::ok;
}

PortStatus SerialPort::read_some(std::string* buffer, Clock::time_point deadline, std::string* message) {
  for (;;) {
    char chunk[256];
    const ssize_t n = ::read(fd_, chunk, sizeof chunk);
    if (n > 0) {
      buffer->append(chunk, static_cast<std::size_t>(n));
      return PortStatus::ok;
    }
    if (n == 0) {
      *message = "end of file: the other end hung up";
      return PortStatus::closed;
    }
    if (errno == EINTR) continue;
    if (errno == EIO) {
      *message = "input/output error: the other end hung up";
      return PortStatus::closed;
    }
    if (errno != EAGAIN) {
      *message = std::strerror(errno);
      return PortStatus::error;
    }
    if (const PortStatus s = wait_until_ready(POLLIN, deadline, message); s != PortStatus::ok) {
      if (s == PortStatus::timeout) *message = "no bytes before the deadline";
      return s;
    }
  }
}

void SerialPort::discard_input() {
  tcflush(fd_, TCIFLUSH);
}

}  // namespace cellwright::drivers
