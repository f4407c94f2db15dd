#include "cellwright/drivers/scripted_driver.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace cellwright::drivers {
namespace {

using namespace std::chrono_literals;

ScriptedDriverConfig config() {
  ScriptedDriverConfig c;
  c.where = {"cell.yaml", 12, 9};
  Capabilities& caps = c.capabilities;
  caps.joints = 6;
  caps.joint_control = caps.cartesian_control = caps.linear_motion = caps.full_orientation = true;
  caps.gripper = caps.gripper_width = caps.gripper_force = true;
  caps.gripper_max_width = 0.08;
  caps.gripper_max_force = 40.0;
  caps.digital_outputs = 4;
  caps.digital_inputs = 4;
  caps.queue_depth = 4;
  caps.reads_joints = caps.reads_pose = true;
  c.tick = 1ms;
  c.home_ticks = 10;
  c.position_ticks = 1;
  c.command_ticks = 5;
  c.home_joints = {0, -0.5, 0.5, 0, 0, 0};
  return c;
}

const MoveJoints kMove{{0.1, 0.2, 0.3, 0.4, 0.5, 0.6}, 0.5};

// Runs the driver until command `id` is no longer pending or running, at most `limit` ticks.
CommandStatus run_until_finished(ScriptedDriver& d, CommandId id, int limit = 1000) {
  for (int i = 0; i < limit; ++i) {
    const CommandStatus s = d.poll(id);
    if (s.phase == CommandPhase::done || s.phase == CommandPhase::failed) return s;
    d.advance();
  }
  return d.poll(id);
}

// Brings a fresh driver into `state` through the public interface only.
void bring_to(ScriptedDriver& d, DriverState state) {
  if (state == DriverState::disconnected) return;
  ASSERT_EQ(d.connect(), ErrorCode::none);
  if (state == DriverState::connected) return;
  if (state == DriverState::fault) {
    d.drop_connection();
    d.connect();  // refused: still in fault
    ASSERT_EQ(d.state(), DriverState::fault);
    return;
  }
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted());
  ASSERT_EQ(run_until_finished(d, h.id).phase, CommandPhase::done);
  if (state == DriverState::homed) return;
  ASSERT_EQ(d.activate(), ErrorCode::none);
  if (state == DriverState::active) return;
  d.stop();
  ASSERT_EQ(d.state(), DriverState::stopped);
}

// The table in robot_driver.hpp, row by row: for each state, which calls are allowed. A fresh driver per cell.
TEST(ScriptedDriverLifecycle, FollowsTheStateTableOfTheInterface) {
  using S = DriverState;
  const std::vector<S> states = {S::disconnected, S::connected, S::homed, S::active, S::stopped, S::fault};
  struct Call {
    std::string name;
    std::function<bool(ScriptedDriver&)> allowed;  // true when accepted, false when refused with wrong_state
    std::set<S> allowed_in;
  };
  auto code_call = [](std::function<ErrorCode(ScriptedDriver&)> f) {
    return [f](ScriptedDriver& d) {
      const ErrorCode e = f(d);
      EXPECT_TRUE(e == ErrorCode::none || e == ErrorCode::wrong_state || e == ErrorCode::connection_lost)
          << to_string(e);
      return e != ErrorCode::wrong_state;
    };
  };
  auto submit_call = [](std::function<Submitted(ScriptedDriver&)> f) {
    return [f](ScriptedDriver& d) {
      const Submitted s = f(d);
      EXPECT_TRUE(s.accepted() || s.error == ErrorCode::wrong_state) << to_string(s.error);
      EXPECT_EQ(s.accepted(), s.id != 0);
      return s.accepted();
    };
  };
  const std::vector<Call> calls = {
      {"connect", code_call([](ScriptedDriver& d) { return d.connect(); }), {S::disconnected}},
      {"home", submit_call([](ScriptedDriver& d) { return d.home(); }), {S::connected, S::homed, S::stopped}},
      {"activate", code_call([](ScriptedDriver& d) { return d.activate(); }), {S::homed, S::stopped}},
      {"submit", submit_call([](ScriptedDriver& d) { return d.submit(kMove); }), {S::active}},
      {"request_position",
       submit_call([](ScriptedDriver& d) { return d.request_position(); }),
       {S::connected, S::homed, S::active, S::stopped}},
      {"reset", code_call([](ScriptedDriver& d) { return d.reset(); }), {S::fault}},
  };
  for (const S state : states) {
    for (const Call& call : calls) {
      SCOPED_TRACE(std::string(to_string(state)) + " " + call.name);
      ScriptedDriver d(config());
      bring_to(d, state);
      ASSERT_EQ(d.state(), state);
      const bool allowed = call.allowed(d);
      EXPECT_EQ(allowed, call.allowed_in.contains(state));
      if (!allowed) {
        EXPECT_EQ(d.state(), state) << "a refused call changed the state";
      }
    }
  }
}

TEST(ScriptedDriverLifecycle, StopAndDisconnectWorkInEveryState) {
  using S = DriverState;
  for (const S state : {S::disconnected, S::connected, S::homed, S::active, S::stopped, S::fault}) {
    SCOPED_TRACE(to_string(state));
    ScriptedDriver d(config());
    bring_to(d, state);
    d.stop();
    EXPECT_EQ(d.state(), state == S::active ? S::stopped : state);
    d.disconnect();
    EXPECT_EQ(d.state(), S::disconnected);
  }
}

TEST(ScriptedDriverLifecycle, RefusalsSayWhy) {
  ScriptedDriver d(config());
  const Submitted s = d.submit(kMove);
  EXPECT_EQ(s.error, ErrorCode::wrong_state);
  EXPECT_EQ(s.id, 0u);
  EXPECT_EQ(s.message,
            "move_joints [0.100000, 0.200000, 0.300000, 0.400000, 0.500000, 0.600000] speed 0.500000 "
            "refused: the driver is disconnected, not active");
  EXPECT_EQ(d.home().message, "home() is not allowed while disconnected");
  EXPECT_TRUE(d.accepted().empty());
}

TEST(ScriptedDriverLifecycle, HomingCompletesThroughPollAndThenTheRobotIsHomed) {
  ScriptedDriver d(config());
  ASSERT_EQ(d.connect(), ErrorCode::none);
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted());
  EXPECT_EQ(h.id, 1u);
  EXPECT_EQ(d.poll(h.id).phase, CommandPhase::running);
  d.advance(9);
  EXPECT_EQ(d.poll(h.id).phase, CommandPhase::running);
  EXPECT_EQ(d.state(), DriverState::connected);
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);
  d.advance(1);
  EXPECT_EQ(d.poll(h.id).phase, CommandPhase::done);
  EXPECT_EQ(d.state(), DriverState::homed);
  EXPECT_EQ(d.joints(), config().home_joints);
}

TEST(ScriptedDriverLifecycle, ActivateWaitsForAHomingInFlight) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::stopped);
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted());
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);
  EXPECT_EQ(run_until_finished(d, h.id).phase, CommandPhase::done);
  EXPECT_EQ(d.state(), DriverState::homed);
  EXPECT_EQ(d.activate(), ErrorCode::none);
}

TEST(ScriptedDriverCommands, RunOneAfterAnotherInTheOrderSubmitted) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const Eigen::Isometry3d target =
      Eigen::Translation3d(0.3, 0.1, 0.2) * Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ());
  const Submitted a = d.submit(kMove);
  const Submitted b = d.submit(MovePose{target, Path::linear, 1.0});
  const Submitted c = d.submit(Grip{Grip::Action::close, 0.02, 10.0});
  ASSERT_TRUE(a.accepted() && b.accepted() && c.accepted());
  EXPECT_LT(a.id, b.id);
  EXPECT_LT(b.id, c.id);
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::running);
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::pending);
  EXPECT_EQ(d.poll(c.id).phase, CommandPhase::pending);
  d.advance(4);
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::running);
  d.advance(1);
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::done);
  EXPECT_EQ(d.joints(), kMove.positions);
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::running);
  EXPECT_EQ(d.poll(c.id).phase, CommandPhase::pending);
  d.advance(5);
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::done);
  EXPECT_TRUE(d.tool_pose().isApprox(target));
  EXPECT_FALSE(d.gripper_closed());
  d.advance(5);
  EXPECT_EQ(d.poll(c.id).phase, CommandPhase::done);
  EXPECT_TRUE(d.gripper_closed());
  const auto acc = d.accepted();
  ASSERT_EQ(acc.size(), 3u);
  EXPECT_EQ(acc[0].first, a.id);
  EXPECT_EQ(describe(acc[1].second), describe(MovePose{target, Path::linear, 1.0}));
  EXPECT_EQ(acc[2].first, c.id);
}

TEST(ScriptedDriverCommands, DurationsCanBeSetPerCommand) {
  ScriptedDriverConfig cfg = config();
  cfg.ticks_for = [](const Command& c) -> std::uint64_t { return std::holds_alternative<Grip>(c) ? 2 : 7; };
  ScriptedDriver d(cfg);
  bring_to(d, DriverState::active);
  const std::uint64_t start = d.now_ticks();
  const Submitted grip = d.submit(Grip{});
  const Submitted move = d.submit(kMove);
  ASSERT_EQ(run_until_finished(d, grip.id).phase, CommandPhase::done);
  EXPECT_EQ(d.now_ticks() - start, 2u);
  ASSERT_EQ(run_until_finished(d, move.id).phase, CommandPhase::done);
  EXPECT_EQ(d.now_ticks() - start, 9u);
}

TEST(ScriptedDriverCommands, MoreThanTheQueueDepthIsRefusedAsBusy) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(d.submit(kMove).accepted());
  const Submitted s = d.submit(kMove);
  EXPECT_EQ(s.error, ErrorCode::busy);
  EXPECT_EQ(s.message, "4 command(s) already in flight (queue depth 4)");
  d.advance(5);  // one done: room again
  EXPECT_TRUE(d.submit(kMove).accepted());
}

TEST(ScriptedDriverCommands, InvalidCommandsAreRefusedWithoutAnId) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const Submitted s = d.submit(MoveJoints{{0, 0}, 1.0});
  EXPECT_EQ(s.error, ErrorCode::invalid_command);
  EXPECT_EQ(s.id, 0u);
  EXPECT_EQ(s.message, "2 joint positions given, the robot has 6 joints");
  EXPECT_TRUE(d.accepted().empty());
  EXPECT_EQ(d.poll(0).error, ErrorCode::unknown_command);
}

TEST(ScriptedDriverCommands, OutputsAndInputs) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const Submitted set = d.submit(SetOutput{2, true});
  EXPECT_FALSE(d.output(2));
  ASSERT_EQ(run_until_finished(d, set.id).phase, CommandPhase::done);
  EXPECT_TRUE(d.output(2));
  EXPECT_FALSE(d.output(1));

  // A wait holds back the commands behind it until its input comes on.
  const Submitted wait = d.submit(WaitInput{3, true, {}});
  const Submitted after = d.submit(kMove);
  d.advance(100);
  EXPECT_EQ(d.poll(wait.id).phase, CommandPhase::running);
  EXPECT_EQ(d.poll(after.id).phase, CommandPhase::pending);
  d.set_input(3, true);
  d.advance(1);
  EXPECT_EQ(d.poll(wait.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(after.id).phase, CommandPhase::running);
}

TEST(ScriptedDriverFaults, AnInjectedFailureHitsAWaitForInputToo) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  d.fail_command(2, ErrorCode::protocol, "reply 'SIG?' not understood");
  const Submitted wait = d.submit(WaitInput{1, true, {}});
  d.set_input(1, true);
  const CommandStatus s = run_until_finished(d, wait.id);
  EXPECT_EQ(s.error, ErrorCode::protocol);
  EXPECT_EQ(d.state(), DriverState::fault);
}

TEST(ScriptedDriverCommands, AWaitForInputTimesOut) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const Submitted wait = d.submit(WaitInput{1, true, 5ms});
  const Submitted after = d.submit(kMove);
  d.advance(4);
  EXPECT_EQ(d.poll(wait.id).phase, CommandPhase::running);
  d.advance(1);
  const CommandStatus s = d.poll(wait.id);
  EXPECT_EQ(s.phase, CommandPhase::failed);
  EXPECT_EQ(s.error, ErrorCode::timeout);
  EXPECT_EQ(s.message, "digital input 1 stayed off for 5000000 ns");
  EXPECT_EQ(d.poll(after.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.state(), DriverState::active);  // a timeout is not a fault
}

TEST(ScriptedDriverCommands, PositionReadBackArrivesLaterStampedWithVirtualTime) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  EXPECT_FALSE(d.last_position().has_value());
  const Submitted move = d.submit(kMove);
  const Submitted ask = d.request_position();  // queued behind the move, as on a serial controller
  ASSERT_TRUE(ask.accepted());
  d.advance(5);
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::done);
  EXPECT_FALSE(d.last_position().has_value());
  d.advance(1);
  EXPECT_EQ(d.poll(ask.id).phase, CommandPhase::done);
  const auto reading = d.last_position();
  ASSERT_TRUE(reading.has_value());
  EXPECT_EQ(reading->request, ask.id);
  EXPECT_EQ(reading->stamp, std::chrono::milliseconds(d.now_ticks()));
  EXPECT_EQ(reading->joints, kMove.positions);
  ASSERT_TRUE(reading->tool_pose.has_value());
}

// A robot that can read its position while moving (capabilities.reads_while_moving) answers after position_ticks even
// while a command runs; the ids keep their order, the read finishes first.
TEST(ScriptedDriverCommands, WithReadsWhileMovingARequestDoesNotWaitForTheMotion) {
  ScriptedDriverConfig cfg = config();
  cfg.capabilities.reads_while_moving = true;
  cfg.position_ticks = 2;
  ScriptedDriver d(cfg);
  bring_to(d, DriverState::active);
  const Submitted move = d.submit(kMove);
  d.advance(1);
  const Submitted ask = d.request_position();
  const Submitted grip = d.submit(Grip{});
  EXPECT_LT(move.id, ask.id);
  EXPECT_LT(ask.id, grip.id);
  d.advance(1);
  EXPECT_EQ(d.poll(ask.id).phase, CommandPhase::running);
  d.advance(1);
  EXPECT_EQ(d.poll(ask.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::running);
  const auto reading = d.last_position();
  ASSERT_TRUE(reading.has_value());
  EXPECT_EQ(reading->request, ask.id);
  EXPECT_EQ(reading->stamp, std::chrono::milliseconds(d.now_ticks()));
  EXPECT_EQ(reading->joints, config().home_joints);  // the move has not finished: the robot is still at home
  EXPECT_EQ(run_until_finished(d, grip.id).phase, CommandPhase::done);
  // Without the capability the same request waits for the move (see PositionReadBackArrivesLater...).
}

TEST(ScriptedDriverCommands, WithReadsWhileMovingAFailedCommandDoesNotCancelARead) {
  ScriptedDriverConfig cfg = config();
  cfg.capabilities.reads_while_moving = true;
  cfg.position_ticks = 3;
  ScriptedDriver d(cfg);
  bring_to(d, DriverState::active);
  d.fail_command(2, ErrorCode::unreachable, "ER 2");
  const Submitted move = d.submit(kMove);
  const Submitted ask = d.request_position();
  const Submitted behind = d.submit(kMove);
  d.advance(3);
  EXPECT_EQ(d.poll(ask.id).phase, CommandPhase::done);
  d.advance(2);
  EXPECT_EQ(d.poll(move.id).error, ErrorCode::unreachable);
  EXPECT_EQ(d.poll(behind.id).error, ErrorCode::cancelled);
  const Submitted late = d.request_position();
  d.stop();
  EXPECT_EQ(d.poll(late.id).message, "cancelled by stop()");
}

// The runtime gives the driver its clock: readings are stamped with it instead of the virtual ticks.
TEST(ScriptedDriverCommands, ReadingsAreStampedOnTheClockGivenToTheDriver) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::homed);
  std::chrono::nanoseconds runtime_clock = 5s;
  d.set_clock([&] { return runtime_clock; });
  const Submitted ask = d.request_position();
  runtime_clock = 6s;  // the reading is taken when the controller answers, not when it was asked
  ASSERT_EQ(run_until_finished(d, ask.id).phase, CommandPhase::done);
  EXPECT_EQ(d.last_position()->stamp, 6s);
  d.set_clock({});
  const Submitted again = d.request_position();
  ASSERT_EQ(run_until_finished(d, again.id).phase, CommandPhase::done);
  EXPECT_EQ(d.last_position()->stamp, std::chrono::milliseconds(d.now_ticks()));
}

TEST(ScriptedDriverCommands, ReadBackReportsOnlyWhatTheControllerCan) {
  ScriptedDriverConfig cfg = config();
  cfg.capabilities.reads_joints = false;  // Movemaster `WH`: a pose, no joints
  ScriptedDriver d(cfg);
  bring_to(d, DriverState::homed);
  const Submitted ask = d.request_position();
  ASSERT_EQ(run_until_finished(d, ask.id).phase, CommandPhase::done);
  EXPECT_TRUE(d.last_position()->joints.empty());
  EXPECT_TRUE(d.last_position()->tool_pose.has_value());
}

TEST(ScriptedDriverCommands, TheNotifierIsCalledWhenSomethingFinishes) {
  ScriptedDriver d(config());
  int notified = 0;
  d.set_notifier([&] { ++notified; });
  bring_to(d, DriverState::active);
  const int after_homing = notified;
  EXPECT_EQ(after_homing, 1);
  d.submit(kMove);
  d.advance(4);
  EXPECT_EQ(notified, after_homing);  // running, not finished: nothing to tell
  d.advance(1);
  EXPECT_EQ(notified, after_homing + 1);
  d.advance(10);  // idle
  EXPECT_EQ(notified, after_homing + 1);
  d.submit(kMove);
  d.stop();  // cancelling counts
  EXPECT_EQ(notified, after_homing + 2);
  d.set_notifier({});
  d.drop_connection();
  EXPECT_EQ(notified, after_homing + 2);
}

TEST(ScriptedDriverCommands, UnknownIdsAndOldIdsPollAsUnknown) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const CommandStatus never = d.poll(999);
  EXPECT_EQ(never.phase, CommandPhase::failed);
  EXPECT_EQ(never.error, ErrorCode::unknown_command);
  EXPECT_EQ(never.message, "command 999 was never issued or is no longer retained");
  CommandId first = 0;
  CommandId last = 0;
  for (std::size_t i = 0; i < kStatusRetention + 10; ++i) {
    const Submitted s = d.submit(SetOutput{1, i % 2 == 0});
    ASSERT_TRUE(s.accepted());
    if (first == 0) first = s.id;
    last = s.id;
    d.advance(5);
  }
  EXPECT_EQ(d.poll(first).error, ErrorCode::unknown_command);
  EXPECT_EQ(d.poll(last).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(last - kStatusRetention + 1).phase, CommandPhase::done);
}

TEST(ScriptedDriverCommands, EveryCallIsCounted) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  d.submit(kMove);
  d.submit(MoveJoints{});  // refused, still a call
  d.poll(1);
  d.poll(2);
  d.last_position();
  d.request_position();
  const ScriptedDriver::Calls c = d.calls();
  EXPECT_EQ(c.connect, 1);
  EXPECT_EQ(c.home, 1);
  EXPECT_EQ(c.activate, 1);
  EXPECT_EQ(c.submit, 2);
  EXPECT_EQ(c.request_position, 1);
  EXPECT_EQ(c.last_position, 1);
  EXPECT_GE(c.poll, 2);  // bring_to polled the homing too
  EXPECT_EQ(c.stop, 0);
  EXPECT_EQ(c.reset, 0);
  EXPECT_EQ(c.disconnect, 0);
}

TEST(ScriptedDriverFaults, TheNthCommandFailsWithTheInjectedErrorAndCancelsTheRest) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);  // homing was command 1
  d.fail_command(3, ErrorCode::unreachable, "MP 400,0,900,0,0: position error (ER 2)");
  const Submitted two = d.submit(kMove);
  const Submitted three = d.submit(kMove);
  const Submitted four = d.submit(Grip{});
  ASSERT_EQ(three.id, 3u);
  EXPECT_EQ(run_until_finished(d, two.id).phase, CommandPhase::done);
  const CommandStatus s3 = run_until_finished(d, three.id);
  EXPECT_EQ(s3.phase, CommandPhase::failed);
  EXPECT_EQ(s3.error, ErrorCode::unreachable);
  EXPECT_EQ(s3.message, "MP 400,0,900,0,0: position error (ER 2)");
  const CommandStatus s4 = d.poll(four.id);
  EXPECT_EQ(s4.error, ErrorCode::cancelled);
  EXPECT_EQ(s4.message, "cancelled: command 3 before it failed");
  EXPECT_EQ(d.state(), DriverState::active);  // an unreachable target is not a fault
  const Submitted five = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, five.id).phase, CommandPhase::done);
}

TEST(ScriptedDriverFaults, AHardwareErrorPutsTheDriverInFaultUntilResetAndHomedAgain) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  d.fail_command(2, ErrorCode::hardware, "ER 1: hardware error");
  const Submitted move = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, move.id).error, ErrorCode::hardware);
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.submit(kMove).error, ErrorCode::wrong_state);
  EXPECT_EQ(d.request_position().error, ErrorCode::wrong_state);
  EXPECT_EQ(d.reset(), ErrorCode::none);
  EXPECT_EQ(d.state(), DriverState::connected);
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);  // must home first
  const Submitted h = d.home();
  EXPECT_EQ(run_until_finished(d, h.id).phase, CommandPhase::done);
  EXPECT_EQ(d.activate(), ErrorCode::none);
}

TEST(ScriptedDriverFaults, ADroppedLinkFailsEverythingInFlightAndNeedsAReconnect) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  int notified = 0;
  d.set_notifier([&] { ++notified; });
  const Submitted a = d.submit(kMove);
  const Submitted b = d.submit(kMove);
  d.advance(2);
  d.drop_connection();
  EXPECT_EQ(notified, 1);
  for (const CommandId id : {a.id, b.id}) {
    EXPECT_EQ(d.poll(id).phase, CommandPhase::failed);
    EXPECT_EQ(d.poll(id).error, ErrorCode::connection_lost);
  }
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.connect(), ErrorCode::wrong_state);
  EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::disconnected);
  EXPECT_EQ(d.connect(), ErrorCode::none);
  EXPECT_EQ(d.state(), DriverState::connected);
}

TEST(ScriptedDriverFaults, ALinkLostDuringACommandIsAFaultToo) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  d.fail_command(2, ErrorCode::connection_lost, "no reply to ER within 2 s");
  const Submitted a = d.submit(kMove);
  const Submitted b = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, a.id).message, "no reply to ER within 2 s");
  EXPECT_EQ(d.poll(b.id).error, ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
}

TEST(ScriptedDriverFaults, ACommandThatNeverCompletesRunsUntilStopped) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  d.never_complete(2);
  const Submitted stuck = d.submit(kMove);
  d.advance(10000);
  EXPECT_EQ(d.poll(stuck.id).phase, CommandPhase::running);
  d.stop();
  const CommandStatus s = d.poll(stuck.id);
  EXPECT_EQ(s.error, ErrorCode::cancelled);
  EXPECT_EQ(s.message, "cancelled by stop()");
  EXPECT_EQ(d.state(), DriverState::stopped);
  EXPECT_EQ(d.activate(), ErrorCode::none);
  const Submitted next = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, next.id).phase, CommandPhase::done);
}

TEST(ScriptedDriverFaults, DisconnectCancelsWhatIsInFlight) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  const Submitted a = d.submit(kMove);
  d.disconnect();
  EXPECT_EQ(d.poll(a.id).message, "cancelled by disconnect()");
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

TEST(ScriptedDriverFaults, AMissingPortIsAnInputErrorNamingTheConfiguration) {
  ScriptedDriver d(config());
  d.refuse_connect("robot 'rv': serial port /dev/ttyUSB3 does not exist");
  try {
    d.connect();
    FAIL() << "connect() did not throw";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "cell.yaml:12:9: error: robot 'rv': serial port /dev/ttyUSB3 does not exist");
  }
  EXPECT_EQ(d.state(), DriverState::disconnected);
  d.refuse_connect("");
  EXPECT_EQ(d.connect(), ErrorCode::none);
}

TEST(ScriptedDriverFaults, OnlyErrorsAControllerReportsCanBeInjected) {
  ScriptedDriver d(config());
  EXPECT_THROW(d.fail_command(1, ErrorCode::none, ""), InternalError);
  EXPECT_THROW(d.fail_command(1, ErrorCode::wrong_state, ""), InternalError);
  EXPECT_THROW(d.fail_command(1, ErrorCode::cancelled, ""), InternalError);
}

TEST(ScriptedDriverSetup, InconsistentConfigurationsAreBugsInTheTest) {
  ScriptedDriverConfig zero = config();
  zero.command_ticks = 0;
  EXPECT_THROW(ScriptedDriver{zero}, InternalError);
  ScriptedDriverConfig joints = config();
  joints.home_joints = {0, 0};
  EXPECT_THROW(ScriptedDriver{joints}, InternalError);
  ScriptedDriverConfig depth = config();
  depth.capabilities.queue_depth = 0;
  EXPECT_THROW(ScriptedDriver{depth}, InternalError);
}

// The way the runtime will use it: the owner thread submits and sleeps until notified, while another thread (the
// simulation) advances the controller. Every command completes, in order, and nothing is reported twice.
TEST(ScriptedDriverThreads, AnOwnerWaitsOnTheNotifierWhileAnotherThreadAdvances) {
  ScriptedDriver d(config());
  bring_to(d, DriverState::active);
  std::mutex m;
  std::condition_variable cv;
  std::uint64_t wakeups = 0;
  d.set_notifier([&] {
    {
      std::lock_guard lock(m);
      ++wakeups;
    }
    cv.notify_one();
  });
  std::atomic<bool> done{false};
  std::thread simulation([&] {
    while (!done) {
      d.advance(1);
      std::this_thread::yield();
    }
  });
  std::vector<CommandId> finished;
  for (int i = 0; i < 50; ++i) {
    const Submitted s = d.submit(MoveJoints{{0.01 * i, 0, 0, 0, 0, 0}, 1.0});
    ASSERT_TRUE(s.accepted());
    std::unique_lock lock(m);
    std::uint64_t seen = wakeups;
    while (d.poll(s.id).phase != CommandPhase::done) {
      cv.wait(lock, [&] { return wakeups != seen; });
      seen = wakeups;
    }
    finished.push_back(s.id);
  }
  done = true;
  simulation.join();
  ASSERT_EQ(finished.size(), 50u);
  for (std::size_t i = 1; i < finished.size(); ++i) EXPECT_EQ(finished[i], finished[i - 1] + 1);
  EXPECT_EQ(d.joints()[0], 0.01 * 49);
}

}  // namespace
}  // namespace cellwright::drivers
