// How the serial drivers share their line between position reads and commands (docs/real-robots.md, "The serial
// line"), against the emulators over pseudo-terminals, the emulator paced as a real line where the figure depends on
// it (emulate/line_pace.hpp):
//  - a paced emulator's answer crosses the line no faster than its rate;
//  - each driver's Capabilities::read_time is the wire time of a read it really makes (request and answer), plus the
//    controller's processing time (within 20 %: the answer's length varies with the values);
//  - a command overtakes a position read that is not on the wire yet: the emulator receives the command first, the
//    read is withdrawn (cancelled), and a read asked after the motion still comes and tells where it ended.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright {
namespace {

using namespace std::chrono_literals;
using drivers::CommandPhase;
using drivers::CommandStatus;
using drivers::ErrorCode;
using drivers::Submitted;

constexpr double kTimeScale = 0.02;  // the arm 50 times as fast as its URDF says
constexpr auto kHang = 10s;

// An emulator of type E on a fresh path, serving on a thread, the lines it receives recorded in order; a driver D.
template <typename E, typename D>
class Line {
 public:
  template <typename EOptions, typename DOptions>
  Line(const char* urdf, EOptions emulator_options, DOptions driver_options)
      : dir_(std::filesystem::path(::testing::TempDir()) / fmt::format("cw-line-{}-{}", ::getpid(), ++serial_)),
        arm_(make_arm(urdf)) {
    std::filesystem::create_directories(dir_);
    emulator_options.log = [this](std::string_view text) {
      if (!text.starts_with("< ")) return;
      std::lock_guard lock(mutex_);
      received_.emplace_back(text.substr(2));
    };
    emulator_ = std::make_unique<E>(arm_, std::move(emulator_options));
    const std::filesystem::path link = dir_ / "line";
    thread_ = std::thread([this, link] { emulator_->serve(link); });
    EXPECT_TRUE(emulator_->wait_published(1, kHang));
    driver_options.serial.line.port = link.string();
    driver_options.serial.where = {"line_sharing_test", 0, 0};
    driver = std::make_unique<D>(std::move(driver_options));
    driver->set_notifier([this] {
      {
        std::lock_guard lock(mutex_);
        ++notified_;
      }
      cv_.notify_all();
    });
  }
  ~Line() {
    driver.reset();
    emulator_->stop();
    thread_.join();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  Line(const Line&) = delete;
  Line& operator=(const Line&) = delete;

  // Waits (woken by the driver's notifier) until job `s` has ended; its status.
  CommandStatus finish(const Submitted& s) {
    EXPECT_TRUE(s.accepted()) << s.message;
    const auto deadline = std::chrono::steady_clock::now() + kHang;
    std::unique_lock lock(mutex_);
    for (;;) {
      const std::uint64_t seen = notified_;
      lock.unlock();
      const CommandStatus st = driver->poll(s.id);
      if (st.phase == CommandPhase::done || st.phase == CommandPhase::failed) return st;
      lock.lock();
      if (!cv_.wait_until(lock, deadline, [&] { return notified_ != seen; })) {
        ADD_FAILURE() << "job " << s.id << " did not end";
        return st;
      }
    }
  }
  void bring_up() {
    ASSERT_EQ(driver->connect(), ErrorCode::none) << driver->connect_problem();
    const CommandStatus h = finish(driver->home());
    ASSERT_EQ(h.phase, CommandPhase::done) << h.message;
    ASSERT_EQ(driver->activate(), ErrorCode::none);
  }
  // The lines the emulator has received so far, in order.
  std::vector<std::string> received() const {
    std::lock_guard lock(mutex_);
    return received_;
  }
  const emulate::KinematicArm& arm() const { return arm_; }

  std::unique_ptr<D> driver;

 private:
  static emulate::KinematicArm make_arm(const char* urdf) {
    emulate::KinematicArmOptions o;
    o.time_scale = kTimeScale;
    return emulate::KinematicArm(models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + urdf), o);
  }
  static inline std::atomic<int> serial_{0};
  std::filesystem::path dir_;
  emulate::KinematicArm arm_;
  std::unique_ptr<E> emulator_;
  std::thread thread_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t notified_ = 0;
  std::vector<std::string> received_;
};

using Val2Line = Line<emulate::Val2Emulator, drivers::Val2Driver>;
using MovemasterLine = Line<emulate::MovemasterEmulator, drivers::MovemasterDriver>;

drivers::Val2Options val2_options() {
  drivers::Val2Options o;
  for (double& v : o.max_joint_speed) v /= kTimeScale;
  o.max_tool_speed /= kTimeScale;
  o.serial.processing_time = 1ms;
  return o;
}

drivers::MovemasterOptions movemaster_options() {
  drivers::MovemasterOptions o;
  o.serial.processing_time = 1ms;
  o.longest_motion = 200ms;
  o.home_time = 400ms;
  o.grip_time = 100ms;
  o.grip_start_time = 0;
  return o;
}

// The exchange the driver recorded for job `id`.
drivers::SerialExchange exchange_of(const drivers::SerialDriver& d, drivers::CommandId id) {
  for (const drivers::SerialExchange& x : d.timing().recent) {
    if (x.id == id) return x;
  }
  ADD_FAILURE() << "no exchange recorded for job " << id;
  return {};
}

TEST(LineSharing, APacedEmulatorsAnswerCrossesTheLineNoFasterThanItsRate) {
  emulate::Val2EmulatorOptions paced;
  paced.pace = {9600, 10};
  Val2Line line("/urdf/puma560.urdf", paced, val2_options());
  line.bring_up();
  const Submitted r = line.driver->request_position();
  ASSERT_EQ(line.finish(r).phase, CommandPhase::done);
  const drivers::SerialExchange x = exchange_of(*line.driver, r.id);
  // The request's bytes and the answer's: each a character time (10 bits at 9600 baud) on the line, one after the
  // other. A pseudo-terminal alone passes them at once.
  const auto wire = x.wire_sent + x.wire_received;
  EXPECT_GT(x.bytes_received, 200u);
  EXPECT_GE(x.elapsed, wire * 95 / 100) << "bytes " << x.bytes_sent << " + " << x.bytes_received;
}

// Capabilities::read_time against a read the driver really makes: the same bytes' wire time (within 20 %: a typical
// answer's length, not this one's) plus the processing time.
template <typename L>
void expect_read_time_of_a_real_read(L& line, std::chrono::nanoseconds processing) {
  line.bring_up();
  const Submitted r = line.driver->request_position();
  ASSERT_EQ(line.finish(r).phase, CommandPhase::done);
  const drivers::SerialExchange x = exchange_of(*line.driver, r.id);
  const auto actual = x.wire_sent + x.wire_received + processing;
  const auto claimed = line.driver->capabilities().read_time;
  EXPECT_GT(claimed, processing);
  EXPECT_NEAR(static_cast<double>(claimed.count()), static_cast<double>(actual.count()),
              0.2 * static_cast<double>(actual.count()))
      << "bytes sent " << x.bytes_sent << ", received " << x.bytes_received;
}

TEST(LineSharing, Val2ReportsTheWireTimeOfAWhere) {
  Val2Line line("/urdf/puma560.urdf", emulate::Val2EmulatorOptions{}, val2_options());
  expect_read_time_of_a_real_read(line, 1ms);
  // At 9600 baud: about a quarter of a second, most of it the answer.
  const auto at_9600 = line.driver->capabilities().read_time;
  EXPECT_GT(at_9600, 200ms);
  EXPECT_LT(at_9600, 300ms);
}

TEST(LineSharing, MovemasterReportsTheWireTimeOfAWh) {
  MovemasterLine line("/urdf/melfa_rve2.urdf", emulate::MovemasterEmulatorOptions{}, movemaster_options());
  expect_read_time_of_a_real_read(line, 1ms);
}

// A read asked for just before a command, while the line's pacing holds both: the command goes first, the read is
// withdrawn; a read asked after the motion tells where it ended.
TEST(LineSharing, ACommandOvertakesAReadThatIsNotOnTheWireYet) {
  drivers::Val2Options o = val2_options();
  o.serial.processing_time = 400ms;  // the window in which both are asked: the line is held after each line sent
  Val2Line line("/urdf/puma560.urdf", emulate::Val2EmulatorOptions{}, o);
  line.bring_up();
  const std::size_t before = line.received().size();
  const std::vector<double> goal = {0, 60 * std::numbers::pi / 180, -120 * std::numbers::pi / 180,
                                    0, 30 * std::numbers::pi / 180, 0};
  const Submitted read = line.driver->request_position();
  const Submitted move = line.driver->submit(drivers::MoveJoints{goal, 1.0});
  const CommandStatus m = line.finish(move);
  ASSERT_EQ(m.phase, CommandPhase::done) << m.message;
  const CommandStatus r = line.finish(read);
  EXPECT_EQ(r.phase, CommandPhase::failed);
  EXPECT_EQ(r.error, ErrorCode::cancelled);
  EXPECT_NE(r.message.find(fmt::format("overtaken by command {}", move.id)), std::string::npos) << r.message;

  // The emulator's record: nothing but the motion's lines (SPEED, DO MOVE) since the home; no WHERE before them.
  std::vector<std::string> lines = line.received();
  lines.erase(lines.begin(), lines.begin() + static_cast<std::ptrdiff_t>(before));
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.back().rfind("DO MOVE", 0), 0u) << lines.back();
  for (const std::string& l : lines) EXPECT_EQ(l.find("WHERE"), std::string::npos) << l;

  // The read after the motion is answered, with the joints the motion went to.
  const Submitted after = line.driver->request_position();
  ASSERT_EQ(line.finish(after).phase, CommandPhase::done);
  const std::optional<drivers::PositionReading> p = line.driver->last_position();
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->request, after.id);
  ASSERT_EQ(p->joints.size(), goal.size());
  for (std::size_t j = 0; j < goal.size(); ++j) EXPECT_NEAR(p->joints[j], goal[j], 1e-3) << "joint " << j + 1;
  EXPECT_EQ(line.received().back(), "WHERE");
}

}  // namespace
}  // namespace cellwright
