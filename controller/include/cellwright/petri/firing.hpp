// The token game: which transitions are enabled, firing one, and choosing among conflicting ones.
// Pure functions over (Net, Marking); the only state besides the marking is the Arbiter value, which remembers
// whom each shared place last served so that no robot is starved.
//
// Thread safety: all functions are re-entrant; the task-control thread owns its Marking and Arbiter.
#pragma once

#include <cstdint>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

// All functions below throw InternalError (CW_CHECK) when given a marking, arbiter or `allowed` vector sized for
// another net, or a transition id out of range: those are callers' bugs, not input errors.

// True when every input place of t holds at least the arc weight.
bool is_enabled(const Net& net, const Marking& m, TransitionId t);

// All enabled transitions, ascending by id.
std::vector<TransitionId> enabled(const Net& net, const Marking& m);

// True when no transition is enabled in m.
bool is_dead(const Net& net, const Marking& m);

// The marking after firing t. Throws InternalError if t is not enabled (callers check first) or if a place would
// exceed the Tokens range.
Marking fire(const Net& net, const Marking& m, TransitionId t);
// In place: m becomes the successor. Same errors as fire(); m is unchanged when it throws.
void fire_in_place(const Net& net, Marking& m, TransitionId t);

// Arbitration state. A value: copy it with the marking to replay or branch a run.
struct Arbiter {
  // For each place, the transition that most recently consumed from it (or kNone); round-robin starts after it.
  std::vector<TransitionId> last_served;
  static constexpr TransitionId kNone = UINT32_MAX;
};
// An arbiter for `net` that has served nobody yet.
Arbiter make_arbiter(const Net& net);

// A maximal set of enabled transitions that can all fire together from m (no two compete for the same tokens),
// chosen deterministically: same net, marking, arbiter and `allowed` set give the same answer. Returned ascending.
// Where transitions compete for a shared place (their joint demand exceeds its tokens), the one after the place's
// last-served transition in round-robin order (ascending ids, wrapping) wins, so a transition that stays enabled is
// served within one round of its competitors (no starvation). A transition contending at several places ranks by
// its worst round-robin position among them; transitions without contention are always chosen.
// `allowed`, if non-empty, restricts the choice (e.g. to transitions whose input commands have completed); it is
// indexed by TransitionId.
std::vector<TransitionId> choose(const Net& net, const Marking& m, const Arbiter& arbiter,
                                 const std::vector<bool>& allowed = {});

// Fire the chosen set (any order, no repeats) in ascending order and update the arbiter: for each input place, the
// chosen transition served last in that place's round-robin order becomes its last-served. Throws InternalError,
// leaving m and the arbiter unchanged, if the set cannot fire together from m.
void fire_chosen(const Net& net, Marking& m, Arbiter& arbiter, const std::vector<TransitionId>& chosen);

}  // namespace cellwright::petri
