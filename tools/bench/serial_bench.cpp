// Serial driver benchmarks: each driver (Movemaster EX, VAL II) against its emulator over a real pseudo-terminal, in
// one process (the emulator serves on a thread; a KinematicArm with a tiny time scale makes motions cost next to
// nothing).
//  - Per command kind: the host's own processing time for the job (SerialExchange::processing: the job's time minus
//    what it spent blocked on pacing and on the line) against the job's wire time at 9600 baud (wire_sent +
//    wire_received, from the line settings). Target: processing <= 1 % of wire time. On a pseudo-terminal the bytes
//    arrive at once, so the wire time is computed, never waited for.
//  - Position read-back round trip: the wall time from request_position() to the reading being done, as the owner
//    sees it, through the pseudo-terminal (Movemaster `WH`, VAL II `WHERE`). Reads are spaced past the pacing window
//    so that the figure is the pty, the emulator and the driver, not the pacing rule.
// Reproduce pinned to one CPU: taskset -c 0 build/tools/serial_bench
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"

namespace {

using namespace cellwright;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using drivers::CommandId;
using drivers::CommandPhase;
using drivers::CommandStatus;
using drivers::ErrorCode;
using drivers::Submitted;

constexpr int kBaud = 9600;
// The pacing rule's processing time: small, so that the run is quick (the rule itself is tested in drivers_tests).
constexpr auto kPacing = 200us;
// Motions on the emulated arm take this fraction of their computed duration.
constexpr double kTimeScale = 1e-6;
constexpr int kCommandJobs = 60;  // jobs per command kind
constexpr int kReads = 600;       // position reads per driver
constexpr double kTargetPct = 1.0;

double deg(double d) {
  return d * std::numbers::pi / 180.0;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5)];
}

double us(std::chrono::nanoseconds t) {
  return static_cast<double>(t.count()) / 1e3;
}

// ---- The rig: an emulator on a pseudo-terminal, and the driver connected to it and homed ------------------------

enum class Robot { movemaster, val2 };

class Rig {
 public:
  explicit Rig(Robot robot) : robot_(robot) {
    dir_ = std::filesystem::temp_directory_path() / fmt::format("cw-serial-bench-{}", ::getpid());
    std::filesystem::create_directories(dir_);
    const std::filesystem::path link = dir_ / (robot == Robot::movemaster ? "movemaster" : "val2");
    const std::string urdf = std::string(models::models_dir()) +
                             (robot == Robot::movemaster ? "/urdf/melfa_rve2.urdf" : "/urdf/puma560.urdf");
    emulate::KinematicArmOptions arm_options;
    arm_options.time_scale = kTimeScale;
    arm_options.home = robot == Robot::movemaster ? std::vector<double>{deg(-90), deg(30), deg(60), 0, deg(60), 0}
                                                  : std::vector<double>{0, deg(90), deg(-90), 0, 0, 0};
    arm_ = std::make_unique<emulate::KinematicArm>(models::KinematicChain::from_urdf_file(urdf), arm_options);

    if (robot == Robot::movemaster) {
      start<emulate::MovemasterEmulator, drivers::MovemasterDriver>(link, emulate::MovemasterEmulatorOptions{},
                                                                    drivers::MovemasterOptions{});
    } else {
      start<emulate::Val2Emulator, drivers::Val2Driver>(link, emulate::Val2EmulatorOptions{}, drivers::Val2Options{});
    }
    server_ = std::thread([this] {
      try {
        serve_();
      } catch (const std::exception& e) {
        std::lock_guard lock(mutex_);
        serve_error_ = e.what();
      }
    });
    driver_->set_notifier([this] {
      {
        std::lock_guard lock(mutex_);
        ++events_;
      }
      cv_.notify_all();
    });
    if (!published_()) {
      problem_ = "the emulator did not publish its pseudo-terminal: " + serve_error();
      return;
    }
    try {  // the server thread runs: nothing may leave the constructor by an exception from here on
      if (driver_->connect() != ErrorCode::none) {
        problem_ = "connect: " + driver_->connect_problem();
        return;
      }
    } catch (const std::exception& e) {
      problem_ = std::string("connect: ") + e.what();
      return;
    }
    if (const auto s = run(driver_->home()); s.phase != CommandPhase::done) problem_ = "home: " + s.message;
  }

  ~Rig() {
    driver_->set_notifier({});
    driver_->disconnect();
    stop_();
    server_.join();
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }
  Rig(const Rig&) = delete;
  Rig& operator=(const Rig&) = delete;

  // Why the rig is not ready, or "".
  const std::string& problem() const { return problem_; }
  drivers::SerialDriver& driver() { return *driver_; }
  const drivers::SerialLine& line() const { return line_; }
  Robot robot() const { return robot_; }
  const models::KinematicChain& chain() const { return arm_->chain(); }

  // Waits (at most 30 s) until the job `s` accepted is done or failed; its status, failed when refused or late.
  CommandStatus run(const Submitted& s) {
    if (!s.accepted()) return {0, CommandPhase::failed, s.error, "refused: " + s.message};
    const auto deadline = Clock::now() + 30s;
    std::unique_lock lock(mutex_);
    for (;;) {
      const std::uint64_t seen = events_;
      CommandStatus status = driver_->poll(s.id);
      if (status.phase == CommandPhase::done || status.phase == CommandPhase::failed) return status;
      if (!cv_.wait_until(lock, deadline, [&] { return events_ != seen; })) {
        return {s.id, CommandPhase::failed, ErrorCode::timeout, "no outcome within 30 s"};
      }
    }
  }

  // The exchange the driver recorded for job `id` (recorded before its outcome is reported).
  drivers::SerialExchange exchange(CommandId id) const {
    const drivers::SerialTiming t = driver_->timing();
    for (auto it = t.recent.rbegin(); it != t.recent.rend(); ++it) {
      if (it->id == id) return *it;
    }
    CW_CHECK(false, "no exchange recorded for job {}", id);
    return {};
  }

 private:
  // Makes the emulator (served later by serve_) and the driver on `link`, at 9600 baud with the bench's pacing.
  template <typename Emulator, typename Driver, typename EmulatorOptions, typename DriverOptions>
  void start(const std::filesystem::path& link, EmulatorOptions emulator_options, DriverOptions o) {
    auto emulator = std::make_shared<Emulator>(*arm_, std::move(emulator_options));
    serve_ = [emulator, link] { emulator->serve(link); };
    stop_ = [emulator] { emulator->stop(); };
    published_ = [emulator] { return emulator->wait_published(1, 10s); };
    o.serial.line.port = link.string();
    o.serial.line.baud = kBaud;
    o.serial.processing_time = kPacing;
    line_ = o.serial.line;
    driver_ = std::make_unique<Driver>(std::move(o));
  }

  std::string serve_error() {
    std::lock_guard lock(mutex_);
    return serve_error_.empty() ? std::string("no reason given") : serve_error_;
  }

  Robot robot_;
  std::filesystem::path dir_;
  std::unique_ptr<emulate::KinematicArm> arm_;
  std::function<void()> serve_, stop_;
  std::function<bool()> published_;
  std::unique_ptr<drivers::SerialDriver> driver_;
  drivers::SerialLine line_;
  std::thread server_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t events_ = 0;
  std::string serve_error_, problem_;
};

// ---- What is reported --------------------------------------------------------------------------------------------

struct CommandRow {
  std::string driver, command;
  double bytes = 0, wire_ms = 0, processing_us = 0, processing_max_us = 0, pct = 0, pct_max = 0;
};
struct ReadRow {
  std::string driver, request;
  double median_us = 0, p99_us = 0, processing_us = 0, wire_ms = 0;
};
std::map<std::pair<int, int>, CommandRow> g_commands;  // by robot and command kind, in the order registered
std::map<int, ReadRow> g_reads;                        // by robot

void counters(benchmark::State& state, std::initializer_list<std::pair<const char*, double>> values) {
  for (const auto& [name, value] : values) state.counters[name] = value;
}

const char* name_of(Robot r) {
  return r == Robot::movemaster ? "Movemaster EX" : "VAL II";
}

// ---- The commands ------------------------------------------------------------------------------------------------

enum class Kind { home, move_pose_joint, move_pose_linear, grip, position, move_joints };

const char* name_of(Kind k) {
  switch (k) {
    case Kind::home:
      return "home";
    case Kind::move_pose_joint:
      return "MovePose joint";
    case Kind::move_pose_linear:
      return "MovePose linear";
    case Kind::grip:
      return "Grip open/close";
    case Kind::position:
      return "position read";
    case Kind::move_joints:
      return "MoveJoints";
  }
  return "?";
}

// Two reachable targets per robot, taken in turn so that every motion moves.
struct Targets {
  Eigen::Isometry3d pose[2];
  std::vector<double> joints[2];
};

Targets targets(const Rig& rig) {
  Targets t;
  if (rig.robot() == Robot::movemaster) {
    // Reachable MELFA poses (tool point mm, pitch, roll: the emulator's tests use them).
    t.pose[0] = drivers::movemaster::to_pose({300, 100, 200, -90, 0});
    t.pose[1] = drivers::movemaster::to_pose({350, -50, 350, -45, 30});
  } else {
    t.joints[0] = {0, deg(60), deg(-120), 0, deg(30), 0};
    t.joints[1] = {deg(30), deg(75), deg(-100), deg(10), deg(20), deg(15)};
    for (int i = 0; i < 2; ++i) {
      t.pose[i] = rig.chain().forward(Eigen::Map<const Eigen::VectorXd>(t.joints[i].data(), 6));
    }
  }
  return t;
}

Submitted submit(Rig& rig, Kind kind, const Targets& t, int i) {
  drivers::SerialDriver& d = rig.driver();
  switch (kind) {
    case Kind::home:
      return d.home();
    case Kind::position:
      return d.request_position();
    case Kind::move_pose_joint:
      return d.submit(drivers::MovePose{t.pose[i % 2], drivers::Path::joint, 1.0});
    case Kind::move_pose_linear:
      return d.submit(drivers::MovePose{t.pose[i % 2], drivers::Path::linear, 1.0});
    case Kind::grip:
      return d.submit(drivers::Grip{i % 2 == 0 ? drivers::Grip::Action::close : drivers::Grip::Action::open, {}, {}});
    case Kind::move_joints:
      return d.submit(drivers::MoveJoints{t.joints[i % 2], 1.0});
  }
  return {};
}

// One job per iteration; the exchange the driver recorded for it gives its processing and wire times. A warm-up job
// first (the first motion after homing sends SPEED/SP, the first Movemaster linear move a WH).
void BM_Command(benchmark::State& state, Robot robot, Kind kind) {
  Rig rig(robot);
  if (!rig.problem().empty()) {
    state.SkipWithError(rig.problem().c_str());
    return;
  }
  if (kind != Kind::home && kind != Kind::position && rig.driver().activate() != ErrorCode::none) {
    state.SkipWithError("activate() was refused");
    return;
  }
  const Targets t = targets(rig);
  int i = 0;
  if (const CommandStatus s = rig.run(submit(rig, kind, t, i++)); s.phase != CommandPhase::done) {
    state.SkipWithError(("warm-up job failed: " + s.message).c_str());
    return;
  }
  std::vector<double> processing, wire, pct, bytes;
  for (auto _ : state) {
    const Submitted sub = submit(rig, kind, t, i++);
    const CommandStatus s = rig.run(sub);
    if (s.phase != CommandPhase::done) {
      state.SkipWithError((std::string(name_of(kind)) + " failed: " + s.message).c_str());
      return;
    }
    const drivers::SerialExchange x = rig.exchange(sub.id);
    const auto w = x.wire_sent + x.wire_received;
    processing.push_back(us(x.processing));
    wire.push_back(us(w) / 1e3);
    pct.push_back(100.0 * static_cast<double>(x.processing.count()) / static_cast<double>(w.count()));
    bytes.push_back(static_cast<double>(x.bytes_sent + x.bytes_received));
  }
  CommandRow row{.driver = name_of(robot), .command = name_of(kind), .bytes = percentile(bytes, 0.5)};
  row.wire_ms = percentile(wire, 0.5);
  row.processing_us = percentile(processing, 0.5);
  row.processing_max_us = percentile(processing, 1.0);
  row.pct = percentile(pct, 0.5);
  row.pct_max = percentile(pct, 1.0);
  counters(state, {{"processing_us", row.processing_us},
                   {"processing_max_us", row.processing_max_us},
                   {"wire_ms", row.wire_ms},
                   {"processing_pct_of_wire", row.pct},
                   {"bytes", row.bytes}});
  g_commands[{static_cast<int>(robot), static_cast<int>(kind)}] = row;
}

// request_position() to its reading, wall time as the owner sees it. Each read starts after the pacing window of the
// previous line has passed (outside the timing), so that no pacing wait is in the figure.
void BM_ReadRoundTrip(benchmark::State& state, Robot robot) {
  Rig rig(robot);
  if (!rig.problem().empty()) {
    state.SkipWithError(rig.problem().c_str());
    return;
  }
  const auto gap = rig.line().wire_time(16) + kPacing;  // longer than `WH`'s or `WHERE`'s line plus the pacing
  std::vector<double> round_trip, processing, wire;
  for (auto _ : state) {
    std::this_thread::sleep_for(gap);
    const auto start = Clock::now();
    const Submitted sub = rig.driver().request_position();
    const CommandStatus s = rig.run(sub);
    const auto end = Clock::now();
    if (s.phase != CommandPhase::done) {
      state.SkipWithError(("position read failed: " + s.message).c_str());
      return;
    }
    state.SetIterationTime(std::chrono::duration<double>(end - start).count());
    const drivers::SerialExchange x = rig.exchange(sub.id);
    round_trip.push_back(us(end - start));
    processing.push_back(us(x.processing));
    wire.push_back(us(x.wire_sent + x.wire_received) / 1e3);
  }
  const ReadRow row{.driver = name_of(robot),
                    .request = robot == Robot::movemaster ? "WH" : "WHERE",
                    .median_us = percentile(round_trip, 0.5),
                    .p99_us = percentile(round_trip, 0.99),
                    .processing_us = percentile(processing, 0.5),
                    .wire_ms = percentile(wire, 0.5)};
  counters(state, {{"round_trip_us", row.median_us},
                   {"round_trip_p99_us", row.p99_us},
                   {"processing_us", row.processing_us},
                   {"wire_ms", row.wire_ms}});
  g_reads[static_cast<int>(robot)] = row;
}

void register_all() {
  const std::pair<Robot, std::vector<Kind>> plan[] = {
      {Robot::movemaster, {Kind::home, Kind::move_pose_joint, Kind::move_pose_linear, Kind::grip, Kind::position}},
      {Robot::val2,
       {Kind::home, Kind::move_joints, Kind::move_pose_joint, Kind::move_pose_linear, Kind::grip, Kind::position}},
  };
  for (const auto& [robot, kinds] : plan) {
    const std::string prefix = robot == Robot::movemaster ? "Movemaster" : "Val2";
    for (const Kind kind : kinds) {
      std::string name = fmt::format("BM_{}/{}", prefix, name_of(kind));
      std::replace(name.begin(), name.end(), ' ', '_');
      benchmark::RegisterBenchmark(name.c_str(), BM_Command, robot, kind)
          ->Iterations(kCommandJobs)
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond);
    }
    benchmark::RegisterBenchmark(fmt::format("BM_{}/read_round_trip", prefix).c_str(), BM_ReadRoundTrip, robot)
        ->Iterations(kReads)
        ->UseManualTime()
        ->Unit(benchmark::kMicrosecond);
  }
}

void print_table() {
  if (g_commands.empty() && g_reads.empty()) return;
  fmt::print(
      "\nPer command: host processing vs wire time at {} baud (computed: a pty delivers at once); target <= "
      "{:.0f} %; medians of {} jobs\n",
      kBaud, kTargetPct, kCommandJobs);
  fmt::print("{:<14} {:<16} {:>6} {:>9} {:>14} {:>13} {:>10} {:>9}  {}\n", "driver", "command", "bytes", "wire ms",
             "processing us", "(max) us", "% of wire", "(max) %", "verdict");
  for (const auto& [key, r] : g_commands) {
    fmt::print("{:<14} {:<16} {:>6.0f} {:>9.2f} {:>14.1f} {:>13.1f} {:>10.3f} {:>9.3f}  {}\n", r.driver, r.command,
               r.bytes, r.wire_ms, r.processing_us, r.processing_max_us, r.pct, r.pct_max,
               r.pct <= kTargetPct ? "ok" : "OVER");
  }
  if (!g_reads.empty()) {
    fmt::print(
        "\nPosition read-back round trip through the pty, request_position() to done ({} reads, spaced past "
        "the pacing window)\n",
        kReads);
    fmt::print("{:<14} {:<8} {:>12} {:>10} {:>15} {:>20}\n", "driver", "request", "median us", "p99 us",
               "processing us", "wire ms (9600 baud)");
    for (const auto& [key, r] : g_reads) {
      fmt::print("{:<14} {:<8} {:>12.1f} {:>10.1f} {:>15.1f} {:>20.2f}\n", r.driver, r.request, r.median_us, r.p99_us,
                 r.processing_us, r.wire_ms);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  fmt::print(
      "serial_bench: per command, the serial drivers' host processing time (SerialExchange::processing) against the "
      "job's wire time at {} baud, target <= {:.0f} %, and the round trip of a position read (WH / WHERE); each "
      "driver against its emulator over a real pseudo-terminal in this process. Wire time is computed from the line "
      "settings (a pty delivers at once; nothing waits for it). Pin it: taskset -c 0 build/tools/serial_bench\n",
      kBaud, kTargetPct);
  std::fflush(stdout);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  register_all();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  print_table();
  return 0;
}
