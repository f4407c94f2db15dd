// One robot-control thread's unit (RobotControl) driven directly, turn by turn, as the lock-step runtime would: the
// simulation's turn (the scripted controller runs one tick, the model's clock moves on), then robot control's step().
// The PUMA of the paper's cell sits behind a ScriptedDriver (through ReadbackDriver, which can misreport read-backs);
// what is checked is what a user sees: the RobotStatus, the `sensor` and `command_*` events, and the driver commands.
#include "cellwright/runtime/robot_control.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "controller/runtime/robot_control_fixture.hpp"

namespace cellwright::runtime {
namespace {

using test::close_on;
using test::exchange_motions;
using test::move;
using test::open_from;
using test::RobotControlTest;
using test::to_eigen;
using cellwright::testing::paper_cell;
using std::chrono::milliseconds;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using K = task::TargetKind;

// ---- Bring-up ----

TEST_F(RobotControlTest, BringUpHomesAndActivatesTheDriverAndReportsNothing) {
  make(joint_arm());
  bring_up();
  EXPECT_EQ(scripted_->state(), drivers::DriverState::active);
  EXPECT_EQ(scripted_->calls().home, 1);
  EXPECT_EQ(scripted_->calls().activate, 1);
  EXPECT_FALSE(status().has_value());
  EXPECT_EQ(control_->view().driver, drivers::DriverState::active);
}

TEST_F(RobotControlTest, HomingThatFailsIsReportedWithoutACommand) {
  make(joint_arm());
  scripted_->fail_command(1, drivers::ErrorCode::timeout, "no reference mark found");  // home() is command 1
  const RobotStatus s = next_status();
  EXPECT_EQ(s.index, RobotStatus::kNoCommand);
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "driver of puma could not be brought up: homing failed: timeout: no reference mark found");
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
  // A failed robot takes no further commands.
  send(0, move(K::kHome));
  for (int i = 0; i < 50; ++i) turn();
  EXPECT_EQ(scripted_->calls().submit, 0);
  EXPECT_FALSE(status().has_value());
}

TEST_F(RobotControlTest, ADriverInFaultIsReportedWithoutACommand) {
  make(joint_arm());
  scripted_->drop_connection();
  const RobotStatus s = next_status();
  EXPECT_EQ(s.index, RobotStatus::kNoCommand);
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "driver of puma could not be brought up: the driver is fault");
  EXPECT_EQ(scripted_->calls().home, 0);
}

TEST_F(RobotControlTest, ADriverNeverConnectedIsReportedWithoutACommand) {
  make(joint_arm(), {}, /*connect=*/false);
  const RobotStatus s = next_status();
  EXPECT_EQ(s.index, RobotStatus::kNoCommand);
  EXPECT_EQ(s.reason, "driver of puma could not be brought up: the driver is disconnected");
}

// ---- Moves and the position check ----

TEST_F(RobotControlTest, AMoveIsSentAsJointsAndEndsWhenTheReadBackReachesTheGoal) {
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(s.index, 0u);
  ASSERT_EQ(sent().size(), 1u);
  ASSERT_TRUE(std::holds_alternative<drivers::MoveJoints>(sent()[0]));
  const drivers::MoveJoints mj = std::get<drivers::MoveJoints>(sent()[0]);
  EXPECT_DOUBLE_EQ(mj.speed, MotionOptions{}.speed);
  // The tool goes above A, gripper down.
  const RobotState r = robot();
  const Eigen::Isometry3d tool = r.base() * chain_.forward(to_eigen(mj.positions));
  const Eigen::Vector3d a = part("A").pose.translation();
  EXPECT_NEAR(tool.translation().x(), a.x(), 1e-3);
  EXPECT_NEAR(tool.translation().y(), a.y(), 1e-3);
  EXPECT_GT(tool.translation().z(), a.z());
  EXPECT_LT(tool.linear().col(2).z(), -0.99);
  // The model has the read-back joints.
  EXPECT_EQ(r.joints, mj.positions);
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_reached"});
  const auto starts = events("command_start");
  ASSERT_EQ(starts.size(), 1u);
  EXPECT_EQ(starts[0]["command"], "move above(A)");
  EXPECT_EQ(starts[0]["detail"], drivers::describe(sent()[0]));
  const auto ends = events("command_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_EQ(control_->phase(), RobotPhase::kReady);
}

TEST_F(RobotControlTest, AJointThatStopsShortFailsTheMoveNamingTheJoint) {
  make(joint_arm());
  bring_up();
  driver_->misread_joint(1, 0.05);  // joint 2 reads 0.05 rad from where it was sent
  const RobotStatus s = run(3, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.index, 3u);
  EXPECT_EQ(s.reason, "position not reached: joint 2 is 0.0500 rad from its goal (tolerance 0.0100)");
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_missed"});
  const auto ends = events("command_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);
  EXPECT_EQ(ends[0]["reason"], s.reason);
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
}

TEST_F(RobotControlTest, AJointWithinTheToleranceReachesThePosition) {
  make(joint_arm());
  bring_up();
  driver_->misread_joint(1, 0.8 * MotionOptions{}.position_tolerance);
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_reached"});
}

TEST_F(RobotControlTest, AToolThatStopsShortFailsAPoseMove) {
  make(pose_arm());
  bring_up();
  driver_->misread_tool(Eigen::Vector3d(0, 0, 0.02));
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "position not reached: the tool is 0.0200 m from its goal (tolerance 0.0050)");
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_missed"});
  ASSERT_EQ(sent().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<drivers::MovePose>(sent()[0]));
}

TEST_F(RobotControlTest, ADriverThatReadsNothingBackCannotTellThePosition) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.reads_joints = false;
  make(c);
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_not_sensed"});
}

TEST_F(RobotControlTest, TheMoveIsCheckedOnlyOnAReadAskedForAfterTheDriverSaidDone) {
  make(joint_arm());
  bring_up();
  // Each answer gives the arm where it was when asked: a read asked during the move shows it at its start, far from
  // the goal. Robot control must not take it for the end position.
  driver_->latch_on_request(true);
  send(0, move(K::kAbove, "A"));
  turn();
  ASSERT_EQ(sent().size(), 1u);
  const drivers::CommandId move_id = scripted_->accepted()[0].first;
  const std::uint64_t submitted = scripted_->now_ticks();
  ASSERT_TRUE(turn_until([&] { return scripted_->poll(move_id).phase == drivers::CommandPhase::done; }));
  const std::uint64_t done = scripted_->now_ticks();
  const int requests_at_done = scripted_->calls().request_position;
  // A read was asked during the move (periodically) and is answered only after it.
  const auto& requests = driver_->requests();
  ASSERT_FALSE(requests.empty());
  EXPECT_GE(requests.back().tick, submitted);
  EXPECT_LT(requests.back().tick, done);
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_reached"});
  // It asked again once the driver said done, and ended on that answer.
  EXPECT_GT(scripted_->calls().request_position, requests_at_done);
  EXPECT_GE(driver_->requests().back().tick, done);
  ASSERT_TRUE(scripted_->last_position().has_value());
  EXPECT_EQ(scripted_->last_position()->request, driver_->requests().back().id);
}

// ---- Grip sensors ----

TEST_F(RobotControlTest, ACloseSendsTheGripWithTheCellsForce) {
  make(joint_arm());
  bring_up();
  set_fingers("A");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  ASSERT_EQ(sent().size(), 1u);
  ASSERT_TRUE(std::holds_alternative<drivers::Grip>(sent()[0]));
  const drivers::Grip g = std::get<drivers::Grip>(sent()[0]);
  EXPECT_EQ(g.action, drivers::Grip::Action::close);
  ASSERT_TRUE(g.force.has_value());
  EXPECT_DOUBLE_EQ(*g.force, spec_.grip_force);
  EXPECT_TRUE(scripted_->gripper_closed());
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"gripped"});
  EXPECT_EQ(robot().hold->workpiece, "A");
  EXPECT_EQ(part("A").held_by, "puma");
}

TEST_F(RobotControlTest, ClosingOnTheWrongPartFailsNamingBoth) {
  make(joint_arm());
  bring_up();
  set_fingers("B");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "the gripper closed on B, expected A");
  const auto sensors = events("sensor");
  ASSERT_EQ(sensors.size(), 1u);
  EXPECT_EQ(sensors[0]["condition"], "closed_on_wrong_part");
  EXPECT_EQ(sensors[0]["workpiece"], "B");
  EXPECT_EQ(events("command_end").at(0)["reason"], s.reason);
  EXPECT_FALSE(robot().hold.has_value());
  EXPECT_EQ(part("A").held_by, "");
  EXPECT_EQ(part("B").held_by, "");
}

TEST_F(RobotControlTest, ClosingOnNothingFails) {
  make(joint_arm());
  bring_up();
  set_fingers("");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "the gripper closed on nothing (expected A)");
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"closed_on_nothing"});
  EXPECT_FALSE(robot().hold.has_value());
}

TEST_F(RobotControlTest, AGripNobodySensesIsTakenAsDoneAndTheRobotHoldsThePart) {
  make(joint_arm());
  bring_up();
  set_fingers(std::nullopt);
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  const auto sensors = events("sensor");
  ASSERT_EQ(sensors.size(), 1u);
  EXPECT_EQ(sensors[0]["condition"], "grip_not_sensed");
  EXPECT_EQ(sensors[0]["workpiece"], "A");
  ASSERT_TRUE(robot().hold.has_value());
  EXPECT_EQ(robot().hold->workpiece, "A");
  EXPECT_EQ(part("A").held_by, "puma");
}

TEST_F(RobotControlTest, AnOpenReleasesWhatTheRobotHeld) {
  make(joint_arm());
  bring_up();
  set_fingers("A");
  ASSERT_EQ(run(0, close_on("A")).outcome, CommandOutcome::kDone);
  const RobotStatus s = run(1, open_from("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"gripped", "released"}));
  EXPECT_EQ(events("sensor").back()["workpiece"], "A");
  EXPECT_FALSE(robot().hold.has_value());
  EXPECT_TRUE(robot().released_tcp.has_value());
  EXPECT_EQ(part("A").held_by, "");
  EXPECT_FALSE(scripted_->gripper_closed());
}

// ---- Waiting for a part ----

TEST_F(RobotControlTest, AMoveToAnAbsentPartWaitsForItThenProceeds) {
  make(joint_arm());
  bring_up();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  send(0, move(K::kAbove, "A"));
  for (int i = 0; i < 200; ++i) turn();
  EXPECT_EQ(control_->phase(), RobotPhase::kResolving);
  EXPECT_FALSE(control_->view().detail.empty());
  EXPECT_FALSE(status().has_value());
  EXPECT_EQ(scripted_->calls().submit, 0);
  const auto sensors = events("sensor");
  ASSERT_EQ(sensors.size(), 1u);  // once, not every turn
  EXPECT_EQ(sensors[0]["condition"], "waiting_for_part");
  EXPECT_EQ(sensors[0]["workpiece"], "A");
  EXPECT_EQ(events("command_start").size(), 1u);

  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = true; });
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  ASSERT_EQ(sent().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<drivers::MoveJoints>(sent()[0]));
  // The wait ends with part_ready when the command goes to the driver (the Gantt chart's wait for the part).
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"waiting_for_part", "part_ready", "position_reached"}));
  EXPECT_EQ(events("sensor")[1]["workpiece"], "A");
  EXPECT_EQ(events("command_start").size(), 1u);  // the command started once
}

TEST_F(RobotControlTest, AMoveToAMovingPartWaitsUntilItRests) {
  MotionOptions options;
  make(joint_arm(), options);
  bring_up();
  const double speed = 10 * options.targets.part_at_rest_speed;
  env_.write([&](EnvironmentModel& m) { m.find_workpiece("A")->velocity = Eigen::Vector3d(speed, 0, 0); });
  send(0, move(K::kAt, "A"));
  for (int i = 0; i < 100; ++i) turn();
  EXPECT_EQ(control_->phase(), RobotPhase::kResolving);
  EXPECT_EQ(scripted_->calls().submit, 0);
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"waiting_for_part"});

  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->velocity.setZero(); });
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sent().size(), 1u);
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"waiting_for_part", "part_ready", "position_reached"}));
}

// ---- Inverse kinematics at run time ----

TEST_F(RobotControlTest, ATargetOutOfReachFailsWithoutAnyDriverCommand) {
  make(joint_arm());
  bring_up();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->pose.translation() = Eigen::Vector3d(3.0, 0, 0.5); });
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_THAT(s.reason, StartsWith("above(A): tool at (3.000, 0.000, "));
  EXPECT_THAT(s.reason, HasSubstr(" is unreachable for puma: "));
  EXPECT_EQ(scripted_->calls().submit, 0);
  EXPECT_TRUE(sent().empty());
  const auto ends = events("command_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], false);
  EXPECT_EQ(events("command_start").at(0)["detail"], "");  // nothing was sent
}

// ---- Refusals and a busy driver ----

TEST_F(RobotControlTest, ACloseOnADriverWithoutGripperIsRefused) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.gripper = false;
  c.capabilities.gripper_force = false;
  make(c);
  bring_up();
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_THAT(s.reason, StartsWith("the driver refused 'grip close"));
  EXPECT_THAT(s.reason, HasSubstr("': unsupported: this robot has no gripper"));
  EXPECT_TRUE(sent().empty());
  EXPECT_EQ(events("command_end").at(0)["reason"], s.reason);
}

TEST_F(RobotControlTest, ADriverThatFailsTheCommandFailsIt) {
  make(joint_arm());
  bring_up();
  // The next accepted command is the move (no read is in flight right after bring-up's read is answered).
  send(0, move(K::kAbove, "A"));
  turn();
  ASSERT_EQ(sent().size(), 1u);
  scripted_->fail_command(scripted_->accepted()[0].first, drivers::ErrorCode::unreachable, "ER 2");
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "the driver failed '" + drivers::describe(sent()[0]) + "': unreachable: ER 2");
  EXPECT_TRUE(sensor_conditions().empty());
}

TEST_F(RobotControlTest, ABusyDriverIsAskedAgainNextTurn) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.queue_depth = 1;
  c.position_ticks = 5;
  make(c);
  bring_up();
  // Wait for a periodic read to be asked: it fills the one-deep queue for five ticks.
  const std::size_t reads = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > reads; }));
  send(0, move(K::kAbove, "A"));
  turn();
  EXPECT_EQ(scripted_->calls().submit, 1);
  EXPECT_TRUE(sent().empty());  // refused busy
  EXPECT_FALSE(status().has_value());
  EXPECT_NE(control_->phase(), RobotPhase::kFailed);
  ASSERT_TRUE(turn_until([&] { return !sent().empty(); }, 20));
  EXPECT_GT(scripted_->calls().submit, 1);
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sent().size(), 1u);
  EXPECT_EQ(events("command_start").size(), 1u);
}

// ---- Commands that fit the robot ----

TEST_F(RobotControlTest, APoseOnlyDriverGetsPosesWithStraightApproachAndLift) {
  make(pose_arm());
  bring_up();
  set_fingers(std::nullopt);
  std::vector<task::Primitive> program = {move(K::kAbove, "A"), move(K::kAt, "A"), close_on("A"), move(K::kAbove, "A"),
                                          move(K::kHome)};
  for (std::size_t i = 0; i < program.size(); ++i) {
    const RobotStatus s = run(i, program[i]);
    ASSERT_EQ(s.outcome, CommandOutcome::kDone) << program[i].target.object << ": " << s.reason;
    ASSERT_EQ(s.index, i);
    if (program[i].kind == task::PrimitiveKind::kMove) {
      // The tool pose was checked, and the model's joints are those the pose was solved with.
      const Eigen::Isometry3d pose = std::get<drivers::MovePose>(sent().back()).pose;
      EXPECT_TRUE(chain_.forward(to_eigen(robot().joints)).isApprox(pose, 1e-6)) << task::to_string(program[i]);
      ASSERT_TRUE(robot().tcp.has_value());
      EXPECT_TRUE(robot().tcp->isApprox(robot().base() * pose, 1e-9));
    }
  }
  const std::vector<drivers::Command> cmds = sent();
  ASSERT_EQ(cmds.size(), 5u);
  const auto path = [&](std::size_t i) { return std::get<drivers::MovePose>(cmds.at(i)).path; };
  ASSERT_TRUE(std::holds_alternative<drivers::MovePose>(cmds[0]));
  EXPECT_EQ(path(0), drivers::Path::joint);   // above(A): from home
  EXPECT_EQ(path(1), drivers::Path::linear);  // at(A) after above(A): straight down
  EXPECT_TRUE(std::holds_alternative<drivers::Grip>(cmds[2]));
  EXPECT_EQ(path(3), drivers::Path::linear);  // above(A) after at(A): straight up
  EXPECT_EQ(path(4), drivers::Path::joint);   // home
  EXPECT_TRUE(std::get<drivers::MovePose>(cmds[4]).pose.isApprox(chain_.forward(to_eigen(spec_.home)), 1e-9));
  EXPECT_EQ(sensor_conditions(), (std::vector<std::string>{"position_reached", "position_reached", "grip_not_sensed",
                                                           "position_reached", "position_reached"}));
  EXPECT_EQ(scripted_->calls().submit, 5);
}

TEST_F(RobotControlTest, APoseOnlyDriverWithoutStraightMovesGetsJointPathsOnly) {
  drivers::ScriptedDriverConfig c = pose_arm();
  c.capabilities.linear_motion = false;
  make(c);
  bring_up();
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(run(1, move(K::kAt, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(sent().size(), 2u);
  EXPECT_EQ(std::get<drivers::MovePose>(sent()[1]).path, drivers::Path::joint);
}

TEST_F(RobotControlTest, ADriverThatPrefersPosesGetsPosesEvenWithJointControl) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.cartesian_control = true;
  c.capabilities.prefers_pose = true;
  c.capabilities.reads_pose = true;
  c.home_pose = chain_.forward(to_eigen(spec_.home));
  make(c);
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  ASSERT_EQ(sent().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<drivers::MovePose>(sent()[0]));
}

TEST_F(RobotControlTest, ADriverWithBothThatPrefersJointsGetsJoints) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.cartesian_control = true;
  c.capabilities.linear_motion = true;
  c.capabilities.prefers_pose = false;
  make(c);
  bring_up();
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(run(1, move(K::kAt, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(sent().size(), 2u);
  EXPECT_TRUE(std::holds_alternative<drivers::MoveJoints>(sent()[0]));
  EXPECT_TRUE(std::holds_alternative<drivers::MoveJoints>(sent()[1]));
}

TEST_F(RobotControlTest, HomeGoesStraightToTheHomeJoints) {
  make(joint_arm());
  bring_up();
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(run(1, move(K::kHome)).outcome, CommandOutcome::kDone);
  ASSERT_EQ(sent().size(), 2u);
  EXPECT_EQ(std::get<drivers::MoveJoints>(sent()[1]).positions, spec_.home);
}

// ---- Position reads ----

TEST_F(RobotControlTest, WhileIdleThePositionIsReadEveryPeriod) {
  MotionOptions options;
  options.position_period = milliseconds(10);
  drivers::ScriptedDriverConfig c = joint_arm();
  make(c, options);
  bring_up();
  const std::size_t before = driver_->requests().size();
  for (int i = 0; i < 200; ++i) turn();
  const auto& r = driver_->requests();
  ASSERT_GE(r.size() - before, 2u);
  const auto period_ticks = static_cast<std::uint64_t>(options.position_period / c.tick);
  for (std::size_t i = before + 1; i < r.size(); ++i) {
    const std::uint64_t gap = r[i].tick - r[i - 1].tick;
    EXPECT_GE(gap, period_ticks) << "read " << i;
    EXPECT_LE(gap, period_ticks + c.position_ticks) << "read " << i;
  }
  EXPECT_GE(r.size() - before, 200 / (period_ticks + c.position_ticks));
}

TEST_F(RobotControlTest, AJointReadBackIsWrittenIntoTheModel) {
  make(joint_arm());
  bring_up();
  driver_->misread_joint(0, 0.1);  // as if the arm had been pushed
  const std::size_t before = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > before + 1; }));  // one asked and answered since
  const RobotState r = robot();
  std::vector<double> expected = spec_.home;
  expected[0] += 0.1;
  ASSERT_EQ(r.joints.size(), expected.size());
  for (std::size_t j = 0; j < expected.size(); ++j) EXPECT_NEAR(r.joints[j], expected[j], 1e-12) << j;
  ASSERT_TRUE(r.tcp.has_value());
  EXPECT_TRUE(r.tcp->isApprox(r.base() * chain_.forward(to_eigen(expected)), 1e-9));
}

TEST_F(RobotControlTest, AToolPoseReadBackIsWrittenIntoTheModel) {
  make(pose_arm());
  bring_up();
  driver_->misread_tool(Eigen::Vector3d(0.03, 0, 0));
  const std::size_t before = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > before + 1; }));
  const RobotState r = robot();
  Eigen::Isometry3d expected = chain_.forward(to_eigen(spec_.home));
  expected.translation().x() += 0.03;
  ASSERT_TRUE(r.tcp.has_value());
  EXPECT_TRUE(r.tcp->isApprox(r.base() * expected, 1e-9));
  EXPECT_EQ(r.joints, spec_.home);  // no joint read-back: the joints are the last known
}

TEST_F(RobotControlTest, AReadThatFailsDoesNotFailTheCommand) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.reads_while_moving = true;  // reads are behind nothing: a failed read cancels no command
  make(c);
  bring_up();
  send(0, move(K::kAbove, "A"));
  turn();
  ASSERT_EQ(sent().size(), 1u);
  // Fail the next read asked during the move.
  const std::size_t before = driver_->requests().size();
  ASSERT_TRUE(turn_until([&] { return driver_->requests().size() > before; }));
  const drivers::CommandId read = driver_->requests().back().id;
  scripted_->fail_command(read, drivers::ErrorCode::timeout, "no answer to WH");
  turn();
  ASSERT_EQ(scripted_->poll(read).phase, drivers::CommandPhase::failed);
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"position_reached"});
  EXPECT_GT(driver_->requests().back().id, read);  // it asked again
}

// ---- The paper's program ----

TEST_F(RobotControlTest, R1sPartOfTheExchangeRunsOnAJointArm) {
  make(joint_arm());
  bring_up();
  set_fingers(std::nullopt);  // no grip sensor: closes are taken as done
  const auto motions = exchange_motions("r1");
  ASSERT_EQ(motions.size(), 7u);  // open, above(A), at(A), close A, above(A), handover(r2), open A
  for (const auto& [index, p] : motions) {
    const RobotStatus s = run(index, p);
    ASSERT_EQ(s.outcome, CommandOutcome::kDone) << task::to_string(p) << ": " << s.reason;
    EXPECT_EQ(s.index, index);
    if (p.kind == task::PrimitiveKind::kClose) {
      EXPECT_EQ(part("A").held_by, "puma");
    }
  }
  EXPECT_EQ(part("A").held_by, "");
  const std::vector<drivers::Command> cmds = sent();
  ASSERT_EQ(cmds.size(), motions.size());
  for (std::size_t i = 0; i < motions.size(); ++i) {
    const task::Primitive& p = motions[i].second;
    if (p.kind == task::PrimitiveKind::kMove) {
      EXPECT_TRUE(std::holds_alternative<drivers::MoveJoints>(cmds[i])) << task::to_string(p);
    } else {
      ASSERT_TRUE(std::holds_alternative<drivers::Grip>(cmds[i])) << task::to_string(p);
      EXPECT_EQ(std::get<drivers::Grip>(cmds[i]).action,
                p.kind == task::PrimitiveKind::kClose ? drivers::Grip::Action::close : drivers::Grip::Action::open);
    }
  }
  EXPECT_EQ(sensor_conditions(),
            (std::vector<std::string>{"released", "position_reached", "position_reached", "grip_not_sensed",
                                      "position_reached", "position_reached", "released"}));
  // Each command_start tells the task- and motion-level command it came from, and what was sent.
  const auto starts = events("command_start");
  ASSERT_EQ(starts.size(), motions.size());
  for (std::size_t i = 0; i < motions.size(); ++i) {
    EXPECT_EQ(starts[i]["primitive"], motions[i].first);
    EXPECT_EQ(starts[i]["command"], task::to_string(motions[i].second));
    EXPECT_EQ(starts[i]["task"], motions[i].second.task);
    EXPECT_EQ(starts[i]["motion"], motions[i].second.motion);
    EXPECT_EQ(starts[i]["detail"], drivers::describe(cmds[i]));
  }
}

TEST_F(RobotControlTest, R1sPickOnAPoseOnlyArmGoesStraightDownAndUp) {
  make(pose_arm());
  bring_up();
  set_fingers(std::nullopt);
  std::vector<drivers::Path> paths;
  for (const auto& [index, p] : exchange_motions("r1")) {
    const RobotStatus s = run(index, p);
    ASSERT_EQ(s.outcome, CommandOutcome::kDone) << task::to_string(p) << ": " << s.reason;
    if (p.kind == task::PrimitiveKind::kMove) paths.push_back(std::get<drivers::MovePose>(sent().back()).path);
  }
  // above(A), at(A), above(A), handover(r2).
  using P = drivers::Path;
  EXPECT_EQ(paths, (std::vector<P>{P::joint, P::linear, P::linear, P::joint}));
}

// ---- More of the rules ----

TEST_F(RobotControlTest, WhileWaitingNothingIsSentAndTheLogSaysSo) {
  make(joint_arm());
  bring_up();
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  send(0, move(K::kAbove, "A"));
  for (int i = 0; i < 20; ++i) turn();
  ASSERT_EQ(control_->phase(), RobotPhase::kResolving);
  ASSERT_EQ(scripted_->calls().submit, 0);
  const auto starts = events("command_start");
  ASSERT_EQ(starts.size(), 1u);
  EXPECT_EQ(starts[0]["detail"], "");
}

TEST_F(RobotControlTest, ATargetThatNamesNothingFails) {
  make(joint_arm());
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "Z"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "above(Z): 'Z' is neither a workpiece nor a location of the cell");
  EXPECT_EQ(events("command_end").at(0)["reason"], s.reason);
  EXPECT_TRUE(sent().empty());
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
}

TEST_F(RobotControlTest, ADriverThatTakesNeitherJointsNorPosesFailsAMove) {
  drivers::ScriptedDriverConfig c = joint_arm();
  c.capabilities.joint_control = false;
  make(c);
  bring_up();
  const RobotStatus s = run(0, move(K::kAbove, "A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_EQ(s.reason, "the driver of puma takes neither joint nor pose motions");
  EXPECT_EQ(scripted_->calls().submit, 0);
}

TEST_F(RobotControlTest, MovesGoAtTheConfiguredSpeed) {
  MotionOptions options;
  options.speed = 0.3;
  make(pose_arm(), options);
  bring_up();
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  EXPECT_DOUBLE_EQ(std::get<drivers::MovePose>(sent().at(0)).speed, 0.3);
}

TEST_F(RobotControlTest, TheViewShowsTheCommandBeingExecuted) {
  make(joint_arm());
  bring_up();
  send(4, move(K::kAbove, "A"));
  turn();
  const RobotControlView v = control_->view();
  EXPECT_EQ(v.robot, "r1");
  EXPECT_EQ(v.cell, "puma");
  EXPECT_EQ(v.phase, RobotPhase::kExecuting);
  EXPECT_EQ(v.primitive, std::optional<std::size_t>(4));
  EXPECT_EQ(v.command, "move above(A)");
  ASSERT_EQ(sent().size(), 1u);
  EXPECT_EQ(v.detail, drivers::describe(sent()[0]));
  EXPECT_EQ(v.driver, drivers::DriverState::active);
}

// With await_fresh_truth (real-time mode), a close is checked on grip sensors written after the driver said done.
TEST_F(RobotControlTest, WithFreshTruthACloseIsCheckedOnTheNextModelUpdate) {
  await_fresh_truth_ = true;
  make(joint_arm());
  bring_up();
  set_fingers("");  // the sensors of the steps before the grip finished
  send(0, close_on("A"));
  ASSERT_TRUE(turn_until([&] { return scripted_->gripper_closed(); }));  // done in this turn, model not newer
  EXPECT_FALSE(status().has_value());
  set_fingers("A");  // the simulation writes the step's truth
  const RobotStatus s = next_status();
  EXPECT_EQ(s.outcome, CommandOutcome::kDone) << s.reason;
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"gripped"});
}

TEST_F(RobotControlTest, InLockStepACloseIsCheckedOnTheModelOfItsTurn) {
  make(joint_arm());
  bring_up();
  set_fingers("");
  send(0, close_on("A"));
  ASSERT_TRUE(turn_until([&] { return scripted_->gripper_closed(); }));
  const std::optional<RobotStatus> s = status();
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->outcome, CommandOutcome::kFailed);
  EXPECT_EQ(sensor_conditions(), std::vector<std::string>{"closed_on_nothing"});
}

TEST_F(RobotControlTest, AHeldPartMovesWithTheHandWhenNothingMeasuresIt) {
  MotionOptions options;
  options.track_held_parts = true;
  make(joint_arm(), options);
  bring_up();
  set_fingers(std::nullopt);
  ASSERT_EQ(run(0, move(K::kAbove, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(run(1, move(K::kAt, "A")).outcome, CommandOutcome::kDone);
  ASSERT_EQ(run(2, close_on("A")).outcome, CommandOutcome::kDone);
  const Eigen::Vector3d picked = part("A").pose.translation();
  ASSERT_EQ(run(3, move(K::kHome)).outcome, CommandOutcome::kDone);
  for (int i = 0; i < 20; ++i) turn();  // a read-back at home, then a turn that tracks it
  const RobotState r = robot();
  ASSERT_TRUE(r.hold.has_value() && r.tcp.has_value());
  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.pose.isApprox(*r.tcp * r.hold->in_hand, 1e-9));
  EXPECT_GT((a.pose.translation() - picked).norm(), 0.05);
}

// ---- Failures injected by the FaultyDriver ----

TEST_F(RobotControlTest, AGripThatFailsWithAHardwareErrorFailsTheClose) {
  drivers::FaultPlan plan;
  plan.rules.push_back({drivers::CommandKind::grip, 1, {drivers::ErrorCode::hardware, false, "gripper motor stalled"}});
  faults_ = plan;
  make(joint_arm());
  bring_up();
  set_fingers("A");
  const RobotStatus s = run(2, close_on("A"));
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_THAT(s.reason, StartsWith("the driver failed 'grip close"));
  EXPECT_THAT(s.reason, HasSubstr("': hardware: gripper motor stalled"));
  EXPECT_TRUE(sensor_conditions().empty());  // the grip sensors are not asked
  EXPECT_EQ(faulty_->state(), drivers::DriverState::fault);
  EXPECT_EQ(control_->phase(), RobotPhase::kFailed);
  EXPECT_FALSE(robot().hold.has_value());
}

TEST_F(RobotControlTest, AMoveThatNeverEndsStaysExecutingUntilHalted) {
  drivers::FaultPlan plan;
  plan.rules.push_back({drivers::CommandKind::move_joints, 1, {drivers::ErrorCode::timeout, true, ""}});
  faults_ = plan;
  make(joint_arm());
  bring_up();
  send(0, move(K::kAbove, "A"));
  for (int i = 0; i < 1000; ++i) turn();
  EXPECT_EQ(control_->phase(), RobotPhase::kExecuting);
  EXPECT_FALSE(status().has_value());
  control_->halt();
  EXPECT_EQ(faulty_->state(), drivers::DriverState::stopped);
  const RobotStatus s = next_status(5);
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_THAT(s.reason, HasSubstr(": cancelled: "));
}

}  // namespace
}  // namespace cellwright::runtime
