// Analysis before run: reachability counts against known values and a naive oracle, deadlocks with replayable
// shortest paths, unboundedness, mutual exclusion, the state limit, and the reports.
#include "cellwright/petri/analysis.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;
using testnets::add_place;
using testnets::add_transition;
using testnets::replay;

// n independent switches, each flipping between off and on: 2^n markings.
Net switches(int n) {
  NetBuilder b(fmt::format("switches-{}", n));
  for (int i = 0; i < n; ++i) {
    const PlaceId off = add_place(b, fmt::format("off{}", i), 1);
    const PlaceId on = add_place(b, fmt::format("on{}", i));
    add_transition(b, fmt::format("up{}", i), {{off, 1}}, {{on, 1}});
    add_transition(b, fmt::format("down{}", i), {{on, 1}}, {{off, 1}});
  }
  return std::move(b).build();
}

TEST(Analysis, SmallNetsHaveTheirKnownCounts) {
  for (int n : {1, 3, 10}) {
    const AnalysisResult r = analyze(switches(n));
    EXPECT_TRUE(r.complete);
    EXPECT_EQ(r.states, 1u << n);
    EXPECT_EQ(r.edges, static_cast<std::uint64_t>(n) << n);  // every marking enables n transitions
    EXPECT_EQ(r.deadlocks, 0u);
    EXPECT_TRUE(r.bounded);
    EXPECT_TRUE(r.dead_transitions.empty());
    EXPECT_TRUE(r.ok());
  }
  // A chain a -> b -> c ends dead in c: three markings, a deadlock because no final marking is declared.
  NetBuilder b("chain");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId m = add_place(b, "b");
  const PlaceId c = add_place(b, "c");
  add_transition(b, "t1", {{a, 1}}, {{m, 1}});
  add_transition(b, "t2", {{m, 1}}, {{c, 1}});
  const AnalysisResult r = analyze(std::move(b).build());
  EXPECT_EQ(r.states, 3u);
  EXPECT_EQ(r.edges, 2u);
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_FALSE(r.ok());
}

TEST(Analysis, DegenerateNets) {
  // No places: one (empty) marking; a transition without arcs is always enabled and loops on it.
  NetBuilder loop("empty-loop");
  add_transition(loop, "noop", {}, {});
  const AnalysisResult r = analyze(std::move(loop).build());
  EXPECT_EQ(r.states, 1u);
  EXPECT_EQ(r.edges, 1u);
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_TRUE(r.ok());
  // No transitions: the initial marking is dead.
  NetBuilder still("still");
  add_place(still, "p", 3);
  const AnalysisResult d = analyze(std::move(still).build());
  EXPECT_EQ(d.states, 1u);
  EXPECT_EQ(d.deadlocks, 1u);
  ASSERT_EQ(d.deadlock_examples.size(), 1u);
  EXPECT_TRUE(d.deadlock_examples[0].path.empty());
  EXPECT_EQ(d.deadlock_examples[0].marking, (Marking{3}));
  // A source transition: tokens from nowhere.
  NetBuilder source("source");
  const PlaceId p = add_place(source, "p");
  add_transition(source, "make", {}, {{p, 1}});
  const AnalysisResult u = analyze(std::move(source).build());
  EXPECT_FALSE(u.bounded);
  EXPECT_EQ(u.unbounded_places, (std::vector<PlaceId>{p}));
}

TEST(Analysis, SameNetSameAnswer) {
  const Net net = generators::philosophers(4);
  AnalysisOptions opt;
  opt.max_deadlocks_reported = 3;
  const AnalysisResult a = analyze(net, opt);
  const AnalysisResult b = analyze(net, opt);
  EXPECT_EQ(a.states, b.states);
  EXPECT_EQ(a.edges, b.edges);
  ASSERT_EQ(a.deadlock_examples.size(), b.deadlock_examples.size());
  for (std::size_t i = 0; i < a.deadlock_examples.size(); ++i) {
    EXPECT_EQ(a.deadlock_examples[i].path, b.deadlock_examples[i].path);
  }
  EXPECT_EQ(format_report(net, a), format_report(net, b));
}

TEST(Analysis, KanbanMatchesThePublishedStateCounts) {
  EXPECT_EQ(generators::kanban_reachable(1), 160u);
  EXPECT_EQ(generators::kanban_reachable(2), 4600u);
  for (Tokens n : {1u, 2u, 3u}) {
    const Net net = generators::kanban(n);
    EXPECT_EQ(net.num_places(), 16u);
    EXPECT_EQ(net.num_transitions(), 16u);
    const AnalysisResult r = analyze(net);
    EXPECT_TRUE(r.complete) << r.stop_reason;
    EXPECT_EQ(r.states, generators::kanban_reachable(n)) << "N=" << n;
    EXPECT_EQ(r.deadlocks, 0u);
    EXPECT_TRUE(r.bounded);
    // Each station's cards never exceed N in any place (places widen from 0 tokens = 1 bit to N's width).
    EXPECT_EQ(r.place_bounds, std::vector<Tokens>(16, n));
    EXPECT_TRUE(r.dead_transitions.empty());
  }
}

TEST(Analysis, PhilosophersDeadlockWithAShortestReplayablePath) {
  for (int n : {2, 3, 5}) {
    const Net net = generators::philosophers(n);
    const AnalysisResult r = analyze(net);
    EXPECT_TRUE(r.complete);
    EXPECT_EQ(r.deadlocks, 1u) << "only 'everyone holds the left fork' is dead";
    ASSERT_EQ(r.deadlock_examples.size(), 1u);
    const Deadlock& d = r.deadlock_examples[0];
    EXPECT_EQ(d.path.size(), static_cast<std::size_t>(n)) << "n left forks taken, nothing shorter";
    const Marking end = replay(net, d.path);
    EXPECT_EQ(end, d.marking);
    EXPECT_TRUE(enabled(net, end).empty());
    for (int i = 0; i < n; ++i) EXPECT_EQ(end[*net.find_place(fmt::format("hasLeft{}", i))], 1u);
    const auto naive = testnets::naive_explore(net, 1'000'000);
    EXPECT_EQ(r.states, naive.states);
    EXPECT_EQ(r.edges, naive.edges);
    EXPECT_FALSE(r.ok());
  }
}

TEST(Analysis, ReportsAsManyDeadlockExamplesAsAskedButCountsAll) {
  // Two independent chains, each able to stop early or late: several dead markings.
  NetBuilder b("forks");
  const PlaceId s = add_place(b, "s", 1);
  const PlaceId x = add_place(b, "x");
  const PlaceId y = add_place(b, "y");
  const PlaceId z = add_place(b, "z");
  add_transition(b, "a", {{s, 1}}, {{x, 1}});
  add_transition(b, "b", {{s, 1}}, {{y, 1}});
  add_transition(b, "c", {{y, 1}}, {{z, 1}});
  const Net net = std::move(b).build();
  AnalysisOptions opt;
  opt.max_deadlocks_reported = 5;
  const AnalysisResult r = analyze(net, opt);
  EXPECT_EQ(r.deadlocks, 2u);  // x and z
  ASSERT_EQ(r.deadlock_examples.size(), 2u);
  EXPECT_EQ(r.deadlock_examples[0].path.size(), 1u);  // BFS: the shorter one first
  EXPECT_EQ(r.deadlock_examples[1].path.size(), 2u);
  opt.max_deadlocks_reported = 0;
  const AnalysisResult none = analyze(net, opt);
  EXPECT_EQ(none.deadlocks, 2u);
  EXPECT_TRUE(none.deadlock_examples.empty());
}

TEST(Analysis, ProperEndsAreNotDeadlocks) {
  NetBuilder b("ends");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId done = add_place(b, "done", 0, PlaceKind::kDone);
  const PlaceId stuck = add_place(b, "stuck");
  add_transition(b, "finish", {{a, 1}}, {{done, 1}});
  add_transition(b, "fail", {{a, 1}}, {{stuck, 1}});
  b.set_final({{done, 1}});
  const AnalysisResult r = analyze(std::move(b).build());
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_EQ(r.deadlocks, 1u);
  ASSERT_EQ(r.deadlock_examples.size(), 1u);
  EXPECT_EQ(r.deadlock_examples[0].marking, (Marking{0, 0, 1}));
}

TEST(Analysis, AnUnboundedProducerIsDetectedAndExplorationStops) {
  // A producer loop: idle -> busy -> idle + one item in the buffer.
  NetBuilder b("producer");
  const PlaceId idle = add_place(b, "idle", 1);
  const PlaceId busy = add_place(b, "busy");
  const PlaceId buffer = add_place(b, "buffer");
  const PlaceId consumed = add_place(b, "consumed");
  add_transition(b, "start", {{idle, 1}}, {{busy, 1}});
  add_transition(b, "produce", {{busy, 1}}, {{idle, 1}, {buffer, 1}});
  add_transition(b, "consume", {{buffer, 2}}, {{consumed, 1}});
  add_transition(b, "recycle", {{consumed, 1}}, {});
  const Net net = std::move(b).build();
  const AnalysisResult r = analyze(net);
  EXPECT_FALSE(r.bounded);
  EXPECT_FALSE(r.complete);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.unbounded_places, (std::vector<PlaceId>{buffer}));
  EXPECT_THAT(r.stop_reason, HasSubstr("unbounded: 'buffer' grows without limit"));
  EXPECT_LT(r.states, 100u);
  ASSERT_TRUE(r.unbounded_witness);
  // The witness ends in a marking that strictly covers one it passed through.
  const auto& path = r.unbounded_witness->path;
  EXPECT_EQ(replay(net, path), r.unbounded_witness->marking);
  bool covers_earlier = false;
  Marking m = net.initial_marking();
  for (std::size_t i = 0; i < path.size(); ++i) {
    const Marking& end = r.unbounded_witness->marking;
    bool covers = m != end;
    for (std::size_t p = 0; p < m.size(); ++p) covers = covers && end[p] >= m[p];
    covers_earlier = covers_earlier || covers;
    fire_in_place(net, m, path[i]);
  }
  EXPECT_TRUE(covers_earlier);
  EXPECT_TRUE(r.dead_transitions.empty()) << "not claimed when the exploration is incomplete";
}

TEST(Analysis, AnUnboundedNetWithoutALoopAtTheStartIsFoundToo) {
  // Tokens circulate a -> b -> c -> a, and each round trip through b also leaves a token in `out`; the grow cycle
  // only appears after a prefix.
  NetBuilder b("late");
  const PlaceId s = add_place(b, "s", 2);
  const PlaceId a = add_place(b, "a");
  const PlaceId m = add_place(b, "m");
  const PlaceId c = add_place(b, "c");
  const PlaceId out = add_place(b, "out");
  add_transition(b, "go", {{s, 2}}, {{a, 1}});
  add_transition(b, "ab", {{a, 1}}, {{m, 1}});
  add_transition(b, "bc", {{m, 1}}, {{c, 1}, {out, 1}});
  add_transition(b, "ca", {{c, 1}}, {{a, 1}});
  const AnalysisResult r = analyze(std::move(b).build());
  EXPECT_FALSE(r.bounded);
  EXPECT_EQ(r.unbounded_places, (std::vector<PlaceId>{out}));
}

TEST(Analysis, AnUnboundedPlaceIsFoundWhileASiblingBranchSetsTheMaxima) {
  // `pump` adds one token to `out` per firing, but from the initial marking `burst` adds two at once on a branch
  // that covers nothing; after that every new maximum of `out` is set on such branches. A covering test that only
  // runs on new per-place maxima never looks at the pumping path; this net (found by the random-net search) ran to
  // the state limit under that rule.
  NetBuilder b("sibling");
  const PlaceId p0 = add_place(b, "p0", 2);
  const PlaceId p1 = add_place(b, "p1", 2);
  const PlaceId out = add_place(b, "out");
  const PlaceId p3 = add_place(b, "p3", 1);
  add_transition(b, "burst", {{p0, 2}, {p1, 1}, {p3, 1}}, {{p1, 1}, {out, 2}});
  add_transition(b, "pump", {{p0, 1}}, {{p0, 1}, {out, 1}});
  add_transition(b, "drain", {{p0, 2}, {p1, 2}}, {{out, 1}, {p3, 1}});
  const AnalysisResult r = analyze(std::move(b).build());
  EXPECT_FALSE(r.bounded) << r.stop_reason;
  EXPECT_EQ(r.unbounded_places, (std::vector<PlaceId>{out}));
  EXPECT_LT(r.states, 100u);
}

TEST(Analysis, MutualExclusionHoldsWithOneTokenAndBreaksWithTwo) {
  const AnalysisResult good = analyze(testnets::region_loop(3, 1));
  EXPECT_TRUE(good.mutex_ok);
  ASSERT_EQ(good.regions.size(), 1u);
  EXPECT_EQ(good.regions[0].name, "Z");
  EXPECT_TRUE(good.regions[0].exclusive);
  EXPECT_EQ(good.regions[0].max_inside, 1u);
  EXPECT_TRUE(good.ok());

  const Net net = testnets::region_loop(3, 2);  // a semaphore initialised to 2 guards a region for one
  const AnalysisResult bad = analyze(net);
  EXPECT_TRUE(bad.complete);
  EXPECT_FALSE(bad.mutex_ok);
  EXPECT_FALSE(bad.ok());
  ASSERT_EQ(bad.regions.size(), 1u);
  EXPECT_FALSE(bad.regions[0].exclusive);
  EXPECT_EQ(bad.regions[0].max_inside, 2u);
  ASSERT_TRUE(bad.regions[0].witness);
  const Deadlock& w = *bad.regions[0].witness;
  EXPECT_EQ(w.path.size(), 2u) << "two robots entering is the shortest violation";
  const Marking end = replay(net, w.path);
  EXPECT_EQ(end, w.marking);
  Tokens inside = 0;
  for (PlaceId p : net.regions()[0].inside) inside += end[p];
  EXPECT_EQ(inside, 2u);
}

// A user's Ctrl-C sets the stop flag from another thread: exploration ends at its next check with what it found.
TEST(Analysis, StopsWhenAskedAndSaysSo) {
  std::atomic<bool> stop{true};
  AnalysisOptions opt;
  opt.stop = &stop;
  const AnalysisResult r = analyze(switches(12), opt);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.states, 1u);
  EXPECT_EQ(r.stop_reason, "interrupted after 1 markings");
  EXPECT_FALSE(r.ok());
  stop = false;
  EXPECT_TRUE(analyze(switches(4), opt).complete);
}

// A net too large for the state limit: the checking commands say so on stderr with the figures.
TEST(Analysis, CheckAndReportGivesTheFiguresOfAnExplorationCutShort) {
  CheckOptions options;
  options.analysis.max_states = 100;
  std::ostringstream out, err;
  std::streambuf* old = std::cerr.rdbuf(err.rdbuf());
  const int status = check_and_report(switches(12), "big.pnml", options, out);
  std::cerr.rdbuf(old);
  EXPECT_EQ(status, 1);
  EXPECT_THAT(err.str(), HasSubstr("big.pnml: note: exploration stopped (state limit of 100 markings reached; raise "
                                   "--max-states): 100 markings explored in "));
  EXPECT_THAT(err.str(), HasSubstr("markings/s; state limit 100); --reduction stubborn explores fewer"));
}

TEST(Analysis, StopsAtTheStateLimitAndSaysSo) {
  AnalysisOptions opt;
  opt.max_states = 100;
  const AnalysisResult r = analyze(switches(12), opt);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.states, 100u);
  EXPECT_EQ(r.stop_reason, "state limit of 100 markings reached; raise --max-states");
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(r.bounded) << "no evidence against boundedness";

  opt.max_states = 4096;  // exactly enough
  EXPECT_TRUE(analyze(switches(12), opt).complete);
  opt.max_states = 0;
  EXPECT_THROW((void)analyze(switches(1), opt), std::invalid_argument);
}

TEST(Analysis, FindsTransitionsThatCanNeverFire) {
  NetBuilder b("dead");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId m = add_place(b, "b");
  const PlaceId never = add_place(b, "never");
  add_transition(b, "t0", {{a, 1}}, {{m, 1}});
  add_transition(b, "t1", {{m, 1}}, {{a, 1}});
  add_transition(b, "needs_never", {{never, 1}, {a, 1}}, {{m, 1}});
  add_transition(b, "needs_two", {{a, 2}}, {});
  const AnalysisResult r = analyze(std::move(b).build());
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.dead_transitions, (std::vector<TransitionId>{2, 3}));
}

TEST(Analysis, WidensPlacesBeyondTheirInitialWidth) {
  // 0 tokens in `to` start it at one bit; moving 37 tokens over (weights 1 and 3) needs six.
  NetBuilder b("widen");
  const PlaceId from = add_place(b, "from", 37);
  const PlaceId to = add_place(b, "to");
  add_transition(b, "one", {{from, 1}}, {{to, 1}});
  add_transition(b, "three", {{from, 3}}, {{to, 3}});
  const Net net = std::move(b).build();
  const AnalysisResult r = analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.states, 38u);
  EXPECT_EQ(r.place_bounds, (std::vector<Tokens>{37, 37}));
  EXPECT_EQ(r.deadlocks, 1u);
  ASSERT_EQ(r.deadlock_examples.size(), 1u);
  EXPECT_EQ(r.deadlock_examples[0].marking, (Marking{0, 37}));
  EXPECT_EQ(r.deadlock_examples[0].path.size(), 13u);  // 12 x three + 1 x one
  EXPECT_EQ(replay(net, r.deadlock_examples[0].path), (Marking{0, 37}));
}

TEST(Analysis, LargeCountsAndManyPlacesRoundTripThroughTheStore) {
  // Fields straddle 64-bit words: 40 places of up to 2^20 tokens.
  NetBuilder b("wide");
  std::vector<PlaceId> ps;
  for (int i = 0; i < 40; ++i) ps.push_back(add_place(b, fmt::format("p{}", i), i == 0 ? 1'000'000u : 0u));
  for (int i = 0; i + 1 < 40; ++i) {
    add_transition(b, fmt::format("t{}", i), {{ps[static_cast<std::size_t>(i)], 500'000}},
                   {{ps[static_cast<std::size_t>(i) + 1], 500'000}});
  }
  const Net net = std::move(b).build();
  const AnalysisResult r = analyze(net);
  const auto naive = testnets::naive_explore(net, 100'000);
  ASSERT_TRUE(naive.complete);
  EXPECT_EQ(r.states, naive.states);
  EXPECT_EQ(r.edges, naive.edges);
  EXPECT_EQ(r.deadlocks, naive.deadlocks);
  EXPECT_EQ(r.place_bounds, naive.bounds);
  ASSERT_FALSE(r.deadlock_examples.empty());
  EXPECT_EQ(replay(net, r.deadlock_examples[0].path), r.deadlock_examples[0].marking);
}

TEST(Analysis, StoreStaysWithinSixtyFourBytesPerMarking) {
  const AnalysisResult r = analyze(switches(17));
  ASSERT_EQ(r.states, 1u << 17);
  EXPECT_GT(r.stored_bytes, 0u);
  EXPECT_LE(static_cast<double>(r.stored_bytes) / static_cast<double>(r.states), 64.0);
}

// A random net: a few places and transitions, small weights and markings, some regions and a final marking.
Net random_net(std::mt19937& rng, int index) {
  auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  NetBuilder b(fmt::format("random-{}", index));
  const int np = pick(1, 6);
  const int nt = pick(0, 6);
  for (int p = 0; p < np; ++p) add_place(b, fmt::format("p{}", p), static_cast<Tokens>(pick(0, 2)));
  for (int t = 0; t < nt; ++t) {
    std::vector<Arc> in, out;
    for (int p = 0; p < np; ++p) {
      if (pick(0, 2) == 0) in.push_back({static_cast<PlaceId>(p), static_cast<Tokens>(pick(1, 2))});
      if (pick(0, 2) == 0) out.push_back({static_cast<PlaceId>(p), static_cast<Tokens>(pick(1, 2))});
    }
    add_transition(b, fmt::format("t{}", t), in, out);
  }
  if (pick(0, 1) == 0) {
    Region reg;
    reg.name = "R";
    for (int p = 0; p < np; ++p) {
      if (pick(0, 1) == 0) reg.inside.push_back(static_cast<PlaceId>(p));
    }
    reg.capacity = static_cast<Tokens>(pick(0, 2));
    b.add_region(reg);
  }
  if (pick(0, 1) == 0) b.set_final({{static_cast<PlaceId>(pick(0, np - 1)), 1}});
  return std::move(b).build();
}

TEST(Analysis, AgreesWithANaiveExplorerOnRandomNets) {
  std::mt19937 rng(7);
  constexpr std::uint64_t kCap = 3000;
  int compared = 0, unbounded = 0, with_deadlock = 0;
  for (int i = 0; i < 600; ++i) {
    const Net net = random_net(rng, i);
    SCOPED_TRACE(fmt::format("random net {}", i));
    AnalysisOptions opt;
    opt.max_states = kCap;
    const AnalysisResult r = analyze(net, opt);
    const testnets::NaiveResult naive = testnets::naive_explore(net, kCap);
    if (naive.complete) {
      // A finite reachability set: the explorer must see all of it, and never claim a covering.
      ++compared;
      ASSERT_TRUE(r.complete) << r.stop_reason;
      EXPECT_TRUE(r.bounded);
      EXPECT_EQ(r.states, naive.states);
      EXPECT_EQ(r.edges, naive.edges);
      EXPECT_EQ(r.deadlocks, naive.deadlocks);
      EXPECT_EQ(r.final_states, naive.final_states);
      EXPECT_EQ(r.place_bounds, naive.bounds);
      std::vector<TransitionId> dead;
      for (std::size_t t = 0; t < net.num_transitions(); ++t) {
        if (!naive.ever_enabled[t]) dead.push_back(static_cast<TransitionId>(t));
      }
      EXPECT_EQ(r.dead_transitions, dead);
      for (std::size_t k = 0; k < net.regions().size(); ++k) {
        EXPECT_EQ(r.regions[k].max_inside, naive.region_max[k]);
        EXPECT_EQ(r.regions[k].exclusive, !naive.region_violation_depth[k]);
        if (r.regions[k].witness) {
          EXPECT_EQ(r.regions[k].witness->path.size(), *naive.region_violation_depth[k]) << "shortest";
          EXPECT_EQ(replay(net, r.regions[k].witness->path), r.regions[k].witness->marking);
        }
      }
      if (naive.first_deadlock_depth) {
        ++with_deadlock;
        ASSERT_FALSE(r.deadlock_examples.empty());
        const Deadlock& d = r.deadlock_examples[0];
        EXPECT_EQ(d.path.size(), *naive.first_deadlock_depth) << "shortest";
        const Marking end = replay(net, d.path);
        EXPECT_EQ(end, d.marking);
        EXPECT_TRUE(enabled(net, end).empty());
        EXPECT_FALSE(net.is_final(end));
      }
    } else {
      // More than kCap markings: either a proven covering or the state limit.
      EXPECT_FALSE(r.complete);
      if (!r.bounded) {
        ++unbounded;
        ASSERT_TRUE(r.unbounded_witness);
        EXPECT_EQ(replay(net, r.unbounded_witness->path), r.unbounded_witness->marking);
      } else {
        EXPECT_EQ(r.states, kCap);
      }
    }
  }
  // The generator must exercise every branch, or this test proves little.
  EXPECT_GT(compared, 250);
  EXPECT_GT(with_deadlock, 100);
  EXPECT_GT(unbounded, 150);
}

// A two-robot hand-over net with program origins, as to_net builds them, for the reports.
Net handover() {
  NetBuilder b("exchange.task");
  b.set_robots({"r1", "r2"});
  auto robot_place = [&](const std::string& id, const std::string& robot, PlaceKind kind, Tokens init, int line,
                         const std::string& task, const std::string& motion) {
    Place p;
    p.id = id;
    p.name = id;
    p.kind = kind;
    p.initial = init;
    p.origin.robot = robot;
    p.origin.line = line;
    p.origin.task = task;
    p.origin.motion = motion;
    return b.add_place(p);
  };
  Place ev;
  ev.id = "ev.step2.r2>r1";
  ev.name = "event step2.r2>r1";
  ev.kind = PlaceKind::kEvent;
  const PlaceId e = b.add_place(ev);
  const PlaceId s1 = robot_place("r1.start", "r1", PlaceKind::kStart, 1, 0, "", "");
  const PlaceId w1 = robot_place("r1.p0", "r1", PlaceKind::kWaiting, 0, 7, "Put r2", "wait for r2");
  const PlaceId d1 = robot_place("r1.done", "r1", PlaceKind::kDone, 0, 0, "", "");
  const PlaceId s2 = robot_place("r2.start", "r2", PlaceKind::kStart, 1, 0, "", "");
  const PlaceId x2 = robot_place("r2.p0", "r2", PlaceKind::kExecuting, 0, 8, "Get r1", "approach r1");
  auto transition = [&](const std::string& id, const std::string& robot, std::vector<Arc> in, std::vector<Arc> out,
                        int line, const std::string& task, const std::string& motion) {
    Transition t;
    t.id = id;
    t.name = id;
    t.inputs = std::move(in);
    t.outputs = std::move(out);
    t.origin.robot = robot;
    t.origin.line = line;
    t.origin.task = task;
    t.origin.motion = motion;
    return b.add_transition(t);
  };
  transition("r1.t0", "r1", {{s1, 1}}, {{w1, 1}}, 7, "Put r2", "wait for r2");
  transition("r1.t1", "r1", {{w1, 1}, {e, 1}}, {{d1, 1}}, 7, "Put r2", "");
  transition("r2.t0", "r2", {{s2, 1}}, {{x2, 1}}, 8, "Get r1", "approach r1");
  // r2 never signals: r1 waits forever.
  b.set_final({{d1, 1}});
  return std::move(b).build();
}

TEST(Report, TellsTheDeadlockInTheProgramsTerms) {
  const Net net = handover();
  const AnalysisResult r = analyze(net);
  ASSERT_EQ(r.deadlocks, 1u);
  const Deadlock& d = r.deadlock_examples[0];
  EXPECT_EQ(describe_path(net, d.path),
            "1. r1 line 7 'Put r2' (wait for r2): r1.t0\n"
            "2. r2 line 8 'Get r1' (approach r1): r2.t0");
  EXPECT_EQ(describe_marking(net, d.marking),
            "r1: waiting for event step2.r2>r1 (line 7 'Put r2'); r2: executing approach r1 (line 8 'Get r1')");
  const std::string text = format_report(net, r);
  EXPECT_THAT(text, StartsWith("FAIL: 1 deadlock\n"));
  EXPECT_THAT(text, HasSubstr("deadlock after 2 firings:\n  1. r1 line 7"));
  EXPECT_THAT(text, HasSubstr("  stuck: r1: waiting for event step2.r2>r1"));
  EXPECT_EQ(text.back(), '\n');
}

TEST(Report, JsonCarriesTheVerdictAndTheCounterexample) {
  const Net net = handover();
  const AnalysisResult r = analyze(net);
  const nlohmann::json j = to_json(net, r);
  EXPECT_EQ(j["states"], r.states);
  EXPECT_EQ(j["edges"], r.edges);
  EXPECT_EQ(j["deadlocks"], 1);
  EXPECT_EQ(j["final_states"], 0);
  EXPECT_EQ(j["bounded"], true);
  EXPECT_EQ(j["mutex_ok"], true);
  EXPECT_EQ(j["complete"], true);
  EXPECT_EQ(j["ok"], false);
  EXPECT_EQ(j["stop_reason"], "");
  EXPECT_TRUE(j["unbounded_places"].is_array());
  EXPECT_TRUE(j["regions"].is_array());
  EXPECT_EQ(j["dead_transitions"], nlohmann::json::array({"r1.t1"}));
  ASSERT_EQ(j["deadlock_path"].size(), 2u);
  EXPECT_EQ(j["deadlock_path"][0]["transition"], "r1.t0");
  EXPECT_EQ(j["deadlock_path"][0]["robot"], "r1");
  EXPECT_EQ(j["deadlock_path"][0]["line"], 7);
  EXPECT_EQ(j["deadlock_path"][0]["task"], "Put r2");
  EXPECT_EQ(j["deadlock_path"][0]["motion"], "wait for r2");
  EXPECT_EQ(j["deadlock_marking"], nlohmann::json({{"r1.p0", 1}, {"r2.p0", 1}}));
  EXPECT_EQ(j["place_bounds"]["r1.start"], 1);
}

TEST(Report, OkAndIncompleteVerdicts) {
  const Net loop = testnets::region_loop(2);
  const AnalysisResult ok = analyze(loop);
  const std::string text = format_report(loop, ok);
  EXPECT_THAT(text, StartsWith("OK: no deadlock, bounded, mutual exclusion holds\n"));
  EXPECT_THAT(text, HasSubstr("region Z: exclusive (at most 1 inside, capacity 1)"));

  AnalysisOptions opt;
  opt.max_states = 10;
  const Net sw = switches(8);
  const AnalysisResult part = analyze(sw, opt);
  EXPECT_THAT(format_report(sw, part), StartsWith("UNKNOWN: exploration stopped early"));
  EXPECT_THAT(format_report(sw, part), HasSubstr("stopped: state limit of 10 markings reached; raise --max-states"));
  const nlohmann::json j = to_json(sw, part);
  EXPECT_TRUE(j["dead_transitions"].is_null());
  EXPECT_TRUE(j["deadlock_path"].is_null());
  EXPECT_EQ(j["stop_reason"], "state limit of 10 markings reached; raise --max-states");

  const Net bad = testnets::region_loop(2, 2);
  const AnalysisResult violated = analyze(bad);
  const std::string vt = format_report(bad, violated);
  EXPECT_THAT(vt, StartsWith("FAIL: region Z not exclusive\n"));
  EXPECT_THAT(vt, HasSubstr("region Z: 2 inside at once (capacity 1), first after 2 firings:"));
  const nlohmann::json vj = to_json(bad, violated);
  EXPECT_EQ(vj["mutex_ok"], false);
  EXPECT_EQ(vj["regions"][0]["exclusive"], false);
  EXPECT_EQ(vj["regions"][0]["witness_path"].size(), 2u);
}

TEST(Report, ForeignNetsAreToldByNamesAndIds) {
  const Net net = generators::philosophers(2);
  const AnalysisResult r = analyze(net);
  ASSERT_FALSE(r.deadlock_examples.empty());
  EXPECT_EQ(describe_path(net, r.deadlock_examples[0].path), "1. takeLeft0\n2. takeLeft1");
  EXPECT_EQ(describe_marking(net, r.deadlock_examples[0].marking), "hasLeft0: 1; hasLeft1: 1");
  EXPECT_EQ(describe_path(net, {}), "(no firing: the initial marking)");
  EXPECT_EQ(describe_marking(net, Marking(net.num_places(), 0)), "(no tokens)");
}

TEST(Report, ReducedRunsSayWhatTheirCountsAreAndWhichPathsMayNotBeShortest) {
  AnalysisOptions stubborn;
  stubborn.reduction = Reduction::kStubborn;
  // Two robots looping through a region with two free tokens: a violation, found by the reduced search.
  const Net bad = testnets::region_loop(2, 2);
  const AnalysisResult r = analyze(bad, stubborn);
  ASSERT_TRUE(r.reduced);
  const std::string text = format_report(bad, r);
  EXPECT_THAT(text, StartsWith("FAIL: region Z not exclusive\n"));
  EXPECT_THAT(text, HasSubstr(fmt::format("{} markings explored (reduced), ", r.states)));
  EXPECT_THAT(text, HasSubstr("(not necessarily shortest):"));
  EXPECT_THAT(text, Not(HasSubstr("never enabled")));
  const nlohmann::json j = to_json(bad, r);
  EXPECT_EQ(j["reduction"], "stubborn");
  EXPECT_EQ(j["reduced"], true);
  EXPECT_EQ(j["deadlock_path_shortest"], true);
  EXPECT_EQ(j["regions"][0]["witness_shortest"], false);
  EXPECT_TRUE(j["place_bounds"].is_null());
  EXPECT_TRUE(j["dead_transitions"].is_null());

  // Full exploration keeps its wording and exact figures.
  const AnalysisResult full = analyze(bad);
  EXPECT_THAT(format_report(bad, full), HasSubstr(fmt::format("explored {} markings, ", full.states)));
  const nlohmann::json fj = to_json(bad, full);
  EXPECT_EQ(fj["reduction"], "none");
  EXPECT_EQ(fj["reduced"], false);
  EXPECT_EQ(fj["regions"][0]["witness_shortest"], true);
}

TEST(Report, FallbackToFullExplorationIsNamed) {
  AnalysisOptions stubborn;
  stubborn.reduction = Reduction::kStubborn;
  // A token cycling a -> c -> a, leaving a note in e on the way and taking it back, and a pump that would fill e from
  // g, which starts empty and is never filled: bounded, with cycles, but not from every initial marking (a token in g
  // makes e grow), so no weighting of the places that no firing increases shows it. The reduced search finds no
  // growth, which proves nothing here, so the net is explored fully.
  NetBuilder b("fallback");
  const PlaceId a = add_place(b, "a", 1);
  const PlaceId c = add_place(b, "c", 0);
  const PlaceId e = add_place(b, "e", 0);
  const PlaceId g = add_place(b, "g", 0);
  add_transition(b, "go", {{a, 1}}, {{c, 1}, {e, 1}});
  add_transition(b, "back", {{c, 1}, {e, 1}}, {{a, 1}});
  add_transition(b, "pump", {{g, 1}}, {{g, 1}, {e, 1}});
  const Net net = std::move(b).build();
  const AnalysisResult r = analyze(net, stubborn);
  EXPECT_TRUE(r.ok()) << format_report(net, r);
  EXPECT_FALSE(r.reduced);
  EXPECT_FALSE(r.reduction_note.empty());
  EXPECT_THAT(format_report(net, r), HasSubstr("reduction stubborn not applied: "));
  EXPECT_EQ(r.states, analyze(net).states);
}

TEST(Analysis, ProgressIsReportedWhileARunLastsAndNeverForAShortOne) {
  const Net net = generators::robot_cell(5, 6, 1);
  std::vector<AnalysisProgress> seen;
  AnalysisOptions o;
  o.progress = [&seen](const AnalysisProgress& p) { seen.push_back(p); };
  o.progress_interval = std::chrono::milliseconds(0);  // every check: the interval has always passed
  const AnalysisResult r = analyze(net, o);
  ASSERT_GT(seen.size(), 2u);
  for (std::size_t i = 1; i < seen.size(); ++i) {
    EXPECT_GE(seen[i].markings, seen[i - 1].markings);
    EXPECT_GE(seen[i].edges, seen[i - 1].edges);
    EXPECT_GE(seen[i].seconds, seen[i - 1].seconds);
  }
  EXPECT_LE(seen.back().markings, r.states);
  EXPECT_LE(seen.back().queue, seen.back().markings);
  EXPECT_FALSE(seen.back().reduced);

  seen.clear();
  o.progress_interval = std::chrono::hours(1);
  analyze(net, o);
  EXPECT_TRUE(seen.empty());
}

TEST(Report, ProgressLineInPlaceOnATerminalAndOneLineEachOtherwise) {
  AnalysisProgress p;
  p.markings = 2'000'000;
  p.edges = 5'000'000;
  p.queue = 300'000;
  p.seconds = 2.0;
  std::ostringstream tty;
  ProgressPrinter on_tty(tty, true);
  on_tty(p);
  p.markings = 3'000'000;
  p.seconds = 3.0;
  on_tty(p);
  on_tty.finish();
  EXPECT_EQ(tty.str(),
            "\rchecking: 2000000 markings, 1000000/s, queue 300000, 2 s\x1b[K"
            "\rchecking: 3000000 markings, 1000000/s, queue 300000, 3 s\x1b[K\r\x1b[K");

  std::ostringstream log;
  ProgressPrinter plain(log, false);
  p.reduced = true;
  plain(p);
  plain.finish();
  EXPECT_EQ(log.str(), "checking: 3000000 markings (reduced), 1000000/s, queue 300000, 3 s\n");

  std::ostringstream quiet;
  ProgressPrinter none(quiet, true);
  none.finish();  // nothing shown, nothing to erase
  EXPECT_EQ(quiet.str(), "");
}

// A program too large for exhaustive analysis is said to be so from the first progress report, with the figures:
// while the frontier is wide the space is still growing, and the note gives how soon the limit comes at this rate.
TEST(Analysis, SizeWarningComesWhileTheFrontierIsWideAndGivesTheFigures) {
  AnalysisProgress p;
  p.markings = 800'000;
  p.queue = 260'000;
  p.seconds = 1.0;
  EXPECT_EQ(size_warning(p, 5'000'000),
            "after 1.0 s 800000 markings, 260000 not expanded yet (800000/s): still growing; at this rate the state "
            "limit of 5000000 is reached in about 6 s; --reduction stubborn explores fewer interleavings");
  p.reduced = true;  // already reduced: no advice to reduce
  EXPECT_THAT(size_warning(p, 5'000'000), ::testing::EndsWith("reached in about 6 s"));

  p.queue = 50'000;  // a narrow frontier: the exploration may be about to end
  EXPECT_EQ(size_warning(p, 5'000'000), "");
  p.queue = 260'000;
  EXPECT_EQ(size_warning(p, 800'000), "");  // the limit is reached already: the closing note says so
  p.seconds = 0;
  EXPECT_EQ(size_warning(p, 5'000'000), "");
}

// check_and_report prints it once, at the first progress report, before the closing note.
TEST(Analysis, CheckAndReportWarnsOfASpaceTooLargeOnce) {
  CheckOptions options;
  options.progress = true;
  options.analysis.max_states = 200'000;
  options.analysis.progress_interval = std::chrono::milliseconds(1);
  std::ostringstream out, err;
  std::streambuf* old = std::cerr.rdbuf(err.rdbuf());
  const int status = check_and_report(switches(30), "wide.pnml", options, out);  // 2^30 markings, breadth first
  std::cerr.rdbuf(old);
  EXPECT_EQ(status, 1);
  const std::string text = err.str();
  const std::string note = "wide.pnml: note: after ";
  const auto warning = text.find(note);
  ASSERT_NE(warning, std::string::npos) << text;
  EXPECT_EQ(text.find(note, warning + note.size()), std::string::npos) << "warned twice:\n" << text;
  EXPECT_THAT(text.substr(warning), HasSubstr("still growing; at this rate the state limit of 200000 is reached in"));
  EXPECT_GT(text.find("wide.pnml: note: exploration stopped (state limit"), warning);
}

}  // namespace
}  // namespace cellwright::petri
