// The shipped coordinated carry (scenes/beam.yaml, issue 27) in the MuJoCo twin, lock-step: the PUMA and the MELFA
// carry a 0.8 m beam held by friction at its ends from the input stand to the fixture. What a user checks in the
// event log, the report and the outcome: every segment of the block starts on both arms in the same control period
// with the same driver duration, ends on both within one control period, and the beam lies level on the fixture.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/sim/sweep.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <cmath>
#include <map>
#include <sstream>
#include <string>

namespace cellwright::cell {
namespace {

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

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
}

}  // namespace
}  // namespace cellwright::cell
