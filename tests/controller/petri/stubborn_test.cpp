// Stubborn-set reduction (stubborn.hpp, AnalysisOptions::reduction): the reduced search gives the verdicts of full
// exploration (deadlocks, each region, boundedness) on hundreds of random nets and generated programs with and without
// loops, fewer markings, and the structural facts it relies on (finite runs, bounding weightings of the places).
#include "cellwright/petri/stubborn.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <algorithm>

#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cellwright/petri/agglomerate.hpp"
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
using testnets::program_net;
using testnets::replay;

// The stubborn-set search alone (agglomerate false: its own guarantees, shortest deadlock paths included, are checked
// here), or after the net reduction (agglomerate.hpp), as `twin check` runs it.
AnalysisResult reduced(const Net& net, std::uint64_t max_states = 5'000'000, bool agglomerate = false) {
  AnalysisOptions o;
  o.reduction = Reduction::kStubborn;
  o.max_states = max_states;
  o.agglomerate = agglomerate;
  return analyze(net, o);
}



// What the comparison saw, so that the test can insist every kind of net was among the samples.
struct Tally {
  int compared = 0, deadlocking = 0, violating = 0, unbounded = 0, cyclic_regions_reduced = 0, fell_back = 0,
      smaller = 0, skipped = 0, linear_program = 0, agglomerated = 0, delayed = 0;
};

// A violation witness is a firing sequence of `net` to the marking given, with more than the capacity inside.
void expect_violation_witness(const Net& net, std::size_t k, const RegionCheck& rc) {
  ASSERT_TRUE(rc.witness.has_value());
  const Marking m = replay(net, rc.witness->path);
  EXPECT_EQ(m, rc.witness->marking);
  Tokens inside = 0;
  for (PlaceId p : net.regions()[k].inside) inside += m[p];
  EXPECT_GT(inside, net.regions()[k].capacity);
}

// The stubborn-set search after the net reduction (agglomerate.hpp) gives full exploration's verdicts, the exact
// numbers of deadlocks and proper ends, each region's largest occupancy, and counterexamples that are firing
// sequences of the original net.
void compare_agglomerated(const Net& net, const AnalysisResult& full, Tally& tally) {
  SCOPED_TRACE("agglomerated");
  constexpr std::uint64_t kLimit = 200'000;
  const AnalysisResult red = reduced(net, kLimit, true);
  const Agglomeration agg = agglomerate(net);
  EXPECT_EQ(red.net_reduction.empty(), !agg.changed());
  if (agg.changed()) ++tally.agglomerated;
  if (agg.pre > 0) ++tally.delayed;
  EXPECT_EQ(red.bounded, full.bounded) << format_report(net, red);
  if (!full.bounded) {
    ASSERT_TRUE(red.unbounded_witness.has_value());
    EXPECT_EQ(replay(net, red.unbounded_witness->path), red.unbounded_witness->marking);
    return;
  }
  ASSERT_TRUE(red.complete) << red.stop_reason;
  EXPECT_EQ(red.deadlocks, full.deadlocks);
  EXPECT_EQ(red.final_states, full.final_states);
  if (full.deadlocks > 0) {
    ASSERT_FALSE(red.deadlock_examples.empty());
    const Deadlock& d = red.deadlock_examples.front();
    EXPECT_EQ(replay(net, d.path), d.marking);
    EXPECT_TRUE(is_dead(net, d.marking));
    EXPECT_FALSE(net.is_final(d.marking));
    if (red.net_reduction.empty()) {
      EXPECT_EQ(d.path.size(), full.deadlock_examples.front().path.size());
    }
  }
  EXPECT_EQ(red.mutex_ok, full.mutex_ok);
  ASSERT_EQ(red.regions.size(), full.regions.size());
  for (std::size_t k = 0; k < full.regions.size(); ++k) {
    SCOPED_TRACE(full.regions[k].name);
    EXPECT_EQ(red.regions[k].exclusive, full.regions[k].exclusive);
    if (red.regions[k].by_invariant) {
      EXPECT_LE(red.regions[k].max_inside, full.regions[k].max_inside);
    } else {
      EXPECT_EQ(red.regions[k].max_inside, full.regions[k].max_inside);
    }
    if (!red.regions[k].exclusive) expect_violation_witness(net, k, red.regions[k]);
  }
  EXPECT_EQ(red.ok(), full.ok());
}

__extension__ typedef unsigned __int128 Wide;

// A bounding weighting found for `net` is one (checked here independently of is_bounding_weighting: the weighted
// token sum never grows along any transition), and every place bound of a full exploration respects it:
// bound(p) * y(p) <= y . m0.
void check_weighting(const Net& net, const BoundingWeights& w, const AnalysisResult& full) {
  ASSERT_EQ(w.weight.size(), net.num_places());
  for (std::uint64_t y : w.weight) EXPECT_GE(y, 1u);
  for (const Transition& t : net.transitions()) {
    Wide in = 0, out = 0;
    for (const Arc& a : t.inputs) in += static_cast<Wide>(w.weight[a.place]) * a.weight;
    for (const Arc& a : t.outputs) out += static_cast<Wide>(w.weight[a.place]) * a.weight;
    EXPECT_LE(out, in) << t.id;
  }
  EXPECT_TRUE(is_bounding_weighting(net, w.weight));
  EXPECT_TRUE(full.bounded) << "a bounding weighting for an unbounded net";
  if (!full.complete || full.place_bounds.size() != net.num_places()) return;
  Wide total = 0;
  for (std::size_t p = 0; p < net.num_places(); ++p) total += static_cast<Wide>(w.weight[p]) * net.places()[p].initial;
  for (std::size_t p = 0; p < net.num_places(); ++p) {
    EXPECT_LE(static_cast<Wide>(full.place_bounds[p]) * w.weight[p], total) << net.places()[p].id;
  }
}

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
  compare_agglomerated(net, full, tally);
  const AnalysisResult red = reduced(net, kLimit);
  ++tally.compared;
  if (const auto w = bounding_weights(net)) {
    check_weighting(net, *w, full);
    if (w->linear_program) ++tally.linear_program;
  }
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
    if (red.regions[k].by_invariant) {
      // Proved exclusive by a place invariant: the exploration no longer watches it, so it has seen at most the
      // largest occupancy, and the invariant's bound covers that.
      EXPECT_TRUE(full.regions[k].exclusive);
      EXPECT_LE(red.regions[k].max_inside, full.regions[k].max_inside);
      EXPECT_GE(red.regions[k].invariant_bound, full.regions[k].max_inside);
    } else {
      EXPECT_EQ(red.regions[k].max_inside, full.regions[k].max_inside);
    }
    if (!red.regions[k].exclusive) {
      expect_violation_witness(net, k, red.regions[k]);
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
      "%d cyclic with regions reduced, %d fell back, %d smaller, %d shown bounded by the linear program, "
      "%d agglomerated (%d with delayed transitions)\n",
      what, tally.compared, tally.skipped, tally.deadlocking, tally.violating, tally.unbounded,
      tally.cyclic_regions_reduced, tally.fell_back, tally.smaller, tally.linear_program, tally.agglomerated,
      tally.delayed);
  EXPECT_GE(tally.compared, at_least.compared);
  EXPECT_GE(tally.deadlocking, at_least.deadlocking);
  EXPECT_GE(tally.violating, at_least.violating);
  EXPECT_GE(tally.unbounded, at_least.unbounded);
  EXPECT_GE(tally.cyclic_regions_reduced, at_least.cyclic_regions_reduced);
  EXPECT_GE(tally.fell_back, at_least.fell_back);
  EXPECT_GE(tally.smaller, at_least.smaller);
  EXPECT_GE(tally.linear_program, at_least.linear_program);
  EXPECT_GE(tally.agglomerated, at_least.agglomerated);
  EXPECT_GE(tally.delayed, at_least.delayed);
}

using testnets::random_looping_program;

TEST(Stubborn, SameVerdictsAsFullExplorationOnRandomCellPrograms) {
  Tally at_least;
  at_least.compared = 550;
  at_least.deadlocking = 30;
  at_least.violating = 20;
  at_least.unbounded = 20;
  at_least.cyclic_regions_reduced = 10;
  at_least.fell_back = 1;  // bounded, but not for every initial marking
  at_least.smaller = 100;
  at_least.linear_program = 10;
  at_least.agglomerated = 400;
  at_least.delayed = 200;
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
  // Every table of two robots or more has a barrier, whose waits the net reduction fuses (12 tables and the scenes).
  EXPECT_GE(tally.delayed, 12);
}

TEST(Stubborn, SameVerdictsAsFullExplorationOnRandomLoopingPrograms) {
  // Compiled programs with loops: cyclic nets whose leaders tell their followers again or exit every iteration.
  Tally tally;
  int looping = 0;
  for (std::uint64_t seed = 1; seed <= 400; ++seed) {
    const std::string text = random_looping_program(seed);
    SCOPED_TRACE(text);
    Net net;
    ASSERT_NO_THROW(net = program_net(text));
    if (!finite_runs(net)) ++looping;
    compare(net, tally);
  }
  std::printf(
      "random looping programs: %d compared (%d skipped at the state limit, %d cyclic), %d deadlocking, %d unbounded, "
      "%d fell back, %d smaller, %d shown bounded by the linear program, %d agglomerated (%d with delayed "
      "transitions)\n",
      tally.compared, tally.skipped, looping, tally.deadlocking, tally.unbounded, tally.fell_back, tally.smaller,
      tally.linear_program, tally.agglomerated, tally.delayed);
  EXPECT_GE(tally.compared, 380);
  EXPECT_GE(looping, 300);
  EXPECT_GE(tally.deadlocking, 30);
  EXPECT_GE(tally.unbounded, 20);
  EXPECT_GE(tally.smaller, 100);
  EXPECT_GE(tally.linear_program, 90);
  EXPECT_GE(tally.agglomerated, 350);
  EXPECT_GE(tally.delayed, 180);
}

TEST(Stubborn, SameVerdictsAsFullExplorationOnRandomProgramsWithDevices) {
  // The looping programs again, now commanding a machine, a belt and its photo-eye too (issue 27: every kind of
  // command a cell program has), with and without the net reduction.
  Tally tally;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    const std::string text = random_looping_program(seed, true);
    SCOPED_TRACE(text);
    Net net;
    ASSERT_NO_THROW(net = program_net(text));
    compare(net, tally);
  }
  std::printf(
      "random programs with devices: %d compared (%d skipped at the state limit), %d deadlocking, %d unbounded, "
      "%d fell back, %d smaller, %d agglomerated (%d with delayed transitions)\n",
      tally.compared, tally.skipped, tally.deadlocking, tally.unbounded, tally.fell_back, tally.smaller,
      tally.agglomerated, tally.delayed);
  EXPECT_GE(tally.compared, 150);
  EXPECT_GE(tally.deadlocking, 50);
  EXPECT_GE(tally.agglomerated, 150);
  EXPECT_GE(tally.delayed, 20);
}

TEST(Stubborn, LoopingLockStepTablesAreReducedAndShownBounded) {
  Tally tally;
  for (int robots = 1; robots <= 4; ++robots) {
    for (int lines : {3, 4, 7, 8}) compare(program_net(generators::lockstep_program(robots, lines, 5)), tally);
  }
  EXPECT_EQ(tally.skipped, 0);
  EXPECT_EQ(tally.fell_back, 0);
  EXPECT_GE(tally.linear_program, 12);  // every table of two robots or more: the again and exit events need it

  // The count is not in the net; the 12-robot table explores a few markings per transition, as without the loop.
  const Net big = program_net(generators::lockstep_program(12, 20, 1000));
  EXPECT_FALSE(finite_runs(big));
  const auto w = bounding_weights(big);
  ASSERT_TRUE(w.has_value());
  EXPECT_TRUE(w->linear_program);
  EXPECT_TRUE(is_bounding_weighting(big, w->weight));
  const AnalysisResult r = reduced(big);
  ASSERT_TRUE(r.complete) << r.stop_reason;
  EXPECT_TRUE(r.reduced) << r.reduction_note;
  EXPECT_TRUE(r.ok()) << format_report(big, r);
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_LT(r.states, 4 * big.num_transitions());
  EXPECT_EQ(program_net(generators::lockstep_program(12, 20, 3)).num_transitions(), big.num_transitions());
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

TEST(Stubborn, BoundingWeightsExistExactlyWhenNoFiringCountsGrowTheNet) {
  // Completeness, against the other side of Farkas' lemma: a net has no bounding weighting iff some firing counts
  // x >= 0 change no place negatively and some place positively (C x >= 0, C x != 0). The random nets are small
  // enough to search every x in {0..3}^transitions; the seeds are fixed, so the witnesses found are facts.
  int with_weights = 0, with_witness = 0;
  for (std::uint64_t seed = 1; seed <= 400; ++seed) {
    const Net net = generators::random_net(seed);
    SCOPED_TRACE(net.name());
    const std::size_t nt = net.num_transitions(), np = net.num_places();
    std::vector<std::vector<std::int64_t>> c(nt, std::vector<std::int64_t>(np, 0));
    for (std::size_t t = 0; t < nt; ++t) {
      for (const Arc& a : net.transitions()[t].inputs) c[t][a.place] -= a.weight;
      for (const Arc& a : net.transitions()[t].outputs) c[t][a.place] += a.weight;
    }
    bool witness = false;
    std::vector<std::int64_t> x(nt, 0), change(np);
    for (;;) {
      std::size_t k = 0;
      while (k < nt && x[k] == 3) x[k++] = 0;
      if (k == nt) break;
      ++x[k];
      std::fill(change.begin(), change.end(), 0);
      for (std::size_t t = 0; t < nt; ++t) {
        for (std::size_t p = 0; p < np; ++p) change[p] += c[t][p] * x[t];
      }
      const bool none_lower = std::all_of(change.begin(), change.end(), [](std::int64_t v) { return v >= 0; });
      const bool some_raise = std::any_of(change.begin(), change.end(), [](std::int64_t v) { return v > 0; });
      if (none_lower && some_raise) {
        witness = true;
        break;
      }
    }
    const auto w = bounding_weights(net);
    EXPECT_NE(w.has_value(), witness);
    with_weights += w.has_value() ? 1 : 0;
    with_witness += witness ? 1 : 0;
  }
  std::printf("random nets: %d with bounding weights, %d with growing firing counts\n", with_weights, with_witness);
  EXPECT_GE(with_weights, 100);
  EXPECT_GE(with_witness, 100);
}

TEST(Stubborn, AFractionalWeightingIsScaledToIntegers) {
  // t1 takes 3 from a and gives 2 to b, t2 takes 3 from b and gives 4 to a: weights need 2 b <= 3 a and 4 a <= 3 b,
  // and the least (a = 1, b = 4/3) is exact only as the integers 3 and 4.
  NetBuilder b("fraction");
  const PlaceId a = add_place(b, "a", 3);
  const PlaceId bb = add_place(b, "b", 0);
  add_transition(b, "t1", {{a, 3}}, {{bb, 2}});
  add_transition(b, "t2", {{bb, 3}}, {{a, 4}});
  const Net net = std::move(b).build();
  const auto w = bounding_weights(net);
  ASSERT_TRUE(w.has_value());
  EXPECT_TRUE(w->linear_program);
  EXPECT_EQ(w->weight, (std::vector<std::uint64_t>{3, 4}));
  AnalysisOptions options;
  options.reduction = Reduction::kNone;
  check_weighting(net, *w, analyze(net, options));
  // One more token to a from t2 and the weighted sum can grow: no weighting.
  NetBuilder g("growing");
  const PlaceId ga = add_place(g, "a", 3);
  const PlaceId gb = add_place(g, "b", 0);
  add_transition(g, "t1", {{ga, 3}}, {{gb, 2}});
  add_transition(g, "t2", {{gb, 2}}, {{ga, 4}});
  EXPECT_FALSE(bounding_weights(std::move(g).build()).has_value());
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
