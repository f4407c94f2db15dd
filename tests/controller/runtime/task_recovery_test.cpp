// Task control's part of fault recovery (task_control.hpp steps 4 and 5, docs/faults.md): lost signals (injected with
// a signal filter that drops the n-th signal, as a rig does), the watchdog on waits (wait_timeout, diagnosed with the decision tree: resignal or stop the cell) and
// a robot's stop_cell. TaskControl is driven turn by turn from the test, with robots that finish each command one turn
// after it was sent (no threads, no sleeping: the simulated time is what the test passes to step()).
#include "cellwright/runtime/task_control.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::milliseconds;
using ::testing::HasSubstr;

struct Harness {
  Harness(const std::string& program, RecoveryOptions recovery, std::vector<std::uint64_t> lost_signals = {})
      : compiled(task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/" + program)),
        net(task::to_net(compiled)),
        statuses(16) {
    std::vector<MessageQueue<MotionCommand>*> ptrs;
    for (std::size_t r = 0; r < compiled.robots.size(); ++r) {
      inboxes.push_back(std::make_unique<MessageQueue<MotionCommand>>(4));
      ptrs.push_back(inboxes.back().get());
    }
    // As a rig injects it (cell/sim's ScenarioRun): the filter drops the n-th signals and logs the injection.
    SignalFilter filter;
    if (!lost_signals.empty()) {
      filter = [this, lost = std::move(lost_signals)](const SignalSent& s) {
        if (std::find(lost.begin(), lost.end(), s.count) == lost.end()) return true;
        log.fault_injected(s.time, "lost_signal", "", "",
                           "signal " + s.event + " of " + s.robot + " (the " + std::to_string(s.count) +
                               "th signal fired) is lost");
        return false;
      };
    }
    tc = std::make_unique<TaskControl>(net, compiled, ptrs, statuses, log, std::move(recovery), std::move(filter));
  }

  std::vector<std::optional<MotionCommand>> take() {
    std::vector<std::optional<MotionCommand>> out;
    for (auto& q : inboxes) {
      MotionCommand c;
      out.push_back(q->try_pop(c) == QueueStatus::ok ? std::optional(c) : std::nullopt);
    }
    return out;
  }

  // One turn every 10 ms; robots report each command done the turn after it was sent, except robot `stuck` (if
  // set), which never reports. Stops when the run is no longer running.
  void run(int max_turns = 2000, std::optional<std::size_t> stuck = std::nullopt) {
    std::vector<std::optional<MotionCommand>> pending(compiled.robots.size());
    for (int turn = 1; turn <= max_turns && tc->state() == TaskControl::State::kRunning; ++turn) {
      now = milliseconds(10 * turn);
      tc->step(now);
      for (std::size_t r = 0; r < pending.size(); ++r) {
        if (!pending[r] || (stuck && *stuck == r)) continue;
        ASSERT_EQ(statuses.try_push(RobotStatus{pending[r]->robot, pending[r]->index, CommandOutcome::kDone, "",
                                                false, now}),
                  QueueStatus::ok);
        pending[r].reset();
      }
      auto got = take();
      for (std::size_t r = 0; r < got.size(); ++r) {
        if (got[r]) pending[r] = got[r];
      }
    }
  }

  std::vector<nlohmann::json> events(const std::string& type) const {
    std::vector<nlohmann::json> out;
    for (const std::string& line : log.lines()) {
      nlohmann::json j = nlohmann::json::parse(line);
      if (j["type"] == type) out.push_back(std::move(j));
    }
    return out;
  }

  // The event place of `event` holds how many tokens now.
  petri::Tokens tokens(const std::string& event) const {
    return tc->marking()[*net.find_place(task::event_place_id(event))];
  }

  task::CompiledProgram compiled;
  petri::Net net;
  EventLog log;
  MessageQueue<RobotStatus> statuses;
  std::vector<std::unique_ptr<MessageQueue<MotionCommand>>> inboxes;
  std::unique_ptr<TaskControl> tc;
  SimDuration now{0};
};

RecoveryOptions with_recovery(SimDuration wait_timeout = milliseconds(200)) {
  RecoveryOptions o;
  o.enabled = true;
  o.wait_timeout = wait_timeout;
  return o;
}

RecoveryOptions without_recovery() {
  RecoveryOptions o;
  o.enabled = false;
  return o;
}

// The event of the first signal a robot's program gives (in exchange.task r2's barrier opens with it at once).
std::string first_signal(const task::CompiledProgram& p, std::size_t robot) {
  for (const task::Primitive& prim : p.programs[robot].primitives) {
    if (prim.kind == task::PrimitiveKind::kSignal) return prim.event;
  }
  return "";
}

// ---- Lost signals ----

TEST(RuntimeTaskRecovery, ALostSignalsEventVanishesWithAFaultInjectedEvent) {
  Harness h("exchange.task", without_recovery(), {1});
  h.tc->step(milliseconds(10));
  // The first signal fired is r2's, at the first turn: its event never reaches its place.
  const std::string event = first_signal(h.compiled, 1);
  ASSERT_FALSE(event.empty());
  EXPECT_EQ(h.tokens(event), 0);
  const auto injected = h.events("fault_injected");
  ASSERT_EQ(injected.size(), 1u);
  EXPECT_EQ(injected[0]["kind"], "lost_signal");
  EXPECT_THAT(injected[0]["detail"].get<std::string>(), HasSubstr("signal " + event + " of r2"));
  EXPECT_THAT(injected[0]["detail"].get<std::string>(), HasSubstr("1th signal fired"));

  // The same program without the injection has the token there.
  Harness clean("exchange.task", without_recovery());
  clean.tc->step(milliseconds(10));
  EXPECT_EQ(clean.tokens(event), 1);
  EXPECT_TRUE(clean.events("fault_injected").empty());
}

TEST(RuntimeTaskRecovery, OnlyTheNthSignalIsLost) {
  Harness h("exchange.task", without_recovery(), {2});
  h.tc->step(milliseconds(10));
  EXPECT_TRUE(h.events("fault_injected").empty()) << "the first signal is delivered";
  h.run();
  const auto injected = h.events("fault_injected");
  ASSERT_EQ(injected.size(), 1u);
  EXPECT_THAT(injected[0]["detail"].get<std::string>(), HasSubstr("2th signal fired"));
}

TEST(RuntimeTaskRecovery, WithoutRecoveryALostSignalEndsInADeadlock) {
  Harness h("exchange.task", without_recovery(), {1});
  h.run();
  EXPECT_EQ(h.tc->state(), TaskControl::State::kFailed);
  EXPECT_THAT(h.tc->reason(), HasSubstr("deadlock"));
  EXPECT_TRUE(h.events("fault_detected").empty());
}

// ---- The watchdog on waits ----

// The events of `type` about robot `robot`.
std::vector<nlohmann::json> of_robot(const std::vector<nlohmann::json>& events, const std::string& robot) {
  std::vector<nlohmann::json> out;
  for (const auto& e : events) {
    if (e["robot"] == robot) out.push_back(e);
  }
  return out;
}

TEST(RuntimeTaskRecovery, ARobotWaitingForALostSignalIsDetectedAndTheEventDeliveredAgain) {
  Harness h("exchange.task", with_recovery(milliseconds(200)), {1});
  h.run();
  ASSERT_EQ(h.tc->state(), TaskControl::State::kFinished) << h.tc->reason();
  // r1 waited for r2's lost signal.
  const std::string event = first_signal(h.compiled, 1);
  const auto detected = of_robot(h.events("fault_detected"), "r1");
  ASSERT_EQ(detected.size(), 1u);
  EXPECT_EQ(detected[0]["symptom"], "wait_timeout");
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("for event " + event));
  const auto diagnoses = of_robot(h.events("diagnosis"), "r1");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["symptom"], "wait_timeout");
  EXPECT_EQ(diagnoses[0]["cause"], "signal_lost");
  EXPECT_EQ(diagnoses[0]["action"], "resignal");
  EXPECT_EQ(diagnoses[0]["path"], "signal_fired=yes");
  const auto ends = of_robot(h.events("recovery_end"), "r1");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_THAT(ends[0]["detail"].get<std::string>(), HasSubstr("event " + event + " delivered again"));
  // Every move, open and close of both robots was still sent and done: the program ran to its end.
  for (std::size_t r = 0; r < 2; ++r) EXPECT_TRUE(h.tc->view().robots[r].done) << r;
}

TEST(RuntimeTaskRecovery, TheWaitForALostSignalIsDetectedAfterWaitTimeout) {
  // r2 never finishes its first command: the net is never dead, and only the watchdog can find r1's wait. (A wait
  // whose signal did not fire goes on here, whatever the standard tree says: r1 later waits for r2.)
  RecoveryOptions o = with_recovery(milliseconds(200));
  o.tree = std::make_shared<const DecisionTree>(DecisionTree::parse(
      "wait_timeout:\n"
      "  ask: signal_fired\n"
      "  yes: {cause: signal_lost, action: resignal}\n"
      "  no: {cause: slow_partner, action: go_on}\n",
      "patient.yaml"));
  Harness h("exchange.task", o, {1});
  h.run(100, /*stuck=*/1);
  const auto detected = of_robot(h.events("fault_detected"), "r1");
  ASSERT_GE(detected.size(), 1u);  // the first; later r1 waits for r2, which never comes
  const int wait = detected[0]["primitive"].get<int>();
  ASSERT_EQ(h.compiled.programs[0].primitives.at(static_cast<std::size_t>(wait)).kind, task::PrimitiveKind::kWait);
  // When r1 began to wait: the firing that started its wait primitive.
  std::optional<double> began;
  for (const auto& f : h.events("fire")) {
    if (f["robot"] == "r1" && f["primitive"] == wait) began = f["t"].get<double>();
  }
  ASSERT_TRUE(began.has_value());
  const double after = detected[0]["t"].get<double>() - *began;
  EXPECT_GE(after, 0.2 - 1e-9);
  EXPECT_LE(after, 0.21 + 1e-9);  // at the first turn past the timeout
  EXPECT_EQ(of_robot(h.events("diagnosis"), "r1").at(0)["action"], "resignal");
  // The event delivered again, r1 went on with its program.
  EXPECT_EQ(h.tc->state(), TaskControl::State::kRunning) << h.tc->reason();
  EXPECT_GT(h.tc->view().robots[0].primitive, wait);
}

TEST(RuntimeTaskRecovery, AWaitShorterThanTheTimeoutIsNoSymptom) {
  Harness h("exchange.task", with_recovery(std::chrono::seconds(30)));
  h.run();
  ASSERT_EQ(h.tc->state(), TaskControl::State::kFinished) << h.tc->reason();
  EXPECT_TRUE(h.events("fault_detected").empty());
}

TEST(RuntimeTaskRecovery, AWaitWhoseSignalNeverFiredStopsTheCell) {
  // r1 never finishes its first command, so it never gives the signal r2 waits for from the start; the tree (the
  // standard one's first version) says that is the program's fault.
  RecoveryOptions o = with_recovery(milliseconds(200));
  o.tree = std::make_shared<const DecisionTree>(DecisionTree::parse(
      "wait_timeout:\n"
      "  ask: signal_fired\n"
      "  yes: {cause: signal_lost, action: resignal}\n"
      "  no: {cause: program_error, action: stop_cell}\n",
      "strict.yaml"));
  Harness h("exchange.task", o);
  h.run(100, /*stuck=*/0);
  ASSERT_EQ(h.tc->state(), TaskControl::State::kStopped) << h.tc->reason();
  EXPECT_THAT(h.tc->reason(), HasSubstr("robot r2: waited"));
  EXPECT_THAT(h.tc->reason(), HasSubstr("program_error"));
  const auto diagnoses = h.events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "program_error");
  EXPECT_EQ(diagnoses[0]["action"], "stop_cell");
  EXPECT_EQ(diagnoses[0]["path"], "signal_fired=no");
  const auto ends = h.events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);
  // Stopped: nothing more is fired.
  const auto firings = h.tc->firings();
  EXPECT_EQ(h.tc->step(h.now + milliseconds(10)), TaskControl::State::kStopped);
  EXPECT_EQ(h.tc->firings(), firings);
  for (const RobotView& r : h.tc->view().robots) EXPECT_EQ(r.activity, RobotActivity::kIdle);
}

TEST(RuntimeTaskRecovery, ATreeThatStopsOnALostSignalIsObeyed) {
  RecoveryOptions o = with_recovery(milliseconds(200));
  o.tree = std::make_shared<const DecisionTree>(
      DecisionTree::parse("wait_timeout: {cause: no_patience, action: stop_cell}\n", "strict.yaml"));
  Harness h("exchange.task", o, {1});
  h.run();
  ASSERT_EQ(h.tc->state(), TaskControl::State::kStopped) << h.tc->reason();
  EXPECT_THAT(h.tc->reason(), HasSubstr("no_patience"));
  EXPECT_EQ(h.events("diagnosis").at(0)["path"], "");
}

TEST(RuntimeTaskRecovery, ATreeThatSaysGoOnLooksAgainAfterAnotherTimeout) {
  RecoveryOptions o = with_recovery(milliseconds(200));
  o.tree = std::make_shared<const DecisionTree>(
      DecisionTree::parse("wait_timeout: {cause: slow_partner, action: go_on}\n", "patient.yaml"));
  Harness h("exchange.task", o);
  h.run(100, /*stuck=*/0);  // 1 s: r2 waits from the first turn
  EXPECT_EQ(h.tc->state(), TaskControl::State::kRunning) << h.tc->reason();
  const auto detected = h.events("fault_detected");
  EXPECT_GE(detected.size(), 4u);
  EXPECT_LE(detected.size(), 5u);
}

// ---- stop_cell from a robot ----

TEST(RuntimeTaskRecovery, ARobotThatStopsTheCellStopsTheRunWithItsReason) {
  Harness h("exchange.task", with_recovery());
  h.tc->step(milliseconds(10));
  auto got = h.take();
  ASSERT_TRUE(got[0].has_value());
  ASSERT_EQ(h.statuses.try_push(RobotStatus{0, got[0]->index, CommandOutcome::kFailed,
                                            "no_second_chance: the gripper closed on nothing (expected A)", true,
                                            milliseconds(15)}),
            QueueStatus::ok);
  EXPECT_EQ(h.tc->step(milliseconds(20)), TaskControl::State::kStopped);
  EXPECT_EQ(h.tc->reason(), "robot r1: no_second_chance: the gripper closed on nothing (expected A)");
  const auto firings = h.tc->firings();
  h.tc->step(milliseconds(30));
  EXPECT_EQ(h.tc->firings(), firings);
  auto after = h.take();
  EXPECT_FALSE(after[0].has_value());
  EXPECT_FALSE(after[1].has_value());
}

TEST(RuntimeTaskRecovery, AStopCellWithoutACommandStopsTheRun) {
  Harness h("exchange.task", with_recovery());
  ASSERT_EQ(h.statuses.try_push(RobotStatus{1, RobotStatus::kNoCommand, CommandOutcome::kFailed,
                                            "the driver of melfa could not be reset", true, milliseconds(5)}),
            QueueStatus::ok);
  EXPECT_EQ(h.tc->step(milliseconds(10)), TaskControl::State::kStopped);
  EXPECT_EQ(h.tc->reason(), "robot r2: the driver of melfa could not be reset");
}

TEST(RuntimeTaskRecovery, AFailureWithoutStopCellStillFailsTheRun) {
  Harness h("exchange.task", with_recovery());
  h.tc->step(milliseconds(10));
  auto got = h.take();
  ASSERT_TRUE(got[0].has_value());
  ASSERT_EQ(h.statuses.try_push(RobotStatus{0, got[0]->index, CommandOutcome::kFailed, "gripper jammed", false,
                                            milliseconds(15)}),
            QueueStatus::ok);
  EXPECT_EQ(h.tc->step(milliseconds(20)), TaskControl::State::kFailed);
  EXPECT_THAT(h.tc->reason(), HasSubstr("gripper jammed"));
}

}  // namespace
}  // namespace cellwright::runtime
