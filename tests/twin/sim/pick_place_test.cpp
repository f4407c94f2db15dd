// The physics that matters most: a robot picks a workpiece off the input conveyor by friction alone, lifts it, carries
// it and puts it down where it was meant to go; the part rises with the gripper (it is carried by contacts, never
// moved by the simulation), stays put in the fingers, and lands within millimetres of the target. A grasp that misses
// is known for what it is.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include "cellwright/twin/sim/world.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using drivers::CommandPhase;
using drivers::Path;
using namespace testing;  // NOLINT: the simulation test helpers

// The paper's cell with a side table (a machine without process time) 30 cm downstream of the input conveyor's pick
// point, at the belt's height, and a location on it.
const models::CellDescription& cell_with_table() {
  static const models::CellDescription cell = [] {
    YAML::Node doc = YAML::LoadFile((kSource / "scenes/cell.yaml").string());
    YAML::Node table;
    table["name"] = "table";
    table["pose"]["xyz"] = std::vector<double>{0.33, -0.55, 0.0};
    table["pose"]["yaw"] = 0.0;
    table["size"] = std::vector<double>{0.2, 0.2, 0.47};
    table["fixture"]["size"] = std::vector<double>{0.1, 0.1, 0.03};
    table["process_time"] = 0.0;
    doc["machines"].push_back(table);
    YAML::Node place;
    place["name"] = "table_top";
    place["at"] = "table.fixture";
    place["yaw"] = 90.0;
    place["reach"] = std::vector<std::string>{"puma"};
    doc["locations"].push_back(place);
    YAML::Emitter out;
    out << doc;
    return models::parse_cell(out.c_str(), kSource / "scenes/cell-with-table.yaml");
  }();
  return cell;
}

class PickPlaceTest : public cellwright::testing::MujocoTest {
 protected:
  void SetUp() override {
    MujocoTest::SetUp();
    WorldOptions options;
    options.parked = {"D"};  // the machine's fixture is free
    world_ = std::make_unique<World>(build_scene(cell_with_table()), options);
    puma_ = &world_->add_sim_driver("puma");
    bring_up(*world_, *puma_);
  }
  void TearDown() override {
    expect_no_data_warnings(world_->data());
    EXPECT_THAT(world_->drain_warnings(), ::testing::IsEmpty());
    MujocoTest::TearDown();
  }

  WorkpieceTruth part(const std::string& name) const {
    for (const auto& w : world_->truth().workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }
  Eigen::Isometry3d tcp() const { return world_->truth().robots[0].tcp; }

  // Runs until the conveyor has brought part A to rest at the pick location.
  void wait_for_part_at_pick() {
    while (world_->now() < 60s && !(part("A").location == "input_pick" && part("A").linear_velocity.norm() < 0.005)) {
      world_->advance(100ms);
    }
    ASSERT_EQ(part("A").location, "input_pick");
  }

  // Moves the tool to the world pose `pose` (gripper down) and expects the move to complete.
  void move_to(const Eigen::Isometry3d& world_pose, Path path, double speed, const std::function<void()>& each = {}) {
    const Eigen::Isometry3d base = base_of(*world_, "puma");
    const auto s = execute(*world_, *puma_, pose_move(base.inverse() * world_pose, path, speed), 20s, each);
    ASSERT_EQ(s.phase, CommandPhase::done) << s.message;
  }

  Eigen::Isometry3d down(const Eigen::Vector3d& p, double yaw) const {
    return models::grasp_pose(p, models::Approach::kDown, yaw, base_of(*world_, "puma"));
  }

  std::unique_ptr<World> world_;
  SimDriver* puma_ = nullptr;
};

// Picks A at the end of the input conveyor: approach above it, go down, close. Returns where the part sits in the
// hand (tool frame), and the grasp point and the part's bottom centre (world) at the grasp.
struct Grasped {
  Eigen::Isometry3d in_hand;
  Eigen::Vector3d grasp, bottom;
};

class PickPlaceRun : public PickPlaceTest {
 protected:
  Grasped pick_a() {
    const models::LocationSpec& pick = *world_->scene().cell().find_location("input_pick");
    const double height = world_->scene().cell().find_workpiece("A")->size.z();
    Grasped g;
    g.bottom = part("A").pose.translation() - Eigen::Vector3d(0, 0, height / 2);
    g.grasp = g.bottom + Eigen::Vector3d(0, 0, pick.grasp_height);
    const double yaw = pick.pose.rpy.z();
    move_to(down(g.grasp + Eigen::Vector3d(0, 0, pick.approach_height), yaw), Path::joint, 0.5, watch());
    move_to(down(g.grasp, yaw), Path::linear, 0.3, watch());
    EXPECT_EQ(execute(*world_, *puma_, grip(drivers::Grip::Action::close)).phase, CommandPhase::done);
    EXPECT_TRUE(puma_->last_grip() && puma_->last_grip()->on_part);
    EXPECT_NEAR(puma_->last_grip()->opening, world_->scene().cell().find_workpiece("A")->size.y(), 0.002);
    EXPECT_EQ(part("A").held_by, std::optional<std::size_t>(0));
    EXPECT_EQ(part("A").support, SupportKind::gripper);
    g.in_hand = tcp().inverse() * part("A").pose;
    return g;
  }

  // Lifts the part 10 cm straight up; it must rise with the gripper without sagging in the fingers.
  void lift(const Grasped& g, double yaw) {
    const double z_before = part("A").pose.translation().z();
    double lowest = z_before;
    move_to(down(g.grasp + Eigen::Vector3d(0, 0, 0.10), yaw), Path::linear, 0.3, [&] {
      carried(g);
      lowest = std::min(lowest, part("A").pose.translation().z());
    });
    EXPECT_NEAR(part("A").pose.translation().z() - z_before, 0.10, 0.002);
    EXPECT_GE(lowest, z_before - 0.001) << "the part sagged out of the fingers";
  }

  // Puts the part's bottom on `target` (world), opens, departs.
  void put_down(const Grasped& g, const Eigen::Vector3d& target, double yaw, double approach) {
    const Eigen::Vector3d put = target + Eigen::Vector3d(0, 0, g.grasp.z() - g.bottom.z());
    move_to(down(put + Eigen::Vector3d(0, 0, approach), yaw), Path::joint, 0.5, [&] { carried(g); });
    move_to(down(put + Eigen::Vector3d(0, 0, 0.001), yaw), Path::linear, 0.2, [&] { carried(g); });
    const auto opened = world_->now();
    ASSERT_EQ(execute(*world_, *puma_, grip(drivers::Grip::Action::open), 20s, watch()).phase, CommandPhase::done);
    release_s_ = std::chrono::duration<double>(world_->now() - opened).count();
    release_opening_ = puma_->last_grip()->opening;
    move_to(down(put + Eigen::Vector3d(0, 0, approach), yaw), Path::linear, 0.3, watch());
    world_->advance(500ms);
    watch()();
  }

  std::function<void()> watch() {
    return [this] {
      for (Collision& c : world_->new_collisions()) collisions_.push_back(std::move(c));
    };
  }
  // Per period while carrying: held by the PUMA, and how far the part has moved in the hand.
  void carried(const Grasped& g) {
    watch()();
    const WorkpieceTruth a = part("A");
    slip_ = std::max(slip_, ((tcp().inverse() * a.pose).translation() - g.in_hand.translation()).norm());
    always_held_ = always_held_ && a.held_by == std::optional<std::size_t>(0);
  }
  void expect_landed(const Eigen::Vector3d& target, const std::string& location, const std::string& machine,
                     double tolerance) {
    const double height = world_->scene().cell().find_workpiece("A")->size.z();
    const WorkpieceTruth end = part("A");
    const Eigen::Vector3d landed = end.pose.translation() - Eigen::Vector3d(0, 0, height / 2);
    EXPECT_LT((landed - target).head<2>().norm(), tolerance) << "landed at " << landed.transpose();
    EXPECT_NEAR(landed.z(), target.z(), 0.002);
    EXPECT_TRUE(end.upright);
    EXPECT_FALSE(end.held_by);
    EXPECT_EQ(end.support, SupportKind::machine);
    EXPECT_EQ(end.support_name, machine);
    EXPECT_EQ(end.location, location);
    EXPECT_LT(end.linear_velocity.norm(), 1e-3);
    EXPECT_TRUE(always_held_) << "the part left the fingers while carried";
    for (const Collision& c : collisions_) {
      ADD_FAILURE() << "collision " << c.body1 << " / " << c.body2 << " at " << c.time.count() << " ns";
    }
  }

  std::vector<Collision> collisions_;
  double release_s_ = 0, release_opening_ = 0;  // put_down(): how long its open took, the opening it left
  double slip_ = 0;
  bool always_held_ = true;
};

TEST_F(PickPlaceRun, PicksAPartOffTheConveyorLiftsItMovesIt30CmAndPutsItDown) {
  wait_for_part_at_pick();
  const Grasped g = pick_a();
  const double yaw = world_->scene().cell().find_location("input_pick")->pose.rpy.z();
  lift(g, yaw);
  // 30 cm across to the side table, at the lifted height, in a straight line; then down onto the table.
  const models::LocationSpec& table = *world_->scene().cell().find_location("table_top");
  const Eigen::Vector3d lifted = g.grasp + Eigen::Vector3d(0, 0, 0.10);
  const Eigen::Vector3d across = lifted + Eigen::Vector3d(table.pose.xyz.x() - g.bottom.x(), 0, 0);
  EXPECT_NEAR((across - lifted).norm(), 0.30, 0.01);
  move_to(down(across, yaw), Path::linear, 0.5, [&] { carried(g); });
  put_down(g, table.pose.xyz, table.pose.rpy.z(), 0.05);
  RecordProperty("slip_mm", std::to_string(slip_ * 1000));
  // The cell's pick holds the part's upper 25 mm (its lower half is left free for the hand-over): the part creeps
  // ~2 mm in the pads over this carry (docs/simulation.md); 3 mm is still well inside the 5 mm landing tolerance.
  EXPECT_LT(slip_, 0.003) << "the part moved in the fingers";
  expect_landed(table.pose.xyz, "table_top", "table", 0.005);
}

// The long way: from the conveyor round the PUMA's base into the machine (joint 1 turns through 170 degrees), via a
// point in front of the base. The MELFA holds its home, tucked out of the PUMA's sweep: no collision may occur.
TEST_F(PickPlaceRun, CarriesAPartRoundTheBaseIntoTheMachine) {
  SimDriver& melfa = world_->add_sim_driver("melfa");
  bring_up(*world_, melfa);
  wait_for_part_at_pick();
  const Grasped g = pick_a();
  const double yaw = world_->scene().cell().find_location("input_pick")->pose.rpy.z();
  lift(g, yaw);
  move_to(down(Eigen::Vector3d(0.45, -0.05, g.grasp.z() + 0.1), yaw), Path::joint, 0.5, [&] { carried(g); });
  const models::LocationSpec& place = *world_->scene().cell().find_location("machine_fixture");
  put_down(g, place.pose.xyz, place.pose.rpy.z(), place.approach_height);
  RecordProperty("slip_mm", std::to_string(slip_ * 1000));
  // A held part creeps along the pads during long sweeps (see docs/simulation.md): it must stay in the hand and land
  // at the machine's location.
  EXPECT_LT(slip_, 0.015);
  expect_landed(place.pose.xyz, "machine_fixture", "mill", 0.015);
}

// Letting go of a part is a release (sim_driver.hpp): the fingers open from the part's faces only
// release_clearance beyond them, not from fully closed to fully open (1.53 s), and the part stays where it was put.
// The next open, with nothing in the hand, opens fully.
TEST_F(PickPlaceRun, ALetGoOpensOnlyClearOfThePartAndTheNextOpenOpensFully) {
  wait_for_part_at_pick();
  const Grasped g = pick_a();
  const double yaw = world_->scene().cell().find_location("input_pick")->pose.rpy.z();
  lift(g, yaw);
  const models::LocationSpec& table = *world_->scene().cell().find_location("table_top");
  put_down(g, table.pose.xyz, table.pose.rpy.z(), 0.05);
  const double width = world_->scene().cell().find_workpiece("A")->size.y();
  const double clearance = SimDriverOptions{}.release_clearance;
  EXPECT_LT(release_s_, 0.4) << "a release took as long as a full open";
  EXPECT_NEAR(release_opening_, width + 2 * clearance, 0.002);
  expect_landed(table.pose.xyz, "table_top", "table", 0.005);
  ASSERT_EQ(execute(*world_, *puma_, grip(drivers::Grip::Action::open)).phase, CommandPhase::done);
  EXPECT_NEAR(puma_->last_grip()->opening, puma_->capabilities().gripper_max_width, 0.001);
}

TEST_F(PickPlaceRun, AGraspBesideThePartClosesOnNothing) {
  wait_for_part_at_pick();
  const models::LocationSpec& pick = *world_->scene().cell().find_location("input_pick");
  const double height = world_->scene().cell().find_workpiece("A")->size.z();
  const Eigen::Vector3d bottom = part("A").pose.translation() - Eigen::Vector3d(0, 0, height / 2);
  // 9 cm beside the part, towards the robot (the open fingers reach 5 cm to each side): they close on air.
  const Eigen::Vector3d wrong = bottom + Eigen::Vector3d(0, 0.09, pick.grasp_height);
  const double yaw = pick.pose.rpy.z();
  move_to(down(wrong + Eigen::Vector3d(0, 0, pick.approach_height), yaw), Path::joint, 0.5);
  move_to(down(wrong, yaw), Path::linear, 0.3);
  ASSERT_EQ(execute(*world_, *puma_, grip(drivers::Grip::Action::close)).phase, CommandPhase::done);
  ASSERT_TRUE(puma_->last_grip());
  EXPECT_FALSE(puma_->last_grip()->on_part);
  EXPECT_LT(puma_->last_grip()->opening, 0.001);
  EXPECT_FALSE(part("A").held_by);
  // Lifting leaves the part where it was.
  move_to(down(wrong + Eigen::Vector3d(0, 0, 0.1), yaw), Path::linear, 0.3);
  EXPECT_LT((part("A").pose.translation() - bottom - Eigen::Vector3d(0, 0, height / 2)).norm(), 0.002);
  EXPECT_EQ(part("A").location, "input_pick");
  EXPECT_TRUE(world_->new_collisions().empty());
}

}  // namespace
}  // namespace cellwright::twin::sim
