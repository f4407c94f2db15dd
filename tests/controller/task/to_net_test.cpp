// The net generated from a compiled program: its structure, and that its behaviour is the program's.
#include "cellwright/task/to_net.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"

namespace cellwright::task {
namespace {

Primitive prim(PrimitiveKind kind, const std::string& arg = "", int line = 1) {
  Primitive p;
  p.kind = kind;
  if (kind == PrimitiveKind::kSignal || kind == PrimitiveKind::kWait) p.event = arg;
  if (kind == PrimitiveKind::kMove) p.target = Target{TargetKind::kAbove, arg};
  p.where = SourceLocation{"t.task", line, 3};
  p.task = "cmd on line " + std::to_string(line);
  p.motion = "motion";
  return p;
}

CompiledProgram two_robots(std::vector<Primitive> a, std::vector<Primitive> b, std::vector<Semaphore> sems) {
  CompiledProgram c;
  c.file = "t.task";
  c.robots = {"r1", "r2"};
  c.programs = {RobotProgram{"r1", std::move(a), {}}, RobotProgram{"r2", std::move(b), {}}};
  c.semaphores = std::move(sems);
  return c;
}

TEST(ToNet, ChainPerRobotWithSharedEventPlace) {
  const auto c = two_robots({prim(PrimitiveKind::kMove, "A"), prim(PrimitiveKind::kSignal, "e")},
                            {prim(PrimitiveKind::kWait, "e"), prim(PrimitiveKind::kClose)}, {{"e", 0, false, {}}});
  const petri::Net net = to_net(c);
  // Per robot: start + 2 primitive places + done; plus one event place.
  EXPECT_EQ(net.num_places(), 9u);
  // Per robot: one transition per primitive begin plus the finish.
  EXPECT_EQ(net.num_transitions(), 6u);
  EXPECT_EQ(net.robots(), (std::vector<std::string>{"r1", "r2"}));

  const auto ev = net.find_place(event_place_id("e"));
  ASSERT_TRUE(ev);
  EXPECT_EQ(net.places()[*ev].kind, petri::PlaceKind::kEvent);
  EXPECT_EQ(net.places()[*net.find_place(place_id("r2", 0))].kind, petri::PlaceKind::kWaiting);

  // r1's T1 begins the signal: it puts a token on e. r2's T1 ends the wait: it takes one.
  const auto& t_sig = net.transitions()[*net.find_transition(transition_id("r1", 1))];
  EXPECT_TRUE(std::any_of(t_sig.outputs.begin(), t_sig.outputs.end(), [&](auto& a) { return a.place == *ev; }));
  const auto& t_wait_end = net.transitions()[*net.find_transition(transition_id("r2", 1))];
  EXPECT_TRUE(std::any_of(t_wait_end.inputs.begin(), t_wait_end.inputs.end(), [&](auto& a) { return a.place == *ev; }));
  ASSERT_TRUE(t_wait_end.starts_robot);
  EXPECT_EQ(*t_wait_end.starts_robot, 1u);
  EXPECT_EQ(t_wait_end.starts_primitive, 1);
  EXPECT_EQ(t_wait_end.origin.robot, "r2");
}

TEST(ToNet, SignalledProgramRunsToTheEndAndIsNotADeadlock) {
  const auto c = two_robots({prim(PrimitiveKind::kMove, "A"), prim(PrimitiveKind::kSignal, "e")},
                            {prim(PrimitiveKind::kWait, "e"), prim(PrimitiveKind::kClose)}, {{"e", 0, false, {}}});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_TRUE(r.ok());

  // r2 cannot pass its wait before r1 has signalled: play the token game.
  petri::Marking m = net.initial_marking();
  const auto r2_end_wait = *net.find_transition(transition_id("r2", 1));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r2", 0)));
  EXPECT_FALSE(petri::is_enabled(net, m, r2_end_wait));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r1", 0)));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r1", 1)));
  EXPECT_TRUE(petri::is_enabled(net, m, r2_end_wait));
}

TEST(ToNet, CrossedWaitsDeadlockWithAShortestCounterexample) {
  // r1: wait s1, signal s2; r2: wait s2, signal s1 — each waits for the other.
  const auto c = two_robots({prim(PrimitiveKind::kWait, "s1", 4), prim(PrimitiveKind::kSignal, "s2", 5)},
                            {prim(PrimitiveKind::kWait, "s2", 8), prim(PrimitiveKind::kSignal, "s1", 9)},
                            {{"s1", 0, false, {}}, {"s2", 0, false, {}}});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_FALSE(r.ok());
  ASSERT_FALSE(r.deadlock_examples.empty());
  // Both robots begin their waits: two firings, then nothing is enabled and neither robot is done.
  const auto& d = r.deadlock_examples.front();
  EXPECT_EQ(d.path.size(), 2u);
  petri::Marking m = net.initial_marking();
  for (auto t : d.path) petri::fire_in_place(net, m, t);
  EXPECT_EQ(m, d.marking);
  EXPECT_TRUE(petri::enabled(net, m).empty());
  EXPECT_FALSE(net.is_final(m));
  EXPECT_EQ(m[*net.find_place(place_id("r1", 0))], 1u);
  EXPECT_EQ(m[*net.find_place(place_id("r2", 0))], 1u);
  // The counterexample is told in program terms: robot, line, command.
  const std::string text = petri::describe_marking(net, m);
  EXPECT_NE(text.find("r1"), std::string::npos) << text;
  EXPECT_NE(text.find("s1"), std::string::npos) << text;
}

TEST(ToNet, RegionIsAResourcePlaceAndStaysExclusive) {
  // Both robots: enter Z (wait Z), move, leave Z (signal Z).
  auto body = [] {
    return std::vector<Primitive>{prim(PrimitiveKind::kWait, "Z"), prim(PrimitiveKind::kMove, "M"),
                                  prim(PrimitiveKind::kMove, "N"), prim(PrimitiveKind::kSignal, "Z")};
  };
  auto c = two_robots(body(), body(), {{"Z", 1, true, {}}});
  c.regions = {RegionUse{"Z", {{"r1", 1, 3}, {"r2", 1, 3}}}};
  const petri::Net net = to_net(c);
  ASSERT_EQ(net.regions().size(), 1u);
  EXPECT_EQ(net.regions()[0].inside.size(), 4u);
  EXPECT_EQ(net.places()[*net.find_place(event_place_id("Z"))].kind, petri::PlaceKind::kRegion);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.ok());
  ASSERT_EQ(r.regions.size(), 1u);
  EXPECT_TRUE(r.regions[0].exclusive);
  EXPECT_EQ(r.regions[0].max_inside, 1u);

  // With two tokens in the region place the same spans are no longer exclusive, and the check says so.
  c.semaphores[0].initial = 2;
  const auto broken = petri::analyze(to_net(c));
  EXPECT_FALSE(broken.mutex_ok);
  EXPECT_EQ(broken.regions[0].max_inside, 2u);
}

TEST(ToNet, UndeclaredEventIsAnInputErrorAtTheCommand) {
  const auto c = two_robots({prim(PrimitiveKind::kSignal, "nope", 7)}, {}, {});
  try {
    (void)to_net(c);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, 7);
    EXPECT_NE(e.problem().find("nope"), std::string::npos);
  }
}

TEST(ToNet, EmptyProgramGoesStraightToDone) {
  const auto c = two_robots({}, {}, {});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_EQ(r.states, 4u);  // each robot independently: ready or done
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_TRUE(r.ok());
}

}  // namespace
}  // namespace cellwright::task
