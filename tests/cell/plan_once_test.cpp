// Planned once, compiled once (issue 24): the preflight's motion plan is the one the estimate, the run and the robot
// programs use (none plans again), a run and its preflight's sweep share one compiled model of the cell, and the
// twin's estimate (what `twin campaign` reads) is the run's without building one.
#include <gtest/gtest.h>

#include <string>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/robot_programs.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/common/error.hpp"

namespace cellwright::cell {
namespace {

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// The first move of program robot `robot` that the plan could make.
PlannedCommand& first_move(MotionPlan& plan, std::size_t robot) {
  for (PlannedCommand& c : plan.commands.at(robot)) {
    if (c.kind == task::PrimitiveKind::kMove && !c.goal.empty()) return c;
  }
  throw std::runtime_error("no move");
}

const CommandEstimate& estimate_of(const Estimate& e, const PlannedCommand& c) {
  for (const CommandEstimate& ce : e.commands) {
    if (ce.robot == c.robot && ce.primitive == c.primitive) return ce;
  }
  throw std::runtime_error("no such command");
}

// A plan changed by hand (its first move made to go nowhere) shows in the estimate the run prints and in the twin's
// estimate: neither plans the program again.
TEST(PlanOnce, TheEstimatesTimeThePreflightsPlan) {
  const Scenario s = load_scenario(kScenes + "/exchange.yaml");
  Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();
  ASSERT_TRUE(pre.plan.has_value());
  PlannedCommand& moved = first_move(*pre.plan, 0);
  {
    const ScenarioRun run(s, pre);
    EXPECT_NE(estimate_of(run.estimate(), moved).basis, "joint move, largest step 0.000 rad (joint 1)");
  }
  moved.goal = moved.from;
  const ScenarioRun run(s, pre);
  const Estimate port = twin_port().estimate(s, pre);
  for (const Estimate* e : {&run.estimate(), &port}) {
    const CommandEstimate& c = estimate_of(*e, moved);
    EXPECT_EQ(c.basis, "joint move, largest step 0.000 rad (joint 1)");
    EXPECT_DOUBLE_EQ(c.motion, sim::SimDriverOptions{}.min_move_time);
  }
}

// The robot programs write the preflight's plan: a goal changed in it is the pose the program is sent to.
TEST(PlanOnce, TheRobotProgramsWriteThePreflightsPlan) {
  Scenario s = load_scenario(kScenes + "/exchange.yaml");
  set_language(s, "puma=val2", {"test", 0, 0});
  set_language(s, "melfa=movemaster", {"test", 0, 0});
  Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();
  const RobotPrograms before = generate_robot_programs(s, pre);
  PlannedCommand& moved = first_move(*pre.plan, 0);
  moved.goal = moved.from;
  const RobotPrograms after = generate_robot_programs(s, pre);
  ASSERT_EQ(before.robots.size(), after.robots.size());
  EXPECT_NE(before.robots[0].text, after.robots[0].text);
  EXPECT_EQ(before.robots[1].text, after.robots[1].text);
}

// A run compiles its cell once: its World runs on the model the preflight's sweep compiled, with data of its own.
TEST(PlanOnce, ARunSharesTheModelItsPreflightSweptOn) {
  for (const char* file : {"exchange.yaml", "pipeline_shift.yaml", "vision.yaml"}) {
    const Scenario s = load_scenario(kScenes + "/" + file);
    const Preflight pre = preflight(s, &twin_port());
    ASSERT_TRUE(pre.ok()) << file << ": " << pre.problems.front();
    ASSERT_NE(pre.twin, nullptr) << file;
    ScenarioRun run(s, pre);
    EXPECT_EQ(run.world().scene().model(), pre.twin->scene.model()) << file;
    EXPECT_NE(run.world().data(), pre.twin->scene.data()) << file;
  }
}

// The twin's estimate is the one the run makes, from the same plan and the same timing, and it builds no run: it is
// had for a scenario whose run could not be built here (a robot on a real driver whose port does not exist).
TEST(PlanOnce, TheTwinsEstimateIsTheRunsWithoutARun) {
  for (const char* file : {"exchange.yaml", "pipeline_shift.yaml"}) {
    const Scenario s = load_scenario(kScenes + "/" + file);
    const Preflight pre = preflight(s, &twin_port());
    ASSERT_TRUE(pre.ok()) << file << ": " << pre.problems.front();
    const ScenarioRun run(s, pre);
    const Estimate port = twin_port().estimate(s, pre);
    EXPECT_EQ(port.cycle_time, run.estimate().cycle_time) << file;
    ASSERT_EQ(port.commands.size(), run.estimate().commands.size()) << file;
    for (std::size_t i = 0; i < port.commands.size(); ++i) {
      EXPECT_EQ(port.commands[i].seconds, run.estimate().commands[i].seconds) << file << " command " << i;
      EXPECT_EQ(port.commands[i].basis, run.estimate().commands[i].basis) << file << " command " << i;
    }
  }
  Scenario s = load_scenario(kScenes + "/exchange.yaml");
  set_driver(s, "puma=movemaster:/nonexistent/ttyCW", {"test", 0, 0});
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();
  EXPECT_THROW(ScenarioRun(s, pre), InputError);  // a run would connect the real driver (and refuses lock-step)
  const Scenario simulated = load_scenario(kScenes + "/exchange.yaml");
  const double expected = twin_port().estimate(simulated, preflight(simulated, &twin_port())).cycle_time;
  EXPECT_EQ(twin_port().estimate(s, pre).cycle_time, expected);
}

}  // namespace
}  // namespace cellwright::cell
