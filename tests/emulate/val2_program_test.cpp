// The VAL II emulator's stored programs (docs/real-robots.md, "Robot programs"): `.PROGRAM` ... `.END` and
// `.LOCATIONS` ... `.END` received at the monitor, `EXECUTE` running the steps through the monitor's executor (named
// locations, SIGNAL, WAIT SIG), the prompt when the program has ended, and the errors. Over a real pseudo-terminal,
// the host being the project's SerialPort; the arm a PumaFakeArm.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <condition_variable>
#include <future>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/emulate/val2_emulator.hpp"
#include "emulate/program_host.hpp"
#include "emulate/val2_fake_arm.hpp"

namespace cellwright::emulate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using testing::ProgramHost;
using testing::PumaFakeArm;

class Val2ProgramTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::path(::testing::TempDir()) /
           fmt::format("v2_program_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    Val2EmulatorOptions o;
    o.echo = false;
    o.on_program_step = [this](int n) {
      {
        std::lock_guard lock(mutex_);
        steps_.push_back(n);
      }
      ran_.notify_all();
    };
    emulator_ = std::make_unique<Val2Emulator>(arm_, std::move(o));
    served_ = std::async(std::launch::async, [this] { emulator_->serve(dir_ / "puma"); });
    ASSERT_TRUE(emulator_->wait_published(1, 10s));
    host_ = std::make_unique<ProgramHost>(dir_ / "puma");
    ASSERT_TRUE(host_->sync_val2()) << "the monitor does not answer";
  }
  void TearDown() override {
    host_.reset();
    emulator_->stop();
    served_.get();
    std::filesystem::remove_all(dir_);
  }

  std::vector<int> steps_run() {
    std::lock_guard lock(mutex_);
    return steps_;
  }
  bool wait_for_step(int n) {
    std::unique_lock lock(mutex_);
    return ran_.wait_for(lock, 10s, [&] { return std::find(steps_.begin(), steps_.end(), n) != steps_.end(); });
  }

  // WHERE's X Y Z O A T now, with Z changed by `dz` mm: a location the arm can reach.
  std::string here(double dz) {
    host_->send("WHERE", "\r");
    std::istringstream out(host_->until_prompt(10s).value_or(""));
    std::string header, values;
    while (header.find("X/JT1") == std::string::npos && std::getline(out, header)) {
    }
    std::getline(out, values);
    std::istringstream v(values);
    double x, y, z, o, a, t;
    v >> x >> y >> z >> o >> a >> t;
    EXPECT_FALSE(v.fail()) << values;
    return fmt::format("{} {} {} {} {} {}", x, y, z + dz, o, a, t);
  }

  std::filesystem::path dir_;
  PumaFakeArm arm_;
  std::unique_ptr<Val2Emulator> emulator_;
  std::future<void> served_;
  std::unique_ptr<ProgramHost> host_;
  std::mutex mutex_;
  std::condition_variable ran_;
  std::vector<int> steps_;
};

TEST_F(Val2ProgramTest, ExecutesAStoredProgramWithNamedLocationsAndSignals) {
  const std::string printed =
      host_->load_val2({".PROGRAM test", "; a comment step", "  SIGNAL 2", "  WAIT SIG(1004)", "  MOVE low.1",
                        "  CLOSEI", ".END", ".LOCATIONS", "low.1 " + here(-20), ".END"});
  EXPECT_EQ(printed.find('*'), std::string::npos) << printed;
  EXPECT_TRUE(arm_.puma_moves().empty()) << "program steps are stored, not executed";
  host_->send("EXECUTE test", "\r");
  ASSERT_TRUE(wait_for_step(3)) << "the program does not reach its WAIT SIG";
  EXPECT_TRUE(arm_.output(2));
  EXPECT_TRUE(arm_.puma_moves().empty());
  arm_.set_input(4, true);
  EXPECT_THAT(host_->until_prompt(10s).value_or("(no prompt)"), HasSubstr("Program completed"));
  ASSERT_EQ(arm_.puma_moves().size(), 1u);
  EXPECT_EQ(arm_.grips(), std::vector<bool>{true});
  EXPECT_EQ(steps_run(), (std::vector<int>{1, 2, 3, 4, 5}));
}

TEST_F(Val2ProgramTest, AFailingStepStopsTheProgram) {
  host_->load_val2({".PROGRAM bad", "  SIGNAL 1", "  MOVE nowhere", "  SIGNAL 3", ".END"});
  const std::string out = (host_->send("ex bad", "\r"), host_->until_prompt(10s)).value_or("(no prompt)");
  EXPECT_THAT(out, HasSubstr("*Undefined location*"));
  EXPECT_THAT(out, HasSubstr("Program stopped at step 2"));
  EXPECT_TRUE(arm_.output(1));
  EXPECT_FALSE(arm_.output(3));
}

TEST_F(Val2ProgramTest, AStepThatDoesNotParseLeavesTheProgramUnstored) {
  const std::string printed = host_->load_val2({".PROGRAM broken", "  SIGNAL 1", "  FROBNICATE", ".END"});
  EXPECT_THAT(printed, HasSubstr("*Unknown instruction*"));
  EXPECT_THAT(printed, HasSubstr("*Program not stored*"));
  EXPECT_THAT(host_->execute_val2("broken", 10s).value_or("(no prompt)"), HasSubstr("*Undefined program*"));
  EXPECT_FALSE(arm_.output(1));
  EXPECT_THAT(host_->load_val2({".LOCATIONS", "p1 1 2 3", ".END"}), HasSubstr("*Invalid argument*"));
}

}  // namespace
}  // namespace cellwright::emulate
