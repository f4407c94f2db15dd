// Structural checks (structural.hpp) and what analyze() under Reduction::kStubborn makes of them: region exclusion by
// a place invariant, deadlock freedom by the state equation, a deadlock found by the search it guides. The three
// 12-robot shapes of issue 27 get their verdicts (a lock-step table, twelve sequences sharing one region, twelve
// philosophers), and on hundreds of random nets and programs every verdict reached past a tiny exploration budget
// (so that the structural checks decide) is the verdict of full exploration.
#include "cellwright/petri/structural.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "cellwright/petri/stubborn.hpp"
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


AnalysisResult check(const Net& net, std::uint64_t budget = AnalysisOptions{}.exploration_budget,
                     std::uint64_t max_states = 5'000'000) {
  AnalysisOptions o;
  o.reduction = Reduction::kStubborn;
  o.exploration_budget = budget;
  o.max_states = max_states;
  return analyze(net, o);
}


TEST(Structural, TheLockStepTableOfTwelveRobotsPasses) {
  const Net net = program_net(generators::lockstep_program(12, 20));
  const AnalysisResult r = check(net);
  EXPECT_TRUE(r.ok()) << format_report(net, r);
  EXPECT_TRUE(r.explored_all);  // small enough to explore: exact counts, as before
  EXPECT_EQ(r.final_states, 1u);
}

TEST(Structural, TwelveSequencesSharingOneRegionPassWithTheRegionExclusive) {
  const Net net = program_net(generators::shared_region_program(12));
  ASSERT_EQ(net.regions().size(), 1u);
  const auto proof = prove_region_exclusive(net, 0);
  ASSERT_TRUE(proof.has_value());
  EXPECT_TRUE(is_region_proof(net, 0, *proof));
  EXPECT_EQ(proof->bound, 1u);
  EXPECT_FALSE(proof->linear_program);  // the free place + inside weighting

  const StateEquationResult se = deadlock_free_by_state_equation(net);
  EXPECT_EQ(se.verdict, StateEquationResult::Verdict::kDeadlockFree) << se.reason;

  const AnalysisResult r = check(net);
  EXPECT_TRUE(r.ok()) << format_report(net, r);
  EXPECT_TRUE(r.complete);
  EXPECT_FALSE(r.explored_all);  // the exploration alone would not end (3.5 times the markings per robot)
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_FALSE(r.deadlock_proof.empty());
  ASSERT_EQ(r.regions.size(), 1u);
  EXPECT_TRUE(r.regions[0].exclusive);
  EXPECT_TRUE(r.regions[0].by_invariant);
  EXPECT_EQ(r.regions[0].invariant_bound, 1u);
  const std::string text = format_report(net, r);
  EXPECT_NE(text.find("OK: no deadlock, bounded, mutual exclusion holds"), std::string::npos) << text;
  EXPECT_NE(text.find("by a place invariant"), std::string::npos) << text;
}

TEST(Structural, SmallSharedRegionProgramsGetTheVerdictOfFullExploration) {
  for (int robots = 1; robots <= 4; ++robots) {
    const Net net = program_net(generators::shared_region_program(robots));
    const AnalysisResult full = analyze(net);
    ASSERT_TRUE(full.complete);
    EXPECT_TRUE(full.ok());
    const AnalysisResult forced = check(net, 1);
    EXPECT_TRUE(forced.ok()) << format_report(net, forced);
  }
}

// The philosophers' counterexample: a real firing sequence to a dead marking that is not a proper end.
void expect_real_deadlock(const Net& net, const AnalysisResult& r) {
  EXPECT_FALSE(r.ok());
  EXPECT_GE(r.deadlocks, 1u);
  ASSERT_FALSE(r.deadlock_examples.empty()) << format_report(net, r);
  const Deadlock& d = r.deadlock_examples.front();
  const Marking end = replay(net, d.path);
  EXPECT_EQ(end, d.marking);
  EXPECT_TRUE(is_dead(net, end));
  EXPECT_FALSE(net.is_final(end));
}

TEST(Structural, TwelvePhilosophersAreRefusedWithAReplayableDeadlock) {
  const Net net = program_net(generators::philosophers_program(12));
  for (std::size_t k = 0; k < net.regions().size(); ++k) EXPECT_TRUE(prove_region_exclusive(net, k).has_value());
  const AnalysisResult r = check(net);
  expect_real_deadlock(net, r);
  EXPECT_TRUE(r.mutex_ok);
  EXPECT_TRUE(r.bounded);
  const std::string text = format_report(net, r);
  EXPECT_EQ(text.rfind("FAIL: ", 0), 0u) << text;
  EXPECT_NE(text.find("stuck: "), std::string::npos) << text;
}

TEST(Structural, FiftyPhilosophersAreRefusedThroughTheStateEquation) {
  const Net net = program_net(generators::philosophers_program(50));
  const StateEquationResult se = deadlock_free_by_state_equation(net);
  ASSERT_EQ(se.verdict, StateEquationResult::Verdict::kCandidate) << se.reason;
  const auto path = guided_deadlock_search(net, se.firings);
  ASSERT_TRUE(path.has_value());
  const Marking end = replay(net, *path);
  EXPECT_TRUE(is_dead(net, end));
  EXPECT_FALSE(net.is_final(end));

  const AnalysisResult r = check(net);
  expect_real_deadlock(net, r);
  EXPECT_TRUE(r.complete);
  EXPECT_FALSE(r.explored_all);
  EXPECT_FALSE(r.deadlock_path_shortest);  // found by the guided search: the report says so
  EXPECT_NE(format_report(net, r).find("not necessarily shortest"), std::string::npos);
}

TEST(Structural, FiftySequencesSharingOneRegionPass) {
  const Net net = program_net(generators::shared_region_program(50));
  const AnalysisResult r = check(net);
  EXPECT_TRUE(r.ok()) << format_report(net, r);
  EXPECT_TRUE(r.regions.at(0).by_invariant);
}

TEST(Structural, ARegionWithTwoFreeTokensIsNotProvedAndTheExplorationFindsTheViolation) {
  const Net net = testnets::region_loop(2, 2);
  EXPECT_FALSE(prove_region_exclusive(net, 0).has_value());
  const AnalysisResult r = check(net, 1);
  EXPECT_FALSE(r.mutex_ok);
  EXPECT_FALSE(r.regions.at(0).by_invariant);
  ASSERT_TRUE(r.regions.at(0).witness.has_value());
}

TEST(Structural, AProofIsCheckedExactly) {
  const Net net = testnets::region_loop(3);
  auto proof = prove_region_exclusive(net, 0);
  ASSERT_TRUE(proof.has_value());
  EXPECT_TRUE(is_region_proof(net, 0, *proof));
  RegionProof wrong = *proof;
  wrong.bound = 0;
  EXPECT_FALSE(is_region_proof(net, 0, wrong));
  wrong = *proof;
  for (auto& w : wrong.weight) w = 0;
  EXPECT_FALSE(is_region_proof(net, 0, wrong));
}

TEST(Structural, AStateEquationCandidateIsReplayedToARealDeadlock) {
  // t moves p's token on while q is marked (q is given back twice); u needs r, which is never marked. After t,
  // nothing is enabled: the candidate's firing counts (t once) lead there.
  NetBuilder b("trap");
  const PlaceId p = add_place(b, "p", 1), q = add_place(b, "q", 1), r = add_place(b, "r", 0);
  add_transition(b, "t", {{p, 1}, {q, 1}}, {{q, 2}});
  add_transition(b, "u", {{r, 1}, {q, 1}}, {{q, 1}, {r, 1}});
  const Net net = std::move(b).build();
  const StateEquationResult se = deadlock_free_by_state_equation(net);
  ASSERT_EQ(se.verdict, StateEquationResult::Verdict::kCandidate) << se.reason;
  const auto path = guided_deadlock_search(net, se.firings);
  ASSERT_TRUE(path.has_value());
  EXPECT_TRUE(is_dead(net, replay(net, *path)));
}

TEST(Structural, ASourceTransitionMeansNoDeadlock) {
  NetBuilder b("source");
  const PlaceId p = add_place(b, "p", 0);
  add_transition(b, "make", {}, {{p, 1}});
  const Net net = std::move(b).build();
  EXPECT_EQ(deadlock_free_by_state_equation(net).verdict, StateEquationResult::Verdict::kDeadlockFree);
}

// What the comparison saw.
struct Tally {
  int compared = 0, decided = 0, proved_free = 0, guided = 0, regions_proved = 0, explored_on = 0, skipped = 0;
};

// Full exploration and the check with a budget of one marking (so that the structural checks decide whatever they
// can) agree on every verdict they both give.
void compare(const Net& net, Tally& tally) {
  SCOPED_TRACE(net.name());
  constexpr std::uint64_t kLimit = 200'000;
  AnalysisOptions full_options;
  full_options.max_states = kLimit;
  const AnalysisResult full = analyze(net, full_options);
  if (!full.complete && full.bounded) {
    ++tally.skipped;
    return;
  }
  ++tally.compared;
  const AnalysisResult fast = check(net, 1, kLimit);
  for (std::size_t k = 0; k < fast.regions.size(); ++k) {
    if (!fast.regions[k].by_invariant) continue;
    ++tally.regions_proved;
    EXPECT_TRUE(full.regions[k].exclusive) << "region " << full.regions[k].name << " proved but not exclusive";
    EXPECT_GE(fast.regions[k].invariant_bound, full.regions[k].max_inside);
  }
  if (!fast.complete) {
    // Not decided: the stated reason is there, and nothing definite it says is wrong.
    EXPECT_FALSE(fast.stop_reason.empty());
    if (fast.deadlocks > 0 && full.complete) {
      EXPECT_GT(full.deadlocks, 0u);
    }
    if (!fast.bounded) {
      EXPECT_FALSE(full.bounded);
    }
    return;
  }
  ++tally.decided;
  if (fast.explored_all) ++tally.explored_on;
  EXPECT_EQ(fast.ok(), full.ok()) << format_report(net, fast) << "full:\n" << format_report(net, full);
  EXPECT_EQ(fast.deadlocks > 0, full.deadlocks > 0) << format_report(net, fast);
  EXPECT_EQ(fast.bounded, full.bounded);
  EXPECT_EQ(fast.mutex_ok, full.mutex_ok);
  if (!fast.explored_all && fast.deadlocks == 0) ++tally.proved_free;
  if (fast.deadlocks > 0) {
    if (!fast.deadlock_path_shortest) ++tally.guided;
    ASSERT_FALSE(fast.deadlock_examples.empty());
    const Deadlock& d = fast.deadlock_examples.front();
    const Marking end = replay(net, d.path);
    EXPECT_EQ(end, d.marking);
    EXPECT_TRUE(is_dead(net, end));
    EXPECT_FALSE(net.is_final(end));
    if (fast.deadlock_path_shortest) {
      EXPECT_EQ(d.path.size(), full.deadlock_examples.front().path.size());
    }
  }
}

void print(const char* what, const Tally& t) {
  std::printf(
      "%s: %d compared (%d skipped at the state limit), %d decided (%d by exploring on), %d proved deadlock-free by "
      "the state equation, %d deadlocks found by the guided search, %d regions proved by invariants\n",
      what, t.compared, t.skipped, t.decided, t.explored_on, t.proved_free, t.guided, t.regions_proved);
}

TEST(Structural, SameVerdictsAsFullExplorationOnRandomCells) {
  Tally t;
  for (std::uint64_t seed = 1; seed <= 300; ++seed) compare(generators::random_cell(seed), t);
  print("random cells", t);
  EXPECT_GE(t.compared, 250);
  EXPECT_GE(t.proved_free, 20);
  EXPECT_GE(t.guided, 10);
  EXPECT_GE(t.regions_proved, 50);
}

TEST(Structural, SameVerdictsAsFullExplorationOnRandomNets) {
  Tally t;
  for (std::uint64_t seed = 1; seed <= 300; ++seed) compare(generators::random_net(seed), t);
  print("random nets", t);
  EXPECT_GE(t.compared, 250);
}

TEST(Structural, SameVerdictsAsFullExplorationOnRandomPrograms) {
  // Tables, sequences, regions, semaphores and loops (testnets::random_looping_program), and the generated shapes.
  Tally t;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    const std::string text = testnets::random_looping_program(seed);
    SCOPED_TRACE(text);
    compare(program_net(text), t);
  }
  for (int robots = 2; robots <= 4; ++robots) {
    compare(program_net(generators::philosophers_program(robots)), t);
    compare(program_net(generators::shared_region_program(robots)), t);
    compare(program_net(generators::lockstep_program(robots, 5)), t);
  }
  print("random programs", t);
  EXPECT_GE(t.compared, 190);
  EXPECT_GE(t.proved_free, 20);
  EXPECT_GE(t.guided, 10);
  EXPECT_GE(t.regions_proved, 50);
}

}  // namespace
}  // namespace cellwright::petri
