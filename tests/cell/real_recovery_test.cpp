// Recovery on a real arm, over pseudo-terminals (docs/faults.md, reset_rehome; docs/real-robots.md, "What the
// emulators can be told to do wrong"): the exchange as a cell of real robots with no twin (RealRun), the PUMA's VAL II
// monitor and the MELFA's Movemaster EX emulated with the project's kinematics behind them, 4 times faster than real
// time, the PUMA's monitor told to fail chosen commands. Each run must end well before its time limit (cell time), and
// what the monitor received shows what the recovery did to the arm.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/real_run.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cell/real_exchange.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr double kLimit = 90;  // s of cell time: a clean exchange takes well under half of it


// The two controllers on their pseudo-terminals, each on a thread of its own until the end of the scope; the lines the
// PUMA's monitor received ("< ...") and answered ("> ..."), in order.
class EmulatedPair {
 public:
  EmulatedPair(const fs::path& dir, const std::vector<std::string>& puma_misbehaviours)
      : puma_arm_(test_real::arm_at_home("/urdf/puma560.urdf", test_real::kPumaHome)),
        melfa_arm_(test_real::arm_at_home("/urdf/melfa_rve2.urdf", test_real::kMelfaHome)),
        puma_(puma_arm_, puma_options(puma_misbehaviours)),
        melfa_(melfa_arm_, {}),
        puma_link_(dir / "puma"),
        melfa_link_(dir / "melfa") {
    puma_thread_ = std::thread([this] { puma_.serve(puma_link_); });
    melfa_thread_ = std::thread([this] { melfa_.serve(melfa_link_); });
    EXPECT_TRUE(puma_.wait_published(1, std::chrono::seconds(10)));
    EXPECT_TRUE(melfa_.wait_published(1, std::chrono::seconds(10)));
  }
  ~EmulatedPair() {
    puma_.stop();
    melfa_.stop();
    puma_thread_.join();
    melfa_thread_.join();
  }
  EmulatedPair(const EmulatedPair&) = delete;
  EmulatedPair& operator=(const EmulatedPair&) = delete;

  const fs::path& puma_link() const { return puma_link_; }
  const fs::path& melfa_link() const { return melfa_link_; }
  std::vector<std::string> puma_lines() const {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 private:
  emulate::Val2EmulatorOptions puma_options(const std::vector<std::string>& specs) {
    emulate::Val2EmulatorOptions o;
    for (const std::string& spec : specs) o.misbehaviours.push_back(emulate::parse_misbehaviour(spec));
    o.log = [this](std::string_view line) {
      std::lock_guard lock(mutex_);
      lines_.emplace_back(line);
    };
    return o;
  }

  emulate::KinematicArm puma_arm_, melfa_arm_;
  mutable std::mutex mutex_;
  std::vector<std::string> lines_;
  emulate::Val2Emulator puma_;
  emulate::MovemasterEmulator melfa_;
  fs::path puma_link_, melfa_link_;
  std::thread puma_thread_, melfa_thread_;
};

// What a run left: its result and its events.
struct Ran {
  runtime::RunResult result;
  std::vector<nlohmann::json> events;
  std::vector<nlohmann::json> of(const std::string& type) const {
    std::vector<nlohmann::json> out;
    for (const nlohmann::json& e : events) {
      if (e["type"] == type) out.push_back(e);
    }
    return out;
  }
};

class RealRecoveryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("cw_real_recovery_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The exchange with A at the input conveyor's stop bar (a run without the twin has no part sensor), on the pair,
  // with `recovery` as the scenario's.
  Ran run(EmulatedPair& pair, bool recovery = true) {
    Scenario s = test_real::exchange_at_the_stop(dir_);
    s.limits.sim_time = kLimit;
    s.recovery.enabled = recovery;
    set_driver(s, "puma=val2:" + pair.puma_link().string(), {"--driver", 0, 0});
    set_driver(s, "melfa=movemaster:" + pair.melfa_link().string(), {"--driver", 0, 0});
    const Preflight pre = preflight(s, nullptr);
    EXPECT_TRUE(pre.ok()) << (pre.problems.empty() ? std::string() : pre.problems.front());
    RealRunOptions options;
    options.speed = 4;
    RealRun real(s, pre.net, options);
    Ran ran;
    ran.result = real.run();
    std::istringstream lines(real.runtime().log().text());
    for (std::string line; std::getline(lines, line);) {
      if (!line.empty()) ran.events.push_back(nlohmann::json::parse(line));
    }
    return ran;
  }

  fs::path dir_;
};

double seconds(runtime::SimDuration d) {
  return std::chrono::duration<double>(d).count();
}

// The commands the monitor received after the first answer containing `answer`, in order ("DO READY", "WHERE", ...).
std::vector<std::string> received_after(const std::vector<std::string>& lines, const std::string& answer) {
  std::vector<std::string> out;
  bool after = false;
  for (const std::string& l : lines) {
    if (!after) {
      after = l.starts_with("> ") && l.find(answer) != std::string::npos;
      continue;
    }
    if (!l.starts_with("< ") || l.size() == 2) continue;  // answers, and the empty lines of a reset
    out.push_back(l.substr(2, l.find("  (") == std::string::npos ? std::string::npos : l.find("  (") - 2));
  }
  return out;
}

std::size_t first_starting(const std::vector<std::string>& commands, const std::string& start) {
  for (std::size_t i = 0; i < commands.size(); ++i) {
    if (commands[i].starts_with(start)) return i;
  }
  return commands.size();
}

// A hardware error on the PUMA's first move (its hand empty): the recovery asks WHERE before it sends DO READY, and
// the exchange is done.
TEST_F(RealRecoveryTest, AfterAHardwareErrorTheArmIsReadBackBeforeItIsHomed) {
  EmulatedPair pair(dir_, {"error@domove#1"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kFinished) << ran.result.reason;
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  const std::vector<std::string> after = received_after(pair.puma_lines(), "*Arm power off*");
  const std::size_t where = first_starting(after, "WHERE"), ready = first_starting(after, "DO READY");
  ASSERT_LT(ready, after.size()) << "never homed again";
  EXPECT_LT(where, ready) << "homed again before asking where the arm stopped";
  ASSERT_EQ(ran.of("fault_detected").size(), 1u);
  EXPECT_EQ(ran.of("fault_detected")[0]["symptom"], "driver_fault");
  bool read_back = false;
  for (const nlohmann::json& e : ran.of("sensor")) read_back = read_back || e["condition"] == "stopped_at";
  EXPECT_TRUE(read_back);
}

// A hardware error on the PUMA's lift with A in its hand (its third move): it is not homed through the MELFA's space;
// the cell stops, well before the time limit, and the verdict says why.
TEST_F(RealRecoveryTest, ALoadedArmIsNotHomedAndTheCellStopsSayingWhy) {
  EmulatedPair pair(dir_, {"error@domove#3"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kStopped) << ran.result.reason;
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  EXPECT_THAT(ran.result.reason, HasSubstr("puma holds A where it stopped"));
  EXPECT_THAT(ran.result.reason, HasSubstr("*Arm power off*"));
  const std::vector<std::string> after = received_after(pair.puma_lines(), "*Arm power off*");
  EXPECT_EQ(first_starting(after, "DO READY"), after.size()) << "the loaded arm was homed";
  EXPECT_LT(first_starting(after, "WHERE"), after.size()) << "where it stopped was not read";
}

// Each step of the recovery fails once in turn: the read-back of where the arm stopped, then the homing. Each failure
// starts the steps over, and the exchange is done, well before the time limit.
TEST_F(RealRecoveryTest, AFaultDuringTheRecoveryIsItselfRecovered) {
  EmulatedPair pair(dir_, {"error@domove#1", "error@where#1", "error@doready#1"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kFinished) << ran.result.reason;
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  std::size_t errors = 0;
  for (const std::string& l : pair.puma_lines()) errors += l == "> *Arm power off*" ? 1 : 0;
  EXPECT_EQ(errors, 3u);
}

// The homing fails every time: the cell stops after max_attempts, naming the last failure, well before the time limit
// (never round and round until it).
TEST_F(RealRecoveryTest, ARecoveryThatKeepsFailingStopsTheCell) {
  EmulatedPair pair(dir_, {"error@domove#1", "error@doready#1", "error@doready#1", "error@doready#1"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kStopped) << ran.result.reason;
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  EXPECT_THAT(ran.result.reason, HasSubstr("puma could not be recovered"));
  EXPECT_THAT(ran.result.reason, HasSubstr("*Arm power off*"));
}

// The first WHERE of the run after the PUMA's bring-up fails (the script starts at the homing, answered 10 ms late;
// the bring-up's own cross-check read is the first WHERE after it, the run's first read the second): a fault
// of the PUMA at once, whose detail is the monitor's error; recovered.
TEST_F(RealRecoveryTest, AFailedReadBackIsAFaultOfThatRobotWithItsCause) {
  EmulatedPair pair(dir_, {"late@doready#1:0.01", "error@where#2"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kFinished) << ran.result.reason;
  const std::vector<nlohmann::json> detected = ran.of("fault_detected");
  ASSERT_EQ(detected.size(), 1u);
  EXPECT_EQ(detected[0]["robot"], "r1");
  EXPECT_THAT(detected[0]["detail"].get<std::string>(),
              HasSubstr("the position read-back failed: hardware: WHERE: the controller answered '*Arm power off*'"));
}

// Without recovery the same failure ends the run at once, and the verdict keeps the monitor's error.
TEST_F(RealRecoveryTest, WithoutRecoveryTheVerdictKeepsTheReadBacksCause) {
  EmulatedPair pair(dir_, {"late@doready#1:0.01", "error@where#2"});
  const Ran ran = run(pair, false);
  EXPECT_NE(ran.result.outcome, runtime::Outcome::kFinished);
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  EXPECT_THAT(ran.result.reason, HasSubstr("*Arm power off*"));
}

// An error text the VAL II driver does not know (`*Invalid format*`): its own symptom, and the cell stops safely
// without the arm being homed.
TEST_F(RealRecoveryTest, AnErrorTheDriverDoesNotKnowStopsTheCell) {
  EmulatedPair pair(dir_, {"unknown@domove#1"});
  const Ran ran = run(pair);
  ASSERT_EQ(ran.result.outcome, runtime::Outcome::kStopped) << ran.result.reason;
  EXPECT_LT(seconds(ran.result.end_time), kLimit / 2);
  EXPECT_THAT(ran.result.reason, HasSubstr("unknown_controller_error"));
  EXPECT_THAT(ran.result.reason, HasSubstr("*Invalid format*"));
  ASSERT_EQ(ran.of("fault_detected").size(), 1u);
  EXPECT_EQ(ran.of("fault_detected")[0]["symptom"], "unknown_error");
  const std::vector<std::string> after = received_after(pair.puma_lines(), "*Invalid format*");
  EXPECT_EQ(first_starting(after, "DO READY"), after.size());
}

}  // namespace
}  // namespace cellwright::cell
