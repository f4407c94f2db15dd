// The serial drivers against the controller emulators, over real pseudo-terminals: the Movemaster EX driver against
// the Movemaster EX emulator and the VAL II driver against the VAL II emulator, each pair written apart from
// docs/real-robots.md. In each test the emulator serves a fresh path on a thread of its own, with a KinematicArm on the
// project's URDF behind it (sped up by time_scale), and the driver opens that path as it opens /dev/ttyUSB0.
//
// What a user of the pair would check: the driver connects and homes; a motion ends where it was sent, as the read-back
// says and as the arm's own joints say; the grip closes the hand; a pose out of reach fails and the driver goes on;
// each thing an emulator can be told to do wrong ends as the doc says (a fault the user can reset, a failed command,
// a lost link the driver connects to again); a random run of misbehaviours never hangs; the byte counts of the
// driver's timing are the bytes on the line.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <numbers>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/misbehaviour.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright {
namespace {

using namespace std::chrono_literals;
using drivers::CommandId;
using drivers::CommandPhase;
using drivers::CommandStatus;
using drivers::DriverState;
using drivers::ErrorCode;
using drivers::Grip;
using drivers::MoveJoints;
using drivers::MovePose;
using drivers::Path;
using drivers::Submitted;
using emulate::KinematicArm;
using emulate::Misbehaviour;
using emulate::MisbehaviourKind;
using Steady = std::chrono::steady_clock;

constexpr double kDeg = std::numbers::pi / 180.0;
// Motions take this share of their real time: the arm is 50 times as fast as the URDF says, and the drivers are told
// so (their speeds and longest motions scaled alike), so that their deadlines stay as tight as they would be.
constexpr double kTimeScale = 0.02;
// The longest any one call may take before a test calls it a hang: well above every driver deadline used here.
constexpr auto kHang = 5s;

// ---- Waiting for the driver ----------------------------------------------------------------------------------------

// The driver's notifier: waits for a condition with a deadline, woken by each notification instead of sleeping.
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
  bool wait(const std::function<bool()>& holds, std::chrono::nanoseconds within = kHang) {
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

bool ended(const CommandStatus& s) {
  return s.phase == CommandPhase::done || s.phase == CommandPhase::failed;
}

// ---- The two pairs -------------------------------------------------------------------------------------------------

// The line of both pairs: a pseudo-terminal at a fast rate (pacing costs little), short answer deadlines.
void fast_line(drivers::SerialOptions& serial, const std::string& port) {
  serial.line.port = port;
  serial.line.baud = 115200;
  serial.where = {"serial_drivers_test", 0, 0};
  serial.processing_time = 1ms;
  serial.reply_timeout = 500ms;
}

// An emulator that publishes again soon after a drop.
template <typename EmulatorOptions>
EmulatorOptions quick_reconnect() {
  EmulatorOptions o;
  o.reconnect_delay = 50ms;
  return o;
}

// What differs between the Movemaster EX pair and the VAL II pair; the Rig below is the same for both.
struct Movemaster {
  using Emulator = emulate::MovemasterEmulator;
  using EmulatorOptions = emulate::MovemasterEmulatorOptions;
  using Driver = drivers::MovemasterDriver;
  using DriverOptions = drivers::MovemasterOptions;
  static constexpr const char* kUrdf = "/urdf/melfa_rve2.urdf";
  static constexpr const char* kName = "movemaster";

  // Short deadlines: the longest motion of the sped-up RV-E2 at level 9 is about 40 ms (joint 2's 180° at
  // 1.57 rad/s, times kTimeScale).
  static DriverOptions driver_options(const std::string& port) {
    DriverOptions o;
    fast_line(o.serial, port);
    o.longest_motion = 100ms;
    o.home_time = 200ms;
    o.grip_time = 100ms;
    o.grip_start_time = 0;
    return o;
  }
  static EmulatorOptions emulator_options() { return quick_reconnect<EmulatorOptions>(); }
  static std::uint64_t publications(const Emulator& e) { return e.stats().publications; }
};

struct Val2 {
  using Emulator = emulate::Val2Emulator;
  using EmulatorOptions = emulate::Val2EmulatorOptions;
  using Driver = drivers::Val2Driver;
  using DriverOptions = drivers::Val2Options;
  static constexpr const char* kUrdf = "/urdf/puma560.urdf";
  static constexpr const char* kName = "val2";

  static DriverOptions driver_options(const std::string& port) {
    DriverOptions o;
    fast_line(o.serial, port);
    for (double& v : o.max_joint_speed) v /= kTimeScale;  // the arm is that much faster
    o.max_tool_speed /= kTimeScale;
    o.motion_margin = 300ms;
    o.home_timeout = 1s;
    o.resync_quiet = 30ms;
    return o;
  }
  static EmulatorOptions emulator_options() { return quick_reconnect<EmulatorOptions>(); }
  static std::uint64_t publications(const Emulator& e) { return e.stats().connections; }
};

// An emulator serving a fresh path on its own thread, the arm behind it, and a driver for that path.
template <typename Pair>
class Rig {
 public:
  using Emulator = typename Pair::Emulator;
  using Driver = typename Pair::Driver;

  explicit Rig(typename Pair::EmulatorOptions emulator_options = Pair::emulator_options(),
               const std::function<void(typename Pair::DriverOptions&)>& tweak = {})
      : dir_(make_dir()), link(dir_ / Pair::kName), arm(make_arm()) {
    emulator = std::make_unique<Emulator>(arm, std::move(emulator_options));
    thread_ = std::thread([this] {
      try {
        emulator->serve(link);
      } catch (const std::exception& e) {
        ADD_FAILURE() << "serve() threw: " << e.what();
      }
    });
    EXPECT_TRUE(emulator->wait_published(1, kHang));
    typename Pair::DriverOptions options = Pair::driver_options(link.string());
    if (tweak) tweak(options);
    driver = std::make_unique<Driver>(std::move(options));
    driver->set_notifier(events.notifier());
  }
  ~Rig() {
    driver.reset();  // disconnects: its thread ends before the line does
    emulator->stop();
    thread_.join();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  Rig(const Rig&) = delete;
  Rig& operator=(const Rig&) = delete;

  // Waits for a submitted command to end (a hang is a failure) and returns its status.
  CommandStatus finish(const Submitted& submitted) {
    EXPECT_TRUE(submitted.accepted()) << submitted.message;
    if (!submitted.accepted()) return {};
    const CommandId id = submitted.id;
    EXPECT_TRUE(events.wait([&] { return ended(driver->poll(id)); })) << "command " << id << " did not end";
    return driver->poll(id);
  }
  // Submits and waits; expects success.
  void done(const drivers::Command& command) {
    const CommandStatus s = finish(driver->submit(command));
    EXPECT_EQ(s.phase, CommandPhase::done)
        << drivers::describe(command) << ": " << to_string(s.error) << ": " << s.message;
  }
  // connect(), home(), activate().
  void bring_up() {
    ASSERT_EQ(driver->connect(), ErrorCode::none) << driver->connect_problem();
    home_and_activate();
  }
  void home_and_activate() {
    const CommandStatus h = finish(driver->home());
    ASSERT_EQ(h.phase, CommandPhase::done) << to_string(h.error) << ": " << h.message;
    ASSERT_EQ(driver->state(), DriverState::homed);
    ASSERT_EQ(driver->activate(), ErrorCode::none);
  }
  // A position read-back (request_position() and its answer).
  drivers::PositionReading read_back() {
    const Submitted r = driver->request_position();
    const CommandStatus s = finish(r);
    EXPECT_EQ(s.phase, CommandPhase::done) << to_string(s.error) << ": " << s.message;
    const std::optional<drivers::PositionReading> reading = driver->last_position();
    EXPECT_TRUE(reading && reading->request == r.id);
    return reading.value_or(drivers::PositionReading{});
  }
  // Waits for the driver to be in `state`.
  bool reaches(DriverState state) {
    return events.wait([&] { return driver->state() == state; });
  }
  // The tool pose the arm stands at, by the project's kinematics (the truth behind both sides of the line).
  Eigen::Isometry3d arm_pose() const {
    const std::vector<double> q = arm.joints();
    return arm.chain().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
  }

 private:
  static std::filesystem::path make_dir() {
    static std::atomic<int> serial{0};
    const std::filesystem::path d =
        std::filesystem::path(::testing::TempDir()) / fmt::format("cw-serial-{}-{}", ::getpid(), ++serial);
    std::filesystem::create_directories(d);
    return d;
  }
  static KinematicArm make_arm() {
    emulate::KinematicArmOptions o;
    o.time_scale = kTimeScale;
    return KinematicArm(models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + Pair::kUrdf), o);
  }

  std::filesystem::path dir_;

 public:
  std::filesystem::path link;
  KinematicArm arm;
  std::unique_ptr<Emulator> emulator;
  Events events;
  std::unique_ptr<Driver> driver;

 private:
  std::thread thread_;
};

// After a fault that the doc says leaves the link up: reset() -> connected, then home and activate work again.
template <typename Pair>
void expect_reset_and_home(Rig<Pair>& rig) {
  ASSERT_TRUE(rig.reaches(DriverState::fault));
  ASSERT_EQ(rig.driver->reset(), ErrorCode::none);
  EXPECT_EQ(rig.driver->state(), DriverState::connected);
  rig.home_and_activate();
}

// After the link dropped: reset() -> disconnected, and connect() to the republished pseudo-terminal works.
template <typename Pair>
void expect_reconnect(Rig<Pair>& rig, std::uint64_t publications) {
  ASSERT_TRUE(rig.reaches(DriverState::fault));
  EXPECT_EQ(rig.driver->reset(), ErrorCode::connection_lost);
  EXPECT_EQ(rig.driver->state(), DriverState::disconnected);
  ASSERT_TRUE(rig.emulator->wait_published(publications, kHang));
  ASSERT_EQ(rig.driver->connect(), ErrorCode::none) << rig.driver->connect_problem();
}

Misbehaviour at(MisbehaviourKind kind, std::uint64_t line) {
  Misbehaviour m;
  m.kind = kind;
  m.at_line = line;
  return m;
}

Misbehaviour random(MisbehaviourKind kind, double probability, std::chrono::nanoseconds delay = {}) {
  Misbehaviour m;
  m.kind = kind;
  m.probability = probability;
  m.delay = delay;
  return m;
}

double degrees_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() / kDeg;
}

// ---- Movemaster EX -------------------------------------------------------------------------------------------------

using MovemasterRig = Rig<Movemaster>;

// A pose under the doc's 5-axis rule, built here from the doc's words (not from either side's code): the tool point
// (mm), the approach axis at pitch p in the vertical plane through the base axis and the point, and roll r about it;
// R = [w × a, w, a] · Rz(r).
Eigen::Isometry3d five_axis(double x, double y, double z, double p, double r) {
  const double theta = std::atan2(y, x);
  const Eigen::Vector3d u(std::cos(theta), std::sin(theta), 0), w(-std::sin(theta), std::cos(theta), 0);
  const Eigen::Vector3d a = std::cos(p * kDeg) * u + std::sin(p * kDeg) * Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d r0;
  r0 << w.cross(a), w, a;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = r0 * Eigen::AngleAxisd(r * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, y, z) / 1000.0;
  return pose;
}

// The resolution a Movemaster read-back can agree to: WH's one decimal (half of it), plus the emulator's inverse
// kinematics tolerance (models::IkOptions: 0.01 mm, 1e-4 rad). The poses sent have one decimal, so MP rounds nothing.
constexpr double kMovemasterMm = 0.05 + 0.01 + 1e-6;
// Pitch and roll each within 0.05° + 1e-4 rad: their rotations together stay within the sum.
constexpr double kMovemasterDeg = 2 * (0.05 + 1e-4 / kDeg);

void expect_pose_near(const Eigen::Isometry3d& got, const Eigen::Isometry3d& want, double mm, double deg,
                      const std::string& what) {
  EXPECT_LE((got.translation() - want.translation()).norm() * 1000.0, mm)
      << what << ": at " << (got.translation() * 1000).transpose() << " mm, sent "
      << (want.translation() * 1000).transpose();
  EXPECT_LE(degrees_between(got.linear(), want.linear()), deg) << what;
}

TEST(MovemasterAgainstEmulator, ConnectsHomesMovesGripsAndReadsBackWhatWasSent) {
  MovemasterRig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  EXPECT_EQ(rig.arm.joints(), rig.arm.home());

  struct Target {
    const char* what;
    Eigen::Isometry3d pose;
    Path path;
    double speed;
  };
  const Target targets[] = {
      {"tool down, joint", five_axis(300.0, 0.0, 200.0, -90.0, 0.0), Path::joint, 1.0},
      {"tool down and rolled, linear", five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::linear, 0.5},
      {"horizontal and radial, joint", five_axis(420.0, -150.0, 300.0, 0.0, 0.0), Path::joint, 0.3},
      {"pitched and rolled, linear", five_axis(350.0, 100.0, 200.0, -45.0, -60.0), Path::linear, 1.0},
  };
  for (const Target& t : targets) {
    rig.done(MovePose{t.pose, t.path, t.speed});
    // The arm stands where it was sent, by the project's kinematics (the emulator's inverse kinematics tolerance).
    expect_pose_near(rig.arm_pose(), t.pose, 0.01 + 1e-6, 1e-4 / kDeg + 1e-9, std::string(t.what) + " (the arm)");
    // And WH says so, to the protocol's resolution.
    const drivers::PositionReading reading = rig.read_back();
    ASSERT_TRUE(reading.tool_pose.has_value());
    EXPECT_TRUE(reading.joints.empty());  // WH reports no joints
    expect_pose_near(*reading.tool_pose, t.pose, kMovemasterMm, kMovemasterDeg, std::string(t.what) + " (WH)");
  }

  // Grip: GC closes the hand (with a force, GP first), GO opens it; a straight move with the hand closed keeps it
  // closed (the MS letter follows the last grip).
  rig.done(Grip{Grip::Action::close, std::nullopt, 10.0});
  EXPECT_EQ(rig.arm.gripper_opening(), 0.0);
  rig.done(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0), Path::linear, 1.0});
  EXPECT_EQ(rig.arm.gripper_opening(), 0.0) << "MS opened the closed hand";
  rig.done(Grip{Grip::Action::open, std::nullopt, std::nullopt});
  EXPECT_GT(rig.arm.gripper_opening(), 0.0);
  rig.done(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::linear, 1.0});
  EXPECT_GT(rig.arm.gripper_opening(), 0.0) << "MS closed the open hand";
  EXPECT_EQ(rig.emulator->stats().er_answers[1] + rig.emulator->stats().er_answers[2], 0u);
}

TEST(MovemasterAgainstEmulator, APoseOutOfReachFailsUnreachableAndTheDriverGoesOn) {
  MovemasterRig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const Eigen::Isometry3d near = five_axis(300.0, 0.0, 200.0, -90.0, 0.0);
  rig.done(MovePose{near, Path::joint, 1.0});
  const std::vector<double> before = rig.arm.joints();

  // Well within the 5-axis rule, but 1.5 m out: the emulator answers ER 2, joint and linear alike.
  for (const Path path : {Path::joint, Path::linear}) {
    const CommandStatus s =
        rig.finish(rig.driver->submit(MovePose{five_axis(1500.0, 0.0, 300.0, 0.0, 0.0), path, 1.0}));
    EXPECT_EQ(s.phase, CommandPhase::failed);
    EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
    EXPECT_EQ(rig.driver->state(), DriverState::active);
    EXPECT_EQ(rig.arm.joints(), before) << "the arm moved for an unreachable pose";
  }
  // Out of the vertical plane (yawed 20° about the vertical): the driver refuses it without sending it.
  Eigen::Isometry3d yawed = near;
  yawed.linear() = Eigen::AngleAxisd(20 * kDeg, Eigen::Vector3d::UnitZ()) * five_axis(300, 0, 200, 0, 0).linear();
  rig.read_back();  // answered after every line sent before it (the RS after ER 2) was taken
  const std::uint64_t lines = rig.emulator->stats().lines;
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{yawed, Path::joint, 1.0}));
  EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
  EXPECT_EQ(rig.emulator->stats().lines, lines);

  // The driver goes on: the next move works and reads back.
  const Eigen::Isometry3d next = five_axis(250.0, 150.0, 150.0, -90.0, 30.0);
  rig.done(MovePose{next, Path::linear, 1.0});
  expect_pose_near(*rig.read_back().tool_pose, next, kMovemasterMm, kMovemasterDeg, "after the unreachable ones");
}

// The lines the driver sends, counted from 1 as the emulator counts them: connect `ER` (1); home `NT` (2), `ER` (3);
// the first MovePose joint at speed 1: `SP 9` (4), `MP ...` (5), `ER` (6).
constexpr std::uint64_t kFirstMp = 5, kFirstMoveEr = 6;

TEST(MovemasterAgainstEmulator, EveryLineSettingOfTheDocAgrees) {
  namespace mm = drivers::movemaster;
  struct Setting {
    const char* what;
    mm::LineEnd host_end;
    const char* reply_end;
    drivers::MovemasterOptions::Completion completion;
    mm::Acceleration acceleration;
  };
  const Setting settings[] = {
      {"LF from the host, LF answers", mm::LineEnd::lf, "\n", drivers::MovemasterOptions::Completion::er,
       mm::Acceleration::high},
      {"CR from the host", mm::LineEnd::cr, "\r\n", drivers::MovemasterOptions::Completion::er, mm::Acceleration::low},
      {"completion by polling WH", mm::LineEnd::crlf, "\r\n", drivers::MovemasterOptions::Completion::poll,
       mm::Acceleration::none},
  };
  for (const Setting& setting : settings) {
    SCOPED_TRACE(setting.what);
    auto options = Movemaster::emulator_options();
    options.reply_line_end = setting.reply_end;
    MovemasterRig rig(std::move(options), [&](drivers::MovemasterOptions& o) {
      o.line_end = setting.host_end;
      o.completion = setting.completion;
      o.acceleration = setting.acceleration;
      o.poll_period = 10ms;
    });
    ASSERT_NO_FATAL_FAILURE(rig.bring_up());
    for (const Eigen::Isometry3d& pose :
         {five_axis(300.0, 0.0, 200.0, -90.0, 0.0), five_axis(350.0, 100.0, 200.0, -45.0, -60.0)}) {
      for (const Path path : {Path::joint, Path::linear}) {
        rig.done(MovePose{pose, path, 0.7});
        expect_pose_near(*rig.read_back().tool_pose, pose, kMovemasterMm, kMovemasterDeg, setting.what);
        rig.done(MovePose{five_axis(420.0, -150.0, 300.0, 0.0, 0.0), path, 1.0});
      }
    }
    EXPECT_EQ(rig.emulator->stats().format_errors, 0u);
  }
}

TEST(MovemasterAgainstEmulator, TheToolLengthSetAtConnectMovesTheToolPoint) {
  MovemasterRig rig({}, [](drivers::MovemasterOptions& o) { o.tool_length_mm = 100.0; });
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  for (const Eigen::Isometry3d& pose :
       {five_axis(300.0, 0.0, 300.0, -90.0, 0.0), five_axis(250.0, 150.0, 250.0, -90.0, 30.0)}) {
    rig.done(MovePose{pose, Path::joint, 1.0});
    // The chain's tip (the tool at TL 0, the emulator's nominal length) is 100 mm behind the tool point.
    Eigen::Isometry3d tip = pose;
    tip.translation() -= 0.1 * pose.linear().col(2);
    expect_pose_near(rig.arm_pose(), tip, 0.01 + 1e-6, 1e-4 / kDeg + 1e-9, "the chain's tip");
    expect_pose_near(*rig.read_back().tool_pose, pose, kMovemasterMm, kMovemasterDeg, "WH with TL 100");
  }
}

TEST(MovemasterAgainstEmulator, ErOneIsAHardwareFaultThatResetAndHomeClear) {
  MovemasterRig rig([] {
    auto o = Movemaster::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::error, kFirstMp)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const std::vector<double> home = rig.arm.joints();
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0)}));
  EXPECT_EQ(s.error, ErrorCode::hardware) << s.message;
  EXPECT_NE(s.message.find("ER answered 1"), std::string::npos) << s.message;
  EXPECT_EQ(rig.arm.joints(), home);
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
  const Eigen::Isometry3d pose = five_axis(300.0, 0.0, 200.0, -90.0, 0.0);
  rig.done(MovePose{pose});
  expect_pose_near(*rig.read_back().tool_pose, pose, kMovemasterMm, kMovemasterDeg, "after reset");
  EXPECT_EQ(rig.emulator->stats().er_answers[1], 1u);
}

TEST(MovemasterAgainstEmulator, ErTwoFailsTheCommandUnreachableAndTheDriverGoesOn) {
  MovemasterRig rig([] {
    auto o = Movemaster::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::unreachable, kFirstMp)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const Eigen::Isometry3d pose = five_axis(300.0, 0.0, 200.0, -90.0, 0.0);
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{pose}));
  EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
  EXPECT_EQ(rig.driver->state(), DriverState::active);
  rig.done(MovePose{pose});
  expect_pose_near(*rig.read_back().tool_pose, pose, kMovemasterMm, kMovemasterDeg, "after ER 2");
}

TEST(MovemasterAgainstEmulator, GarbageIsAProtocolFaultQuotingTheBytes) {
  MovemasterRig rig([] {
    auto o = Movemaster::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::garbage, kFirstMoveEr)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0)}));
  EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
  // The emulator's garbage is "\x02#?\x7f~garbage\x1b": the message quotes it, the control bytes escaped.
  EXPECT_NE(s.message.find("\\x02#?\\x7f~garbage\\x1b"), std::string::npos) << s.message;
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
  rig.done(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::linear, 1.0});
}

TEST(MovemasterAgainstEmulator, SilenceFaultsWithinTheDriversDeadline) {
  MovemasterRig rig([] {
    auto o = Movemaster::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::silent, kFirstMoveEr)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const auto start = Steady::now();
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0)}));
  const auto took = Steady::now() - start;
  EXPECT_EQ(s.error, ErrorCode::connection_lost) << s.message;
  EXPECT_NE(s.message.find("silent"), std::string::npos) << s.message;
  // The deadline of the ER after a motion at level 9: longest_motion × 10 / 10 plus reply_timeout.
  const auto& o = rig.driver->options();
  EXPECT_GE(took, o.serial.reply_timeout);
  EXPECT_LT(took, o.longest_motion + o.serial.reply_timeout + 1s);
  // Silence is taken for a lost link: reset() leaves the driver disconnected, and it connects again to the same line.
  ASSERT_NO_FATAL_FAILURE(expect_reconnect(rig, 1));
  ASSERT_NO_FATAL_FAILURE(rig.home_and_activate());
  rig.done(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0)});
}

TEST(MovemasterAgainstEmulator, ADropIsConnectionLostAndTheDriverConnectsToTheNewLine) {
  // Line 7 is the `WH` of the read-back after the first move.
  MovemasterRig rig([] {
    auto o = Movemaster::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::drop, kFirstMoveEr + 1)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const Eigen::Isometry3d pose = five_axis(300.0, 0.0, 200.0, -90.0, 0.0);
  rig.done(MovePose{pose});
  const std::vector<double> there = rig.arm.joints();
  const CommandStatus s = rig.finish(rig.driver->request_position());
  EXPECT_EQ(s.error, ErrorCode::connection_lost) << s.message;
  ASSERT_NO_FATAL_FAILURE(expect_reconnect(rig, 2));
  // The controller kept its arm where it was: nothing moved over the drop and the reconnect.
  EXPECT_EQ(rig.arm.joints(), there);
  ASSERT_NO_FATAL_FAILURE(rig.home_and_activate());
  rig.done(MovePose{pose, Path::linear, 1.0});
  expect_pose_near(*rig.read_back().tool_pose, pose, kMovemasterMm, kMovemasterDeg, "after the reconnect");
}

TEST(MovemasterAgainstEmulator, TimingCountsTheBytesOnTheLine) {
  // The emulator's log names every line it took and every answer it gave; with CR LF both ways, each is its text and
  // two bytes.
  std::mutex mutex;
  std::vector<std::string> log;
  auto options = Movemaster::emulator_options();
  options.log = [&](std::string_view line) {
    std::lock_guard lock(mutex);
    log.emplace_back(line);
  };
  MovemasterRig rig(std::move(options));
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const drivers::SerialTiming before = rig.driver->timing();
  std::size_t from = 0;
  {
    std::lock_guard lock(mutex);
    from = log.size();
  }
  rig.done(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0), Path::joint, 0.5});
  rig.done(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::linear, 0.5});
  rig.done(Grip{Grip::Action::close, std::nullopt, 5.0});
  rig.read_back();
  const drivers::SerialTiming after = rig.driver->timing();

  std::size_t in = 0, out = 0, lines = 0;
  {
    std::lock_guard lock(mutex);
    for (std::size_t i = from; i < log.size(); ++i) {
      if (log[i].starts_with("< ")) {
        in += log[i].size() - 2 + 2;
        ++lines;
      } else if (log[i].starts_with("> ")) {
        out += log[i].size() - 2 + 2;
      }
    }
  }
  EXPECT_EQ(after.jobs - before.jobs, 4u);
  EXPECT_EQ(after.bytes_sent - before.bytes_sent, in);
  EXPECT_EQ(after.bytes_received - before.bytes_received, out);
  // SP, MP, ER; PD, MS, ER; GP, GC, ER; WH.
  EXPECT_EQ(lines, 10u);
  // Wire time at 7E2: 11 bits a character.
  const auto& last = after.recent.back();
  EXPECT_EQ(last.what, "position");
  EXPECT_NEAR(std::chrono::duration<double>(last.wire_sent).count(),
              static_cast<double>(last.bytes_sent) * 11.0 / 115200.0, 1e-6);
  EXPECT_NEAR(std::chrono::duration<double>(last.wire_received).count(),
              static_cast<double>(last.bytes_received) * 11.0 / 115200.0, 1e-6);
}

// ---- VAL II --------------------------------------------------------------------------------------------------------

using Val2Rig = Rig<Val2>;

// A VAL II read-back agrees to WHERE's resolution: 0.01 mm (half of it) and 0.001° (half), plus what TRANS's three
// decimals round (0.0005 mm and 0.0005° a value) and the emulator's inverse kinematics tolerance (1 µm, 1 µrad).
constexpr double kVal2Mm = std::numbers::sqrt3 * (0.005 + 0.0005 + 0.001) + 1e-9;
constexpr double kVal2Deg = 3 * (0.0005 + 0.0005 + 1e-6 / kDeg) + 1e-9;
constexpr double kVal2JointDeg = 0.0005 + 0.0005 + 1e-9;  // #PPOINT's and WHERE's three decimals

Eigen::Isometry3d forward(const KinematicArm& arm, const std::vector<double>& q) {
  return arm.chain().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
}

void expect_joints_near(const std::vector<double>& got, const std::vector<double>& want, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (std::size_t j = 0; j < got.size(); ++j) {
    EXPECT_NEAR(got[j] / kDeg, want[j] / kDeg, kVal2JointDeg) << what << ", joint " << j + 1;
  }
}

// Joint vectors of the PUMA well inside its limits and away from its singularities; their tool poses are the pose
// targets (so they are reachable, whatever the arm's configuration when they are sent).
const std::vector<double> kQ1 = {0.3, 0.5, -1.0, 0.4, 0.6, 0.2};
const std::vector<double> kQ2 = {-0.4, 0.8, -1.6, -0.3, 0.9, -0.5};
const std::vector<double> kQ3 = {0.1, 0.3, -0.7, 0.9, -0.8, 1.2};

TEST(Val2AgainstEmulator, ConnectsHomesMovesGripsAndReadsBackWhatWasSent) {
  Val2Rig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  EXPECT_EQ(rig.arm.joints(), rig.arm.home());

  // MoveJoints: #PPOINT; WHERE's joints are the ones sent, and its world values are the project's kinematics of them.
  rig.done(MoveJoints{kQ1, 1.0});
  expect_joints_near(rig.arm.joints(), kQ1, "the arm after MoveJoints");
  drivers::PositionReading r = rig.read_back();
  expect_joints_near(r.joints, kQ1, "WHERE after MoveJoints");
  ASSERT_TRUE(r.tool_pose.has_value());
  expect_pose_near(*r.tool_pose, forward(rig.arm, kQ1), kVal2Mm, kVal2Deg, "WHERE's world after MoveJoints");

  // MovePose, joint-interpolated (MOVE TRANS) and straight (MOVES TRANS), at several speeds.
  struct Target {
    const char* what;
    std::vector<double> q;
    Path path;
    double speed;
  };
  for (const Target& t : {Target{"MOVE", kQ2, Path::joint, 0.5}, Target{"MOVES", kQ3, Path::linear, 1.0},
                          Target{"MOVE back", kQ1, Path::joint, 0.25}, Target{"MOVES back", kQ2, Path::linear, 0.8}}) {
    const Eigen::Isometry3d pose = forward(rig.arm, t.q);
    rig.done(MovePose{pose, t.path, t.speed});
    expect_pose_near(rig.arm_pose(), pose, 0.001 + 0.0005 * std::numbers::sqrt3, 1e-6 / kDeg + 0.0015,
                     std::string(t.what) + " (the arm)");
    r = rig.read_back();
    ASSERT_TRUE(r.tool_pose.has_value());
    expect_pose_near(*r.tool_pose, pose, kVal2Mm, kVal2Deg, std::string(t.what) + " (WHERE)");
    expect_joints_near(r.joints, rig.arm.joints(), std::string(t.what) + " (WHERE's joints)");
  }

  // Grip, output, input.
  rig.done(Grip{Grip::Action::close, std::nullopt, std::nullopt});
  EXPECT_EQ(rig.arm.gripper_opening(), 0.0);
  rig.done(Grip{Grip::Action::open, std::nullopt, std::nullopt});
  EXPECT_GT(rig.arm.gripper_opening(), 0.0);
  rig.done(drivers::SetOutput{7, true});
  EXPECT_TRUE(rig.arm.outputs().at(6));
  rig.done(drivers::SetOutput{7, false});
  EXPECT_FALSE(rig.arm.outputs().at(6));
  rig.arm.set_input(5, true);
  rig.done(drivers::WaitInput{5, true, 1s});
  EXPECT_EQ(rig.emulator->stats().errors, 0u) << rig.emulator->stats().last_error;
}

TEST(Val2AgainstEmulator, APoseOutOfReachFailsUnreachableAndTheDriverGoesOn) {
  Val2Rig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  rig.done(MoveJoints{kQ1, 1.0});
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(3.0, 0.0, 0.5);
  for (const Path path : {Path::joint, Path::linear}) {
    const CommandStatus s = rig.finish(rig.driver->submit(MovePose{far, path, 1.0}));
    EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
    EXPECT_EQ(rig.driver->state(), DriverState::active);
  }
  // A precision point beyond joint 5's limits: `*Joint 5 limit stop*`.
  std::vector<double> beyond = kQ1;
  beyond[4] = 2.5;
  const CommandStatus s = rig.finish(rig.driver->submit(MoveJoints{beyond, 1.0}));
  EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
  expect_joints_near(rig.arm.joints(), kQ1, "after the unreachable ones");
  const Eigen::Isometry3d pose = forward(rig.arm, kQ2);
  rig.done(MovePose{pose, Path::linear, 1.0});
  expect_pose_near(*rig.read_back().tool_pose, pose, kVal2Mm, kVal2Deg, "after the unreachable ones");
}

// The lines the VAL II driver sends, counted from 1 as the emulator counts them: connect, an empty line (1); home,
// `DO READY` (2); the first motion at a new speed: `SPEED n` (3), `DO MOVE ...` (4); its read-back `WHERE` (5).
constexpr std::uint64_t kFirstMove = 4;

TEST(Val2AgainstEmulator, AnErrorLineIsAHardwareFaultThatResetAndHomeClear) {
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::error, kFirstMove)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const CommandStatus s = rig.finish(rig.driver->submit(MoveJoints{kQ1, 1.0}));
  EXPECT_EQ(s.error, ErrorCode::hardware) << s.message;
  EXPECT_NE(s.message.find("*Arm power off*"), std::string::npos) << s.message;
  EXPECT_EQ(rig.arm.joints(), rig.arm.home());
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
  rig.done(MoveJoints{kQ1, 1.0});
  expect_joints_near(rig.read_back().joints, kQ1, "after reset");
}

TEST(Val2AgainstEmulator, AnOutOfRangeLineFailsTheCommandUnreachableAndTheDriverGoesOn) {
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::unreachable, kFirstMove)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const Eigen::Isometry3d pose = forward(rig.arm, kQ2);
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{pose, Path::linear, 1.0}));
  EXPECT_EQ(s.error, ErrorCode::unreachable) << s.message;
  EXPECT_EQ(rig.driver->state(), DriverState::active);
  rig.done(MovePose{pose, Path::linear, 1.0});
  expect_pose_near(*rig.read_back().tool_pose, pose, kVal2Mm, kVal2Deg, "after the error line");
}

TEST(Val2AgainstEmulator, GarbageIsAProtocolFaultQuotingTheBytes) {
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::garbage, kFirstMove + 1)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  rig.done(MoveJoints{kQ1, 1.0});
  const CommandStatus s = rig.finish(rig.driver->request_position());
  EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
  // The garbage is bytes 0x80-0xFE: the message quotes them escaped.
  EXPECT_NE(s.message.find("'\\x"), std::string::npos) << s.message;
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
  rig.done(MoveJoints{kQ2, 1.0});
  expect_joints_near(rig.read_back().joints, kQ2, "after reset");
}

TEST(Val2AgainstEmulator, SilenceFaultsWithinTheDriversDeadline) {
  // Line 5: the first grip, `DO CLOSEI`, whose deadline is reply_timeout.
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::silent, kFirstMove + 1)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  rig.done(MoveJoints{kQ1, 1.0});
  const auto start = Steady::now();
  const CommandStatus s = rig.finish(rig.driver->submit(Grip{Grip::Action::close, std::nullopt, std::nullopt}));
  const auto took = Steady::now() - start;
  EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
  EXPECT_GE(took, rig.driver->options().serial.reply_timeout);
  EXPECT_LT(took, rig.driver->options().serial.reply_timeout + 1s);
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
  rig.done(Grip{Grip::Action::close, std::nullopt, std::nullopt});
  EXPECT_EQ(rig.arm.gripper_opening(), 0.0);
}

TEST(Val2AgainstEmulator, SilenceDuringAMotionFaultsWithinTheMotionsDeadline) {
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::silent, kFirstMove)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const auto start = Steady::now();
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{forward(rig.arm, kQ1), Path::joint, 1.0}));
  const auto took = Steady::now() - start;
  EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
  // A joint-interpolated pose move's bound: the slowest joint's whole travel at full speed, plus motion_margin.
  const auto& o = rig.driver->options();
  double worst = 0;
  for (std::size_t j = 0; j < 6; ++j) worst = std::max(worst, o.joint_travel[j] / o.max_joint_speed[j]);
  EXPECT_LT(took, std::chrono::duration<double>(worst) + o.motion_margin + 1s);
  ASSERT_NO_FATAL_FAILURE(expect_reset_and_home(rig));
}

TEST(Val2AgainstEmulator, ADropIsConnectionLostAndTheDriverConnectsToTheNewLine) {
  Val2Rig rig([] {
    auto o = Val2::emulator_options();
    o.misbehaviours = {at(MisbehaviourKind::drop, kFirstMove + 1)};
    return o;
  }());
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  rig.done(MoveJoints{kQ1, 1.0});
  const CommandStatus s = rig.finish(rig.driver->request_position());
  EXPECT_EQ(s.error, ErrorCode::connection_lost) << s.message;
  ASSERT_NO_FATAL_FAILURE(expect_reconnect(rig, 2));
  expect_joints_near(rig.arm.joints(), kQ1, "over the drop");
  ASSERT_NO_FATAL_FAILURE(rig.home_and_activate());
  rig.done(MoveJoints{kQ2, 1.0});
  expect_joints_near(rig.read_back().joints, kQ2, "after the reconnect");
}

TEST(Val2AgainstEmulator, TimingCountsTheBytesOnTheLine) {
  Val2Rig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  // After the home's prompt the line is quiet: from here each side's counts must move together.
  const drivers::SerialTiming before = rig.driver->timing();
  const emulate::Val2Emulator::Stats at_start = rig.emulator->stats();
  rig.done(MoveJoints{kQ1, 0.5});
  rig.done(MovePose{forward(rig.arm, kQ2), Path::linear, 0.5});
  rig.done(Grip{Grip::Action::close, std::nullopt, std::nullopt});
  rig.read_back();
  const drivers::SerialTiming after = rig.driver->timing();
  EXPECT_EQ(after.jobs - before.jobs, 4u);
  EXPECT_EQ(after.bytes_sent - before.bytes_sent, rig.emulator->stats().bytes_in - at_start.bytes_in);
  // The emulator counts what it wrote just after writing it: the driver may have read it (and ended the job) first.
  const std::size_t received = after.bytes_received - before.bytes_received;
  const auto deadline = Steady::now() + kHang;
  while (rig.emulator->stats().bytes_out - at_start.bytes_out < received && Steady::now() < deadline) {
    std::this_thread::yield();
  }
  // ... and the other way round: the prompt it writes after an answer may still be on its way when the driver has
  // ended the job on the answer (the next job reads it). Everything the driver read was written; at most the prompt
  // (a '.' and its line end) was not read yet.
  const std::size_t written = rig.emulator->stats().bytes_out - at_start.bytes_out;
  EXPECT_GE(written, received);
  EXPECT_LE(written - received, 3u) << written << " written, " << received << " received";
  // Wire time at 8N1: 10 bits a character.
  const auto& last = after.recent.back();
  EXPECT_NEAR(std::chrono::duration<double>(last.wire_sent).count(),
              static_cast<double>(last.bytes_sent) * 10.0 / 115200.0, 1e-6);
  EXPECT_NEAR(std::chrono::duration<double>(last.wire_received).count(),
              static_cast<double>(last.bytes_received) * 10.0 / 115200.0, 1e-6);
}

TEST(Val2AgainstEmulator, EveryLineSettingOfTheDocAgrees) {
  struct Setting {
    const char* what;
    bool echo;
    drivers::Val2LineEnd end;
  };
  for (const Setting& setting : {Setting{"no echo", false, drivers::Val2LineEnd::cr},
                                 Setting{"CR LF from the host", true, drivers::Val2LineEnd::crlf},
                                 Setting{"LF from the host, no echo", false, drivers::Val2LineEnd::lf}}) {
    SCOPED_TRACE(setting.what);
    auto options = Val2::emulator_options();
    options.echo = setting.echo;
    Val2Rig rig(std::move(options), [&](drivers::Val2Options& o) { o.line_end = setting.end; });
    ASSERT_NO_FATAL_FAILURE(rig.bring_up());
    rig.done(MoveJoints{kQ1, 0.6});
    expect_joints_near(rig.read_back().joints, kQ1, setting.what);
    const Eigen::Isometry3d pose = forward(rig.arm, kQ3);
    rig.done(MovePose{pose, Path::linear, 1.0});
    expect_pose_near(*rig.read_back().tool_pose, pose, kVal2Mm, kVal2Deg, setting.what);
    rig.done(Grip{Grip::Action::close, std::nullopt, std::nullopt});
    rig.done(drivers::SetOutput{32, true});
    EXPECT_TRUE(rig.arm.outputs().at(31));
    EXPECT_EQ(rig.emulator->stats().errors, 0u) << rig.emulator->stats().last_error;
  }
}

// A monitor that follows VAL's published conventions (O, A, T all zero: the hand along −Y, the fingers horizontal),
// its world at the shoulder and its tool point at the flange (docs/real-robots.md, "Commissioning"): a driver told the
// same settings sends poses that arrive where they were meant and reads back what the kinematics say; a driver on the
// page's defaults reads back a pose 671.83 mm and tens of degrees away.
TEST(Val2AgainstEmulator, AMonitorWithValsConventionsAgreesWithADriverGivenTheSameSettings) {
  auto options = Val2::emulator_options();
  options.orientation = emulate::Val2EmulatorOptions::Orientation::val;
  options.world.translation() = Eigen::Vector3d(0, 0, 0.67183);
  options.tool.translation() = Eigen::Vector3d(0, 0, -0.146);
  Val2Rig rig(options, [](drivers::Val2Options& o) {
    o.orientation = drivers::val2::Orientation::val;
    o.frames.world.translation() = Eigen::Vector3d(0, 0, 0.67183);
    o.frames.tool.translation() = Eigen::Vector3d(0, 0, -0.146);
  });
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  for (const auto& q : {kQ1, kQ2, kQ3}) {
    const Eigen::Isometry3d pose = forward(rig.arm, q);
    rig.done(MovePose{pose, Path::joint, 1.0});
    // The tool point 146 mm from the TCP turns the angles' rounding (0.001° sent, 0.001° read) into up to 4 µm.
    expect_pose_near(rig.arm_pose(), pose, 0.01, 0.003, "the arm");
    const drivers::PositionReading r = rig.read_back();
    ASSERT_TRUE(r.tool_pose.has_value());
    expect_pose_near(*r.tool_pose, forward(rig.arm, r.joints), kVal2Mm + 0.01, kVal2Deg, "WHERE's world");
    ASSERT_TRUE(rig.driver->last_location().has_value());
    // What the monitor printed is in its own frame: the tool point at the flange, the height from the shoulder.
    const Eigen::Vector3d flange = (pose * Eigen::Vector3d(0, 0, -0.146)) * 1000.0;
    EXPECT_NEAR(rig.driver->last_location()->z, flange.z() - 671.83, 0.02);
  }

  Val2Rig plain(options);  // the driver on the page's defaults
  ASSERT_NO_FATAL_FAILURE(plain.bring_up());
  plain.done(MoveJoints{kQ1, 1.0});
  const drivers::PositionReading r = plain.read_back();
  const Eigen::Isometry3d fk = forward(plain.arm, r.joints);
  EXPECT_GT((r.tool_pose->translation() - fk.translation()).norm(), 0.5);
  EXPECT_GT(degrees_between(r.tool_pose->linear(), fk.linear()), 10.0);
}

// The Movemaster's settings on both sides: a world frame turned and raised, p read with +90 down, roll left-handed.
TEST(MovemasterAgainstEmulator, AControllerWithOtherConventionsAgreesWithADriverGivenTheSameSettings) {
  auto options = Movemaster::emulator_options();
  options.world.translation() = Eigen::Vector3d(0, 0, 0.3);
  options.world.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  options.pitch_down_deg = 90;
  options.roll_sense = -1;
  MovemasterRig rig(options, [&](drivers::MovemasterOptions& o) {
    o.frames.world = options.world;
    o.pitch_down_deg = 90;
    o.roll_sense = -1;
  });
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  // In the turned frame the numbers sent (one decimal) no longer fall on the pose's own grid: each is off by up to
  // 0.05 mm or 0.05°, and so is each read back.
  for (const Eigen::Isometry3d& pose :
       {five_axis(300.0, 0.0, 200.0, -90.0, 0.0), five_axis(350.0, 100.0, 200.0, -45.0, -60.0)}) {
    rig.done(MovePose{pose, Path::joint, 1.0});
    expect_pose_near(rig.arm_pose(), pose, 2 * kMovemasterMm, 2 * kMovemasterDeg, "the arm");
    expect_pose_near(*rig.read_back().tool_pose, pose, 4 * kMovemasterMm, 4 * kMovemasterDeg, "WH");
  }
  // Straight down reads p = +90 on this controller.
  rig.done(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0), Path::joint, 1.0});
  rig.read_back();
  ASSERT_TRUE(rig.driver->last_wh().has_value());
  EXPECT_NEAR(rig.driver->last_wh()->p, 90.0, 0.1);
}

TEST(Val2AgainstEmulator, AWaitForAnInputThatTimesOutHoldsTheNextCommandUntilTheMonitorIsDone) {
  Val2Rig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const CommandStatus s = rig.finish(rig.driver->submit(drivers::WaitInput{3, true, 100ms}));
  EXPECT_EQ(s.error, ErrorCode::timeout) << s.message;
  EXPECT_EQ(rig.driver->state(), DriverState::active);
  // The monitor still waits: the next command is not sent while its prompt is owed, and fails with timeout.
  const std::uint64_t lines = rig.emulator->stats().lines;
  const CommandStatus next = rig.finish(rig.driver->submit(MoveJoints{kQ1, 1.0}));
  EXPECT_EQ(next.error, ErrorCode::timeout) << next.message;
  EXPECT_EQ(rig.emulator->stats().lines, lines);
  EXPECT_EQ(rig.arm.joints(), rig.arm.home());
  // The input comes: the monitor finishes the wait, and the next command goes out and runs.
  rig.arm.set_input(3, true);
  rig.done(MoveJoints{kQ1, 1.0});
  expect_joints_near(rig.read_back().joints, kQ1, "after the wait");
}

// ---- Random misbehaviour -------------------------------------------------------------------------------------------

// Brings the driver back to active as a user would after failures (reset(); connect() again when the link dropped;
// home; activate), checking each failure on the way with `check`. False (a test failure) if that takes longer than
// `within`: the pair hung.
template <typename Pair>
bool bring_back(Rig<Pair>& rig, const std::function<void(const CommandStatus&, const std::string&)>& check,
                const std::function<void()>& on_homed = {}, std::chrono::nanoseconds within = 2 * kHang) {
  const auto deadline = Steady::now() + within;
  for (;;) {
    if (Steady::now() > deadline) {
      ADD_FAILURE() << "the driver did not come back within " << std::chrono::duration<double>(within).count()
                    << " s; it is " << to_string(rig.driver->state());
      return false;
    }
    switch (rig.driver->state()) {
      case DriverState::active:
        return true;
      case DriverState::fault:
        rig.driver->reset();
        break;
      case DriverState::disconnected:
        // A drop: the emulator publishes a fresh line after its reconnect delay; a greeting may misbehave too.
        try {
          if (rig.driver->connect() == ErrorCode::none) break;
          check(CommandStatus{0, CommandPhase::failed, ErrorCode::connection_lost, rig.driver->connect_problem()},
                "connect");
        } catch (const InputError&) {
          // The path is gone until the emulator publishes again (Movemaster): wait for that, within a deadline.
        }
        rig.emulator->wait_published(Pair::publications(*rig.emulator) + 1, 100ms);
        break;
      case DriverState::connected:
      case DriverState::stopped: {
        const CommandStatus h = rig.finish(rig.driver->home());
        check(h, "home");
        if (h.phase == CommandPhase::done && on_homed) on_homed();
        break;
      }
      case DriverState::homed:
        EXPECT_EQ(rig.driver->activate(), ErrorCode::none);
        break;
    }
  }
}

// Drives `rig` through `commands` commands (every fifth a position read-back) while the emulator misbehaves at
// random, bringing the driver back after each failure. Nothing may hang, and every failure must be one of `allowed`.
// Returns how many calls failed.
template <typename Pair>
int random_run(Rig<Pair>& rig, int commands, const std::set<ErrorCode>& allowed,
               const std::function<drivers::Command(int)>& command_at) {
  int failed = 0;
  const auto check = [&](const CommandStatus& s, const std::string& what) {
    if (s.phase == CommandPhase::failed) {
      ++failed;
      EXPECT_TRUE(allowed.contains(s.error)) << what << " failed with " << to_string(s.error) << ": " << s.message;
      EXPECT_FALSE(s.message.empty()) << what;
    }
  };
  for (int i = 1; i <= commands; ++i) {
    if (!bring_back(rig, check)) break;
    if (i % 5 == 0) {
      check(rig.finish(rig.driver->request_position()), "position");
    } else {
      const drivers::Command c = command_at(i);
      check(rig.finish(rig.driver->submit(c)), drivers::describe(c));
    }
  }
  return failed;
}

// Each kind at 1 % a line: about 5 % of the lines misbehave.
std::vector<Misbehaviour> random_misbehaviours() {
  return {random(MisbehaviourKind::error, 0.01),   random(MisbehaviourKind::unreachable, 0.01),
          random(MisbehaviourKind::garbage, 0.01), random(MisbehaviourKind::silent, 0.01),
          random(MisbehaviourKind::drop, 0.01),    random(MisbehaviourKind::late, 0.01, 20ms)};
}

TEST(MovemasterAgainstEmulator, ARandomRunOfMisbehavioursNeverHangsAndFailsOnlyAsTheDocAllows) {
  auto options = Movemaster::emulator_options();
  options.seed = 20240611;
  options.misbehaviours = random_misbehaviours();
  MovemasterRig rig(std::move(options), [](drivers::MovemasterOptions& o) { o.serial.reply_timeout = 250ms; });
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const Eigen::Isometry3d poses[] = {five_axis(300.0, 0.0, 200.0, -90.0, 0.0),
                                     five_axis(250.0, 150.0, 150.0, -90.0, 30.0),
                                     five_axis(420.0, -150.0, 300.0, 0.0, 0.0)};
  const int failed = random_run(
      rig, 60, {ErrorCode::unreachable, ErrorCode::hardware, ErrorCode::protocol, ErrorCode::connection_lost},
      [&](int i) -> drivers::Command {
        if (i % 7 == 3) return Grip{i % 2 ? Grip::Action::close : Grip::Action::open, std::nullopt, 8.0};
        return MovePose{poses[i % 3], i % 2 ? Path::linear : Path::joint, i % 4 ? 1.0 : 0.4};
      });
  const auto stats = rig.emulator->stats();
  std::uint64_t misbehaved = 0;
  for (const std::uint64_t n : stats.misbehaviours) misbehaved += n;
  EXPECT_GT(misbehaved, 0u);
  EXPECT_GT(failed, 0);
}

// Z-Y-Z angles are degenerate for a tool straight down (A = 0: O and T turn about the same axis), the commonest pose;
// the READY position is read back before any location was sent; and a slow speed stretches every motion (the
// driver's deadlines must still hold: a straight move's is estimated from the tool's travel, not the joints').
TEST(Val2AgainstEmulator, AToolStraightDownTheHomeAndSlowMotionsAgree) {
  Val2Rig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  drivers::PositionReading r = rig.read_back();
  expect_joints_near(r.joints, rig.arm.home(), "home");
  expect_pose_near(*r.tool_pose, rig.arm_pose(), kVal2Mm, kVal2Deg, "home pose");
  for (const auto& [x, y, z, turn] : {std::array{0.5, 0.1, 0.4, 0.0}, std::array{0.5, 0.1, 0.6, 30.0},
                                      std::array{0.4, -0.2, 0.5, -150.0}, std::array{0.6, 0.0, 0.5, 180.0}}) {
    Eigen::Isometry3d down = Eigen::Isometry3d::Identity();
    down.translation() = Eigen::Vector3d(x, y, z);
    down.linear() = (Eigen::AngleAxisd(turn * kDeg, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
    rig.done(MovePose{down, Path::joint, 1.0});
    expect_pose_near(rig.arm_pose(), down, 0.002, 0.002, fmt::format("tool down, turned {}°: the arm", turn));
    expect_pose_near(*rig.read_back().tool_pose, down, kVal2Mm, kVal2Deg,
                     fmt::format("tool down, turned {}°: WHERE", turn));
  }
  for (const double speed : {0.05}) {
    rig.done(MovePose{forward(rig.arm, kQ3), Path::linear, speed});
    rig.done(MovePose{forward(rig.arm, kQ2), Path::linear, speed});
    rig.done(MovePose{forward(rig.arm, kQ1), Path::joint, speed});
    rig.done(MoveJoints{kQ3, speed});
  }
}

// The nest (the tool point on the base's z axis: no azimuth, θ = 0 both sides) reads back as the arm stands; a roll
// of half a turn; slow motions (speed level 0: the driver's deadlines must still hold).
TEST(MovemasterAgainstEmulator, TheNestAHalfTurnRollAndSlowMotionsAgree) {
  MovemasterRig rig;
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  expect_pose_near(*rig.read_back().tool_pose, rig.arm_pose(), kMovemasterMm, kMovemasterDeg, "home");
  for (const double speed : {0.05}) {
    rig.done(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 180.0), Path::linear, speed});
    rig.done(MovePose{five_axis(420.0, -150.0, 300.0, 0.0, -90.0), Path::linear, speed});
    rig.done(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::joint, speed});
  }
  rig.done(drivers::MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 180.0), Path::joint, 1.0});
  expect_pose_near(*rig.read_back().tool_pose, five_axis(300.0, 0.0, 200.0, -90.0, 180.0), kMovemasterMm,
                   kMovemasterDeg, "r 180");
}

TEST(Val2AgainstEmulator, ARandomRunOfMisbehavioursNeverHangsAndFailsOnlyAsTheDocAllows) {
  auto options = Val2::emulator_options();
  options.seed = 20240611;
  options.misbehaviours = random_misbehaviours();
  Val2Rig rig(std::move(options), [](drivers::Val2Options& o) { o.serial.reply_timeout = 250ms; });
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const std::vector<double>* joints[] = {&kQ1, &kQ2, &kQ3};
  const int failed = random_run(
      rig, 60, {ErrorCode::unreachable, ErrorCode::hardware, ErrorCode::protocol, ErrorCode::connection_lost},
      [&](int i) -> drivers::Command {
        if (i % 7 == 3) return Grip{i % 2 ? Grip::Action::close : Grip::Action::open, std::nullopt, std::nullopt};
        const std::vector<double>& q = *joints[i % 3];
        if (i % 3 == 0) return MoveJoints{q, i % 4 ? 1.0 : 0.4};
        return MovePose{forward(rig.arm, q), i % 2 ? Path::linear : Path::joint, i % 4 ? 1.0 : 0.4};
      });
  EXPECT_GT(rig.emulator->stats().misbehaviours, 0u);
  EXPECT_GT(failed, 0);
}

// ---- Answers later than the deadline ------------------------------------------------------------------------------

// An answer that comes after the driver gave up on it arrives while the driver is getting back (reconnecting,
// resynchronising). Whatever the driver makes of it (a failed greeting, a protocol fault, bytes discarded), it must
// never take it for the answer to a later question: once back, a motion is done only when the arm is there, homing
// only when it is home, and a read-back says where the arm is.
template <typename Pair>
void expect_no_answer_taken_for_another(Rig<Pair>& rig, const std::vector<drivers::Command>& moves,
                                        const std::function<Eigen::Isometry3d(const drivers::Command&)>& target,
                                        const std::set<ErrorCode>& allowed) {
  const auto check = [&](const CommandStatus& s, const std::string& what) {
    if (s.phase == CommandPhase::failed) {
      EXPECT_TRUE(allowed.contains(s.error)) << what << " failed with " << to_string(s.error) << ": " << s.message;
    }
  };
  const auto at_home = [&] { EXPECT_EQ(rig.arm.joints(), rig.arm.home()) << "homing was done with the arm elsewhere"; };
  int done = 0;
  for (const drivers::Command& c : moves) {
    ASSERT_TRUE(bring_back(rig, check, at_home));
    const CommandStatus m = rig.finish(rig.driver->submit(c));
    check(m, drivers::describe(c));
    if (m.phase != CommandPhase::done) continue;
    ++done;
    expect_pose_near(rig.arm_pose(), target(c), 0.01 + 1e-6, 1e-4 / kDeg + 1e-9,
                     "the arm when " + drivers::describe(c) + " was done");
    const Submitted r = rig.driver->request_position();
    const CommandStatus rs = rig.finish(r);
    check(rs, "position");
    if (rs.phase == CommandPhase::done) {
      expect_pose_near(*rig.driver->last_position()->tool_pose, rig.arm_pose(), 0.1, 0.2, "the read-back");
    }
  }
  EXPECT_GT(done, 0) << "the driver never got back to work";
}

TEST(MovemasterAgainstEmulator, AnAnswerLaterThanTheDeadlineIsNeverTakenForAnother) {
  // The ER after the first move (level 9: deadline longest_motion + reply_timeout = 0.6 s) is answered after 0.8 s,
  // while the driver, having reset and connected again, waits for the answer to its greeting's ER.
  auto options = Movemaster::emulator_options();
  Misbehaviour late = at(MisbehaviourKind::late, kFirstMoveEr);
  late.delay = 800ms;
  options.misbehaviours = {late};
  MovemasterRig rig(std::move(options));
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  const CommandStatus s = rig.finish(rig.driver->submit(MovePose{five_axis(300.0, 0.0, 200.0, -90.0, 0.0)}));
  EXPECT_EQ(s.error, ErrorCode::connection_lost) << s.message;
  std::vector<drivers::Command> moves;
  for (int i = 0; i < 3; ++i) {
    moves.emplace_back(MovePose{five_axis(250.0, 150.0, 150.0, -90.0, 30.0), Path::joint, 1.0});
    moves.emplace_back(MovePose{five_axis(420.0, -150.0, 300.0, 0.0, 0.0), Path::joint, 1.0});
  }
  expect_no_answer_taken_for_another(rig, moves, [](const drivers::Command& c) { return std::get<MovePose>(c).pose; },
                                     {ErrorCode::protocol, ErrorCode::connection_lost});
}

TEST(Val2AgainstEmulator, AnAnswerLaterThanTheDeadlineIsNeverTakenForAnother) {
  // The first grip's prompt (deadline: reply_timeout, 0.5 s) comes after 0.7 s, while the driver resynchronises.
  auto options = Val2::emulator_options();
  Misbehaviour late = at(MisbehaviourKind::late, kFirstMove + 1);
  late.delay = 700ms;
  options.misbehaviours = {late};
  Val2Rig rig(std::move(options));
  ASSERT_NO_FATAL_FAILURE(rig.bring_up());
  rig.done(MoveJoints{kQ1, 1.0});
  const CommandStatus s = rig.finish(rig.driver->submit(Grip{Grip::Action::close, std::nullopt, std::nullopt}));
  EXPECT_EQ(s.error, ErrorCode::protocol) << s.message;
  std::vector<drivers::Command> moves;
  for (int i = 0; i < 3; ++i) {
    moves.emplace_back(MoveJoints{kQ2, 1.0});
    moves.emplace_back(MoveJoints{kQ3, 1.0});
  }
  expect_no_answer_taken_for_another(
      rig, moves, [&](const drivers::Command& c) { return forward(rig.arm, std::get<MoveJoints>(c).positions); },
      {ErrorCode::protocol});
}

}  // namespace
}  // namespace cellwright
