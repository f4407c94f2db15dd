// The physical faults in the World (docs/faults.md section 1): each happens when it should and does what it says — a
// drop makes the carried part leave the fingers and fall, a slip moves it down between the pads while both still
// touch it, an obstacle appears ahead of the moving tool and is seen for its duration, a missing part never arrives,
// a misplaced one arrives offset, an unreachable one lies beyond every robot's reach — a fault whose moment never
// comes is not injected, and the same seed gives the same injections.
#include "cellwright/twin/sim/fault_injector.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <numbers>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/twin/sim/world_plant.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using drivers::CommandPhase;
using drivers::Path;
using namespace testing;  // NOLINT: the simulation test helpers

FaultSpec fault(const std::string& text) {
  return parse_fault_text(text, paper_cell());
}

// A World of the paper's cell with the PUMA's simulation driver, and the plant that injects `faults`.
class FaultWorld : public cellwright::testing::MujocoTest {
 protected:
  void make(std::vector<FaultSpec> faults, std::vector<std::string> parked = {}, std::vector<FeedEvent> feed = {},
            std::uint64_t seed = 1) {
    plant_.reset();
    WorldOptions options;
    options.parked = std::move(parked);
    world_ = std::make_unique<World>(build_scene(paper_cell(), FaultInjector::scene_options(faults)), options);
    puma_ = &world_->add_sim_driver("puma");
    plant_ = std::make_unique<WorldPlant>(*world_, std::move(feed), std::move(faults), seed);
  }
  void TearDown() override {
    if (world_) {
      expect_no_data_warnings(world_->data());
      EXPECT_THAT(plant_->warnings(), ::testing::IsEmpty());
    }
    MujocoTest::TearDown();
  }

  // One control period of the plant; collects what it injected.
  void period() {
    plant_->advance(kPeriod);
    for (InjectedFault& f : plant_->take_injected()) {
      injected_.push_back(std::move(f));
      injected_at_.push_back(world_->now());
    }
    for (runtime::Arrival& a : plant_->new_arrivals()) arrivals_.push_back(a.workpiece);
    if (each_) each_();
  }
  void run_for(std::chrono::nanoseconds t) {
    const auto end = world_->now() + t;
    while (world_->now() < end) period();
  }
  CommandPhase execute(const drivers::Command& c) {
    const drivers::Submitted s = puma_->submit(c);
    if (!s.accepted()) return CommandPhase::failed;
    const auto end = world_->now() + 20s;
    while (world_->now() < end) {
      period();
      const drivers::CommandStatus st = puma_->poll(s.id);
      if (st.phase == CommandPhase::done || st.phase == CommandPhase::failed) return st.phase;
    }
    return CommandPhase::running;
  }
  void bring_up() {
    ASSERT_EQ(puma_->connect(), drivers::ErrorCode::none);
    const drivers::Submitted home = puma_->home();
    ASSERT_TRUE(home.accepted());
    while (puma_->poll(home.id).phase != CommandPhase::done) {
      ASSERT_LT(world_->now(), 20s);
      period();
    }
    ASSERT_EQ(puma_->activate(), drivers::ErrorCode::none);
  }
  WorkpieceTruth part(const std::string& name) const {
    for (const auto& w : world_->truth().workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }
  RobotTruth robot() const { return world_->truth().robots[0]; }
  void move_to(const Eigen::Vector3d& grasp, Path path, double speed) {
    const double yaw = paper_cell().find_location("input_pick")->pose.rpy.z();
    ASSERT_EQ(execute(pose_move(down_at(*world_, "puma", grasp, yaw), path, speed)), CommandPhase::done);
  }
  // Waits for A at the input conveyor's stop, grasps it there and lifts it by `lift` m. Returns the grasp point.
  Eigen::Vector3d pick_a(double lift = 0.10) {
    while (world_->now() < 60s && !(part("A").location == "input_pick" && part("A").linear_velocity.norm() < 0.005)) {
      period();
    }
    EXPECT_EQ(part("A").location, "input_pick");
    const models::LocationSpec& pick = *paper_cell().find_location("input_pick");
    const double height = paper_cell().find_workpiece("A")->size.z();
    const Eigen::Vector3d grasp = part("A").pose.translation() + Eigen::Vector3d(0, 0, pick.grasp_height - height / 2);
    move_to(grasp + Eigen::Vector3d(0, 0, pick.approach_height), Path::joint, 0.5);
    move_to(grasp, Path::linear, 0.3);
    EXPECT_EQ(execute(grip(drivers::Grip::Action::close)), CommandPhase::done);
    EXPECT_EQ(part("A").held_by, std::optional<std::size_t>(0));
    grasped_at_ = world_->now();
    move_to(grasp + Eigen::Vector3d(0, 0, lift), Path::linear, 0.3);
    return grasp;
  }
  std::vector<std::string> kinds() const {
    std::vector<std::string> out;
    for (const auto& f : injected_) out.push_back(f.kind);
    return out;
  }

  std::unique_ptr<World> world_;
  SimDriver* puma_ = nullptr;
  std::unique_ptr<WorldPlant> plant_;
  std::vector<InjectedFault> injected_;
  std::vector<std::chrono::nanoseconds> injected_at_;
  std::vector<std::string> arrivals_;
  std::function<void()> each_;
  std::chrono::nanoseconds grasped_at_{0};
};

TEST_F(FaultWorld, DropMakesTheCarriedPartLeaveTheFingersAndFall) {
  make({fault("drop:robot=puma,carry=1,after=0.3")});
  bring_up();
  pick_a();
  // The lift took longer than 0.3 s: the part was dropped on the way up, once it was in the air.
  ASSERT_THAT(kinds(), ::testing::ElementsAre("drop"));
  EXPECT_EQ(injected_[0].robot, "puma");
  EXPECT_EQ(injected_[0].workpiece, "A");
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("carry 1 of 'A'"));
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("lost its grip force for 0.3 s"));
  double after = 0;  // from the carry's start, when both pads first touched (before the close was done)
  ASSERT_EQ(std::sscanf(injected_[0].detail.c_str(), "carry 1 of 'A', %lf s after the grasp", &after), 1);
  EXPECT_GE(after, 0.3 - 1e-9);
  EXPECT_GE(injected_at_[0], grasped_at_);
  run_for(1s);
  const WorkpieceTruth a = part("A");
  EXPECT_FALSE(a.held_by);
  const double lifted = robot().tcp.translation().z();
  EXPECT_LT(a.pose.translation().z(), lifted - 0.05) << "the part is not below the fingers";
  EXPECT_NE(a.support, SupportKind::gripper);
  // The fingers obey the close again: they end up closed on nothing.
  const RobotTruth r = robot();
  EXPECT_LT(r.finger_opening, 0.01);
}

TEST_F(FaultWorld, SlipMovesThePartDownInTheFingersWhileBothPadsStillTouchIt) {
  make({fault("slip:robot=puma,carry=1,after=0.2,distance=0.015")});
  bring_up();
  pick_a(0.0);
  // Picked but not lifted yet: the part still rests on the belt, so it has not slipped.
  EXPECT_THAT(kinds(), ::testing::IsEmpty());
  const Eigen::Isometry3d before = robot().tcp.inverse() * part("A").pose;
  const double yaw = paper_cell().find_location("input_pick")->pose.rpy.z();
  const Eigen::Vector3d up = robot().tcp.translation() + Eigen::Vector3d(0, 0, 0.10);
  ASSERT_EQ(execute(pose_move(down_at(*world_, "puma", up, yaw), Path::linear, 0.3)), CommandPhase::done);
  run_for(500ms);
  ASSERT_THAT(kinds(), ::testing::ElementsAre("slip"));
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("slides 0.015 m down"));
  const WorkpieceTruth a = part("A");
  const RobotTruth r = robot();
  const Eigen::Vector3d moved = (r.tcp.inverse() * a.pose).translation() - before.translation();
  EXPECT_GE(moved.norm(), 0.01) << "moved " << moved.transpose();
  EXPECT_EQ(a.held_by, std::optional<std::size_t>(0));
  EXPECT_TRUE(r.finger_contact[0] && r.finger_contact[1]);
  EXPECT_TRUE(plant_->truth().robots[0].between_fingers == std::optional<std::string>("A"));
}

TEST_F(FaultWorld, ObstacleAppearsAheadOfTheMovingToolForItsDuration) {
  make({fault("obstacle:robot=puma,time=0.5,size=0.06,ahead=0.15,duration=1")});
  bring_up();
  EXPECT_TRUE(plant_->truth().obstacles.empty());
  const Eigen::Vector3d start = robot().tcp.translation();
  std::optional<Eigen::Vector3d> tool_when_placed, velocity_when_placed;
  Eigen::Vector3d last = start;
  std::size_t seen = 0, periods_seen = 0;
  each_ = [&] {
    const runtime::Truth t = plant_->truth();
    const Eigen::Vector3d p = robot().tcp.translation();
    if (!t.obstacles.empty()) {
      ++periods_seen;
      if (!tool_when_placed) {
        tool_when_placed = p;
        velocity_when_placed = (p - last) / 0.01;
      }
    }
    seen = std::max(seen, t.obstacles.size());
    last = p;
  };
  // A sideways move of the tool, 0.3 m along y.
  const double yaw = paper_cell().find_location("input_pick")->pose.rpy.z();
  execute(pose_move(down_at(*world_, "puma", start + Eigen::Vector3d(0, 0.3, 0), yaw), Path::linear, 0.5));
  run_for(1500ms);
  ASSERT_THAT(kinds(), ::testing::ElementsAre("obstacle"));
  ASSERT_TRUE(tool_when_placed);
  EXPECT_GE(injected_at_[0], 500ms);
  EXPECT_EQ(seen, 1u);
  EXPECT_NEAR(static_cast<double>(periods_seen) * 0.01, 1.0, 0.02) << "in the cell for its duration";
  // Where it was: ahead of the tool along its motion (within the jitter and one period's travel).
  const Eigen::Vector3d centre = [&] {
    // Read back from the detail: "a 0.060 m box at (x, y, z) m"
    double x = 0, y = 0, z = 0;
    EXPECT_EQ(std::sscanf(injected_[0].detail.c_str(), "a %*f m box at (%lf, %lf, %lf)", &x, &y, &z), 3);
    return Eigen::Vector3d(x, y, z);
  }();
  EXPECT_GT((centre - *tool_when_placed).dot(Eigen::Vector3d::UnitY()), 0.1) << "not ahead along +y";
  EXPECT_NEAR((centre - *tool_when_placed).norm(), 0.15, 0.03);
  EXPECT_TRUE(plant_->truth().obstacles.empty());
}

TEST_F(FaultWorld, MissingPartsNeverArrive) {
  std::vector<FeedEvent> feed = {{1s, "B", "input", Eigen::Isometry3d::Identity()}};
  make({fault("missing:workpiece=B"), fault("missing:workpiece=C")}, {"B"}, std::move(feed));
  // C, in the cell at the start, is taken out at once.
  EXPECT_TRUE(world_->parked("C"));
  run_for(3s);
  EXPECT_THAT(arrivals_, ::testing::IsEmpty());
  EXPECT_TRUE(world_->parked("B"));
  ASSERT_THAT(kinds(), ::testing::ElementsAre("missing", "missing"));
  EXPECT_EQ(injected_[0].workpiece, "C");
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("taken out of the cell at the start"));
  EXPECT_EQ(injected_[1].workpiece, "B");
  EXPECT_THAT(injected_[1].detail, ::testing::HasSubstr("never fed (due at 1.000 s)"));
  EXPECT_EQ(injected_at_[1], 1s);
}

TEST_F(FaultWorld, MisplacedPartArrivesOffset) {
  std::vector<FeedEvent> feed = {{500ms, "B", "input", Eigen::Isometry3d::Identity()}};
  make({fault("misplace:workpiece=B,offset=0.04/0.02,yaw=30")}, {"B", "A", "C"}, std::move(feed));
  run_for(510ms);  // the first period after the feed: the belt has not carried it yet
  ASSERT_THAT(arrivals_, ::testing::ElementsAre("B"));
  ASSERT_THAT(kinds(), ::testing::ElementsAre("misplace"));
  const models::ConveyorSpec& c = *paper_cell().find_conveyor("input");
  const Eigen::Vector3d entry = c.belt_point(c.enter);
  const WorkpieceTruth b = part("B");
  const Eigen::Vector3d d = b.pose.translation() - entry;
  EXPECT_NEAR(std::abs(d.x()), 0.04, 0.003);
  EXPECT_NEAR(std::abs(d.y()), 0.02, 0.003);
  const double yaw = std::atan2(b.pose.linear()(1, 0), b.pose.linear()(0, 0)) * 180 / std::numbers::pi;
  EXPECT_NEAR(std::abs(yaw), 30, 1);
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("arrived moved by ("));
}

TEST_F(FaultWorld, UnreachablePartLiesBeyondEveryRobotsReach) {
  make({fault("unreachable:workpiece=A")});
  run_for(500ms);
  ASSERT_THAT(kinds(), ::testing::ElementsAre("unreachable"));
  const WorkpieceTruth a = part("A");
  EXPECT_EQ(a.support, SupportKind::floor);
  EXPECT_TRUE(a.upright);
  for (const models::RobotSpec& r : paper_cell().robots) {
    const models::KinematicChain chain = models::KinematicChain::from_urdf_file(r.urdf);
    const Eigen::Vector3d joint1 = r.base.transform() * chain.first_joint_origin();
    EXPECT_GT((a.pose.translation() - joint1).norm(), chain.max_reach()) << r.name;
  }
  EXPECT_THAT(injected_[0].detail, ::testing::HasSubstr("beyond the reach of every robot"));
}

TEST_F(FaultWorld, NothingIsInjectedWhenTheMomentNeverComes) {
  std::vector<FeedEvent> feed = {{100s, "B", "input", Eigen::Isometry3d::Identity()}};
  make({fault("drop:robot=puma,carry=2"), fault("slip:robot=puma,after=5"), fault("obstacle:robot=puma,time=50"),
        fault("misplace:workpiece=B")},
       {"B"}, std::move(feed));
  bring_up();
  pick_a(0.0);
  // Open before the slip's 5 s, the part never lifted: the carry ends, and there is no second one.
  ASSERT_EQ(execute(grip(drivers::Grip::Action::open)), CommandPhase::done);
  run_for(6s);
  EXPECT_THAT(kinds(), ::testing::IsEmpty());
  EXPECT_TRUE(plant_->truth().obstacles.empty());
}

TEST_F(FaultWorld, SameSeedSameInjections) {
  const auto run = [&](std::uint64_t seed) {
    // B arrives (misplaced) while A is picked, a metre upstream of it: a misplaced part fed early rides to the stop
    // and may topple against A (how it falls is the physics', not this test's business) and block the grasp.
    std::vector<FeedEvent> feed = {{20s, "B", "input", Eigen::Isometry3d::Identity()}};
    injected_.clear();
    injected_at_.clear();
    arrivals_.clear();
    make({fault("misplace:workpiece=B"), fault("obstacle:robot=puma,time=0.1"), fault("drop:robot=puma")}, {"B"},
         std::move(feed), seed);
    bring_up();
    pick_a();
    run_for(500ms);
    std::vector<std::string> out;
    for (std::size_t i = 0; i < injected_.size(); ++i) {
      out.push_back(fmt::format("{} {} {} {} {}", injected_at_[i].count(), injected_[i].kind, injected_[i].robot,
                                injected_[i].workpiece, injected_[i].detail));
    }
    return out;
  };
  const std::vector<std::string> first = run(7);
  ASSERT_EQ(first.size(), 3u);
  EXPECT_EQ(run(7), first);
}

TEST(FaultCamera, FramesAreLostFromTheirTimeForTheirCount) {
  World world(build_scene(paper_cell()));
  FaultInjector injector(world, {parse_fault_text("frame_lost:time=1,count=2", paper_cell())}, 1);
  EXPECT_FALSE(injector.lose_frame(400ms));
  EXPECT_TRUE(injector.take().empty());
  EXPECT_TRUE(injector.lose_frame(1200ms));
  EXPECT_TRUE(injector.lose_frame(1600ms));
  EXPECT_FALSE(injector.lose_frame(2000ms));
  const std::vector<InjectedFault> f = injector.take();
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].kind, "frame_lost");
  EXPECT_THAT(f[0].detail, ::testing::HasSubstr("no frame for 2 frames from t=1.200 s"));
}

// A detector that sees every workpiece where it is told, for the noise decorator.
class FixedDetector final : public runtime::PartDetector {
 public:
  std::vector<std::string> workpieces() const override { return {"A"}; }
  runtime::Sightings detect(const runtime::Image&, const std::vector<runtime::Prediction>&) const override {
    runtime::Sightings s;
    runtime::Sighting a;
    a.workpiece = "A";
    a.yaw = 0.0;
    a.confidence = 1;
    s.seen.push_back(a);
    return s;
  }
};

TEST(FaultCamera, DetectionNoiseOnlyInItsWindowAndTheSameForTheSameSeed) {
  runtime::SimDuration t{0};
  const auto make = [&](std::uint64_t seed) {
    return NoisyDetector(std::make_shared<FixedDetector>(),
                         {parse_fault_text("detection_noise:time=1,duration=2,sigma=0.01,sigma_yaw=5",
                                                     paper_cell())},
                         seed, [&t] { return t; });
  };
  const NoisyDetector a = make(3), b = make(3);
  const runtime::Image image;
  t = 500ms;
  EXPECT_TRUE(a.detect(image, {}).seen[0].pose.translation().isZero());
  double largest = 0;
  for (t = 1s; t < 3s; t += 400ms) {
    const runtime::Sighting sa = a.detect(image, {}).seen[0];
    const runtime::Sighting sb = b.detect(image, {}).seen[0];
    EXPECT_EQ(sa.pose.translation(), sb.pose.translation());
    EXPECT_EQ(*sa.yaw, *sb.yaw);
    EXPECT_LE(sa.pose.translation().norm(), 0.03 * std::sqrt(2.0) + 1e-12);
    largest = std::max(largest, sa.pose.translation().norm());
  }
  EXPECT_GT(largest, 0.0);
  t = 3s;
  EXPECT_TRUE(a.detect(image, {}).seen[0].pose.translation().isZero());
}

}  // namespace
}  // namespace cellwright::twin::sim
