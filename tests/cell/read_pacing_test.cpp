// Position reads paced to a 9600-baud line (docs/real-robots.md, "The serial line"): robot control of the PUMA over the
// VAL II driver, against the VAL II emulator paced as a real 9600-baud line (emulate/line_pace.hpp), over a
// pseudo-terminal, in real time. What a user of a real cell would check, on the emulator's record of the lines it
// received: idle, the robot is read at most once per read_time / read_line_share; a motion goes out behind at most the
// one read already on the wire; between two motions the line carries one read, the one that checks the first.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "controller/runtime/scripted_cell.hpp"

namespace cellwright {
namespace {

using namespace std::chrono_literals;
using runtime::RobotPhase;
using Steady = std::chrono::steady_clock;

constexpr double kTimeScale = 0.1;  // motions take a tenth of their time; the line does not

task::Primitive move(task::TargetKind kind, std::string object = "") {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kMove;
  p.target = {kind, std::move(object)};
  return p;
}

class ReadPacingTest : public ::testing::Test {
 protected:
  ReadPacingTest()
      : spec_(*testing::paper_cell().find_robot("puma")),
        chain_(models::KinematicChain::from_urdf_file(spec_.urdf)),
        dir_(std::filesystem::path(::testing::TempDir()) / fmt::format("cw-read-pacing-{}", ::getpid())),
        arm_(chain_, arm_options()),
        env_(runtime::make_environment_model(testing::paper_cell())),
        inbox_(4),
        statuses_(8) {
    std::filesystem::create_directories(dir_);
    emulate::Val2EmulatorOptions e;
    e.pace = {9600, 10};
    e.log = [this](std::string_view text) {
      if (!text.starts_with("< ")) return;
      std::lock_guard lock(mutex_);
      lines_.emplace_back(text.substr(2));
    };
    emulator_ = std::make_unique<emulate::Val2Emulator>(arm_, std::move(e));
    const std::filesystem::path link = dir_ / "puma";
    serving_ = std::thread([this, link] { emulator_->serve(link); });
    EXPECT_TRUE(emulator_->wait_published(1, 10s));
    drivers::Val2Options o;
    o.serial.line.port = link.string();
    o.serial.where = spec_.where;
    for (double& v : o.max_joint_speed) v /= kTimeScale;
    o.max_tool_speed /= kTimeScale;
    driver_ = std::make_unique<drivers::Val2Driver>(std::move(o));
    driver_->set_notifier([this] {
      {
        std::lock_guard lock(mutex_);
        ++notified_;
      }
      cv_.notify_all();
    });
  }
  ~ReadPacingTest() override {
    control_.reset();
    driver_.reset();
    emulator_->stop();
    serving_.join();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  emulate::KinematicArmOptions arm_options() const {
    emulate::KinematicArmOptions a;
    a.home = spec_.home;
    a.time_scale = kTimeScale;
    return a;
  }

  void make(runtime::MotionOptions options) {
    runtime::NameMap names;
    names.robots = {{"r1", "puma"}};
    names.objects = {{"A", "A"}};
    control_ = std::make_unique<runtime::RobotControl>(0, "r1", "puma", *driver_, chain_, spec_.grip_force, names, env_,
                                                       inbox_, statuses_, log_, options);
    control_->connect();
    start_ = Steady::now();
  }

  // Robot control's turns in real time (as its thread runs them: a turn, then a wait for the driver or 1 ms), until
  // `done` or `limit` has passed; whether `done` came.
  template <typename Pred>
  bool run_until(Pred done, std::chrono::nanoseconds limit) {
    const auto end = Steady::now() + limit;
    while (Steady::now() < end) {
      control_->step(Steady::now() - start_);
      if (done()) return true;
      std::unique_lock lock(mutex_);
      const std::uint64_t seen = notified_;
      cv_.wait_for(lock, 1ms, [&] { return notified_ != seen; });
    }
    return done();
  }

  void send(std::size_t index, task::Primitive p) {
    runtime::MotionCommand c;
    c.index = index;
    c.primitive = std::move(p);
    ASSERT_EQ(inbox_.try_push(std::move(c)), runtime::QueueStatus::ok);
  }
  // Runs until robot control reports a status (at most 20 s).
  std::optional<runtime::RobotStatus> next_status() {
    std::optional<runtime::RobotStatus> got;
    run_until(
        [&] {
          runtime::RobotStatus s;
          if (statuses_.try_pop(s) == runtime::QueueStatus::ok) got = s;
          return got.has_value();
        },
        20s);
    return got;
  }

  std::vector<std::string> lines() const {
    std::lock_guard lock(mutex_);
    return lines_;
  }
  static std::size_t wheres(const std::vector<std::string>& l, std::size_t from, std::size_t to) {
    std::size_t n = 0;
    for (std::size_t i = from; i < to && i < l.size(); ++i) n += l[i] == "WHERE" ? 1 : 0;
    return n;
  }
  static std::size_t next_motion(const std::vector<std::string>& l, std::size_t from) {
    for (std::size_t i = from; i < l.size(); ++i) {
      if (l[i].starts_with("DO MOVE")) return i;
    }
    return l.size();
  }
  std::size_t conditions(const std::string& condition) const {
    std::size_t n = 0;
    for (const std::string& line : log_.lines()) {
      const nlohmann::json j = nlohmann::json::parse(line);
      n += j["type"] == "sensor" && j["condition"] == condition ? 1 : 0;
    }
    return n;
  }

  const models::RobotSpec& spec_;
  const models::KinematicChain chain_;
  std::filesystem::path dir_;
  emulate::KinematicArm arm_;
  std::unique_ptr<emulate::Val2Emulator> emulator_;
  std::thread serving_;
  std::unique_ptr<drivers::Val2Driver> driver_;
  runtime::SharedEnvironment env_;
  runtime::MessageQueue<runtime::MotionCommand> inbox_;
  runtime::MessageQueue<runtime::RobotStatus> statuses_;
  runtime::EventLog log_;
  std::unique_ptr<runtime::RobotControl> control_;
  Steady::time_point start_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t notified_ = 0;
  std::vector<std::string> lines_;
};

TEST_F(ReadPacingTest, IdleReadsKeepToTheirShareOfTheLineAndMotionsDoNotWaitBehindReads) {
  const runtime::MotionOptions options;  // read_line_share 0.25
  make(options);
  ASSERT_TRUE(run_until([&] { return control_->phase() == RobotPhase::kReady; }, 20s));

  // Idle for 3.2 s: at most one read per read_time / read_line_share (about 1.07 s), and the first at once.
  const auto read_time = driver_->capabilities().read_time;
  ASSERT_GT(read_time, 200ms);  // 9600 baud: a WHERE and its answer
  const auto period = std::chrono::duration_cast<std::chrono::nanoseconds>(read_time / options.read_line_share);
  const std::size_t idle_from = lines().size();
  const auto idle = 3200ms;
  run_until([] { return false; }, idle);
  const std::size_t idle_reads = wheres(lines(), idle_from, lines().size());
  EXPECT_GE(idle_reads, 2u);  // it is still read
  EXPECT_LE(idle_reads, static_cast<std::size_t>(idle / period) + 1)
      << "idle reads in " << idle.count() << " ms with a period of " << period.count() / 1000000 << " ms";

  // Two motions. The first goes out behind at most the read already on the wire (its WHERE received before or just
  // after the motion was sent); between the two, one read: the one that checks the first; after the second, its check.
  const std::size_t sent_at = lines().size();
  send(0, move(task::TargetKind::kAbove, "A"));
  const std::optional<runtime::RobotStatus> first = next_status();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->outcome, runtime::CommandOutcome::kDone) << first->reason;
  send(1, move(task::TargetKind::kHome));
  const std::optional<runtime::RobotStatus> second = next_status();
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->outcome, runtime::CommandOutcome::kDone) << second->reason;

  const std::vector<std::string> l = lines();
  const std::size_t m1 = next_motion(l, sent_at);
  ASSERT_LT(m1, l.size());
  const std::size_t m2 = next_motion(l, m1 + 1);
  ASSERT_LT(m2, l.size());
  EXPECT_LE(wheres(l, sent_at, m1), 1u) << "reads the first motion went out behind";
  EXPECT_EQ(wheres(l, m1 + 1, m2), 1u) << "reads between the two motions (the check of the first only)";
  EXPECT_GE(wheres(l, m2 + 1, l.size()), 1u) << "the read that checks the second motion";
  EXPECT_EQ(conditions("position_reached"), 2u);  // each motion checked on its read-back
}

}  // namespace
}  // namespace cellwright
