// The cycle-time estimate of a scenario: command durations from the kinematics, the controller's speeds and the
// lock-step turns, the part's arrival on the conveyor, a shift's parts fed as their bodies come back, and the timed
// net they feed; and, on every shipped scenario, the estimate against a lock-step run of it made here (so it stays
// true whatever the physics or the runtime become).
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/estimate.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "cellwright/task/to_net.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/twin/sim/grip_timing.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::cell {
namespace {

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

EstimateOptions uniform(double joint_speed, double min_move_time) {
  EstimateOptions o;
  for (const char* robot : {"puma", "melfa"}) {
    RobotTiming t;
    t.max_joint_speed.assign(6, joint_speed);
    t.speed = 0.5;
    t.min_move_time = min_move_time;
    t.finger_speed = 0.05;
    t.finger_open = 0.04;
    t.finger_closed = 0.0;
    t.finger_squeeze = 0.002;
    o.robots[robot] = t;
  }
  o.control_period = 0.01;
  o.physics_step = 0.002;
  return o;
}

// The estimate of `s`'s program from its motion plan (the targets' defaults), as the preflight would plan it.
Estimate estimate_of(const Scenario& s, const petri::Net& net, const EstimateOptions& o) {
  return estimate_cycle_time(s, net, plan_motions(s, net, {}), o);
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
  const Estimate e = estimate_of(s_, net_, uniform(2.0, 0.2));
  EXPECT_TRUE(e.notes.empty()) << e.notes.front();
  ASSERT_EQ(e.commands.size(), 14u + 16u);
  for (const CommandEstimate& c : e.commands) {
    const task::Primitive& p = s_.program.programs[c.robot == "r1" ? 0 : 1].primitives[c.primitive];
    if (p.kind == task::PrimitiveKind::kMove) {
      // At least the shortest motion; then up to the end of its round, a round to read the position back and one to
      // fire the next transition.
      EXPECT_GE(c.motion, 0.2) << c.command;
      EXPECT_LT(c.motion, 10.0) << c.command;
      EXPECT_GT(c.seconds, c.motion + 2 * 0.01) << c.command;
      EXPECT_LE(c.seconds, c.motion + 3 * 0.01 + 0.002 + 1e-9) << c.command;  // (its end rounded to a 2 ms step)
      EXPECT_NEAR(std::remainder(c.seconds, 0.01), 0.0, 1e-9) << c.command;   // whole rounds
    } else if (p.kind == task::PrimitiveKind::kOpen || p.kind == task::PrimitiveKind::kClose) {
      EXPECT_GT(c.seconds, c.motion + 0.01) << c.command;  // no read-back
      EXPECT_LE(c.seconds, c.motion + 2 * 0.01 + 0.002 + 1e-9) << c.command;
    } else {
      EXPECT_EQ(c.seconds, 0.0) << c.command;
    }
  }
  // "move at(A)" after "move above(A)" is a short straight drop: shorter than the move from home to above A.
  EXPECT_LT(find(e, "r1", 2).seconds, find(e, "r1", 1).seconds);
}

TEST_F(ExchangeEstimate, GripsTakeTheFingerTravelTheyReallyMake) {
  const Estimate e = estimate_of(s_, net_, uniform(2.0, 0.2));
  // r1's first open: the fingers are already open (homing opened them): the shortest finger motion.
  EXPECT_DOUBLE_EQ(find(e, "r1", 0).motion, sim::kFingerMinTime + sim::kFingerRestWindow);
  // Closing on A (40 mm across the fingers): done when the ramp has run the squeeze past the faces, well before
  // fully closed. The open that lets go of it (at the hand-over) is a release: from the part's faces only the
  // release clearance further, not the whole ramp back (sim_driver.hpp).
  const double full = sim::kQuinticPeakSpeed * 0.04 / 0.05;
  const double close = find(e, "r1", 3).motion - sim::kFingerRestWindow;
  EXPECT_NEAR(close, *sim::finger_press_time(0.04, 0.0, 0.02, 0.002, 0.05), 1e-9);
  EXPECT_GT(close, 0.3 * full);
  EXPECT_LT(close, 0.7 * full);
  const double clearance = RobotTiming{}.release_clearance;
  EXPECT_NEAR(find(e, "r1", 10).motion,
              sim::finger_ramp_duration(0.02, 0.02 + clearance, 0.05) + sim::kFingerRestWindow, 1e-12);
  EXPECT_LT(find(e, "r1", 10).motion, 0.2 * full);
}

TEST_F(ExchangeEstimate, FasterJointsMakeMovesProportionallyShorter) {
  // Without a minimum time a joint move's motion is distance / speed: twice the speed, half the time; grips do not
  // change.
  const Estimate slow = estimate_of(s_, net_, uniform(1.0, 0.0));
  const Estimate fast = estimate_of(s_, net_, uniform(2.0, 0.0));
  ASSERT_EQ(slow.commands.size(), fast.commands.size());
  for (std::size_t i = 0; i < slow.commands.size(); ++i) {
    if (slow.commands[i].command.starts_with("move")) {
      EXPECT_NEAR(fast.commands[i].motion, slow.commands[i].motion / 2, 1e-9) << slow.commands[i].command;
    } else {
      EXPECT_DOUBLE_EQ(fast.commands[i].seconds, slow.commands[i].seconds) << slow.commands[i].command;
    }
  }
  EXPECT_LT(fast.cycle_time, slow.cycle_time);
}

TEST_F(ExchangeEstimate, PuttingThePartOnTheBeltWaitsForItToReachTheStop) {
  const Estimate e = estimate_of(s_, net_, uniform(2.0, 0.2));
  // A starts on the input belt and rides it to the stop bar at the belt's speed.
  const models::ConveyorSpec& input = *s_.cell.find_conveyor("input");
  const models::WorkpieceSpec& a = *s_.cell.find_workpiece("A");
  const double s0 = (input.pose.transform().inverse() * a.pose.xyz).x() + input.length / 2;
  const double arrival = (input.leave - a.size.x() / 2 - s0) / input.speed;
  ASSERT_GT(arrival, 1.0);
  // The move that goes above A (r1's primitive 1, started by r1.t1) waits for it; the open before it only for the
  // robot's bring-up.
  const auto t1 = *e.timed_net.find_transition(task::transition_id("r1", 1));
  const auto t0 = *e.timed_net.find_transition(task::transition_id("r1", 0));
  for (const TimedFiring& f : e.run.firings) {
    if (f.transition == t0) {
      // After the bring-up: homing (the shortest motion, 0.2 s) seen in round 21, the first command taken in 22.
      EXPECT_NEAR(f.time, 0.22, 1e-9);
    }
    if (f.transition == t1) {
      EXPECT_NEAR(f.time, std::ceil(arrival / 0.01 - 1e-9) * 0.01, 1e-9);  // seen in the round after
    }
  }
  EXPECT_TRUE(e.run.finished);
  EXPECT_GT(e.cycle_time, arrival);
  EXPECT_DOUBLE_EQ(e.cycle_time, e.run.finish);
}

TEST_F(ExchangeEstimate, CycleIsTheTimedNetsFinishWithTheseDurations) {
  const Estimate e = estimate_of(s_, net_, uniform(2.0, 0.2));
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
  EstimateOptions o = uniform(2.0, 0.2);
  o.robots.erase("melfa");
  EXPECT_THROW(estimate_of(s_, net_, o), InternalError);
}

// ---- A shift: ten parts of a class from three bodies, each fed again once it has left the cell ---------------------

// The relay belt (scenes/relay_belt.yaml): the MELFA's class `relayed` is whatever the relay belt brings to its stop,
// not a part of the input's feed. Its first move is planned to the relay's pick location; the PUMA's class takes the
// fed bodies.
TEST(RelayPlan, AClassTakenAtAnotherBeltsStopTakesNoFedBody) {
  const Scenario s = load_scenario(kScenes + "/relay_belt.yaml");
  const petri::Net net = task::to_net(s.program);
  const MotionPlan plan = plan_motions(s, net, {});
  std::map<std::string, std::pair<std::string, bool>> takes;  // label -> (location, fed)
  for (const MotionPlan::ClassTake& t : plan.class_takes) takes.emplace(t.label, std::make_pair(t.location, t.fed));
  EXPECT_EQ(takes.at("part"), std::make_pair(std::string("input_pick"), true));
  EXPECT_EQ(takes.at("relayed"), std::make_pair(std::string("relay_pick"), false));
  for (const PlannedCommand& c : plan.commands[1]) {
    EXPECT_TRUE(c.problem.empty()) << c.command << ": " << c.problem;
  }
}

class ShiftEstimate : public ::testing::Test {
 protected:
  ShiftEstimate() : s_(load_scenario(kScenes + "/pipeline_shift.yaml")), net_(task::to_net(s_.program)) {}

  // The times at which transitions with these ids fired in the estimate's timed run, in order.
  static std::vector<double> fired(const Estimate& e, const std::vector<std::string>& ids) {
    std::vector<double> out;
    for (const TimedFiring& f : e.run.firings) {
      const std::string& id = e.timed_net.transitions()[f.transition].id;
      if (std::find(ids.begin(), ids.end(), id) != ids.end()) out.push_back(f.time);
    }
    return out;
  }
  // The ids of the transitions that start these commands.
  std::vector<std::string> starting(const std::vector<petri::TransitionId>& transitions) const {
    std::vector<std::string> out;
    for (petri::TransitionId t : transitions) out.push_back(net_.transitions()[t].id);
    return out;
  }

  Scenario s_;
  petri::Net net_;
};

TEST_F(ShiftEstimate, TheFeedBringsThePartsAndTheOutputBeltTakesThemOut) {
  const MotionPlan plan = plan_motions(s_, net_, {});
  EXPECT_TRUE(plan.problems().empty()) << plan.problems().front();
  EXPECT_TRUE(plan.gates.empty());  // no named part
  // The PUMA's first Pick and the loop's take a new part each: their first moves, above it.
  ASSERT_EQ(plan.feed_takes.size(), 2u);
  for (petri::TransitionId t : plan.feed_takes) {
    const petri::Transition& tr = net_.transitions()[t];
    ASSERT_TRUE(tr.starts_robot.has_value());
    const PlannedCommand& c = plan.commands[*tr.starts_robot][static_cast<std::size_t>(tr.starts_primitive)];
    EXPECT_EQ(c.cell, "puma");
    EXPECT_EQ(c.command, "move above(part)");
  }
  // A part rides the input belt from its entry point to the stop bar, its centre 20 mm before it.
  const models::ConveyorSpec& input = *s_.cell.find_conveyor("input");
  EXPECT_NEAR(plan.feed_ride, (input.leave - 0.02 - input.enter) / input.speed, 1e-9);
  // The MELFA's two Places (in the loop and after it) let go of the part on the output belt where parts are put on
  // it (output_drop is its entry point); the world takes it out 5 cm before the stop bar at the belt's end.
  const models::ConveyorSpec& output = *s_.cell.find_conveyor("output");
  ASSERT_EQ(plan.deliveries.size(), 2u);
  for (const Delivery& d : plan.deliveries) {
    EXPECT_EQ(plan.commands[d.robot][d.primitive].cell, "melfa");
    EXPECT_EQ(plan.commands[d.robot][d.primitive].command, "open part");
    EXPECT_EQ(d.conveyor, "output");
    EXPECT_NEAR(d.distance, output.leave - 0.05 - output.enter, 1e-3);
    EXPECT_NEAR(d.ride, d.distance / output.speed, 1e-9);
  }
}

TEST_F(ShiftEstimate, APartComesAtItsFeedTimeOrWhenABodyIsBackWhicheverIsLater) {
  const Estimate e = estimate_of(s_, net_, uniform(2.0, 0.2));
  const MotionPlan plan = plan_motions(s_, net_, {});
  ASSERT_TRUE(e.run.finished);
  const std::vector<double> feeds = fired(e, {"feed.feed"});
  std::vector<petri::TransitionId> opens;
  for (const Delivery& d : plan.deliveries) opens.push_back(d.transition);
  const std::vector<double> delivered = fired(e, starting(opens));
  const std::vector<double> picks = fired(e, starting(plan.feed_takes));
  ASSERT_EQ(feeds.size(), 10u);
  ASSERT_EQ(delivered.size(), 10u);
  ASSERT_EQ(picks.size(), 10u);
  // A body is free once its part, let go of as the open starts (a release: the fingers no longer press it), has
  // ridden 0.87 m at 5 cm/s: the world takes it out in that control period, the feed puts it on the belt in the next.
  const double back = 0.87 / 0.05;
  for (std::size_t i = 0; i < feeds.size(); ++i) {
    const double due = 4.0 * static_cast<double>(i);  // feed: start 0, period 4 s
    const double body = i < 3 ? 0.0 : delivered[i - 3] + back;
    const double expected = std::max(due, body);
    EXPECT_GE(feeds[i], expected - 0.002) << "part " << i;  // (the release is rounded to the 2 ms physics step)
    EXPECT_LE(feeds[i], expected + 0.01 + 1e-9) << "part " << i;
    // The cell takes longer than the feed's period: from the fourth part on, every part waits for a body.
    if (i >= 3) {
      EXPECT_GT(body, due) << "part " << i;
    }
    // Each part is picked once it has ridden the input belt to the stop (1.03 m at 5 cm/s), not before.
    EXPECT_GE(picks[i], feeds[i] + 1.03 / 0.05 - 1e-9) << "part " << i;
  }
  EXPECT_NEAR(picks[0], 20.6, 1e-9);  // the first part: nothing in the way
}

TEST_F(ShiftEstimate, AFourthBodyShortensTheShiftAndTooFewPartsNeverEndIt) {
  const Estimate three = estimate_of(s_, net_, uniform(2.0, 0.2));
  Scenario four = s_;
  four.feed->workpieces.push_back("D");
  const Estimate more = estimate_of(four, net_, uniform(2.0, 0.2));
  ASSERT_TRUE(three.run.finished);
  ASSERT_TRUE(more.run.finished);
  EXPECT_LT(more.cycle_time, three.cycle_time - 4.0);
  // The program takes ten parts: a feed of nine leaves the last Pick waiting for ever.
  Scenario short_feed = s_;
  short_feed.feed->count = 9;
  EXPECT_FALSE(estimate_of(short_feed, net_, uniform(2.0, 0.2)).run.finished);
}

// A loop runs its body again from where the body's end left the arm: in scenes/relay_single.yaml the Pick's approach
// starts from home on the first pass and from above the take-away belt (the body's last move, half a turn of the
// waist away) on the eleven others. The estimate times it as the repeats make it; the moves that start where the
// move before them ended on every pass keep their one start.
TEST(LoopEstimate, ARepeatedMoveIsTimedFromWhereTheBodyLeavesTheArm) {
  const Scenario s = load_scenario(kScenes + "/relay_single.yaml");
  const petri::Net net = task::to_net(s.program);
  const MotionPlan plan = plan_motions(s, net, {});
  const std::vector<PlannedCommand>& r1 = plan.commands[0];
  ASSERT_GE(r1.size(), 9u);
  ASSERT_EQ(r1[1].command, "move above(part)");
  ASSERT_EQ(r1[8].command, "move above(AWAY)");
  EXPECT_EQ(r1[1].again_from, r1[8].goal);
  EXPECT_NE(r1[1].from, r1[8].goal);
  for (std::size_t k : {2u, 4u, 5u, 6u, 8u}) EXPECT_TRUE(r1[k].again_from.empty()) << k << " " << r1[k].command;

  const EstimateOptions o = uniform(2.0, 0.2);
  const Estimate e = estimate_cycle_time(s, net, plan, o);
  const auto v = [](const std::vector<double>& q) {
    return Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
  };
  const Eigen::VectorXd speeds = Eigen::VectorXd::Constant(6, 2.0);
  const double again = sim::move_duration(v(r1[1].again_from), v(r1[1].goal), speeds, 0.5, 0.2);
  const double first = sim::move_duration(v(r1[1].from), v(r1[1].goal), speeds, 0.5, 0.2);
  EXPECT_DOUBLE_EQ(find(e, "r1", 1).motion, again);
  EXPECT_GT(again, first + 1.0);  // the swing back from the take-away belt, not the short move from home
  EXPECT_THAT(find(e, "r1", 1).basis, ::testing::HasSubstr("as the loop repeats it"));
}

// The relay belt of scenes/relay_belt.yaml accumulates: while a part waits at its stop bar the belt stands, and the part
// the PUMA let go of behind it rides up only once the MELFA has lifted the one before. So each take of a part at the
// stop comes no earlier than the ride after the later of the part's put and the previous part's lift, and with arms
// fast enough for parts to wait behind each other, some takes wait for exactly that.
TEST(QueueEstimate, APartLetGoOfBehindAnotherRidesUpOnceThatOneIsLifted) {
  const Scenario s = load_scenario(kScenes + "/relay_belt.yaml");
  const petri::Net net = task::to_net(s.program);
  const MotionPlan plan = plan_motions(s, net, {});
  ASSERT_EQ(plan.queue_belts.size(), 1u);
  const MotionPlan::QueueBelt& q = plan.queue_belts[0];
  EXPECT_EQ(q.conveyor, "relay");
  ASSERT_EQ(q.puts.size(), 1u);
  ASSERT_EQ(q.takes.size(), 1u);
  ASSERT_EQ(q.lifts.size(), 1u);
  const auto command_of = [&](petri::TransitionId t) {
    const petri::Transition& tr = net.transitions()[t];
    return plan.commands[*tr.starts_robot][static_cast<std::size_t>(tr.starts_primitive)].command;
  };
  EXPECT_EQ(command_of(q.puts[0]), "open part");               // the PUMA's Place DROP lets go of it
  EXPECT_EQ(command_of(q.takes[0]), "move above(relayed)");    // the MELFA's Pick goes to it ...
  EXPECT_EQ(command_of(q.lifts[0]), "move above(relayed)");    // ... and lifts it after the close
  EXPECT_NE(q.takes[0], q.lifts[0]);
  // DROP is at the belt's upstream end (the part's centre at `enter`); the part stops half its length before the bar.
  const models::ConveyorSpec& relay = *s.cell.find_conveyor("relay");
  const double half = s.cell.find_workpiece("A")->size.x() / 2;
  EXPECT_NEAR(q.ride, (relay.leave - half - relay.enter) / relay.speed, 0.02);

  const Estimate e = estimate_cycle_time(s, net, plan, uniform(4.0, 0.2));
  ASSERT_TRUE(e.run.finished);
  std::vector<double> puts, takes, lifts;
  for (const TimedFiring& f : e.run.firings) {
    if (f.transition == q.puts[0]) puts.push_back(f.time);
    if (f.transition == q.takes[0]) takes.push_back(f.time);
    if (f.transition == q.lifts[0]) lifts.push_back(f.time);
  }
  ASSERT_EQ(puts.size(), 12u);
  ASSERT_EQ(takes.size(), 12u);
  ASSERT_EQ(lifts.size(), 12u);
  const double ride = std::ceil(q.ride / 0.01 - 1e-9) * 0.01;
  int waited = 0;
  for (std::size_t k = 0; k < takes.size(); ++k) {
    const double put = puts[k] + ride, lifted = k == 0 ? 0.0 : lifts[k - 1] + ride;
    EXPECT_GE(takes[k], std::max(put, lifted) - 1e-9) << "part " << k + 1;
    if (k > 0 && lifted > put && std::abs(takes[k] - lifted) < 1e-9) ++waited;
  }
  EXPECT_GE(waited, 5) << "the parts hardly ever queued: the test shows nothing";
}

// The beam (scenes/beam.yaml): two arms carry one beam in a coordinated block.
class BeamEstimate : public ::testing::Test {
 protected:
  BeamEstimate() : s_(load_scenario(kScenes + "/beam.yaml")), net_(task::to_net(s_.program)) {}
  // Per robot, the primitives of its moves in the block, in order.
  std::vector<std::size_t> segment_moves(std::size_t robot) const {
    std::vector<std::size_t> out;
    const auto& prims = s_.program.programs[robot].primitives;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      if (prims[k].segment && prims[k].kind == task::PrimitiveKind::kMove) out.push_back(k);
    }
    return out;
  }
  Scenario s_;
  petri::Net net_;
};

TEST_F(BeamEstimate, TheFollowerCarriesTheBeamWithTheGraspTransformOfTheGrasp) {
  const MotionPlan plan = plan_motions(s_, net_, {});
  EXPECT_TRUE(plan.problems().empty()) << plan.problems().front();
  const auto tool = [&](std::size_t robot, const std::vector<double>& q) {
    const models::RobotSpec& spec = *s_.cell.find_robot(s_.robot_of(s_.program.robots[robot]));
    const Eigen::VectorXd joints = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
    return spec.base.transform() * models::robot_chain(spec).forward(joints);
  };
  const std::vector<std::size_t> lead = segment_moves(0), follow = segment_moves(1);
  ASSERT_EQ(lead.size(), follow.size());
  ASSERT_EQ(s_.program.robots[0], "left");  // the master
  std::optional<Eigen::Isometry3d> grasp;
  int carried = 0;
  for (std::size_t i = 0; i < lead.size(); ++i) {
    const PlannedCommand& l = plan.commands[0][lead[i]];
    const PlannedCommand& f = plan.commands[1][follow[i]];
    ASSERT_FALSE(l.goal.empty()) << l.command << ": " << l.problem;
    ASSERT_FALSE(f.goal.empty()) << f.command << ": " << f.problem;
    EXPECT_NE(l.goal, l.from) << l.command;  // every segment moves the arm
    // Every move but the first approach goes straight.
    EXPECT_EQ(l.line_to.has_value(), i > 0) << l.command;
    EXPECT_EQ(f.line_to.has_value(), i > 0) << f.command;
    if (f.held.empty()) continue;
    // While both hold it, the follower's tool keeps the grasp transform to the master's: the beam is one body.
    const Eigen::Isometry3d relative = tool(0, l.goal).inverse() * tool(1, f.goal);
    if (!grasp) grasp = tool(0, l.from).inverse() * tool(1, f.from);
    EXPECT_TRUE(relative.isApprox(*grasp, 1e-6)) << f.command;
    ++carried;
  }
  EXPECT_GE(carried, 3);  // the lift, over MID, above and at FIX
}

TEST_F(BeamEstimate, EachSegmentTakesTheSlowerArmsTimeOnBothArms) {
  const Estimate even = estimate_of(s_, net_, uniform(2.0, 0.2));
  EstimateOptions slow_follower = uniform(2.0, 0.2);
  slow_follower.robots.at("melfa").max_joint_speed.assign(6, 0.5);
  const Estimate slowed = estimate_of(s_, net_, slow_follower);
  EXPECT_TRUE(slowed.notes.empty()) << slowed.notes.front();
  const std::vector<std::size_t> lead = segment_moves(0), follow = segment_moves(1);
  int longer = 0;
  for (std::size_t i = 0; i < lead.size(); ++i) {
    const CommandEstimate& l = find(slowed, "left", lead[i]);
    const CommandEstimate& f = find(slowed, "right", follow[i]);
    EXPECT_DOUBLE_EQ(l.motion, f.motion) << l.command;
    EXPECT_DOUBLE_EQ(l.seconds, f.seconds) << l.command;
    EXPECT_GE(l.motion, find(even, "left", lead[i]).motion) << l.command;
    if (l.motion > find(even, "left", lead[i]).motion + 0.05) ++longer;
    // lockstep_span (its end seen, the read-back, the next firing) and one period: posted in the round task control
    // starts it, submitted in the next (the master's turn comes first).
    const double rounds = std::floor(std::ceil(l.motion / 0.002 - 1e-9) * 0.002 / 0.01 + 1e-9) + 1;
    EXPECT_NEAR(l.seconds, (rounds + 2 + 1) * 0.01, 1e-9) << l.command;
  }
  EXPECT_GT(longer, 0);  // the slow follower holds the master back
  // The master's own move after the block (home) is its own.
  const std::size_t home = s_.program.programs[0].primitives.size() - 1;
  EXPECT_DOUBLE_EQ(find(slowed, "left", home).motion, find(even, "left", home).motion);
  EXPECT_GT(slowed.cycle_time, even.cycle_time);
}

// ---- The estimate against the twin -------------------------------------------------------------------------------

// Every scenario shipped in scenes/ (a YAML file with a program).
std::vector<std::string> shipped_scenarios() {
  std::vector<std::string> out;
  for (const auto& entry : std::filesystem::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".yaml") continue;
    std::ifstream in(entry.path());
    for (std::string line; std::getline(in, line);) {
      if (line.starts_with("program:")) {
        out.push_back(entry.path().filename().string());
        break;
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Per robot command: when the estimate and the run started it, and how long each took (for a failure's message).
std::string comparison(const Estimate& e, const std::string& events_text) {
  std::map<std::string, double> est_fire, fire;
  for (const TimedFiring& f : e.run.firings) est_fire.emplace(e.timed_net.transitions()[f.transition].id, f.time);
  for (const runtime::LoggedEvent& ev : runtime::decode_log(events_text, "events.jsonl")) {
    if (const auto* f = std::get_if<runtime::events::Fire>(&ev.event)) {
      fire.emplace(f->transition, std::chrono::duration<double>(f->t).count());
    }
  }
  std::string out = "robot primitive command: started estimated / measured, lasted estimated / measured (s)\n";
  for (std::size_t i = 0; i < e.commands.size(); ++i) {
    const CommandEstimate& c = e.commands[i];
    const auto at = [](const std::map<std::string, double>& m, const std::string& id) {
      const auto it = m.find(id);
      return it == m.end() ? -1.0 : it->second;
    };
    const std::string id = task::transition_id(c.robot, c.primitive);
    const std::string next = task::transition_id(c.robot, c.primitive + 1);
    out += fmt::format("{} {:2} {:28} {:8.2f} / {:8.2f}  {:6.2f} / {:6.2f}  {}\n", c.robot, c.primitive, c.command,
                       at(est_fire, id), at(fire, id), c.seconds, at(fire, next) - at(fire, id), c.basis);
  }
  return out;
}

class ShippedScenario : public ::testing::TestWithParam<std::string> {};

// The target of docs/scenarios.md: the estimate printed before a run within 5 % of the cycle the run measures (the
// last firing), on every shipped scenario, from a lock-step run made here.
TEST_P(ShippedScenario, EstimateIsWithinFivePercentOfTheMeasuredCycle) {
  const Scenario s = load_scenario(kScenes + "/" + GetParam());
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();
  ScenarioRun run(s, pre);
  const Estimate& e = run.estimate();
  EXPECT_TRUE(e.run.finished);
  EXPECT_TRUE(e.notes.empty()) << e.notes.front();
  ASSERT_EQ(run.runtime().run().outcome, runtime::Outcome::kFinished);
  const Report report = run.report();
  ASSERT_TRUE(report.finished_at.has_value());
  // What `twin test scenes/` checks of it: every expected outcome holds.
  EXPECT_TRUE(report.ok()) << GetParam() << ": " << report.failures.front();
  // Carries are measured for coordinated blocks only: the exchange's hand-over, two hands on a part for a moment, is
  // none; the beam's carry is one.
  if (s.program.coordinated.empty()) {
    EXPECT_TRUE(report.carries.empty()) << GetParam() << ": a carry of " << report.carries.front().workpiece;
  } else {
    EXPECT_FALSE(report.carries.empty()) << GetParam();
  }
  const double measured = *report.finished_at;
  const double error = (e.cycle_time - measured) / measured;
  RecordProperty("estimated_cycle_s", fmt::format("{:.2f}", e.cycle_time));
  RecordProperty("measured_cycle_s", fmt::format("{:.2f}", measured));
  EXPECT_LE(std::abs(error), 0.05) << fmt::format("estimated {:.2f} s, measured {:.2f} s ({:+.1f} %)\n", e.cycle_time,
                                                  measured, 100 * error)
                                   << comparison(e, run.runtime().log().text());
}

INSTANTIATE_TEST_SUITE_P(Scenes, ShippedScenario, ::testing::ValuesIn(shipped_scenarios()),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param.substr(0, param.param.find('.'));
                           for (char& ch : name) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace cellwright::cell
