// MovemasterDriver over real pseudo-terminals: a peer thread holds the master side, reads what the driver sends byte
// for byte and answers as each test scripts it. Checked against docs/real-robots.md: the exact bytes of each call,
// WH answers in their lenient forms, ER 1 / ER 2 and RS, reset(), garbage, unasked-for bytes, silence, hang-up and a
// reconnect on a new pseudo-terminal, a missing port, pacing, timing, completion by polling, and the options.
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/common/pty.hpp"

namespace cellwright::drivers {
namespace {

namespace mm = movemaster;
using namespace std::chrono_literals;
using Steady = std::chrono::steady_clock;

// ---- The controller's side ----------------------------------------------------------------------------------------

// The master side of a pseudo-terminal and a thread that reads it: every line the driver sends (ended by CR, LF or
// both) is recorded with the time it arrived, and answered as `answer` says, on the peer's thread, in order.
class Peer {
 public:
  struct Reply {
    std::string bytes;     // written back at once
    bool hang_up = false;  // then the master is closed, as when a cable is pulled
    // When set, the bytes are written one at a time this far apart, as a slow line delivers them.
    std::chrono::microseconds byte_gap{0};
  };
  using Answer = std::function<Reply(const std::string& line)>;
  struct Line {
    std::string text;
    Steady::time_point arrived;   // when the read that completed it returned
    Steady::time_point answered;  // just before the answer was written
  };

  explicit Peer(Answer answer, std::filesystem::path link = {}) : pty_(std::move(link)), answer_(std::move(answer)) {
    thread_ = std::thread([this] { run(); });
  }
  ~Peer() {
    quit_ = true;
    thread_.join();
  }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;

  std::string path() const { return pty_.path(); }

  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return received_.size();
  }
  // The bytes received from offset `from` on, once at least `count` of them have arrived (or `within` has passed).
  std::string await(std::size_t from, std::size_t count, std::chrono::milliseconds within = 3s) const {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, within, [&] { return received_.size() >= from + count; });
    return received_.size() > from ? received_.substr(from) : std::string();
  }
  std::vector<Line> lines() const {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 private:
  void run() {
    std::string pending;
    while (!quit_) {
      pollfd p{pty_.master(), POLLIN, 0};
      if (::poll(&p, 1, 10) <= 0) continue;  // a hung-up master (-1) is ignored by poll: the loop just checks quit_
      char chunk[256];
      const ssize_t n = ::read(pty_.master(), chunk, sizeof chunk);
      if (n <= 0) continue;
      const auto arrived = Steady::now();
      {
        std::lock_guard lock(mutex_);
        received_.append(chunk, static_cast<std::size_t>(n));
      }
      cv_.notify_all();
      pending.append(chunk, static_cast<std::size_t>(n));
      for (std::size_t end = pending.find_first_of("\r\n"); end != std::string::npos && !pty_.hung_up();
           end = pending.find_first_of("\r\n")) {
        const std::string text = pending.substr(0, end);
        pending.erase(0, end + 1);
        if (text.empty()) continue;  // the LF of a CR LF
        const Reply reply = answer_(text);
        {
          std::lock_guard lock(mutex_);
          lines_.push_back({text, arrived, Steady::now()});
        }
        if (reply.byte_gap.count() == 0) {
          write_all(reply.bytes);
        } else {
          for (const char c : reply.bytes) {
            std::this_thread::sleep_for(reply.byte_gap);  // the line's pace, not a race: see Reply::byte_gap
            write_all(std::string(1, c));
          }
        }
        if (reply.hang_up) pty_.hang_up();
      }
    }
  }

  void write_all(const std::string& bytes) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::write(pty_.master(), bytes.data() + sent, bytes.size() - sent);
      if (n > 0) {
        sent += static_cast<std::size_t>(n);
      } else {
        pollfd p{pty_.master(), POLLOUT, 0};
        ::poll(&p, 1, 100);
      }
    }
  }

  PseudoTerminal pty_;
  Answer answer_;
  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  std::string received_;
  std::vector<Line> lines_;
  std::atomic<bool> quit_{false};
  std::thread thread_;  // last: starts when the rest exists
};

// A controller that does as it is told: ER answers 0, WH answers `where`, every other line nothing.
Peer::Answer obedient(std::string where = "300.0,0.0,200.0,-90.0,0.0\r\n") {
  return [where](const std::string& line) -> Peer::Reply {
    if (line == "ER") return {"0\r\n"};
    if (line == "WH") return {where};
    return {};
  };
}

// `base`, except that the nth (from 1) line equal to `command` gets `reply`.
Peer::Answer except_nth(const std::string& command, int nth, Peer::Reply reply, Peer::Answer base) {
  return [command, nth, reply, base, seen = 0](const std::string& line) mutable -> Peer::Reply {
    if (line == command && ++seen == nth) return reply;
    return base(line);
  };
}

// ---- The driver's side --------------------------------------------------------------------------------------------

// The driver's notifier, to wait for a condition with a deadline instead of sleeping.
class Events {
 public:
  std::function<void()> notifier() {
    return [this] {
      {
        std::lock_guard lock(mutex_);
        ++count_;
      }
      cv_.notify_all();
    };
  }
  // Waits until `holds()` is true, checking again after each notification; returns it at the deadline.
  bool wait(const std::function<bool()>& holds, std::chrono::milliseconds within = 5s) {
    const auto deadline = Steady::now() + within;
    std::unique_lock lock(mutex_);
    for (;;) {
      const std::uint64_t seen = count_;
      lock.unlock();
      if (holds()) return true;
      lock.lock();
      if (!cv_.wait_until(lock, deadline, [&] { return count_ != seen; })) {
        lock.unlock();
        return holds();
      }
    }
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t count_ = 0;
};

// Short deadlines and a fast line, so that the suite stays quick; the tests of pacing and timing use 9600 baud.
MovemasterOptions fast_options() {
  MovemasterOptions o;
  o.serial.where = {"cell.yaml", 12, 5};
  o.serial.line.baud = 115200;
  o.serial.processing_time = 1ms;
  o.serial.reply_timeout = 300ms;
  o.longest_motion = 100ms;
  o.home_time = 100ms;
  o.grip_time = 50ms;
  o.poll_period = 20ms;
  return o;
}

MovemasterOptions on_port(MovemasterOptions o, const std::string& port) {
  o.serial.line.port = port;
  return o;
}

// A peer and a driver on its pseudo-terminal (destroyed in that order reversed: the driver disconnects first).
struct Rig {
  explicit Rig(Peer::Answer answer, const MovemasterOptions& options = fast_options())
      : peer(std::move(answer)), driver(on_port(options, peer.path())) {
    driver.set_notifier(events.notifier());
  }

  // Waits until command `id` has finished and returns its status.
  CommandStatus finish(CommandId id, std::chrono::milliseconds within = 5s) {
    events.wait(
        [&] {
          const CommandPhase p = driver.poll(id).phase;
          return p == CommandPhase::done || p == CommandPhase::failed;
        },
        within);
    return driver.poll(id);
  }
  CommandStatus run(const Command& command) {
    const Submitted s = driver.submit(command);
    EXPECT_TRUE(s.accepted()) << s.message;
    return finish(s.id);
  }
  // connect, home, activate.
  void bring_up() {
    ASSERT_EQ(driver.connect(), ErrorCode::none) << driver.connect_problem();
    const Submitted h = driver.home();
    ASSERT_TRUE(h.accepted()) << h.message;
    ASSERT_EQ(finish(h.id).phase, CommandPhase::done) << driver.poll(h.id).message;
    ASSERT_EQ(driver.activate(), ErrorCode::none);
  }
  // The bytes sent since offset `from`, once `expected.size()` of them have arrived.
  std::string sent_since(std::size_t from, const std::string& expected) const {
    return peer.await(from, expected.size());
  }

  Peer peer;
  Events events;
  MovemasterDriver driver;
};

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

MovePose move_to(const mm::Xyzpr& v, Path path = Path::joint, double speed = 1.0) {
  return MovePose{mm::to_pose(v), path, speed};
}

// ---- Connect ------------------------------------------------------------------------------------------------------

TEST(MovemasterDriverConnect, SendsErThenTheToolLength) {
  MovemasterOptions o = fast_options();
  o.tool_length_mm = 107.5;
  Rig r(obedient(), o);
  ASSERT_EQ(r.driver.connect(), ErrorCode::none) << r.driver.connect_problem();
  EXPECT_EQ(r.driver.state(), DriverState::connected);
  const std::string expected = "ER\r\nTL 107.5\r\nER\r\n";
  EXPECT_EQ(r.sent_since(0, expected), expected);
}

TEST(MovemasterDriverConnect, LineEndIsASetting) {
  for (const auto& [end, expected] : {std::pair{mm::LineEnd::lf, std::string("ER\nNT\nER\n")},
                                      std::pair{mm::LineEnd::cr, std::string("ER\rNT\rER\r")},
                                      std::pair{mm::LineEnd::crlf, std::string("ER\r\nNT\r\nER\r\n")}}) {
    MovemasterOptions o = fast_options();
    o.line_end = end;
    Rig r(obedient(), o);
    r.bring_up();
    EXPECT_EQ(r.sent_since(0, expected), expected);
  }
}

TEST(MovemasterDriverConnect, AnswerOtherThanZeroFailsConnectNamingTheBytes) {
  Rig r([](const std::string&) { return Peer::Reply{"OK?\r\n"}; });
  EXPECT_EQ(r.driver.connect(), ErrorCode::connection_lost);
  EXPECT_EQ(r.driver.state(), DriverState::disconnected);
  EXPECT_TRUE(contains(r.driver.connect_problem(), "protocol")) << r.driver.connect_problem();
  EXPECT_TRUE(contains(r.driver.connect_problem(), "'OK?\\r\\n'")) << r.driver.connect_problem();
}

TEST(MovemasterDriverConnect, ErrorAtConnectIsResetWithRsAndTheNextConnectWorks) {
  Rig r(except_nth("ER", 1, {"1\r\n"}, obedient()));
  EXPECT_EQ(r.driver.connect(), ErrorCode::connection_lost);
  EXPECT_TRUE(contains(r.driver.connect_problem(), "ER answered 1")) << r.driver.connect_problem();
  EXPECT_EQ(r.sent_since(0, "ER\r\nRS\r\n"), "ER\r\nRS\r\n");
  EXPECT_EQ(r.driver.connect(), ErrorCode::none) << r.driver.connect_problem();
}

TEST(MovemasterDriverConnect, SilentControllerFailsConnect) {
  Rig r([](const std::string&) { return Peer::Reply{}; });
  const auto start = Steady::now();
  EXPECT_EQ(r.driver.connect(), ErrorCode::connection_lost);
  EXPECT_GE(Steady::now() - start, fast_options().serial.reply_timeout);
  EXPECT_TRUE(contains(r.driver.connect_problem(), "silent")) << r.driver.connect_problem();
}

TEST(MovemasterDriverConnect, MissingPortIsAnInputErrorNamingIt) {
  MovemasterDriver d(on_port(fast_options(), "/nonexistent-cellwright/ttyMM0"));
  try {
    d.connect();
    FAIL() << "connect() to a missing port did not throw";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "/nonexistent-cellwright/ttyMM0")) << e.what();
    EXPECT_EQ(e.where().file, "cell.yaml");
    EXPECT_EQ(e.where().line, 12);
  }
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

// ---- Options and capabilities -------------------------------------------------------------------------------------

TEST(MovemasterDriverOptions, OutOfRangeSettingsAreInputErrorsNamingTheValue) {
  const std::vector<std::pair<std::function<void(MovemasterOptions&)>, std::string>> cases = {
      {[](MovemasterOptions& o) { o.linear_slot = 0; }, "linear_slot 0"},
      {[](MovemasterOptions& o) { o.linear_slot = 630; }, "linear_slot 630"},
      {[](MovemasterOptions& o) { o.ms_open_letter = 'X'; }, "ms_open_letter 'X'"},
      {[](MovemasterOptions& o) { o.grip_start_time = 100; }, "grip_start_time 100"},
      {[](MovemasterOptions& o) { o.yaw_tolerance_deg = -1.0; }, "yaw_tolerance_deg -1"},
      {[](MovemasterOptions& o) { o.tool_length_mm = -5.0; }, "tool_length_mm -5"},
      {[](MovemasterOptions& o) { o.gripper_max_force = 0.0; }, "gripper_max_force 0"},
      {[](MovemasterOptions& o) {
         o.max_joint_speed = {1.0, 2.0};
       },
       "max_joint_speed has 2 values for 5 joints"},
  };
  for (const auto& [change, expected] : cases) {
    MovemasterOptions o = on_port(fast_options(), "/dev/null");
    change(o);
    try {
      MovemasterDriver d(o);
      ADD_FAILURE() << "accepted: " << expected;
    } catch (const InputError& e) {
      EXPECT_TRUE(contains(e.what(), expected)) << e.what();
      EXPECT_EQ(e.where().file, "cell.yaml");
    }
  }
}

TEST(MovemasterDriverCapabilities, AreThoseOfAFiveAxisPoseController) {
  MovemasterOptions o = on_port(fast_options(), "/dev/null");
  o.gripper_max_force = 25.0;
  o.max_tool_speed = 0.4;
  const MovemasterDriver d(o);
  const Capabilities& c = d.capabilities();
  EXPECT_EQ(c.joints, 5u);
  EXPECT_FALSE(c.joint_control);
  EXPECT_TRUE(c.cartesian_control);
  EXPECT_TRUE(c.linear_motion);
  EXPECT_FALSE(c.full_orientation);
  EXPECT_TRUE(c.gripper);
  EXPECT_FALSE(c.gripper_width);
  EXPECT_TRUE(c.gripper_force);
  EXPECT_EQ(c.gripper_max_force, 25.0);
  EXPECT_EQ(c.max_tool_speed, 0.4);
  EXPECT_EQ(c.digital_outputs, 0u);
  EXPECT_EQ(c.digital_inputs, 0u);
  EXPECT_EQ(c.queue_depth, 2u);
  EXPECT_FALSE(c.reads_joints);
  EXPECT_TRUE(c.reads_pose);
  EXPECT_FALSE(c.reads_while_moving);
  EXPECT_TRUE(c.prefers_pose);
}

// ---- Commands -----------------------------------------------------------------------------------------------------

TEST(MovemasterDriverCommands, HomeSendsNtThenEr) {
  Rig r(obedient());
  ASSERT_EQ(r.driver.connect(), ErrorCode::none);
  const std::size_t from = r.peer.size();
  const Submitted h = r.driver.home();
  ASSERT_TRUE(h.accepted());
  EXPECT_EQ(r.finish(h.id).phase, CommandPhase::done);
  EXPECT_EQ(r.driver.state(), DriverState::homed);
  EXPECT_EQ(r.sent_since(from, "NT\r\nER\r\n"), "NT\r\nER\r\n");
}

TEST(MovemasterDriverCommands, JointMoveSendsSpeedOnlyWhenItChangesThenMpThenEr) {
  Rig r(obedient());
  r.bring_up();
  const std::size_t from = r.peer.size();
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0}, Path::joint, 0.5)).phase, CommandPhase::done);
  EXPECT_EQ(r.run(move_to({0.0, 250.0, 300.0, 0.0, 30.0}, Path::joint, 0.5)).phase, CommandPhase::done);
  EXPECT_EQ(r.run(move_to({-120.5, 200.25, 150.0, -45.0, -170.0}, Path::joint, 1.0)).phase, CommandPhase::done);
  const std::string expected =
      "SP 5\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nER\r\n"
      "MP 0.0,250.0,300.0,0.0,30.0\r\nER\r\n"
      "SP 9\r\nMP -120.5,200.3,150.0,-45.0,-170.0\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverCommands, LinearMoveDefinesTheSlotThenMovesStraightWithTheGripLetter) {
  Rig r(obedient("300.0,0.0,200.0,-90.0,0.0\r\n"));
  r.bring_up();
  const std::size_t from = r.peer.size();
  // After homing the driver does not know where the arm is: WH first, to count the points (50 mm: 5).
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 250.0, -90.0, 0.0}, Path::linear)).phase, CommandPhase::done);
  EXPECT_EQ(r.run(Grip{Grip::Action::close, {}, {}}).phase, CommandPhase::done);
  // From the target it reached: 100 mm, 10 points; the tool is closed now.
  EXPECT_EQ(r.run(move_to({300.0, 100.0, 250.0, -90.0, 0.0}, Path::linear)).phase, CommandPhase::done);
  const std::string expected =
      "SP 9\r\nWH\r\nPD 629,300.0,0.0,250.0,-90.0,0.0\r\nMS 629,5,O\r\nER\r\n"
      "GC\r\nER\r\n"
      "PD 629,300.0,100.0,250.0,-90.0,0.0\r\nMS 629,10,C\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverCommands, SlotAndOpenLetterAreSettings) {
  MovemasterOptions o = fast_options();
  o.linear_slot = 12;
  o.ms_open_letter = 'C';
  Rig r(obedient(), o);
  r.bring_up();
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0})).phase, CommandPhase::done);
  const std::size_t from = r.peer.size();
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 100.0, -90.0, 0.0}, Path::linear)).phase, CommandPhase::done);
  const std::string expected = "PD 12,300.0,0.0,100.0,-90.0,0.0\r\nMS 12,10,C\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverCommands, GripSendsTheForceThenGcOrGo) {
  Rig r(obedient());  // gripper_max_force 20 N by default: 10 N is level 7.5 -> 8
  r.bring_up();
  const std::size_t from = r.peer.size();
  EXPECT_EQ(r.run(Grip{Grip::Action::close, {}, 10.0}).phase, CommandPhase::done);
  EXPECT_EQ(r.run(Grip{Grip::Action::open, {}, {}}).phase, CommandPhase::done);
  const std::string expected = "GP 8,8,3\r\nGC\r\nER\r\nGO\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverCommands, WhatTheControllerCannotDoIsRefusedUnsent) {
  Rig r(obedient());
  r.bring_up();
  const std::size_t from = r.peer.size();
  EXPECT_EQ(r.driver.submit(MoveJoints{{0, 0, 0, 0, 0}, 1.0}).error, ErrorCode::unsupported);
  EXPECT_EQ(r.driver.submit(Grip{Grip::Action::open, 0.01, {}}).error, ErrorCode::unsupported);
  EXPECT_EQ(r.driver.submit(SetOutput{1, true}).error, ErrorCode::invalid_command);
  EXPECT_EQ(r.driver.submit(WaitInput{1, true, {}}).error, ErrorCode::invalid_command);
  // The next line on the wire is the position request's.
  EXPECT_EQ(r.finish(r.driver.request_position().id).phase, CommandPhase::done);
  EXPECT_EQ(r.sent_since(from, "WH\r\n"), "WH\r\n");
}

TEST(MovemasterDriverCommands, PoseBreakingTheFiveAxisRuleFailsUnreachableUnsent) {
  Rig r(obedient());
  r.bring_up();
  const std::size_t from = r.peer.size();
  MovePose turned = move_to({300.0, 0.0, 200.0, 0.0, 0.0});
  turned.pose.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix() * turned.pose.linear();
  const CommandStatus s = r.run(turned);
  EXPECT_EQ(s.phase, CommandPhase::failed);
  EXPECT_EQ(s.error, ErrorCode::unreachable);
  EXPECT_TRUE(contains(s.message, "nothing sent")) << s.message;
  EXPECT_EQ(r.driver.state(), DriverState::active);
  MovePose on_axis = move_to({300.0, 0.0, 200.0, -90.0, 0.0});
  on_axis.pose.translation() = Eigen::Vector3d(0.0, 0.0, 0.5);
  EXPECT_EQ(r.run(on_axis).error, ErrorCode::unreachable);
  EXPECT_EQ(r.finish(r.driver.request_position().id).phase, CommandPhase::done);
  EXPECT_EQ(r.sent_since(from, "WH\r\n"), "WH\r\n");
}

// ---- Position -----------------------------------------------------------------------------------------------------

TEST(MovemasterDriverPosition, WhAnswersInEveryFormBecomeToolPoses) {
  const std::vector<std::pair<std::string, mm::Xyzpr>> answers = {
      {"+12.5,-.5,12,0.25,-90\r\n", {12.5, -0.5, 12.0, 0.25, -90.0}},
      {"300.0,0.0,200.0,-90.0,0.0\n", {300.0, 0.0, 200.0, -90.0, 0.0}},
      {" 250.5 , -100 , +.5 , -0.5 , 12.25 \r\n", {250.5, -100.0, 0.5, -0.5, 12.25}},
  };
  Rig r([&answers, next = std::size_t{0}](const std::string& line) mutable -> Peer::Reply {
    if (line == "ER") return {"0\r\n"};
    if (line == "WH") return {answers[next++ % answers.size()].first};
    return {};
  });
  r.bring_up();
  for (const auto& [text, v] : answers) {
    SCOPED_TRACE(text);
    const Submitted s = r.driver.request_position();
    ASSERT_TRUE(s.accepted());
    ASSERT_EQ(r.finish(s.id).phase, CommandPhase::done) << r.driver.poll(s.id).message;
    const std::optional<PositionReading> reading = r.driver.last_position();
    ASSERT_TRUE(reading.has_value());
    EXPECT_EQ(reading->request, s.id);
    EXPECT_TRUE(reading->joints.empty());
    ASSERT_TRUE(reading->tool_pose.has_value());
    EXPECT_TRUE(reading->tool_pose->translation().isApprox(Eigen::Vector3d(v.x, v.y, v.z) / 1000.0, 1e-12));
    EXPECT_TRUE(reading->tool_pose->isApprox(mm::to_pose(v), 1e-12)) << text;
  }
}

TEST(MovemasterDriverPosition, StraightDownAnswerIsAToolPointingDown) {
  Rig r(obedient("300.0,0.0,200.0,-90.0,0.0\r\n"));
  r.bring_up();
  ASSERT_EQ(r.finish(r.driver.request_position().id).phase, CommandPhase::done);
  const Eigen::Isometry3d pose = *r.driver.last_position()->tool_pose;
  EXPECT_TRUE(pose.translation().isApprox(Eigen::Vector3d(0.3, 0.0, 0.2), 1e-12));
  EXPECT_TRUE(pose.linear().col(2).isApprox(-Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE(pose.linear().col(1).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

// ---- Controller errors --------------------------------------------------------------------------------------------

TEST(MovemasterDriverErrors, ErOneIsAHardwareFaultThenRsAndResetClearsIt) {
  // ER 1: greeting, 2: homing, 3: the move.
  Rig r(except_nth("ER", 3, {"1\r\n"}, obedient()));
  r.bring_up();
  std::size_t from = r.peer.size();
  const CommandStatus s = r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0}));
  EXPECT_EQ(s.error, ErrorCode::hardware);
  EXPECT_TRUE(contains(s.message, "ER answered 1")) << s.message;
  EXPECT_EQ(r.driver.state(), DriverState::fault);
  std::string expected = "SP 9\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nER\r\nRS\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);

  from = r.peer.size();
  EXPECT_EQ(r.driver.reset(), ErrorCode::none);
  EXPECT_EQ(r.driver.state(), DriverState::connected);
  const Submitted h = r.driver.home();
  ASSERT_TRUE(h.accepted());
  EXPECT_EQ(r.finish(h.id).phase, CommandPhase::done);
  ASSERT_EQ(r.driver.activate(), ErrorCode::none);
  // The speed level is sent again: after an error the driver does not trust what it sent before.
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0})).phase, CommandPhase::done);
  expected = "RS\r\nER\r\nNT\r\nER\r\nSP 9\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverErrors, ResetThatDoesNotClearFaultsAgain) {
  // ER 3 (after GO) and ER 4 (after RS) both answer 1.
  Rig r(except_nth("ER", 4, {"1\r\n"}, except_nth("ER", 3, {"1\r\n"}, obedient())));
  r.bring_up();
  EXPECT_EQ(r.run(Grip{Grip::Action::open, {}, {}}).error, ErrorCode::hardware);
  EXPECT_EQ(r.driver.reset(), ErrorCode::none);
  EXPECT_TRUE(r.events.wait([&] { return r.driver.state() == DriverState::fault; }));
}

TEST(MovemasterDriverErrors, ErTwoFailsUnreachableThenRsAndTheDriverGoesOn) {
  Rig r(except_nth("ER", 3, {"2\r\n"}, obedient()));
  r.bring_up();
  const std::size_t from = r.peer.size();
  const Submitted first = r.driver.submit(move_to({900.0, 0.0, 200.0, -90.0, 0.0}));
  const Submitted behind = r.driver.submit(Grip{Grip::Action::close, {}, {}});
  ASSERT_TRUE(first.accepted() && behind.accepted());
  const CommandStatus s = r.finish(first.id);
  EXPECT_EQ(s.error, ErrorCode::unreachable);
  EXPECT_TRUE(contains(s.message, "ER answered 2")) << s.message;
  EXPECT_TRUE(contains(s.message, "MP 900.0,0.0,200.0,-90.0,0.0")) << s.message;
  EXPECT_EQ(r.finish(behind.id).error, ErrorCode::cancelled);
  EXPECT_EQ(r.driver.state(), DriverState::active);
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0})).phase, CommandPhase::done);
  const std::string expected =
      "SP 9\r\nMP 900.0,0.0,200.0,-90.0,0.0\r\nER\r\nRS\r\n"
      "SP 9\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
}

TEST(MovemasterDriverErrors, GarbageIsAProtocolFaultQuotingTheBytes) {
  const std::vector<std::pair<std::string, std::string>> answers = {
      {"1.0\r\n", "'1.0'"}, {"ER\r\n", "'ER'"}, {"0,0\r\n", "'0,0'"}, {"\x80\x07\r\n", "'\\x80\\x07'"}};
  for (const auto& [bad, quoted] : answers) {
    SCOPED_TRACE(quoted);
    Rig r(except_nth("ER", 3, {bad}, obedient()));
    r.bring_up();
    const CommandStatus s = r.run(Grip{Grip::Action::close, {}, {}});
    EXPECT_EQ(s.error, ErrorCode::protocol);
    EXPECT_TRUE(contains(s.message, quoted)) << s.message;
    EXPECT_EQ(r.driver.state(), DriverState::fault);
  }
  Rig r(obedient("HELLO\x07\r\n"));
  r.bring_up();
  const CommandStatus s = r.finish(r.driver.request_position().id);
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_TRUE(contains(s.message, "'HELLO\\x07\\r\\n'")) << s.message;
  EXPECT_EQ(r.driver.state(), DriverState::fault);
}

TEST(MovemasterDriverErrors, BytesNobodyAskedForAreAProtocolFault) {
  Rig r(obedient("300.0,0.0,200.0,-90.0,0.0\r\n0\r\n"));  // one line too many
  r.bring_up();
  EXPECT_EQ(r.finish(r.driver.request_position().id).phase, CommandPhase::done);
  const std::size_t from = r.peer.size();
  const CommandStatus s = r.run(Grip{Grip::Action::open, {}, {}});
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_TRUE(contains(s.message, "'0\\r\\n'")) << s.message;
  EXPECT_EQ(r.peer.size(), from) << "the grip went out after unasked-for bytes";
}

TEST(MovemasterDriverErrors, SilenceIsAFaultAtTheDeadline) {
  // A position read waits reply_timeout.
  Rig r(except_nth("WH", 1, {}, obedient()));
  r.bring_up();
  const auto start = Steady::now();
  const CommandStatus read = r.finish(r.driver.request_position().id);
  EXPECT_GE(Steady::now() - start, fast_options().serial.reply_timeout);
  EXPECT_EQ(read.error, ErrorCode::connection_lost);
  EXPECT_TRUE(contains(read.message, "silent") && contains(read.message, "'WH'")) << read.message;
  EXPECT_EQ(r.driver.state(), DriverState::fault);
}

TEST(MovemasterDriverErrors, SilenceAfterAMotionWaitsForTheMotionsBound) {
  Rig r(except_nth("ER", 3, {}, obedient()));
  r.bring_up();
  const auto start = Steady::now();
  const CommandStatus s = r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0}));
  EXPECT_GE(Steady::now() - start, fast_options().longest_motion + fast_options().serial.reply_timeout);
  EXPECT_EQ(s.error, ErrorCode::connection_lost);
  EXPECT_TRUE(contains(s.message, "silent")) << s.message;
  EXPECT_EQ(r.driver.state(), DriverState::fault);
  EXPECT_EQ(r.driver.reset(), ErrorCode::connection_lost);  // the link is treated as lost: connect() again
  EXPECT_EQ(r.driver.state(), DriverState::disconnected);
}

TEST(MovemasterDriverErrors, HangUpIsConnectionLostAndANewPseudoTerminalReconnects) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / fmt::format("cw-mmdrv-{}", ::getpid());
  std::filesystem::create_directories(dir);
  const std::filesystem::path link = dir / "melfa";
  Events events;
  {
    auto first = std::make_unique<Peer>(except_nth("WH", 1, {{}, true}, obedient()), link);
    MovemasterDriver driver(on_port(fast_options(), link.string()));
    driver.set_notifier(events.notifier());
    ASSERT_EQ(driver.connect(), ErrorCode::none);
    const Submitted h = driver.home();
    ASSERT_TRUE(events.wait([&] { return driver.poll(h.id).phase == CommandPhase::done; }));
    const Submitted p = driver.request_position();
    ASSERT_TRUE(events.wait([&] { return driver.poll(p.id).phase == CommandPhase::failed; }));
    EXPECT_EQ(driver.poll(p.id).error, ErrorCode::connection_lost) << driver.poll(p.id).message;
    EXPECT_EQ(driver.state(), DriverState::fault);
    EXPECT_EQ(driver.reset(), ErrorCode::connection_lost);
    EXPECT_EQ(driver.state(), DriverState::disconnected);

    first.reset();  // the old controller is gone; a new one is published at the same path
    Peer second(obedient(), link);
    ASSERT_EQ(driver.connect(), ErrorCode::none) << driver.connect_problem();
    const Submitted h2 = driver.home();
    ASSERT_TRUE(events.wait([&] { return driver.poll(h2.id).phase == CommandPhase::done; }));
    EXPECT_EQ(second.await(0, 12), "ER\r\nNT\r\nER\r\n");
  }
  std::filesystem::remove_all(dir);
}

// ---- Pacing, timing, completion -----------------------------------------------------------------------------------

TEST(MovemasterDriverTiming, LinesAreNoCloserThanWireTimePlusProcessingTime) {
  MovemasterOptions o = fast_options();
  o.serial.line.baud = 9600;
  o.serial.processing_time = 60ms;
  Rig r(obedient(), o);
  r.bring_up();
  const Submitted read = r.driver.request_position();
  const Submitted grip = r.driver.submit(Grip{Grip::Action::open, {}, {}});
  ASSERT_TRUE(read.accepted() && grip.accepted());
  ASSERT_EQ(r.finish(grip.id).phase, CommandPhase::done);
  // The read was still held by the pacing after the home's last line when the grip came: the grip overtook it (a
  // read never delays a command). GO goes out after the home's ER was answered (at `answered`); the ER after GO then
  // waits for GO's wire time plus the processing time. Only the lower bound is checked.
  EXPECT_EQ(r.finish(read.id).error, ErrorCode::cancelled);
  const std::vector<Peer::Line> lines = r.peer.lines();
  ASSERT_GE(lines.size(), 3u);
  const Peer::Line& home_er = lines[lines.size() - 3];
  const Peer::Line& er = lines[lines.size() - 1];
  ASSERT_EQ(home_er.text, "ER");
  ASSERT_EQ(lines[lines.size() - 2].text, "GO");
  ASSERT_EQ(er.text, "ER");
  EXPECT_GE(er.arrived - home_er.answered, o.serial.line.wire_time(4) + o.serial.processing_time);
}

TEST(MovemasterDriverTiming, CountsBytesAndWireTimePerCommand) {
  MovemasterOptions o = fast_options();
  o.serial.line.baud = 9600;
  const std::string answer = "300.0,0.0,200.0,-90.0,0.0\r\n";
  Rig r(obedient(answer), o);
  r.bring_up();
  const Submitted p = r.driver.request_position();
  ASSERT_EQ(r.finish(p.id).phase, CommandPhase::done);
  // The thread records a job's timing before it reports the job done: no wait.
  const SerialTiming t = r.driver.timing();
  ASSERT_EQ(t.jobs, 2u);  // home, position
  const SerialExchange& x = t.recent.back();
  EXPECT_EQ(x.id, p.id);
  EXPECT_EQ(x.bytes_sent, 4u);  // WH CR LF
  EXPECT_EQ(x.bytes_received, answer.size());
  EXPECT_EQ(x.wire_sent, o.serial.line.wire_time(4));
  EXPECT_EQ(x.wire_received, o.serial.line.wire_time(answer.size()));
  EXPECT_GT(x.wire_sent, 4 * 1100us);  // 11 bits a character at 9600 baud: 1.146 ms
  EXPECT_EQ(t.bytes_sent, std::string("NT\r\nER\r\nWH\r\n").size());
  EXPECT_EQ(t.bytes_received, 3 + answer.size());
}

TEST(MovemasterDriverCompletion, PollSendsWhUntilTwoAnswersAgreeThenEr) {
  MovemasterOptions o = fast_options();
  o.completion = MovemasterOptions::Completion::poll;
  const std::vector<std::string> where = {"280.0,0.0,210.0,-90.0,0.0\r\n", "299.5,0.0,200.5,-90.0,0.0\r\n",
                                          "300.0,0.0,200.0,-90.0,0.0\r\n"};
  Rig r(
      [&where, next = std::size_t{0}](const std::string& line) mutable -> Peer::Reply {
        if (line == "ER") return {"0\r\n"};
        if (line == "WH") return {where[std::min(next++, where.size() - 1)]};
        return {};
      },
      o);
  r.bring_up();
  const std::size_t from = r.peer.size();
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0})).phase, CommandPhase::done);
  const std::string expected = "SP 9\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nWH\r\nWH\r\nWH\r\nWH\r\nER\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
  // A WH goes out poll_period after the answer to the one before.
  const std::vector<Peer::Line> lines = r.peer.lines();
  ASSERT_GE(lines.size(), 3u);
  EXPECT_GE(lines[lines.size() - 2].arrived - lines[lines.size() - 3].answered, o.poll_period);
}

// ---- Answer variants (issue 25): the controller's line ends, whatever the host sends ------------------------------

// A controller that ends its answers with `end` (CR LF, LF alone or CR alone).
Peer::Answer obedient_with(std::string end) {
  return [end](const std::string& line) -> Peer::Reply {
    if (line == "ER") return {"0" + end};
    if (line == "WH") return {"300.0,0.0,200.0,-90.0,0.0" + end};
    return {};
  };
}

TEST(MovemasterDriverVariants, AnswersEndedByCrLfOrCrAloneOrLfAlone) {
  for (const std::string end : {"\r\n", "\r", "\n"}) {
    SCOPED_TRACE(end == "\r" ? "CR" : end == "\n" ? "LF" : "CR LF");
    Rig r(except_nth("ER", 4, {"2" + end}, obedient_with(end)));
    r.bring_up();
    // WH: the pose read back.
    const Submitted p = r.driver.request_position();
    ASSERT_EQ(r.finish(p.id).phase, CommandPhase::done) << r.driver.poll(p.id).message;
    const Eigen::Isometry3d pose = *r.driver.last_position()->tool_pose;
    EXPECT_TRUE(pose.translation().isApprox(Eigen::Vector3d(0.3, 0.0, 0.2), 1e-12));
    EXPECT_TRUE(pose.linear().col(2).isApprox(-Eigen::Vector3d::UnitZ(), 1e-12));
    // A move, then ER 2 (the 4th ER) in the same line ends: unreachable, the driver goes on.
    EXPECT_EQ(r.run(move_to({300.0, 0.0, 250.0, -90.0, 0.0})).phase, CommandPhase::done);
    const CommandStatus s = r.run(move_to({900.0, 0.0, 200.0, -90.0, 0.0}));
    EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
    EXPECT_EQ(r.driver.state(), DriverState::active);
    EXPECT_EQ(r.run(Grip{Grip::Action::close, {}, {}}).phase, CommandPhase::done);
  }
}

TEST(MovemasterDriverVariants, ACrLfSplitAcrossTwoWritesIsOneLineEnd) {
  // The CR ends the answer at once; its LF, written after the driver has read the line, is not taken for bytes
  // nobody asked for before the next command.
  Rig r([owed = false](const std::string& line) mutable -> Peer::Reply {
    std::string reply = owed ? "\n" : "";  // the LF of the last answer's CR LF comes first
    owed = line == "ER" || line == "WH";
    if (line == "ER") reply += "0\r";
    if (line == "WH") reply += "300.0,0.0,200.0,-90.0,0.0\r";
    return {reply};
  });
  r.bring_up();
  const Submitted p = r.driver.request_position();
  ASSERT_EQ(r.finish(p.id).phase, CommandPhase::done) << r.driver.poll(p.id).message;
  EXPECT_EQ(r.run(move_to({300.0, 0.0, 250.0, -90.0, 0.0})).phase, CommandPhase::done) << r.driver.poll(p.id).message;
  EXPECT_EQ(r.driver.state(), DriverState::active);
}

TEST(MovemasterDriverVariants, AnErCodeOutsideTheManualsIsAnUnknownFaultThenRs) {
  Rig r(except_nth("ER", 3, {"7\r\n"}, obedient()));
  r.bring_up();
  const std::size_t from = r.peer.size();
  const CommandStatus s = r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0}));
  EXPECT_EQ(s.error, ErrorCode::unknown) << s.message;
  EXPECT_TRUE(contains(s.message, "ER answered 7")) << s.message;
  EXPECT_EQ(r.driver.state(), DriverState::fault);
  const std::string expected = "SP 9\r\nMP 300.0,0.0,200.0,-90.0,0.0\r\nER\r\nRS\r\n";
  EXPECT_EQ(r.sent_since(from, expected), expected);
  EXPECT_EQ(r.driver.reset(), ErrorCode::none);
  const Submitted h = r.driver.home();
  EXPECT_EQ(r.finish(h.id).phase, CommandPhase::done);
}

// ---- Answer variants (issue 25): every form of WH and every class of ER code, over the pseudo-terminal ------------
// The forms are those docs/real-robots.md ("Controller to host") and facts.md allow: values with or without a sign
// (a leading '+' too) and a leading zero, with or without decimals, spaces around them, answers ended by CR LF, LF or
// CR. The ER codes: 0, 1 (hardware), 2 (position or format), another number of one or two digits (unknown).

const char* end_name(const std::string& end) {
  return end == "\r" ? "CR" : end == "\n" ? "LF" : "CR LF";
}

TEST(MovemasterDriverVariants, EveryWhFormOverEveryLineEndIsTheSamePose) {
  // Each form written its own way; all of them the pose x 300, y -0.5, z 200, p -90, r 0.5 (except the whole numbers).
  const std::vector<std::pair<std::string, mm::Xyzpr>> forms = {
      {"+300.0,-0.5,+200.0,-90.0,+0.5", {300.0, -0.5, 200.0, -90.0, 0.5}},          // every value signed
      {"300,-1,200,-90,1", {300.0, -1.0, 200.0, -90.0, 1.0}},                       // whole numbers
      {"300.00,-.5,200.25,-90.0,.5", {300.0, -0.5, 200.25, -90.0, 0.5}},            // no leading zero, two decimals
      {" 300.0, -0.5, 200.0, -90.0, 0.5", {300.0, -0.5, 200.0, -90.0, 0.5}},        // a space after each comma
      {"+300.0 , -.5 , +200.0 , -90.0 , +.5 ", {300.0, -0.5, 200.0, -90.0, 0.5}},  // spaces around each value
      {"\t300.0,\t-0.5,\t200.0,\t-90.0,\t0.5", {300.0, -0.5, 200.0, -90.0, 0.5}},      // tabs
  };
  for (const std::string end : {"\r\n", "\n", "\r"}) {
    SCOPED_TRACE(end_name(end));
    Rig r([&forms, end, next = std::size_t{0}](const std::string& line) mutable -> Peer::Reply {
      if (line == "ER") return {"0" + end};
      if (line == "WH") return {forms[next++ % forms.size()].first + end};
      return {};
    });
    r.bring_up();
    for (const auto& [text, v] : forms) {
      SCOPED_TRACE(text);
      const Submitted s = r.driver.request_position();
      ASSERT_TRUE(s.accepted());
      ASSERT_EQ(r.finish(s.id).phase, CommandPhase::done) << r.driver.poll(s.id).message;
      const std::optional<PositionReading> reading = r.driver.last_position();
      ASSERT_TRUE(reading.has_value() && reading->tool_pose.has_value());
      EXPECT_EQ(reading->request, s.id);
      EXPECT_TRUE(reading->tool_pose->translation().isApprox(Eigen::Vector3d(v.x, v.y, v.z) / 1000.0, 1e-12));
      EXPECT_TRUE(reading->tool_pose->isApprox(mm::to_pose(v), 1e-12));
    }
    EXPECT_EQ(r.driver.state(), DriverState::active);
  }
}

TEST(MovemasterDriverVariants, AWhAnswerTricklingInAByteAtATimeIsOneAnswer) {
  // At 9600 baud a character takes about 1.1 ms: the answer comes in pieces, and its CR LF last.
  Rig r([](const std::string& line) -> Peer::Reply {
    if (line == "ER") return {"0\r\n"};
    if (line == "WH") return {"+300.0,-0.5,+200.0,-90.0,+0.5\r\n", false, std::chrono::microseconds(1500)};
    return {};
  });
  r.bring_up();
  const Submitted s = r.driver.request_position();
  ASSERT_EQ(r.finish(s.id).phase, CommandPhase::done) << r.driver.poll(s.id).message;
  EXPECT_TRUE(r.driver.last_position()->tool_pose->isApprox(mm::to_pose({300.0, -0.5, 200.0, -90.0, 0.5}), 1e-12));
  // The LF that came last is no answer to the next command.
  EXPECT_EQ(r.run(Grip{Grip::Action::close, {}, {}}).phase, CommandPhase::done);
  EXPECT_EQ(r.driver.state(), DriverState::active);
}

// One class of answers to ER: what the command comes to and whether the driver goes on.
struct ErClass {
  std::string answer;  // the ER line, without its line end
  ErrorCode error;
  bool fault;        // the driver enters fault (reset() clears it); else it goes on
  std::string says;  // in the command's message
};

const std::vector<ErClass>& er_classes() {
  static const std::vector<ErClass> classes = {
      {"1", ErrorCode::hardware, true, "ER answered 1"},
      {"2", ErrorCode::unreachable, false, "ER answered 2"},
      {" 2 ", ErrorCode::unreachable, false, "ER answered 2"},
      {"3", ErrorCode::unknown, true, "ER answered 3"},
      {"42", ErrorCode::unknown, true, "ER answered 42"},
      {"99", ErrorCode::unknown, true, "ER answered 99"},
  };
  return classes;
}

// Each command the driver sends, with the lines it sends for it (after a bring-up, speed level 9 not sent yet).
struct Sent {
  std::string name;
  std::function<Submitted(MovemasterDriver&)> submit;
  std::string lines;  // what goes out before the ER
};

std::vector<Sent> every_command() {
  const mm::Xyzpr to{300.0, 0.0, 250.0, -90.0, 0.0};
  return {
      {"home", [](MovemasterDriver& d) { return d.home(); }, "NT\r\n"},
      {"joint move", [to](MovemasterDriver& d) { return d.submit(move_to(to)); },
       "SP 9\r\nMP 300.0,0.0,250.0,-90.0,0.0\r\n"},
      // Linear: the driver does not know where the arm is after homing, so it asks (WH) to count the points.
      {"linear move", [to](MovemasterDriver& d) { return d.submit(move_to(to, Path::linear)); },
       "SP 9\r\nWH\r\nPD 629,300.0,0.0,250.0,-90.0,0.0\r\nMS 629,5,O\r\n"},
      {"grip with force", [](MovemasterDriver& d) { return d.submit(Grip{Grip::Action::close, {}, 10.0}); },
       "GP 8,8,3\r\nGC\r\n"},
  };
}

TEST(MovemasterDriverVariants, EveryErCodeClassAfterEveryCommandThenRs) {
  for (const ErClass& c : er_classes()) {
    for (const Sent& command : every_command()) {
      SCOPED_TRACE(fmt::format("ER '{}' after the {}", c.answer, command.name));
      // ER 1: connect, ER 2: homing (for the home case, the ER after NT is the 2nd), then the command's.
      const int nth = command.name == "home" ? 2 : 3;
      Rig r(except_nth("ER", nth, {c.answer + "\r\n"}, obedient()));
      if (command.name == "home") {
        ASSERT_EQ(r.driver.connect(), ErrorCode::none) << r.driver.connect_problem();
      } else {
        r.bring_up();
      }
      const std::size_t from = r.peer.size();
      const Submitted s = command.submit(r.driver);
      ASSERT_TRUE(s.accepted()) << s.message;
      const CommandStatus st = r.finish(s.id);
      EXPECT_EQ(st.phase, CommandPhase::failed);
      EXPECT_EQ(st.error, c.error) << st.message;
      EXPECT_TRUE(contains(st.message, c.says)) << st.message;
      const std::string expected = command.lines + "ER\r\nRS\r\n";
      EXPECT_EQ(r.sent_since(from, expected), expected);
      if (c.fault) {
        EXPECT_TRUE(r.events.wait([&] { return r.driver.state() == DriverState::fault; }));
        EXPECT_EQ(r.driver.reset(), ErrorCode::none);
        EXPECT_TRUE(r.events.wait([&] { return r.driver.state() == DriverState::connected; }));
      } else {
        EXPECT_NE(r.driver.state(), DriverState::fault);
      }
      // Either way the driver goes on with the controller: an active driver moves again, another homes; a read-back.
      if (r.driver.state() == DriverState::active) {
        EXPECT_EQ(r.run(move_to({300.0, 0.0, 200.0, -90.0, 0.0})).phase, CommandPhase::done);
      } else {
        const Submitted h = r.driver.home();
        ASSERT_TRUE(h.accepted()) << h.message;
        EXPECT_EQ(r.finish(h.id).phase, CommandPhase::done) << r.driver.poll(h.id).message;
      }
      EXPECT_EQ(r.finish(r.driver.request_position().id).phase, CommandPhase::done);
    }
  }
}

TEST(MovemasterDriverVariants, EveryNonZeroErCodeAtConnectFailsItThenRsAndTheNextConnectWorks) {
  for (const ErClass& c : er_classes()) {
    SCOPED_TRACE(c.answer);
    Rig r(except_nth("ER", 1, {c.answer + "\r\n"}, obedient()));
    EXPECT_EQ(r.driver.connect(), ErrorCode::connection_lost);
    EXPECT_EQ(r.driver.state(), DriverState::disconnected);
    EXPECT_TRUE(contains(r.driver.connect_problem(), c.says)) << r.driver.connect_problem();
    EXPECT_EQ(r.sent_since(0, "ER\r\nRS\r\n"), "ER\r\nRS\r\n");
    EXPECT_EQ(r.driver.connect(), ErrorCode::none) << r.driver.connect_problem();
  }
}

TEST(MovemasterDriverVariants, AnErCodeOtherThanZeroAfterRsKeepsTheFault) {
  for (const ErClass& c : er_classes()) {
    SCOPED_TRACE(c.answer);
    // ER 3 (after GO) answers 1; ER 4 (after the reset's RS) answers the class's code.
    Rig r(except_nth("ER", 4, {c.answer + "\r\n"}, except_nth("ER", 3, {"1\r\n"}, obedient())));
    r.bring_up();
    EXPECT_EQ(r.run(Grip{Grip::Action::open, {}, {}}).error, ErrorCode::hardware);
    EXPECT_EQ(r.driver.reset(), ErrorCode::none);  // accepted: the RS goes out on the communication thread
    EXPECT_TRUE(r.events.wait([&] { return r.driver.state() == DriverState::fault; }));
    const Submitted h = r.driver.home();
    EXPECT_FALSE(h.accepted()) << "a driver whose controller kept its error took a command";
  }
}

}  // namespace
}  // namespace cellwright::drivers
