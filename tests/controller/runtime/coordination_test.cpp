// Coordinated blocks executed by the runtime (issue 27, docs/runtime.md "Coordinated blocks"): two scripted arms of
// scenes/beam_cell.yaml carry the beam of scenes/beam.task in lock-step on a kinematic plant. What a user checks in
// the event log: every segment starts on both robots in the same control period and ends within one, even when one
// arm is much slower than the other; while both hold the beam the follower's tool keeps the grasp transform to the
// master's; the beam ends on the fixture. Also the rendezvous board alone.
#include "cellwright/runtime/coordination.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/runtime/scripted_plant.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::milliseconds;

TEST(Coordination, AgreesOnTheLongerLeastTimeOnlyAfterBothPostedAndTheNextTurn) {
  Coordination board;
  EXPECT_FALSE(board.master_post("carry", 0).has_value());
  board.post("carry", 0, true, SegmentPost{Eigen::Isometry3d::Identity(), 1.5, milliseconds(100)});
  ASSERT_TRUE(board.master_post("carry", 0).has_value());
  EXPECT_FALSE(board.agreed("carry", 0, milliseconds(110)).has_value());  // the follower has not posted
  board.post("carry", 0, false, SegmentPost{std::nullopt, 2.25, milliseconds(110)});
  EXPECT_FALSE(board.agreed("carry", 0, milliseconds(110)).has_value());  // not in the turn of the later post
  ASSERT_TRUE(board.agreed("carry", 0, milliseconds(120)).has_value());
  EXPECT_DOUBLE_EQ(*board.agreed("carry", 0, milliseconds(120)), 2.25);
  EXPECT_FALSE(board.agreed("carry", 1, milliseconds(120)).has_value());  // another segment
  board.taken("carry", 0, true);
  EXPECT_TRUE(board.agreed("carry", 0, milliseconds(120)).has_value());  // the follower has not taken it yet
  board.taken("carry", 0, false);
  EXPECT_FALSE(board.master_post("carry", 0).has_value());  // forgotten once both took it
}

TEST(Coordination, TheCarryWatchIsClaimedOncePerPeriodAndAStopIsSeenByBoth) {
  Coordination board;
  EXPECT_FALSE(board.grasp("carry").has_value());
  board.set_grasp("carry", Eigen::Isometry3d(Eigen::Translation3d(0.68, 0, 0)));
  ASSERT_TRUE(board.grasp("carry").has_value());
  EXPECT_DOUBLE_EQ(board.grasp("carry")->translation().x(), 0.68);
  EXPECT_TRUE(board.claim_watch("carry", milliseconds(100)));    // the first robot of the period checks
  EXPECT_FALSE(board.claim_watch("carry", milliseconds(100)));   // the second does not
  EXPECT_TRUE(board.claim_watch("carry", milliseconds(110)));    // the next period anew
  EXPECT_TRUE(board.claim_watch("other", milliseconds(110)));    // another block on its own
  EXPECT_FALSE(board.stopped("carry").has_value());
  board.stop("carry", "right lags left");
  board.stop("carry", "a later reason");
  ASSERT_TRUE(board.stopped("carry").has_value());
  EXPECT_EQ(*board.stopped("carry"), "right lags left");  // the first reason stays
  EXPECT_FALSE(board.stopped("other").has_value());
  board.forget_carry("carry");
  EXPECT_FALSE(board.grasp("carry").has_value());
  EXPECT_TRUE(board.stopped("carry").has_value());  // a stop stays
}

// A scripted arm that times its moves: a move takes 1 ms per `ms_per_mrad` of its largest joint change (at least
// 50 ticks), a grip 40 ticks; a timed move at least its duration.
drivers::ScriptedDriverConfig timed_arm(const models::RobotSpec& spec, double ms_per_mrad) {
  drivers::ScriptedDriverConfig c = cellwright::testing::scripted_arm(spec, {});
  c.capabilities.timed_motion = true;
  // The driver's own joints are not visible to ticks_for: a move's time follows from its goal's distance from home,
  // a stand-in for a distance-dependent profile that differs between the arms.
  const std::vector<double> home = spec.home;
  c.ticks_for = [home, ms_per_mrad](const drivers::Command& cmd) -> std::uint64_t {
    if (const auto* m = std::get_if<drivers::MoveJoints>(&cmd)) {
      double most = 0;
      for (std::size_t j = 0; j < home.size(); ++j) most = std::max(most, std::abs(m->positions[j] - home[j]));
      return std::max<std::uint64_t>(50, static_cast<std::uint64_t>(most * 1000.0 / ms_per_mrad));
    }
    return 40;
  };
  return c;
}

struct BeamRun {
  explicit BeamRun(double melfa_ms_per_mrad) {
    cell = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/beam_cell.yaml");
    for (const auto& r : cell.robots) {
      drivers.emplace(r.name, std::make_unique<drivers::ScriptedDriver>(
                                  timed_arm(r, r.name == "melfa" ? melfa_ms_per_mrad : 2.0)));
      chains.emplace(r.name, models::robot_chain(r));
      bases.emplace(r.name, r.base.transform());
    }
    std::map<std::string, drivers::ScriptedDriver*> raw;
    for (auto& [name, d] : drivers) raw[name] = d.get();
    plant = std::make_unique<ScriptedPlant>(cell, raw);
    config.program = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/beam.task");
    config.net = task::to_net(config.program);
    config.cell = cell;
    config.binding.where = {"beam.yaml", 1, 1};
    config.binding.robots["left"] = {"puma", {"beam.yaml", 2, 1}};
    config.binding.robots["right"] = {"melfa", {"beam.yaml", 2, 20}};
    config.binding.objects["FIX"] = {"beam_fix", {"beam.yaml", 3, 1}};
    config.binding.objects["MID"] = {"beam_mid", {"beam.yaml", 3, 20}};
    for (auto& [name, d] : drivers) config.drivers[name] = d.get();
    config.plant = plant.get();
    config.sensors = plant->sensors();
    config.limits.sim_time = std::chrono::seconds(60);
  }
  Eigen::Isometry3d tool(const std::string& robot) const {
    const std::vector<double> q = drivers.at(robot)->joints();
    const Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
    return bases.at(robot) * chains.at(robot).forward(v);
  }
  models::CellDescription cell;
  std::map<std::string, std::unique_ptr<drivers::ScriptedDriver>> drivers;
  std::map<std::string, models::KinematicChain> chains;
  std::map<std::string, Eigen::Isometry3d> bases;
  std::unique_ptr<ScriptedPlant> plant;
  RunConfig config;
};

struct SegmentTimes {
  std::map<std::string, double> start, end;  // per robot label
};

TEST(CoordinatedRun, BothArmsStartEachSegmentInOnePeriodAndEndWithinOneEvenWhenOneIsFourTimesSlower) {
  BeamRun run(0.5);  // the MELFA's moves take four times the PUMA's
  // While both hold the beam, at the end of each segment (once both ended it) the master's tool -> follower's tool.
  std::vector<Eigen::Isometry3d> relation;
  std::map<int, int> ended;  // segment index -> robots that ended it
  const auto& progs = run.config.program.programs;
  run.config.event_observers.push_back([&](const LogEvent& e) {
    const auto* end = std::get_if<events::CommandEnd>(&e);
    if (end == nullptr || !end->ok) return;
    const std::size_t r = end->robot == "left" ? 0 : 1;
    const task::Primitive& p = progs[r].primitives[end->primitive];
    if (!p.segment) return;
    // Segments 5 (the lift) to 9 (the put-down): the beam is held by both.
    if (++ended[p.segment->index] == 2 && p.segment->index >= 5 && p.segment->index <= 9) {
      relation.push_back(run.tool("puma").inverse() * run.tool("melfa"));
    }
  });
  Runtime rt(run.config);
  const RunResult result = rt.run();
  ASSERT_EQ(result.outcome, Outcome::kFinished) << result.reason << "\n" << rt.log().text();

  std::map<int, SegmentTimes> seg;
  for (const auto& line : rt.log().lines()) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] != "command_start" && e["type"] != "command_end") continue;
    const std::string robot = e["robot"];
    const task::Primitive& p = progs[robot == "left" ? 0 : 1].primitives[e["primitive"].get<std::size_t>()];
    if (!p.segment) continue;
    auto& times = e["type"] == "command_start" ? seg[p.segment->index].start : seg[p.segment->index].end;
    times[robot] = e["t"].get<double>();
    if (e["type"] == "command_start" && p.kind == task::PrimitiveKind::kMove) {
      EXPECT_NE(e["detail"].get<std::string>().find(" duration "), std::string::npos) << e["detail"];
    }
  }
  ASSERT_EQ(seg.size(), 10u);  // Pick: 5, via: 1, Place: 4
  for (const auto& [k, t] : seg) {
    ASSERT_EQ(t.start.size(), 2u) << "segment " << k;
    ASSERT_EQ(t.end.size(), 2u) << "segment " << k;
    EXPECT_EQ(t.start.at("left"), t.start.at("right")) << "segment " << k;
    EXPECT_LE(std::abs(t.end.at("left") - t.end.at("right")), 0.01 + 1e-9) << "segment " << k;
  }
  // The slower arm set the time: the carry over MID (segment 6) lasted what the MELFA needs, not the PUMA's time.
  EXPECT_GT(seg[6].end.at("left") - seg[6].start.at("left"), 0.1);

  ASSERT_EQ(relation.size(), 5u);
  for (const Eigen::Isometry3d& g : relation) {
    EXPECT_LT((g.translation() - relation.front().translation()).norm(), 1e-3);
    EXPECT_LT(Eigen::AngleAxisd(g.linear() * relation.front().linear().transpose()).angle(), 1e-3);
  }
  // The beam lies on the fixture, level, held by nobody.
  const Eigen::Isometry3d beam = run.plant->workpiece_pose("beam");
  const Eigen::Vector3d fix = run.cell.find_location("beam_fix")->pose.xyz;
  EXPECT_LT((beam.translation().head<2>() - fix.head<2>()).norm(), 0.01) << beam.translation().transpose();
  EXPECT_NEAR(beam.translation().z() - 0.02, fix.z(), 0.005);
  EXPECT_LT(std::abs(beam.linear().col(0).z()), 1e-3);  // not tilted
  EXPECT_EQ(result.environment.find_workpiece("beam")->held_by, "");
}

TEST(CoordinatedRun, ADriverThatCannotTimeItsMovesFailsTheSegmentNamingIt) {
  BeamRun run(2.0);
  drivers::ScriptedDriverConfig untimed = timed_arm(*run.cell.find_robot("melfa"), 2.0);
  untimed.capabilities.timed_motion = false;
  run.drivers["melfa"] = std::make_unique<drivers::ScriptedDriver>(untimed);
  std::map<std::string, drivers::ScriptedDriver*> raw;
  for (auto& [name, d] : run.drivers) raw[name] = d.get();
  run.plant = std::make_unique<ScriptedPlant>(run.cell, raw);
  run.config.drivers["melfa"] = run.drivers["melfa"].get();
  run.config.plant = run.plant.get();
  run.config.sensors = run.plant->sensors();
  Runtime rt(run.config);
  const RunResult result = rt.run();
  EXPECT_EQ(result.outcome, Outcome::kFailed);
  EXPECT_NE(result.reason.find("the driver of melfa cannot tell how long"), std::string::npos) << result.reason;
  EXPECT_NE(result.reason.find("cannot be timed"), std::string::npos) << result.reason;
}

}  // namespace
}  // namespace cellwright::runtime
