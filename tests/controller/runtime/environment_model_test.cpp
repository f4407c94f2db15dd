// The environment model: pre-coded from the cell, updated from truth, corrected by vision, and the targets robot
// control resolves against it.
#include "cellwright/runtime/environment_model.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <cmath>
#include <numbers>

#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::paper_cell;
using std::chrono::milliseconds;
using ::testing::HasSubstr;

// A simulated plant's truth through its sensors (TruthSensors) into the model, as the simulation thread does.
void apply_truth(EnvironmentModel& m, const Truth& t, Perception perception = Perception::kTruth) {
  TruthSensors plant;
  plant.update(t);
  Sensors sensors = plant.sensors();
  std::vector<std::string> robots;
  for (const RobotState& r : m.robots) robots.push_back(r.name);
  apply_readings(m, read_sensors(sensors, robots, t.time), perception);
}

task::Target target(task::TargetKind kind, std::string object) {
  return task::Target{kind, std::move(object)};
}

TEST(RuntimeEnvironment, IsPreCodedFromTheCellDescription) {
  const models::CellDescription& cell = paper_cell();
  const EnvironmentModel m = make_environment_model(cell);
  ASSERT_EQ(m.robots.size(), cell.robots.size());
  EXPECT_EQ(m.find_robot("melfa")->joints, cell.find_robot("melfa")->home);
  EXPECT_TRUE(m.find_robot("melfa")->base().isApprox(cell.find_robot("melfa")->base.transform()));
  ASSERT_EQ(m.workpieces.size(), cell.workpieces.size());
  const WorkpieceState& a = *m.find_workpiece("A");
  EXPECT_TRUE(a.pose.isApprox(cell.find_workpiece("A")->pose.transform()));
  EXPECT_TRUE(a.present);
  EXPECT_EQ(a.held_by, "");
  EXPECT_EQ(a.confidence, 1.0);
  EXPECT_EQ(a.size(), cell.find_workpiece("A")->size);
  EXPECT_EQ(m.geometry->locations.size(), cell.locations.size());
  EXPECT_EQ(m.geometry->conveyors.size(), 2u);
  EXPECT_EQ(m.geometry->machines.size(), 1u);
  ASSERT_TRUE(m.geometry->handover.has_value());
  EXPECT_EQ(m.geometry->handover->name, "exchange");
  EXPECT_EQ(m.find_robot("kuka"), nullptr);
  // The fixed geometry is shared, not copied, by a copy of the model; the copy's state is its own.
  EnvironmentModel copy = m;
  EXPECT_EQ(copy.geometry.get(), m.geometry.get());
  EXPECT_EQ(copy.find_workpiece("A")->fixed, m.find_workpiece("A")->fixed);
  copy.find_workpiece("A")->pose.translation().x() += 0.1;
  EXPECT_TRUE(m.find_workpiece("A")->pose.isApprox(cell.find_workpiece("A")->pose.transform()));
}

TEST(RuntimeEnvironment, TruthUpdatesPosesAndFingersButNeitherJointsNorWhoHolds) {
  EnvironmentModel m = make_environment_model(paper_cell());
  m.find_workpiece("A")->held_by = "puma";
  Truth t;
  t.time = milliseconds(1230);
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(0.1, 0.2, 0.3);
  t.workpieces.push_back({"A", p, {0.05, 0, 0}, true});
  t.workpieces.push_back({"B", p, {0, 0, 0}, false});
  t.workpieces.push_back({"no-such-part", p, {0, 0, 0}, true});
  t.robots.push_back({"puma", {1, 2, 3, 4, 5, 6}, std::string("A"), std::nullopt});
  t.robots.push_back({"melfa", {}, std::nullopt, std::nullopt});
  apply_truth(m, t);
  EXPECT_EQ(m.time, milliseconds(1230));
  EXPECT_TRUE(m.find_workpiece("A")->pose.isApprox(p));
  EXPECT_DOUBLE_EQ(m.find_workpiece("A")->velocity.x(), 0.05);
  EXPECT_EQ(m.find_workpiece("A")->held_by, "puma");
  EXPECT_EQ(m.find_workpiece("A")->stamp, milliseconds(1230));
  EXPECT_FALSE(m.find_workpiece("B")->present);
  // Where a robot is comes from its driver, never from the simulation: the truth's joints are not taken.
  EXPECT_EQ(m.find_robot("puma")->joints, paper_cell().find_robot("puma")->home);
  EXPECT_EQ(m.find_robot("puma")->grip, std::optional(GripReading::of("A")));  // the grip sensor is
  EXPECT_EQ(m.find_robot("melfa")->joints, paper_cell().find_robot("melfa")->home);
  EXPECT_FALSE(m.find_robot("melfa")->grip.has_value());
}

TEST(RuntimeEnvironment, VisionCorrectsFreePartsOnly) {
  EnvironmentModel m = make_environment_model(paper_cell());
  m.time = milliseconds(2000);
  Eigen::Isometry3d seen = Eigen::Isometry3d::Identity();
  seen.translation() = Eigen::Vector3d(0.4, -0.5, 0.53);
  EXPECT_TRUE(correct(m, "B", seen, 0.8, milliseconds(400)));
  EXPECT_TRUE(m.find_workpiece("B")->pose.isApprox(seen));
  EXPECT_EQ(m.find_workpiece("B")->confidence, 0.8);
  EXPECT_EQ(m.find_workpiece("B")->stamp, milliseconds(1600));
  const WorkpieceState before = *m.find_workpiece("C");
  m.find_workpiece("C")->held_by = "melfa";
  EXPECT_FALSE(correct(m, "C", seen, 0.9, milliseconds(0)));  // the hand hides it
  EXPECT_TRUE(m.find_workpiece("C")->pose.isApprox(before.pose));
  EXPECT_FALSE(correct(m, "nothing", seen, 0.9, milliseconds(0)));
  EXPECT_FALSE(correct(m, "B", seen, 1.5, milliseconds(0)));
  EXPECT_FALSE(correct(m, "B", seen, std::nan(""), milliseconds(0)));
  EXPECT_FALSE(correct(m, "B", seen, 0.5, milliseconds(-1)));
}

TEST(RuntimeEnvironment, AboveAndAtAPartAtALocationUseThatLocationsHeights) {
  const EnvironmentModel m = make_environment_model(paper_cell());  // A rests at input_pick
  const CellLocation& pick = *m.find_location("input_pick");
  const MotionTarget at = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  const MotionTarget above = resolve_target(m, "puma", target(task::TargetKind::kAbove, "A"));
  ASSERT_EQ(at.resolution, MotionTarget::Resolution::kOk) << at.reason;
  ASSERT_EQ(above.resolution, MotionTarget::Resolution::kOk) << above.reason;
  ASSERT_EQ(at.poses.size(), 2u);  // the fingers either way round
  const Eigen::Vector3d grasp = pick.pose.translation() + Eigen::Vector3d(0, 0, pick.grasp_height);
  for (const auto& p : at.poses) {
    EXPECT_TRUE(p.translation().isApprox(grasp, 1e-9)) << p.translation().transpose();
    EXPECT_TRUE(p.linear().col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-9));  // pointing down
  }
  EXPECT_TRUE(at.poses[0].linear().col(1).isApprox(-at.poses[1].linear().col(1), 1e-9));
  EXPECT_NEAR(above.poses[0].translation().z() - grasp.z(), pick.approach_height, 1e-9);
  EXPECT_THAT(at.description, HasSubstr("at(A): tool at ("));
}

TEST(RuntimeEnvironment, APartThatIsMovingAbsentOrHeldElsewhereIsWaitedFor) {
  EnvironmentModel m = make_environment_model(paper_cell());
  m.find_workpiece("A")->velocity = Eigen::Vector3d(0.05, 0, 0);
  MotionTarget t = resolve_target(m, "puma", target(task::TargetKind::kAbove, "A"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);
  EXPECT_THAT(t.reason, HasSubstr("workpiece A is still moving (0.0500 m/s)"));
  m.find_workpiece("A")->velocity.setZero();
  m.find_workpiece("A")->present = false;
  t = resolve_target(m, "puma", target(task::TargetKind::kAbove, "A"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);
  EXPECT_THAT(t.reason, HasSubstr("not in the cell yet"));
  m.find_workpiece("A")->present = true;
  m.find_workpiece("A")->held_by = "melfa";
  t = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);
  EXPECT_THAT(t.reason, HasSubstr("held by melfa"));
}

TEST(RuntimeEnvironment, PuttingDownKeepsTheHoldSoThePartsBottomLandsOnTheLocation) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const CellLocation& drop = *m.find_location("output_drop");
  RobotState& melfa = *m.find_robot("melfa");
  melfa.hold = Hold{"A", models::Approach::kSide, 0.01};
  const MotionTarget at = resolve_target(m, "melfa", target(task::TargetKind::kAt, "output_drop"));
  ASSERT_EQ(at.resolution, MotionTarget::Resolution::kOk);
  ASSERT_EQ(at.poses.size(), at.rank.size());
  ASSERT_GT(at.poses.size(), 2u);  // side holds offer turned tool directions
  for (const auto& p : at.poses) {
    EXPECT_NEAR(p.translation().z(), drop.pose.translation().z() + 0.01, 1e-9);
    EXPECT_NEAR(p.linear().col(2).z(), 0.0, 1e-9);  // tool axis horizontal: the part stays upright
  }
  EXPECT_EQ(*std::min_element(at.rank.begin(), at.rank.end()), 0);
  melfa.hold = Hold{"A", models::Approach::kDown, 0.05};
  const MotionTarget down = resolve_target(m, "melfa", target(task::TargetKind::kAbove, "output_drop"));
  ASSERT_EQ(down.poses.size(), 2u);
  EXPECT_NEAR(down.poses[0].translation().z(), drop.pose.translation().z() + 0.05 + drop.approach_height, 1e-9);
}

TEST(RuntimeEnvironment, DepartingAfterAPutDownLiftsTheOpenHandStraightUp) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const CellLocation& drop = *m.find_location("output_drop");
  RobotState& melfa = *m.find_robot("melfa");
  // It opened its hand holding the part from the side, tool pointing along +y, 1 cm off the drop point.
  Eigen::Isometry3d released = Eigen::Isometry3d::Identity();
  released.linear() << 0, 0, 1,  //
      -1, 0, 0,                  //
      0, -1, 0;
  released.translation() = drop.pose.translation() + Eigen::Vector3d(0.01, 0, 0.015);
  melfa.released_tcp = released;
  melfa.tcp = released;  // still there
  const MotionTarget depart = resolve_target(m, "melfa", target(task::TargetKind::kAbove, "output_drop"));
  ASSERT_EQ(depart.resolution, MotionTarget::Resolution::kOk);
  ASSERT_EQ(depart.poses.size(), 1u);
  EXPECT_TRUE(depart.poses[0].linear().isApprox(released.linear()));
  EXPECT_TRUE(
      depart.poses[0].translation().isApprox(released.translation() + Eigen::Vector3d(0, 0, drop.approach_height)));
  // The hand has moved on since (a later visit): the usual approach from above.
  melfa.tcp->translation().z() += 0.3;
  const MotionTarget later = resolve_target(m, "melfa", target(task::TargetKind::kAbove, "output_drop"));
  ASSERT_EQ(later.poses.size(), 2u);
  EXPECT_NEAR(later.poses[0].linear().col(2).z(), -1.0, 1e-9);
  // Released elsewhere (beyond the location tolerance): the usual approach from above.
  melfa.released_tcp->translation() = drop.pose.translation() + Eigen::Vector3d(0.2, 0, 0);
  melfa.tcp = melfa.released_tcp;
  const MotionTarget usual = resolve_target(m, "melfa", target(task::TargetKind::kAbove, "output_drop"));
  ASSERT_EQ(usual.poses.size(), 2u);
  EXPECT_NEAR(usual.poses[0].linear().col(2).z(), -1.0, 1e-9);
}

TEST(RuntimeEnvironment, WithoutACameraTheModelPutsARestingPartAtItsLocationsNominalPose) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const CellLocation& pick = *m.find_location("input_pick");
  const double half = m.find_workpiece("A")->size().z() / 2;
  // The real part stands 5 cm to the side of the pick location, turned: the presence sensor there only says "a part".
  Truth t;
  t.time = milliseconds(500);
  Eigen::Isometry3d real = pick.pose;
  real.translation() += Eigen::Vector3d(0, 0.05, half);
  real.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.workpieces.push_back({"A", real, {0, 0, 0}, true});
  Eigen::Isometry3d riding = real;
  riding.translation().x() -= 0.5;  // far from every location, moving
  t.workpieces.push_back({"B", riding, {0.05, 0, 0}, true});
  const Eigen::Isometry3d b_before = m.find_workpiece("B")->pose;
  apply_truth(m, t, Perception::kCad);
  const WorkpieceState& a = *m.find_workpiece("A");
  EXPECT_TRUE(a.pose.translation().isApprox(pick.pose.translation() + Eigen::Vector3d(0, 0, half)));
  EXPECT_TRUE(a.pose.linear().isApprox(pick.pose.linear()));
  EXPECT_TRUE(a.present);
  EXPECT_TRUE(m.find_workpiece("B")->pose.isApprox(b_before));  // the model cannot know where it is
  EXPECT_DOUBLE_EQ(m.find_workpiece("B")->velocity.x(), 0.05);  // but the belt's encoder says it moves

  // With a camera, the truth says nothing of the parts: only vision does.
  EnvironmentModel v = make_environment_model(paper_cell());
  const Eigen::Isometry3d a_before = v.find_workpiece("A")->pose;
  t.robots.push_back({"puma", {1, 2, 3, 4, 5, 6}, std::string(""), std::nullopt});
  apply_truth(v, t, Perception::kVision);
  EXPECT_TRUE(v.find_workpiece("A")->pose.isApprox(a_before));
  EXPECT_EQ(v.find_robot("puma")->joints, paper_cell().find_robot("puma")->home);
  EXPECT_EQ(v.find_robot("puma")->grip, std::optional(GripReading::nothing()));
  EXPECT_EQ(v.time, milliseconds(500));
}

TEST(RuntimeEnvironment, APartSeenOnceIsNotGraspedUntilItsMotionIsKnown) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const Eigen::Isometry3d p = m.find_workpiece("A")->pose;
  ASSERT_TRUE(correct(m, "A", p, 0.9, milliseconds(0), std::nullopt));
  const MotionTarget t = resolve_target(m, "puma", target(task::TargetKind::kAbove, "A"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);
  EXPECT_THAT(t.reason, HasSubstr("seen once"));
  ASSERT_TRUE(correct(m, "A", p, 0.9, milliseconds(0), Eigen::Vector3d::Zero()));
  EXPECT_EQ(resolve_target(m, "puma", target(task::TargetKind::kAbove, "A")).resolution, MotionTarget::Resolution::kOk);
  EXPECT_FALSE(correct(m, "A", p, 0.9, milliseconds(0), Eigen::Vector3d(NAN, 0, 0)));
}

TEST(RuntimeEnvironment, APartNearItsPickLocationIsTakenWithTheLocationsFingerDirection) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const CellLocation& pick = *m.find_location("input_pick");
  WorkpieceState& a = *m.find_workpiece("A");
  // 4 cm to the side of the pick point and turned by 80 degrees: a square box, so its faces are also at -10 degrees
  // and 170, and the location's direction (90 degrees) is nearest to 80.
  a.pose = pick.pose;
  a.pose.translation() += Eigen::Vector3d(0, 0.04, a.size().z() / 2);
  a.pose.linear() = Eigen::AngleAxisd(80 * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  a.velocity.setZero();
  const MotionTarget t = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  ASSERT_EQ(t.resolution, MotionTarget::Resolution::kOk);
  const Eigen::Vector3d fingers = t.poses[0].linear().col(1);  // the closing direction
  const double angle = std::atan2(fingers.y(), fingers.x());
  const Eigen::Vector3d location_fingers =
      resolve_target(m, "puma", target(task::TargetKind::kAt, "input_pick")).poses[0].linear().col(1);
  const double want = std::atan2(location_fingers.y(), location_fingers.x());
  // 10 degrees off the location's own direction (mod half a turn): the part's face, not the location's.
  const double off = std::remainder(angle - want, std::numbers::pi);
  EXPECT_NEAR(std::abs(off), 10 * std::numbers::pi / 180, 1e-6);
  EXPECT_NEAR(t.poses[0].translation().z(), pick.pose.translation().z() + pick.grasp_height, 1e-9);
}

// A part dropped while carried and picked again where it fell is taken as it was held: the hand-over after the
// re-grasp expects the giver's fingers on the upper half (pipeline campaign, seed 13 run 109: taken at the default
// height, the PUMA's fingers met the MELFA's at the hand-over and could not open). A part on its side is not.
TEST(RuntimeEnvironment, APartDroppedWhileCarriedIsTakenAgainAsItWasHeld) {
  EnvironmentModel m = make_environment_model(paper_cell());
  WorkpieceState& a = *m.find_workpiece("A");
  a.pose = Eigen::Isometry3d::Identity();
  a.pose.translation() = Eigen::Vector3d(0.5, 0.0, a.size().z() / 2);  // upright on the floor, far from locations
  a.velocity.setZero();
  const double bottom = 0.0;
  const double by_default = resolve_target(m, "puma", target(task::TargetKind::kAt, "A")).poses.at(0).translation().z();
  RobotState& puma = *m.find_robot("puma");
  puma.dropped_hold = Hold{"A", models::Approach::kDown, 0.05};
  const MotionTarget again = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  ASSERT_EQ(again.resolution, MotionTarget::Resolution::kOk);
  EXPECT_NEAR(again.poses[0].translation().z(), bottom + 0.05, 1e-9);
  EXPECT_GT(std::abs(by_default - (bottom + 0.05)), 0.005) << "the test needs a default that differs";
  // Another part, or this one lying on its side, is taken the usual way.
  puma.dropped_hold = Hold{"B", models::Approach::kDown, 0.05};
  EXPECT_NEAR(resolve_target(m, "puma", target(task::TargetKind::kAt, "A")).poses.at(0).translation().z(), by_default,
              1e-9);
  // Held from the side before, or at a height the part does not have: the usual way too.
  puma.dropped_hold = Hold{"A", models::Approach::kSide, 0.05};
  EXPECT_NEAR(resolve_target(m, "puma", target(task::TargetKind::kAt, "A")).poses.at(0).translation().z(), by_default,
              1e-9);
  puma.dropped_hold = Hold{"A", models::Approach::kDown, a.size().z() + 0.01};
  EXPECT_NEAR(resolve_target(m, "puma", target(task::TargetKind::kAt, "A")).poses.at(0).translation().z(), by_default,
              1e-9);
  // Tilted by 20 degrees (not upright): not as it was held.
  puma.dropped_hold = Hold{"A", models::Approach::kDown, 0.05};
  a.pose.linear() = Eigen::AngleAxisd(20 * std::numbers::pi / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  ASSERT_FALSE(stands_upright(a));
  const MotionTarget tilted = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  puma.dropped_hold.reset();
  const MotionTarget usual = resolve_target(m, "puma", target(task::TargetKind::kAt, "A"));
  ASSERT_EQ(tilted.resolution, usual.resolution);
  if (usual.resolution == MotionTarget::Resolution::kOk) {
    EXPECT_TRUE(tilted.poses.at(0).isApprox(usual.poses.at(0), 1e-12));
  }
}

TEST(RuntimeEnvironment, HandOverTargetsFollowTheCellsHandOverSpec) {
  EnvironmentModel m = make_environment_model(paper_cell());
  const models::HandoverSpec& h = *m.geometry->handover;
  const MotionTarget give = resolve_target(m, "puma", target(task::TargetKind::kHandover, "melfa"));
  ASSERT_EQ(give.resolution, MotionTarget::Resolution::kOk);
  EXPECT_TRUE(give.poses[0].translation().isApprox(h.pose.xyz + h.grasps[0].offset, 1e-9));
  EXPECT_TRUE(give.poses[0].linear().col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-9));

  const MotionTarget grasp = resolve_target(m, "melfa", target(task::TargetKind::kHandGrasp, "puma"));
  ASSERT_EQ(grasp.resolution, MotionTarget::Resolution::kOk);
  EXPECT_TRUE(grasp.poses[0].translation().isApprox(h.pose.xyz + h.grasps[1].offset, 1e-9));
  EXPECT_NEAR(grasp.poses[0].linear().col(2).z(), 0.0, 1e-9);  // from the side
  // Where the giver really presents the part counts: 1 cm off, the taker goes 1 cm off too.
  m.find_robot("puma")->hold = Hold{"A", models::Approach::kDown, 0.05};
  m.find_workpiece("A")->pose.translation() = h.pose.xyz + Eigen::Vector3d(0, 0.01, 0);
  const MotionTarget real = resolve_target(m, "melfa", target(task::TargetKind::kHandGrasp, "puma"));
  EXPECT_TRUE(
      real.poses[0].translation().isApprox(h.pose.xyz + h.grasps[1].offset + Eigen::Vector3d(0, 0.01, 0), 1e-9));

  const MotionTarget approach = resolve_target(m, "melfa", target(task::TargetKind::kHandApproach, "puma"));
  ASSERT_EQ(approach.resolution, MotionTarget::Resolution::kOk);
  ASSERT_EQ(approach.rank[0], 0);
  const Eigen::Vector3d back =
      h.pose.xyz + h.grasps[1].offset - grasp.poses[0].linear().col(2) * TargetOptions{}.handover_clearance;
  EXPECT_TRUE(approach.poses[0].translation().isApprox(back, 1e-9));
}

TEST(RuntimeEnvironment, TargetsNamingNothingFailWithTheName) {
  EnvironmentModel m = make_environment_model(paper_cell());
  MotionTarget t = resolve_target(m, "puma", target(task::TargetKind::kAt, "nowhere"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kFail);
  EXPECT_THAT(t.reason, HasSubstr("'nowhere' is neither a workpiece nor a location"));
  t = resolve_target(m, "kuka", target(task::TargetKind::kHome, ""));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kFail);
  models::CellDescription no_handover = paper_cell();
  no_handover.handover.reset();
  m = make_environment_model(no_handover);
  t = resolve_target(m, "puma", target(task::TargetKind::kHandover, "melfa"));
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kFail);
  EXPECT_THAT(t.reason, HasSubstr("the cell has no hand-over"));
  const MotionTarget home = resolve_target(m, "melfa", target(task::TargetKind::kHome, ""));
  ASSERT_EQ(home.resolution, MotionTarget::Resolution::kOk);
  EXPECT_EQ(home.joints, paper_cell().find_robot("melfa")->home);
}

TEST(RuntimeEnvironment, ParkGoesToTheCellsParkPoseAndFailsWithoutOne) {
  models::CellDescription cell = paper_cell();
  cell.robots.front().park = {0.5, 0.1, 0.2, 0, 0.3, 0};
  const EnvironmentModel m = make_environment_model(cell);
  const MotionTarget park = resolve_target(m, cell.robots.front().name, target(task::TargetKind::kPark, ""));
  ASSERT_EQ(park.resolution, MotionTarget::Resolution::kOk);
  EXPECT_EQ(park.joints, cell.robots.front().park);
  const MotionTarget none = resolve_target(m, cell.robots.back().name, target(task::TargetKind::kPark, ""));
  EXPECT_EQ(none.resolution, MotionTarget::Resolution::kFail);
  EXPECT_THAT(none.reason, HasSubstr("has no park pose"));
}

}  // namespace
}  // namespace cellwright::runtime
