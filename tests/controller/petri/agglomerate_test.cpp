// Net reduction before exploring (agglomerate.hpp): which places the two rules remove and which they keep, that a
// lock-step barrier becomes one transition per robot, that counterexamples found in the reduced net are firing
// sequences of the original net (a deadlock behind a delayed wait included), and that exact counts are untouched
// without the stubborn-set reduction. stubborn_test.cpp compares its verdicts with full exploration on random nets
// and programs.
#include "cellwright/petri/agglomerate.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

using testnets::add_place;
using testnets::add_transition;
using testnets::program_net;
using testnets::replay;

AnalysisResult checked(const Net& net, bool agglomerate = true) {
  AnalysisOptions o;
  o.reduction = Reduction::kStubborn;
  o.agglomerate = agglomerate;
  return analyze(net, o);
}

// The places of `agg.net` by their original ids.
std::vector<std::string> kept_places(const Agglomeration& agg) {
  std::vector<std::string> ids;
  for (const Place& p : agg.net.places()) ids.push_back(p.id);
  return ids;
}

TEST(Agglomerate, AChainOfCommandsBecomesOneTransition) {
  // a -t1-> p -t2-> q -t3-> b: p and q have one producer and one consumer each, and t2, t3 take from them alone.
  NetBuilder b("chain");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId p = add_place(b, "p");
  const PlaceId q = add_place(b, "q");
  const PlaceId e = add_place(b, "b");
  add_transition(b, "t1", {{a, 1}}, {{p, 1}});
  add_transition(b, "t2", {{p, 1}}, {{q, 1}});
  add_transition(b, "t3", {{q, 1}}, {{e, 1}});
  const Net net = std::move(b).build();
  const Agglomeration agg = agglomerate(net);
  EXPECT_EQ(agg.post, 2u);
  EXPECT_EQ(agg.pre, 0u);
  EXPECT_EQ(kept_places(agg), (std::vector<std::string>{"a", "b"}));
  ASSERT_EQ(agg.net.num_transitions(), 1u);
  EXPECT_EQ(agg.expansion[0], (std::vector<TransitionId>{0, 1, 2}));
  EXPECT_EQ(agg.expand({0}), (std::vector<TransitionId>{0, 1, 2}));
  const Transition& t = agg.net.transitions()[0];
  EXPECT_EQ(t.id, "t1");
  ASSERT_EQ(t.inputs.size(), 1u);
  ASSERT_EQ(t.outputs.size(), 1u);
  EXPECT_EQ(agg.place(t.inputs[0].place), a);
  EXPECT_EQ(agg.place(t.outputs[0].place), e);
}

TEST(Agglomerate, KeepsMarkedRegionFinalAndSharedPlaces) {
  NetBuilder b("kept");
  const PlaceId s = add_place(b, "start", 1);
  const PlaceId in = add_place(b, "inside");     // inside region Z: its occupancy must stay observable
  const PlaceId mid = add_place(b, "mid");       // removable
  const PlaceId fork = add_place(b, "fork");     // two consumers: a choice
  const PlaceId weighted = add_place(b, "two");  // an arc of weight 2
  const PlaceId done = add_place(b, "done", 0, PlaceKind::kDone);
  const PlaceId other = add_place(b, "other");
  add_transition(b, "enter", {{s, 1}}, {{in, 1}});
  add_transition(b, "leave", {{in, 1}}, {{mid, 1}});
  add_transition(b, "split", {{mid, 1}}, {{fork, 1}});
  add_transition(b, "left", {{fork, 1}}, {{weighted, 2}});
  add_transition(b, "right", {{fork, 1}}, {{other, 1}});
  add_transition(b, "end", {{weighted, 2}}, {{done, 1}});
  Region z;
  z.name = "Z";
  z.inside = {in};
  b.add_region(z);
  b.set_final({{done, 1}});
  const Net net = std::move(b).build();
  const Agglomeration agg = agglomerate(net);
  EXPECT_EQ(kept_places(agg), (std::vector<std::string>{"start", "inside", "fork", "two", "done", "other"}));
  EXPECT_EQ(agg.post, 1u);  // mid: leave;split
  ASSERT_EQ(agg.net.regions().size(), 1u);
  ASSERT_EQ(agg.net.regions()[0].inside.size(), 1u);
  EXPECT_EQ(agg.place(agg.net.regions()[0].inside[0]), in);
  ASSERT_EQ(agg.net.final_places().size(), 1u);
  EXPECT_EQ(agg.place(agg.net.final_places()[0].place), done);
  // The verdicts carry over: "right" leaves the program short of its end.
  const AnalysisResult r = checked(net);
  EXPECT_FALSE(r.net_reduction.empty());
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_TRUE(r.mutex_ok);
  ASSERT_EQ(r.deadlock_examples.size(), 1u);
  EXPECT_EQ(replay(net, r.deadlock_examples[0].path), r.deadlock_examples[0].marking);
  EXPECT_EQ(r.deadlock_examples[0].marking[other], 1u);
}

TEST(Agglomerate, ALockStepBarrierBecomesOneTransitionPerRobot) {
  // 3 robots, 4 lines: 3 barriers of 3 x 2 signals and 3 x 2 waits. Between two waits for events nothing else
  // competes, so a robot's run shrinks to one transition per barrier plus its first (begin to the first barrier's
  // waits) and the event places stay (each joins two robots).
  const Net net = program_net(
      "robot r1 r2 r3\nworkpiece part from IN\nlocation IN OUT\nsteps\n  r1 | r2 | r3\n"
      "  Pick part | Pick part | Pick part\n  Place OUT | Place OUT | Place OUT\n"
      "  Pick part | Pick part | Pick part\n  Place OUT | Place OUT | Place OUT\nend\n");
  const Agglomeration agg = agglomerate(net);
  EXPECT_GT(agg.pre, 0u);
  EXPECT_GT(agg.post, 0u);
  EXPECT_EQ(agg.net.num_transitions(), 3u * (3 + 1));
  std::size_t events = 0, original_events = 0;
  for (const Place& p : agg.net.places()) events += p.kind == PlaceKind::kEvent ? 1 : 0;
  for (const Place& p : net.places()) original_events += p.kind == PlaceKind::kEvent ? 1 : 0;
  EXPECT_EQ(events, original_events);
  EXPECT_EQ(original_events, 3u * 3 * 2);
  // Every original transition is in exactly one expansion.
  std::vector<int> seen(net.num_transitions(), 0);
  for (const auto& e : agg.expansion) {
    for (TransitionId t : e) ++seen[t];
  }
  for (std::size_t t = 0; t < seen.size(); ++t) EXPECT_EQ(seen[t], 1) << net.transitions()[t].id;

  const AnalysisResult on = checked(net), off = checked(net, false);
  ASSERT_TRUE(on.complete) << on.stop_reason;
  EXPECT_TRUE(on.ok()) << format_report(net, on);
  EXPECT_EQ(on.final_states, 1u);
  EXPECT_LT(on.states, off.states);
  EXPECT_NE(format_report(net, on).find("before exploring, the net was reduced"), std::string::npos);
  EXPECT_EQ(to_json(net, on)["net_reduction"], on.net_reduction);
  EXPECT_TRUE(off.net_reduction.empty());

  // The generated 12-robot, 20-line table (hand-overs and semaphores too): one interleaving of the fused transitions.
  const Net big = program_net(generators::lockstep_program(12, 20));
  const Agglomeration big_agg = agglomerate(big);
  const AnalysisResult r = checked(big);
  ASSERT_TRUE(r.complete) << r.stop_reason;
  EXPECT_TRUE(r.ok()) << format_report(big, r);
  EXPECT_TRUE(r.explored_all);
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_LT(big_agg.net.num_transitions() * 10, big.num_transitions());
  EXPECT_LE(r.states, big_agg.net.num_transitions() + 1);
}

TEST(Agglomerate, ADeadlockBehindADelayedWaitIsReplayedInTheOriginalNet) {
  // A robot waits for e1, then for e2; only e1 is ever signalled. The two waits fuse into one transition that needs
  // both events, dead at once in the reduced net; in the original net the robot takes e1 and then waits for e2.
  NetBuilder b("waits");
  const PlaceId w1 = add_place(b, "w1", 1, PlaceKind::kWaiting);
  const PlaceId w2 = add_place(b, "w2", 0, PlaceKind::kWaiting);
  const PlaceId after = add_place(b, "after");
  const PlaceId done = add_place(b, "done", 0, PlaceKind::kDone);
  const PlaceId e1 = add_place(b, "e1", 1, PlaceKind::kEvent);
  const PlaceId e2 = add_place(b, "e2", 0, PlaceKind::kEvent);
  const TransitionId take1 = add_transition(b, "take1", {{w1, 1}, {e1, 1}}, {{w2, 1}});
  add_transition(b, "take2", {{w2, 1}, {e2, 1}}, {{after, 1}});
  add_transition(b, "finish", {{after, 1}}, {{done, 1}});
  b.set_final({{done, 1}});
  const Net net = std::move(b).build();
  const Agglomeration agg = agglomerate(net);
  EXPECT_EQ(agg.pre, 1u);
  EXPECT_EQ(agg.post, 1u);
  ASSERT_EQ(agg.net.num_transitions(), 1u);
  EXPECT_TRUE(agg.delayed[take1]);
  EXPECT_TRUE(is_dead(agg.net, agg.net.initial_marking()));

  const AnalysisResult r = checked(net);
  ASSERT_TRUE(r.complete);
  EXPECT_FALSE(r.net_reduction.empty());
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_FALSE(r.deadlock_path_shortest);
  ASSERT_EQ(r.deadlock_examples.size(), 1u);
  const Deadlock& d = r.deadlock_examples[0];
  EXPECT_EQ(d.path, std::vector<TransitionId>{take1});
  EXPECT_EQ(replay(net, d.path), d.marking);
  EXPECT_TRUE(is_dead(net, d.marking));
  EXPECT_EQ(d.marking[w2], 1u);
  EXPECT_EQ(d.marking[e1], 0u);
  // The same verdict and marking as without the reduction.
  const AnalysisResult off = checked(net, false);
  EXPECT_EQ(off.deadlocks, 1u);
  EXPECT_EQ(off.deadlock_examples.at(0).marking, d.marking);
}

TEST(Agglomerate, UnboundednessSurvivesTheFusion) {
  // t1 pumps p from a marked self-loop, t2 moves p on to q: fused into a -> a + q; both p (original) and q grow.
  NetBuilder b("pump");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId p = add_place(b, "p");
  const PlaceId q = add_place(b, "q");
  add_transition(b, "t1", {{a, 1}}, {{a, 1}, {p, 1}});
  add_transition(b, "t2", {{p, 1}}, {{q, 1}});
  const Net net = std::move(b).build();
  EXPECT_EQ(agglomerate(net).post, 1u);
  const AnalysisResult r = checked(net);
  EXPECT_FALSE(r.bounded);
  EXPECT_EQ(r.unbounded_places, std::vector<PlaceId>{q});
  ASSERT_TRUE(r.unbounded_witness.has_value());
  EXPECT_EQ(replay(net, r.unbounded_witness->path), r.unbounded_witness->marking);
  // A consumer without outputs is not fused: the tokens it drains would vanish from the reduced net (here p is
  // unbounded although t1;t2 would change nothing).
  NetBuilder d("drain");
  const PlaceId da = add_place(d, "a", 1);
  const PlaceId dp = add_place(d, "p");
  add_transition(d, "t1", {{da, 1}}, {{da, 1}, {dp, 1}});
  add_transition(d, "t2", {{dp, 1}}, {});
  const Net drain = std::move(d).build();
  EXPECT_FALSE(agglomerate(drain).changed());
  EXPECT_FALSE(checked(drain).bounded);
}

TEST(Agglomerate, ARegionViolationIsWitnessedInTheOriginalNet) {
  // Two robots enter Z after two commands each, without taking its token: the witness path, expanded, reaches a
  // marking with both inside.
  NetBuilder b("violation");
  Region z;
  z.name = "Z";
  for (const char* r : {"r1", "r2"}) {
    const std::string s = r;
    const PlaceId start = add_place(b, s + ".start", 1, PlaceKind::kStart);
    const PlaceId c1 = add_place(b, s + ".c1", 0, PlaceKind::kExecuting);
    const PlaceId c2 = add_place(b, s + ".c2", 0, PlaceKind::kExecuting);
    const PlaceId in = add_place(b, s + ".in", 0, PlaceKind::kExecuting);
    add_transition(b, s + ".t0", {{start, 1}}, {{c1, 1}});
    add_transition(b, s + ".t1", {{c1, 1}}, {{c2, 1}});
    add_transition(b, s + ".t2", {{c2, 1}}, {{in, 1}});
    z.inside.push_back(in);
  }
  b.add_region(z);
  const Net net = std::move(b).build();
  const AnalysisResult r = checked(net);
  EXPECT_FALSE(r.net_reduction.empty());
  EXPECT_FALSE(r.mutex_ok);
  ASSERT_TRUE(r.regions[0].witness.has_value());
  EXPECT_FALSE(r.regions[0].witness_shortest);
  EXPECT_EQ(r.regions[0].max_inside, 2u);
  const Marking m = replay(net, r.regions[0].witness->path);
  EXPECT_EQ(m, r.regions[0].witness->marking);
  EXPECT_EQ(m[net.regions()[0].inside[0]] + m[net.regions()[0].inside[1]], 2u);
}

TEST(Agglomerate, PhilosophersDeadlockIsReplayedAndExactCountsNeedNoReduction) {
  const Net net = program_net(generators::philosophers_program(3));
  const AnalysisResult r = checked(net);
  ASSERT_TRUE(r.complete) << r.stop_reason;
  EXPECT_GE(r.deadlocks, 1u);
  ASSERT_FALSE(r.deadlock_examples.empty());
  const Deadlock& d = r.deadlock_examples[0];
  EXPECT_EQ(replay(net, d.path), d.marking);
  EXPECT_TRUE(is_dead(net, d.marking));
  EXPECT_FALSE(net.is_final(d.marking));
  // Without the stubborn sets nothing is reduced: the counts are the reachability graph's.
  const AnalysisResult full = analyze(net);
  EXPECT_TRUE(full.net_reduction.empty());
  EXPECT_FALSE(full.reduced);
  EXPECT_EQ(full.states, testnets::naive_explore(net, 1'000'000).states);
  EXPECT_EQ(full.deadlocks, r.deadlocks);
}

}  // namespace
}  // namespace cellwright::petri
