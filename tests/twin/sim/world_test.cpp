// The simulated world: exact time, ground truth that says where parts are and what carries them, the workpiece
// feed, collision reports, MuJoCo's warnings surfaced, and bit-identical repeated runs.
#include "cellwright/twin/sim/world.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>

#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using drivers::CommandPhase;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using namespace testing;  // NOLINT: the simulation test helpers

class WorldTest : public cellwright::testing::MujocoTest {
 protected:
  void TearDown() override {
    for (World* w : worlds_) {
      expect_no_data_warnings(w->data());
      EXPECT_THAT(w->drain_warnings(), ::testing::IsEmpty());
    }
    MujocoTest::TearDown();
  }
  // A world checked for warnings when the test ends.
  World& make(WorldOptions options = {}) {
    owned_.push_back(std::make_unique<World>(build_scene(paper_cell()), std::move(options)));
    worlds_.push_back(owned_.back().get());
    return *owned_.back();
  }
  static const WorkpieceTruth& part(const WorldTruth& t, const std::string& name) {
    for (const auto& w : t.workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }

  std::vector<std::unique_ptr<World>> owned_;
  std::vector<World*> worlds_;
};

TEST_F(WorldTest, CountsTimeInWholeSteps) {
  World& w = make();
  EXPECT_EQ(w.timestep(), 5ms);  // the cell's timestep
  for (int i = 0; i < 1000; ++i) w.advance(kPeriod);
  EXPECT_EQ(w.now(), 10s);
  EXPECT_EQ(w.steps(), 2000);
  EXPECT_DOUBLE_EQ(w.time(), 10.0);
  EXPECT_THROW(w.advance(3ms), InternalError);
  EXPECT_THROW(w.advance(-5ms), InternalError);
  w.advance(0ms);
  EXPECT_EQ(w.steps(), 2000);
}

TEST_F(WorldTest, TruthDescribesTheCellAsItStarts) {
  World& w = make();
  WorldTruth t = w.truth();
  EXPECT_EQ(t.time, 0ns);
  ASSERT_EQ(t.robots.size(), 2u);
  for (const RobotTruth& r : t.robots) {
    const models::RobotSpec& spec = *paper_cell().find_robot(r.name);
    ASSERT_EQ(r.joints.size(), spec.home.size());
    for (std::size_t j = 0; j < r.joints.size(); ++j) EXPECT_NEAR(r.joints[j], spec.home[j], 1e-9) << r.name;
    EXPECT_NEAR(r.finger_opening, 0.08, 1e-9) << r.name;
    EXPECT_FALSE(r.finger_contact[0] || r.finger_contact[1]) << r.name;
  }
  ASSERT_EQ(t.workpieces.size(), 4u);
  // The parts start touching their supports without pressing on them yet: give the contacts a step or two.
  w.advance(kPeriod);
  t = w.truth();
  // A, B, C lie on the input conveyor; D sits in the machine's fixture, at its location.
  for (const char* name : {"A", "B", "C"}) {
    EXPECT_EQ(part(t, name).support, SupportKind::conveyor) << name;
    EXPECT_EQ(part(t, name).support_name, "input") << name;
    EXPECT_TRUE(part(t, name).upright) << name;
    EXPECT_FALSE(part(t, name).held_by) << name;
  }
  EXPECT_EQ(part(t, "D").support, SupportKind::machine);
  EXPECT_EQ(part(t, "D").support_name, "mill");
  EXPECT_EQ(part(t, "D").location, "machine_fixture");
  ASSERT_EQ(t.conveyors.size(), 2u);
}

TEST_F(WorldTest, TheInputConveyorBringsTheFirstPartToThePickLocation) {
  World& w = make();
  // At rest as the stop's part-present sensor sees it: its speed averaged over 0.1 s under the runtime's rest speed.
  // (Its instantaneous speed chatters: below.)
  const int sensor = paper_cell().find_conveyor("input")->sensor;
  while (w.now() < 60s && !(part(w.truth(), "A").location == "input_pick" && w.signals().get(sensor))) {
    w.advance(100ms);
  }
  const WorldTruth t = w.truth();
  const WorkpieceTruth& a = part(t, "A");
  EXPECT_EQ(a.location, "input_pick") << "A at " << a.pose.translation().transpose() << " after " << w.time() << " s";
  EXPECT_TRUE(w.signals().get(sensor));
  EXPECT_TRUE(a.upright);
  // Against the stop, with the belt stopped under it (the conveyor accumulates: world.hpp, "DEVICES"), the part
  // stays at the location, on the belt, seen at rest by the sensor.
  int on_belt = 0;
  for (int i = 0; i < 100; ++i) {
    w.advance(kPeriod);
    const WorkpieceTruth now = part(w.truth(), "A");
    EXPECT_EQ(now.location, "input_pick");
    EXPECT_LT(std::abs(now.pose.translation().z() - a.pose.translation().z()), 0.0005);
    if (now.support == SupportKind::conveyor && now.support_name == "input") ++on_belt;
    EXPECT_TRUE(w.signals().get(sensor)) << "at " << w.time() << " s";
  }
  EXPECT_EQ(on_belt, 100);
  // The belt stopped when the part blocked the stop's eye.
  EXPECT_LT(std::abs(w.truth().conveyors[0].belt_speed), 1e-3);
  EXPECT_TRUE(w.new_collisions().empty());
}

TEST_F(WorldTest, FeedsParkedPartsOntoTheConveyorEntry) {
  WorldOptions options;
  options.parked = {"B", "C"};
  World& w = make(options);
  WorldTruth t = w.truth();
  EXPECT_TRUE(part(t, "B").parked);
  EXPECT_EQ(part(t, "B").support, SupportKind::parked);
  EXPECT_TRUE(w.parked("C"));
  EXPECT_FALSE(w.parked("A"));
  // Parked parts wait outside the cell, clear of everything, at rest on the floor.
  w.advance(500ms);
  t = w.truth();
  EXPECT_LT(part(t, "B").linear_velocity.norm(), 1e-4);
  EXPECT_GT(part(t, "B").pose.translation().x(), 1.5);

  EXPECT_EQ(w.feed("X", "input").status, FeedStatus::unknown_workpiece);
  EXPECT_EQ(w.feed("B", "nowhere").status, FeedStatus::unknown_conveyor);
  EXPECT_EQ(w.feed("A", "input").status, FeedStatus::not_parked);
  ASSERT_TRUE(w.feed("B", "input").ok());
  t = w.truth();
  const models::ConveyorSpec& input = paper_cell().conveyors[0];
  const Eigen::Vector3d entry = input.belt_point(input.enter) + Eigen::Vector3d(0, 0, 0.03);
  EXPECT_LT((part(t, "B").pose.translation() - entry).norm(), 1e-9);
  EXPECT_EQ(part(t, "B").linear_velocity.norm(), 0.0);
  EXPECT_FALSE(part(t, "B").parked);
  // B still occupies the entry: C must wait until the belt has taken B away.
  const FeedResult busy = w.feed("C", "input");
  EXPECT_EQ(busy.status, FeedStatus::occupied);
  EXPECT_THAT(busy.message, HasSubstr("'B'"));
  w.advance(2s);
  t = w.truth();
  EXPECT_EQ(part(t, "B").support, SupportKind::conveyor);
  EXPECT_GT(part(t, "B").pose.translation().x(), entry.x() + 0.06) << "the belt carries it";
  EXPECT_TRUE(w.feed("C", "input").ok());
  w.advance(1s);
  EXPECT_EQ(part(w.truth(), "C").support, SupportKind::conveyor);
  ASSERT_TRUE(w.park("C").ok());
  EXPECT_TRUE(w.parked("C"));
  EXPECT_EQ(w.park("nothing").status, FeedStatus::unknown_workpiece);
  EXPECT_TRUE(w.new_collisions().empty());
}

TEST_F(WorldTest, RefusesUnknownParkedParts) {
  WorldOptions options;
  options.where = {"feed.yaml", 4, 9};
  options.parked = {"Z"};
  try {
    World w(build_scene(paper_cell()), options);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("feed.yaml:4:9"));
    EXPECT_THAT(e.what(), HasSubstr("'Z'"));
  }
}

TEST_F(WorldTest, ReportsTwoRobotsDrivenIntoEachOtherOnce) {
  World& w = make();
  SimDriver& puma = w.add_sim_driver("puma");
  SimDriver& melfa = w.add_sim_driver("melfa");
  bring_up(w, puma);
  bring_up(w, melfa);
  EXPECT_TRUE(w.new_collisions().empty());
  // Both grippers to the same point between the arms (the hand-over point, where their grasps are meant to be
  // 4 cm apart): the PUMA's from above, the MELFA's from the side.
  const Eigen::Vector3d meet = paper_cell().handover->pose.xyz;
  const Eigen::Isometry3d melfa_base = base_of(w, "melfa");
  const drivers::Submitted a = puma.submit(pose_move(down_at(w, "puma", meet, 1.57), drivers::Path::joint));
  const drivers::Submitted b = melfa.submit(pose_move(
      melfa_base.inverse() * models::grasp_pose(meet, models::Approach::kSide, 0.0, melfa_base), drivers::Path::joint));
  ASSERT_TRUE(a.accepted() && b.accepted());
  std::vector<Collision> seen;
  for (int i = 0; i < 400; ++i) {
    w.advance(kPeriod);
    for (Collision& c : w.new_collisions()) seen.push_back(std::move(c));
  }
  ASSERT_FALSE(seen.empty()) << "puma: " << puma.poll(a.id).message << "; melfa: " << melfa.poll(b.id).message;
  const Collision& first = seen.front();
  EXPECT_THAT((std::vector<std::string>{first.robot1, first.robot2}), ::testing::UnorderedElementsAre("puma", "melfa"));
  EXPECT_THAT(first.body1 + " " + first.body2, HasSubstr("puma/"));
  EXPECT_THAT(first.body1 + " " + first.body2, HasSubstr("melfa/"));
  EXPECT_GE(first.depth, 0.0);
  EXPECT_LT((first.position - meet).norm(), 0.3);
  EXPECT_GT(first.time, 0ns);
  // Each pair is reported when it starts touching, not every step while it touches.
  std::set<std::pair<std::string, std::string>> pairs;
  for (const Collision& c : seen) pairs.emplace(c.body1, c.body2);
  EXPECT_EQ(seen.size(), pairs.size()) << "a pair reported more than once while the arms pressed on each other";
  // The arm that arrives second is blocked by the other: it cannot settle and fails with the joint errors.
  const auto sa = run_until_finished(w, puma, a.id);
  const auto sb = run_until_finished(w, melfa, b.id);
  const auto& blocked = sa.error == drivers::ErrorCode::timeout ? sa : sb;
  EXPECT_EQ(blocked.error, drivers::ErrorCode::timeout) << "puma: " << sa.message << "; melfa: " << sb.message;
  EXPECT_THAT(blocked.message, HasSubstr("joint errors"));
  w.new_collisions();
  // Nothing but the two robots touched.
  for (const Collision& c : seen) {
    EXPECT_FALSE(c.robot1.empty() || c.robot2.empty()) << c.body1 << " / " << c.body2 << " at " << c.time.count();
  }
}

TEST_F(WorldTest, ReportsARobotHittingTheConveyor) {
  World& w = make();
  SimDriver& puma = w.add_sim_driver("puma");
  bring_up(w, puma);
  // The fingers down into the input conveyor, upstream of the parts, 3 cm below its belt.
  const models::ConveyorSpec& input = paper_cell().conveyors[0];
  const Eigen::Vector3d below = input.belt_point(input.leave - 0.25) - Eigen::Vector3d(0, 0, 0.03);
  ASSERT_EQ(
      execute(w, puma, pose_move(down_at(w, "puma", below + Eigen::Vector3d(0, 0, 0.15), 1.57), drivers::Path::joint))
          .phase,
      CommandPhase::done);
  ASSERT_TRUE(w.new_collisions().empty());
  execute(w, puma, pose_move(down_at(w, "puma", below, 1.57), drivers::Path::linear, 0.2), 10s);
  const std::vector<Collision> hits = w.new_collisions();
  ASSERT_FALSE(hits.empty());
  EXPECT_EQ(hits.front().robot1, "puma");
  EXPECT_EQ(hits.front().robot2, "");
  EXPECT_THAT(hits.front().body2, StartsWith("conveyor/input"));
}

TEST_F(WorldTest, SurfacesMujocoWarnings) {
  World& w = make();
  SimDriver& puma = w.add_sim_driver("puma");
  bring_up(w, puma);
  const auto wait = puma.submit(drivers::WaitInput{1, true, {}});
  // MuJoCo raises its warnings through counters in mjData; stand in for a real overflow here.
  mjData* d = const_cast<mjData*>(w.data());  // NOLINT: the test plays MuJoCo
  mj_warning(d, mjWARN_INERTIA, 1000);
  warnings().clear();  // the fixture's handler saw it too
  w.advance(kPeriod);
  EXPECT_TRUE(w.warnings());
  std::vector<std::string> lines = w.drain_warnings();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("inertia matrix"));
  EXPECT_THAT(lines[0], HasSubstr("last info 1000"));
  EXPECT_THAT(lines[0], StartsWith("t=0."));
  EXPECT_FALSE(w.warnings());
  EXPECT_EQ(puma.state(), drivers::DriverState::active);
  // Bad accelerations make MuJoCo reset the simulation: the drivers fault.
  mj_warning(d, mjWARN_BADQACC, 3);
  warnings().clear();
  w.advance(kPeriod);
  lines = w.drain_warnings();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("bad qacc"));
  EXPECT_EQ(puma.state(), drivers::DriverState::fault);
  EXPECT_EQ(puma.poll(wait.id).error, drivers::ErrorCode::hardware);
  // The counters were raised on purpose: clear them for the fixture's check.
  for (int i = 0; i < mjNWARNING; ++i) d->warning[i].number = 0;
}

// A full contact or constraint buffer means MuJoCo dropped contacts: parts fall through what holds them. The drivers
// fault, and the message says the scene's buffers were too small, with their sizes.
TEST_F(WorldTest, AFullContactBufferFaultsTheRobotsAndSaysWhy) {
  for (const int warning : {mjWARN_CONTACTFULL, mjWARN_CNSTRFULL}) {
    World& w = make();
    SimDriver& puma = w.add_sim_driver("puma");
    bring_up(w, puma);
    const auto wait = puma.submit(drivers::WaitInput{1, true, {}});
    mjData* d = const_cast<mjData*>(w.data());  // NOLINT: the test plays MuJoCo
    mj_warning(d, warning, 1000);
    warnings().clear();
    w.advance(kPeriod);
    const std::vector<std::string> lines = w.drain_warnings();
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_THAT(lines[0], HasSubstr("buffer is full"));
    EXPECT_EQ(puma.state(), drivers::DriverState::fault);
    const drivers::CommandStatus st = puma.poll(wait.id);
    EXPECT_EQ(st.error, drivers::ErrorCode::hardware);
    EXPECT_THAT(st.message, HasSubstr("dropped contacts"));
    EXPECT_THAT(st.message, HasSubstr(fmt::format("{} constraint rows, {} contacts", w.scene().model()->njmax,
                                                  w.scene().model()->nconmax)));
    for (int i = 0; i < mjNWARNING; ++i) d->warning[i].number = 0;
  }
}

// Runs a fixed script of commands on a fresh world for 5 s of simulation time.
std::vector<double> scripted_run(bool with_drivers) {
  World w(build_scene(paper_cell()));
  if (with_drivers) {
    SimDriver& puma = w.add_sim_driver("puma");
    SimDriver& melfa = w.add_sim_driver("melfa");
    puma.connect();
    melfa.connect();
    puma.home();
    melfa.home();
    w.advance(1s);
    puma.activate();
    melfa.activate();
    std::vector<double> goal = paper_cell().find_robot("puma")->home;
    goal[0] -= 0.8;
    puma.submit(drivers::MoveJoints{goal, 0.7});
    puma.submit(grip(drivers::Grip::Action::close));
    melfa.submit(pose_move(down_at(w, "melfa", {0.6, 0.2, 0.6}, 0.5), drivers::Path::linear, 0.5));
  }
  w.advance(4s);
  const mjData* d = w.data();
  std::vector<double> state(d->qpos, d->qpos + w.scene().model()->nq);
  state.insert(state.end(), d->qvel, d->qvel + w.scene().model()->nv);
  return state;
}

TEST_F(WorldTest, IdenticalRunsGiveBitIdenticalStates) {
  for (bool drivers : {false, true}) {
    const std::vector<double> a = scripted_run(drivers), b = scripted_run(drivers);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0) << "with drivers: " << drivers;
  }
  // And the drivers did move something.
  EXPECT_NE(scripted_run(false), scripted_run(true));
}

// The World computes MuJoCo's sensors only on the steps after which someone reads them (world.hpp): stepping a
// period, or 3 s, at a time gives the states, sensor values and grip outcomes of stepping one step at a time, which
// computes them all. The PUMA closes on the part in the machine's fixture and opens; when each ends is decided by the
// fingers' touch sensors, and when the open starts moves everything after it.
TEST_F(WorldTest, SkippingTheSensorsNobodyReadsChangesNothing) {
  const auto run = [](std::chrono::nanoseconds chunk) {
    World w(build_scene(paper_cell()));
    SimDriver& puma = w.add_sim_driver("puma");
    bring_up(w, puma);
    const models::LocationSpec& fixture = *paper_cell().find_location("machine_fixture");
    const Eigen::Vector3d part = fixture.pose.xyz + Eigen::Vector3d(0, 0, fixture.grasp_height);
    EXPECT_EQ(execute(w, puma, pose_move(down_at(w, "puma", part, fixture.pose.rpy.z()), drivers::Path::joint)).phase,
              CommandPhase::done);
    puma.submit(grip(drivers::Grip::Action::close));
    puma.submit(grip(drivers::Grip::Action::open));
    for (auto t = 0ns; t < 3s; t += chunk) w.advance(chunk);
    const mjData* d = w.data();
    const mjModel* m = w.scene().model();
    std::vector<double> state(d->qpos, d->qpos + m->nq);
    state.insert(state.end(), d->qvel, d->qvel + m->nv);
    state.insert(state.end(), d->sensordata, d->sensordata + m->nsensordata);
    const std::optional<GripOutcome> g = puma.last_grip();
    EXPECT_TRUE(g && g->action == drivers::Grip::Action::open) << "the open did not end";
    return state;
  };
  const std::vector<double> one = run(5ms);
  for (std::chrono::nanoseconds chunk : {std::chrono::nanoseconds(kPeriod), std::chrono::nanoseconds(3s)}) {
    const std::vector<double> other = run(chunk);
    ASSERT_EQ(one.size(), other.size());
    EXPECT_EQ(std::memcmp(one.data(), other.data(), one.size() * sizeof(double)), 0) << chunk.count() << " ns";
  }
}

}  // namespace
}  // namespace cellwright::twin::sim
