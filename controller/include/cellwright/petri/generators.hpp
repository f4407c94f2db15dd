// Nets of known structure and known state-space size, built programmatically: oracles for the tests, workloads for
// the benchmarks (tools/bench/petri_bench.cpp) and small examples.
//
// Thread safety: all functions are re-entrant.
#pragma once

#include <cstdint>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri::generators {

// The Kanban system of Ciardo & Tilgner (1996), as in the Model Checking Contest: four stations with N kanban cards
// each. Per station i (1..4) places Pm<i> (part being machined), Pback<i> (sent back for rework), Pkan<i> (free
// cards, N initially) and Pout<i> (finished), and transitions tredo<i>, tback<i>, tok<i>; tin1 takes a card into
// station 1, tsynch1_23 moves a finished part of station 1 into stations 2 and 3 at once, tsynch4_23 joins them into
// station 4, and tout4 returns station 4's card. 16 places, 16 transitions, no deadlock, every place bounded by N.
Net kanban(Tokens n);
// Its reachable markings, by the published closed form C(N+3,3)^2 (3N^5+30N^4+115N^3+210N^2+182N+60)/60
// (160 for N=1, 4,600 for N=2, 2,546,432 for N=5).
std::uint64_t kanban_reachable(std::uint64_t n);

// Dining philosophers: philosopher i has places think<i> (1), hasLeft<i>, eat<i> and fork fork<i> (1); takeLeft<i>,
// takeRight<i> (fork<(i+1) mod n>), release<i>. The only dead marking is everyone holding the left fork, n firings
// from the start. Throws std::invalid_argument if n < 1.
Net philosophers(int n);

// A workcell of `robots` robots, each cycling forever through `steps` command places ("r<i>.c<j>", kExecuting, with
// Origin robot/line/task/motion filled in), sharing `regions` critical regions (places "Z<k>.free", kRegion, one
// token). Region k spans steps s+1 and s+2 of every robot, where s = k * steps / regions: the transition from step s
// takes the region's token and the one from step s+2 gives it back. One transition per robot and step, so
// robots * steps transitions. Throws std::invalid_argument unless robots >= 1, regions >= 0 and
// steps >= max(2, 3 * regions) (regions must not overlap).
Net robot_cell(int robots, int steps, int regions);
// Its reachable markings: sum over j = 0..min(regions, robots) of C(regions, j) * robots!/(robots-j)! * 2^j *
// (steps - 2 regions)^(robots - j) (each occupied region holds one robot at one of its two steps).
std::uint64_t robot_cell_reachable(int robots, int steps, int regions);

}  // namespace cellwright::petri::generators
