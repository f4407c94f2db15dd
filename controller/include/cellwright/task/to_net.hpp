// From a compiled task program to the Petri net that the task-control thread executes (paper section 2, Fig. 1).
//
// Per robot with primitives p0..p(n-1) the net has a chain of places and transitions:
//
//   start --T0--> P0 --T1--> P1 ... P(n-1) --Tn--> done
//
// Place Pk means "robot executing primitive k" (kExecuting), or, for a wait, "robot waiting for the event"
// (kWaiting). Transition Tk is the end of primitive k-1 and the begin of primitive k: firing it sends primitive k to
// the robot (Transition::starts_robot/starts_primitive). Synchronisation is by shared places:
//  - `signal e` as primitive k: Tk also puts a token on the event place of e (the signal is instant);
//  - `wait e` as primitive k: the robot waits in Pk; T(k+1) also takes a token from e, so it fires only once e has
//    been signalled;
//  - a critical region Z is a place with one token (free); entering is a wait on it, leaving a signal, and the places
//    in between are Region::inside, so mutual exclusion can be checked on the reachability graph.
// A loop (`repeat N ... end`, compiled.hpp `Loop`) with body [b, k) and its kLoop primitive k makes the chain a
// cycle. Pk is the decision: the leader's is a kExecuting place that takes no time ("r1 deciding loop7 (repeat 9)"),
// a follower's a kWaiting place ("r2 waiting for loop7 decision"). Two transitions leave it:
//  - exit, the usual T(k+1): the leader's also puts a token on each follower's `loopL.LEADER>F.exit` event; a
//    follower's also takes a token from its own;
//  - again (loop_again_transition_id): back to Pb, beginning primitive b as Tb does (and signalling its event if it
//    is a signal); the leader's also puts a token on each follower's `loopL.LEADER>F.again` event, a follower's takes
//    one from its own.
// The iteration count is not in the net: both of the leader's transitions are enabled together, so an analysis holds
// for any count and costs the same for 3 iterations or 3,000; whoever executes the net chooses by the count
// (task/loop_control.hpp).
// A coordinated block (compiled.hpp CoordinatedUse) needs nothing of its own: the barrier pair before each of its
// segments (and after the last) is a signal and a wait on inserted events, so neither robot begins a segment or leaves
// the block without the other, and a block only one robot reaches is a dead marking the analysis reports.
// One token per robot; the final marking has every robot in its done place.
#pragma once

#include "cellwright/petri/net.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::task {

petri::Net to_net(const CompiledProgram& program);

// Ids of the places and transitions, so that runtime code and tests can find them without string building.
std::string place_id(const std::string& robot, std::size_t primitive);
std::string transition_id(const std::string& robot, std::size_t primitive);
// The "again" transition of the loop whose kLoop primitive is `primitive` (its "exit" is transition_id(robot,
// primitive + 1)).
std::string loop_again_transition_id(const std::string& robot, std::size_t primitive);
std::string start_place_id(const std::string& robot);
std::string done_place_id(const std::string& robot);
std::string event_place_id(const std::string& event);

}  // namespace cellwright::task
