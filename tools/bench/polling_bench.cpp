// Position reads on a 9600-baud line (docs/real-robots.md, "The serial line"): robot control of the PUMA over the
// VAL II driver, against the VAL II emulator paced as a real 9600-baud line (emulate/line_pace.hpp: its answers reach
// the driver one character time apart, 10 bits a character, and it takes a line once its last byte would have
// arrived), over a pseudo-terminal, in real time, in one process. Each run: bring-up, idle for --idle seconds, then
// --motions motions (above A and home in turn), each sent after an idle gap (seeded, 0.3 to 1.3 s, so that motions
// become ready at every phase of the polling). Printed, per mode, medians over --runs runs:
//  - reads per second idle, and the line's use idle (bytes both ways at 10 bits each, against 9600 bit/s);
//  - reads per motion while moving (WHEREs from the motion being ready to its check), and per second;
//  - the extra latency each motion saw: from being ready (its command handed to robot control) to its first byte on
//    the wire (the emulator's time for its first line, less that line's wire time), median and maximum;
//  - the check latency: from the motion's end (the first read after its last line going on the wire) to its check
//    being done (one read when nothing waits behind the motion);
// against the wire time of one read (Capabilities::read_time). Modes: "before" (MotionOptions::read_line_share 0: a
// read every position_period, asked behind commands: how it was) and "after" (0.25, the default: reads at least 4
// read times apart and none while a command is in the driver). The driver's rule that a command overtakes a read not
// yet on the wire is on in both.
// Reproduce pinned to one CPU: taskset -c 0 build/tools/polling_bench [--idle 10] [--motions 6] [--runs 3]
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/runtime/robot_control.hpp"

namespace {

using namespace cellwright;
using namespace std::chrono_literals;
using Steady = std::chrono::steady_clock;

constexpr int kBaud = 9600;
constexpr int kBits = 10;            // 8N1
constexpr double kTimeScale = 0.25;  // motions take a quarter of their time (the line keeps its own)

double ms(std::chrono::nanoseconds d) {
  return static_cast<double>(d.count()) / 1e6;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

struct Line {
  Steady::time_point at;  // when the emulator took it
  std::string text;
};

struct RunFigures {
  double idle_reads_per_s = 0, idle_line_use_pct = 0, idle_bytes_per_s = 0;
  double reads_per_motion = 0, moving_reads_per_s = 0;
  double latency_median_ms = 0, latency_max_ms = 0, check_median_ms = 0;
  double read_time_ms = 0;
};

models::CellDescription cell() {
  models::CellDescription c = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml");
  // Part A waits at the pick location (nothing brings it there: no plant).
  const models::LocationSpec* pick = c.find_location("input_pick");
  for (auto& w : c.workpieces) {
    if (w.name == "A") {
      w.pose.xyz = pick->pose.xyz + Eigen::Vector3d(0, 0, w.size.z() / 2);
      w.pose.rpy = Eigen::Vector3d::Zero();
    }
  }
  return c;
}

task::Primitive move(task::TargetKind kind, std::string object) {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kMove;
  p.target = {kind, std::move(object)};
  return p;
}

class Bench {
 public:
  Bench(const models::CellDescription& c, double share, std::uint64_t seed)
      : spec_(*c.find_robot("puma")),
        chain_(models::KinematicChain::from_urdf_file(spec_.urdf)),
        dir_(std::filesystem::temp_directory_path() / fmt::format("cw-polling-bench-{}", ::getpid())),
        arm_(chain_, arm_options()),
        env_(runtime::make_environment_model(c)),
        inbox_(4),
        statuses_(8),
        log_(),
        random_(seed) {
    std::filesystem::create_directories(dir_);
    emulate::Val2EmulatorOptions e;
    e.pace = {kBaud, kBits};
    e.log = [this](std::string_view text) {
      if (!text.starts_with("< ")) return;
      std::lock_guard lock(mutex_);
      lines_.push_back({Steady::now(), std::string(text.substr(2))});
    };
    emulator_ = std::make_unique<emulate::Val2Emulator>(arm_, std::move(e));
    const std::filesystem::path link = dir_ / "puma";
    serving_ = std::thread([this, link] {
      try {
        emulator_->serve(link);
      } catch (const std::exception& ex) {
        std::fprintf(stderr, "polling_bench: the emulator stopped: %s\n", ex.what());
      }
    });
    if (!emulator_->wait_published(1, 10s)) throw std::runtime_error("the emulator did not publish its terminal");
    drivers::Val2Options o;
    o.serial.line.port = link.string();
    o.serial.line.baud = kBaud;
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
    runtime::MotionOptions options;
    options.read_line_share = share;
    runtime::NameMap names;
    names.robots = {{"r1", "puma"}};
    names.objects = {{"A", "A"}};
    control_ = std::make_unique<runtime::RobotControl>(0, "r1", "puma", *driver_, chain_, spec_.grip_force, names, env_,
                                                       inbox_, statuses_, log_, options);
    control_->connect();
    start_ = Steady::now();
  }
  ~Bench() {
    control_.reset();
    driver_.reset();
    emulator_->stop();
    serving_.join();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  Bench(const Bench&) = delete;
  Bench& operator=(const Bench&) = delete;

  RunFigures run(std::chrono::nanoseconds idle, int motions) {
    RunFigures f;
    f.read_time_ms = ms(driver_->capabilities().read_time);
    if (!run_until([&] { return control_->phase() == runtime::RobotPhase::kReady; }, 60s)) {
      throw std::runtime_error("bring-up did not finish");
    }
    // Idle.
    const auto stats0 = emulator_->stats();
    const auto idle_start = Steady::now();
    run_until([] { return false; }, idle);
    const auto idle_end = Steady::now();
    const auto stats1 = emulator_->stats();
    const double idle_s = std::chrono::duration<double>(idle_end - idle_start).count();
    f.idle_reads_per_s = static_cast<double>(wheres(idle_start, idle_end)) / idle_s;
    const double bytes = static_cast<double>(stats1.bytes_in - stats0.bytes_in + stats1.bytes_out - stats0.bytes_out);
    f.idle_bytes_per_s = bytes / idle_s;
    f.idle_line_use_pct = 100.0 * bytes * kBits / kBaud / idle_s;

    // Motions.
    std::uniform_real_distribution<double> gap(0.3, 1.3);
    std::vector<double> latency, check;
    std::size_t moving_reads = 0;
    double moving_s = 0;
    for (int i = 0; i < motions; ++i) {
      run_until([] { return false; },
                std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(gap(random_))));
      runtime::MotionCommand c;
      c.index = static_cast<std::size_t>(i);
      c.primitive = i % 2 == 0 ? move(task::TargetKind::kAbove, "A") : move(task::TargetKind::kHome, "");
      const auto ready = Steady::now();
      if (inbox_.try_push(std::move(c)) != runtime::QueueStatus::ok) throw std::runtime_error("inbox full");
      std::optional<runtime::RobotStatus> status;
      run_until(
          [&] {
            runtime::RobotStatus s;
            if (statuses_.try_pop(s) == runtime::QueueStatus::ok) status = s;
            return status.has_value();
          },
          60s);
      const auto end = Steady::now();
      if (!status || status->outcome != runtime::CommandOutcome::kDone) {
        throw std::runtime_error(fmt::format("motion {} did not finish: {}", i, status ? status->reason : "no status"));
      }
      // Its first line (SPEED or DO MOVE: not a WHERE) and its last motion line, as the emulator took them.
      std::lock_guard lock(mutex_);
      // and the first WHERE after its last line (on the wire once the motion has ended).
      Steady::time_point first{}, after{};
      bool seen_motion = false, seen_read = false;
      for (const Line& l : lines_) {
        if (l.at < ready || l.at > end) continue;
        if (l.text != "WHERE") {
          if (!seen_motion) first = l.at - line_time(l.text);
          seen_motion = true;
          seen_read = false;
        } else if (seen_motion && !seen_read) {
          after = l.at - line_time(l.text);
          seen_read = true;
        }
      }
      if (!seen_motion || !seen_read) {
        throw std::runtime_error(fmt::format("motion {}: no motion line, or no read after it", i));
      }
      latency.push_back(ms(std::max(Steady::duration::zero(), first - ready)));
      check.push_back(ms(end - after));
      moving_reads += wheres_locked(ready, end);
      moving_s += std::chrono::duration<double>(end - ready).count();
    }
    f.reads_per_motion = static_cast<double>(moving_reads) / motions;
    f.moving_reads_per_s = static_cast<double>(moving_reads) / moving_s;
    f.latency_median_ms = median(latency);
    f.latency_max_ms = *std::max_element(latency.begin(), latency.end());
    f.check_median_ms = median(check);
    return f;
  }

 private:
  emulate::KinematicArmOptions arm_options() const {
    emulate::KinematicArmOptions a;
    a.home = spec_.home;
    a.time_scale = kTimeScale;
    return a;
  }
  // A line's wire time with its CR, at the paced rate.
  static std::chrono::nanoseconds line_time(const std::string& text) {
    return std::chrono::nanoseconds(
        static_cast<std::int64_t>(1e9 * kBits * static_cast<double>(text.size() + 1) / kBaud));
  }
  std::size_t wheres(Steady::time_point from, Steady::time_point to) {
    std::lock_guard lock(mutex_);
    return wheres_locked(from, to);
  }
  std::size_t wheres_locked(Steady::time_point from, Steady::time_point to) const {
    std::size_t n = 0;
    for (const Line& l : lines_) n += l.at >= from && l.at < to && l.text == "WHERE" ? 1 : 0;
    return n;
  }
  // Robot control's turns in real time, as its thread runs them: a turn, then a wait for the driver or 1 ms.
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
  std::mutex mutex_;
  std::condition_variable cv_;
  std::uint64_t notified_ = 0;
  std::vector<Line> lines_;
  std::mt19937_64 random_;
};

int usage(const char* why) {
  std::fprintf(stderr, "polling_bench: %s\nusage: polling_bench [--idle SECONDS] [--motions N] [--runs N]\n", why);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  double idle_s = 10;
  int motions = 6, runs = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage(fmt::format("{} needs a value", a).c_str());
    char* end = nullptr;
    const double v = std::strtod(argv[++i], &end);
    if (end == argv[i] || *end != '\0' || !(v > 0))
      return usage(fmt::format("{} {}: not a positive number", a, argv[i]).c_str());
    if (a == "--idle") {
      idle_s = v;
    } else if (a == "--motions") {
      motions = static_cast<int>(v);
    } else if (a == "--runs") {
      runs = static_cast<int>(v);
    } else {
      return usage(fmt::format("unknown option {}", a).c_str());
    }
  }
  fmt::print(
      "polling_bench: robot control of the PUMA over the VAL II driver and the VAL II emulator paced as a {}-baud "
      "line ({} bits a character) over a pseudo-terminal, real time; idle {} s, then {} motions; medians of {} runs. "
      "before: read_line_share 0 (a read every 10 ms, asked behind commands); after: 0.25.\n",
      kBaud, kBits, idle_s, motions, runs);
  std::fflush(stdout);
  const models::CellDescription c = cell();
  const auto idle = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(idle_s));
  fmt::print("{:<7} {:>9} {:>10} {:>10} {:>10} {:>11} {:>11} {:>11} {:>10} {:>10}\n", "mode", "read ms", "idle rd/s",
             "idle use%", "idle B/s", "rd/motion", "moving rd/s", "extra ms", "(max) ms", "check ms");
  for (const double share : {0.0, 0.25}) {
    std::vector<RunFigures> all;
    try {
      for (int r = 0; r < runs; ++r) {
        Bench bench(c, share, 1 + static_cast<std::uint64_t>(r));
        all.push_back(bench.run(idle, motions));
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "polling_bench: %s\n", e.what());
      return 1;
    }
    const auto med = [&](double RunFigures::*field) {
      std::vector<double> v;
      for (const RunFigures& f : all) v.push_back(f.*field);
      return median(v);
    };
    fmt::print("{:<7} {:>9.1f} {:>10.2f} {:>10.1f} {:>10.0f} {:>11.2f} {:>11.2f} {:>11.1f} {:>10.1f} {:>10.1f}\n",
               share == 0.0 ? "before" : "after", med(&RunFigures::read_time_ms), med(&RunFigures::idle_reads_per_s),
               med(&RunFigures::idle_line_use_pct), med(&RunFigures::idle_bytes_per_s),
               med(&RunFigures::reads_per_motion), med(&RunFigures::moving_reads_per_s),
               med(&RunFigures::latency_median_ms), med(&RunFigures::latency_max_ms),
               med(&RunFigures::check_median_ms));
    std::fflush(stdout);
  }
  return 0;
}
