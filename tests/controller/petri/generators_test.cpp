// The generated nets have the structure and state-space sizes their headers promise (checked against the naive
// explorer, not only against analyze()).
#include "cellwright/petri/generators.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

#include "cellwright/petri/analysis.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

TEST(Generators, RobotCellCountsMatchTheClosedFormAndTheNaiveExplorer) {
  struct Shape {
    int robots, steps, regions;
  };
  for (const Shape s : {Shape{1, 2, 0}, Shape{2, 3, 1}, Shape{3, 6, 2}, Shape{4, 7, 2}, Shape{3, 9, 3}}) {
    SCOPED_TRACE(fmt::format("{} robots, {} steps, {} regions", s.robots, s.steps, s.regions));
    const Net net = generators::robot_cell(s.robots, s.steps, s.regions);
    EXPECT_EQ(net.num_transitions(), static_cast<std::size_t>(s.robots * s.steps));
    EXPECT_EQ(net.regions().size(), static_cast<std::size_t>(s.regions));
    EXPECT_EQ(net.robots().size(), static_cast<std::size_t>(s.robots));
    const auto naive = testnets::naive_explore(net, 1'000'000);
    ASSERT_TRUE(naive.complete);
    EXPECT_EQ(naive.states, generators::robot_cell_reachable(s.robots, s.steps, s.regions));
    const AnalysisResult r = analyze(net);
    EXPECT_EQ(r.states, naive.states);
    EXPECT_TRUE(r.ok()) << format_report(net, r);
    for (const RegionCheck& rc : r.regions) EXPECT_EQ(rc.max_inside, 1u);
  }
  // 2 robots, 6 steps, 2 regions by hand: 36 position pairs less the 2 * 4 with both robots in one region.
  EXPECT_EQ(generators::robot_cell_reachable(2, 6, 2), 28u);
  EXPECT_EQ(generators::robot_cell_reachable(8, 8, 2), 1'507'328u);
}

TEST(Generators, RobotCellCarriesProgramOrigins) {
  const Net net = generators::robot_cell(2, 6, 2);
  const Place& p = net.places()[*net.find_place("r2.c3")];
  EXPECT_EQ(p.kind, PlaceKind::kExecuting);
  EXPECT_EQ(p.origin.robot, "r2");
  EXPECT_EQ(p.origin.line, 4);
  const Transition& t = net.transitions()[*net.find_transition("r1.t0")];
  ASSERT_TRUE(t.starts_robot);
  EXPECT_EQ(*t.starts_robot, 0u);
  EXPECT_EQ(t.starts_primitive, 1);
  EXPECT_EQ(net.places()[*net.find_place("Z1.free")].kind, PlaceKind::kRegion);
}

TEST(Generators, RejectsImpossibleShapes) {
  EXPECT_THROW((void)generators::robot_cell(0, 4, 1), std::invalid_argument);
  EXPECT_THROW((void)generators::robot_cell(2, 5, 2), std::invalid_argument);  // regions would overlap
  EXPECT_THROW((void)generators::robot_cell(2, 1, 0), std::invalid_argument);
  EXPECT_THROW((void)generators::philosophers(0), std::invalid_argument);
  EXPECT_THROW((void)generators::lockstep_program(0, 4), std::invalid_argument);
  // A loop's body must end with empty hands: 1 or 2 lines (mod 4) leave a workpiece held.
  EXPECT_THROW((void)generators::lockstep_program(2, 6, 3), std::invalid_argument);
  EXPECT_THROW((void)generators::lockstep_program(2, 5, 3), std::invalid_argument);
  EXPECT_NO_THROW((void)generators::lockstep_program(2, 5));
}

TEST(Generators, LockStepProgramInALoop) {
  const std::string text = generators::lockstep_program(3, 4, 7);
  EXPECT_NE(text.find("\nrepeat 7\n  Pick W1 |  | Pick W2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\n  signal s1 | wait s1 | \nend\nend\n"), std::string::npos) << text;
}

TEST(Generators, KanbanClosedFormMatchesPublishedSizes) {
  EXPECT_EQ(generators::kanban_reachable(1), 160u);
  EXPECT_EQ(generators::kanban_reachable(2), 4'600u);
  EXPECT_EQ(generators::kanban_reachable(3), 58'400u);
  EXPECT_EQ(generators::kanban_reachable(5), 2'546'432u);
  const auto naive = testnets::naive_explore(generators::kanban(2), 1'000'000);
  EXPECT_EQ(naive.states, 4'600u);
}

TEST(Generators, OnePhilosopherDeadlocksAfterTakingTheOnlyFork) {
  const Net net = generators::philosophers(1);
  const AnalysisResult r = analyze(net);
  EXPECT_EQ(r.states, 2u);
  EXPECT_EQ(r.deadlocks, 1u);
}

}  // namespace
}  // namespace cellwright::petri
