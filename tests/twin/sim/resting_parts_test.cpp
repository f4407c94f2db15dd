// Resting parts sleep (twin/src/sim/resting_parts.hpp): a part still on something still leaves the physics, stays
// exactly where it lies and is reported as before (support, location, the machine loaded); a belt that starts, a
// part taken from the queue or a gripper coming near wakes it before anything touches it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>


#include "cellwright/twin/sim/world.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using drivers::CommandPhase;
using drivers::Path;
using namespace testing;  // NOLINT: the simulation test helpers

class RestingPartsTest : public PaperCellTest {
 protected:
  WorkpieceTruth part(const std::string& name) const {
    for (const WorkpieceTruth& w : world_->truth().workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }
  // Contacts MuJoCo found for a workpiece's geom in the last step.
  int contacts_of(const std::string& name) const {
    const WorkpieceIds* ids = nullptr;
    for (const WorkpieceIds& w : world_->scene().workpieces()) {
      if (w.name == name) ids = &w;
    }
    const mjData* d = world_->data();
    int n = 0;
    for (int c = 0; c < d->ncon; ++c) n += d->contact[c].geom1 == ids->geom || d->contact[c].geom2 == ids->geom;
    return n;
  }
};

TEST_F(RestingPartsTest, APartOnTheFixtureSleepsWhereItLiesAndIsReportedAsBefore) {
  world_->advance(50ms);
  EXPECT_FALSE(world_->asleep("D"));  // still settling on its contacts
  EXPECT_GT(contacts_of("D"), 0);
  world_->advance(500ms);
  ASSERT_TRUE(world_->asleep("D"));
  const WorkpieceTruth before = part("D");
  for (int i = 0; i < 500; ++i) {
    world_->advance(kPeriod);
    const WorkpieceTruth now = part("D");
    ASSERT_TRUE(now.pose.isApprox(before.pose, 0.0)) << "moved at " << world_->time() << " s";
    EXPECT_EQ(now.linear_velocity.norm(), 0.0);
  }
  EXPECT_EQ(contacts_of("D"), 0);  // out of the physics
  const WorkpieceTruth d = part("D");
  EXPECT_EQ(d.support, SupportKind::machine);
  EXPECT_EQ(d.support_name, "mill");
  EXPECT_EQ(d.location, "machine_fixture");
  EXPECT_TRUE(d.upright);
  ASSERT_EQ(world_->devices().machines.size(), 1u);
  EXPECT_EQ(world_->devices().machines[0].state, MachineState::loaded);
}

TEST_F(RestingPartsTest, TheQueueOnAStoppedBeltSleepsAndMovesOnWhenTheFirstPartIsTaken) {
  const int eye = paper_cell().find_conveyor("input")->sensor;
  while (world_->now() < 60s && !(part("A").location == "input_pick" && world_->signals().get(eye))) {
    world_->advance(100ms);
  }
  ASSERT_EQ(part("A").location, "input_pick");
  world_->advance(1s);
  // The belt stopped under the queue (it accumulates): every part on it sleeps, and the eye still sees A.
  EXPECT_LT(std::abs(world_->truth().conveyors[0].belt_speed), 1e-3);
  for (const char* name : {"A", "B", "C"}) {
    EXPECT_TRUE(world_->asleep(name)) << name;
    EXPECT_EQ(part(name).support, SupportKind::conveyor) << name;
    EXPECT_EQ(part(name).support_name, "input") << name;
  }
  EXPECT_TRUE(world_->signals().get(eye));
  // A is taken away: the belt runs again, wakes the parts on it, and brings B to the stop.
  const double b_was = part("B").pose.translation().x();
  ASSERT_TRUE(world_->park("A").ok());
  world_->advance(100ms);
  EXPECT_GT(world_->truth().conveyors[0].belt_speed, 0.04);
  EXPECT_FALSE(world_->asleep("B"));
  EXPECT_FALSE(world_->asleep("C"));
  while (world_->now() < 90s && !(part("B").location == "input_pick" && world_->signals().get(eye))) {
    world_->advance(100ms);
  }
  EXPECT_EQ(part("B").location, "input_pick");
  EXPECT_GT(part("B").pose.translation().x(), b_was + 0.03);
  world_->advance(1s);
  EXPECT_TRUE(world_->asleep("B"));
  EXPECT_TRUE(world_->asleep("A"));  // parked parts sleep too
  EXPECT_TRUE(world_->new_collisions().empty());
}

TEST_F(RestingPartsTest, AGripperComingNearWakesThePartBeforeItTouchesAndLeavesItWhereItWas) {
  SimDriver& puma = world_->add_sim_driver("puma");
  bring_up(*world_, puma);
  world_->advance(500ms);
  ASSERT_TRUE(world_->asleep("D"));
  const WorkpieceTruth before = part("D");
  const double yaw = paper_cell().find_location("machine_fixture")->pose.rpy.z();
  const double half = paper_cell().find_workpiece("D")->size.z() / 2;
  // The tool centre point (the open fingers' tips) 1 cm above the part's top: close, not touching.
  const Eigen::Vector3d above = before.pose.translation() + Eigen::Vector3d(0, 0, half + 0.01);
  const Eigen::Isometry3d start = base_of(*world_, "puma").inverse() * world_->truth().robots[0].tcp;
  bool woke = false, touched = false;
  const auto watch = [&] {
    woke = woke || !world_->asleep("D");
    const RobotTruth& r = world_->truth().robots[0];
    touched = touched || r.finger_contact[0] || r.finger_contact[1];
  };
  const auto s = execute(*world_, puma, pose_move(down_at(*world_, "puma", above, yaw), Path::joint, 0.5), 20s, watch);
  ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  EXPECT_TRUE(woke);
  EXPECT_FALSE(touched);
  EXPECT_FALSE(world_->asleep("D"));  // the fingers are near
  EXPECT_LT((part("D").pose.translation() - before.pose.translation()).norm(), 5e-4);
  EXPECT_EQ(part("D").support, SupportKind::machine);
  // The arm goes back; the part falls asleep again where it lay.
  ASSERT_EQ(execute(*world_, puma, pose_move(start, Path::joint, 0.5)).phase, CommandPhase::done);
  world_->advance(500ms);
  EXPECT_TRUE(world_->asleep("D"));
  EXPECT_LT((part("D").pose.translation() - before.pose.translation()).norm(), 5e-4);
  EXPECT_TRUE(world_->new_collisions().empty());
}

}  // namespace
}  // namespace cellwright::twin::sim
