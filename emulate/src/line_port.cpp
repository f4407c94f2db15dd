// LinePort (line_port.hpp): a PseudoTerminal read line by line with poll(), and an eventfd that ends every wait.
#include "cellwright/emulate/line_port.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "cellwright/common/error.hpp"

namespace cellwright::emulate {

namespace {

constexpr char kXon = 0x11;
constexpr char kXoff = 0x13;

}  // namespace

LinePort::LinePort(std::size_t max_line, LineRate pace) : max_line_(max_line), pace_(pace) {
  CW_CHECK(max_line > 0, "a line port needs room for a line");
  stop_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (stop_fd_ < 0) {
    throw InputError({"<emulator>", 0, 0}, fmt::format("cannot make an eventfd: {}", std::strerror(errno)));
  }
}

LinePort::~LinePort() {
  pty_.reset();
  ::close(stop_fd_);
}

void LinePort::publish(const std::filesystem::path& link) {
  hang_up();
  pty_ = std::make_unique<PseudoTerminal>(link);
  std::lock_guard lock(mutex_);
  ++publications_;
  published_.notify_all();
}

void LinePort::hang_up() {
  pty_.reset();  // closes both sides and removes the link
  lines_.clear();
  partial_ = {};
  skip_lf_ = false;
  pace_.reset();
}

std::string LinePort::slave_path() const {
  return pty_ ? pty_->slave_path() : std::string();
}

void LinePort::take(const char* bytes, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    const char c = bytes[i];
    const bool lf_of_crlf = skip_lf_ && c == '\n';
    skip_lf_ = false;
    if (lf_of_crlf || c == kXon || c == kXoff) continue;
    if (c == '\r' || c == '\n') {
      skip_lf_ = c == '\r';
      lines_.push_back(std::move(partial_));
      partial_ = {};
    } else if (partial_.text.size() < max_line_) {
      partial_.text.push_back(c);
    } else {
      partial_.overlong = true;  // the tail up to the line's end is thrown away
    }
  }
}

std::optional<ReceivedLine> LinePort::next_line() {
  char bytes[512];
  while (lines_.empty()) {
    if (!pty_ || !wait_master(POLLIN)) return std::nullopt;
    const ssize_t n = ::read(pty_->master(), bytes, sizeof bytes);
    if (n > 0) {
      take(bytes, static_cast<std::size_t>(n));
      arrived_ = pace_.received(static_cast<std::size_t>(n), LinePace::Clock::now());
    } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
      throw InputError({pty_->slave_path(), 0, 0},
                       fmt::format("cannot read the pseudo-terminal's master: {}", std::strerror(errno)));
    }
  }
  if (pace_.paced() && !wait(arrived_ - LinePace::Clock::now())) return std::nullopt;  // its end is still on the line
  ReceivedLine line = std::move(lines_.front());
  lines_.pop_front();
  return line;
}

bool LinePort::write(std::string_view bytes) {
  const auto write_some = [this](std::string_view part) -> std::size_t {
    for (;;) {
      if (!pty_ || stopped()) return 0;
      const ssize_t n = ::write(pty_->master(), part.data(), part.size());
      if (n > 0) return static_cast<std::size_t>(n);
      if (n < 0 && errno != EAGAIN && errno != EINTR) {
        throw InputError({pty_->slave_path(), 0, 0},
                         fmt::format("cannot write the pseudo-terminal's master: {}", std::strerror(errno)));
      }
      if (!wait_master(POLLOUT)) return 0;
    }
  };
  return pace_.write(bytes, write_some,
                     [this](LinePace::Clock::time_point t) { return wait(t - LinePace::Clock::now()); });
}

bool LinePort::wait(std::chrono::nanoseconds duration) {
  const auto end = std::chrono::steady_clock::now() + duration;
  for (;;) {
    const auto left = end - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds::zero()) return !stopped();
    const auto s = std::chrono::duration_cast<std::chrono::seconds>(left);
    const timespec ts{static_cast<time_t>(s.count()), static_cast<long>((left - s).count())};
    pollfd p{stop_fd_, POLLIN, 0};
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    if (r > 0) return false;  // stop() wrote the eventfd
  }
}

bool LinePort::wait_master(short events) const {
  for (;;) {
    pollfd p[2] = {{pty_->master(), events, 0}, {stop_fd_, POLLIN, 0}};
    const int r = ::poll(p, 2, -1);
    if (r < 0 && errno == EINTR) continue;
    CW_CHECK(r > 0, "poll on a pseudo-terminal failed: {}", std::strerror(errno));
    if (p[1].revents != 0) return false;
    if (p[0].revents != 0) return true;
  }
}

void LinePort::stop() {
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(stop_fd_, &one, sizeof one);  // never full: written a few times at most
  std::lock_guard lock(mutex_);
  stopped_ = true;
  published_.notify_all();
}

bool LinePort::stopped() const {
  std::lock_guard lock(mutex_);
  return stopped_;
}

std::uint64_t LinePort::publications() const {
  std::lock_guard lock(mutex_);
  return publications_;
}

bool LinePort::wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const {
  std::unique_lock lock(mutex_);
  published_.wait_for(lock, timeout, [&] { return publications_ >= count || stopped_; });
  return publications_ >= count;
}

}  // namespace cellwright::emulate
