// The timed-net simulation behind the cycle-time estimate, on hand-made nets whose earliest finish is known.
#include "cellwright/cell/timed_net.hpp"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <map>
#include <string>

#include "cellwright/task/compile.hpp"
#include "cellwright/task/program.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::cell {
namespace {

using petri::Arc;
using petri::NetBuilder;
using petri::PlaceId;

// Builds nets out of robot chains (start -> command places -> done) and shared event places, and keeps each place's
// duration.
class TimedNetBuilder {
 public:
  TimedNetBuilder() : b_("timed") {}

  PlaceId place(const std::string& id, double duration, petri::Tokens initial = 0) {
    petri::Place p;
    p.id = id;
    p.name = id;
    p.initial = initial;
    const PlaceId pid = b_.add_place(std::move(p));
    durations_.push_back(duration);
    ids_[id] = pid;
    return pid;
  }
  petri::TransitionId transition(const std::string& id, std::vector<PlaceId> in, std::vector<PlaceId> out) {
    petri::Transition t;
    t.id = id;
    t.name = id;
    for (PlaceId p : in) t.inputs.push_back({p, 1});
    for (PlaceId p : out) t.outputs.push_back({p, 1});
    return b_.add_transition(std::move(t));
  }
  // A robot doing commands of the given durations one after the other: start -> c0 -> c1 ... -> done. Returns the
  // transition ids t0..tn (t_k starts command k; t_n ends the last one).
  std::vector<petri::TransitionId> chain(const std::string& robot, const std::vector<double>& durations) {
    std::vector<petri::TransitionId> ts;
    PlaceId prev = place(robot + ".start", 0, 1);
    for (std::size_t k = 0; k < durations.size(); ++k) {
      const PlaceId p = place(fmt::format("{}.c{}", robot, k), durations[k]);
      ts.push_back(transition(fmt::format("{}.t{}", robot, k), {prev}, {p}));
      prev = p;
    }
    const PlaceId done = place(robot + ".done", 0);
    ts.push_back(transition(fmt::format("{}.t{}", robot, durations.size()), {prev}, {done}));
    final_.push_back({done, 1});
    return ts;
  }
  NetBuilder& builder() { return b_; }
  PlaceId id(const std::string& name) const { return ids_.at(name); }
  const std::vector<double>& durations() const { return durations_; }
  petri::Net build() && {
    b_.set_final(final_);
    return std::move(b_).build();
  }

 private:
  NetBuilder b_;
  std::vector<double> durations_;
  std::map<std::string, PlaceId> ids_;
  std::vector<Arc> final_;
};

TEST(TimedNet, SequenceTakesTheSumOfItsCommands) {
  TimedNetBuilder b;
  b.chain("r1", {2.0, 3.5, 0.25});
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_TRUE(run.finished);
  EXPECT_DOUBLE_EQ(run.finish, 5.75);
  ASSERT_EQ(run.firings.size(), 4u);
  EXPECT_DOUBLE_EQ(run.firings[0].time, 0.0);
  EXPECT_DOUBLE_EQ(run.firings[1].time, 2.0);
  EXPECT_DOUBLE_EQ(run.firings[2].time, 5.5);
}

TEST(TimedNet, ParallelRobotsTakeTheLongestOfThem) {
  TimedNetBuilder b;
  b.chain("r1", {1.0, 3.0});
  b.chain("r2", {2.0, 2.0, 3.0});
  b.chain("r3", {0.5});
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_TRUE(run.finished);
  EXPECT_DOUBLE_EQ(run.finish, 7.0);
  // Firing times never decrease.
  for (std::size_t i = 1; i < run.firings.size(); ++i) EXPECT_LE(run.firings[i - 1].time, run.firings[i].time);
}

// A hand-over: the giver moves (a s) and signals "ready"; the taker moves (b s), waits for "ready", then takes the
// part and goes on (c s). The taker ends at max(a, b) + c whichever arrives first.
double handover_finish(double giver_move, double taker_move, double rest) {
  TimedNetBuilder b;
  const PlaceId ready = b.place("ev.ready", 0);
  // Giver: move, then its signal place (instant), then done.
  const auto g = b.chain("r1", {giver_move, 0.0});
  b.builder().transition(g[1]).outputs.push_back({ready, 1});  // t1 starts "signal ready"
  // Taker: move, wait (instant place), then the rest; the transition leaving the wait takes the signal.
  const auto t = b.chain("r2", {taker_move, 0.0, rest});
  b.builder().transition(t[2]).inputs.push_back({ready, 1});
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_TRUE(run.finished);
  return run.finish;
}

TEST(TimedNet, HandoverWaitsForTheLaterArrivalThenDoesTheRest) {
  EXPECT_DOUBLE_EQ(handover_finish(3.0, 5.0, 2.0), 7.0);  // the taker arrives last
  EXPECT_DOUBLE_EQ(handover_finish(6.0, 5.0, 2.0), 8.0);  // the giver arrives last
  EXPECT_DOUBLE_EQ(handover_finish(4.0, 4.0, 1.5), 5.5);  // together
}

TEST(TimedNet, SemaphoreServesTheRobotReadyFirstAndTheOtherWaits) {
  // Two robots, each: approach (r1 1 s, r2 2 s), enter region Z, work inside 3 s, leave, then 0.5 s outside.
  TimedNetBuilder b;
  const PlaceId z = b.place("ev.Z", 0, 1);
  for (const auto& [robot, approach] : {std::pair<std::string, double>{"r1", 1.0}, {"r2", 2.0}}) {
    const auto t = b.chain(robot, {approach, 3.0, 0.5});
    b.builder().transition(t[1]).inputs.push_back({z, 1});   // entering takes Z
    b.builder().transition(t[2]).outputs.push_back({z, 1});  // leaving gives it back
  }
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_TRUE(run.finished);
  // r1 inside 1..4, r2 waits until 4, inside 4..7, then 0.5 s outside.
  EXPECT_DOUBLE_EQ(run.finish, 7.5);
}

TEST(TimedNet, DeadlockEndsUnfinishedWhereItStuck) {
  TimedNetBuilder b;
  const PlaceId s1 = b.place("ev.s1", 0);
  const PlaceId s2 = b.place("ev.s2", 0);
  const auto r1 = b.chain("r1", {1.0, 0.0});  // waits for s1, then signals s2
  const auto r2 = b.chain("r2", {2.0, 0.0});  // waits for s2, then signals s1
  b.builder().transition(r1[2]).inputs.push_back({s1, 1});
  b.builder().transition(r1[2]).outputs.push_back({s2, 1});
  b.builder().transition(r2[2]).inputs.push_back({s2, 1});
  b.builder().transition(r2[2]).outputs.push_back({s1, 1});
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_FALSE(run.finished);
  EXPECT_DOUBLE_EQ(run.finish, 2.0);  // the last thing that happened: r2 reached its wait
  EXPECT_EQ(run.firings.size(), 4u);
}

TEST(TimedNet, UnboundedNetStopsAtTheFiringLimit) {
  TimedNetBuilder b;
  const PlaceId loop = b.place("loop", 1.0, 1);
  const PlaceId pile = b.place("pile", 0);
  b.transition("grow", {loop}, {loop, pile});
  const auto durations = b.durations();
  const petri::Net net = std::move(b).build();
  const TimedRun run = simulate_timed(net, durations, 10);
  EXPECT_FALSE(run.finished);
  EXPECT_EQ(run.firings.size(), 10u);
  EXPECT_DOUBLE_EQ(run.finish, 10.0);
  EXPECT_EQ(run.final_marking[pile], 10u);
}

TEST(TimedNet, PaperExchangeProgramWithUnitCommandsHasTheHandComputedCycle) {
  // Table 1 of the paper, compiled; every move/open/close takes 1 s, signals and waits nothing. The critical path
  // (docs/task-language.md's listing): r1 picks (5 commands: 0..5), r2 opens and approaches (5..7), grasps at the
  // hand (7..9), r1 opens (9..10), r2 departs (10..11) and places (11..15).
  const task::CompiledProgram prog = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/exchange.task");
  const petri::Net net = task::to_net(prog);
  std::vector<double> durations(net.num_places(), 0.0);
  for (std::size_t r = 0; r < prog.programs.size(); ++r) {
    const auto& prims = prog.programs[r].primitives;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      const bool command = prims[k].kind == task::PrimitiveKind::kMove || prims[k].kind == task::PrimitiveKind::kOpen ||
                           prims[k].kind == task::PrimitiveKind::kClose;
      durations[*net.find_place(task::place_id(prog.robots[r], k))] = command ? 1.0 : 0.0;
    }
  }
  const TimedRun run = simulate_timed(net, durations);
  EXPECT_TRUE(run.finished);
  EXPECT_DOUBLE_EQ(run.finish, 15.0);
}

TEST(TimedNet, WrongDurationVectorIsABug) {
  TimedNetBuilder b;
  b.chain("r1", {1.0});
  const petri::Net net = std::move(b).build();
  EXPECT_THROW(simulate_timed(net, {0.0}), InternalError);
  EXPECT_THROW(simulate_timed(net, {0.0, -1.0, 0.0}), InternalError);
}

}  // namespace
}  // namespace cellwright::cell
