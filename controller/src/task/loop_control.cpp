#include "cellwright/task/loop_control.hpp"

#include "cellwright/common/error.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::task {

LoopControl::LoopControl(const petri::Net& net, const CompiledProgram& program)
    : by_transition_(net.transitions().size(), -1) {
  for (std::size_t r = 0; r < program.programs.size(); ++r) {
    const RobotProgram& rp = program.programs[r];
    for (std::size_t l = 0; l < rp.loops.size(); ++l) {
      const Loop& loop = rp.loops[l];
      if (loop.leader != rp.robot) continue;  // a follower's choice is made by its events
      const auto again = net.find_transition(loop_again_transition_id(rp.robot, loop.end));
      const auto exit = net.find_transition(transition_id(rp.robot, loop.end + 1));
      CW_CHECK(again && exit, "robot {} loop {}: no again/exit transition at primitive {} in net {}", rp.robot,
               loop.name, loop.end, net.name());
      CW_CHECK(loop.count >= 1, "robot {} loop {} has count 0", rp.robot, loop.name);
      by_transition_[*again] = static_cast<int>(decisions_.size());
      by_transition_[*exit] = static_cast<int>(decisions_.size());
      decisions_.push_back({r, l, *again, *exit, loop.count, 0});
    }
  }
}

void LoopControl::restrict(std::vector<bool>& allowed) const {
  if (allowed.empty()) allowed.assign(by_transition_.size(), true);
  CW_CHECK(allowed.size() == by_transition_.size(), "allowed mask of {} for {} transitions", allowed.size(),
           by_transition_.size());
  for (const Decision& d : decisions_) {
    const bool last = d.agains + 1 >= d.count;  // the iteration now ending is the count-th
    if (last) {
      allowed[d.again] = false;
    } else {
      allowed[d.exit] = false;
    }
  }
}

void LoopControl::fired(petri::TransitionId t) {
  if (t >= by_transition_.size() || by_transition_[t] < 0) return;
  Decision& d = decisions_[static_cast<std::size_t>(by_transition_[t])];
  if (t == d.again) {
    ++d.agains;
  } else {
    d.agains = 0;
  }
}

std::uint32_t LoopControl::iterations(std::size_t robot, std::size_t loop) const {
  for (const Decision& d : decisions_) {
    if (d.robot == robot && d.loop == loop) return d.agains;
  }
  return 0;
}

}  // namespace cellwright::task
