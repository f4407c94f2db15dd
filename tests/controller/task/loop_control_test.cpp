// LoopControl: the loops of a program run as many times as their `repeat` says when the net is executed, though the
// net itself lets the leader choose freely.
#include "cellwright/task/loop_control.hpp"

#include <gtest/gtest.h>

#include <string>

#include "cellwright/petri/firing.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "controller/task/task_test_helpers.hpp"

namespace cellwright::task {
namespace {

// Fires the net to its end as task control does (restrict, choose, fire, count) and returns how often each robot
// began the primitive at `index` (robot label -> count), and whether it ended in the final marking.
struct Played {
  std::map<std::string, int> began;
  bool final = false;
  int firings = 0;
};

Played play(const CompiledProgram& c, const petri::Net& net, std::size_t index) {
  LoopControl loops(net, c);
  petri::Marking m = net.initial_marking();
  petri::Arbiter arbiter = petri::make_arbiter(net);
  Played out;
  while (out.firings < 100000) {
    std::vector<bool> allowed;
    loops.restrict(allowed);
    const auto chosen = petri::choose(net, m, arbiter, allowed);
    if (chosen.empty()) break;
    petri::fire_chosen(net, m, arbiter, chosen);
    for (const petri::TransitionId t : chosen) {
      loops.fired(t);
      ++out.firings;
      const petri::Transition& tr = net.transitions()[t];
      if (tr.starts_robot && static_cast<std::size_t>(tr.starts_primitive) == index) {
        ++out.began[c.robots[*tr.starts_robot]];
      }
    }
  }
  out.final = net.is_final(m);
  return out;
}

const char* const kTable = R"(robot r1 r2
workpiece part from IN
location IN OUT
steps
  r1        | r2
  Pick part |
  Put r2    | Get r1
repeat COUNT
  Pick part | Place OUT
  Put r2    | Get r1
end
            | Place OUT
end
)";

std::string with_count(const char* text, int count) {
  std::string s = text;
  s.replace(s.find("COUNT"), 5, std::to_string(count));
  return s;
}

TEST(LoopControl, TableLoopRunsItsCountForLeaderAndFollower) {
  for (const int count : {1, 2, 7}) {
    const CompiledProgram c = compile(parse_program(with_count(kTable, count), "shift.task"));
    const petri::Net net = to_net(c);
    ASSERT_EQ(c.programs[0].loops.size(), 1u);
    // The body's first primitive of each robot: begun once per iteration.
    const std::size_t r1_body = c.programs[0].loops[0].begin;
    const std::size_t r2_body = c.programs[1].loops[0].begin;
    const Played p1 = play(c, net, r1_body);
    const Played p2 = play(c, net, r2_body);
    EXPECT_TRUE(p1.final) << "count " << count;
    EXPECT_EQ(p1.began.at("r1"), count) << "count " << count;
    EXPECT_EQ(p2.began.at("r2"), count) << "count " << count;
  }
}

TEST(LoopControl, IterationsCountUpAndStartAgainAfterTheExit) {
  const CompiledProgram c = compile(parse_program(with_count(kTable, 3), "shift.task"));
  const petri::Net net = to_net(c);
  LoopControl loops(net, c);
  ASSERT_TRUE(loops.any());
  const Loop& loop = c.programs[0].loops[0];
  const petri::TransitionId again = *net.find_transition(loop_again_transition_id("r1", loop.end));
  const petri::TransitionId exit = *net.find_transition(transition_id("r1", loop.end + 1));
  auto allowed = [&] {
    std::vector<bool> a;
    loops.restrict(a);
    return std::make_pair(static_cast<bool>(a[again]), static_cast<bool>(a[exit]));
  };
  EXPECT_EQ(allowed(), std::make_pair(true, false));
  loops.fired(again);
  EXPECT_EQ(loops.iterations(0, 0), 1u);
  EXPECT_EQ(allowed(), std::make_pair(true, false));
  loops.fired(again);
  EXPECT_EQ(allowed(), std::make_pair(false, true));  // the third iteration is ending: exit only
  loops.fired(exit);
  EXPECT_EQ(loops.iterations(0, 0), 0u);
  EXPECT_EQ(allowed(), std::make_pair(true, false));
  // Followers have no decision of their own: their again/exit are left to the leader's events.
  const Loop& follows = c.programs[1].loops[0];
  const petri::TransitionId f_again = *net.find_transition(loop_again_transition_id("r2", follows.end));
  std::vector<bool> a;
  loops.restrict(a);
  EXPECT_TRUE(a[f_again]);
}

TEST(LoopControl, CooperatingSequencesRunTheLeadersCountInLockStep) {
  // The stand relay played as task control plays it: both sequences run the body `count` times, every part put on
  // the stand is taken from it, and the run ends in the final marking.
  for (const int count : {1, 3, 8}) {
    const std::string n = std::to_string(count);
    const CompiledProgram c = compile(parse_program(test::stand_relay("repeat " + n + " with r2", "repeat " + n + " with r1"),
                                                    "relay.task"));
    const petri::Net net = to_net(c);
    const Played p1 = play(c, net, c.programs[0].loops[0].begin);
    const Played p2 = play(c, net, c.programs[1].loops[0].begin);
    EXPECT_TRUE(p1.final) << "count " << count;
    EXPECT_EQ(p1.began.at("r1"), count) << "count " << count;
    EXPECT_EQ(p2.began.at("r2"), count) << "count " << count;
  }
}

TEST(LoopControl, SequenceLoopAndAProgramWithoutLoops) {
  const CompiledProgram c = compile(parse_program(R"(robot r1
workpiece part from IN
location IN OUT
sequence r1
repeat 4
  Pick part
  Place OUT
end
end
)",
                                                  "seq.task"));
  const petri::Net net = to_net(c);
  const Played p = play(c, net, c.programs[0].loops[0].begin);
  EXPECT_TRUE(p.final);
  EXPECT_EQ(p.began.at("r1"), 4);

  const CompiledProgram plain = compile(parse_program("robot r1\nworkpiece A\nlocation B\nsequence r1\n"
                                                      "  Pick A\n  Place B\nend\n",
                                                      "plain.task"));
  const petri::Net plain_net = to_net(plain);
  LoopControl none(plain_net, plain);
  EXPECT_FALSE(none.any());
  std::vector<bool> a;
  none.restrict(a);
  EXPECT_EQ(a, std::vector<bool>(plain_net.num_transitions(), true));
  EXPECT_TRUE(play(plain, plain_net, 0).final);
}

}  // namespace
}  // namespace cellwright::task
