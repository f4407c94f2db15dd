// Partial-order reduction for the reachability analysis (analysis.hpp, AnalysisOptions::reduction): stubborn sets in
// the sense of Valmari, as LoLA computes them for P/T nets, and the structural facts that decide what a reduced
// search may claim.
//
// A stubborn set S of a marking m (not dead) is a set of transitions with
//  - D1: for every enabled t in S, every transition that consumes from a place of t's pre-set is in S (so no
//    transition outside S can disable t, and t commutes with every sequence of transitions outside S);
//  - D2: for every disabled t in S, all transitions that raise one of its insufficiently marked places (the
//    "scapegoat") are in S (so no sequence outside S can enable t);
//  - at least one enabled transition (the key);
//  - V (regions): if S holds an enabled transition that lowers the tokens inside some watched region, S holds every
//    transition that raises the tokens inside some watched region (a region is watched unless a place sub-invariant
//    has shown it exclusive, structural.hpp: then its verdict needs no exploration, and V and the proviso are not
//    needed for it; deadlocks never need them).
// Firing only the enabled transitions of S keeps every reachable dead marking reachable, at its BFS distance (so a
// breadth-first search still reports shortest deadlock paths and the exact number of dead markings), and, with V and
// the ignoring proviso below, every upward-closed set of region occupancies (so each region's verdict and its largest
// occupancy are exact; the witness path may be longer than the shortest one).
//
// The ignoring proviso: in a state space with cycles, a transition can stay enabled forever outside every stubborn
// set along a cycle. The explorer fully expands a marking whose reduced successors include one already expanded
// (breadth-first, every cycle then holds a fully expanded marking: the member expanded last). It is not needed when
// every run is finite (finite_runs()), nor when the net has no regions (deadlocks do not need it).
//
// Boundedness is not preserved by stubborn sets (a transition that pumps tokens can be ignored in favour of one that
// drains them). A covering found by the reduced search is a real unbounded witness; the absence of one proves
// nothing, so analyze() trusts a reduced search for boundedness only when structurally_bounded() holds (every run
// finite, or a bounding weighting of the places exists, found by difference constraints or a linear program), and
// otherwise falls back to full exploration.
//
// Thread safety: a StubbornSets is used by one exploration; the free functions are re-entrant.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

// True when every transition can fire only finitely often in any run, shown structurally: a transition is finite when
// it takes tokens (net) from a place that only finite transitions raise. Then every run is finite, the reachability
// graph is finite and acyclic, and the net is bounded. Holds for every task program without loops (each robot's chain
// is acyclic), whatever its events, regions and hand-overs.
bool finite_runs(const Net& net);

// A bounding weighting of the places (a positive sub-invariant): weight[p] >= 1 for every place and
// weight . C(t) <= 0 for every transition t, C(t) being the net change of firing t. The weighted token sum then never
// grows, so place p holds at most (weight . m0) / weight[p] tokens in any marking reachable from any initial marking
// m0; and such a weighting exists iff the net is bounded for every initial marking (structurally bounded, Memmi and
// Roucairol). `linear_program` says how it was found.
struct BoundingWeights {
  std::vector<std::uint64_t> weight;  // per place, >= 1
  bool linear_program = false;        // by the linear program (weight 1 for every place off the robots' chains failed)
};

// Finds a bounding weighting, or nullopt. Exact: a weighting returned has passed is_bounding_weighting(). Complete as
// far as GLPK's answer can be made exact (below): the steps are equivalences, not heuristics. Path places (robot places
// first, then any place every transition takes one token from or gives one token to, at most one of each per
// transition) only need difference constraints, which are eliminated exactly: constraints between strongly connected
// components are dropped, chains inside one are added up, so a robot's loop becomes one condition on the weights of the
// other places (events, semaphores, regions, loop decisions). Those are tried at weight 1 first (a Bellman-Ford over
// what is left: loops whose events are handshaken, each signal answered before the next), then found by a linear
// program solved by GLPK (minimise their sum subject to weight >= 1 and the conditions: a loop whose leader tells its
// followers again or exit needs it). GLPK's floating-point answer is turned into small-denominator rationals and scaled
// to integers; if that does not hold exactly, GLPK's exact rational simplex (glp_exact) is asked for the same vertex.
// The path places' weights are then shortest-path potentials. nullopt means no weighting exists, or (never seen on task
// nets or the tests' random nets) that no exact one could be recovered from GLPK's answer: boundedness is then simply
// not claimed. Weights stay below 2^53. Uses GLPK, whose environment is per thread and freed before returning.
std::optional<BoundingWeights> bounding_weights(const Net& net);

// True when `weight` (one entry per place) is a bounding weighting of `net`, checked in exact integer arithmetic.
bool is_bounding_weighting(const Net& net, const std::vector<std::uint64_t>& weight);

// finite_runs(net) or a bounding weighting exists (bounding_weights(net) has a value): every place of the net is
// bounded, whatever the initial marking.
bool structurally_bounded(const Net& net);

// The stubborn-set computation for one net (precomputed consumers, raisers and region effects).
class StubbornSets {
 public:
  // `watched`, one flag per region (empty: every region), names the regions whose occupancy the exploration must
  // observe: only they take part in condition V. A region shown exclusive by a place sub-invariant (structural.hpp)
  // needs no observing, so analyze() leaves it out (it is what made every leave pull in every enter).
  explicit StubbornSets(const Net& net, const std::vector<bool>& watched = {});

  // The enabled transitions of the smallest stubborn set found (closures from each enabled transition as key, the
  // first with a single enabled transition wins), ascending, into `out`. `enabled` lists the enabled transitions,
  // ascending and non-empty; `tokens(p)` gives the marking. The result is a non-empty subset of `enabled`.
  void choose(const std::vector<TransitionId>& enabled, const std::function<Tokens(PlaceId)>& tokens,
              std::vector<TransitionId>& out);

 private:
  // Closure from `key`: returns the number of enabled transitions in it, or stops (returning `limit`) once it reaches
  // `limit`. Members carry stamp_ == gen_.
  std::size_t closure(TransitionId key, std::size_t limit, const std::function<Tokens(PlaceId)>& tokens);
  void push(TransitionId t);

  const Net& net_;
  std::vector<std::vector<TransitionId>> consumers_;  // per place: transitions with it in their pre-set
  std::vector<std::vector<TransitionId>> raisers_;    // per place: transitions whose firing adds to it (net)
  std::vector<TransitionId> region_raisers_;          // transitions that add tokens inside some region
  std::vector<bool> region_lowers_;                   // per transition: it removes tokens from inside some region
  std::vector<std::uint32_t> stamp_;                  // closure membership, by generation
  std::vector<std::uint32_t> enabled_stamp_;          // enabled in the current marking, by generation
  std::uint32_t gen_ = 0;
  std::uint32_t marking_gen_ = 0;
  std::vector<TransitionId> stack_;
};

}  // namespace cellwright::petri
