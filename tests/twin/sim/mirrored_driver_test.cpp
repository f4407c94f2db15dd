// MirroredDriver: a real robot's driver (here a ScriptedDriver claiming a Movemaster's or a VAL II controller's
// capabilities) with the robot's copy in the twin (another ScriptedDriver, reading joints) following it. Both
// controllers are advanced by the test, one tick per control cycle, and the mirror is looked at once per cycle as the
// robot-control thread would. The tests check what a user of the twin sees: the real driver's answers unchanged, the
// copy moving with the real robot, real commands held until the copy has caught up, corrections from fresh read-backs
// only, and a copy that never holds back or fails the real robot.
#include "cellwright/twin/sim/mirrored_driver.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::twin::sim {
namespace {

using namespace std::chrono_literals;
using drivers::Capabilities;
using drivers::Command;
using drivers::CommandId;
using drivers::CommandPhase;
using drivers::CommandStatus;
using drivers::DriverState;
using drivers::ErrorCode;
using drivers::Grip;
using drivers::MoveJoints;
using drivers::MovePose;
using drivers::Path;
using drivers::ScriptedDriver;
using drivers::ScriptedDriverConfig;
using drivers::SetOutput;
using drivers::Submitted;
using drivers::WaitInput;

const models::KinematicChain& puma() {
  static const models::KinematicChain chain =
      models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + "/urdf/puma560.urdf");
  return chain;
}

Eigen::VectorXd eig(const std::vector<double>& q) {
  return Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
}

// The puma's home in the paper's cell (scenes/cell.yaml), in radians.
std::vector<double> home_joints() {
  constexpr double kDeg = std::numbers::pi / 180.0;
  return {0, 84 * kDeg, -192 * kDeg, 0, -72 * kDeg, 90 * kDeg};
}

// `base` with `delta` added joint by joint.
std::vector<double> offset(std::vector<double> base, const std::vector<double>& delta) {
  for (std::size_t i = 0; i < base.size(); ++i) base[i] += delta[i];
  return base;
}

// Two targets near home, within the puma's limits.
const std::vector<double> kA = offset(home_joints(), {0.2, -0.1, 0.15, 0.1, 0.2, -0.1});
const std::vector<double> kB = offset(home_joints(), {-0.15, 0.1, -0.1, -0.2, 0.1, 0.25});

Eigen::Isometry3d fk(const std::vector<double>& q) {
  return puma().forward(eig(q));
}

// A scripted controller of the puma claiming `caps`, homing where the cell's puma homes.
ScriptedDriverConfig config(Capabilities caps, std::uint64_t command_ticks, std::uint64_t position_ticks) {
  ScriptedDriverConfig c;
  c.where = {"cell.yaml", 19, 5};
  c.capabilities = std::move(caps);
  c.command_ticks = command_ticks;
  c.position_ticks = position_ticks;
  if (c.capabilities.joints == home_joints().size()) c.home_joints = home_joints();
  c.home_pose = fk(home_joints());
  return c;
}

// The twin's copy: what a SimDriver claims (every motion, gripper, signals, reads joints at any step).
ScriptedDriverConfig copy_config(std::uint64_t command_ticks = 5) {
  Capabilities caps;
  caps.joints = 6;
  caps.joint_control = caps.cartesian_control = caps.linear_motion = caps.full_orientation = true;
  caps.gripper = caps.gripper_width = caps.gripper_force = true;
  caps.gripper_max_width = 0.08;
  caps.gripper_max_force = 40;
  caps.digital_outputs = caps.digital_inputs = 4;
  caps.queue_depth = 4;
  caps.reads_joints = caps.reads_pose = caps.reads_while_moving = true;
  return config(std::move(caps), command_ticks, 1);
}

// A Movemaster-like controller: tool poses only (no joint control, no joint read-back), 5 axes, no digital I/O, a
// queue of two, `WH` answered between commands.
ScriptedDriverConfig movemaster_config(std::uint64_t command_ticks = 5) {
  Capabilities caps;
  caps.joints = 5;
  caps.cartesian_control = caps.linear_motion = true;
  caps.gripper = caps.gripper_force = true;
  caps.gripper_max_force = 30;
  caps.queue_depth = 2;
  caps.reads_pose = true;
  caps.prefers_pose = true;
  return config(std::move(caps), command_ticks, 2);
}

// A VAL II-like controller: joints and poses both ways, 6 axes, digital I/O, a queue of two.
ScriptedDriverConfig val_config(std::uint64_t command_ticks = 5) {
  Capabilities caps;
  caps.joints = 6;
  caps.joint_control = caps.cartesian_control = caps.linear_motion = caps.full_orientation = true;
  caps.gripper = true;
  caps.digital_outputs = caps.digital_inputs = 32;
  caps.queue_depth = 2;
  caps.reads_joints = caps.reads_pose = true;
  caps.prefers_pose = true;
  return config(std::move(caps), command_ticks, 2);
}

bool finished(CommandPhase p) {
  return p == CommandPhase::done || p == CommandPhase::failed;
}

// The real driver (owned by the mirror) and the copy, advanced together.
struct Rig {
  explicit Rig(ScriptedDriverConfig real_config, ScriptedDriverConfig copy_config_ = copy_config())
      : copy(std::move(copy_config_)),
        mirror("puma", std::make_unique<ScriptedDriver>(std::move(real_config)), copy, puma()) {}

  ScriptedDriver& real() { return static_cast<ScriptedDriver&>(mirror.real()); }

  // One tick of both controllers, without looking at the mirror.
  void step() {
    real().advance();
    copy.advance();
  }
  // `n` control cycles: a tick of both controllers, then the owner looks at the mirror.
  void cycles(int n) {
    for (int i = 0; i < n; ++i) {
      step();
      mirror.last_position();
    }
  }
  // Cycles until the mirror reports command `id` done or failed; returns its status.
  CommandStatus run(CommandId id, int limit = 500) {
    for (int i = 0; i < limit; ++i) {
      const CommandStatus s = mirror.poll(id);
      if (finished(s.phase)) return s;
      step();
    }
    return mirror.poll(id);
  }

  ScriptedDriver copy;  // declared before the mirror, which refers to it until destroyed
  MirroredDriver mirror;
};

// connect, home, activate, and the few cycles the copy needs to come up and read where it stands.
void bring_up(Rig& rig) {
  ASSERT_EQ(rig.mirror.connect(), ErrorCode::none);
  const Submitted h = rig.mirror.home();
  ASSERT_TRUE(h.accepted()) << h.message;
  ASSERT_EQ(rig.run(h.id).phase, CommandPhase::done);
  ASSERT_EQ(rig.mirror.activate(), ErrorCode::none);
  rig.cycles(3);
  ASSERT_EQ(rig.copy.state(), DriverState::active);
}

void expect_joints(const std::vector<double>& actual, const std::vector<double>& expected, double tolerance = 1e-9) {
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < actual.size(); ++i) EXPECT_NEAR(actual[i], expected[i], tolerance) << "joint " << i;
}

void expect_pose(const Eigen::Isometry3d& actual, const Eigen::Isometry3d& expected, double tolerance) {
  EXPECT_LT((actual.translation() - expected.translation()).norm(), tolerance);
  EXPECT_LT(Eigen::AngleAxisd(actual.linear().transpose() * expected.linear()).angle(), tolerance);
}

// Submits the same command to the mirror and to the real driver's twin, checking the answers agree.
Submitted submit_both(Rig& rig, ScriptedDriver& alone, const Command& command) {
  const Submitted m = rig.mirror.submit(command);
  const Submitted a = alone.submit(command);
  EXPECT_EQ(m.id, a.id) << drivers::describe(command);
  EXPECT_EQ(m.error, a.error) << drivers::describe(command);
  EXPECT_EQ(m.message, a.message);
  return m;
}

// ---------------------------------------------------------------------------------------------------------------------
// Every call answers as the real driver does.

// The same calls to the mirror and to a second real driver alone, advanced in lock-step: the same ids, refusals,
// states, statuses and readings, although the copy can do more (joints, widths, signals) and uses its own ids.
void expect_answers_of_the_real_driver_alone(const ScriptedDriverConfig& config) {
  Rig rig(config);
  ScriptedDriver alone(config);
  MirroredDriver& m = rig.mirror;
  const auto tick = [&](int n) {
    for (int i = 0; i < n; ++i) {
      rig.cycles(1);
      alone.advance();
    }
  };
  const auto same_status = [&](CommandId id) {
    for (int i = 0; i < 200 && !(finished(m.poll(id).phase) && finished(alone.poll(id).phase)); ++i) tick(1);
    const CommandStatus x = m.poll(id), y = alone.poll(id);
    EXPECT_EQ(x.phase, y.phase) << "command " << id;
    EXPECT_EQ(x.error, y.error) << "command " << id;
    EXPECT_EQ(x.message, y.message);
  };

  EXPECT_EQ(m.capabilities().joints, config.capabilities.joints);
  EXPECT_EQ(m.capabilities().joint_control, config.capabilities.joint_control);
  EXPECT_EQ(m.capabilities().reads_joints, config.capabilities.reads_joints);
  EXPECT_EQ(m.capabilities().prefers_pose, config.capabilities.prefers_pose);
  EXPECT_EQ(m.capabilities().queue_depth, config.capabilities.queue_depth);
  EXPECT_EQ(m.capabilities().digital_outputs, config.capabilities.digital_outputs);

  const MovePose to_a{fk(kA), Path::joint, 0.5};
  EXPECT_EQ(m.state(), alone.state());
  submit_both(rig, alone, to_a);
  EXPECT_EQ(m.connect(), alone.connect());
  EXPECT_EQ(m.connect(), alone.connect());
  EXPECT_EQ(m.state(), alone.state());
  EXPECT_EQ(m.activate(), alone.activate());
  EXPECT_EQ(m.request_position().error, alone.request_position().error);
  const Submitted h = m.home();
  EXPECT_EQ(h.id, alone.home().id);
  same_status(h.id);
  EXPECT_EQ(m.state(), alone.state());
  EXPECT_EQ(m.activate(), alone.activate());
  tick(3);

  submit_both(rig, alone, MoveJoints{kB, 0.5});
  const Submitted pose = submit_both(rig, alone, to_a);
  const Submitted grip = submit_both(rig, alone, Grip{Grip::Action::close, 0.01, std::nullopt});
  const Submitted close = submit_both(rig, alone, Grip{Grip::Action::close, std::nullopt, std::nullopt});
  submit_both(rig, alone, SetOutput{1, true});
  submit_both(rig, alone, MovePose{fk(kB), Path::linear, 0.5});
  for (const Submitted& s : {pose, grip, close}) {
    if (s.accepted()) same_status(s.id);
  }

  const Submitted read = submit_both(rig, alone, to_a);  // a third motion, then the reading behind it
  const Submitted r = m.request_position();
  EXPECT_EQ(r.id, alone.request_position().id);
  same_status(read.id);
  same_status(r.id);
  const auto x = m.last_position(), y = alone.last_position();
  ASSERT_TRUE(x.has_value() && y.has_value());
  EXPECT_EQ(x->request, y->request);
  EXPECT_EQ(x->stamp, y->stamp);
  EXPECT_EQ(x->joints, y->joints);  // empty for a pose-only controller, though the copy reads joints
  ASSERT_EQ(x->tool_pose.has_value(), y->tool_pose.has_value());
  EXPECT_TRUE(x->tool_pose->isApprox(*y->tool_pose));

  // A failure the real controller reports, and the command it cancels.
  const Submitted bad = submit_both(rig, alone, MovePose{fk(kB), Path::joint, 1.0});
  rig.real().fail_command(bad.id, ErrorCode::unreachable, "out of reach");
  alone.fail_command(bad.id, ErrorCode::unreachable, "out of reach");
  const Submitted behind = submit_both(rig, alone, Grip{Grip::Action::open, std::nullopt, std::nullopt});
  same_status(bad.id);
  same_status(behind.id);
  EXPECT_EQ(m.poll(behind.id).error, ErrorCode::cancelled);

  // The link drops: fault, the command in flight lost, reset() leaves it disconnected.
  const Submitted lost = submit_both(rig, alone, to_a);
  tick(1);
  rig.real().drop_connection();
  alone.drop_connection();
  EXPECT_EQ(m.state(), DriverState::fault);
  same_status(lost.id);
  EXPECT_EQ(m.poll(lost.id).error, ErrorCode::connection_lost);
  EXPECT_EQ(m.reset(), alone.reset());
  EXPECT_EQ(m.state(), alone.state());
  EXPECT_EQ(m.poll(0).error, alone.poll(0).error);
}

TEST(MirroredDriverAnswers, EveryCallAnswersAsAPoseOnlyRealDriverAlone) {
  expect_answers_of_the_real_driver_alone(movemaster_config());
}

TEST(MirroredDriverAnswers, EveryCallAnswersAsAJointsAndPoseRealDriverAlone) {
  expect_answers_of_the_real_driver_alone(val_config());
}

TEST(MirroredDriverAnswers, IdsAreTheRealDriversNotTheCopys) {
  Rig rig(val_config());
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  ASSERT_TRUE(s.accepted());
  ASSERT_FALSE(rig.real().accepted().empty());
  ASSERT_FALSE(rig.copy.accepted().empty());
  EXPECT_EQ(s.id, rig.real().accepted().back().first);
  EXPECT_NE(s.id, rig.copy.accepted().back().first);  // the copy's own home and reads came first
}

TEST(MirroredDriverAnswers, ARefusalOfTheRealDriverIsNotMirrored) {
  Rig rig(movemaster_config());
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});  // the copy could, the Movemaster cannot
  EXPECT_EQ(s.error, ErrorCode::unsupported);
  EXPECT_EQ(s.id, 0u);
  rig.cycles(20);
  EXPECT_TRUE(rig.copy.accepted().empty());
  expect_joints(rig.copy.joints(), home_joints());
  EXPECT_EQ(rig.mirror.counts().mirrored, 0);
}

// ---------------------------------------------------------------------------------------------------------------------
// The copy follows.

TEST(MirroredDriverFollows, MotionsAndGripsReachTheCopyAtOnce) {
  Rig rig(val_config());
  bring_up(rig);
  const Submitted move = rig.mirror.submit(MoveJoints{kA, 0.5});
  ASSERT_TRUE(move.accepted());
  const auto given = rig.copy.accepted();
  ASSERT_EQ(given.size(), 1u);  // before either controller has ticked
  const auto* copied = std::get_if<MoveJoints>(&given.back().second);
  ASSERT_NE(copied, nullptr);
  EXPECT_EQ(copied->positions, kA);
  EXPECT_EQ(copied->speed, 0.5);
  EXPECT_EQ(rig.mirror.counts().mirrored, 1);
  ASSERT_EQ(rig.run(move.id).phase, CommandPhase::done);
  expect_joints(rig.copy.joints(), kA);

  const Submitted grip = rig.mirror.submit(Grip{Grip::Action::close, std::nullopt, std::nullopt});
  ASSERT_EQ(rig.run(grip.id).phase, CommandPhase::done);
  EXPECT_TRUE(rig.copy.gripper_closed());
  EXPECT_TRUE(std::holds_alternative<Grip>(rig.copy.accepted().back().second));

  // A straight line goes to the copy as a straight line (its own controller interpolates it).
  const MovePose line{fk(kB), Path::linear, 0.25};
  const Submitted straight = rig.mirror.submit(line);
  ASSERT_EQ(rig.run(straight.id).phase, CommandPhase::done);
  const auto given_line = rig.copy.accepted();
  const auto* copied_line = std::get_if<MovePose>(&given_line.back().second);
  ASSERT_NE(copied_line, nullptr);
  EXPECT_EQ(copied_line->path, Path::linear);
  EXPECT_TRUE(copied_line->pose.isApprox(line.pose));
  EXPECT_EQ(rig.mirror.counts().mirrored, 3);
}

TEST(MirroredDriverFollows, ACopyStillHomingDoesWhatTheRealRobotWasToldOnceItIsUp) {
  // The real robot homes in 10 ticks, its copy in 200: the first motion comes while the copy still homes.
  ScriptedDriverConfig slow = copy_config();
  slow.home_ticks = 200;
  Rig rig(val_config(), slow);
  ASSERT_EQ(rig.mirror.connect(), ErrorCode::none);
  const Submitted h = rig.mirror.home();
  ASSERT_EQ(rig.run(h.id).phase, CommandPhase::done);
  ASSERT_EQ(rig.mirror.activate(), ErrorCode::none);
  ASSERT_NE(rig.copy.state(), DriverState::active);
  const Submitted move = rig.mirror.submit(MoveJoints{kA, 0.5});
  // Not held back by a copy that is not up.
  ASSERT_EQ(rig.run(move.id).phase, CommandPhase::done);
  ASSERT_NE(rig.copy.state(), DriverState::active);
  // Once up, the copy makes the move it missed.
  rig.cycles(400);
  EXPECT_EQ(rig.copy.state(), DriverState::active);
  expect_joints(rig.copy.joints(), kA);
  EXPECT_EQ(rig.mirror.counts().mirrored, 1);
}

TEST(MirroredDriverFollows, APoseMoveReachesTheCopyAsTheJointsNearestItsOwn) {
  Rig rig(movemaster_config());
  bring_up(rig);
  const Eigen::Isometry3d target = fk(kA);
  const Submitted s = rig.mirror.submit(MovePose{target, Path::joint, 0.5});
  ASSERT_TRUE(s.accepted());
  ASSERT_EQ(rig.copy.accepted().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<MoveJoints>(rig.copy.accepted().back().second));
  ASSERT_EQ(rig.run(s.id).phase, CommandPhase::done);
  expect_pose(fk(rig.copy.joints()), target, 1e-4);
  // Of the puma's solutions for that pose, the one next to where the copy stood (kA is near home).
  expect_joints(rig.copy.joints(), kA, 1e-3);
  EXPECT_TRUE(rig.real().tool_pose().isApprox(target));
}

// ---------------------------------------------------------------------------------------------------------------------
// Real commands are held until the copy has finished them.

TEST(MirroredDriverHolds, ARealMotionDoneFirstRunsUntilTheCopyHasFinished) {
  Rig rig(val_config(5), copy_config(20));
  bring_up(rig);
  for (const Command& command : {Command{MoveJoints{kA, 0.5}}, Command{Grip{Grip::Action::close, {}, {}}}}) {
    const Submitted s = rig.mirror.submit(command);
    ASSERT_TRUE(s.accepted());
    bool real_done = false, held = false;
    for (int i = 0; i < 200 && !finished(rig.mirror.poll(s.id).phase); ++i) {
      rig.step();
      const CommandPhase seen = rig.mirror.poll(s.id).phase;
      if (rig.real().poll(s.id).phase == CommandPhase::done && seen == CommandPhase::running) held = true;
      if (seen == CommandPhase::done) real_done = rig.real().poll(s.id).phase == CommandPhase::done;
    }
    EXPECT_TRUE(held) << drivers::describe(command);
    EXPECT_TRUE(real_done);
    // Done once the copy has finished it too: the twin shows the robot where the real one is.
    ASSERT_EQ(rig.mirror.poll(s.id).phase, CommandPhase::done);
    EXPECT_EQ(rig.copy.poll(rig.copy.accepted().back().first).phase, CommandPhase::done);
  }
  expect_joints(rig.copy.joints(), kA);
  EXPECT_TRUE(rig.copy.gripper_closed());
}

TEST(MirroredDriverHolds, ACopyDoneFirstDoesNotMakeTheRealCommandDone) {
  Rig rig(val_config(12), copy_config(3));
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  for (int i = 0; i < 200 && rig.real().poll(s.id).phase != CommandPhase::done; ++i) {
    EXPECT_EQ(rig.mirror.poll(s.id).phase, rig.real().poll(s.id).phase);
    rig.step();
  }
  EXPECT_EQ(rig.mirror.poll(s.id).phase, CommandPhase::done);
}

TEST(MirroredDriverHolds, TheNotifierWakesTheOwnerWhenTheCopyReleasesACommand) {
  Rig rig(val_config(5), copy_config(20));
  bring_up(rig);
  int notified = 0;
  rig.mirror.set_notifier([&notified] { ++notified; });
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  const CommandId copied = rig.copy.accepted().back().first;
  while (rig.copy.poll(copied).phase != CommandPhase::done && rig.copy.now_ticks() < 200) {
    rig.real().advance();
    const int before = notified;
    rig.copy.advance();
    // The copy finishing is what releases the held command: the owner must hear of it (the real robot, done
    // earlier, has nothing more to say).
    if (rig.copy.poll(copied).phase == CommandPhase::done) {
      EXPECT_GT(notified, before);
    }
  }
  EXPECT_EQ(rig.mirror.poll(s.id).phase, CommandPhase::done);
}

// ---------------------------------------------------------------------------------------------------------------------
// Digital I/O is the real cell's only.

TEST(MirroredDriverIo, DigitalIoIsNotMirroredAndNeverHeld) {
  Rig rig(val_config(5), copy_config(60));
  bring_up(rig);
  const Submitted move = rig.mirror.submit(MoveJoints{kA, 0.5});
  const Submitted out = rig.mirror.submit(SetOutput{3, true});
  ASSERT_TRUE(move.accepted() && out.accepted());
  EXPECT_EQ(rig.run(out.id).phase, CommandPhase::done);
  EXPECT_TRUE(rig.real().output(3));
  EXPECT_FALSE(rig.copy.output(3));
  EXPECT_EQ(rig.mirror.poll(move.id).phase, CommandPhase::running);  // the copy is still moving

  const Submitted wait = rig.mirror.submit(WaitInput{2, true, 0ns});
  ASSERT_TRUE(wait.accepted());
  rig.cycles(3);
  EXPECT_EQ(rig.mirror.poll(wait.id).phase, CommandPhase::running);
  rig.real().set_input(2, true);
  EXPECT_EQ(rig.run(wait.id, 3).phase, CommandPhase::done);
  EXPECT_EQ(rig.mirror.poll(move.id).phase, CommandPhase::running);

  ASSERT_EQ(rig.copy.accepted().size(), 1u);
  EXPECT_TRUE(std::holds_alternative<MoveJoints>(rig.copy.accepted().front().second));
  EXPECT_EQ(rig.mirror.counts().mirrored, 1);
  EXPECT_EQ(rig.run(move.id).phase, CommandPhase::done);
}

// ---------------------------------------------------------------------------------------------------------------------
// Corrections from the real robot's read-backs.

TEST(MirroredDriverReadings, AJointReadingAskedBeforeTheLastMotionNeverMovesTheCopyBack) {
  Rig rig(val_config());
  bring_up(rig);
  const Submitted read = rig.mirror.request_position();  // answered at home, before the move
  const Submitted move = rig.mirror.submit(MoveJoints{kA, 0.5});
  ASSERT_EQ(rig.run(move.id).phase, CommandPhase::done);
  rig.cycles(30);
  const auto reading = rig.mirror.last_position();
  ASSERT_TRUE(reading.has_value());
  ASSERT_EQ(reading->request, read.id);
  expect_joints(reading->joints, home_joints());  // it differs from where the copy stands
  expect_joints(rig.copy.joints(), kA);
  EXPECT_EQ(rig.mirror.counts().corrections, 0);
}

TEST(MirroredDriverReadings, APoseReadingAskedBeforeTheLastMotionNeverMovesTheCopyBack) {
  Rig rig(movemaster_config());
  bring_up(rig);
  const Submitted read = rig.mirror.request_position();
  const Submitted move = rig.mirror.submit(MovePose{fk(kA), Path::joint, 0.5});
  ASSERT_EQ(rig.run(move.id).phase, CommandPhase::done);
  rig.cycles(30);
  ASSERT_EQ(rig.mirror.last_position()->request, read.id);
  expect_pose(fk(rig.copy.joints()), fk(kA), 1e-4);
  EXPECT_EQ(rig.mirror.counts().corrections, 0);
}

// The real robot homes elsewhere than the copy by `delta`; a reading asked for after that shows it.
struct Correction {
  int corrections;
  std::vector<double> copy;
  std::vector<double> real;
};
Correction after_a_fresh_joint_reading(double delta) {
  ScriptedDriverConfig real = val_config();
  real.home_joints = offset(home_joints(), {0, delta, 0, 0, -delta, 0});
  Rig rig(real);
  bring_up(rig);
  rig.cycles(20);
  EXPECT_EQ(rig.mirror.counts().corrections, 0);  // nothing read yet
  const Submitted r = rig.mirror.request_position();
  EXPECT_EQ(rig.run(r.id).phase, CommandPhase::done);
  rig.cycles(20);
  return {rig.mirror.counts().corrections, rig.copy.joints(), rig.real().joints()};
}

TEST(MirroredDriverReadings, AFreshJointReadingBeyondTheToleranceCorrectsTheCopy) {
  const Correction c = after_a_fresh_joint_reading(3 * MirroredDriver::kJointTolerance);
  EXPECT_EQ(c.corrections, 1);
  expect_joints(c.copy, c.real);
}

TEST(MirroredDriverReadings, AFreshJointReadingWithinTheToleranceLeavesTheCopy) {
  const Correction c = after_a_fresh_joint_reading(0.5 * MirroredDriver::kJointTolerance);
  EXPECT_EQ(c.corrections, 0);
  expect_joints(c.copy, home_joints());
}

TEST(MirroredDriverReadings, AFreshPoseReadingCorrectsTheCopyThroughIkOnlyBeyondTheTolerance) {
  for (const double factor : {0.5, 3.0}) {
    SCOPED_TRACE(factor);
    ScriptedDriverConfig real = movemaster_config();
    real.home_pose.pretranslate(Eigen::Vector3d(factor * MirroredDriver::kToolTolerance, 0, 0));
    Rig rig(real);
    bring_up(rig);
    const Submitted r = rig.mirror.request_position();
    ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
    rig.cycles(20);
    EXPECT_EQ(rig.mirror.counts().corrections, factor > 1 ? 1 : 0);
    if (factor > 1) {
      expect_pose(fk(rig.copy.joints()), real.home_pose, 1e-4);
    } else {
      expect_joints(rig.copy.joints(), home_joints());
    }
  }
}

TEST(MirroredDriverReadings, AFreshPoseReadingFarFromTheCopyIsFollowedThroughIk) {
  ScriptedDriverConfig real = movemaster_config();
  real.home_pose = fk(offset(home_joints(), {0.05, 0.05, -0.05, 0.1, 0, 0}));
  Rig rig(real);
  bring_up(rig);
  const Submitted r = rig.mirror.request_position();
  ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
  rig.cycles(20);
  EXPECT_EQ(rig.mirror.counts().corrections, 1);
  expect_pose(fk(rig.copy.joints()), real.home_pose, 1e-4);
  // A second reading of the same place finds the copy there.
  const Submitted again = rig.mirror.request_position();
  ASSERT_EQ(rig.run(again.id).phase, CommandPhase::done);
  rig.cycles(20);
  EXPECT_EQ(rig.mirror.counts().corrections, 1);
}

// ---------------------------------------------------------------------------------------------------------------------
// The copy's failures never hold back or fail the real robot.

TEST(MirroredDriverCopyFailures, ACopyFailingACommandNeitherHoldsNorFailsTheReal) {
  Rig rig(val_config(5), copy_config(20));
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  rig.copy.fail_command(rig.copy.accepted().back().first, ErrorCode::unreachable, "joint 3 outside its limits");
  EXPECT_EQ(rig.run(s.id).phase, CommandPhase::done);
  EXPECT_EQ(rig.mirror.state(), DriverState::active);
  rig.cycles(30);
  EXPECT_EQ(rig.mirror.counts().misses, 1);
  expect_joints(rig.copy.joints(), home_joints());  // it did not move: the next reading puts it right
  const Submitted r = rig.mirror.request_position();
  ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
  rig.cycles(30);
  EXPECT_EQ(rig.mirror.counts().corrections, 1);
  expect_joints(rig.copy.joints(), kA);
  const auto given = rig.copy.accepted();
  const auto* correction = std::get_if<MoveJoints>(&given.back().second);
  ASSERT_NE(correction, nullptr);
  EXPECT_EQ(correction->speed, 0.5);  // the speed of the last motion
}

TEST(MirroredDriverCopyFailures, ACopyRefusingACommandDoesNotHoldTheReal) {
  ScriptedDriverConfig copy = copy_config(20);
  copy.capabilities.gripper = copy.capabilities.gripper_width = copy.capabilities.gripper_force = false;
  Rig rig(val_config(5), copy);
  bring_up(rig);
  const Submitted s = rig.mirror.submit(Grip{Grip::Action::close, {}, {}});
  ASSERT_TRUE(s.accepted());
  EXPECT_EQ(rig.mirror.counts().misses, 1);
  for (int i = 0; i < 100 && rig.real().poll(s.id).phase != CommandPhase::done; ++i) rig.step();
  EXPECT_EQ(rig.mirror.poll(s.id).phase, CommandPhase::done);  // in the cycle the real robot finished it
}

TEST(MirroredDriverCopyFailures, ACopyInFaultNeitherHoldsNorFailsTheRealAndComesBack) {
  Rig rig(val_config(5), copy_config(40));
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  rig.cycles(2);
  rig.copy.drop_connection();
  for (int i = 0; i < 100 && rig.real().poll(s.id).phase != CommandPhase::done; ++i) rig.step();
  EXPECT_EQ(rig.mirror.poll(s.id).phase, CommandPhase::done);
  EXPECT_EQ(rig.mirror.state(), DriverState::active);
  EXPECT_EQ(rig.mirror.counts().misses, 1);

  // The copy is reset, re-homed and follows again: a reading puts it where the real robot is, the next move is
  // mirrored.
  rig.cycles(30);
  ASSERT_EQ(rig.copy.state(), DriverState::active);
  const Submitted r = rig.mirror.request_position();
  ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
  rig.cycles(60);
  expect_joints(rig.copy.joints(), kA);
  const Submitted next = rig.mirror.submit(MoveJoints{kB, 0.5});
  ASSERT_EQ(rig.run(next.id).phase, CommandPhase::done);
  expect_joints(rig.copy.joints(), kB);
}

TEST(MirroredDriverCopyFailures, ACopyFaultingWhileItHomesComesBackUp) {
  Rig rig(val_config());
  ASSERT_EQ(rig.mirror.connect(), ErrorCode::none);
  const Submitted h = rig.mirror.home();
  rig.cycles(3);
  rig.copy.drop_connection();  // its homing fails with it
  ASSERT_EQ(rig.run(h.id).phase, CommandPhase::done);
  ASSERT_EQ(rig.mirror.activate(), ErrorCode::none);
  rig.cycles(40);
  EXPECT_EQ(rig.copy.state(), DriverState::active);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  ASSERT_EQ(rig.run(s.id).phase, CommandPhase::done);
  expect_joints(rig.copy.joints(), kA);
}

TEST(MirroredDriverCopyFailures, ACommandTheRealRobotCancelledIsNotDoneByTheCopy) {
  Rig rig(val_config(5), copy_config(20));
  bring_up(rig);
  const Submitted move = rig.mirror.submit(MoveJoints{kA, 0.5});
  rig.real().fail_command(move.id, ErrorCode::unreachable, "joint 3 outside its limits");
  const Submitted grip = rig.mirror.submit(Grip{Grip::Action::close, {}, {}});
  EXPECT_EQ(rig.run(move.id).phase, CommandPhase::failed);
  EXPECT_EQ(rig.mirror.poll(grip.id).error, ErrorCode::cancelled);
  rig.cycles(60);
  EXPECT_FALSE(rig.copy.gripper_closed());
  for (const auto& [id, command] : rig.copy.accepted()) EXPECT_FALSE(std::holds_alternative<Grip>(command));
}

// ---------------------------------------------------------------------------------------------------------------------
// The lifecycle reaches both.

TEST(MirroredDriverLifecycle, StopReachesBothAndTheCopyStaysWhereTheRealRobotStopped) {
  Rig rig(val_config(10), copy_config(10));
  bring_up(rig);
  ASSERT_EQ(rig.run(rig.mirror.submit(MoveJoints{kA, 0.5}).id).phase, CommandPhase::done);
  rig.cycles(3);
  const Submitted s = rig.mirror.submit(MoveJoints{kB, 0.5});
  rig.cycles(3);
  rig.mirror.stop();
  EXPECT_EQ(rig.mirror.state(), DriverState::stopped);
  EXPECT_EQ(rig.copy.state(), DriverState::stopped);
  const CommandStatus st = rig.mirror.poll(s.id);
  EXPECT_EQ(st.phase, CommandPhase::failed);
  EXPECT_EQ(st.error, ErrorCode::cancelled);
  // The real robot stands (still at kA: the scripted robot moves only when a motion completes): so does the copy.
  rig.cycles(40);
  expect_joints(rig.real().joints(), kA);
  expect_joints(rig.copy.joints(), kA);
  EXPECT_EQ(rig.mirror.counts().corrections, 0);

  ASSERT_EQ(rig.mirror.activate(), ErrorCode::none);
  const Submitted again = rig.mirror.submit(MoveJoints{kB, 0.5});
  ASSERT_EQ(rig.run(again.id).phase, CommandPhase::done);
  expect_joints(rig.copy.joints(), kB);
}

TEST(MirroredDriverLifecycle, DisconnectReachesBothAndTheCopyWaitsForTheNextConnect) {
  Rig rig(val_config(), copy_config(20));
  bring_up(rig);
  const Submitted s = rig.mirror.submit(MoveJoints{kA, 0.5});
  rig.cycles(2);
  rig.mirror.disconnect();
  EXPECT_EQ(rig.mirror.state(), DriverState::disconnected);
  EXPECT_EQ(rig.copy.state(), DriverState::disconnected);
  EXPECT_EQ(rig.mirror.poll(s.id).error, ErrorCode::cancelled);
  rig.cycles(30);
  EXPECT_EQ(rig.copy.state(), DriverState::disconnected);

  bring_up(rig);
  const Submitted next = rig.mirror.submit(MoveJoints{kB, 0.5});
  ASSERT_EQ(rig.run(next.id).phase, CommandPhase::done);
  expect_joints(rig.copy.joints(), kB);
}

TEST(MirroredDriverLifecycle, HomeSendsTheCopyHome) {
  Rig rig(val_config());
  bring_up(rig);
  ASSERT_EQ(rig.run(rig.mirror.submit(MoveJoints{kA, 0.5}).id).phase, CommandPhase::done);
  rig.cycles(3);
  rig.mirror.stop();
  const Submitted h = rig.mirror.home();
  ASSERT_TRUE(h.accepted());
  ASSERT_EQ(rig.run(h.id).phase, CommandPhase::done);
  rig.cycles(3);
  expect_joints(rig.copy.joints(), home_joints());
  ASSERT_EQ(rig.mirror.activate(), ErrorCode::none);
  rig.cycles(3);
  EXPECT_EQ(rig.copy.state(), DriverState::active);
  // Both stand at home: a reading there finds nothing to correct.
  const Submitted r = rig.mirror.request_position();
  ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
  rig.cycles(20);
  EXPECT_EQ(rig.mirror.counts().corrections, 0);
  expect_joints(rig.copy.joints(), home_joints());
}

TEST(MirroredDriverLifecycle, TheClockStampsTheReadingsOfBoth) {
  Rig rig(movemaster_config());
  bring_up(rig);
  rig.mirror.set_clock([] { return std::chrono::nanoseconds(42s); });
  const Submitted r = rig.mirror.request_position();
  ASSERT_EQ(rig.run(r.id).phase, CommandPhase::done);
  EXPECT_EQ(rig.mirror.last_position()->stamp, 42s);
  const Submitted m = rig.mirror.submit(MovePose{fk(kA), Path::joint, 0.5});
  ASSERT_EQ(rig.run(m.id).phase, CommandPhase::done);  // the copy reads where it stands after each command
  rig.cycles(3);
  ASSERT_TRUE(rig.copy.last_position().has_value());
  EXPECT_EQ(rig.copy.last_position()->stamp, 42s);
}

}  // namespace
}  // namespace cellwright::twin::sim
