// The Movemaster EX emulator's stored program (docs/real-robots.md, "Robot programs"): numbered lines stored, RN
// running them through the executor with the program commands (MO, OB, TB, GT, ED), the ER after RN answered when
// the program has ended, and the errors that end a run. Over a real pseudo-terminal, the host being the project's
// SerialPort; the arm a FakeArm.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <condition_variable>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/emulate/movemaster_emulator.hpp"
#include "emulate/fake_arm.hpp"
#include "emulate/program_host.hpp"

namespace cellwright::emulate {
namespace {

using namespace std::chrono_literals;
using testing::FakeArm;
using testing::ProgramHost;

class MovemasterProgramTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::path(::testing::TempDir()) /
           fmt::format("mm_program_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    MovemasterEmulatorOptions o;
    o.on_program_line = [this](int n) {
      {
        std::lock_guard lock(mutex_);
        lines_.push_back(n);
      }
      ran_.notify_all();
    };
    emulator_ = std::make_unique<MovemasterEmulator>(arm_, std::move(o));
    served_ = std::async(std::launch::async, [this] { emulator_->serve(dir_ / "melfa"); });
    ASSERT_TRUE(emulator_->wait_published(1, 10s));
    host_ = std::make_unique<ProgramHost>(dir_ / "melfa");
  }
  void TearDown() override {
    host_.reset();
    emulator_->stop();
    served_.get();
    std::filesystem::remove_all(dir_);
  }

  std::vector<int> lines_run() {
    std::lock_guard lock(mutex_);
    return lines_;
  }
  // Waits until line `n` has started.
  bool wait_for_line(int n) {
    std::unique_lock lock(mutex_);
    return ran_.wait_for(lock, 10s, [&] { return std::find(lines_.begin(), lines_.end(), n) != lines_.end(); });
  }

  // The pose the arm stands at now (WH's answer), with z changed by `dz` mm: a PD's values it can reach.
  std::string here(double dz) {
    host_->send("WH", "\r\n");
    const std::string wh = host_->line(10s).value_or("");
    // Five signed numbers separated by commas (split by hand: GCC 12's <regex> warns falsely under ASan).
    std::vector<std::string> v;
    std::size_t from = 0;
    for (std::size_t comma; (comma = wh.find(',', from)) != std::string::npos; from = comma + 1) {
      v.push_back(wh.substr(from, comma - from));
    }
    v.push_back(wh.substr(from));
    EXPECT_EQ(v.size(), 5u) << wh;
    for (const std::string& x : v) EXPECT_TRUE(!x.empty() && (x[0] == '+' || x[0] == '-')) << wh;
    if (v.size() != 5) return "0,0,0,0,0";
    return fmt::format("{},{},{:.1f},{},{}", v[0], v[1], std::stod(v[2]) + dz, v[3], v[4]);
  }

  std::filesystem::path dir_;
  FakeArm arm_;
  std::unique_ptr<MovemasterEmulator> emulator_;
  std::future<void> served_;
  std::unique_ptr<ProgramHost> host_;
  std::mutex mutex_;
  std::condition_variable ran_;
  std::vector<int> lines_;
};

TEST_F(MovemasterProgramTest, RunsStoredLinesWithIoAndEndsAtEd) {
  ASSERT_TRUE(host_->load_movemaster(
      {fmt::format("10 PD 1,{}", here(-20)), "20 OB +3", "30 TB -5,30", "40 MO 1", "50 GC", "60 ED", "70 GO"}));
  EXPECT_TRUE(arm_.moves().empty()) << "stored lines are not executed";
  host_->send("RN", "\r\n");
  host_->send("ER", "\r\n");
  // The program stands at line 30 until input 5 comes on: OB +3 has run, MO 1 has not.
  ASSERT_TRUE(wait_for_line(30));
  EXPECT_TRUE(arm_.output(3));
  EXPECT_TRUE(arm_.moves().empty());
  arm_.set_input(5, true);
  EXPECT_EQ(host_->line(10s).value_or("(nothing)"), "0");
  ASSERT_EQ(arm_.moves().size(), 1u);
  EXPECT_FALSE(arm_.moves()[0].linear) << "MO is joint-interpolated";
  EXPECT_EQ(arm_.grips(), std::vector<bool>{true}) << "GC ran, the GO after ED did not";
  EXPECT_EQ(lines_run(), (std::vector<int>{10, 20, 30, 40, 50, 60}));
}

TEST_F(MovemasterProgramTest, TestBitJumpsAndGoTo) {
  arm_.set_input(2, true);
  ASSERT_TRUE(host_->load_movemaster({"10 TB +2,40", "20 OB +1", "30 ED", "40 OB +4", "50 GT 20"}));
  EXPECT_EQ(host_->run_movemaster(10s).value_or("(nothing)"), "0");
  EXPECT_TRUE(arm_.output(1));
  EXPECT_TRUE(arm_.output(4));
  EXPECT_EQ(lines_run(), (std::vector<int>{10, 40, 50, 20, 30}));
}

TEST_F(MovemasterProgramTest, AFailingLineEndsTheRunWithError2) {
  ASSERT_TRUE(host_->load_movemaster({"10 OB +1", "20 MO 7", "30 OB +2"}));
  EXPECT_EQ(host_->run_movemaster(10s).value_or("(nothing)"), "2") << "position 7 is not defined";
  EXPECT_TRUE(arm_.output(1));
  EXPECT_FALSE(arm_.output(2)) << "the run ended at the failing line";
  host_->send("RS", "\r\n");
  host_->send("20 GT 99", "\r\n");  // replaces line 20
  EXPECT_EQ(host_->run_movemaster(10s).value_or("(nothing)"), "2") << "a jump to a line that does not exist";
}

TEST_F(MovemasterProgramTest, BadProgramLinesAreFormatErrorsAndNwDeletes) {
  for (const char* bad : {"10 XX 1", "0 GO", "3000 GO", "10 RN", "10 OB +17", "10 TB +1"}) {
    host_->send(bad, "\r\n");
    host_->send("ER", "\r\n");
    EXPECT_EQ(host_->line(10s).value_or("(nothing)"), "2") << bad;
    host_->send("RS", "\r\n");
  }
  ASSERT_TRUE(host_->load_movemaster({"10 OB +1"}));
  host_->send("NW", "\r\n");
  EXPECT_EQ(host_->run_movemaster(10s).value_or("(nothing)"), "0");
  EXPECT_FALSE(arm_.output(1)) << "NW deleted the program: RN ran nothing";
}

}  // namespace
}  // namespace cellwright::emulate
