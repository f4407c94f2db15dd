// The net generated from a compiled program: its structure, and that its behaviour is the program's.
#include "cellwright/task/to_net.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/task/compile.hpp"
#include "controller/task/task_test_helpers.hpp"

namespace cellwright::task {
namespace {

Primitive prim(PrimitiveKind kind, const std::string& arg = "", int line = 1) {
  Primitive p;
  p.kind = kind;
  if (kind == PrimitiveKind::kSignal || kind == PrimitiveKind::kWait) p.event = arg;
  if (kind == PrimitiveKind::kMove) p.target = Target{TargetKind::kAbove, arg};
  p.where = SourceLocation{"t.task", line, 3};
  p.task = "cmd on line " + std::to_string(line);
  p.motion = "motion";
  return p;
}

CompiledProgram two_robots(std::vector<Primitive> a, std::vector<Primitive> b, std::vector<Semaphore> sems) {
  CompiledProgram c;
  c.file = "t.task";
  c.robots = {"r1", "r2"};
  c.programs = {RobotProgram{"r1", std::move(a), {}}, RobotProgram{"r2", std::move(b), {}}};
  c.semaphores = std::move(sems);
  return c;
}

TEST(ToNet, ChainPerRobotWithSharedEventPlace) {
  const auto c = two_robots({prim(PrimitiveKind::kMove, "A"), prim(PrimitiveKind::kSignal, "e")},
                            {prim(PrimitiveKind::kWait, "e"), prim(PrimitiveKind::kClose)}, {{"e", 0, false, {}}});
  const petri::Net net = to_net(c);
  // Per robot: start + 2 primitive places + done; plus one event place.
  EXPECT_EQ(net.num_places(), 9u);
  // Per robot: one transition per primitive begin plus the finish.
  EXPECT_EQ(net.num_transitions(), 6u);
  EXPECT_EQ(net.robots(), (std::vector<std::string>{"r1", "r2"}));

  const auto ev = net.find_place(event_place_id("e"));
  ASSERT_TRUE(ev);
  EXPECT_EQ(net.places()[*ev].kind, petri::PlaceKind::kEvent);
  EXPECT_EQ(net.places()[*net.find_place(place_id("r2", 0))].kind, petri::PlaceKind::kWaiting);

  // r1's T1 begins the signal: it puts a token on e. r2's T1 ends the wait: it takes one.
  const auto& t_sig = net.transitions()[*net.find_transition(transition_id("r1", 1))];
  EXPECT_TRUE(std::any_of(t_sig.outputs.begin(), t_sig.outputs.end(), [&](auto& a) { return a.place == *ev; }));
  const auto& t_wait_end = net.transitions()[*net.find_transition(transition_id("r2", 1))];
  EXPECT_TRUE(std::any_of(t_wait_end.inputs.begin(), t_wait_end.inputs.end(), [&](auto& a) { return a.place == *ev; }));
  ASSERT_TRUE(t_wait_end.starts_robot);
  EXPECT_EQ(*t_wait_end.starts_robot, 1u);
  EXPECT_EQ(t_wait_end.starts_primitive, 1);
  EXPECT_EQ(t_wait_end.origin.robot, "r2");
}

TEST(ToNet, SignalledProgramRunsToTheEndAndIsNotADeadlock) {
  const auto c = two_robots({prim(PrimitiveKind::kMove, "A"), prim(PrimitiveKind::kSignal, "e")},
                            {prim(PrimitiveKind::kWait, "e"), prim(PrimitiveKind::kClose)}, {{"e", 0, false, {}}});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_TRUE(r.ok());

  // r2 cannot pass its wait before r1 has signalled: play the token game.
  petri::Marking m = net.initial_marking();
  const auto r2_end_wait = *net.find_transition(transition_id("r2", 1));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r2", 0)));
  EXPECT_FALSE(petri::is_enabled(net, m, r2_end_wait));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r1", 0)));
  petri::fire_in_place(net, m, *net.find_transition(transition_id("r1", 1)));
  EXPECT_TRUE(petri::is_enabled(net, m, r2_end_wait));
}

TEST(ToNet, CrossedWaitsDeadlockWithAShortestCounterexample) {
  // r1: wait s1, signal s2; r2: wait s2, signal s1 — each waits for the other.
  const auto c = two_robots({prim(PrimitiveKind::kWait, "s1", 4), prim(PrimitiveKind::kSignal, "s2", 5)},
                            {prim(PrimitiveKind::kWait, "s2", 8), prim(PrimitiveKind::kSignal, "s1", 9)},
                            {{"s1", 0, false, {}}, {"s2", 0, false, {}}});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_EQ(r.deadlocks, 1u);
  EXPECT_FALSE(r.ok());
  ASSERT_FALSE(r.deadlock_examples.empty());
  // Both robots begin their waits: two firings, then nothing is enabled and neither robot is done.
  const auto& d = r.deadlock_examples.front();
  EXPECT_EQ(d.path.size(), 2u);
  petri::Marking m = net.initial_marking();
  for (auto t : d.path) petri::fire_in_place(net, m, t);
  EXPECT_EQ(m, d.marking);
  EXPECT_TRUE(petri::enabled(net, m).empty());
  EXPECT_FALSE(net.is_final(m));
  EXPECT_EQ(m[*net.find_place(place_id("r1", 0))], 1u);
  EXPECT_EQ(m[*net.find_place(place_id("r2", 0))], 1u);
  // The counterexample is told in program terms: robot, line, command.
  const std::string text = petri::describe_marking(net, m);
  EXPECT_NE(text.find("r1"), std::string::npos) << text;
  EXPECT_NE(text.find("s1"), std::string::npos) << text;
}

TEST(ToNet, RegionIsAResourcePlaceAndStaysExclusive) {
  // Both robots: enter Z (wait Z), move, leave Z (signal Z).
  auto body = [] {
    return std::vector<Primitive>{prim(PrimitiveKind::kWait, "Z"), prim(PrimitiveKind::kMove, "M"),
                                  prim(PrimitiveKind::kMove, "N"), prim(PrimitiveKind::kSignal, "Z")};
  };
  auto c = two_robots(body(), body(), {{"Z", 1, true, {}}});
  c.regions = {RegionUse{"Z", {{"r1", 1, 3}, {"r2", 1, 3}}}};
  const petri::Net net = to_net(c);
  ASSERT_EQ(net.regions().size(), 1u);
  EXPECT_EQ(net.regions()[0].inside.size(), 4u);
  EXPECT_EQ(net.places()[*net.find_place(event_place_id("Z"))].kind, petri::PlaceKind::kRegion);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.ok());
  ASSERT_EQ(r.regions.size(), 1u);
  EXPECT_TRUE(r.regions[0].exclusive);
  EXPECT_EQ(r.regions[0].max_inside, 1u);

  // With two tokens in the region place the same spans are no longer exclusive, and the check says so.
  c.semaphores[0].initial = 2;
  const auto broken = petri::analyze(to_net(c));
  EXPECT_FALSE(broken.mutex_ok);
  EXPECT_EQ(broken.regions[0].max_inside, 2u);
}

TEST(ToNet, UndeclaredEventIsAnInputErrorAtTheCommand) {
  const auto c = two_robots({prim(PrimitiveKind::kSignal, "nope", 7)}, {}, {});
  try {
    (void)to_net(c);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, 7);
    EXPECT_NE(e.problem().find("nope"), std::string::npos);
  }
}

// ---- loops --------------------------------------------------------------------------------------------------------

std::string read_scene(const std::string& name) {
  std::ifstream in(std::filesystem::path(CW_SOURCE_DIR) / "scenes" / name, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

petri::Net net_of(const std::string& text) {
  return to_net(compile(parse_program(text, "t.task")));
}

const petri::Transition& transition(const petri::Net& net, const std::string& id) {
  const auto t = net.find_transition(id);
  if (!t) throw std::runtime_error("no transition " + id);
  return net.transitions()[*t];
}

petri::PlaceId place(const petri::Net& net, const std::string& id) {
  const auto p = net.find_place(id);
  if (!p) throw std::runtime_error("no place " + id);
  return *p;
}

bool has_arc(const std::vector<petri::Arc>& arcs, petri::PlaceId p) {
  return std::any_of(arcs.begin(), arcs.end(), [&](const petri::Arc& a) { return a.place == p && a.weight == 1; });
}

TEST(ToNet, LoopDecisionHasAgainAndExitTransitions) {
  // scenes/pipeline_shift.task: both robots' kLoop primitive is 28; r1's body is [14, 28), r2's [12, 28).
  const petri::Net net = net_of(read_scene("pipeline_shift.task"));
  const petri::PlaceId again_ev = place(net, event_place_id("loop15.r1>r2.again"));
  const petri::PlaceId exit_ev = place(net, event_place_id("loop15.r1>r2.exit"));
  EXPECT_EQ(net.places()[again_ev].kind, petri::PlaceKind::kEvent);

  // The leader decides at once; the follower waits for the decision.
  const petri::Place& decide = net.places()[place(net, place_id("r1", 28))];
  EXPECT_EQ(decide.kind, petri::PlaceKind::kExecuting);
  EXPECT_EQ(decide.name, "r1 deciding loop15 (repeat 9)");
  EXPECT_EQ(decide.origin.line, 15);
  const petri::Place& wait = net.places()[place(net, place_id("r2", 28))];
  EXPECT_EQ(wait.kind, petri::PlaceKind::kWaiting);
  EXPECT_EQ(wait.name, "r2 waiting for loop15 decision");

  // Leader's again: back to the body's first primitive, telling r2.
  const petri::Transition& again1 = transition(net, loop_again_transition_id("r1", 28));
  EXPECT_EQ(again1.id, "r1.again28");
  EXPECT_EQ(again1.name, "r1 repeat loop15");
  EXPECT_EQ(again1.inputs.size(), 1u);
  EXPECT_TRUE(has_arc(again1.inputs, place(net, place_id("r1", 28))));
  EXPECT_EQ(again1.outputs.size(), 2u);
  EXPECT_TRUE(has_arc(again1.outputs, place(net, place_id("r1", 14))));
  EXPECT_TRUE(has_arc(again1.outputs, again_ev));
  ASSERT_TRUE(again1.starts_robot);
  EXPECT_EQ(*again1.starts_robot, 0u);
  EXPECT_EQ(again1.starts_primitive, 14);
  EXPECT_EQ(again1.origin.robot, "r1");
  EXPECT_EQ(again1.origin.line, 15);
  EXPECT_EQ(again1.origin.task, "repeat 9");
  EXPECT_EQ(again1.origin.primitive, 28);
  // Leader's exit: the usual T29 (r1 has 29 primitives: it finishes), telling r2.
  const petri::Transition& exit1 = transition(net, transition_id("r1", 29));
  EXPECT_EQ(exit1.inputs.size(), 1u);
  EXPECT_TRUE(has_arc(exit1.outputs, place(net, done_place_id("r1"))));
  EXPECT_TRUE(has_arc(exit1.outputs, exit_ev));
  EXPECT_EQ(exit1.outputs.size(), 2u);

  // Follower's again and exit each take the leader's event.
  const petri::Transition& again2 = transition(net, loop_again_transition_id("r2", 28));
  EXPECT_EQ(again2.inputs.size(), 2u);
  EXPECT_TRUE(has_arc(again2.inputs, place(net, place_id("r2", 28))));
  EXPECT_TRUE(has_arc(again2.inputs, again_ev));
  EXPECT_EQ(again2.outputs.size(), 1u);
  EXPECT_TRUE(has_arc(again2.outputs, place(net, place_id("r2", 12))));
  EXPECT_EQ(again2.starts_primitive, 12);
  const petri::Transition& exit2 = transition(net, transition_id("r2", 29));
  EXPECT_EQ(exit2.inputs.size(), 2u);
  EXPECT_TRUE(has_arc(exit2.inputs, exit_ev));
  EXPECT_TRUE(has_arc(exit2.outputs, place(net, place_id("r2", 29))));
  EXPECT_EQ(exit2.starts_primitive, 29);

  // Token game: once r1 has chosen again, r2 can only go again too.
  petri::Marking m = net.initial_marking();
  m[place(net, start_place_id("r1"))] = 0;
  m[place(net, start_place_id("r2"))] = 0;
  m[place(net, place_id("r1", 28))] = 1;
  m[place(net, place_id("r2", 28))] = 1;
  const auto again2_id = *net.find_transition(loop_again_transition_id("r2", 28));
  const auto exit2_id = *net.find_transition(transition_id("r2", 29));
  EXPECT_FALSE(petri::is_enabled(net, m, again2_id));
  EXPECT_FALSE(petri::is_enabled(net, m, exit2_id));
  EXPECT_TRUE(petri::is_enabled(net, m, *net.find_transition(loop_again_transition_id("r1", 28))));
  EXPECT_TRUE(petri::is_enabled(net, m, *net.find_transition(transition_id("r1", 29))));
  petri::fire_in_place(net, m, *net.find_transition(loop_again_transition_id("r1", 28)));
  EXPECT_TRUE(petri::is_enabled(net, m, again2_id));
  EXPECT_FALSE(petri::is_enabled(net, m, exit2_id));
}

TEST(ToNet, AgainBeginsASignalAtTheBodysStartAsTbDoes) {
  // A sequence loop: r1 leads itself, no followers, no decision events; its body starts with a signal.
  const petri::Net net = net_of("robot r1 r2\nsemaphore s\nsequence r1\nrepeat 3\nsignal s\nend\nend\n"
                                "sequence r2\nrepeat 3\nwait s\nend\nend\n");
  const petri::Transition& again = transition(net, loop_again_transition_id("r1", 1));
  EXPECT_EQ(again.inputs.size(), 1u);
  EXPECT_EQ(again.outputs.size(), 2u);
  EXPECT_TRUE(has_arc(again.outputs, place(net, place_id("r1", 0))));
  EXPECT_TRUE(has_arc(again.outputs, place(net, event_place_id("s"))));
  const petri::Transition& exit = transition(net, transition_id("r1", 2));
  EXPECT_EQ(exit.inputs.size(), 1u);
  EXPECT_EQ(exit.outputs.size(), 1u);  // just done
  EXPECT_EQ(net.places()[place(net, place_id("r1", 1))].name, "r1 deciding loop4 (repeat 3)");
}

TEST(ToNet, ShiftProgramHasNoDeadlockAndItsCheckCostsTheSameForAnyCount) {
  const std::string text = read_scene("pipeline_shift.task");
  const auto r = petri::analyze(net_of(text));
  EXPECT_TRUE(r.complete) << r.stop_reason;
  EXPECT_TRUE(r.bounded);
  EXPECT_EQ(r.deadlocks, 0u);
  EXPECT_EQ(r.final_states, 1u);  // every robot done, after the exit
  EXPECT_TRUE(r.ok());
  // The count is not in the net: repeat 3 and repeat 3000 give the same reachability graph.
  const auto with_count = [&](const std::string& n) {
    std::string t = text;
    const auto at = t.find("repeat 9");
    t.replace(at, 8, "repeat " + n);
    return t;
  };
  const auto three = petri::analyze(net_of(with_count("3")));
  const auto many = petri::analyze(net_of(with_count("3000")));
  EXPECT_TRUE(three.ok());
  EXPECT_EQ(three.states, r.states);
  EXPECT_EQ(many.states, three.states);
  EXPECT_EQ(many.edges, three.edges);
}

TEST(ToNet, LoopWaitingForASignalGivenOnlyBeforeItDeadlocks) {
  // r2 signals s once, before the loop; r1 waits for s in every iteration: the second iteration never gets it.
  const std::string text =
      "robot r1 r2\nsemaphore s\nsteps\nr1 | r2\n| signal s\nrepeat 3\nwait s |\nend\nend\n";
  const petri::Net net = net_of(text);
  const auto r = petri::analyze(net);
  EXPECT_TRUE(r.complete);
  EXPECT_GE(r.deadlocks, 1u);
  EXPECT_FALSE(r.ok());
  ASSERT_FALSE(r.deadlock_examples.empty());
  // The deadlock: r1 waits for s again while r2 waits at the barrier of the repeated line.
  petri::Marking m = net.initial_marking();
  for (auto t : r.deadlock_examples.front().path) petri::fire_in_place(net, m, t);
  EXPECT_TRUE(petri::enabled(net, m).empty());
  EXPECT_FALSE(net.is_final(m));
  EXPECT_EQ(m[place(net, place_id("r1", 2))], 1u) << petri::describe_marking(net, m);  // wait s
  // The path goes round the loop: r1's again is in it.
  const auto again = *net.find_transition(loop_again_transition_id("r1", 5));
  const auto& path = r.deadlock_examples.front().path;
  EXPECT_NE(std::find(path.begin(), path.end(), again), path.end());
  // With the signal inside the loop the same program is fine.
  const auto fixed = petri::analyze(net_of("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nrepeat 3\n| signal s\n"
                                           "wait s |\nend\nend\n"));
  EXPECT_TRUE(fixed.ok());
}

TEST(ToNet, SequenceLoopsDecideIndependentlySoTheCheckSeesOneStopEarly) {
  // Two sequences whose loops take turns through s and t. Each robot decides its own loop, and the net leaves the
  // count out, so it also holds the run in which r1 stops after one iteration while r2 goes on and waits for s: the
  // check reports that deadlock (docs/task-language.md, "Loops"). The same work in the table has one leader: fine.
  const auto seqs = petri::analyze(net_of("robot r1 r2\nsemaphore s t\nsequence r1\nrepeat 3\nsignal s\nwait t\nend\n"
                                          "end\nsequence r2\nrepeat 3\nwait s\nsignal t\nend\nend\n"));
  EXPECT_TRUE(seqs.complete);
  EXPECT_GE(seqs.deadlocks, 1u);
  const auto table = petri::analyze(net_of("robot r1 r2\nsemaphore s t\nsteps\nr1 | r2\nrepeat 3\nsignal s | wait s\n"
                                           "wait t | signal t\nend\nend\n"));
  EXPECT_TRUE(table.ok());
}

TEST(ToNet, CooperatingSequencesWithOneDecisionPassTheCheckForAnyCount) {
  // The stand relay: two looping sequences that meet only at the stand. With one decision (`with`) the check
  // accepts them, and the count is not in the net.
  const auto shared = petri::analyze(net_of(test::stand_relay("repeat 10 with r2", "repeat 10 with r1")));
  EXPECT_TRUE(shared.complete) << shared.stop_reason;
  EXPECT_TRUE(shared.bounded);
  EXPECT_EQ(shared.deadlocks, 0u);
  EXPECT_TRUE(shared.ok());
  const auto more = petri::analyze(net_of(test::stand_relay("repeat 3000 with r2", "repeat 3000 with r1")));
  EXPECT_EQ(more.states, shared.states);
  // Each loop deciding alone: refused, with a counterexample in which r1 has left its loop while r2 waits for a part
  // that never comes.
  const petri::Net alone = net_of(test::stand_relay("repeat 10", "repeat 10"));
  const auto refused = petri::analyze(alone);
  EXPECT_FALSE(refused.ok());
  ASSERT_FALSE(refused.deadlock_examples.empty());
  petri::Marking m = alone.initial_marking();
  for (auto t : refused.deadlock_examples.front().path) petri::fire_in_place(alone, m, t);
  EXPECT_TRUE(petri::enabled(alone, m).empty());
  EXPECT_FALSE(alone.is_final(m));
  EXPECT_EQ(m[place(alone, done_place_id("r1"))], 1u) << petri::describe_marking(alone, m);
}

TEST(ToNet, APacedLeaderDecidesOnlyOnceItsFollowerHasTakenTheLastDecision) {
  const CompiledProgram c = compile(parse_program(test::stand_relay("repeat 2 with r2", "repeat 2 with r1"), "t"));
  const petri::Net net = to_net(c);
  const Loop& lead = c.programs[0].loops[0];
  const Loop& follow = c.programs[1].loops[0];
  const auto taken = place(net, event_place_id("loop8.r2>r1.taken"));
  EXPECT_EQ(net.initial_marking()[taken], 1u);
  const auto has = [](const std::vector<petri::Arc>& arcs, petri::PlaceId p) {
    return std::any_of(arcs.begin(), arcs.end(), [&](const petri::Arc& a) { return a.place == p; });
  };
  // The leader's again and exit each take the acknowledgement; the follower's give it back.
  EXPECT_TRUE(has(transition(net, loop_again_transition_id("r1", lead.end)).inputs, taken));
  EXPECT_TRUE(has(transition(net, transition_id("r1", lead.end + 1)).inputs, taken));
  EXPECT_TRUE(has(transition(net, loop_again_transition_id("r2", follow.end)).outputs, taken));
  EXPECT_TRUE(has(transition(net, transition_id("r2", follow.end + 1)).outputs, taken));
  // So the follower never finds again and exit signalled at once: every event place of the decision is 1-bounded.
  const auto r = petri::analyze(net);
  ASSERT_TRUE(r.complete);
  for (const char* e : {"loop8.r1>r2.again", "loop8.r1>r2.exit", "loop8.r2>r1.taken"}) {
    EXPECT_EQ(r.place_bounds[place(net, event_place_id(e))], 1u) << e;
  }
}

TEST(ToNet, EmptyProgramGoesStraightToDone) {
  const auto c = two_robots({}, {}, {});
  const petri::Net net = to_net(c);
  const auto r = petri::analyze(net);
  EXPECT_EQ(r.states, 4u);  // each robot independently: ready or done
  EXPECT_EQ(r.final_states, 1u);
  EXPECT_TRUE(r.ok());
}

}  // namespace
}  // namespace cellwright::task
