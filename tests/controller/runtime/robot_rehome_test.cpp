// Recovery on a real arm (robot_control.hpp, docs/faults.md reset_rehome and section 2): where the arm stopped is read
// back before the recovery moves it, a loaded arm is never sent home (the cell stops, saying why), a fault during any
// step of the re-homing is recovered a bounded number of times and then stops the cell (never a loop), a read-back that
// fails while the robot is idle is a fault of that robot at once with the driver's message, and an error the driver
// does not know stops the cell. The scripted PUMA of robot_control_fixture.hpp, its faults scripted on the controller
// itself (ScriptedDriver::fail_command, drop_connection) so that every call reaches it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "controller/runtime/robot_control_fixture.hpp"

namespace cellwright::runtime {
namespace {

using test::close_on;
using test::move;
using ::testing::HasSubstr;
using K = task::TargetKind;

class RobotRehomeTest : public test::RobotControlTest {
 protected:
  RobotRehomeTest() { recovery_ = true; }

  // Sends `p` and, once the controller has taken it, makes it fail with `error` when it would complete.
  void send_failing(std::size_t index, task::Primitive p, drivers::ErrorCode error, const std::string& message) {
    const std::size_t before = scripted_->accepted().size();
    send(index, std::move(p));
    ASSERT_TRUE(turn_until([&] { return scripted_->accepted().size() > before; }));
    scripted_->fail_command(scripted_->accepted().back().first, error, message);
  }

  // Turns until a status comes (at most `max_turns`), with `between` called after each tick of the controller and
  // before robot control's step: what happens on the controller's side between two steps.
  template <typename Between>
  std::optional<RobotStatus> status_within(int max_turns, Between between) {
    for (int i = 0; i < max_turns; ++i) {
      scripted_->advance(1);
      between();
      now_ += test::milliseconds(1);
      env_.write([&](EnvironmentModel& m) { m.time = now_; });
      control_->step(now_);
      if (std::optional<RobotStatus> s = status()) return s;
    }
    return std::nullopt;
  }
  std::optional<RobotStatus> status_within(int max_turns) {
    return status_within(max_turns, [] {});
  }

  std::vector<std::string> field_of(const std::string& type, const std::string& field) const {
    std::vector<std::string> out;
    for (const auto& e : events(type)) out.push_back(e[field].is_string() ? e[field].get<std::string>() : e[field].dump());
    return out;
  }
};

// The arm stopped somewhere (after a first move, on its way to a second one): the recovery reads where before it homes
// the arm, and the model has it.
TEST_F(RobotRehomeTest, WhereTheArmStoppedIsReadBackBeforeItIsHomedAgain) {
  make(joint_arm());
  bring_up();
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  const std::vector<double> stopped = scripted_->joints();
  send_failing(1, move(K::kAt, "A"), drivers::ErrorCode::hardware, "*Arm power off*");
  const std::size_t reads_before = driver_->requests().size();
  // Up to the moment the recovery sends the arm home.
  ASSERT_TRUE(turn_until([&] { return scripted_->calls().home == 2; }));
  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"driver_fault"});
  EXPECT_EQ(field_of("sensor", "condition").back(), "stopped_at");
  ASSERT_GT(driver_->requests().size(), reads_before) << "no read-back after the fault, before homing";
  const std::vector<double> model = robot().joints;
  ASSERT_EQ(model.size(), stopped.size());
  for (std::size_t j = 0; j < model.size(); ++j) EXPECT_NEAR(model[j], stopped[j], 1e-9) << "joint " << j + 1;
  const std::optional<RobotStatus> s = status_within(3000);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->outcome, CommandOutcome::kDone) << s->reason;
}

// The arm holds A: homing it could carry A through the other robot's space, and robot control cannot check that way.
// The cell stops, and the reason says which arm holds which part where; the arm is not homed.
TEST_F(RobotRehomeTest, ALoadedArmIsNotHomedTheCellStopsSayingWhy) {
  make(joint_arm());
  bring_up();
  set_fingers("A");
  ASSERT_EQ(run(0, close_on("A")).outcome, CommandOutcome::kDone);
  ASSERT_TRUE(robot().hold.has_value());
  send_failing(1, move(K::kAbove, "A"), drivers::ErrorCode::hardware, "*Servo error*");
  const std::optional<RobotStatus> s = status_within(3000);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s->stop_cell);
  EXPECT_THAT(s->reason, HasSubstr("puma holds A where it stopped"));
  EXPECT_THAT(s->reason, HasSubstr("*Servo error*"));  // the fault's cause is kept
  EXPECT_THAT(s->reason, HasSubstr("melfa"));
  EXPECT_EQ(scripted_->calls().home, 1) << "the loaded arm was sent home";
  EXPECT_EQ(field_of("sensor", "condition").back(), "stopped_at");  // read back first all the same
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"false"});
}

// The loop: a fault lands after the re-homing has finished but before the driver is activated. The recovery
// starts over (reset, read back, home, activate: a new home command, not the old one polled again) and the command is
// done, well before any time limit.
TEST_F(RobotRehomeTest, AFaultBetweenTheReHomingAndActivationIsRecovered) {
  make(joint_arm());
  bring_up();
  send_failing(0, move(K::kAbove, "A"), drivers::ErrorCode::hardware, "*Arm power off*");
  bool dropped = false;
  const std::optional<RobotStatus> s = status_within(5000, [&] {
    if (!dropped && scripted_->calls().home == 2 && scripted_->state() == drivers::DriverState::homed) {
      scripted_->drop_connection();  // the homing is done; the link fails before robot control activates
      dropped = true;
    }
  });
  ASSERT_TRUE(dropped);
  ASSERT_TRUE(s.has_value()) << "no status: the recovery went round in circles";
  EXPECT_EQ(s->outcome, CommandOutcome::kDone) << s->reason;
  EXPECT_EQ(scripted_->calls().home, 3);
  EXPECT_EQ(scripted_->state(), drivers::DriverState::active);
  EXPECT_EQ(field_of("recovery_end", "ok"), std::vector<std::string>{"true"});
}

// Every re-homing fails: after RecoveryOptions::max_attempts attempts the cell stops, naming the last failure.
TEST_F(RobotRehomeTest, AReHomingThatFailsEveryTimeStopsTheCellAfterMaxAttempts) {
  make(joint_arm());
  bring_up();
  send_failing(0, move(K::kAbove, "A"), drivers::ErrorCode::hardware, "*Arm power off*");
  int homes_failed = 1;  // the bring-up's homing
  const std::optional<RobotStatus> s = status_within(20000, [&] {
    // Each new homing fails as it is taken.
    const auto accepted = scripted_->calls().home;
    if (accepted > homes_failed && scripted_->state() == drivers::DriverState::connected) {
      scripted_->drop_connection();
      homes_failed = accepted;
    }
  });
  ASSERT_TRUE(s.has_value()) << "no status: the recovery went round in circles";
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s->stop_cell);
  const int max = MotionOptions{}.recovery.max_attempts;
  EXPECT_THAT(s->reason, HasSubstr(fmt::format("tried {} times", max)));
  EXPECT_THAT(s->reason, HasSubstr("connection_lost"));
  EXPECT_EQ(scripted_->calls().home, 1 + max);
}

// A read-back that fails while the robot waits for its next command is a fault of that robot at once, with the
// driver's message; the driver is brought back before the next command, which is done.
TEST_F(RobotRehomeTest, AFailedIdleReadIsAFaultAtOnceWithItsCause) {
  make(joint_arm());
  bring_up();
  const std::size_t asked = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > asked; }));
  scripted_->fail_command(driver_->requests().back().id, drivers::ErrorCode::hardware, "*Arm power off*");
  const SimDuration failed_at = now_;
  ASSERT_TRUE(turn_until([&] { return !events("fault_detected").empty(); }, 20));
  const auto detected = events("fault_detected");
  EXPECT_EQ(detected[0]["symptom"], "driver_fault");
  EXPECT_EQ(detected[0]["primitive"], -1);  // no command
  EXPECT_THAT(detected[0]["detail"].get<std::string>(), HasSubstr("position read-back failed: hardware: *Arm power off*"));
  EXPECT_LE(now_ - failed_at, test::milliseconds(5));
  EXPECT_EQ(field_of("diagnosis", "action"), std::vector<std::string>{"reset_rehome"});
  // Brought back while idle.
  ASSERT_TRUE(turn_until([&] { return scripted_->state() == drivers::DriverState::active; }));
  EXPECT_EQ(scripted_->calls().home, 2);
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
}

// Without recovery, the same failure fails the robot at once with the driver's message (the run's verdict).
TEST_F(RobotRehomeTest, WithoutRecoveryAFailedIdleReadFailsTheRobotWithItsCause) {
  recovery_ = false;
  make(joint_arm());
  bring_up();
  const std::size_t asked = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > asked; }));
  scripted_->fail_command(driver_->requests().back().id, drivers::ErrorCode::hardware, "*Arm power off*");
  const std::optional<RobotStatus> s = status_within(20);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s->index, RobotStatus::kNoCommand);
  EXPECT_EQ(s->reason, "the position read-back failed: hardware: *Arm power off*");
}

// An error text the driver does not know: its own symptom, and the standard tree stops the cell without moving the arm.
TEST_F(RobotRehomeTest, AnErrorTheDriverDoesNotKnowStopsTheCell) {
  make(joint_arm());
  bring_up();
  send_failing(0, move(K::kAbove, "A"), drivers::ErrorCode::unknown, "*Invalid format*");
  const std::optional<RobotStatus> s = status_within(3000);
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(s->stop_cell);
  EXPECT_THAT(s->reason, HasSubstr("unknown_controller_error"));
  EXPECT_THAT(s->reason, HasSubstr("*Invalid format*"));
  EXPECT_EQ(field_of("fault_detected", "symptom"), std::vector<std::string>{"unknown_error"});
  EXPECT_EQ(field_of("diagnosis", "action"), std::vector<std::string>{"stop_cell"});
  EXPECT_EQ(scripted_->calls().home, 1);
  EXPECT_EQ(scripted_->calls().reset, 0);
}

}  // namespace
}  // namespace cellwright::runtime
