// The token game: enabling, firing, and the arbiter's choice (maximal, deterministic, fair).
#include "cellwright/petri/firing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <random>

#include "cellwright/common/error.hpp"
#include "controller/petri/test_nets.hpp"

namespace cellwright::petri {
namespace {

using testnets::add_place;
using testnets::add_transition;

// p(3) --2--> t --> q(0), plus u: q -> p.
Net weighted() {
  NetBuilder b("w");
  const PlaceId p = add_place(b, "p", 3);
  const PlaceId q = add_place(b, "q");
  add_transition(b, "t", {{p, 2}}, {{q, 1}});
  add_transition(b, "u", {{q, 1}}, {{p, 1}});
  return std::move(b).build();
}

TEST(Firing, EnabledNeedsTheArcWeightInEveryInputPlace) {
  const Net net = weighted();
  EXPECT_TRUE(is_enabled(net, {3, 0}, 0));
  EXPECT_TRUE(is_enabled(net, {2, 0}, 0));
  EXPECT_FALSE(is_enabled(net, {1, 0}, 0));
  EXPECT_FALSE(is_enabled(net, {1, 0}, 1));
  EXPECT_EQ(enabled(net, {2, 1}), (std::vector<TransitionId>{0, 1}));
  EXPECT_EQ(enabled(net, {1, 0}), (std::vector<TransitionId>{}));
  EXPECT_TRUE(is_dead(net, {1, 0}));
  EXPECT_FALSE(is_dead(net, {0, 1}));
}

TEST(Firing, FireMovesTokensByTheWeights) {
  const Net net = weighted();
  EXPECT_EQ(fire(net, {3, 0}, 0), (Marking{1, 1}));
  Marking m{3, 0};
  fire_in_place(net, m, 0);
  fire_in_place(net, m, 1);
  EXPECT_EQ(m, (Marking{2, 0}));
}

TEST(Firing, FiringADisabledTransitionIsAnInternalErrorAndChangesNothing) {
  const Net net = weighted();
  Marking m{1, 0};
  EXPECT_THROW(fire_in_place(net, m, 0), InternalError);
  EXPECT_EQ(m, (Marking{1, 0}));
  EXPECT_THROW((void)fire(net, m, 5), InternalError);
  EXPECT_THROW((void)is_enabled(net, {1, 0, 0}, 0), InternalError);
  EXPECT_THROW((void)enabled(net, {1}), InternalError);
}

TEST(Firing, TokenOverflowIsCaughtBeforeChangingTheMarking) {
  NetBuilder b("big");
  const PlaceId p = add_place(b, "p", 1);
  const PlaceId q = add_place(b, "q", 4'000'000'000u);
  add_transition(b, "t", {{p, 1}}, {{p, 1}, {q, 400'000'000u}});
  const Net net = std::move(b).build();
  Marking m = net.initial_marking();
  EXPECT_THROW(fire_in_place(net, m, 0), InternalError);
  EXPECT_EQ(m, net.initial_marking());
}

// Runs `rounds` steps of a chooser on a region_loop net and counts how often each robot entered.
std::vector<int> entries(const Net& net, int rounds,
                         const std::function<std::vector<TransitionId>(const Marking&, const Arbiter&)>& chooser) {
  Marking m = net.initial_marking();
  Arbiter arb = make_arbiter(net);
  std::vector<int> count(net.robots().size(), 0);
  for (int i = 0; i < rounds; ++i) {
    const std::vector<TransitionId> step = chooser(m, arb);
    EXPECT_FALSE(step.empty()) << "the loop net never deadlocks";
    for (TransitionId t : step) {
      const Transition& tr = net.transitions()[t];
      if (tr.id.ends_with(".enter")) ++count[static_cast<std::size_t>(tr.id[1] - '1')];
    }
    fire_chosen(net, m, arb, step);
  }
  return count;
}

int spread(const std::vector<int>& c) {
  const auto [lo, hi] = std::minmax_element(c.begin(), c.end());
  return *hi - *lo;
}

// "Lowest id wins": maximal and deterministic, but with no memory of whom it served.
std::vector<TransitionId> lowest_id_wins(const Net& net, const Marking& m) {
  Marking left = m;
  std::vector<TransitionId> out;
  for (TransitionId t : enabled(net, m)) {
    if (is_enabled(net, left, t)) {
      for (const Arc& a : net.transitions()[t].inputs) left[a.place] -= a.weight;
      out.push_back(t);
    }
  }
  return out;
}

TEST(Arbiter, RobotsSharingARegionTakeTurns) {
  for (int robots : {2, 3}) {
    const Net net = testnets::region_loop(robots);
    const auto count = entries(net, 1000, [&](const Marking& m, const Arbiter& a) { return choose(net, m, a); });
    EXPECT_LE(spread(count), 1) << robots << " robots";
    // Every second round frees the region, so 500 entries in all.
    int total = 0;
    for (int c : count) total += c;
    EXPECT_EQ(total, 500) << robots << " robots";
  }
}

TEST(Arbiter, RoundRobinAlsoHoldsForARegionOfTwo) {
  const Net net = testnets::region_loop(3, 2);
  const auto count = entries(net, 999, [&](const Marking& m, const Arbiter& a) { return choose(net, m, a); });
  EXPECT_LE(spread(count), 1);
  EXPECT_GT(count[0], 300);
}

TEST(Arbiter, LowestIdWinsWouldStarveTheSameRobots) {
  // The check above is not vacuous: without the arbiter's memory robot 1 takes the region every time.
  for (int robots : {2, 3}) {
    const Net net = testnets::region_loop(robots);
    const auto count = entries(net, 1000, [&](const Marking& m, const Arbiter&) { return lowest_id_wins(net, m); });
    EXPECT_GT(spread(count), 1) << robots << " robots";
    EXPECT_EQ(count[1], 0);
  }
}

TEST(Arbiter, AllowedRestrictsTheChoice) {
  const Net net = testnets::region_loop(2);
  const Arbiter arb = make_arbiter(net);
  const Marking m = net.initial_marking();
  const TransitionId enter1 = *net.find_transition("r1.enter");
  const TransitionId enter2 = *net.find_transition("r2.enter");
  EXPECT_EQ(choose(net, m, arb), (std::vector<TransitionId>{enter1}));
  std::vector<bool> allowed(net.num_transitions(), true);
  allowed[enter1] = false;
  EXPECT_EQ(choose(net, m, arb, allowed), (std::vector<TransitionId>{enter2}));
  std::fill(allowed.begin(), allowed.end(), false);
  EXPECT_TRUE(choose(net, m, arb, allowed).empty());
  EXPECT_THROW((void)choose(net, m, arb, std::vector<bool>(1, true)), InternalError);
}

TEST(Arbiter, FireChosenRejectsASetThatCannotFireTogetherAndChangesNothing) {
  const Net net = testnets::region_loop(2);
  Arbiter arb = make_arbiter(net);
  Marking m = net.initial_marking();
  const std::vector<TransitionId> both{*net.find_transition("r1.enter"), *net.find_transition("r2.enter")};
  EXPECT_THROW(fire_chosen(net, m, arb, both), InternalError);
  EXPECT_EQ(m, net.initial_marking());
  EXPECT_EQ(arb.last_served, make_arbiter(net).last_served);
  EXPECT_THROW(fire_chosen(net, m, arb, {both[0], both[0]}), InternalError);
}

TEST(Arbiter, FireChosenRemembersWhomEachPlaceServed) {
  const Net net = testnets::region_loop(2);
  Arbiter arb = make_arbiter(net);
  Marking m = net.initial_marking();
  const TransitionId enter2 = *net.find_transition("r2.enter");
  fire_chosen(net, m, arb, {enter2});
  EXPECT_EQ(arb.last_served[*net.find_place("free")], enter2);
  EXPECT_EQ(arb.last_served[*net.find_place("r2.out")], enter2);
  EXPECT_EQ(arb.last_served[*net.find_place("r1.out")], Arbiter::kNone);
}

// A random net and a marking reached by a random walk, for property checks.
struct RandomCase {
  Net net;
  Marking m;
};

RandomCase random_case(std::mt19937& rng) {
  auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  NetBuilder b("random");
  const int np = pick(1, 6);
  const int nt = pick(1, 8);
  for (int p = 0; p < np; ++p) add_place(b, fmt::format("p{}", p), static_cast<Tokens>(pick(0, 3)));
  for (int t = 0; t < nt; ++t) {
    std::vector<Arc> in, out;
    for (int p = 0; p < np; ++p) {
      if (pick(0, 2) == 0) in.push_back({static_cast<PlaceId>(p), static_cast<Tokens>(pick(1, 2))});
      if (pick(0, 2) == 0) out.push_back({static_cast<PlaceId>(p), static_cast<Tokens>(pick(1, 2))});
    }
    add_transition(b, fmt::format("t{}", t), in, out);
  }
  RandomCase c{std::move(b).build(), {}};
  c.m = c.net.initial_marking();
  const int steps = pick(0, 5);
  for (int i = 0; i < steps; ++i) {
    const auto en = enabled(c.net, c.m);
    if (en.empty()) break;
    const TransitionId t = en[static_cast<std::size_t>(pick(0, static_cast<int>(en.size()) - 1))];
    if (c.m.size() > 0 && *std::max_element(c.m.begin(), c.m.end()) > 50) break;
    fire_in_place(c.net, c.m, t);
  }
  return c;
}

TEST(Arbiter, ChoiceIsConflictFreeMaximalAndDeterministic) {
  std::mt19937 rng(20240607);
  int nontrivial = 0;
  for (int i = 0; i < 500; ++i) {
    const RandomCase c = random_case(rng);
    Arbiter arb = make_arbiter(c.net);
    // Some history, so that the round-robin positions differ from the initial ones.
    for (std::size_t p = 0; p < arb.last_served.size(); ++p) {
      arb.last_served[p] = static_cast<TransitionId>((p * 7 + static_cast<std::size_t>(i)) % c.net.num_transitions());
    }
    const auto chosen = choose(c.net, c.m, arb);
    EXPECT_EQ(chosen, choose(c.net, c.m, arb)) << "deterministic";
    EXPECT_TRUE(std::is_sorted(chosen.begin(), chosen.end()));
    // Conflict-free: the whole set fits into the marking at once.
    Marking left = c.m;
    for (TransitionId t : chosen) {
      for (const Arc& a : c.net.transitions()[t].inputs) {
        ASSERT_GE(left[a.place], a.weight) << "set does not fit at " << c.net.transitions()[t].id;
        left[a.place] -= a.weight;
      }
    }
    // Maximal: no other enabled transition fits into what is left.
    for (TransitionId t : enabled(c.net, c.m)) {
      if (std::binary_search(chosen.begin(), chosen.end(), t)) continue;
      EXPECT_FALSE(is_enabled(c.net, left, t)) << c.net.transitions()[t].id << " could have been added";
    }
    if (chosen.size() < enabled(c.net, c.m).size()) ++nontrivial;
    // And the set fires.
    Marking m = c.m;
    Arbiter a2 = arb;
    EXPECT_NO_THROW(fire_chosen(c.net, m, a2, chosen));
  }
  EXPECT_GT(nontrivial, 50) << "the random cases should exercise real conflicts";
}

}  // namespace
}  // namespace cellwright::petri
