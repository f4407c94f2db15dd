// Nets of known structure and known state-space size, built programmatically: oracles for the tests, workloads for
// the benchmarks (tools/bench/petri_bench.cpp) and small examples.
//
// Thread safety: all functions are re-entrant.
#pragma once

#include <cstdint>
#include <string>

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

// A task-level program (docs/task-language.md) of `robots` robots (r1..rN) in one lock-step table of `lines` lines:
// robots work in pairs (r1 with r2, r3 with r4, ...; an odd last robot alone) through a cycle of four lines: the giver
// picks its workpiece, hands it to the taker (Put/Get), the taker places it, and the giver signals a semaphore that
// the taker waits for on the same line. Every line ends in a barrier of every robot with every other, so the net has
// lines - 1 barriers of robots * (robots - 1) events each. The workload for `twin check` at scale. With repeat > 0
// the lines are the body of a loop `repeat <repeat> ... end` (the table for a shift: a cyclic net, r1 the leader
// telling every other robot again or exit, and a barrier after the body's last line too). Throws
// std::invalid_argument unless robots >= 1 and lines >= 1, and, with a loop, lines is 0 or 3 modulo 4 (the body must
// end with every hand empty, as the compiler requires).
std::string lockstep_program(int robots, int lines, std::uint32_t repeat = 0);

// A task-level program of `robots` free sequences (r1..rN, the paper's independent level) that share one region
// `zone`: robot i picks its workpiece Ai, enters the zone, places it on its fixture Fi, leaves, goes home, enters
// again, picks Ai back up, leaves and places it on its output Oi. Deadlock-free and the zone is exclusive; every
// order of entering is a real conflict, so explored markings grow about 3.5 times per robot. Throws
// std::invalid_argument unless robots >= 1.
std::string shared_region_program(int robots);

// A task-level program of `robots` "philosophers": regions Z1..ZN, robot i picks Ai, enters Zi, then Z(i mod N + 1),
// places Ai on Fi, leaves both and goes home. It can deadlock: every robot inside its own region, waiting for its
// neighbour's (N firings of each robot's first two commands). Throws std::invalid_argument unless robots >= 2.
std::string philosophers_program(int robots);

// A random net shaped like a compiled cell program, from `seed` (the same seed gives the same net on every platform):
// 1 to 4 robots, each a chain of places (kStart, kExecuting/kWaiting, kDone) with one token, some looping back to
// their start; events signalled and waited for at random (kEvent), hand-over handshakes between two robots, lock-step
// barriers among some robots, and critical regions entered and left (kRegion, capacity 1), sometimes with two free
// tokens or entered without taking one, so that exclusion can fail. Deadlocks, region violations and unbounded
// events (a loop that signals more than its partner waits) all occur among the seeds. Small enough to explore fully.
Net random_cell(std::uint64_t seed);

// A random P/T net from `seed`: 2 to 6 places with 0 to 2 tokens, 2 to 6 transitions with random arcs of weight 1 or
// 2, sometimes a region over one or two places. Bounded or not, deadlocking or not.
Net random_net(std::uint64_t seed);

}  // namespace cellwright::petri::generators
