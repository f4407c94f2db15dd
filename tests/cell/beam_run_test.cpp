// The shipped coordinated carry (scenes/beam.yaml, issue 27) in the MuJoCo twin, lock-step: the PUMA and the MELFA
// carry a 0.8 m beam held by friction at its ends from the input stand to the fixture. What a user checks in the
// event log and the outcome: every segment of the block starts on both arms in the same control period with the same
// driver duration, ends on both within one control period, and the beam lies level on the fixture; the report gives
// the segments' skews and the carry's figures as the twin measured them. And the safety layer's stop of both arms (docs/runtime.md "Coordinated blocks"): one
// end dropped (a `drop` fault on one gripper), a squeeze force or a relative tool error over a limit the scenario
// sets: the run ends stopped, the fault event names the cause, both arms are stopped in the same control period and
// the beam is not counted as placed.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/sim/sweep.hpp"

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <gmock/gmock.h>

#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>
#include <string>

namespace cellwright::cell {
namespace {

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";
namespace fs = std::filesystem;
using ::testing::HasSubstr;

TEST(BeamRun, BothArmsStartAndStopEverySegmentTogetherAndPutTheBeamDownLevelOnTheFixture) {
  const Scenario s = load_scenario(kScenes + "/beam.yaml");
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();
  ScenarioRun run(s, pre);
  const runtime::RunResult r = run.runtime().run();
  ASSERT_EQ(r.outcome, runtime::Outcome::kFinished) << r.reason;

  // Per segment ("[carry K/10: ..."): each robot's start, end and driver command.
  struct Times {
    std::map<std::string, double> start, end;
    std::map<std::string, std::string> duration;
  };
  std::map<int, Times> seg;
  std::istringstream in(run.runtime().log().text());
  for (std::string line; std::getline(in, line);) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] != "command_start" && e["type"] != "command_end") continue;
    const std::string command = e["command"];
    const auto at = command.find("[carry ");
    if (at == std::string::npos) continue;
    const int k = std::stoi(command.substr(at + 7));
    const std::string robot = e["robot"];
    if (e["type"] == "command_start") {
      seg[k].start[robot] = e["t"];
      const std::string detail = e["detail"];
      const auto d = detail.find(" duration ");
      if (d != std::string::npos) seg[k].duration[robot] = detail.substr(d);
    } else {
      seg[k].end[robot] = e["t"];
    }
  }
  ASSERT_EQ(seg.size(), 10u);
  const double period = s.options.control_period;
  for (const auto& [k, t] : seg) {
    ASSERT_EQ(t.start.size(), 2u) << "segment " << k;
    EXPECT_EQ(t.start.at("left"), t.start.at("right")) << "segment " << k;
    EXPECT_EQ(t.duration.size(), t.duration.empty() ? 0u : 2u) << "segment " << k;
    if (!t.duration.empty()) {
      EXPECT_EQ(t.duration.at("left"), t.duration.at("right")) << "segment " << k;
    }
    // ... and stops on both within one control period (the stop skew): the trajectories end at the same
    // physics step, and a timed move is done once its arm is at rest where its servo holds it under the beam's load.
    EXPECT_LE(std::abs(t.end.at("left") - t.end.at("right")), period + 1e-9) << "segment " << k;
  }
  // The report says the same: ten segments, their largest start and end skews.
  const Report report = run.report();
  ASSERT_EQ(report.segments.size(), 10u);
  ASSERT_TRUE(report.max_start_skew && report.max_end_skew);
  EXPECT_EQ(*report.max_start_skew, 0.0);
  EXPECT_LE(*report.max_end_skew, period + 1e-9);
  for (const SegmentTiming& g : report.segments) {
    EXPECT_EQ(g.block, "carry");
    EXPECT_EQ(g.master, "left");
    EXPECT_EQ(g.start_skew, std::abs(seg.at(g.index).start.at("left") - seg.at(g.index).start.at("right")));
  }
  // Every move of the block is timed: 7 moves, 3 grips.
  int timed = 0;
  for (const auto& [k, t] : seg) timed += t.duration.empty() ? 0 : 1;
  EXPECT_EQ(timed, 7);

  const runtime::WorkpieceState* beam = r.environment.find_workpiece("beam");
  ASSERT_NE(beam, nullptr);
  const Eigen::Vector3d fix = s.cell.find_location("beam_fix")->pose.xyz;
  EXPECT_LT((beam->pose.translation().head<2>() - fix.head<2>()).norm(), 0.03) << beam->pose.translation().transpose();
  EXPECT_NEAR(beam->pose.translation().z() - 0.02, fix.z(), 0.01);
  // Level: its long axis within 2 degrees of horizontal.
  EXPECT_LT(std::abs(beam->pose.linear().col(0).z()), std::sin(2.0 * M_PI / 180.0));

  // The report: one carry, measured every period while both hands held the beam, with its figures.
  const Report rep = run.report();
  EXPECT_TRUE(rep.ok()) << (rep.failures.empty() ? "" : rep.failures.front());
  ASSERT_EQ(rep.carries.size(), 1u);
  const CarryReport& c = rep.carries.front();
  EXPECT_EQ(c.workpiece, "beam");
  EXPECT_EQ(c.a, "puma");
  EXPECT_EQ(c.b, "melfa");
  EXPECT_EQ(c.samples, static_cast<std::size_t>(std::lround((c.end - c.start) / 0.01)) + 1);  // every period
  EXPECT_GT(c.end - c.start, 3.0);  // the lift, the carry and the put-down
  // Within the scenario's limits of the safety layer, which therefore did not stop it.
  EXPECT_DOUBLE_EQ(s.safety.squeeze_force, 20.0);
  EXPECT_LT(std::abs(c.peak_squeeze), s.safety.squeeze_force);
  EXPECT_LT(c.max_error, s.safety.carry_error * 1000.0);
  EXPECT_LT(c.max_tilt, 2.0);
  EXPECT_GT(c.max_error, 0.0);  // measured, not a constant
  const std::string summary = format_summary(rep);
  EXPECT_THAT(summary, HasSubstr("carry of beam by puma and melfa"));
  EXPECT_THAT(summary, HasSubstr("peak squeeze"));
  const nlohmann::json j = to_json(s, rep);
  ASSERT_TRUE(j.contains("carries"));
  EXPECT_EQ(j["carries"][0]["samples"], c.samples);
}

// The shipped beam scenario with more YAML (a fault, limits) appended, run in lock-step to the end.
class BeamSafety : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("beam_safety_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  struct Stopped {
    runtime::RunResult result;
    Report report;
    std::vector<nlohmann::json> events;
    // The events of a type.
    std::vector<nlohmann::json> of(const std::string& type) const {
      std::vector<nlohmann::json> out;
      std::copy_if(events.begin(), events.end(), std::back_inserter(out),
                   [&](const nlohmann::json& e) { return e["type"] == type; });
      return out;
    }
  };

  Stopped run(const std::string& more) {
    const fs::path p = dir_ / "beam.yaml";
    std::ofstream(p) << fmt::format(
        "cell: {0}/beam_cell.yaml\nprogram: {0}/beam.task\nseed: 1\nrobots: {{left: puma, right: melfa}}\n"
        "bind: {{FIX: beam_fix, MID: beam_mid}}\nlimits: {{sim_time: 60, wall_time: 600}}\n"
        "expect:\n  beam: beam_fix\ntolerance: 0.03\n{1}",
        kScenes, more);
    const Scenario s = load_scenario(p);
    const Preflight pre = preflight(s, &twin_port());
    EXPECT_TRUE(pre.ok());
    ScenarioRun r(s, pre);
    Stopped out;
    out.result = r.runtime().run();
    out.report = r.report();
    std::istringstream in(r.runtime().log().text());
    for (std::string line; std::getline(in, line);) out.events.push_back(nlohmann::json::parse(line));
    return out;
  }

  // What a user checks of every such stop: stopped (not finished, not a failure of the program), one detection
  // naming `cause`, both arms' protective stops in the same period as it, and the beam not counted as placed.
  static void expect_both_stopped(const Stopped& r, const std::string& symptom, const std::string& text) {
    EXPECT_EQ(r.result.outcome, runtime::Outcome::kStopped) << r.result.reason;
    EXPECT_THAT(r.result.reason, HasSubstr("both arms stopped"));
    EXPECT_THAT(r.result.reason, HasSubstr(text));
    const std::vector<nlohmann::json> detected = r.of("fault_detected");
    ASSERT_EQ(detected.size(), 1u);
    EXPECT_EQ(detected[0]["symptom"], symptom);
    EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr(text));
    const std::vector<nlohmann::json> stops = r.of("protective_stop");
    ASSERT_EQ(stops.size(), 2u);
    EXPECT_NE(stops[0]["robot"], stops[1]["robot"]);
    EXPECT_EQ(stops[0]["t"], detected[0]["t"]);
    EXPECT_EQ(stops[1]["t"], detected[0]["t"]);  // the second arm in the same control period
    EXPECT_EQ(r.report.outcome, "stopped");
    EXPECT_FALSE(r.report.ok());
    EXPECT_EQ(r.report.parts_completed, 0u);
    EXPECT_TRUE(r.report.placed_at.empty());
    ASSERT_EQ(r.report.workpieces.size(), 1u);
    EXPECT_FALSE(r.report.workpieces[0].completed);
  }

  fs::path dir_;
};

// One gripper loses its force 2 s into its first carry (in the carry over the gap): its end of the beam falls.
// Either arm's: the World knows both holders of a part carried together.
TEST_F(BeamSafety, OneEndDroppedStopsBothArmsNamingTheArmWhoseEndSlipped) {
  for (const auto& [robot, label] : {std::pair{"puma", "left"}, std::pair{"melfa", "right"}}) {
    SCOPED_TRACE(robot);
    const Stopped r = run(fmt::format("faults:\n  - {{kind: drop, robot: {}, carry: 1, after: 2.0}}\n", robot));
    expect_both_stopped(r, "grip_lost", fmt::format("{} ({})'s end of beam slipped", label, robot));
    ASSERT_EQ(r.report.faults.size(), 1u);
    EXPECT_EQ(r.report.faults[0].robot, robot);
    EXPECT_TRUE(r.report.faults[0].detected);
    EXPECT_TRUE(r.report.faults[0].stopped_safely);
  }
}

TEST_F(BeamSafety, ASqueezeOverTheLimitStopsBothArmsWithTheForceAndTheLimit) {
  const Stopped r = run("safety: {squeeze_force: 0.5}\n");
  expect_both_stopped(r, "protective_stop", "over the limit of 0.5 N");
}

TEST_F(BeamSafety, ARelativeToolErrorOverTheLimitStopsBothArmsNamingTheLaggingArm) {
  const Stopped r = run("safety: {carry_error: 0.0002}\n");
  expect_both_stopped(r, "protective_stop", "lags");
  EXPECT_THAT(r.result.reason, HasSubstr("relative tool error"));
  EXPECT_THAT(r.result.reason, HasSubstr("limits 0.2 mm"));
}

}  // namespace
}  // namespace cellwright::cell
