// The cycle-time estimate of a scenario: command durations from the kinematics and the controller's speeds, the
// part's arrival on the conveyor, and the timed net they feed.
#include "cellwright/twin/scenario/estimate.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "cellwright/task/to_net.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::twin::scenario {
namespace {

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

EstimateOptions uniform(double joint_speed, double min_move_time, double dispatch) {
  EstimateOptions o;
  for (const char* robot : {"puma", "melfa"}) {
    RobotTiming t;
    t.max_joint_speed.assign(6, joint_speed);
    t.speed = 0.5;
    t.min_move_time = min_move_time;
    t.finger_speed = 0.05;
    t.finger_travel = 0.04;
    o.robots[robot] = t;
  }
  o.dispatch = dispatch;
  return o;
}

const CommandEstimate& find(const Estimate& e, const std::string& robot, std::size_t primitive) {
  for (const auto& c : e.commands) {
    if (c.robot == robot && c.primitive == primitive) return c;
  }
  throw std::runtime_error("no such command");
}

class ExchangeEstimate : public ::testing::Test {
 protected:
  ExchangeEstimate() : s_(load_scenario(kScenes + "/exchange.yaml")), net_(task::to_net(s_.program)) {}
  Scenario s_;
  petri::Net net_;
};

TEST_F(ExchangeEstimate, CommandDurationsFollowTheirKinds) {
  const Estimate e = estimate_cycle_time(s_, net_, uniform(2.0, 0.2, 0.02));
  EXPECT_TRUE(e.notes.empty()) << e.notes.front();
  ASSERT_EQ(e.commands.size(), 14u + 16u);
  const double grip = sim::kQuinticPeakSpeed * 0.04 / 0.05 + 0.02;
  for (const CommandEstimate& c : e.commands) {
    const task::Primitive& p = s_.program.programs[c.robot == "r1" ? 0 : 1].primitives[c.primitive];
    switch (p.kind) {
      case task::PrimitiveKind::kMove:
        EXPECT_GE(c.seconds, 0.2 + 0.02) << c.command;
        EXPECT_LT(c.seconds, 10.0) << c.command;
        break;
      case task::PrimitiveKind::kOpen:
      case task::PrimitiveKind::kClose:
        EXPECT_DOUBLE_EQ(c.seconds, grip) << c.command;
        break;
      case task::PrimitiveKind::kSignal:
      case task::PrimitiveKind::kWait:
        EXPECT_EQ(c.seconds, 0.0) << c.command;
        break;
    }
  }
  // "move at(A)" after "move above(A)" is a short straight drop: shorter than the move from home to above A.
  EXPECT_LT(find(e, "r1", 2).seconds, find(e, "r1", 1).seconds);
}

TEST_F(ExchangeEstimate, FasterJointsMakeMovesProportionallyShorter) {
  // Without a minimum time or dispatch cost a joint move's duration is distance / speed: twice the speed, half the
  // time; grips do not change.
  const Estimate slow = estimate_cycle_time(s_, net_, uniform(1.0, 0.0, 0.0));
  const Estimate fast = estimate_cycle_time(s_, net_, uniform(2.0, 0.0, 0.0));
  ASSERT_EQ(slow.commands.size(), fast.commands.size());
  for (std::size_t i = 0; i < slow.commands.size(); ++i) {
    if (slow.commands[i].command.starts_with("move")) {
      EXPECT_NEAR(fast.commands[i].seconds, slow.commands[i].seconds / 2, 1e-9) << slow.commands[i].command;
    } else {
      EXPECT_DOUBLE_EQ(fast.commands[i].seconds, slow.commands[i].seconds) << slow.commands[i].command;
    }
  }
  EXPECT_LT(fast.cycle_time, slow.cycle_time);
}

TEST_F(ExchangeEstimate, PuttingThePartOnTheBeltWaitsForItToReachTheStop) {
  const Estimate e = estimate_cycle_time(s_, net_, uniform(2.0, 0.2, 0.02));
  // A starts on the input belt and rides it to the stop bar at the belt's speed.
  const models::ConveyorSpec& input = *s_.cell.find_conveyor("input");
  const models::WorkpieceSpec& a = *s_.cell.find_workpiece("A");
  const double s0 = (input.pose.transform().inverse() * a.pose.xyz).x() + input.length / 2;
  const double arrival = (input.leave - a.size.x() / 2 - s0) / input.speed;
  ASSERT_GT(arrival, 1.0);
  // The move that goes above A (r1's primitive 1, started by r1.t1) waits for it; the open before it does not.
  const auto t1 = *e.timed_net.find_transition(task::transition_id("r1", 1));
  const auto t0 = *e.timed_net.find_transition(task::transition_id("r1", 0));
  for (const TimedFiring& f : e.run.firings) {
    if (f.transition == t0) {
      EXPECT_DOUBLE_EQ(f.time, 0.0);
    }
    if (f.transition == t1) {
      EXPECT_NEAR(f.time, arrival, 1e-9);
    }
  }
  EXPECT_TRUE(e.run.finished);
  EXPECT_GT(e.cycle_time, arrival);
  EXPECT_DOUBLE_EQ(e.cycle_time, e.run.finish);
}

TEST_F(ExchangeEstimate, CycleIsTheTimedNetsFinishWithTheseDurations) {
  const Estimate e = estimate_cycle_time(s_, net_, uniform(2.0, 0.2, 0.02));
  const TimedRun again = simulate_timed(e.timed_net, e.place_duration);
  EXPECT_DOUBLE_EQ(again.finish, e.cycle_time);
  // The critical path after the pick: r2 cannot start its approach before r1's step 1 ends, and places last. The
  // cycle is at least the sum of r2's commands from then on.
  double r2_after_barrier = 0;
  for (const CommandEstimate& c : e.commands) {
    if (c.robot == "r2" && c.primitive >= 2) r2_after_barrier += c.seconds;
  }
  double r1_pick = 0;
  for (const CommandEstimate& c : e.commands) {
    if (c.robot == "r1" && c.primitive <= 4) r1_pick += c.seconds;
  }
  EXPECT_GE(e.cycle_time + 1e-9, r1_pick + r2_after_barrier);
}

TEST_F(ExchangeEstimate, RobotWithoutTimingIsABug) {
  EstimateOptions o = uniform(2.0, 0.2, 0.02);
  o.robots.erase("melfa");
  EXPECT_THROW(estimate_cycle_time(s_, net_, o), InternalError);
}

}  // namespace
}  // namespace cellwright::twin::scenario
