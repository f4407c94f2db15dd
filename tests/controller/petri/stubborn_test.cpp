// Stubborn-set reduction (stubborn.hpp, AnalysisOptions::reduction): the reduced search gives the verdicts of full
// exploration (deadlocks, each region, boundedness) on hundreds of random nets, fewer markings, and the structural
// facts it relies on.
#include "cellwright/petri/stubborn.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/program.hpp"
#include "cellwright/task/to_net.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

using testnets::add_place;
using testnets::add_transition;

AnalysisResult reduced(const Net& net, std::uint64_t max_states = 5'000'000) {
  AnalysisOptions o;
  o.reduction = Reduction::kStubborn;
  o.max_states = max_states;
  return analyze(net, o);
}

// Fires `path` from the initial marking (each step must be enabled) and returns the marking reached.
Marking replay(const Net& net, const std::vector<TransitionId>& path) {
  Marking m = net.initial_marking();
  for (TransitionId t : path) {
    EXPECT_TRUE(is_enabled(net, m, t)) << net.transitions()[t].id;
    if (!is_enabled(net, m, t)) return m;
    fire_in_place(net, m, t);
  }
  return m;
}

Net program_net(const std::string& text) {
  return task::to_net(task::compile(task::parse_program(text, "generated.task")));
}

// What the comparison saw, so that the test can insist every kind of net was among the samples.
struct Tally {
  int compared = 0, deadlocking = 0, violating = 0, unbounded = 0, cyclic_regions_reduced = 0, fell_back = 0,
      smaller = 0, skipped = 0;
};

// Full and reduced exploration of one net agree on every verdict; the reduced counterexamples are real and the
// deadlock path is as short as the full one.
void compare(const Net& net, Tally& tally) {
  SCOPED_TRACE(net.name());
  constexpr std::uint64_t kLimit = 200'000;
  AnalysisOptions full_options;
  full_options.max_states = kLimit;
  const AnalysisResult full = analyze(net, full_options);
  if (!full.complete && full.bounded) {  // the state limit, not a verdict
    ++tally.skipped;
    return;
  }
  const AnalysisResult red = reduced(net, kLimit);
  ++tally.compared;
  EXPECT_EQ(red.reduction, Reduction::kStubborn);
  EXPECT_EQ(red.bounded, full.bounded) << format_report(net, red);
  if (!full.bounded) {
    ++tally.unbounded;
    ASSERT_TRUE(red.unbounded_witness.has_value());
    // The witness is a real firing sequence to a marking that covers an earlier one on it.
    EXPECT_EQ(replay(net, red.unbounded_witness->path), red.unbounded_witness->marking);
    return;
  }
  ASSERT_TRUE(red.complete) << red.stop_reason;
  if (red.reduced) {
    EXPECT_LE(red.states, full.states);
    if (red.states < full.states) ++tally.smaller;
    EXPECT_TRUE(red.reduction_note.empty());
  } else {
    ++tally.fell_back;
    EXPECT_FALSE(red.reduction_note.empty());
    EXPECT_EQ(red.states, full.states);
  }
  if (red.reduced && !finite_runs(net) && !net.regions().empty()) ++tally.cyclic_regions_reduced;
  // Every dead marking is kept: the counts are exact, not only the yes/no.
  EXPECT_EQ(red.deadlocks, full.deadlocks);
  EXPECT_EQ(red.final_states, full.final_states);
  EXPECT_TRUE(red.deadlock_path_shortest);
  if (full.deadlocks > 0) {
    ++tally.deadlocking;
    ASSERT_FALSE(red.deadlock_examples.empty());
    const Deadlock& d = red.deadlock_examples.front();
    EXPECT_EQ(d.path.size(), full.deadlock_examples.front().path.size()) << "the reduced deadlock path is shortest";
    EXPECT_EQ(replay(net, d.path), d.marking);
    EXPECT_TRUE(is_dead(net, d.marking));
    EXPECT_FALSE(net.is_final(d.marking));
  }
  EXPECT_EQ(red.mutex_ok, full.mutex_ok);
  if (!full.mutex_ok) ++tally.violating;
  ASSERT_EQ(red.regions.size(), full.regions.size());
  for (std::size_t k = 0; k < full.regions.size(); ++k) {
    SCOPED_TRACE(full.regions[k].name);
    EXPECT_EQ(red.regions[k].exclusive, full.regions[k].exclusive);
    EXPECT_EQ(red.regions[k].max_inside, full.regions[k].max_inside);
    if (!red.regions[k].exclusive) {
      ASSERT_TRUE(red.regions[k].witness.has_value());
      const Marking m = replay(net, red.regions[k].witness->path);
      EXPECT_EQ(m, red.regions[k].witness->marking);
      Tokens inside = 0;
      for (PlaceId p : net.regions()[k].inside) inside += m[p];
      EXPECT_GT(inside, net.regions()[k].capacity);
      EXPECT_EQ(red.regions[k].witness_shortest, !red.reduced);
    }
  }
  EXPECT_EQ(red.ok(), full.ok());
}

// Compares full and reduced exploration on `count` nets from `make(seed)` and checks that every kind of net was among
// them (the seeds are fixed, so these minima are facts about the sample, printed for the record).
template <typename Make>
void compare_random(const char* what, std::uint64_t count, Make make, const Tally& at_least) {
  Tally tally;
  for (std::uint64_t seed = 1; seed <= count; ++seed) compare(make(seed), tally);
  std::printf(
      "%s: %d compared (%d skipped at the state limit), %d deadlocking, %d violating, %d unbounded, "
      "%d cyclic with regions reduced, %d fell back, %d smaller\n",
      what, tally.compared, tally.skipped, tally.deadlocking, tally.violating, tally.unbounded,
      tally.cyclic_regions_reduced, tally.fell_back, tally.smaller);
  EXPECT_GE(tally.compared, at_least.compared);
  EXPECT_GE(tally.deadlocking, at_least.deadlocking);
  EXPECT_GE(tally.violating, at_least.violating);
  EXPECT_GE(tally.unbounded, at_least.unbounded);
  EXPECT_GE(tally.cyclic_regions_reduced, at_least.cyclic_regions_reduced);
  EXPECT_GE(tally.fell_back, at_least.fell_back);
  EXPECT_GE(tally.smaller, at_least.smaller);
}

TEST(Stubborn, SameVerdictsAsFullExplorationOnRandomCellPrograms) {
  Tally at_least;
  at_least.compared = 550;
  at_least.deadlocking = 30;
  at_least.violating = 20;
  at_least.unbounded = 20;
  at_least.cyclic_regions_reduced = 10;
  at_least.fell_back = 5;
  at_least.smaller = 100;
  compare_random("random cells", 600, generators::random_cell, at_least);
}

TEST(Stubborn, SameVerdictsAsFullExplorationOnRandomNets) {
  Tally at_least;
  at_least.compared = 350;
  at_least.deadlocking = 30;
  at_least.violating = 10;
  at_least.unbounded = 30;
  at_least.smaller = 20;
  compare_random("random nets", 400, generators::random_net, at_least);
}

TEST(Stubborn, SameVerdictsOnGeneratedLockStepProgramsAndTheShippedExamples) {
  Tally tally;
  for (int robots = 1; robots <= 4; ++robots) {
    for (int lines = 1; lines <= 5; ++lines) compare(program_net(generators::lockstep_program(robots, lines)), tally);
  }
  for (const char* scene : {"exchange.task", "pick_place.task", "regions.task", "deadlock.task", "pipeline.task"}) {
    compare(task::to_net(task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/" + scene)), tally);
  }
  EXPECT_EQ(tally.skipped, 0);
  EXPECT_GE(tally.deadlocking, 1);  // scenes/deadlock.task
}

TEST(Stubborn, ALockStepTableExploresAlmostOneInterleaving) {
  // Independent robots between barriers: the reduced search follows one order of their commands.
  const Net net = program_net(generators::lockstep_program(4, 2));
  const AnalysisResult full = analyze(net);
  const AnalysisResult red = reduced(net);
  ASSERT_TRUE(full.complete);
  ASSERT_TRUE(red.complete);
  EXPECT_TRUE(red.reduced);
  EXPECT_TRUE(red.ok()) << format_report(net, red);
  EXPECT_EQ(red.final_states, 1u);
  EXPECT_LT(red.states * 100, full.states) << red.states << " reduced vs " << full.states;

  const Net big = program_net(generators::lockstep_program(12, 20));
  const AnalysisResult r = reduced(big);
  ASSERT_TRUE(r.complete) << r.stop_reason;
  EXPECT_TRUE(r.ok()) << format_report(big, r);
  // At most a few markings per transition (each fires once in a run).
  EXPECT_LT(r.states, 4 * big.num_transitions());
}

TEST(Stubborn, PumpIgnoredForADrainIsStillFoundUnbounded) {
  // t1 pumps q, t2 drains it: the stubborn set {t2} at {p, q, r} closes a cycle with the fully expanded {p, r}, so a
  // reduced graph alone would look finite. The net is not structurally bounded, so the verdict must come from a search
  // that can see the growth.
  NetBuilder b("pump-drain");
  const PlaceId p = add_place(b, "p", 1);
  const PlaceId q = add_place(b, "q", 0);
  const PlaceId r = add_place(b, "r", 1);
  add_transition(b, "t1", {{p, 1}}, {{p, 1}, {q, 1}});
  add_transition(b, "t2", {{q, 1}, {r, 1}}, {{r, 1}});
  const Net net = std::move(b).build();
  EXPECT_FALSE(structurally_bounded(net));
  const AnalysisResult red = reduced(net);
  EXPECT_FALSE(red.bounded);
  EXPECT_EQ(red.unbounded_places, std::vector<PlaceId>{q});
  EXPECT_FALSE(red.ok());
}

TEST(Stubborn, IgnoringProvisoFindsAViolationBehindAnEndlessLoop) {
  // Robot a loops on its own forever (its transitions come first, so they make the smallest stubborn sets); robot b's
  // one step puts a second token inside Z. Without the proviso the reduced search would circle a's loop only.
  NetBuilder b("ignoring");
  auto robot_place = [&](const std::string& id, const std::string& robot, Tokens initial) {
    Place p;
    p.id = id;
    p.name = id;
    p.initial = initial;
    p.kind = PlaceKind::kExecuting;
    p.origin.robot = robot;
    return b.add_place(std::move(p));
  };
  const PlaceId a0 = robot_place("a0", "a", 1), a1 = robot_place("a1", "a", 0);
  const PlaceId b0 = robot_place("b0", "b", 1), b1 = robot_place("b1", "b", 0);
  const PlaceId x = add_place(b, "x", 1);
  add_transition(b, "a.go", {{a0, 1}}, {{a1, 1}});
  add_transition(b, "a.back", {{a1, 1}}, {{a0, 1}});
  add_transition(b, "b.in", {{b0, 1}}, {{b1, 1}});
  Region z;
  z.name = "Z";
  z.inside = {b1, x};
  b.add_region(z);
  const Net net = std::move(b).build();
  EXPECT_FALSE(finite_runs(net));
  EXPECT_TRUE(structurally_bounded(net));
  const AnalysisResult red = reduced(net);
  ASSERT_TRUE(red.complete);
  EXPECT_TRUE(red.reduced);
  EXPECT_FALSE(red.mutex_ok);
  ASSERT_TRUE(red.regions[0].witness.has_value());
  EXPECT_FALSE(red.regions[0].witness_shortest);
  EXPECT_EQ(red.regions[0].max_inside, 2u);
}

TEST(Stubborn, StructuralFacts) {
  // Acyclic programs: every run finite.
  EXPECT_TRUE(finite_runs(program_net(generators::lockstep_program(3, 4))));
  EXPECT_FALSE(finite_runs(generators::philosophers(3)));
  // Robots looping through a region, handshaken by its token: bounded by structure, with cycles.
  const Net loop = testnets::region_loop(3);
  EXPECT_FALSE(finite_runs(loop));
  EXPECT_TRUE(structurally_bounded(loop));
  // Kanban conserves tokens; robot_cell loops through regions.
  EXPECT_TRUE(structurally_bounded(generators::kanban(2)));
  EXPECT_TRUE(structurally_bounded(generators::robot_cell(3, 6, 2)));
  // A transition without inputs that produces: nothing bounds it.
  NetBuilder b("source");
  const PlaceId p = add_place(b, "p");
  add_transition(b, "t", {}, {{p, 1}});
  const Net source = std::move(b).build();
  EXPECT_FALSE(finite_runs(source));
  EXPECT_FALSE(structurally_bounded(source));
}

TEST(Stubborn, StubbornSetOfIndependentRobotsIsOneTransition) {
  const Net net = generators::robot_cell(4, 6, 0);
  StubbornSets s(net);
  const Marking m = net.initial_marking();
  std::vector<TransitionId> out;
  s.choose(
      enabled(net, m), [&](PlaceId p) { return m[p]; }, out);
  EXPECT_EQ(out.size(), 1u);
  // Robots competing for a region's token at its entry are in one set (they conflict).
  const Net contended = testnets::region_loop(3);
  StubbornSets c(contended);
  const Marking m0 = contended.initial_marking();
  c.choose(
      enabled(contended, m0), [&](PlaceId p) { return m0[p]; }, out);
  EXPECT_EQ(out.size(), 3u);
}

}  // namespace
}  // namespace cellwright::petri
