// Earliest-time simulation of a timed Petri net: the core of the cycle-time estimate (estimate.hpp).
//
// Timing is on places (the paper's timed places): a token put into place p at time t may leave it from t + d(p) on,
// where d(p) is the duration of what the place stands for (the command a robot executes there; 0 for events, waits,
// start and done places). A transition fires as soon as every token it needs is available: all robots run
// concurrently, and a wait is resolved at the time its signal was given.
//
// The simulation is greedy and deterministic: among the enabled transitions it fires the one that can fire earliest
// (the latest availability of the tokens it needs), ties to the lowest transition id; it consumes the earliest
// available tokens of each input place. For the nets of task programs (conflict-free but for semaphores and regions)
// that is the earliest schedule; where transitions compete for a semaphore, the one ready first gets it.
//
// Thread safety: a pure function; any thread may call it.
#pragma once

#include <cstdint>
#include <vector>

#include "cellwright/petri/net.hpp"
#include "cellwright/task/loop_control.hpp"

namespace cellwright::cell {

struct TimedFiring {
  petri::TransitionId transition = 0;
  double time = 0;  // s since the start
};

struct TimedRun {
  std::vector<TimedFiring> firings;  // in firing order (times never decrease)
  petri::Marking final_marking;
  bool finished = false;  // the run ended in the net's final marking (every robot done); false: it died elsewhere, or
                          // hit the firing limit
  double finish = 0;      // time of the last firing (0 if none): the cycle time when finished
};

// Runs the net from its initial marking until no transition is enabled, or until `max_firings` firings (a guard
// against unbounded nets; finished is then false). place_duration has one entry per place, each finite and >= 0
// (else InternalError). The net of a program with loops needs `loops` (made for it, fresh): the loops' decisions
// are then taken as their counts say (task/loop_control.hpp); without, a decision goes to the lower transition id.
TimedRun simulate_timed(const petri::Net& net, const std::vector<double>& place_duration,
                        std::uint64_t max_firings = 1'000'000, task::LoopControl* loops = nullptr);

}  // namespace cellwright::cell
