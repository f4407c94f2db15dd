// Net reduction before exploring (analysis.hpp uses it under Reduction::kStubborn, AnalysisOptions::agglomerate):
// transitions that always follow one another are fused into one, by the two agglomeration rules of Berthelot
// ("Transformations and decompositions of nets", 1987; Haddad and Pradat-Peyre's conditions). A task program's net
// shrinks to one transition per robot between its waits: a lock-step barrier of n robots (n - 1 signals and n - 1
// waits per robot, n (n - 1) event places) becomes one transition per robot that takes the events meant for it and
// gives those for the next barrier. The runtime still executes the original primitives; only the checker sees the
// reduced net.
//
// Both rules remove a place p with one producer h and one consumer f (h != f), arcs of weight 1, no initial token, not
// inside any region and not a final place:
//  - post-agglomeration: f's only input is p and f has an output. Once h has fired, f is enabled and nothing can
//    disable it; h is replaced by h;f and f removed.
//  - pre-agglomeration: h's only output is p, h has an input, each of h's input places has h as its only consumer,
//    and h and f share no input place. Nothing else wants h's tokens, so firing h can wait until just before f; f is
//    replaced by h;f and h removed (h is "delayed").
// What is preserved (N the net, N' the reduced one; every marking of N' is a reachable marking of N restricted to
// the kept places, with the removed places empty):
//  - dead markings, one to one: a dead marking of N becomes one of N' by firing the pending post-agglomerated
//    transitions (none: their place is empty when dead) and un-firing the pending delayed ones; back, a dead marking
//    of N' becomes one of N by firing the enabled delayed transitions until none is (complete_dead()). So deadlocks and
//    proper ends are counted exactly;
//  - each region's largest occupancy: a marking of N is covered, on the places inside, by its image in N' (the
//    removed places are not inside; firing a post-agglomerated f only adds, un-firing a delayed h only adds), and N''s
//    markings are N's;
//  - boundedness: N' has N's markings; conversely each removed place holds at most what an output of f (post) or an
//    input of h (pre) holds in the image, so N is bounded iff N' is.
// Paths map back by expanding each fused transition into its original firing sequence (expand()); a path of N' to
// a marking gives a path of N to the same marking. Only the shortest-path property is lost.
//
// Thread safety: agglomerate() is re-entrant; an Agglomeration is an immutable value.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

struct Agglomeration {
  Net net;  // the reduced net: the kept places (same ids, names and kinds), the fused transitions, regions, robots
  // Per transition of `net`: the firing sequence of the original net it stands for (one transition if not fused).
  std::vector<std::vector<TransitionId>> expansion;
  std::vector<PlaceId> original_place;  // per place of `net`: its id in the original net
  std::vector<bool> delayed;            // per original transition: fused into its successor by pre-agglomeration
  std::size_t post = 0;                 // post-agglomerations applied
  std::size_t pre = 0;                  // pre-agglomerations applied

  // Some place was removed (else `net` is a copy of the original).
  bool changed() const { return post + pre > 0; }
  // A path of `net` as a path of the original net.
  std::vector<TransitionId> expand(const std::vector<TransitionId>& path) const;
  // A place id of `net` in the original net.
  PlaceId place(PlaceId reduced) const { return original_place[reduced]; }
};

// Applies both rules until neither applies (a worklist over the places: linear in the net's size for task nets).
Agglomeration agglomerate(const Net& net);

// Given `marking`, reached in `original` by the expansion of a path of agg.net to a dead marking of agg.net, fires the
// enabled delayed transitions until none is, appending them to `path`; returns the marking reached if it is dead in
// `original`, else nullopt (which the rules above exclude; callers then analyse the original net).
std::optional<Marking> complete_dead(const Net& original, const Agglomeration& agg, Marking marking,
                                     std::vector<TransitionId>& path);

}  // namespace cellwright::petri
