// Val2Driver over real pseudo-terminals: a peer thread plays the VAL II monitor on the master side, byte for byte.
#include "cellwright/drivers/val2/val2_driver.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/pty.hpp"

namespace cellwright::drivers {
namespace {

using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;
using std::chrono::nanoseconds;

constexpr double kDeg = std::numbers::pi / 180.0;

const std::string kWhere =
    "     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND\r\n"
    "    431.80    -149.09     433.07     90.000    -90.000      0.000     50.000\r\n"
    "     0.000    -90.000    180.000      0.000      0.000      0.000\r\n"
    ".";

// The monitor's side of a pseudo-terminal: reads what the driver sends, line by line, echoes each line (when told)
// and writes the script's answer.
class Peer {
 public:
  struct Answer {
    std::string bytes;     // written after the echo
    bool hang_up = false;  // close the master instead of answering
  };
  // nullopt: stay silent (after the echo).
  using Script = std::function<std::optional<Answer>(const std::string& line)>;
  struct Line {
    std::string text;                    // without its terminator
    SteadyClock::time_point first_byte;  // when its first byte was read
    SteadyClock::time_point answered{};  // when the answer was written (if it was)
  };

  Peer(const std::filesystem::path& link, Script script, bool echo = true, char terminator = '\r',
       std::string echo_end = "\r\n")
      : pty_(link), script_(std::move(script)), echo_(echo), terminator_(terminator), echo_end_(std::move(echo_end)) {
    if (::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0) throw std::runtime_error("pipe2");
    thread_ = std::thread([this] { run(); });
  }
  ~Peer() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    poke();
    thread_.join();
    ::close(wake_[0]);
    ::close(wake_[1]);
  }

  std::string path() const { return pty_.path(); }

  // Bytes the monitor writes on its own (e.g. a late prompt); returns once they are written.
  void inject(std::string bytes) {
    std::unique_lock lock(mutex_);
    const std::uint64_t ticket = ++injected_;
    inject_.push_back(std::move(bytes));
    lock.unlock();
    poke();
    lock.lock();
    cv_.wait(lock, [&] { return written_injections_ >= ticket; });
  }

  // Waits until `n` lines have come and been answered (or left unanswered), at most `within`.
  bool wait_for_lines(std::size_t n, nanoseconds within) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, within, [&] { return handled_ >= n; });
  }
  std::vector<Line> lines() const {
    std::lock_guard lock(mutex_);
    return lines_;
  }
  std::string received() const {
    std::lock_guard lock(mutex_);
    return received_;
  }
  std::string written() const {
    std::lock_guard lock(mutex_);
    return written_;
  }

 private:
  void poke() {
    const char c = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);
  }

  void write_all(const std::string& bytes) {
    // Held across the write: once the driver has read a byte of it, written() includes it (recorded after the
    // unlocked write, a test reading written() as soon as the driver was done could miss the last answer).
    std::lock_guard lock(mutex_);
    std::size_t done = 0;
    while (done < bytes.size() && !pty_.hung_up()) {
      const ssize_t n = ::write(pty_.master(), bytes.data() + done, bytes.size() - done);
      if (n > 0) {
        done += static_cast<std::size_t>(n);
      } else {
        pollfd p{pty_.master(), POLLOUT, 0};
        ::poll(&p, 1, 100);
      }
    }
    written_ += bytes;
  }

  void on_line(const std::string& text) {
    Script script;
    {
      std::lock_guard lock(mutex_);
      script = script_;
    }
    const std::optional<Answer> answer = script(text);
    if (answer && answer->hang_up) {
      pty_.hang_up();
    } else {
      if (echo_) write_all(text + echo_end_);
      if (answer) write_all(answer->bytes);
    }
    std::lock_guard lock(mutex_);
    if (answer) lines_.back().answered = SteadyClock::now();
    ++handled_;
    cv_.notify_all();
  }

  void run() {
    std::string partial;
    for (;;) {
      pollfd fds[2] = {{pty_.hung_up() ? -1 : pty_.master(), POLLIN, 0}, {wake_[0], POLLIN, 0}};
      ::poll(fds, 2, -1);
      if ((fds[1].revents & POLLIN) != 0) {
        char sink[64];
        while (::read(wake_[0], sink, sizeof sink) > 0) {
        }
        std::vector<std::string> out;
        {
          std::lock_guard lock(mutex_);
          if (stop_) return;
          out.swap(inject_);
        }
        for (const std::string& bytes : out) write_all(bytes);
        std::lock_guard lock(mutex_);
        written_injections_ += out.size();
        cv_.notify_all();
      }
      if ((fds[0].revents & POLLIN) == 0) continue;
      char chunk[256];
      const ssize_t n = ::read(pty_.master(), chunk, sizeof chunk);
      if (n <= 0) continue;
      const auto now = SteadyClock::now();
      for (ssize_t i = 0; i < n; ++i) {
        const char c = chunk[i];
        {
          std::lock_guard lock(mutex_);
          received_ += c;
          if (partial.empty() && !line_open_) {
            lines_.push_back(Line{"", now, {}});
            line_open_ = true;
          }
        }
        if (c == terminator_) {
          while (!partial.empty() && partial.back() == '\r') partial.pop_back();
          {
            std::lock_guard lock(mutex_);
            lines_.back().text = partial;
            line_open_ = false;
          }
          on_line(partial);
          partial.clear();
        } else if (c != '\n' || terminator_ != '\r') {
          partial += c;
        }
      }
    }
  }

  PseudoTerminal pty_;
  Script script_;
  const bool echo_;
  const char terminator_;
  const std::string echo_end_;
  int wake_[2] = {-1, -1};
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  bool line_open_ = false;
  std::vector<Line> lines_;
  std::string received_, written_;
  std::vector<std::string> inject_;
  std::uint64_t injected_ = 0, written_injections_ = 0;
  std::size_t handled_ = 0;
  std::thread thread_;
};

// The monitor as the page describes it: every line answered with the prompt, WHERE with its three lines.
std::optional<Peer::Answer> monitor(const std::string& line) {
  if (line == "WHERE") return Peer::Answer{kWhere};
  return Peer::Answer{"."};
}

// The monitor, silent (after the echo) to the lines that start with `prefix`.
Peer::Script silent_on(std::string prefix) {
  return [prefix](const std::string& line) -> std::optional<Peer::Answer> {
    if (line.starts_with(prefix)) return std::nullopt;
    return monitor(line);
  };
}

// A directory of its own for each test's published pseudo-terminal.
class Val2DriverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           fmt::format("cw-val2-{}-{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path link() const { return dir_ / "val2"; }

  Val2Options options() const {
    Val2Options o;
    o.serial.line.port = link().string();
    o.serial.where = {"cell.yaml", 7, 3};
    o.serial.processing_time = 1ms;
    o.serial.reply_timeout = 1s;
    o.motion_margin = 1s;
    o.home_timeout = 2s;
    o.resync_quiet = 20ms;
    return o;
  }

  std::filesystem::path dir_;
};

// Sleeps on the driver's notifier until a condition holds, at most a given time.
class Waiter {
 public:
  explicit Waiter(RobotDriver& driver) : driver_(driver) {
    driver_.set_notifier([this] {
      std::lock_guard lock(mutex_);
      ++seq_;
      cv_.notify_all();
    });
  }
  ~Waiter() { driver_.set_notifier({}); }

  bool until(const std::function<bool()>& condition, nanoseconds within) {
    const auto deadline = SteadyClock::now() + within;
    for (;;) {
      std::uint64_t seen = 0;
      {
        std::lock_guard lock(mutex_);
        seen = seq_;
      }
      if (condition()) return true;
      std::unique_lock lock(mutex_);
      if (!cv_.wait_until(lock, deadline, [&] { return seq_ != seen; })) return condition();
    }
  }

  // Waits until command `id` has finished and returns its status.
  CommandStatus finished(CommandId id, nanoseconds within = 5s) {
    until([&] { return driver_.poll(id).phase >= CommandPhase::done; }, within);
    return driver_.poll(id);
  }

 private:
  RobotDriver& driver_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t seq_ = 0;
};

// Connects, homes and activates.
void bring_up(Val2Driver& d, Waiter& w) {
  ASSERT_EQ(d.connect(), ErrorCode::none) << d.connect_problem();
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted()) << h.message;
  ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done) << w.finished(h.id).message;
  ASSERT_EQ(d.activate(), ErrorCode::none);
}

CommandStatus run(Val2Driver& d, Waiter& w, const Command& c) {
  const Submitted s = d.submit(c);
  EXPECT_TRUE(s.accepted()) << s.message;
  return w.finished(s.id);
}

std::vector<double> degrees(std::initializer_list<double> values) {
  std::vector<double> out;
  for (const double v : values) out.push_back(v * kDeg);
  return out;
}

Eigen::Isometry3d location(double x, double y, double z, double o, double a, double t) {
  return val2::to_pose(val2::Location{x, y, z, o, a, t}, val2::Orientation::tool_down);
}

TEST_F(Val2DriverTest, CapabilitiesAreThePUMAs) {
  Val2Driver d(options());
  const Capabilities& c = d.capabilities();
  EXPECT_EQ(c.joints, 6U);
  EXPECT_TRUE(c.joint_control && c.cartesian_control && c.linear_motion && c.full_orientation && c.prefers_pose);
  EXPECT_TRUE(c.gripper);
  EXPECT_FALSE(c.gripper_width || c.gripper_force);
  EXPECT_EQ(c.digital_outputs, 32U);
  EXPECT_EQ(c.digital_inputs, 32U);
  EXPECT_TRUE(c.reads_joints && c.reads_pose);
  EXPECT_FALSE(c.reads_while_moving);
  EXPECT_EQ(c.queue_depth, 2U);
  EXPECT_EQ(c.max_joint_speed, options().max_joint_speed);
  EXPECT_EQ(c.max_tool_speed, options().max_tool_speed);
  // The VAL II line by default: 9600 8N1, no handshake.
  const SerialLine line = Val2Options{}.serial.line;
  EXPECT_EQ(line.baud, 9600);
  EXPECT_EQ(line.data_bits, 8);
  EXPECT_EQ(line.parity, Parity::none);
  EXPECT_EQ(line.stop_bits, 1);
  EXPECT_FALSE(line.rts_cts || line.xon_xoff);
}

TEST_F(Val2DriverTest, BadOptionsAreInputErrors) {
  Val2Options o = options();
  o.max_joint_speed = {1, 1, 1, 1, 1};
  EXPECT_THROW(Val2Driver{o}, InputError);
  o = options();
  o.joint_travel[2] = 0.0;
  EXPECT_THROW(Val2Driver{o}, InputError);
  o = options();
  o.max_tool_speed = -1;
  EXPECT_THROW(Val2Driver{o}, InputError);
  o = options();
  o.motion_margin = -1s;
  EXPECT_THROW(Val2Driver{o}, InputError);
  for (const std::string prompt : {"", ". ", "\x01"}) {
    o = options();
    o.prompt = prompt;
    EXPECT_THROW(Val2Driver{o}, InputError) << prompt;
  }
}

TEST_F(Val2DriverTest, SendsExactBytesForEveryCommand) {
  Peer peer(link(), monitor);
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  const Command commands[] = {
      MoveJoints{degrees({0, -90, 180, 0, 45.5, -0.25}), 0.5},
      MovePose{location(431.8, -149.09, 433.07, 90, 0, 0), Path::joint, 0.5},
      MovePose{location(-12.5, 600, 0.25, -30, 120, 45), Path::linear, 1.0},
      Grip{Grip::Action::open, {}, {}},
      Grip{Grip::Action::close, {}, {}},
      SetOutput{3, true},
      SetOutput{32, false},
      WaitInput{5, true, 1s},
      WaitInput{7, false, 0ns},
      MoveJoints{degrees({1, 2, 3, 4, 5, 6}), 0.004},  // 0.4 %: the slowest SPEED is 1
  };
  for (const Command& c : commands) EXPECT_EQ(run(d, w, c).phase, CommandPhase::done) << describe(c);
  const Submitted p = d.request_position();
  ASSERT_TRUE(p.accepted());
  ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done) << w.finished(p.id).message;

  EXPECT_EQ(peer.received(),
            "\r"
            "DO READY\r"
            "SPEED 50\r"
            "DO MOVE #PPOINT(0,-90,180,0,45.5,-0.25)\r"
            "DO MOVE TRANS(431.8,-149.09,433.07,90,0,0)\r"
            "SPEED 100\r"
            "DO MOVES TRANS(-12.5,600,0.25,-30,120,45)\r"
            "DO OPENI\r"
            "DO CLOSEI\r"
            "DO SIGNAL 3\r"
            "DO SIGNAL -32\r"
            "DO WAIT SIG(1005)\r"
            "DO WAIT SIG(-1007)\r"
            "SPEED 1\r"
            "DO MOVE #PPOINT(1,2,3,4,5,6)\r"
            "WHERE\r");

  // The reading: joints in radians, the tool pose in metres in the base frame.
  const std::optional<PositionReading> r = d.last_position();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->request, p.id);
  ASSERT_EQ(r->joints.size(), 6U);
  const std::vector<double> expected = degrees({0, -90, 180, 0, 0, 0});
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(r->joints[i], expected[i], 1e-12);
  ASSERT_TRUE(r->tool_pose.has_value());
  EXPECT_TRUE(r->tool_pose->translation().isApprox(Eigen::Vector3d(0.4318, -0.14909, 0.43307), 1e-12));
  const Eigen::Matrix3d page = (Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  EXPECT_TRUE(r->tool_pose->linear().isApprox(page, 1e-12));
}

TEST_F(Val2DriverTest, LineEndIsASetting) {
  for (const auto& [end, terminator, text] : {std::tuple{Val2LineEnd::crlf, '\n', std::string("\r\n")},
                                              std::tuple{Val2LineEnd::lf, '\n', std::string("\n")}}) {
    Peer peer(link(), monitor, true, terminator);
    Val2Options o = options();
    o.line_end = end;
    Val2Driver d(o);
    Waiter w(d);
    bring_up(d, w);
    EXPECT_EQ(run(d, w, SetOutput{1, true}).phase, CommandPhase::done);
    EXPECT_EQ(peer.received(), text + "DO READY" + text + "DO SIGNAL 1" + text);
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, WorksWithoutEcho) {
  // No echo, and prompts after a blank line: both are the monitor's to choose.
  Peer peer(
      link(),
      [](const std::string& line) -> std::optional<Peer::Answer> {
        if (line == "WHERE") return Peer::Answer{"\r\n" + kWhere};
        return Peer::Answer{"\r\n."};
      },
      false);
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  EXPECT_EQ(run(d, w, MovePose{location(400, 0, 300, 0, 0, 0), Path::linear, 0.25}).phase, CommandPhase::done);
  const Submitted p = d.request_position();
  ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done) << w.finished(p.id).message;
  EXPECT_EQ(peer.received(), "\rDO READY\rSPEED 25\rDO MOVES TRANS(400,0,300,0,0,0)\rWHERE\r");
  EXPECT_TRUE(peer.written().find("DO READY") == std::string::npos);  // really no echo
}

TEST_F(Val2DriverTest, WhereVariantsOverTheLine) {
  const std::vector<std::string> answers = {
      // no hand value, tight spacing, signs
      "X/JT1 Y/JT2 Z/JT3 O/JT4 A/JT5 T/JT6\r\n+431.8 -149.09 433.07 90 -90 0\r\n0 -90 +180 0 0 0\r\n.",
      // no header; a number line that begins with '.', right after the prompt-like '.'
      "431.80 -149.09 433.07 90.000 -90.000 .000 50\r\n.000 -90.000 180.000 .0 0 0\r\n.",
      // blank lines around
      "\r\n" + kWhere.substr(0, kWhere.size() - 1) + "\r\n.",
  };
  for (const std::string& answer : answers) {
    Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
      if (line == "WHERE") return Peer::Answer{answer};
      return Peer::Answer{"."};
    });
    Val2Driver d(options());
    Waiter w(d);
    ASSERT_EQ(d.connect(), ErrorCode::none);
    const Submitted h = d.home();
    ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done);
    const Submitted p = d.request_position();
    ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done) << answer << ": " << w.finished(p.id).message;
    const auto r = d.last_position();
    ASSERT_TRUE(r && r->tool_pose) << answer;
    EXPECT_NEAR(r->joints[2], std::numbers::pi, 1e-12) << answer;
    EXPECT_NEAR(r->tool_pose->translation().y(), -0.14909, 1e-12) << answer;
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, WherePromptSplitFromANumberLineThatBeginsWithAPoint) {
  // The peer writes the joints line in two pieces: "." and the rest. The driver must not take the first for the
  // prompt while the answer still misses its numbers.
  Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
    if (line != "WHERE") return Peer::Answer{"."};
    return Peer::Answer{"431.8 -149.09 433.07 90 -90 0\r\n."};
  });
  Val2Options o = options();
  o.prompt_settle = 500ms;
  Val2Driver d(o);
  Waiter w(d);
  ASSERT_EQ(d.connect(), ErrorCode::none);
  const Submitted h = d.home();
  ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done);
  const Submitted p = d.request_position();
  ASSERT_TRUE(peer.wait_for_lines(3, 2s));
  peer.inject("5 -90 180 0 0 0\r\n.");
  const CommandStatus s = w.finished(p.id);
  ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  EXPECT_NEAR(d.last_position()->joints[0], 0.5 * kDeg, 1e-12);
}

TEST_F(Val2DriverTest, UnreachableFailsTheCommandOnly) {
  Peer peer(link(), [](const std::string& line) -> std::optional<Peer::Answer> {
    if (line.starts_with("DO MOVE")) return Peer::Answer{"*Location out of range*\r\n."};
    return Peer::Answer{"."};
  });
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  const CommandStatus s = run(d, w, MovePose{location(2000, 0, 0, 0, 0, 0), Path::joint, 1.0});
  EXPECT_EQ(s.phase, CommandPhase::failed);
  EXPECT_EQ(s.error, ErrorCode::unreachable);
  EXPECT_NE(s.message.find("*Location out of range*"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("DO MOVE TRANS(2000,0,0,0,0,0)"), std::string::npos) << s.message;
  EXPECT_EQ(d.state(), DriverState::active);
  EXPECT_EQ(run(d, w, SetOutput{2, true}).phase, CommandPhase::done);
}

// Error words outside the driver's lists ("*Unknown command*", "*Invalid format*") are unknown, not hardware: the
// driver faults all the same, so the arm stops until reset and homed again.
TEST_F(Val2DriverTest, ProtocolHardwareAndUnknownErrorsFault) {
  for (const auto& [line_text, expected] : {std::pair{std::string("*Syntax error*"), ErrorCode::protocol},
                                            std::pair{std::string("*Arm power off*"), ErrorCode::hardware},
                                            std::pair{std::string("*Unknown command*"), ErrorCode::unknown},
                                            std::pair{std::string("*Invalid format*"), ErrorCode::unknown}}) {
    const std::string error_line = line_text;
    const ErrorCode code = expected;
    std::atomic<bool> failing = true;
    Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
      if (line == "DO CLOSEI" && failing) return Peer::Answer{error_line + "\r\n."};
      return Peer::Answer{"."};
    });
    Val2Driver d(options());
    Waiter w(d);
    bring_up(d, w);
    const CommandStatus s = run(d, w, Grip{Grip::Action::close, {}, {}});
    EXPECT_EQ(s.error, code) << error_line;
    EXPECT_NE(s.message.find(error_line), std::string::npos) << s.message;
    EXPECT_EQ(d.state(), DriverState::fault);
    // reset(): an empty line, the prompt, then home again.
    failing = false;
    ASSERT_EQ(d.reset(), ErrorCode::none);
    const Submitted h = d.home();
    ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done) << w.finished(h.id).message;
    EXPECT_EQ(peer.received(), "\rDO READY\rDO CLOSEI\r\rDO READY\r");
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, GarbageIsAProtocolFaultNamingTheBytes) {
  // The bytes, and how the message quotes them.
  const std::vector<std::pair<std::string, std::string>> garbage = {
      {"\x07OK?\r\n.", "'\\x07OK?'"}, {"HELLO\r\n.", "'HELLO'"}, {"\x01\x02", "'\\x01\\x02'"}};
  for (const auto& [answer, quoted] : garbage) {
    const std::string bytes = answer;
    Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
      if (line == "DO SIGNAL 4") return Peer::Answer{bytes};
      return Peer::Answer{"."};
    });
    Val2Options o = options();
    o.serial.reply_timeout = 5s;
    Val2Driver d(o);
    Waiter w(d);
    bring_up(d, w);
    const auto start = SteadyClock::now();
    const CommandStatus s = run(d, w, SetOutput{4, true});
    EXPECT_LT(SteadyClock::now() - start, 5s) << "garbage is seen at once, not at the deadline";
    EXPECT_EQ(s.error, ErrorCode::protocol);
    EXPECT_NE(s.message.find(quoted), std::string::npos) << s.message;
    EXPECT_EQ(d.state(), DriverState::fault);
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, BytesTheMonitorSendsUnaskedFailTheNextCommandUnsent) {
  Peer peer(link(), monitor);
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  peer.inject("junk\r\n");
  const CommandStatus s = run(d, w, SetOutput{1, true});
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_NE(s.message.find("junk\\r\\n"), std::string::npos) << s.message;
  EXPECT_EQ(peer.received(), "\rDO READY\r");  // not sent
}

TEST_F(Val2DriverTest, SilencePastTheMotionsDeadlineFaults) {
  Peer peer(link(), silent_on("DO MOVE"));
  Val2Options o = options();
  o.motion_margin = 300ms;
  Val2Driver d(o);
  Waiter w(d);
  bring_up(d, w);
  const Submitted p = d.request_position();  // the start: (0, -90, 180, 0, 0, 0)
  ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done);
  // Joint 1 turns 10°: 0.0873 s at 2 rad/s and SPEED 50, 0.1745 s; the deadline is 0.4745 s after the send.
  const auto start = SteadyClock::now();
  const CommandStatus s = run(d, w, MoveJoints{degrees({10, -90, 180, 0, 0, 0}), 0.5});
  const auto elapsed = SteadyClock::now() - start;
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_NE(s.message.find("no prompt within 0.475 s"), std::string::npos) << s.message;
  EXPECT_GE(elapsed, 474ms);
  EXPECT_LT(elapsed, 474ms + 1s);
  EXPECT_EQ(d.state(), DriverState::fault);
  // Sent once, nothing after it.
  EXPECT_EQ(peer.received(), "\rDO READY\rWHERE\rSPEED 50\rDO MOVE #PPOINT(10,-90,180,0,0,0)\r");
}

TEST_F(Val2DriverTest, SilenceToALineWithoutMotionFaultsAtTheReplyTimeout) {
  Peer peer(link(), silent_on("DO OPENI"));
  Val2Options o = options();
  o.serial.reply_timeout = 300ms;
  Val2Driver d(o);
  Waiter w(d);
  bring_up(d, w);
  const auto start = SteadyClock::now();
  const CommandStatus s = run(d, w, Grip{Grip::Action::open, {}, {}});
  const auto elapsed = SteadyClock::now() - start;
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_NE(s.message.find("received 'DO OPENI\\r\\n'"), std::string::npos) << s.message;  // the echo came
  EXPECT_GE(elapsed, 300ms);
  EXPECT_LT(elapsed, 300ms + 1s);
}

TEST_F(Val2DriverTest, WaitInputTimeoutFailsTheCommandAndTheOwedPromptIsAwaited) {
  Peer peer(link(), silent_on("DO WAIT"));
  Val2Options o = options();
  o.serial.reply_timeout = 300ms;
  Val2Driver d(o);
  Waiter w(d);
  bring_up(d, w);
  const auto start = SteadyClock::now();
  CommandStatus s = run(d, w, WaitInput{9, true, 200ms});
  EXPECT_GE(SteadyClock::now() - start, 200ms);
  EXPECT_EQ(s.error, ErrorCode::timeout);
  EXPECT_NE(s.message.find("input 9 did not turn on within 0.200 s"), std::string::npos) << s.message;
  EXPECT_EQ(d.state(), DriverState::active);

  // The input never comes: the next command is not sent, and fails with timeout too.
  s = run(d, w, SetOutput{1, true});
  EXPECT_EQ(s.error, ErrorCode::timeout);
  EXPECT_NE(s.message.find("not sent"), std::string::npos) << s.message;
  EXPECT_EQ(peer.received(), "\rDO READY\rDO WAIT SIG(1009)\r");

  // Now it comes: the monitor prints its prompt, and the next command goes out once.
  peer.inject(".");
  EXPECT_EQ(run(d, w, SetOutput{1, true}).phase, CommandPhase::done);
  EXPECT_EQ(peer.received(), "\rDO READY\rDO WAIT SIG(1009)\rDO SIGNAL 1\r");
}

TEST_F(Val2DriverTest, DisconnectInterruptsAWaitWithoutTimeout) {
  Peer peer(link(), silent_on("DO WAIT"));
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  const Submitted s = d.submit(WaitInput{1, false, 0ns});
  ASSERT_TRUE(s.accepted());
  ASSERT_TRUE(peer.wait_for_lines(3, 2s));
  const auto start = SteadyClock::now();
  d.disconnect();
  EXPECT_LT(SteadyClock::now() - start, 1s);
  EXPECT_EQ(d.poll(s.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

TEST_F(Val2DriverTest, QueueDepthIsTwo) {
  Peer peer(link(), silent_on("DO SIGNAL 1"));  // answered later, by the test
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  const Submitted a = d.submit(SetOutput{1, true});
  const Submitted b = d.submit(SetOutput{2, true});
  const Submitted c = d.submit(SetOutput{3, true});
  ASSERT_TRUE(a.accepted() && b.accepted());
  EXPECT_EQ(c.error, ErrorCode::busy);
  ASSERT_TRUE(peer.wait_for_lines(3, 2s));
  peer.inject(".");
  EXPECT_EQ(w.finished(a.id).phase, CommandPhase::done);
  EXPECT_EQ(w.finished(b.id).phase, CommandPhase::done);
  EXPECT_EQ(peer.received(), "\rDO READY\rDO SIGNAL 1\rDO SIGNAL 2\r");
  // What the robot cannot do is refused before anything is sent.
  EXPECT_EQ(d.submit(Grip{Grip::Action::close, 0.01, {}}).error, ErrorCode::unsupported);
  EXPECT_EQ(d.submit(SetOutput{33, true}).error, ErrorCode::invalid_command);
  EXPECT_EQ(d.submit(WaitInput{0, true, 0ns}).error, ErrorCode::invalid_command);
}

TEST_F(Val2DriverTest, HangUpIsConnectionLostAndANewPortReconnects) {
  std::optional<Peer> peer;
  peer.emplace(link(), [](const std::string& line) -> std::optional<Peer::Answer> {
    if (line.starts_with("DO MOVE")) return Peer::Answer{"", true};
    return monitor(line);
  });
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  const Submitted a = d.submit(MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 1.0});
  const Submitted b = d.submit(SetOutput{1, true});
  ASSERT_TRUE(a.accepted() && b.accepted());
  const CommandStatus s = w.finished(a.id);
  EXPECT_EQ(s.error, ErrorCode::connection_lost) << s.message;
  EXPECT_EQ(w.finished(b.id).error, ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::disconnected);

  // The monitor comes back on a new pseudo-terminal published at the same path.
  peer.reset();
  peer.emplace(link(), monitor);
  bring_up(d, w);
  EXPECT_EQ(run(d, w, MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 1.0}).phase, CommandPhase::done);
  // SPEED again: the new connection knows nothing of the old one's.
  EXPECT_EQ(peer->received(), "\rDO READY\rSPEED 100\rDO MOVE #PPOINT(0,0,0,0,0,0)\r");
}

TEST_F(Val2DriverTest, AMissingPortIsAnInputErrorNamingIt) {
  Val2Options o = options();
  o.serial.line.port = (dir_ / "no-such-port").string();
  Val2Driver d(o);
  try {
    d.connect();
    FAIL() << "connect() to a missing port returned";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(o.serial.line.port), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cell.yaml:7:3"), std::string::npos) << e.what();
  }
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

TEST_F(Val2DriverTest, ASilentMonitorFailsConnect) {
  Peer peer(link(), [](const std::string&) -> std::optional<Peer::Answer> { return std::nullopt; });
  Val2Options o = options();
  o.serial.reply_timeout = 200ms;
  Val2Driver d(o);
  EXPECT_EQ(d.connect(), ErrorCode::connection_lost);
  EXPECT_NE(d.connect_problem().find("no prompt"), std::string::npos) << d.connect_problem();
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

TEST_F(Val2DriverTest, ResetSkipsTheEndOfWhatTheMonitorWasDoing) {
  // A late answer to the command that faulted arrives after reset()'s empty line; the driver keeps the last prompt.
  std::atomic<int> moves = 0;
  Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
    if (line.starts_with("DO MOVE") && moves++ == 0) return Peer::Answer{"\x7f"};  // garbage, and no prompt yet
    if (line.empty() && moves > 0) return Peer::Answer{".\r\n."};                  // the move's prompt, then ours
    return monitor(line);
  });
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  EXPECT_EQ(run(d, w, MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 1.0}).error, ErrorCode::protocol);
  ASSERT_EQ(d.reset(), ErrorCode::none);
  const Submitted h = d.home();
  ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done) << w.finished(h.id).message;
  ASSERT_EQ(d.activate(), ErrorCode::none);
  EXPECT_EQ(run(d, w, MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 1.0}).phase, CommandPhase::done);
}

TEST_F(Val2DriverTest, PacingKeepsSendsApartByWireAndProcessingTime) {
  Peer peer(link(), monitor);
  Val2Options o = options();
  o.serial.processing_time = 40ms;
  o.serial.line.baud = 1200;  // 8.33 ms a character at 8N1: the wire time counts
  Val2Driver d(o);
  Waiter w(d);
  const auto before = SteadyClock::now();
  bring_up(d, w);
  EXPECT_EQ(run(d, w, MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 0.5}).phase, CommandPhase::done);
  const std::vector<Peer::Line> lines = peer.lines();
  ASSERT_EQ(lines.size(), 4U);  // "", DO READY, SPEED 50, DO MOVE
  // Line k+1 left the driver no sooner than line k's wire time plus the processing time after line k was written,
  // and line k was written after the answer to line k-1 (or, for the first, after `before`).
  for (std::size_t k = 0; k + 1 < lines.size(); ++k) {
    const auto earlier = k == 0 ? before : lines[k - 1].answered;
    const nanoseconds bound = o.serial.line.wire_time(lines[k].text.size() + 1) + o.serial.processing_time;
    EXPECT_GE(lines[k + 1].first_byte - earlier, bound) << "line " << k + 1 << " '" << lines[k + 1].text << "'";
  }
}

TEST_F(Val2DriverTest, TimingCountsEveryJob) {
  Peer peer(link(), monitor);
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  EXPECT_EQ(run(d, w, MoveJoints{degrees({0, 0, 0, 0, 0, 0}), 1.0}).phase, CommandPhase::done);
  const Submitted p = d.request_position();
  ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done);
  // A job is recorded after it is reported done; disconnect() joins the thread, so every record is in.
  d.disconnect();
  const SerialTiming t = d.timing();
  // home, the move (with its SPEED), the position; the greeting is not a job.
  EXPECT_EQ(t.jobs, 3U);
  const std::string sent = peer.received().substr(1);  // less the greeting's CR
  const std::string got = peer.written().substr(3);    // less its echo "\r\n" and prompt
  EXPECT_EQ(t.bytes_sent, sent.size());
  EXPECT_EQ(t.bytes_received, got.size());
  EXPECT_NEAR(std::chrono::duration<double>(t.wire_sent).count(),
              std::chrono::duration<double>(options().serial.line.wire_time(sent.size())).count(), 1e-6);
  ASSERT_EQ(t.recent.size(), 3U);
  EXPECT_EQ(t.recent[0].what, "home");
  EXPECT_EQ(t.recent[0].bytes_sent, std::string("DO READY\r").size());
  EXPECT_EQ(t.recent[1].bytes_sent, std::string("SPEED 100\rDO MOVE #PPOINT(0,0,0,0,0,0)\r").size());
  EXPECT_EQ(t.recent[2].what, "position");
  EXPECT_EQ(t.recent[2].bytes_received, std::string("WHERE\r\n").size() + kWhere.size());
}

// ---- Monitor variants (issue 25): each connects, reads WHERE, moves, and reports errors with their class ----------

// `text` with every CR LF replaced by `end`.
std::string with_line_end(const std::string& text, const std::string& end) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text.compare(i, 2, "\r\n") == 0) {
      out += end;
      ++i;
    } else {
      out += text[i];
    }
  }
  return out;
}

struct MonitorVariant {
  std::string name;
  std::string where;     // the answer to WHERE, its prompt included
  std::string prompt;    // what answers every other line
  std::string echo_end;  // the echo's line end
  bool joints = true;    // the WHERE answer has the joint angles
  std::function<void(Val2Options&)> settings = [](Val2Options&) {};
};

std::vector<MonitorVariant> monitor_variants() {
  const std::string kas =
      "     JT1       JT2       JT3       JT4       JT5       JT6  \r\n"
      "     0.000   -90.000   180.000     0.000     0.000     0.000\r\n"
      "    X[mm]     Y[mm]     Z[mm]     O[deg]    A[deg]    T[deg]\r\n"
      "   431.800  -149.090   433.070    90.000   -90.000     0.000\r\n";
  return {
      {"CR-only line ends", with_line_end(kWhere, "\r"), ".", "\r"},
      {"LF-only line ends", with_line_end(kWhere, "\n"), ".", "\n"},
      {"CR LF line ends and a prompt with a trailing space", kWhere + " ", ". ", "\r\n"},
      {"a WHERE without the joint row",
       "     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND\r\n"
       "    431.80    -149.09     433.07     90.000    -90.000      0.000     50.000\r\n.",
       ".", "\r\n", false},
      {"Kawasaki AS: two-block WHERE, prompt '>'", kas + ">", ">", "\r\n", true,
       [](Val2Options& o) {
         o.prompt = ">";
         o.where_layout = val2::WhereLayout::as_two_block;
       }},
  };
}

TEST_F(Val2DriverTest, EveryMonitorVariantConnectsReadsWhereAndMoves) {
  for (const MonitorVariant& v : monitor_variants()) {
    SCOPED_TRACE(v.name);
    Peer peer(
        link(),
        [&](const std::string& line) -> std::optional<Peer::Answer> {
          if (line == "WHERE") return Peer::Answer{v.where};
          if (line == "DO CLOSEI")
            return Peer::Answer{with_line_end("*Location out of range*\r\n", v.echo_end) + v.prompt};
          return Peer::Answer{v.prompt};
        },
        true, '\r', v.echo_end);
    Val2Options o = options();
    v.settings(o);
    Val2Driver d(o);
    Waiter w(d);
    bring_up(d, w);
    const Submitted p = d.request_position();
    ASSERT_EQ(w.finished(p.id).phase, CommandPhase::done) << w.finished(p.id).message;
    const auto r = d.last_position();
    ASSERT_TRUE(r && r->tool_pose);
    EXPECT_TRUE(r->tool_pose->translation().isApprox(Eigen::Vector3d(0.4318, -0.14909, 0.43307), 1e-12));
    EXPECT_LT(Eigen::AngleAxisd(r->tool_pose->linear().transpose() * location(0, 0, 0, 90, -90, 0).linear()).angle(),
              1e-9);
    if (v.joints) {
      ASSERT_EQ(r->joints.size(), 6U);
      EXPECT_NEAR(r->joints[1], -std::numbers::pi / 2, 1e-12);
      EXPECT_NEAR(r->joints[2], std::numbers::pi, 1e-12);
    } else {
      EXPECT_TRUE(r->joints.empty());
    }
    EXPECT_EQ(run(d, w, MovePose{location(400, 0, 300, 0, 0, 0), Path::joint, 0.5}).phase, CommandPhase::done);
    EXPECT_EQ(run(d, w, MoveJoints{degrees({0, -90, 180, 0, 0, 0}), 0.5}).phase, CommandPhase::done);
    // An error line in the variant's line ends keeps its class: unreachable fails the command only.
    const CommandStatus s = run(d, w, Grip{Grip::Action::close, {}, {}});
    EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
    EXPECT_EQ(d.state(), DriverState::active);
    EXPECT_EQ(peer.received(),
              "\rDO READY\rWHERE\rSPEED 50\rDO MOVE TRANS(400,0,300,0,0,0)\r"
              "DO MOVE #PPOINT(0,-90,180,0,0,0)\rDO CLOSEI\r");
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, ABellBeforeAnErrorLineKeepsTheLinesClass) {
  for (const auto& [error_line, code] : {std::pair{std::string("\a*Location out of range*"), ErrorCode::unreachable},
                                         std::pair{std::string("\a\a*Servo error*"), ErrorCode::hardware}}) {
    SCOPED_TRACE(error_line.substr(error_line.find('*')));
    const std::string answer = error_line + "\r\n.";
    Peer peer(link(), [&](const std::string& line) -> std::optional<Peer::Answer> {
      if (line == "DO CLOSEI") return Peer::Answer{answer};
      return Peer::Answer{"."};
    });
    Val2Driver d(options());
    Waiter w(d);
    bring_up(d, w);
    const CommandStatus s = run(d, w, Grip{Grip::Action::close, {}, {}});
    EXPECT_EQ(s.error, code) << s.message;
    EXPECT_NE(s.message.find(error_line.substr(error_line.find('*'))), std::string::npos) << s.message;
    d.disconnect();
  }
}

TEST_F(Val2DriverTest, UnknownErrorLinesSentUnaskedFaultAsUnknown) {
  Peer peer(link(), monitor);
  Val2Driver d(options());
  Waiter w(d);
  bring_up(d, w);
  peer.inject("\a*Invalid format*\r\n.");
  const CommandStatus s = run(d, w, SetOutput{1, true});
  EXPECT_EQ(s.error, ErrorCode::unknown) << s.message;
  EXPECT_NE(s.message.find("not sent"), std::string::npos) << s.message;
}

TEST_F(Val2DriverTest, EchoIsASetting) {
  {
    // always: an answer without the copy of the line is garbage.
    Peer peer(link(), monitor, false);
    Val2Options o = options();
    o.echo = Val2Echo::always;
    Val2Driver d(o);
    Waiter w(d);
    ASSERT_EQ(d.connect(), ErrorCode::none) << d.connect_problem();
    const Submitted h = d.home();
    ASSERT_EQ(w.finished(h.id).phase, CommandPhase::done);  // an answer of the prompt alone has nothing to check
    const Submitted p = d.request_position();
    const CommandStatus s = w.finished(p.id);
    EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
    d.disconnect();
  }
  {
    // never: a copy of the line is garbage.
    Peer peer(link(), monitor, true);
    Val2Options o = options();
    o.echo = Val2Echo::never;
    Val2Driver d(o);
    Waiter w(d);
    ASSERT_EQ(d.connect(), ErrorCode::none) << d.connect_problem();
    const Submitted h = d.home();
    const CommandStatus s = w.finished(h.id);
    EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
    EXPECT_NE(s.message.find("'DO READY'"), std::string::npos) << s.message;
    d.disconnect();
  }
}

}  // namespace
}  // namespace cellwright::drivers
