// The rig's run of a cell of real robots with no twin (real_run.hpp), over pseudo-terminals: the exchange on the two
// controllers emulated with the project's kinematics behind them (emulate/), 4 times faster than real time. Nothing is
// simulated: no plant, no sensor but what the drivers have (neither driver senses its grip), and the parts end where
// the controller's model puts them.
#include "cellwright/cell/real_run.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <thread>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cell/real_exchange.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;

const std::string kExchange = std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml";


// An emulator serving `link` on a thread of its own until the end of the scope.
template <typename Emulator>
struct Serving {
  Serving(emulate::KinematicArm& arm, fs::path where) : emulator(arm, {}), link(std::move(where)) {
    thread = std::thread([this] { emulator.serve(link); });
    EXPECT_TRUE(emulator.wait_published(1, std::chrono::seconds(10)));
  }
  ~Serving() {
    emulator.stop();
    thread.join();
  }
  Emulator emulator;
  fs::path link;
  std::thread thread;
};

class RealRunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Its own directory: ctest runs the tests of this file as separate processes at once.
    dir_ = fs::temp_directory_path() /
           fmt::format("cw_real_run_{}_{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Scenario exchange_at_the_stop() { return test_real::exchange_at_the_stop(dir_); }
  fs::path dir_;
};

TEST_F(RealRunTest, EveryRobotOfTheProgramNeedsARealDriver) {
  Scenario s = load_scenario(kExchange);
  set_driver(s, "melfa=movemaster:/dev/null", {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  try {
    RealRun run(s, pre.net);
    FAIL() << "a simulated robot was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--driver puma=movemaster:PORT"), std::string::npos) << e.what();
  }
}

// Issue 25: parts the feed puts on a belt while the run goes would be taken where the cell description has them, and
// nothing real sees them arrive: the run is refused before anything connects (the ports here do not exist), naming
// the feed.
TEST_F(RealRunTest, AFeedIsRefusedBeforeAnythingConnects) {
  Scenario s = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/pipeline.yaml");
  set_driver(s, "puma=val2:" + (dir_ / "no-puma").string(), {"--driver", 0, 0});
  set_driver(s, "melfa=movemaster:" + (dir_ / "no-melfa").string(), {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  try {
    RealRun run(s, pre.net);
    FAIL() << "a real run of a feed was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(fs::path(e.where().file).filename(), "pipeline.yaml") << e.what();
    EXPECT_EQ(e.where().line, 10) << e.what();  // feed: {conveyor: input, ...}
    EXPECT_NE(std::string(e.what()).find("the feed puts parts on conveyor 'input'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nothing that sees a part arrive on a belt"), std::string::npos) << e.what();
  }
}

TEST_F(RealRunTest, ExchangeRunsOnTwoEmulatedControllersWithNoPlantAndTheModelsParts) {
  emulate::KinematicArm puma_arm = test_real::arm_at_home("/urdf/puma560.urdf", test_real::kPumaHome);
  emulate::KinematicArm melfa_arm = test_real::arm_at_home("/urdf/melfa_rve2.urdf", test_real::kMelfaHome);
  Serving<emulate::Val2Emulator> puma(puma_arm, dir_ / "puma");
  Serving<emulate::MovemasterEmulator> melfa(melfa_arm, dir_ / "melfa");
  Scenario s = exchange_at_the_stop();
  set_driver(s, "puma=val2:" + puma.link.string(), {"--driver", 0, 0});
  set_driver(s, "melfa=movemaster:" + melfa.link.string(), {"--driver", 0, 0});
  const Preflight pre = preflight(s, nullptr);
  ASSERT_TRUE(pre.ok()) << (pre.problems.empty() ? std::string() : pre.problems.front());

  RealRunOptions options;
  options.speed = 4;
  RealRun run(s, pre.net, options);
  EXPECT_EQ(run.runtime().config().plant, nullptr);
  EXPECT_TRUE(run.runtime().config().sensors.grip.empty());  // neither driver senses its grip
  EXPECT_EQ(run.runtime().config().sensors.parts, nullptr);
  ASSERT_EQ(run.robots().size(), 2u);
  EXPECT_EQ(run.robots()[0].robot, "puma");
  EXPECT_EQ(run.robots()[0].driver, "val2 on " + puma.link.string());
  EXPECT_FALSE(run.robots()[0].senses_grip);
  EXPECT_EQ(describe_sensing(run.robots()[1]), "no grip sensor (a close is taken as done), no wrist force sensor");

  const runtime::RunResult& result = run.run();
  ASSERT_EQ(result.outcome, runtime::Outcome::kFinished) << result.reason;
  RunSetup setup = setup_of(s);
  setup.parts_from_model = true;
  setup.twin_truth = false;
  const Report report = make_report(s, runtime::decode_log(run.runtime().log().text(), "events.jsonl"),
                                    final_poses_of(run.model()), std::nullopt, "events.jsonl", setup);
  EXPECT_TRUE(report.ok()) << format_summary(report);
  ASSERT_FALSE(report.workpieces.empty());
  EXPECT_EQ(report.workpieces.front().where, "output");
  EXPECT_NE(format_summary(report).find("parts: where the controller's model"), std::string::npos);
  EXPECT_EQ(to_json(s, report)["parts_from"], "controller_model");
}

}  // namespace
}  // namespace cellwright::cell
