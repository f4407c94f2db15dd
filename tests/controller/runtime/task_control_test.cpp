// TaskControl on its own, driven turn by turn from the test (no threads): what it sends, when, and how it ends.
#include "cellwright/runtime/task_control.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::milliseconds;
using ::testing::HasSubstr;

struct Harness {
  explicit Harness(const std::string& program)
      : compiled(task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/" + program)),
        net(task::to_net(compiled)),
        statuses(16) {
    std::vector<MessageQueue<MotionCommand>*> ptrs;
    for (std::size_t r = 0; r < compiled.robots.size(); ++r) {
      inboxes.push_back(std::make_unique<MessageQueue<MotionCommand>>(4));
      ptrs.push_back(inboxes.back().get());
    }
    tc = std::make_unique<TaskControl>(net, compiled, ptrs, statuses, log);
  }

  // Commands waiting in each robot's inbox, popped.
  std::vector<std::optional<MotionCommand>> take() {
    std::vector<std::optional<MotionCommand>> out;
    for (auto& q : inboxes) {
      MotionCommand c;
      out.push_back(q->try_pop(c) == QueueStatus::ok ? std::optional(c) : std::nullopt);
    }
    return out;
  }

  void done(const MotionCommand& c) {
    ASSERT_EQ(statuses.try_push(RobotStatus{c.robot, c.index, CommandOutcome::kDone, "", {}}), QueueStatus::ok);
  }

  task::CompiledProgram compiled;
  petri::Net net;
  EventLog log;
  MessageQueue<RobotStatus> statuses;
  std::vector<std::unique_ptr<MessageQueue<MotionCommand>>> inboxes;
  std::unique_ptr<TaskControl> tc;
};

// Runs the program with robots that finish every command one turn after it was sent, in robot order; returns the
// (robot, primitive) sequence of commands sent.
std::vector<std::pair<std::size_t, std::size_t>> run_to_end(Harness& h, int max_turns = 1000) {
  std::vector<std::pair<std::size_t, std::size_t>> sent;
  std::vector<std::optional<MotionCommand>> pending(h.compiled.robots.size());
  for (int turn = 1; turn <= max_turns && h.tc->state() == TaskControl::State::kRunning; ++turn) {
    h.tc->step(milliseconds(10 * turn));
    for (auto& p : pending) {
      if (p) h.done(*p);
      p.reset();
    }
    auto got = h.take();
    for (std::size_t r = 0; r < got.size(); ++r) {
      if (!got[r]) continue;
      sent.emplace_back(r, got[r]->index);
      pending[r] = got[r];
    }
  }
  return sent;
}

TEST(RuntimeTaskControl, FirstTurnStartsEachRobotsFirstCommandAndRunsNetOnlyPrimitivesAtOnce) {
  Harness h("exchange.task");
  ASSERT_EQ(h.tc->step(milliseconds(10)), TaskControl::State::kRunning);
  auto got = h.take();
  // r1 begins with `open`; r2 begins with its barrier (signal step1.r2>r1, then wait): it sends nothing and waits.
  ASSERT_TRUE(got[0].has_value());
  EXPECT_EQ(got[0]->index, 0u);
  EXPECT_EQ(got[0]->primitive.kind, task::PrimitiveKind::kOpen);
  EXPECT_FALSE(got[1].has_value());
  const TaskView v = h.tc->view();
  EXPECT_EQ(v.robots[0].activity, RobotActivity::kBusy);
  EXPECT_EQ(v.robots[1].activity, RobotActivity::kWaiting);
  EXPECT_EQ(v.robots[1].command, "wait step1.r1>r2");
  EXPECT_THAT(v.last_fired, ::testing::ElementsAre("r1.t0", "r2.t0", "r2.t1"));
}

TEST(RuntimeTaskControl, NothingMoreIsSentUntilTheRobotReportsDone) {
  Harness h("exchange.task");
  h.tc->step(milliseconds(10));
  auto first = h.take();
  for (int i = 2; i < 6; ++i) {
    h.tc->step(milliseconds(10 * i));
    auto got = h.take();
    EXPECT_FALSE(got[0].has_value()) << "turn " << i;
  }
  h.done(*first[0]);
  h.tc->step(milliseconds(60));
  auto got = h.take();
  ASSERT_TRUE(got[0].has_value());
  EXPECT_EQ(got[0]->index, 1u);
  EXPECT_EQ(task::to_string(got[0]->primitive), "move above(A)");
}

TEST(RuntimeTaskControl, ExchangeSendsCommandsInAnOrderTheNetAllows) {
  Harness h("exchange.task");
  const auto sent = run_to_end(h);
  ASSERT_EQ(h.tc->state(), TaskControl::State::kFinished) << h.tc->reason();
  auto pos = [&](std::size_t r, std::size_t k) {
    auto it = std::find(sent.begin(), sent.end(), std::make_pair(r, k));
    return it == sent.end() ? -1 : static_cast<long>(it - sent.begin());
  };
  // Every move/open/close of both robots was sent exactly once, in program order per robot.
  for (std::size_t r = 0; r < 2; ++r) {
    long last = -1;
    for (std::size_t k = 0; k < h.compiled.programs[r].primitives.size(); ++k) {
      const auto kind = h.compiled.programs[r].primitives[k].kind;
      if (kind == task::PrimitiveKind::kSignal || kind == task::PrimitiveKind::kWait) {
        EXPECT_EQ(pos(r, k), -1) << "net-only primitive sent: robot " << r << " #" << k;
        continue;
      }
      EXPECT_GT(pos(r, k), last) << "robot " << r << " #" << k;
      last = pos(r, k);
    }
  }
  // r2's hand grasp (#5) only after r1 reached the hand-over (#7); r1 opens (#10) only after r2 closed (#6); r2
  // departs (#9) only after r1 opened; r2 approaches B (#12) only after r1's step-2 work.
  EXPECT_GT(pos(1, 5), pos(0, 7));
  EXPECT_GT(pos(0, 10), pos(1, 6));
  EXPECT_GT(pos(1, 9), pos(0, 10));
  // And r1's ready signal fired before r2's hand-grasp was sent: compare in the log.
  const auto lines = h.log.lines();
  auto line_of = [&](const std::string& needle) {
    for (std::size_t i = 0; i < lines.size(); ++i) {
      if (lines[i].find(needle) != std::string::npos) return static_cast<long>(i);
    }
    return -1L;
  };
  EXPECT_LT(line_of("\"transition\":\"r1.t8\""), line_of("\"transition\":\"r2.t5\""));
  EXPECT_NE(line_of("\"transition\":\"r2.t5\""), -1);
}

TEST(RuntimeTaskControl, AFailedCommandStopsTheRunWithTheRobotsReason) {
  Harness h("exchange.task");
  h.tc->step(milliseconds(10));
  auto got = h.take();
  ASSERT_EQ(h.statuses.try_push(RobotStatus{0, got[0]->index, CommandOutcome::kFailed, "gripper jammed", {}}),
            QueueStatus::ok);
  EXPECT_EQ(h.tc->step(milliseconds(20)), TaskControl::State::kFailed);
  EXPECT_THAT(h.tc->reason(), HasSubstr("robot r1, primitive 0 'open'"));
  EXPECT_THAT(h.tc->reason(), HasSubstr("gripper jammed"));
  // Nothing is fired or sent any more.
  const auto firings = h.tc->firings();
  h.tc->step(milliseconds(30));
  EXPECT_EQ(h.tc->firings(), firings);
  auto after = h.take();
  EXPECT_FALSE(after[0].has_value());
  EXPECT_FALSE(after[1].has_value());
}

TEST(RuntimeTaskControl, ARobotThatCannotBeBroughtUpFailsTheRun) {
  Harness h("exchange.task");
  ASSERT_EQ(h.statuses.try_push(
                RobotStatus{1, RobotStatus::kNoCommand, CommandOutcome::kFailed, "homing failed: hardware", {}}),
            QueueStatus::ok);
  EXPECT_EQ(h.tc->step(milliseconds(10)), TaskControl::State::kFailed);
  EXPECT_EQ(h.tc->reason(), "robot r2: homing failed: hardware");
}

TEST(RuntimeTaskControl, ADeadMarkingThatIsNotFinalStopsWithDeadlock) {
  Harness h("deadlock.task");
  run_to_end(h);
  ASSERT_EQ(h.tc->state(), TaskControl::State::kFailed);
  EXPECT_THAT(h.tc->reason(), HasSubstr("deadlock"));
  EXPECT_THAT(h.tc->reason(), HasSubstr("waiting for"));
}

// A counterexample's replay: task control fires the script's transitions one by one, in its order (either order of
// two independent ones), and nothing else, ending at the dead marking the analysis found.
TEST(RuntimeTaskControl, FollowsAScriptedFiringOrderToTheDeadMarking) {
  for (const bool reversed : {false, true}) {
    Harness h("deadlock.task");
    petri::AnalysisOptions o;
    const petri::AnalysisResult a = petri::analyze(h.net, o);
    ASSERT_FALSE(a.deadlock_examples.empty());
    std::vector<petri::TransitionId> path = a.deadlock_examples.front().path;
    ASSERT_GE(path.size(), 2u);
    if (reversed) std::reverse(path.begin(), path.end());
    h.tc->follow(path);
    std::vector<std::string> fired;
    for (int turn = 1; turn <= 10 && h.tc->state() == TaskControl::State::kRunning; ++turn) {
      h.tc->step(milliseconds(10 * turn));
      for (const std::string& id : h.tc->view().last_fired) fired.push_back(id);
    }
    std::vector<std::string> want;
    for (petri::TransitionId t : path) want.push_back(h.net.transitions()[t].id);
    EXPECT_EQ(fired, want) << (reversed ? "reversed" : "as found");
    EXPECT_EQ(h.tc->followed(), path.size());
    EXPECT_EQ(h.tc->marking(), a.deadlock_examples.front().marking);
    ASSERT_EQ(h.tc->state(), TaskControl::State::kFailed);
    EXPECT_THAT(h.tc->reason(), HasSubstr("deadlock"));
  }
}

// A script that stops short leaves the run where it stopped: nothing else fires.
TEST(RuntimeTaskControl, NothingFiresPastTheScript) {
  Harness h("exchange.task");
  const std::vector<petri::TransitionId> first = petri::choose(h.net, h.net.initial_marking(),
                                                               petri::make_arbiter(h.net));
  ASSERT_FALSE(first.empty());
  h.tc->follow({first.front()});
  for (int turn = 1; turn <= 5; ++turn) h.tc->step(milliseconds(10 * turn));
  EXPECT_EQ(h.tc->firings(), 1u);
  EXPECT_EQ(h.tc->state(), TaskControl::State::kRunning);
}

TEST(RuntimeTaskControl, ActivityTimeAddsUpToTheTimeAccounted) {
  Harness h("exchange.task");
  run_to_end(h);
  ASSERT_EQ(h.tc->state(), TaskControl::State::kFinished);
  const SimDuration end = *h.tc->finished_at() + milliseconds(50);
  h.tc->account_until(end);
  for (std::size_t r = 0; r < 2; ++r) {
    const ActivityTime& t = h.tc->activity_time()[r];
    EXPECT_EQ(t.total(), end) << "robot " << r;
    EXPECT_GT(t.busy.count(), 0);
  }
  // r2 waits for r1's pick before its hand-over moves: it has waiting time; r1 never waits that long at the start.
  EXPECT_GT(h.tc->activity_time()[1].waiting, h.tc->activity_time()[0].waiting);
}

}  // namespace
}  // namespace cellwright::runtime
