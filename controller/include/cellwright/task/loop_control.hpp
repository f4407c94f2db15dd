// LoopControl: the iteration counts of a program's loops (`repeat N ... end`, compiled.hpp `Loop`) when its net is
// executed.
//
// The Petri net of a program leaves every loop's decision free: the leader's kLoop place has two outgoing
// transitions, "again" (back to the body's first primitive) and "exit" (on after the loop), and both are enabled
// whenever the place is marked, so the net's analysis holds for any number of iterations. Whoever executes the net
// (task control at run time, the estimate and the preflight that replay it) asks LoopControl which of the two may
// fire: again while fewer than `count` iterations have ended, exit at the `count`-th. Followers need no counting:
// their kLoop transitions wait for the leader's again/exit events.
//
// Usage, once per firing round:
//
//    std::vector<bool> allowed = ...;           // the caller's own mask (all true if none)
//    loops.restrict(allowed);                   // rules out the decision the counts forbid
//    auto chosen = petri::choose(net, m, arbiter, allowed);
//    petri::fire_chosen(net, m, arbiter, chosen);
//    for (auto t : chosen) loops.fired(t);      // counts the iterations
//
// Thread safety: a plain value; one thread at a time.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cellwright/petri/net.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::task {

class LoopControl {
 public:
  // `net` must be to_net(program): InternalError if a leader's again/exit transition is missing.
  LoopControl(const petri::Net& net, const CompiledProgram& program);

  // Clears allowed[t] for each leader's again transition once its loop has run `count` iterations, and for each exit
  // transition before that. `allowed` is empty (meaning all allowed: it is filled with true first) or has one entry
  // per transition.
  void restrict(std::vector<bool>& allowed) const;

  // Records that transition `t` fired: an again ends an iteration, an exit ends the loop (its count starts again from
  // zero, should the loop be entered anew). Other transitions are ignored.
  void fired(petri::TransitionId t);

  // Iterations ended so far of the loop whose leader is robot `robot` (program order) and whose index in that
  // robot's RobotProgram::loops is `loop`: the agains fired since the loop was last entered.
  std::uint32_t iterations(std::size_t robot, std::size_t loop) const;

  // Whether the program has any loop (then restrict() and fired() matter).
  bool any() const { return !decisions_.empty(); }

 private:
  struct Decision {
    std::size_t robot = 0;
    std::size_t loop = 0;
    petri::TransitionId again = 0;
    petri::TransitionId exit = 0;
    std::uint32_t count = 1;
    std::uint32_t agains = 0;  // iterations ended since the loop was entered
  };
  std::vector<Decision> decisions_;
  std::vector<int> by_transition_;  // per transition: index into decisions_, or -1
};

}  // namespace cellwright::task
