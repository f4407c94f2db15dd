// FaultyDriver wrapping a ScriptedDriver: injected failures look like real ones to the owner (the errors, the states,
// the cancellation of what is behind them), the commands behind a failure never reach the robot, the counters say what
// was injected, and a seed gives the same faults every time.
#include "cellwright/drivers/faulty_driver.hpp"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/scripted_driver.hpp"

namespace cellwright::drivers {
namespace {

using namespace std::chrono_literals;

ScriptedDriverConfig config() {
  ScriptedDriverConfig c;
  Capabilities& caps = c.capabilities;
  caps.joints = 2;
  caps.joint_control = true;
  caps.gripper = true;
  caps.digital_outputs = 2;
  caps.queue_depth = 8;
  caps.reads_joints = true;
  c.home_ticks = 3;
  c.command_ticks = 5;
  c.position_ticks = 1;
  return c;
}

const MoveJoints kMove{{0.1, 0.2}, 1.0};

// Advances the scripted robot until command `id` of the decorator has finished, at most `limit` ticks.
CommandStatus run_until_finished(FaultyDriver& d, ScriptedDriver& robot, CommandId id, int limit = 1000) {
  for (int i = 0; i < limit; ++i) {
    const CommandStatus s = d.poll(id);
    if (s.phase == CommandPhase::done || s.phase == CommandPhase::failed) return s;
    robot.advance();
  }
  return d.poll(id);
}

void bring_up(FaultyDriver& d, ScriptedDriver& robot) {
  ASSERT_EQ(d.connect(), ErrorCode::none);
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted());
  ASSERT_EQ(run_until_finished(d, robot, h.id).phase, CommandPhase::done);
  ASSERT_EQ(d.activate(), ErrorCode::none);
}

FaultPlan nth(std::uint64_t n, ErrorCode error, std::optional<CommandKind> kind = std::nullopt) {
  FaultPlan plan;
  plan.rules.push_back({kind, n, Fault{error, false, {}}});
  return plan;
}

TEST(FaultyDriver, WithoutFaultsItIsTheWrappedDriver) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, {});
  bring_up(d, robot);
  const Submitted a = d.submit(kMove), r = d.request_position();
  EXPECT_EQ(a.id, 2u);
  EXPECT_EQ(r.id, 3u);
  EXPECT_EQ(run_until_finished(d, robot, r.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::done);
  EXPECT_EQ(d.last_position()->request, r.id);
  EXPECT_EQ(d.last_position()->joints, kMove.positions);
  EXPECT_EQ(d.submit(MovePose{}).error, ErrorCode::unsupported);
  EXPECT_EQ(d.injected().failed, 0u);
}

TEST(FaultyDriver, TheNthCommandFailsAndWhatIsBehindItNeverReachesTheRobot) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(2, ErrorCode::unreachable));
  int notified = 0;
  d.set_notifier([&] { ++notified; });
  bring_up(d, robot);
  const int after_homing = notified;
  const Submitted one = d.submit(kMove);
  const Submitted two = d.submit(Grip{});  // chosen: waits for `one`
  const Submitted three = d.submit(MoveJoints{{0.3, 0.3}, 1.0});
  const Submitted four = d.request_position();
  EXPECT_EQ(d.poll(two.id).phase, CommandPhase::pending);
  EXPECT_EQ(d.poll(three.id).phase, CommandPhase::pending);
  EXPECT_EQ(run_until_finished(d, robot, one.id).phase, CommandPhase::done);
  const CommandStatus s2 = d.poll(two.id);
  EXPECT_EQ(s2.phase, CommandPhase::failed);
  EXPECT_EQ(s2.error, ErrorCode::unreachable);
  EXPECT_EQ(s2.message, "injected unreachable");
  for (const CommandId id : {three.id, four.id}) {
    EXPECT_EQ(d.poll(id).error, ErrorCode::cancelled);
    EXPECT_EQ(d.poll(id).message, fmt::format("cancelled: command {} before it failed", two.id));
  }
  EXPECT_EQ(notified, after_homing + 2);  // `one` done (the robot), `two` failed (the decorator)
  EXPECT_EQ(d.state(), DriverState::active);
  // The robot only ever received the first move.
  ASSERT_EQ(robot.accepted().size(), 1u);
  EXPECT_EQ(robot.joints(), kMove.positions);
  EXPECT_EQ(robot.calls().request_position, 0);
  // And the cell goes on.
  const Submitted five = d.submit(kMove);
  EXPECT_EQ(five.id, four.id + 1);
  EXPECT_EQ(run_until_finished(d, robot, five.id).phase, CommandPhase::done);
  EXPECT_EQ(d.injected().failed, 1u);
  EXPECT_EQ(d.injected().by_error.at(ErrorCode::unreachable), 1u);
  EXPECT_EQ(d.injected().cancelled_behind, 2u);
  EXPECT_EQ(d.injected().commands, (std::vector<CommandId>{two.id}));
}

TEST(FaultyDriver, AChosenCommandAtTheHeadFailsAtOnce) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(1, ErrorCode::timeout));
  bring_up(d, robot);
  int notified = 0;
  d.set_notifier([&] { ++notified; });
  const Submitted s = d.submit(kMove);
  ASSERT_TRUE(s.accepted());
  EXPECT_EQ(d.poll(s.id).error, ErrorCode::timeout);
  EXPECT_EQ(notified, 1);
  EXPECT_TRUE(robot.accepted().empty());
}

TEST(FaultyDriver, TheNthCommandOfAKind) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(2, ErrorCode::timeout, CommandKind::grip));
  bring_up(d, robot);
  std::vector<CommandStatus> statuses;
  for (const Command& c : std::vector<Command>{kMove, Grip{}, kMove, Grip{}, kMove}) {
    const Submitted s = d.submit(c);
    ASSERT_TRUE(s.accepted());
    statuses.push_back(run_until_finished(d, robot, s.id));
  }
  EXPECT_EQ(statuses[0].phase, CommandPhase::done);
  EXPECT_EQ(statuses[1].phase, CommandPhase::done);
  EXPECT_EQ(statuses[2].phase, CommandPhase::done);
  EXPECT_EQ(statuses[3].error, ErrorCode::timeout);
  EXPECT_EQ(statuses[4].phase, CommandPhase::done);
  EXPECT_EQ(robot.accepted().size(), 4u);
}

TEST(FaultyDriver, AHardwareErrorIsAFaultUntilResetAndHomedAgain) {
  for (const ErrorCode error : {ErrorCode::hardware, ErrorCode::protocol}) {
    SCOPED_TRACE(to_string(error));
    ScriptedDriver robot(config());
    FaultyDriver d(robot, nth(2, error));
    bring_up(d, robot);
    const Submitted one = d.submit(kMove), a = d.submit(kMove), b = d.submit(kMove);
    EXPECT_EQ(run_until_finished(d, robot, one.id).phase, CommandPhase::done);
    EXPECT_EQ(d.poll(a.id).error, error);
    EXPECT_EQ(d.poll(b.id).error, ErrorCode::cancelled);
    EXPECT_EQ(d.state(), DriverState::fault);
    EXPECT_EQ(d.submit(kMove).error, ErrorCode::wrong_state);
    EXPECT_EQ(d.request_position().error, ErrorCode::wrong_state);
    EXPECT_EQ(d.connect(), ErrorCode::wrong_state);
    EXPECT_EQ(d.reset(), ErrorCode::none);
    EXPECT_EQ(d.state(), DriverState::connected);
    EXPECT_EQ(d.activate(), ErrorCode::wrong_state);  // home first
    const Submitted h = d.home();
    EXPECT_EQ(run_until_finished(d, robot, h.id).phase, CommandPhase::done);
    EXPECT_EQ(d.activate(), ErrorCode::none);
    const Submitted c = d.submit(kMove);
    EXPECT_EQ(run_until_finished(d, robot, c.id).phase, CommandPhase::done);
    EXPECT_EQ(d.injected().by_error.at(error), 1u);
  }
}

TEST(FaultyDriver, ALostLinkFailsEverythingBehindAndNeedsAReconnect) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(2, ErrorCode::connection_lost));
  bring_up(d, robot);
  const Submitted one = d.submit(kMove), a = d.submit(kMove), b = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, robot, one.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(a.id).error, ErrorCode::connection_lost);
  EXPECT_EQ(d.poll(b.id).error, ErrorCode::connection_lost);
  EXPECT_EQ(d.poll(b.id).message, "the link to the controller dropped");
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::disconnected);
  EXPECT_EQ(d.connect(), ErrorCode::none);
  EXPECT_EQ(d.state(), DriverState::connected);
}

TEST(FaultyDriver, ACommandThatNeverCompletesRunsUntilStopped) {
  ScriptedDriver robot(config());
  FaultPlan plan;
  plan.rules.push_back({std::nullopt, 2, Fault{ErrorCode::none, true, {}}});
  FaultyDriver d(robot, plan);
  bring_up(d, robot);
  const Submitted one = d.submit(kMove), stuck = d.submit(kMove), behind = d.submit(Grip{});
  EXPECT_EQ(run_until_finished(d, robot, one.id).phase, CommandPhase::done);
  robot.advance(10000);
  EXPECT_EQ(d.poll(stuck.id).phase, CommandPhase::running);
  EXPECT_EQ(d.poll(behind.id).phase, CommandPhase::pending);
  EXPECT_EQ(d.injected().never_completed, 1u);
  d.stop();
  EXPECT_EQ(d.poll(stuck.id).message, "cancelled by stop()");
  EXPECT_EQ(d.poll(behind.id).message, "cancelled by stop()");
  EXPECT_EQ(d.state(), DriverState::stopped);
  ASSERT_EQ(d.activate(), ErrorCode::none);
  const Submitted next = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, robot, next.id).phase, CommandPhase::done);
  EXPECT_EQ(robot.accepted().size(), 2u);
}

TEST(FaultyDriver, AFaultOfTheRobotEndsACommandThatNeverCompletes) {
  ScriptedDriver robot(config());
  FaultPlan plan;
  plan.rules.push_back({std::nullopt, 1, Fault{ErrorCode::none, true, {}}});
  FaultyDriver d(robot, plan);
  bring_up(d, robot);
  const Submitted stuck = d.submit(kMove);
  robot.drop_connection();
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.poll(stuck.id).phase, CommandPhase::failed);
}

TEST(FaultyDriver, AnEarlierRealFailureCancelsTheChosenCommandToo) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(2, ErrorCode::hardware));
  bring_up(d, robot);
  robot.fail_command(2, ErrorCode::unreachable, "ER 2");  // the robot's own id of the first move
  const Submitted one = d.submit(kMove), two = d.submit(kMove), three = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, robot, one.id).error, ErrorCode::unreachable);
  EXPECT_EQ(d.poll(two.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.poll(three.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.state(), DriverState::active) << "the injection was never made";
  EXPECT_EQ(d.injected().failed, 0u);
  EXPECT_EQ(d.injected().cancelled_behind, 2u);
}

// A protective stop cancels the command in flight; the next command, chosen to never complete, must stall (and be
// detected as a timeout), not be cancelled as if the stopped command had failed in front of it (found by the
// exchange campaign: run 126 of seed 11, an obstacle then a timeout, stopped the cell as a broken controller).
TEST(FaultyDriver, ACommandStoppedEarlierIsNotAFailureInFrontOfTheChosenOne) {
  ScriptedDriver robot(config());
  FaultPlan plan;
  plan.rules.push_back({std::nullopt, 2, Fault{ErrorCode::none, true, {}}});
  FaultyDriver d(robot, plan);
  bring_up(d, robot);
  const Submitted stopped = d.submit(kMove);
  robot.advance();
  d.stop();
  EXPECT_EQ(d.poll(stopped.id).error, ErrorCode::cancelled);
  ASSERT_EQ(d.activate(), ErrorCode::none);
  const Submitted stuck = d.submit(kMove);
  robot.advance(10000);
  EXPECT_EQ(d.poll(stuck.id).phase, CommandPhase::running) << d.poll(stuck.id).message;
  EXPECT_EQ(d.injected().never_completed, 1u);
  EXPECT_EQ(d.injected().cancelled_behind, 0u);
}

TEST(FaultyDriver, RefusedSubmissionsAreNotCounted) {
  ScriptedDriver robot(config());
  FaultyDriver d(robot, nth(2, ErrorCode::timeout));
  bring_up(d, robot);
  const Submitted one = d.submit(kMove);
  EXPECT_EQ(d.submit(MoveJoints{{1.0}, 1.0}).error, ErrorCode::invalid_command);
  const Submitted two = d.submit(kMove);
  EXPECT_EQ(run_until_finished(d, robot, one.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(two.id).error, ErrorCode::timeout);
}

TEST(FaultyDriver, InconsistentPlansAreBugsInTheTest) {
  ScriptedDriver robot(config());
  EXPECT_THROW((FaultyDriver{robot, nth(0, ErrorCode::timeout)}), InternalError);
  EXPECT_THROW((FaultyDriver{robot, nth(1, ErrorCode::cancelled)}), InternalError);
  FaultPlan plan;
  plan.probability = 0.5;
  EXPECT_THROW((FaultyDriver{robot, plan}), InternalError);
}

// Random faults: which commands fail depends on the seed only.
std::vector<CommandId> random_run(std::uint64_t seed, FaultyDriver::Injected* injected) {
  ScriptedDriver robot(config());
  FaultPlan plan;
  plan.probability = 0.1;
  plan.random = {Fault{ErrorCode::unreachable, false, {}}, Fault{ErrorCode::timeout, false, {}}};
  plan.seed = seed;
  FaultyDriver d(robot, plan);
  bring_up(d, robot);
  std::vector<CommandId> failed;
  for (int i = 0; i < 200; ++i) {
    const Submitted s = d.submit(i % 3 == 0 ? Command{Grip{}} : Command{kMove});
    EXPECT_TRUE(s.accepted());
    if (run_until_finished(d, robot, s.id).phase == CommandPhase::failed) failed.push_back(s.id);
  }
  *injected = d.injected();
  return failed;
}

TEST(FaultyDriver, RandomFaultsAreTheSameForTheSameSeed) {
  FaultyDriver::Injected a, b, c;
  const std::vector<CommandId> first = random_run(42, &a);
  const std::vector<CommandId> again = random_run(42, &b);
  const std::vector<CommandId> other = random_run(7, &c);
  EXPECT_EQ(first, again);
  EXPECT_EQ(a.commands, b.commands);
  EXPECT_EQ(a.by_error, b.by_error);
  EXPECT_NE(first, other);
  EXPECT_EQ(first, a.commands);  // one at a time: every failure was an injection
  EXPECT_EQ(a.failed, first.size());
  // About one in ten of 200.
  EXPECT_GE(a.failed, 8u);
  EXPECT_LE(a.failed, 40u);
}

// A rule over a set of kinds counts them together (the scenario's `command: move` counts joint and pose moves), and
// the injection callback is told of the chosen command at once, on the owner's thread.
TEST(FaultyDriver, ASetOfKindsCountsTogetherAndTheCallbackIsToldOfTheChosenCommand) {
  ScriptedDriver robot(config());
  FaultPlan plan;
  plan.kinds_rules.push_back({{CommandKind::move_joints, CommandKind::grip}, 3, Fault{ErrorCode::protocol, false,
                                                                                   "garbage reply"}});
  std::vector<std::pair<CommandId, CommandKind>> told;
  plan.on_injection = [&](CommandId id, const Command& c, const Fault& f) {
    told.emplace_back(id, kind_of(c));
    EXPECT_EQ(f.error, ErrorCode::protocol);
  };
  FaultyDriver d(robot, plan);
  bring_up(d, robot);
  Grip g;
  g.action = Grip::Action::close;
  const Submitted a = d.submit(kMove);
  const Submitted b = d.submit(SetOutput{1, true});  // not counted
  const Submitted c = d.submit(g);
  EXPECT_TRUE(told.empty());
  const Submitted e = d.submit(kMove);  // the third move or grip
  ASSERT_EQ(told.size(), 1u);
  EXPECT_EQ(told[0].first, e.id);
  EXPECT_EQ(told[0].second, CommandKind::move_joints);
  EXPECT_EQ(run_until_finished(d, robot, c.id).phase, CommandPhase::done);
  const CommandStatus failed = run_until_finished(d, robot, e.id);
  EXPECT_EQ(failed.error, ErrorCode::protocol);
  EXPECT_EQ(failed.message, "garbage reply");
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::done);
  EXPECT_EQ(d.state(), DriverState::fault);
}

}  // namespace
}  // namespace cellwright::drivers
