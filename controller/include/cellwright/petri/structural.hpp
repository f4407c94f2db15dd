// Structural checks that decide properties without exploring the reachability graph, for nets too large to explore
// (analysis.hpp uses them under Reduction::kStubborn when its exploration budget runs out).
//
// Region exclusion by a place sub-invariant. For a region with places `inside` and capacity c, a weighting y of the
// places, y >= 0 integral, with y . C(t) <= 0 for every transition t (C(t): what firing t changes) and y(p) >= d >= 1
// for every p inside, gives for every reachable marking M: d * sum_inside M(p) <= y . M <= y . M0, so the tokens inside
// never exceed floor(y . M0 / d); when that is <= c the region is exclusive in every reachable marking. For a task net
// the weighting is 1 on the region's free place and on the places inside (free + inside = 1 is an invariant), which is
// tried first; otherwise a linear program (minimise y . M0 subject to the above with d = 1, solved by GLPK) looks for
// one, and its answer is turned into integers and checked exactly before it is trusted. By LP duality this proves
// exactly the regions whose occupancy the state equation's linear relaxation bounds by c.
//
// Deadlock freedom by the state equation. Every marking M reachable by a firing sequence with Parikh vector x (x_t:
// how often t fires) satisfies M = M0 + C x, M >= 0, x >= 0 integral. A dead marking that is not a proper end also
// satisfies: for every transition t, some input place p holds fewer than W(p, t) tokens; and some final place holds
// fewer than its weight (Net::final_places; no such condition when the net has none). deadlock_free_by_state_equation
// writes these as an integer program over x (GLPK's branch and cut): for a transition whose input places are all
// known to hold at most one token and whose arcs weigh 1, the disjunction is "the sum of its input places' tokens is
// at most (inputs - 1)"; otherwise a binary per input place selects it, with the place's proven bound U as the big-M
// (M(p) <= W - 1 + (U - W + 1)(1 - z)); an input place without a proven bound makes the transition's condition
// vacuous (weaker, still sound). Place bounds come from verified sub-invariants: the bounding weighting
// (stubborn.hpp), each robot's chain (the places with one robot label, when their indicator is a sub-invariant) and
// the region weightings above. Infeasible: no reachable marking is dead and not a proper end, whatever the order of
// firing (the program is deadlock-free). Only an infeasibility with a certificate counts: the linear relaxation's,
// confirmed by GLPK's exact rational simplex. Branch and cut's "no integer solution" is floating point without one, so
// it gives kUnknown (the caller explores on). Feasible: the solution is a candidate only (the state equation admits
// markings that are not reachable). The candidate's unmarked places are then searched for a trap (a set of places that
// every transition taking from it gives back to) that is marked initially: such a trap stays marked in every reachable
// marking, so the constraint "the trap holds a token" excludes the candidate and nothing reachable; the program is
// solved again (trap refinement, Esparza and Melzer). A candidate without such a trap is handed to
// guided_deadlock_search, which looks for a real firing sequence to a dead marking using the candidate's firing
// counts; a sequence found is a true counterexample (replayed with the firing rule), though not necessarily a
// shortest one.
//
// Thread safety: re-entrant; GLPK's environment is per thread and freed before each function returns.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

// A proof that a region never holds more than its capacity: the weighting y and divisor d of the header comment.
struct RegionProof {
  std::vector<std::uint64_t> weight;  // per place, >= 0
  std::uint64_t divisor = 1;          // the least weight of a place inside
  std::uint64_t bound = 0;            // floor(y . M0 / divisor): at most this many tokens inside, ever
  bool linear_program = false;        // found by the LP (the free place + inside weighting did not hold)
};

// A proof for region `k` of `net`, or nullopt (none found: the region may still be exclusive; explore to know).
// Exact: a proof returned has passed is_region_proof(). Throws std::out_of_range for a bad index.
std::optional<RegionProof> prove_region_exclusive(const Net& net, std::size_t k);

// True when `proof` holds for region k, checked with integer arithmetic: weights >= 0, y . C(t) <= 0 for every t,
// divisor >= 1 and every weight inside >= divisor, bound == floor(y . M0 / divisor) <= capacity.
bool is_region_proof(const Net& net, std::size_t k, const RegionProof& proof);

// A proven upper bound per place (nullopt: none known), from the sub-invariants named in the header comment.
std::vector<std::optional<std::uint64_t>> place_bounds(const Net& net);

// The outcome of the state-equation check.
struct StateEquationResult {
  enum class Verdict : std::uint8_t {
    kDeadlockFree,  // no reachable marking is dead and not a proper end (proved)
    kCandidate,     // a solution the traps could not exclude: `marking` and `firings` (maybe not reachable)
    kUnknown,       // the solver gave no answer (time or size limit, numerical trouble): `reason` says which
  };
  Verdict verdict = Verdict::kUnknown;
  Marking marking;                     // the candidate dead marking
  std::vector<std::uint64_t> firings;  // its firing counts, per transition
  std::size_t traps = 0;               // trap constraints added
  std::string reason;                  // for kUnknown
};

struct StateEquationOptions {
  std::size_t max_traps = 8;    // trap refinements before giving a candidate back
  double time_limit_s = 0.1;    // per solve of the integer program (past it: kUnknown, and analyze() explores on)
};

StateEquationResult deadlock_free_by_state_equation(const Net& net, const StateEquationOptions& options = {});

// A firing sequence from the initial marking to a dead marking that is not a proper end, found by a depth-first
// search that fires only transitions with firing counts left in `firings` (each firing uses one), trying them in
// ascending order and never visiting a marking twice, within `max_markings` markings; nullopt if none was found
// (which proves nothing). A sequence returned has been replayed with the firing rule and ends dead.
std::optional<std::vector<TransitionId>> guided_deadlock_search(const Net& net,
                                                                const std::vector<std::uint64_t>& firings,
                                                                std::uint64_t max_markings = 200'000);

}  // namespace cellwright::petri
