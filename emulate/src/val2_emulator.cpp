// Val2Emulator (val2_emulator.hpp): the line (a pseudo-terminal, its bytes cut into lines, the prompt) and the
// misbehaviour plan; parsing and carrying out are val2/instruction.hpp and val2/executor.hpp.
#include "cellwright/emulate/val2_emulator.hpp"

#include <fmt/format.h>

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <optional>
#include <random>

#include "cellwright/common/error.hpp"
#include "cellwright/common/pty.hpp"
#include "cellwright/emulate/line_pace.hpp"
#include "val2/executor.hpp"
#include "val2/instruction.hpp"
#include "val2/program.hpp"

namespace cellwright::emulate {

namespace {

// VAL II's input line is short; longer lines are refused whole rather than cut.
constexpr std::size_t kMaxLine = 255;

// A line as received: its text without the line end, after erasures.
struct ReceivedLine {
  std::string text;
  bool overlong = false;
};

// What handling one line leads to.
enum class Next : std::uint8_t { read_on, hang_up, stop };

}  // namespace

struct Val2Emulator::Impl {
  Impl(EmulatedArm& a, Val2EmulatorOptions o)
      : arm(a),
        options(std::move(o)),
        plan(options.misbehaviours, options.seed),
        executor(a, options.speed, {options.orientation == Val2EmulatorOptions::Orientation::val, options.world,
                                    options.tool}),
        garbage_random(options.seed ^ 0x9e3779b97f4a7c15ULL),
        pace(options.pace) {}

  EmulatedArm& arm;
  const Val2EmulatorOptions options;
  MisbehaviourPlan plan;
  val2::Executor executor;
  val2::Programs programs;  // stored programs and locations (.PROGRAM, .LOCATIONS, EXECUTE)
  std::mt19937_64 garbage_random;
  LinePace pace;  // options.pace: the pseudo-terminal paced as a serial line

  int wake = -1;  // an eventfd, readable once stop() was called
  std::atomic<bool> stopping{false};
  std::atomic<bool> served{false};

  mutable std::mutex stats_mutex;
  std::condition_variable stats_changed;  // wait_published() waits on it
  Stats stats;

  // The connection being served.
  int fd = -1;
  std::string received;  // bytes read and not yet cut into lines
  std::size_t used = 0;  // of `received`
  std::string pending;   // the line being received
  bool pending_overlong = false;
  bool after_cr = false;       // the last byte was a CR: an LF now is its partner
  bool at_line_start = false;  // the last byte written ended a line
  std::chrono::steady_clock::time_point input_arrived{};  // the bytes read so far have crossed the line (pace)

  template <typename F>
  void update(F&& f) {
    {
      std::lock_guard lock(stats_mutex);
      f(stats);
    }
    stats_changed.notify_all();
  }

  // Waits `d` unless stop() comes; false when stopping.
  bool pause(std::chrono::nanoseconds d) {
    const auto until = std::chrono::steady_clock::now() + d;
    for (;;) {
      if (stopping) return false;
      const auto left = until - std::chrono::steady_clock::now();
      if (left <= std::chrono::nanoseconds(0)) return true;
      const auto s = std::chrono::duration_cast<std::chrono::seconds>(left);
      const timespec ts{static_cast<time_t>(s.count()), static_cast<long>((left - s).count())};
      pollfd p{wake, POLLIN, 0};
      ppoll(&p, 1, &ts, nullptr);
    }
  }

  // Waits until `t` unless stop() comes; false when stopping.
  bool pause_until(std::chrono::steady_clock::time_point t) { return pause(t - std::chrono::steady_clock::now()); }

  // Writes all of `bytes` (at the line's pace, options.pace), waiting while the line is full; false when stopping. A
  // line that fails (EIO) loses them.
  bool write_all(std::string_view bytes) {
    if (bytes.empty()) return !stopping;
    std::size_t done = 0;
    const auto write_some = [&](std::string_view part) -> std::size_t {
      for (;;) {
        if (stopping) return 0;
        const ssize_t n = ::write(fd, part.data(), part.size());
        if (n > 0) {
          done += static_cast<std::size_t>(n);
          return static_cast<std::size_t>(n);
        }
        if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
          pollfd p[2] = {{fd, POLLOUT, 0}, {wake, POLLIN, 0}};
          poll(p, 2, -1);
        } else {
          return 0;
        }
      }
    };
    pace.write(bytes, write_some, [&](std::chrono::steady_clock::time_point t) { return pause_until(t); });
    update([&](Stats& s) { s.bytes_out += done; });
    at_line_start = bytes.back() == '\n';
    return !stopping;
  }

  // The next complete line from the bytes read so far, if there is one.
  std::optional<ReceivedLine> take_line() {
    while (used < received.size()) {
      const char c = received[used++];
      if (c == '\n' && after_cr) {
        after_cr = false;
        continue;
      }
      after_cr = c == '\r';
      if (c == '\r' || c == '\n') {
        ReceivedLine line{std::move(pending), pending_overlong};
        pending.clear();
        pending_overlong = false;
        return line;
      }
      if (c == '\b' || c == '\x7f') {
        if (!pending.empty()) pending.pop_back();
      } else if (pending.size() < kMaxLine) {
        pending += c;
      } else {
        pending_overlong = true;
      }
    }
    received.clear();
    used = 0;
    return std::nullopt;
  }

  // One line of seeded bytes that are not the protocol.
  std::string garbage() {
    std::string g(8 + garbage_random() % 16, '\0');
    for (char& c : g) c = static_cast<char>(0x80 + garbage_random() % 0x7f);  // 0x80..0xFE
    return g + "\r\n";
  }

  Next handle(const ReceivedLine& line);
  Next serve_connection(int master);
};

Next Val2Emulator::Impl::handle(const ReceivedLine& line) {
  const std::optional<Misbehaviour> m = plan.next_line(line.text);
  if (options.log) options.log(fmt::format("< {}{}", line.text, m ? fmt::format("  ({})", to_string(*m)) : ""));
  update([&](Stats& s) {
    ++s.lines;
    if (m) ++s.misbehaviours;
  });
  if (m && m->kind == MisbehaviourKind::drop) return Next::hang_up;
  if (m && m->kind == MisbehaviourKind::silent) return Next::read_on;
  if (options.echo && !write_all(line.text + "\r\n")) return Next::stop;

  std::vector<std::string> lines;
  std::string failure;
  if (m && m->kind == MisbehaviourKind::error) {
    lines.emplace_back(val2::kArmPowerOff);
  } else if (m && m->kind == MisbehaviourKind::unreachable) {
    lines.emplace_back(val2::kLocationOutOfRange);
  } else if (m && m->kind == MisbehaviourKind::unknown) {
    lines.emplace_back(val2::kInvalidFormat);
  } else if (std::optional<val2::Outcome> program =
                 line.overlong ? std::nullopt : programs.take(line.text, executor, options.on_program_step)) {
    if (program->interrupted) return Next::stop;
    lines = std::move(program->lines);
    failure = std::move(program->failure);
  } else {
    const val2::Parsed parsed =
        line.overlong ? val2::Parsed{{}, std::string(val2::kSyntaxError)} : val2::parse_monitor_line(line.text);
    if (!parsed.ok()) {
      lines.push_back(parsed.error);
    } else {
      update([](Stats& s) { ++s.commands; });
      val2::Outcome out = executor.execute(parsed.instruction);
      if (out.interrupted) return Next::stop;
      lines = std::move(out.lines);
      failure = std::move(out.failure);
    }
  }

  // The answer starts a line of its own (without echo the output stands after the last prompt).
  std::string answer = at_line_start ? "" : "\r\n";
  if (m && m->kind == MisbehaviourKind::late && !pause(m->delay)) return Next::stop;
  if (m && m->kind == MisbehaviourKind::garbage) {
    answer += garbage();
  } else {
    for (const std::string& l : lines) {
      answer += l + "\r\n";
      if (options.log) options.log(fmt::format("> {}", l));
    }
    answer += ".";
    update([&](Stats& s) {
      for (const std::string& l : lines) {
        if (!l.starts_with('*')) continue;
        ++s.errors;
        s.last_error = l;
        if (!failure.empty()) s.last_failure = failure;
      }
    });
  }
  return write_all(answer) ? Next::read_on : Next::stop;
}

Next Val2Emulator::Impl::serve_connection(int master) {
  fd = master;
  received.clear();
  used = 0;
  pending.clear();
  pending_overlong = false;
  after_cr = false;
  at_line_start = false;
  pace.reset();
  if (!write_all("\r\n.")) return Next::stop;
  char buffer[4096];
  for (;;) {
    while (const std::optional<ReceivedLine> line = take_line()) {
      if (pace.paced() && !pause_until(input_arrived)) return Next::stop;  // its end has not crossed the line yet
      const Next next = handle(*line);
      if (next != Next::read_on) return next;
    }
    pollfd p[2] = {{fd, POLLIN, 0}, {wake, POLLIN, 0}};
    if (poll(p, 2, -1) < 0 && errno != EINTR) return Next::hang_up;
    if (stopping) return Next::stop;
    if ((p[0].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n > 0) {
      received.append(buffer, static_cast<std::size_t>(n));
      input_arrived = pace.received(static_cast<std::size_t>(n), std::chrono::steady_clock::now());
      update([&](Stats& s) { s.bytes_in += static_cast<std::uint64_t>(n); });
    } else if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      continue;
    } else {
      return Next::hang_up;  // the pair keeps its slave open, so this is a broken line: publish a fresh one
    }
  }
}

Val2Emulator::Val2Emulator(EmulatedArm& arm, Val2EmulatorOptions options) {
  const SourceLocation where{"val2 emulator", 0, 0};
  if (arm.chain().dof() != 6) {
    throw InputError(where, fmt::format("the arm has {} joints; a VAL II controller drives 6", arm.chain().dof()));
  }
  if (!(options.speed >= 1 && options.speed <= 100)) {
    throw InputError(where, fmt::format("the speed {} is not a percentage in [1, 100]", options.speed));
  }
  impl_ = std::make_unique<Impl>(arm, std::move(options));
  impl_->wake = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  CW_CHECK(impl_->wake >= 0, "eventfd: {}", std::strerror(errno));
}

Val2Emulator::~Val2Emulator() {
  ::close(impl_->wake);
}

void Val2Emulator::serve(const std::filesystem::path& link) {
  CW_CHECK(!impl_->served.exchange(true), "Val2Emulator::serve() is called once");
  std::unique_ptr<PseudoTerminal> pty;
  while (!impl_->stopping) {
    // The fresh pair takes over the link before the hung-up one is closed, so the path never goes missing.
    pty = std::make_unique<PseudoTerminal>(link);
    impl_->update([](Stats& s) { ++s.connections; });
    if (impl_->serve_connection(pty->master()) != Next::hang_up) break;
    pty->hang_up();
    if (!impl_->pause(impl_->options.reconnect_delay)) break;
  }
}

void Val2Emulator::stop() {
  {
    std::lock_guard lock(impl_->stats_mutex);
    impl_->stopping = true;
  }
  impl_->stats_changed.notify_all();
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(impl_->wake, &one, sizeof one);
  impl_->arm.interrupt();
}

bool Val2Emulator::wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const {
  std::unique_lock lock(impl_->stats_mutex);
  return impl_->stats_changed.wait_for(lock, timeout, [&] {
    return impl_->stats.connections >= count || impl_->stopping;
  }) && impl_->stats.connections >= count;
}

Val2Emulator::Stats Val2Emulator::stats() const {
  std::lock_guard lock(impl_->stats_mutex);
  return impl_->stats;
}

}  // namespace cellwright::emulate
