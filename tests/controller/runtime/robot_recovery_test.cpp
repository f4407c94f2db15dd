// Robot control with recovery on (robot_control.hpp "WHEN THINGS GO WRONG", docs/faults.md): a symptom does not fail
// the command; it is logged (fault_detected), diagnosed with the decision tree (diagnosis) and the action is taken,
// and the command is reported once, done (recovery_end ok) or, when the tree says stop_cell, failed with
// RobotStatus::stop_cell. Faults come from a FaultyDriver around the scripted PUMA, and from the environment model
// (grip sensor, parts absent or elsewhere). What is checked is what a user sees: statuses, the event log, the driver
// commands, the model.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "cellwright/runtime/recovery.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "controller/runtime/robot_control_fixture.hpp"

namespace cellwright::runtime {
namespace {

using test::close_on;
using test::move;
using test::open_from;
using test::to_eigen;
using ::testing::HasSubstr;
using K = task::TargetKind;
using std::chrono::milliseconds;

class RobotRecoveryTest : public test::RobotControlTest {
 protected:
  RobotRecoveryTest() { recovery_ = true; }

  // A plan whose rules fail the n-th command of `kind` with `error`, for each n in `nths`.
  static drivers::FaultPlan failing(drivers::CommandKind kind, drivers::ErrorCode error, std::vector<std::uint64_t> nths,
                                    std::string message = "") {
    drivers::FaultPlan plan;
    for (const std::uint64_t n : nths) plan.rules.push_back({kind, n, {error, false, message}});
    return plan;
  }

  // The values of `field` of every event of `type`, in order.
  std::vector<std::string> field_of(const std::string& type, const std::string& field) const {
    std::vector<std::string> out;
    for (const auto& e : events(type)) out.push_back(e[field].is_string() ? e[field].get<std::string>() : e[field].dump());
    return out;
  }

  // Every status reported so far, popped.
  std::vector<RobotStatus> all_statuses() {
    std::vector<RobotStatus> out;
    while (std::optional<RobotStatus> s = status()) out.push_back(*s);
    return out;
  }

  // Turns until nothing more happens for a while, then every status reported.
  std::vector<RobotStatus> settle(int turns = 500) {
    for (int i = 0; i < turns; ++i) turn();
    return all_statuses();
  }

  // Turns (`one_turn` each) until robot control reports a status, at most `max_turns`.
  template <typename Turn>
  std::optional<RobotStatus> status_after(Turn one_turn, int max_turns = 20000) {
    std::optional<RobotStatus> s;
    for (int i = 0; i < max_turns && !s; ++i) {
      one_turn();
      s = status();
    }
    return s;
  }

  std::vector<std::string> kinds_sent() const {
    std::vector<std::string> out;
    for (const drivers::Command& c : sent()) {
      if (const auto* g = std::get_if<drivers::Grip>(&c)) {
        out.push_back(g->action == drivers::Grip::Action::close ? "close" : "open");
      } else {
        out.push_back(std::holds_alternative<drivers::MoveJoints>(c) ? "move_joints" : "other");
      }
    }
    return out;
  }
};

// ---- Driver failures ----

TEST_F(RobotRecoveryTest, AMoveThatTimesOutIsRetriedAndDone) {
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::timeout, {1}, "no answer");
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(4, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(s.index, 4u);
  EXPECT_FALSE(s.stop_cell);
  EXPECT_TRUE(settle().empty()) << "one status per command";

  const auto detected = events("fault_detected");
  ASSERT_EQ(detected.size(), 1u);
  EXPECT_EQ(detected[0]["symptom"], "driver_timeout");
  EXPECT_EQ(detected[0]["robot"], "r1");
  EXPECT_EQ(detected[0]["primitive"], 4);
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("timeout: no answer"));
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["symptom"], "driver_timeout");
  EXPECT_EQ(diagnoses[0]["cause"], "controller_timeout");
  EXPECT_EQ(diagnoses[0]["action"], "retry");
  EXPECT_EQ(diagnoses[0]["path"], "driver_in_fault=no motion_blocked=no retries_left=yes");
  const auto ends = events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_EQ(ends[0]["action"], "retry");
  // The move was submitted again: the first never reached the controller, the second did and arrived.
  EXPECT_EQ(faulty_->injected().failed, 1u);
  ASSERT_EQ(sent().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<drivers::MoveJoints>(sent()[0]));
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_reached"});
  const auto command_ends = events("command_end");
  ASSERT_EQ(command_ends.size(), 1u);
  EXPECT_EQ(command_ends[0]["ok"], true);
  EXPECT_EQ(events("command_start").size(), 1u);
  EXPECT_EQ(control_->phase(), RobotPhase::kReady);
}

TEST_F(RobotRecoveryTest, AGripThatFailsWithAHardwareErrorIsDoneAgainAfterResetAndRehome) {
  faults_ = failing(drivers::CommandKind::grip, drivers::ErrorCode::hardware, {1}, "gripper motor stalled");
  make(joint_arm());
  bring_up();
  ASSERT_EQ(scripted_->calls().home, 1);
  ASSERT_EQ(scripted_->calls().activate, 1);
  set_fingers("A");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(s.index, 2u);
  EXPECT_TRUE(settle().empty());

  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"driver_fault"});
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "controller_error");
  EXPECT_EQ(diagnoses[0]["action"], "reset_rehome");
  EXPECT_EQ(diagnoses[0]["path"], "retries_left=yes");
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"true"});
  // Reset (which connects the controller again), homed and activated a second time, then the grip again.
  EXPECT_EQ(scripted_->calls().connect, 2);
  EXPECT_EQ(scripted_->calls().home, 2);
  EXPECT_EQ(scripted_->calls().activate, 2);
  EXPECT_EQ(faulty_->state(), drivers::DriverState::active);
  EXPECT_EQ(kinds_sent(), std::vector<std::string>{"close"});  // the failed one never reached the controller
  EXPECT_TRUE(scripted_->gripper_closed());
  // Where the arm stopped was read back before it was homed.
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"stopped_at", "gripped"}));
  ASSERT_TRUE(robot().hold.has_value());
  EXPECT_EQ(robot().hold->workpiece, "A");
  EXPECT_EQ(part("A").held_by, "puma");
}

TEST_F(RobotRecoveryTest, ALostLinkIsConnectedAgainAndTheCommandDone) {
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::connection_lost, {1}, "cable pulled");
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(1, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_FALSE(s.stop_cell);
  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"link_lost"});
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "link_dropped");
  EXPECT_EQ(diagnoses[0]["action"], "reset_rehome");
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"true"});
  // Connected again (reset leaves a lost link disconnected), homed, activated.
  EXPECT_EQ(scripted_->calls().connect, 2);
  EXPECT_EQ(scripted_->calls().home, 2);
  EXPECT_EQ(faulty_->state(), drivers::DriverState::active);
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"stopped_at", "position_reached"}));
}

TEST_F(RobotRecoveryTest, APositionTheControllerRefusesIsRetried) {
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::unreachable, {1}, "ER 2");
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"position_refused"});
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "controller_refused_position");
  EXPECT_EQ(diagnoses[0]["action"], "retry");
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"true"});
  EXPECT_EQ(scripted_->calls().home, 1);  // a retry does not re-home
}

TEST_F(RobotRecoveryTest, TheSameFailureOnceMoreThanMaxAttemptsStopsTheCell) {
  const int max = MotionOptions{}.recovery.max_attempts;
  std::vector<std::uint64_t> nths;
  for (int n = 1; n <= max + 1; ++n) nths.push_back(static_cast<std::uint64_t>(n));
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::unreachable, nths, "ER 2");
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(3, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s.stop_cell);
  EXPECT_EQ(s.index, 3u);
  EXPECT_THAT(s.reason, HasSubstr("position_out_of_reach"));
  EXPECT_THAT(s.reason, HasSubstr("ER 2"));
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
  EXPECT_TRUE(settle().empty());

  EXPECT_EQ(events("fault_detected").size(), static_cast<std::size_t>(max + 1));
  const std::vector<std::string> actions = field_of("diagnosis", "action");
  ASSERT_EQ(actions.size(), static_cast<std::size_t>(max + 1));
  for (int i = 0; i < max; ++i) EXPECT_EQ(actions[static_cast<std::size_t>(i)], "retry") << i;
  EXPECT_EQ(actions.back(), "stop_cell");
  EXPECT_EQ(events("diagnosis").back()["path"], "retries_left=no");
  const auto ends = events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);
  EXPECT_EQ(ends[0]["action"], "stop_cell");
  const auto command_ends = events("command_end");
  ASSERT_EQ(command_ends.size(), 1u);
  EXPECT_EQ(command_ends[0]["ok"], false);
  EXPECT_EQ(faulty_->injected().failed, static_cast<std::uint64_t>(max + 1));
  // A stopped robot takes no further commands.
  send(4, move(K::kHome));
  EXPECT_TRUE(settle(100).empty());
}

TEST_F(RobotRecoveryTest, WithoutRecoveryTheFirstFailureFailsTheCommand) {
  recovery_ = false;
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::timeout, {1});
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_FALSE(s.stop_cell);
  EXPECT_TRUE(events("fault_detected").empty());
  EXPECT_TRUE(events("diagnosis").empty());
}

// ---- Parts ----

TEST_F(RobotRecoveryTest, APartThatNeverArrivesIsSetAsideAndWhatConcernsItSkipped) {
  MotionOptions options;
  options.recovery.part_wait = milliseconds(50);
  make(joint_arm(), options);
  bring_up();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  send(1, move(K::kAbove, "A"));
  for (int i = 0; i < 40; ++i) turn();
  ASSERT_FALSE(status().has_value()) << "still waiting before part_wait";
  EXPECT_TRUE(events("fault_detected").empty());
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(s.index, 1u);
  EXPECT_GE(now_, milliseconds(50));

  const auto detected = events("fault_detected");
  ASSERT_EQ(detected.size(), 1u);
  EXPECT_EQ(detected[0]["symptom"], "part_not_arrived");
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("A has not been in the cell"));
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "missing");
  EXPECT_EQ(diagnoses[0]["action"], "set_aside");
  const auto lost = events("workpiece_lost");
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_EQ(lost[0]["workpiece"], "A");
  EXPECT_EQ(lost[0]["reason"], "missing");
  EXPECT_TRUE(lost[0]["x"].is_null());  // never seen
  EXPECT_TRUE(part("A").lost);
  EXPECT_EQ(part("A").lost_reason, "missing");
  const auto skipped = events("skipped");
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_EQ(skipped[0]["primitive"], 1);
  EXPECT_EQ(skipped[0]["command"], "move above(A)");
  const auto ends = events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_EQ(ends[0]["action"], "set_aside");
  EXPECT_EQ(field_of("command_end", "ok"), std::vector<std::string>{"true"});
  EXPECT_EQ(scripted_->calls().submit, 0);

  // The rest of its pick is skipped too, at once, even if the part turns up: its close and the open that would have
  // released it; a move that concerns no part afterwards is done.
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = true; });
  const RobotStatus at = run(2, move(K::kAt, "A"));
  EXPECT_EQ(at.outcome, CommandOutcome::kDone);
  const RobotStatus close = run(3, close_on("A"));
  EXPECT_EQ(close.outcome, CommandOutcome::kDone);
  EXPECT_EQ(close.index, 3u);
  const RobotStatus open = run(4, open_from("A"));
  EXPECT_EQ(open.outcome, CommandOutcome::kDone);
  EXPECT_EQ(field_of("skipped", "command"),
            (std::vector<std::string>{"move above(A)", "move at(A)", "close A", "open A"}));
  EXPECT_EQ(scripted_->calls().submit, 0);
  const RobotStatus home = run(5, move(K::kHome));
  EXPECT_EQ(home.outcome, CommandOutcome::kDone);
  EXPECT_EQ(events("skipped").size(), 4u);
  EXPECT_EQ(scripted_->calls().submit, 1);
  EXPECT_EQ(events("workpiece_lost").size(), 1u);
}

TEST_F(RobotRecoveryTest, AMoveToALostPartIsSkippedAtOnce) {
  make(joint_arm());
  bring_up();
  env_.write([](EnvironmentModel& m) {
    m.find_workpiece("A")->lost = true;
    m.find_workpiece("A")->lost_reason = "dropped_unseen";
  });
  const RobotStatus s = run(7, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone);
  EXPECT_EQ(s.index, 7u);
  const auto skipped = events("skipped");
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_EQ(skipped[0]["reason"], "its workpiece is lost");
  EXPECT_EQ(scripted_->calls().submit, 0);
  EXPECT_TRUE(events("fault_detected").empty());
}

TEST_F(RobotRecoveryTest, ACloseOnNothingPicksThePartAgainWhereTheModelSeesIt) {
  make(joint_arm());
  bring_up();
  // The part is 3 cm off where the robot went for it (knocked aside: more than part_misplaced's 2 cm off its place,
  // which the re-grasp must not take for a symptom of its own).
  const Eigen::Vector3d was = part("A").pose.translation();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->pose.translation() += Eigen::Vector3d(0.03, 0.0, 0); });
  set_fingers("");
  send(2, close_on("A"));
  ASSERT_TRUE(turn_until([&] { return !events("fault_detected").empty(); }));
  set_fingers("A");  // the fingers will have it after the re-grasp
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(s.index, 2u);
  EXPECT_TRUE(settle().empty());

  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"closed_on_nothing"});
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "part_not_where_expected");
  EXPECT_EQ(diagnoses[0]["action"], "pick_again");
  EXPECT_EQ(diagnoses[0]["path"], "part_seen=yes retries_left=yes part_reachable=yes");
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"true"});
  // The first close, then the recovery steps open, above(A), at(A), then the close again.
  EXPECT_EQ(kinds_sent(), (std::vector<std::string>{"close", "open", "move_joints", "move_joints", "close"}));
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"closed_on_nothing", "released", "position_reached",
                                                           "position_reached", "gripped"}));
  // The re-grasp went to the part where the model sees it, not where it was.
  const RobotState r = robot();
  const Eigen::Vector3d at_tool =
      (r.base() * chain_.forward(to_eigen(std::get<drivers::MoveJoints>(sent()[3]).positions))).translation();
  const Eigen::Vector3d now_at = part("A").pose.translation();
  EXPECT_NEAR(at_tool.x(), now_at.x(), 1e-3);
  EXPECT_NEAR(at_tool.y(), now_at.y(), 1e-3);
  EXPECT_GT((at_tool.head<2>() - was.head<2>()).norm(), 0.02);
  // One command as task control sees it: one start, one end.
  EXPECT_EQ(events("command_start").size(), 1u);
  EXPECT_EQ(field_of("command_end", "ok"), std::vector<std::string>{"true"});
  ASSERT_TRUE(r.hold.has_value());
  EXPECT_EQ(r.hold->workpiece, "A");
}

TEST_F(RobotRecoveryTest, ACloseOnNothingWithThePartUnseenSetsItAside) {
  make(joint_arm());
  bring_up();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  set_fingers("");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "part_gone");
  EXPECT_EQ(diagnoses[0]["action"], "set_aside");
  EXPECT_EQ(diagnoses[0]["path"], "part_seen=no");
  EXPECT_EQ(field_of("skipped", "command"), std::vector<std::string>{"close A"});
  EXPECT_TRUE(part("A").lost);
  EXPECT_EQ(kinds_sent(), std::vector<std::string>{"close"});
}

// ---- No progress (docs/faults.md: no_progress) ----

// The arm pushes against something whenever it moves (a part jammed in the fingers dragged along the belt): the wrist
// force is over the limit while the arm moves, and falls back when the safety layer has stopped it.
class PushingArmTest : public RobotRecoveryTest {
 protected:
  void push_turn() {
    scripted_->advance(1);
    now_ += milliseconds(1);
    const auto accepted = scripted_->accepted();
    const bool moving = !accepted.empty() && std::holds_alternative<drivers::MoveJoints>(accepted.back().second) &&
                        scripted_->poll(accepted.back().first).phase == drivers::CommandPhase::running;
    env_.write([&](EnvironmentModel& m) {
      m.time = now_;
      m.find_robot("puma")->wrist_force = Eigen::Vector3d(0, 0, moving ? 400.0 : 10.0);
    });
    control_->step(now_);
  }
};

TEST_F(PushingArmTest, AForceTripAgainAndAgainIsNoProgressAndTheTreeStopsTheCell) {
  make(joint_arm());
  bring_up();
  send(7, move(K::kAbove, "A"));
  const std::optional<RobotStatus> s = status_after([&] { push_turn(); });
  ASSERT_TRUE(s.has_value()) << "a livelock: " << events("protective_stop").size() << " protective stops";
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s->stop_cell);
  EXPECT_EQ(s->index, 7u);
  EXPECT_THAT(s->reason, HasSubstr("livelock"));
  const int limit = MotionOptions{}.recovery.progress_limit;
  // Stopped, released and stopped again, until the limit-th interruption, which is named for what it is.
  std::vector<std::string> symptoms(static_cast<std::size_t>(limit - 1), "protective_stop");
  symptoms.emplace_back("no_progress");
  EXPECT_EQ(field_of("fault_detected", "symptom"), symptoms);
  const auto detected = events("fault_detected");
  EXPECT_THAT(detected.back()["detail"].get<std::string>(),
              HasSubstr(fmt::format("'move above(A)' interrupted {} times and not done", limit)));
  EXPECT_THAT(detected.back()["detail"].get<std::string>(), HasSubstr("wrist force"));
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), static_cast<std::size_t>(limit));
  EXPECT_EQ(diagnoses.back()["symptom"], "no_progress");
  EXPECT_EQ(diagnoses.back()["cause"], "livelock");
  EXPECT_EQ(diagnoses.back()["action"], "stop_cell");
  EXPECT_EQ(diagnoses.back()["path"], "waiting_for_part=no");
  EXPECT_EQ(events("protective_stop").size(), static_cast<std::size_t>(limit));
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
}

TEST_F(PushingArmTest, TheLimitIsTheScenariosToSet) {
  MotionOptions options;
  options.recovery.progress_limit = 2;
  make(joint_arm(), options);
  bring_up();
  send(7, move(K::kAbove, "A"));
  const std::optional<RobotStatus> s = status_after([&] { push_turn(); });
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(s->stop_cell);
  EXPECT_EQ(field_of("fault_detected", "symptom"), (std::vector<std::string>{"protective_stop", "no_progress"}));
}

TEST_F(RobotRecoveryTest, AWaitForAPartOfAClassSetAsideUpstreamIsNoProgressAndItsWorkIsSkipped) {
  classes_ = {{"p", "output_drop"}};  // nothing there: the part for it was lost before it got there
  MotionOptions options;
  options.recovery.progress_timeout = milliseconds(200);
  make(joint_arm(), options);
  bring_up();
  env_.write([](EnvironmentModel& m) {
    m.find_workpiece("B")->lost = true;  // set aside by a robot upstream
    m.find_workpiece("B")->lost_reason = "dropped_out_of_reach";
  });
  send(1, move(K::kAbove, "p"));
  for (int i = 0; i < 150; ++i) turn();
  ASSERT_FALSE(status().has_value()) << "still waiting before progress_timeout";
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_FALSE(s.stop_cell);
  EXPECT_GE(now_, milliseconds(200));
  const auto detected = events("fault_detected");
  ASSERT_EQ(detected.size(), 1u);
  EXPECT_EQ(detected[0]["symptom"], "no_progress");
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("'move above(p)' has waited"));
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("no part of p has arrived at output_drop"));
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "part_lost_upstream");
  EXPECT_EQ(diagnoses[0]["action"], "set_aside");
  EXPECT_EQ(diagnoses[0]["path"], "waiting_for_part=yes part_lost=yes");
  EXPECT_TRUE(events("workpiece_lost").empty()) << "it was declared lost upstream, once";
  // Its work for that part is skipped up to the open that would have released it; then it goes on.
  EXPECT_EQ(run(2, close_on("p")).outcome, CommandOutcome::kDone);
  EXPECT_EQ(run(3, move(K::kAbove, "B")).outcome, CommandOutcome::kDone);
  EXPECT_EQ(run(4, open_from("p")).outcome, CommandOutcome::kDone);
  EXPECT_EQ(field_of("skipped", "command"),
            (std::vector<std::string>{"move above(p)", "close p", "move above(B)", "open p"}));
  EXPECT_EQ(scripted_->calls().submit, 0);
  EXPECT_EQ(run(5, move(K::kHome)).outcome, CommandOutcome::kDone);
  EXPECT_EQ(scripted_->calls().submit, 1);
  // The next wait for the class is not blamed on the same lost part again.
  send(6, move(K::kAbove, "p"));
  const RobotStatus again = next_status();
  EXPECT_TRUE(again.stop_cell);
  EXPECT_EQ(field_of("diagnosis", "cause"), (std::vector<std::string>{"part_lost_upstream", "part_never_ready"}));
}

TEST_F(RobotRecoveryTest, AWaitForAPartThatNeverComesWithNothingLostStopsTheCell) {
  classes_ = {{"p", "output_drop"}};
  MotionOptions options;
  options.recovery.progress_timeout = milliseconds(200);
  make(joint_arm(), options);
  bring_up();
  const RobotStatus s = run(1, move(K::kAbove, "p"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s.stop_cell);
  EXPECT_THAT(s.reason, HasSubstr("part_never_ready"));
  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"no_progress"});
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["path"], "waiting_for_part=yes part_lost=no");
  EXPECT_EQ(diagnoses[0]["action"], "stop_cell");
}

// ---- A blocked gripper is not a silent controller ----

// A controller that runs every grip it is sent and never ends it (fingers blocked short of their goal, as at a belt's
// stop bar, pressing on it: the wrist force changes), while it goes on answering position requests
// (reads_while_moving): robot control's command_timeout fires.
class BlockedGripperTest : public RobotRecoveryTest {
 protected:
  drivers::ScriptedDriverConfig answering_arm() const {
    drivers::ScriptedDriverConfig c = joint_arm();
    c.capabilities.reads_while_moving = true;
    return c;
  }
  MotionOptions quick() const {
    MotionOptions o;
    o.recovery.command_timeout = milliseconds(300);
    return o;
  }
  void wrist(double newtons) {
    env_.write([&](EnvironmentModel& m) { m.find_robot("puma")->wrist_force = Eigen::Vector3d(0, 0, newtons); });
  }
  // One turn; every grip the controller has taken is blocked, its fingers pressing on what blocks them.
  void blocked_turn() {
    turn();
    for (const auto& [id, c] : scripted_->accepted()) {
      if (std::holds_alternative<drivers::Grip>(c) && blocked_.insert(id).second) {
        scripted_->never_complete(id);
        wrist(18.0);
      }
    }
  }
  std::set<drivers::CommandId> blocked_;
};

TEST_F(BlockedGripperTest, AGripThatNeverEndsWhileTheControllerAnswersIsAnObstruction) {
  make(answering_arm(), quick());
  bring_up();
  set_fingers("A");
  wrist(10.0);  // the hand's weight
  send(2, close_on("A"));
  const std::optional<RobotStatus> s = status_after([&] { blocked_turn(); });
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s->stop_cell);
  EXPECT_THAT(s->reason, HasSubstr("obstruction"));
  EXPECT_THAT(s->reason, ::testing::Not(HasSubstr("controller_not_answering")));
  const int max = MotionOptions{}.recovery.max_attempts;
  std::vector<std::string> causes(static_cast<std::size_t>(max), "obstructed");
  causes.emplace_back("obstruction");
  EXPECT_EQ(field_of("diagnosis", "cause"), causes);
  EXPECT_EQ(events("diagnosis").back()["path"], "driver_in_fault=no motion_blocked=yes retries_left=no");
  EXPECT_EQ(field_of("fault_detected", "symptom"),
            std::vector<std::string>(static_cast<std::size_t>(max + 1), "driver_timeout"));
  EXPECT_EQ(kinds_sent(), std::vector<std::string>(static_cast<std::size_t>(max + 1), "close"));
}

TEST_F(BlockedGripperTest, AnArmThatStopsShortOfItsGoalWhileTheControllerAnswersIsAnObstruction) {
  make(answering_arm(), quick());
  bring_up();
  send(4, move(K::kAbove, "A"));
  // The move never ends, and the read-backs show the arm standing 0.2 rad short of the goal in its first joint.
  ASSERT_TRUE(turn_until([&] { return !scripted_->accepted().empty(); }));
  scripted_->never_complete(scripted_->accepted().front().first);
  driver_->misread_joint(0, 0.2);
  ASSERT_TRUE(turn_until([&] { return !events("diagnosis").empty(); }));
  const auto diagnoses = events("diagnosis");
  EXPECT_EQ(diagnoses[0]["cause"], "obstructed");
  EXPECT_EQ(diagnoses[0]["action"], "retry");
  EXPECT_EQ(diagnoses[0]["path"], "driver_in_fault=no motion_blocked=yes retries_left=yes");
}

TEST_F(BlockedGripperTest, AControllerThatNeverEndsACommandWithNothingHeldBackIsStillNotAnswering) {
  // The controller never ends the grip (the injected timeout) but answers reads all along; nothing presses on the
  // hand.
  drivers::FaultPlan plan;
  for (std::uint64_t n = 1; n <= 4; ++n) plan.rules.push_back({drivers::CommandKind::grip, n, {drivers::ErrorCode::timeout, true, ""}});
  faults_ = plan;
  make(answering_arm(), quick());
  bring_up();
  set_fingers("A");
  wrist(10.0);
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_TRUE(s.stop_cell);
  EXPECT_THAT(s.reason, HasSubstr("controller_not_answering"));
  EXPECT_EQ(field_of("diagnosis", "cause"),
            (std::vector<std::string>{"controller_timeout", "controller_timeout", "controller_timeout",
                                      "controller_not_answering"}));
}

// ---- A tree of one's own ----

TEST_F(RobotRecoveryTest, ACustomTreeIsObeyed) {
  MotionOptions options;
  options.recovery.tree = std::make_shared<const DecisionTree>(
      DecisionTree::parse("closed_on_nothing: {cause: no_second_chance, action: stop_cell}\n", "strict.yaml"));
  make(joint_arm(), options);
  bring_up();
  set_fingers("");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s.stop_cell);
  EXPECT_EQ(s.reason, "no_second_chance: the gripper closed on nothing (expected A)");
  const auto diagnoses = events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["cause"], "no_second_chance");
  EXPECT_EQ(diagnoses[0]["action"], "stop_cell");
  EXPECT_EQ(diagnoses[0]["path"], "");
  const auto ends = events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
  EXPECT_EQ(kinds_sent(), std::vector<std::string>{"close"});  // no pick again
}

TEST_F(RobotRecoveryTest, ASymptomTheCustomTreeDoesNotKnowStopsTheCell) {
  MotionOptions options;
  options.recovery.tree = std::make_shared<const DecisionTree>(
      DecisionTree::parse("frame_lost: {cause: camera_dropout, action: go_on}\n", "small.yaml"));
  faults_ = failing(drivers::CommandKind::move_joints, drivers::ErrorCode::timeout, {1});
  make(joint_arm(), options);
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s.stop_cell);
  EXPECT_THAT(s.reason, HasSubstr("unknown: "));
  EXPECT_EQ(field_of("diagnosis", "cause"), std::vector<std::string>{"unknown"});
}

}  // namespace
}  // namespace cellwright::runtime
