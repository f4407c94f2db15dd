// The simulation driver against the driver interface's contract (lifecycle, refusals, ids, cancellation, notifier)
// and against the physics: the arms reach their targets within tolerance along smooth, speed-limited trajectories,
// straight lines stay straight, the grippers open and close, signals synchronise two robots.
#include "cellwright/twin/sim/sim_driver.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "cellwright/runtime/event.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using drivers::CommandPhase;
using drivers::DriverState;
using drivers::ErrorCode;
using ::testing::HasSubstr;
using namespace testing;  // NOLINT: the simulation test helpers

class SimDriverTest : public PaperCellTest {
 protected:

  World& world() { return *world_; }
  static RobotTruth truth_of(const WorldTruth& t, const std::string& robot) {
    for (const auto& r : t.robots) {
      if (r.name == robot) return r;
    }
    throw std::logic_error("no robot " + robot);
  }
  Eigen::VectorXd joints_now(const std::string& robot) {
    const auto j = truth_of(world().truth(), robot).joints;
    return Eigen::Map<const Eigen::VectorXd>(j.data(), static_cast<Eigen::Index>(j.size()));
  }
};

TEST_F(SimDriverTest, FollowsTheLifecycleTable) {
  SimDriver& d = world().add_sim_driver("puma");
  EXPECT_EQ(d.state(), DriverState::disconnected);
  EXPECT_EQ(d.submit(drivers::SetOutput{1, true}).error, ErrorCode::wrong_state);
  EXPECT_EQ(d.home().error, ErrorCode::wrong_state);
  EXPECT_EQ(d.request_position().error, ErrorCode::wrong_state);
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);
  EXPECT_EQ(d.reset(), ErrorCode::wrong_state);
  ASSERT_EQ(d.connect(), ErrorCode::none);
  EXPECT_EQ(d.connect(), ErrorCode::wrong_state);
  EXPECT_EQ(d.state(), DriverState::connected);
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);  // not homed
  const drivers::Submitted home = d.home();
  ASSERT_TRUE(home.accepted());
  EXPECT_EQ(home.id, 1u);
  EXPECT_EQ(d.activate(), ErrorCode::wrong_state);  // still homing
  EXPECT_EQ(run_until_finished(world(), d, home.id).phase, CommandPhase::done);
  EXPECT_EQ(d.state(), DriverState::homed);
  EXPECT_EQ(d.submit(drivers::SetOutput{1, true}).error, ErrorCode::wrong_state);  // homed is not active
  ASSERT_EQ(d.activate(), ErrorCode::none);
  EXPECT_EQ(d.state(), DriverState::active);
  EXPECT_EQ(d.home().error, ErrorCode::wrong_state);
  const drivers::Submitted out = d.submit(drivers::SetOutput{1, true});
  EXPECT_EQ(out.id, 2u);
  d.stop();
  EXPECT_EQ(d.state(), DriverState::stopped);
  EXPECT_EQ(d.poll(out.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.submit(drivers::SetOutput{1, true}).error, ErrorCode::wrong_state);
  EXPECT_TRUE(d.request_position().accepted());  // allowed while stopped
  ASSERT_EQ(d.activate(), ErrorCode::none);
  d.disconnect();
  EXPECT_EQ(d.state(), DriverState::disconnected);
  EXPECT_EQ(d.poll(999).error, ErrorCode::unknown_command);
}

TEST_F(SimDriverTest, RefusesWhatItCannotDo) {
  SimDriverOptions options;
  options.queue_depth = 2;
  SimDriver& d = world().add_sim_driver("puma", options);
  bring_up(world(), d);
  const auto& caps = d.capabilities();
  EXPECT_EQ(caps.joints, 6u);
  EXPECT_TRUE(caps.joint_control && caps.cartesian_control && caps.linear_motion && caps.full_orientation);
  EXPECT_TRUE(caps.gripper && caps.gripper_width && caps.gripper_force);
  EXPECT_DOUBLE_EQ(caps.gripper_max_width, 0.08);  // the URDF's finger travel, both fingers
  EXPECT_DOUBLE_EQ(caps.gripper_max_force, paper_cell().find_robot("puma")->grip_force);
  ASSERT_EQ(caps.max_joint_speed.size(), 6u);
  for (double v : caps.max_joint_speed) EXPECT_GT(v, 0.0);

  const drivers::Submitted wrong = d.submit(drivers::MoveJoints{{0, 0, 0}, 1.0});
  EXPECT_EQ(wrong.error, ErrorCode::invalid_command);
  EXPECT_THAT(wrong.message, HasSubstr("3 joint positions"));
  EXPECT_EQ(d.submit(drivers::SetOutput{99, true}).error, ErrorCode::invalid_command);
  drivers::Grip too_hard = grip(drivers::Grip::Action::close);
  too_hard.force = 1000;
  EXPECT_EQ(d.submit(too_hard).error, ErrorCode::invalid_command);
  // Queue depth 2: a third command in flight is refused with busy.
  ASSERT_TRUE(d.submit(drivers::WaitInput{1, true, {}}).accepted());
  ASSERT_TRUE(d.submit(drivers::SetOutput{2, true}).accepted());
  EXPECT_EQ(d.submit(drivers::SetOutput{3, true}).error, ErrorCode::busy);
}

TEST_F(SimDriverTest, RejectsBadOptionsNamingTheFile) {
  SimDriverOptions options;
  options.where = {"scenario.yaml", 7, 3};
  options.max_joint_speed = {1, 1, 1};
  try {
    world().add_sim_driver("puma", options);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scenario.yaml:7:3"));
    EXPECT_THAT(e.what(), HasSubstr("max_joint_speed has 3 values for 6 joints"));
  }
  WorldOptions wo;
  wo.where = {"scenario.yaml", 2, 1};
  World other(build_scene(paper_cell()), wo);
  EXPECT_THROW(other.add_sim_driver("kuka"), InputError);
  other.add_sim_driver("melfa");
  EXPECT_THROW(other.add_sim_driver("melfa"), InputError);
}

TEST_F(SimDriverTest, MoveJointsReachesTheTargetSmoothlyWithinTheSpeedLimits) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  const Eigen::VectorXd start = joints_now("puma");
  Eigen::VectorXd goal = start;
  goal[0] += 0.6;
  goal[1] -= 0.2;
  goal[2] += 0.3;
  goal[5] -= 1.0;
  const double speed = 0.5;
  const auto& caps = d.capabilities();
  const Eigen::VectorXd vmax = Eigen::Map<const Eigen::VectorXd>(caps.max_joint_speed.data(), 6);
  const double planned = move_duration(start, goal, vmax, speed, 0.2);

  const auto t0 = world().now();
  double worst_ratio = 0;
  const auto s = execute(world(), d, drivers::MoveJoints{{goal.data(), goal.data() + 6}, speed}, 20s, [&] {
    const auto& r = truth_of(world().truth(), "puma");
    for (std::size_t j = 0; j < 6; ++j) {
      worst_ratio =
          std::max(worst_ratio, std::abs(r.joint_velocities[j]) / (vmax[static_cast<Eigen::Index>(j)] * speed));
    }
  });
  ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  const double took = std::chrono::duration<double>(world().now() - t0).count();
  EXPECT_GE(took, planned);
  EXPECT_LT(took, planned + 0.3) << "the arm should settle soon after the trajectory ends";
  EXPECT_LT((joints_now("puma") - goal).cwiseAbs().maxCoeff(), 0.002);
  // The joints track the trajectory: never more than a few percent over the speed it was timed for.
  EXPECT_LT(worst_ratio, 1.05);
  EXPECT_GT(worst_ratio, 0.9);  // and the slowest joint really ran at its limit
}

TEST_F(SimDriverTest, TargetsOutsideTheLimitsAreUnreachableAndCancelWhatFollows) {
  SimDriver& d = world().add_sim_driver("melfa");
  bring_up(world(), d);
  const auto limit = d.kinematics().limits()[1];
  std::vector<double> goal = paper_cell().find_robot("melfa")->home;
  goal[1] = limit.upper + 0.1;
  const drivers::Submitted bad = d.submit(drivers::MoveJoints{goal, 1.0});
  const drivers::Submitted after = d.submit(drivers::SetOutput{1, true});
  ASSERT_TRUE(bad.accepted() && after.accepted());
  const auto s = run_until_finished(world(), d, bad.id);
  EXPECT_EQ(s.phase, CommandPhase::failed);
  EXPECT_EQ(s.error, ErrorCode::unreachable);
  EXPECT_THAT(s.message, HasSubstr("joint 2"));
  EXPECT_EQ(d.poll(after.id).error, ErrorCode::cancelled);
  EXPECT_FALSE(world().signals().get(1));
  EXPECT_EQ(d.state(), DriverState::active);  // unreachable fails the command only

  drivers::MovePose far;
  far.pose.translation() << 3.0, 0, 0.5;
  const auto s2 = execute(world(), d, far);
  EXPECT_EQ(s2.error, ErrorCode::unreachable) << s2.message;
}

TEST_F(SimDriverTest, PositionReadingsAreStampedWithSimulationTime) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  world().advance(100ms);
  const drivers::Submitted r = d.request_position();
  ASSERT_TRUE(r.accepted());
  EXPECT_FALSE(d.last_position() && d.last_position()->request == r.id);
  const auto before = world().now();
  world().advance(kPeriod);
  ASSERT_EQ(d.poll(r.id).phase, CommandPhase::done);
  const auto reading = d.last_position();
  ASSERT_TRUE(reading);
  EXPECT_EQ(reading->request, r.id);
  EXPECT_EQ(reading->stamp, before);  // taken at the first step after the request
  ASSERT_EQ(reading->joints.size(), 6u);
  ASSERT_TRUE(reading->tool_pose);
  // At rest, the reading agrees with the simulation's own tool frame.
  const auto& tcp = truth_of(world().truth(), "puma").tcp;
  const Eigen::Isometry3d world_tool = base_of(world(), "puma") * *reading->tool_pose;
  EXPECT_LT((world_tool.translation() - tcp.translation()).norm(), 1e-4);
  EXPECT_TRUE(world_tool.linear().isApprox(tcp.linear(), 1e-3));
}

// A simulation can read its joints at any step (reads_while_moving): a request made during a motion is answered at the
// next step, with the joints where the moving arm is, while the motion goes on.
TEST_F(SimDriverTest, PositionRequestsAreAnsweredWhileTheArmMoves) {
  SimDriver& d = world().add_sim_driver("puma");
  EXPECT_TRUE(d.capabilities().reads_while_moving);
  bring_up(world(), d);
  const Eigen::VectorXd start = joints_now("puma");
  Eigen::VectorXd goal = start;
  goal[0] += 0.8;
  const drivers::Submitted move = d.submit(drivers::MoveJoints{{goal.data(), goal.data() + 6}, 0.5});
  ASSERT_TRUE(move.accepted());
  world().advance(300ms);
  const drivers::Submitted r = d.request_position();
  ASSERT_TRUE(r.accepted());
  EXPECT_GT(r.id, move.id);
  const auto before = world().now();
  world().advance(kPeriod);
  ASSERT_EQ(d.poll(r.id).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::running);
  const auto reading = d.last_position();
  ASSERT_TRUE(reading);
  EXPECT_EQ(reading->request, r.id);
  EXPECT_EQ(reading->stamp, before);
  // Part of the way: moved from the start, not yet at the goal.
  EXPECT_GT(reading->joints[0], start[0] + 0.01);
  EXPECT_LT(reading->joints[0], goal[0] - 0.01);
  EXPECT_EQ(run_until_finished(world(), d, move.id).phase, CommandPhase::done);
}

// Given the runtime's clock, the driver stamps readings with it (called on the simulation thread, at the step).
TEST_F(SimDriverTest, PositionReadingsAreStampedOnTheClockGivenToTheDriver) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  std::chrono::nanoseconds runtime_now = 42s;
  d.set_clock([&] { return runtime_now; });
  const drivers::Submitted r = d.request_position();
  runtime_now = 43s;
  world().advance(kPeriod);
  ASSERT_EQ(d.poll(r.id).phase, CommandPhase::done);
  EXPECT_EQ(d.last_position()->stamp, 43s);
  d.set_clock({});
  const drivers::Submitted own = d.request_position();
  const auto before = world().now();
  world().advance(kPeriod);
  ASSERT_EQ(d.poll(own.id).phase, CommandPhase::done);
  EXPECT_EQ(d.last_position()->stamp, before);
}

TEST_F(SimDriverTest, MovePoseReachesThePose) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  const Eigen::Isometry3d target = down_at(world(), "puma", {0.35, -0.3, 0.65}, 0.3);
  const auto s = execute(world(), d, pose_move(target, drivers::Path::joint));
  ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  const Eigen::Isometry3d reached = base_of(world(), "puma").inverse() * truth_of(world().truth(), "puma").tcp;
  EXPECT_LT((reached.translation() - target.translation()).norm(), 0.001);
  EXPECT_LT(Eigen::AngleAxisd(reached.linear().transpose() * target.linear()).angle(), 0.005);
}

TEST_F(SimDriverTest, LinearMovesKeepTheToolOnTheLine) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  const Eigen::Isometry3d a = down_at(world(), "puma", {0.4, -0.2, 0.7}, 0.0);
  const Eigen::Isometry3d b = down_at(world(), "puma", {0.4, 0.2, 0.55}, 0.0);
  ASSERT_EQ(execute(world(), d, pose_move(a, drivers::Path::joint)).phase, CommandPhase::done);
  const Eigen::Vector3d pa = base_of(world(), "puma") * a.translation();
  const Eigen::Vector3d pb = base_of(world(), "puma") * b.translation();
  const Eigen::Vector3d dir = (pb - pa).normalized();
  double worst = 0, fastest = 0;
  Eigen::Vector3d last = pa;
  const auto s = execute(world(), d, pose_move(b, drivers::Path::linear, 0.6), 20s, [&] {
    const Eigen::Vector3d p = truth_of(world().truth(), "puma").tcp.translation();
    const Eigen::Vector3d off = (p - pa) - dir * dir.dot(p - pa);
    worst = std::max(worst, off.norm());
    fastest = std::max(fastest, (p - last).norm() / 0.01);
    last = p;
  });
  ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  EXPECT_LT(worst, 0.001) << "the tool left the straight line by " << worst << " m";
  EXPECT_LT((truth_of(world().truth(), "puma").tcp.translation() - pb).norm(), 0.001);
  EXPECT_LE(fastest, d.capabilities().max_tool_speed * 0.6 * 1.05);
}

TEST_F(SimDriverTest, StopBrakesToRestAndCancels) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  std::vector<double> goal = paper_cell().find_robot("puma")->home;
  goal[0] += 1.5;
  const drivers::Submitted move = d.submit(drivers::MoveJoints{goal, 1.0});
  ASSERT_TRUE(move.accepted());
  world().advance(400ms);
  ASSERT_EQ(d.poll(move.id).phase, CommandPhase::running);
  ASSERT_GT(std::abs(truth_of(world().truth(), "puma").joint_velocities[0]), 0.3);
  d.stop();
  EXPECT_EQ(d.poll(move.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.state(), DriverState::stopped);
  world().advance(1s);
  const auto& r = truth_of(world().truth(), "puma");
  EXPECT_LT(std::abs(r.joint_velocities[0]), 0.01);
  EXPECT_LT(r.joints[0], goal[0] - 0.2) << "it stopped, short of the goal";
  ASSERT_EQ(d.activate(), ErrorCode::none);
  // From wherever it stopped, it moves on.
  EXPECT_EQ(execute(world(), d, drivers::MoveJoints{goal, 1.0}).phase, CommandPhase::done);
}

TEST_F(SimDriverTest, GripperOpensClosesAndKnowsWhenItHoldsNothing) {
  SimDriver& d = world().add_sim_driver("melfa");
  bring_up(world(), d);
  EXPECT_FALSE(d.last_grip());
  const auto closed = execute(world(), d, grip(drivers::Grip::Action::close));
  ASSERT_EQ(closed.phase, CommandPhase::done) << closed.message;
  ASSERT_TRUE(d.last_grip());
  EXPECT_FALSE(d.last_grip()->on_part);
  EXPECT_LT(d.last_grip()->opening, 0.001);
  EXPECT_LT(truth_of(world().truth(), "melfa").finger_opening, 0.001);

  drivers::Grip half = grip(drivers::Grip::Action::open);
  half.width = 0.03;
  ASSERT_EQ(execute(world(), d, half).phase, CommandPhase::done);
  EXPECT_NEAR(truth_of(world().truth(), "melfa").finger_opening, 0.03, 0.001);
  ASSERT_EQ(execute(world(), d, grip(drivers::Grip::Action::open)).phase, CommandPhase::done);
  EXPECT_NEAR(truth_of(world().truth(), "melfa").finger_opening, 0.08, 0.001);
  EXPECT_EQ(d.last_grip()->action, drivers::Grip::Action::open);
}

TEST_F(SimDriverTest, SignalsSynchroniseTwoRobotsAndWaitsTimeOut) {
  SimDriver& puma = world().add_sim_driver("puma");
  SimDriver& melfa = world().add_sim_driver("melfa");
  bring_up(world(), puma);
  bring_up(world(), melfa);
  const drivers::Submitted wait = melfa.submit(drivers::WaitInput{3, true, {}});
  ASSERT_TRUE(wait.accepted());
  world().advance(500ms);
  EXPECT_EQ(melfa.poll(wait.id).phase, CommandPhase::running);
  const drivers::Submitted set = puma.submit(drivers::SetOutput{3, true});
  world().advance(kPeriod);
  EXPECT_EQ(puma.poll(set.id).phase, CommandPhase::done);
  EXPECT_EQ(melfa.poll(wait.id).phase, CommandPhase::done);
  EXPECT_TRUE(world().signals().get(3));

  const auto t0 = world().now();
  const drivers::Submitted timed = melfa.submit(drivers::WaitInput{4, true, 250ms});
  const drivers::Submitted behind = melfa.submit(drivers::SetOutput{5, true});
  const auto s = run_until_finished(world(), melfa, timed.id);
  EXPECT_EQ(s.error, ErrorCode::timeout);
  EXPECT_THAT(s.message, HasSubstr("digital input 4"));
  EXPECT_GE(world().now() - t0, 250ms);
  EXPECT_LE(world().now() - t0, 260ms);
  EXPECT_EQ(melfa.poll(behind.id).error, ErrorCode::cancelled);
}

TEST_F(SimDriverTest, NotifiesWhenCommandsFinish) {
  SimDriver& d = world().add_sim_driver("puma");
  int calls = 0;
  d.set_notifier([&] { ++calls; });
  ASSERT_EQ(d.connect(), ErrorCode::none);
  const auto home = d.home();
  world().advance(kPeriod);
  EXPECT_EQ(calls, 0);
  run_until_finished(world(), d, home.id);
  EXPECT_EQ(calls, 1);
  ASSERT_EQ(d.activate(), ErrorCode::none);
  d.submit(drivers::SetOutput{1, true});
  d.submit(drivers::SetOutput{2, true});
  world().advance(kPeriod);
  EXPECT_EQ(calls, 2);  // once per step in which something finished
  d.submit(drivers::WaitInput{7, true, {}});
  d.stop();
  EXPECT_EQ(calls, 3);
  d.set_notifier({});
  ASSERT_EQ(d.activate(), ErrorCode::none);
  d.submit(drivers::SetOutput{1, false});
  world().advance(kPeriod);
  EXPECT_EQ(calls, 3);
}

TEST_F(SimDriverTest, AFaultFailsEverythingUntilReset) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  const auto wait = d.submit(drivers::WaitInput{1, true, {}});
  d.fault("MuJoCo reset the simulation", world().now(), world().data());
  EXPECT_EQ(d.state(), DriverState::fault);
  EXPECT_EQ(d.poll(wait.id).error, ErrorCode::hardware);
  EXPECT_EQ(d.submit(drivers::SetOutput{1, true}).error, ErrorCode::wrong_state);
  EXPECT_EQ(d.home().error, ErrorCode::wrong_state);
  ASSERT_EQ(d.reset(), ErrorCode::none);
  EXPECT_EQ(d.state(), DriverState::connected);
  const auto home = d.home();
  ASSERT_TRUE(home.accepted());
  EXPECT_EQ(run_until_finished(world(), d, home.id).phase, CommandPhase::done);
  EXPECT_EQ(d.activate(), ErrorCode::none);
}

// The owner thread submits and waits on an event set by the notifier while the simulation thread advances the
// world: the contract's threading, run under ThreadSanitizer in CI.
TEST_F(SimDriverTest, OwnerAndSimulationThreadsShareTheDriver) {
  SimDriver& d = world().add_sim_driver("puma");
  bring_up(world(), d);
  runtime::Event finished(runtime::Event::Kind::auto_reset);
  d.set_notifier([&] { finished.set(); });
  std::atomic<bool> owner_done{false}, sim_over{false};
  const std::vector<double> home = paper_cell().find_robot("puma")->home;
  std::vector<double> last_goal;
  std::vector<drivers::CommandId> ids;
  std::thread owner([&] {
    for (int i = 0; i < 3; ++i) {
      std::vector<double> goal = home;
      goal[0] += i % 2 == 0 ? 0.3 : 0.0;
      const drivers::Submitted s = d.submit(drivers::MoveJoints{goal, 1.0});
      if (!s.accepted()) return;
      ids.push_back(s.id);
      while (d.poll(s.id).phase != CommandPhase::done) {
        if (d.poll(s.id).phase == CommandPhase::failed || sim_over) return;
        finished.wait_for(std::chrono::seconds(1));  // the simulation thread sets it; the timeout only ends a failure
      }
      last_goal = goal;
    }
    owner_done = true;
  });
  // The simulation thread: advances until the owner has seen all three moves done (bounded in simulation time).
  while (!owner_done && world().now() < 60s) world().advance(kPeriod);
  sim_over = true;
  finished.set();
  owner.join();
  ASSERT_TRUE(owner_done);
  EXPECT_EQ(ids, (std::vector<drivers::CommandId>{2, 3, 4}));
  const Eigen::VectorXd goal = Eigen::Map<const Eigen::VectorXd>(last_goal.data(), 6);
  EXPECT_LT((joints_now("puma") - goal).cwiseAbs().maxCoeff(), 0.002);
}

}  // namespace
}  // namespace cellwright::twin::sim
