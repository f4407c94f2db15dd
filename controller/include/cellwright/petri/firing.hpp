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

// True when every input place of t holds at least the arc weight.
bool is_enabled(const Net& net, const Marking& m, TransitionId t);

// All enabled transitions, ascending by id.
std::vector<TransitionId> enabled(const Net& net, const Marking& m);

// The marking after firing t. Throws InternalError if t is not enabled (callers check first).
Marking fire(const Net& net, const Marking& m, TransitionId t);
// In place: m becomes the successor.
void fire_in_place(const Net& net, Marking& m, TransitionId t);

// Arbitration state. A value: copy it with the marking to replay or branch a run.
struct Arbiter {
  // For each place, the transition that most recently consumed from it (or UINT32_MAX); round-robin starts after it.
  std::vector<TransitionId> last_served;
};
Arbiter make_arbiter(const Net& net);

// A maximal set of enabled transitions that can all fire together from m (no two compete for the same tokens),
// chosen deterministically: same net, marking, arbiter and `allowed` set give the same answer. Where transitions
// compete for a shared place, the one after the place's last-served transition in round-robin order wins, so a
// transition that stays enabled is served within one round of its competitors (no starvation).
// `allowed`, if non-empty, restricts the choice (e.g. to transitions whose input commands have completed); it is
// indexed by TransitionId.
std::vector<TransitionId> choose(const Net& net, const Marking& m, const Arbiter& arbiter,
                                 const std::vector<bool>& allowed = {});

// Fire the chosen set in ascending order and update the arbiter.
void fire_chosen(const Net& net, Marking& m, Arbiter& arbiter, const std::vector<TransitionId>& chosen);

}  // namespace cellwright::petri
