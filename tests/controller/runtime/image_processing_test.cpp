// The image-processing thread's unit (ImageProcessing) with a scripted detector: frames in, environment model
// corrected by the rules of image_processing.hpp, one vision event per frame, the processed frame handed on. What a
// real detector makes of real pictures is tested with the cell's detector in tests/vision.
#include "cellwright/runtime/image_processing.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <any>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "controller/runtime/scripted_cell.hpp"
#include "controller/runtime/scripted_detector.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::paper_cell;
using cellwright::testing::ScriptedDetector;
using std::chrono::milliseconds;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::vector<std::string> workpiece_names(const models::CellDescription& cell) {
  std::vector<std::string> names;
  for (const auto& w : cell.workpieces) names.push_back(w.name);
  return names;
}

// A sighting of `workpiece` with its centre at `centre`, turned `yaw_deg` about z (none: a cylinder).
Sighting sighting(const std::string& workpiece, const Eigen::Vector3d& centre, std::optional<double> yaw_deg = 0.0,
                  double confidence = 0.9) {
  Sighting s;
  s.workpiece = workpiece;
  s.pose.translation() = centre;
  if (yaw_deg) {
    s.yaw = *yaw_deg * std::numbers::pi / 180;
    s.pose.linear() = Eigen::AngleAxisd(*s.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  s.confidence = confidence;
  return s;
}

// A tiny picture filled with `shade`: the scripted detector ignores pixels, so the shade only tells frames apart.
Image picture(std::uint8_t shade) {
  return Image{4, 3, std::vector<std::uint8_t>(4 * 3 * 3, shade)};
}

class ImageProcessingTest : public ::testing::Test {
 protected:
  ImageProcessingTest()
      : detector_(workpiece_names(paper_cell())),
        env_(make_environment_model(paper_cell())),
        frames_(8),
        vision_(detector_, env_, frames_, log_, VisionOptions{"overhead", milliseconds(400)},
                [this](const VisionFrame& f) { shown_.push_back(f); }) {}

  // A frame taken at `t`; the model's clock (the simulation's) moves on to `t`.
  void push(SimDuration t, Image image = picture(1), std::string problem = "") {
    env_.write([&](EnvironmentModel& m) { m.time = t; });
    ASSERT_EQ(frames_.try_push(Frame{t, std::move(image), std::move(problem)}), QueueStatus::ok);
  }

  // A frame taken and processed at `t`.
  void frame_at(SimDuration t) {
    push(t);
    ASSERT_EQ(vision_.step(t), 1u);
  }

  WorkpieceState part(const std::string& name) const {
    return env_.read([&](const EnvironmentModel& m) { return *m.find_workpiece(name); });
  }
  Eigen::Vector3d centre(const std::string& name) const { return part(name).pose.translation(); }

  // Puts `robot`'s tool centre point at `where`.
  void tool_at(const std::string& robot, const Eigen::Vector3d& where) {
    env_.write([&](EnvironmentModel& m) {
      Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();
      tcp.translation() = where;
      m.find_robot(robot)->tcp = tcp;
    });
  }

  std::vector<nlohmann::ordered_json> events() const {
    std::vector<nlohmann::ordered_json> out;
    for (const std::string& line : log_.lines()) out.push_back(nlohmann::ordered_json::parse(line));
    return out;
  }
  nlohmann::ordered_json last_event() const { return nlohmann::ordered_json::parse(log_.lines().back()); }

  static std::vector<std::string> names(const nlohmann::ordered_json& list) {
    std::vector<std::string> out;
    for (const auto& e : list) out.push_back(e.is_string() ? e.get<std::string>() : e["workpiece"].get<std::string>());
    return out;
  }

  ScriptedDetector detector_;
  SharedEnvironment env_;
  MessageQueue<Frame> frames_;
  EventLog log_;
  std::vector<VisionFrame> shown_;
  ImageProcessing vision_;
};

void expect_same(const WorkpieceState& after, const WorkpieceState& before) {
  EXPECT_TRUE(after.pose.isApprox(before.pose)) << after.name;
  EXPECT_EQ(after.velocity, before.velocity) << after.name;
  EXPECT_EQ(after.motion_known, before.motion_known) << after.name;
  EXPECT_EQ(after.present, before.present) << after.name;
  EXPECT_EQ(after.confidence, before.confidence) << after.name;
  EXPECT_EQ(after.stamp, before.stamp) << after.name;
}

TEST_F(ImageProcessingTest, CorrectsPoseConfidenceAndStampFromASighting) {
  // The vision runtime starts every part absent: the camera finds A 4 cm off its CAD pose, turned by 15 degrees.
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  const Eigen::Vector3d real = centre("A") + Eigen::Vector3d(0, 0.04, 0);
  detector_.then_sees({sighting("A", real, 15.0, 0.83)});
  frame_at(milliseconds(400));

  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.present);
  EXPECT_TRUE(a.pose.translation().isApprox(real));
  EXPECT_NEAR(Eigen::AngleAxisd(a.pose.linear()).angle(), 15 * std::numbers::pi / 180, 1e-9);
  EXPECT_DOUBLE_EQ(a.confidence, 0.83);
  EXPECT_EQ(a.stamp, milliseconds(400));
  // Parts the frame did not show keep the CAD estimate.
  expect_same(part("B"), *make_environment_model(paper_cell()).find_workpiece("B"));
  EXPECT_EQ(vision_.frames_processed(), 1u);
}

TEST_F(ImageProcessingTest, MotionIsUnknownAfterTheFirstSightingAndAtRestAfterTheSecond) {
  const task::Target above_a{task::TargetKind::kAbove, "A"};
  const Eigen::Vector3d p = centre("A");
  detector_.then_sees({sighting("A", p)});
  frame_at(milliseconds(400));
  EXPECT_FALSE(part("A").motion_known);  // seen once: it may be riding a belt
  const MotionTarget first = env_.read([&](const EnvironmentModel& m) { return resolve_target(m, "puma", above_a); });
  EXPECT_EQ(first.resolution, MotionTarget::Resolution::kWait);
  EXPECT_THAT(first.reason, HasSubstr("seen once"));

  // 2 mm further: within the detector's noise (rest_deadband, 3 mm), so at rest.
  const Eigen::Vector3d q = p + Eigen::Vector3d(0.002, 0, 0);
  detector_.then_sees({sighting("A", q)});
  frame_at(milliseconds(800));
  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.motion_known);
  EXPECT_EQ(a.velocity, Eigen::Vector3d::Zero());
  EXPECT_TRUE(a.pose.translation().isApprox(q));
  EXPECT_EQ(a.stamp, milliseconds(800));
  const MotionTarget second = env_.read([&](const EnvironmentModel& m) { return resolve_target(m, "puma", above_a); });
  EXPECT_EQ(second.resolution, MotionTarget::Resolution::kOk) << second.reason;
}

TEST_F(ImageProcessingTest, MeasuresTheVelocityOfAPartRidingTheBeltFromTwoFrames) {
  const Eigen::Vector3d p = centre("A");
  // 2 cm in 0.4 s along the belt (+x): 5 cm/s. B moves 4 mm, just over the deadband: it moves too.
  detector_.then_sees({sighting("A", p), sighting("B", centre("B"))});
  detector_.then_sees(
      {sighting("A", p + Eigen::Vector3d(0.02, 0, 0)), sighting("B", centre("B") + Eigen::Vector3d(0.004, 0, 0))});
  push(milliseconds(400));
  push(milliseconds(800));
  // Both frames processed together, later: the velocity comes from the frames' own times, 0.4 s apart.
  EXPECT_EQ(vision_.step(milliseconds(1000)), 2u);
  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.motion_known);
  EXPECT_TRUE(a.velocity.isApprox(Eigen::Vector3d(0.05, 0, 0), 1e-9)) << a.velocity.transpose();
  EXPECT_TRUE(part("B").velocity.isApprox(Eigen::Vector3d(0.01, 0, 0), 1e-9)) << part("B").velocity.transpose();
  const MotionTarget t = env_.read([&](const EnvironmentModel& m) {
    return resolve_target(m, "puma", {task::TargetKind::kAbove, "A"});
  });
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);  // still moving
}

TEST_F(ImageProcessingTest, TheFrameBeforeMayBeUpToTwoAndAHalfPeriodsBack) {
  const Eigen::Vector3d a0 = centre("A"), b0 = centre("B");
  // 0.4 s: A and B seen. 0.8 s: neither (an arm passing over them). 1.2 s: A, 2 cm further, measured over the two
  // periods since 0.4 s. 1.4 s: B, where it was: 2.5 periods after its last sighting, the most the frame before may be
  // back.
  detector_.then_sees({sighting("A", a0), sighting("B", b0)});
  frame_at(milliseconds(400));
  const WorkpieceState a_before = part("A");
  detector_.then_sees({});
  frame_at(milliseconds(800));
  expect_same(part("A"), a_before);  // not seen: the model keeps its last estimate, whose stamp tells its age
  EXPECT_EQ(part("A").stamp, milliseconds(400));

  detector_.then_sees({sighting("A", a0 + Eigen::Vector3d(0.02, 0, 0))});
  frame_at(milliseconds(1200));
  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.motion_known);  // from the 0.4 s frame: a missed frame in between still counts
  EXPECT_TRUE(a.velocity.isApprox(Eigen::Vector3d(0.025, 0, 0), 1e-9)) << a.velocity.transpose();

  detector_.then_sees({sighting("B", b0)});
  frame_at(milliseconds(1400));
  EXPECT_TRUE(part("B").motion_known);
  EXPECT_EQ(part("B").velocity, Eigen::Vector3d::Zero());
}

TEST_F(ImageProcessingTest, APartNotSeenForMoreThanTwoAndAHalfPeriodsHasUnknownMotionAgain) {
  const Eigen::Vector3d a0 = centre("A");
  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(400));
  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(800));
  ASSERT_TRUE(part("A").motion_known);

  // Next seen 3 periods later: whatever it did meanwhile, that frame is too old to measure from.
  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(2000));
  EXPECT_FALSE(part("A").motion_known);
  EXPECT_EQ(part("A").stamp, milliseconds(2000));
  const MotionTarget t = env_.read([&](const EnvironmentModel& m) {
    return resolve_target(m, "puma", {task::TargetKind::kAbove, "A"});
  });
  EXPECT_EQ(t.resolution, MotionTarget::Resolution::kWait);

  // One period later it is known again.
  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(2400));
  EXPECT_TRUE(part("A").motion_known);
}

TEST_F(ImageProcessingTest, AConfirmedPartUnderARobotsToolIsNotCorrectedAndLoggedNotSeen) {
  // A is confirmed (the CAD data: present, motion known); the PUMA's tool hovers 20 cm above it, 20 cm to the side.
  const WorkpieceState before = part("A");
  ASSERT_TRUE(before.present && before.motion_known);
  tool_at("puma", before.pose.translation() + Eigen::Vector3d(0.2, 0, 0.2));
  // The arm hides part of A: the detector places it 3 cm off. D, far from the tool, is corrected as usual.
  const Eigen::Vector3d d = centre("D") + Eigen::Vector3d(0.01, 0, 0);
  detector_.then_sees(
      {sighting("A", before.pose.translation() + Eigen::Vector3d(0, 0.03, 0)), sighting("D", d, std::nullopt)});
  frame_at(milliseconds(400));

  expect_same(part("A"), before);
  EXPECT_TRUE(part("D").pose.translation().isApprox(d));
  const nlohmann::ordered_json e = last_event();
  EXPECT_THAT(names(e["seen"]), ElementsAre("D"));
  EXPECT_THAT(names(e["not_seen"]), ::testing::Contains("A"));
}

TEST_F(ImageProcessingTest, APartIsCorrectedWhenTheToolIsFurtherThanTheOcclusionRadiusOrBelowIt) {
  const Eigen::Vector3d a0 = centre("A");
  const Eigen::Vector3d seen = a0 + Eigen::Vector3d(0, 0.01, 0);
  tool_at("puma", a0 + Eigen::Vector3d(0.31, 0, 0.2));    // 31 cm to the side: beyond occlusion_radius (30 cm)
  tool_at("melfa", a0 + Eigen::Vector3d(0.05, 0, -0.1));  // close, but below the part: it hides nothing from above
  detector_.then_sees({sighting("A", seen)});
  frame_at(milliseconds(400));
  EXPECT_TRUE(part("A").pose.translation().isApprox(seen));
  EXPECT_THAT(names(last_event()["seen"]), ElementsAre("A"));
}

TEST_F(ImageProcessingTest, TheOcclusionRadiusIsAnOption) {
  // With a 10 cm occlusion radius, the PUMA's tool 20 cm from confirmed A (the CAD data) hides nothing.
  ASSERT_TRUE(part("A").motion_known);
  VisionOptions options{"overhead", milliseconds(400)};
  options.occlusion_radius = 0.1;
  ImageProcessing narrow(detector_, env_, frames_, log_, options);
  const Eigen::Vector3d a0 = centre("A");
  tool_at("puma", a0 + Eigen::Vector3d(0.2, 0, 0.2));
  const Eigen::Vector3d seen = a0 + Eigen::Vector3d(0, 0.02, 0);
  detector_.then_sees({sighting("A", seen)});
  push(milliseconds(400));
  EXPECT_EQ(narrow.step(milliseconds(400)), 1u);
  EXPECT_TRUE(part("A").pose.translation().isApprox(seen));
  EXPECT_THAT(names(last_event()["seen"]), ElementsAre("A"));
}

TEST_F(ImageProcessingTest, AnUnconfirmedPartUnderAToolIsCorrectedUntilConfirmed) {
  // A first seen with a tool waiting right above it: were it ignored, it would never be confirmed.
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->present = false; });
  const Eigen::Vector3d a0 = centre("A") + Eigen::Vector3d(0, 0.02, 0);
  tool_at("puma", a0 + Eigen::Vector3d(0, 0, 0.1));
  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(400));
  EXPECT_TRUE(part("A").present);
  EXPECT_TRUE(part("A").pose.translation().isApprox(a0));
  EXPECT_THAT(names(last_event()["seen"]), ElementsAre("A"));

  detector_.then_sees({sighting("A", a0)});
  frame_at(milliseconds(800));
  EXPECT_TRUE(part("A").motion_known);  // confirmed
  EXPECT_EQ(part("A").stamp, milliseconds(800));

  // Now confirmed, a sighting 3 cm off under the same tool is the arm's shadow, not motion.
  const WorkpieceState confirmed = part("A");
  detector_.then_sees({sighting("A", a0 + Eigen::Vector3d(0.03, 0, 0))});
  frame_at(milliseconds(1200));
  expect_same(part("A"), confirmed);
  EXPECT_THAT(names(last_event()["not_seen"]), ::testing::Contains("A"));
}

TEST_F(ImageProcessingTest, APartHeldByARobotIsNotCorrected) {
  env_.write([](EnvironmentModel& m) { m.find_workpiece("A")->held_by = "puma"; });
  const WorkpieceState before = part("A");
  detector_.then_sees({sighting("A", before.pose.translation() + Eigen::Vector3d(0, 0.05, 0.1))});
  frame_at(milliseconds(400));
  expect_same(part("A"), before);  // the hand has it: the hold is authoritative
  EXPECT_EQ(part("A").held_by, "puma");
  EXPECT_THAT(names(last_event()["seen"]), ::testing::Not(::testing::Contains("A")));
}

TEST_F(ImageProcessingTest, AFrameThatCouldNotBeMadeChangesNothingAndIsNotShownToTheDetector) {
  const EnvironmentModel before = env_.snapshot();
  push(milliseconds(400), Image{}, "offscreen rendering failed");
  EXPECT_EQ(vision_.step(milliseconds(400)), 1u);

  EXPECT_EQ(detector_.calls(), 0u);
  const EnvironmentModel after = env_.snapshot();
  ASSERT_EQ(after.workpieces.size(), before.workpieces.size());
  for (std::size_t i = 0; i < after.workpieces.size(); ++i) expect_same(after.workpieces[i], before.workpieces[i]);
  nlohmann::ordered_json e;
  for (const auto& ev : events()) {
    if (ev["type"] == "vision") e = ev;
  }
  EXPECT_EQ(e["problem"], "offscreen rendering failed");
  EXPECT_TRUE(e["seen"].empty());
  EXPECT_THAT(names(e["not_seen"]), ElementsAre("A", "B", "C", "D"));
  EXPECT_EQ(e["rejected"], 0);
  EXPECT_EQ(vision_.frames_processed(), 1u);
  ASSERT_EQ(shown_.size(), 1u);
  EXPECT_EQ(shown_[0].result.frame_problem, "offscreen rendering failed");
}

TEST_F(ImageProcessingTest, AFrameThatDidNotComeIsASymptomUntilAFrameComesAgain) {
  push(milliseconds(400), Image{}, "camera 'overhead' delivered no frame");
  vision_.step(milliseconds(400));
  push(milliseconds(800), Image{}, "camera 'overhead' delivered no frame");
  vision_.step(milliseconds(800));
  frame_at(milliseconds(1200));
  std::vector<nlohmann::ordered_json> faults;
  for (const auto& ev : events()) {
    if (ev["type"] == "fault_detected" || ev["type"] == "diagnosis" || ev["type"] == "recovery_end") faults.push_back(ev);
  }
  // Sensed once (the second lost frame is the same fault), diagnosed by the standard tree, over when a frame came.
  ASSERT_EQ(faults.size(), 3u);
  EXPECT_EQ(faults[0]["symptom"], "frame_lost");
  EXPECT_EQ(faults[0]["t"], 0.4);
  EXPECT_EQ(faults[1]["cause"], "camera_dropout");
  EXPECT_EQ(faults[1]["action"], "go_on");
  EXPECT_EQ(faults[2]["ok"], true);
  EXPECT_EQ(faults[2]["t"], 1.2);
  EXPECT_EQ(faults[2]["duration"], 0.8);
}

TEST_F(ImageProcessingTest, AFrameTheDetectorCannotUseChangesNothingAndIsLoggedWithItsProblem) {
  const EnvironmentModel before = env_.snapshot();
  detector_.then_fails("the picture is 4x3, the camera's is 640x480");
  frame_at(milliseconds(400));
  EXPECT_EQ(detector_.calls(), 1u);
  const EnvironmentModel after = env_.snapshot();
  for (std::size_t i = 0; i < after.workpieces.size(); ++i) expect_same(after.workpieces[i], before.workpieces[i]);
  const nlohmann::ordered_json e = last_event();
  EXPECT_THAT(e["problem"].get<std::string>(), HasSubstr("640x480"));
  EXPECT_TRUE(e["seen"].empty());
  EXPECT_THAT(names(e["not_seen"]), ElementsAre("A", "B", "C", "D"));
}

TEST_F(ImageProcessingTest, PredictsWhereTheFreePresentPartsAre) {
  // B is in a hand, C has not arrived, D was moved: the detector is told where A and D are, nothing of B and C.
  Eigen::Vector3d d(0.1, 0.6, 0.45);
  env_.write([&](EnvironmentModel& m) {
    m.find_workpiece("B")->held_by = "puma";
    m.find_workpiece("C")->present = false;
    m.find_workpiece("D")->pose.translation() = d;
  });
  const Eigen::Vector3d a0 = centre("A");
  const Eigen::Vector3d a1 = a0 + Eigen::Vector3d(0.01, -0.01, 0);
  detector_.then_sees({sighting("A", a1)});
  frame_at(milliseconds(400));
  frame_at(milliseconds(800));

  ASSERT_EQ(detector_.calls(), 2u);
  const auto& first = detector_.given()[0].predictions;
  ASSERT_EQ(first.size(), 2u);
  EXPECT_EQ(first[0].workpiece, "A");
  EXPECT_TRUE(first[0].position.isApprox(a0));
  EXPECT_EQ(first[1].workpiece, "D");
  EXPECT_TRUE(first[1].position.isApprox(d));
  // The next frame's predictions carry what the last one corrected.
  const auto& second = detector_.given()[1].predictions;
  ASSERT_EQ(second.size(), 2u);
  EXPECT_TRUE(second[0].position.isApprox(a1));
}

TEST_F(ImageProcessingTest, HandsTheFrameItsImageAndSightingsToOnFrame) {
  detector_.then_sees({sighting("A", centre("A"))}, 2);
  push(milliseconds(400), picture(7));
  push(milliseconds(800), picture(9));
  vision_.step(milliseconds(900));

  // The detector saw the frames' own pictures...
  ASSERT_EQ(detector_.calls(), 2u);
  EXPECT_EQ(detector_.given()[0].image.bgr, picture(7).bgr);
  EXPECT_EQ(detector_.given()[1].image.bgr, picture(9).bgr);
  // ...and on_frame gets each frame's time (not the time it was processed), picture and what the detector said.
  ASSERT_EQ(shown_.size(), 2u);
  EXPECT_EQ(shown_[0].time, milliseconds(400));
  EXPECT_EQ(shown_[1].time, milliseconds(800));
  EXPECT_EQ(shown_[0].image.width, 4);
  EXPECT_EQ(shown_[0].image.height, 3);
  EXPECT_EQ(shown_[0].image.bgr, picture(7).bgr);
  EXPECT_EQ(shown_[1].image.bgr, picture(9).bgr);
  ASSERT_EQ(shown_[0].result.seen.size(), 1u);
  EXPECT_EQ(shown_[0].result.seen[0].workpiece, "A");
  EXPECT_EQ(shown_[0].result.rejected, 2u);
  EXPECT_THAT(shown_[0].result.not_seen, ElementsAre("B", "C", "D"));
  EXPECT_TRUE(shown_[1].result.seen.empty());
  // The detector's own full result travels along, for whoever draws it.
  EXPECT_EQ(std::any_cast<std::size_t>(shown_[0].result.detail), 0u);
  EXPECT_EQ(std::any_cast<std::size_t>(shown_[1].result.detail), 1u);
}

TEST_F(ImageProcessingTest, LogsOneVisionEventPerFrame) {
  const Eigen::Vector3d a = centre("A") + Eigen::Vector3d(0.0123, 0, 0);
  const Eigen::Vector3d d = centre("D");
  detector_.then_sees({sighting("D", d, std::nullopt, 0.75), sighting("A", a, -30.0, 0.9)}, 3);
  push(milliseconds(400));
  vision_.step(milliseconds(1000));

  const std::vector<nlohmann::ordered_json> all = events();
  ASSERT_EQ(all.size(), 1u);
  const nlohmann::ordered_json& e = all[0];
  std::vector<std::string> keys;
  for (const auto& [key, value] : e.items()) keys.push_back(key);
  EXPECT_THAT(keys, ElementsAre("t", "type", "frame", "seen", "not_seen", "rejected", "problem"));
  EXPECT_EQ(e["type"], "vision");
  EXPECT_DOUBLE_EQ(e["t"].get<double>(), 1.0);      // when it was processed
  EXPECT_DOUBLE_EQ(e["frame"].get<double>(), 0.4);  // when it was taken
  ASSERT_EQ(e["seen"].size(), 2u);
  const nlohmann::ordered_json& sa = e["seen"][0];  // the cell's order: A before D
  std::vector<std::string> seen_keys;
  for (const auto& [key, value] : sa.items()) seen_keys.push_back(key);
  EXPECT_THAT(seen_keys, ElementsAre("workpiece", "x", "y", "z", "yaw", "confidence"));
  EXPECT_EQ(sa["workpiece"], "A");
  EXPECT_NEAR(sa["x"].get<double>(), a.x(), 5e-5);
  EXPECT_NEAR(sa["y"].get<double>(), a.y(), 5e-5);
  EXPECT_NEAR(sa["z"].get<double>(), a.z(), 5e-5);
  EXPECT_NEAR(sa["yaw"].get<double>(), -30.0, 0.005);  // degrees
  EXPECT_NEAR(sa["confidence"].get<double>(), 0.9, 5e-4);
  const nlohmann::ordered_json& sd = e["seen"][1];
  EXPECT_EQ(sd["workpiece"], "D");
  EXPECT_TRUE(sd["yaw"].is_null());  // a cylinder has no yaw
  EXPECT_NEAR(sd["confidence"].get<double>(), 0.75, 5e-4);
  EXPECT_THAT(names(e["not_seen"]), ElementsAre("B", "C"));
  EXPECT_EQ(e["rejected"], 3);
  EXPECT_EQ(e["problem"], "");
}

TEST_F(ImageProcessingTest, StepProcessesEveryQueuedFrameInOrderAndReturnsHowMany) {
  EXPECT_EQ(vision_.step(milliseconds(0)), 0u);  // nothing queued
  EXPECT_EQ(log_.size(), 0u);
  push(milliseconds(400));
  push(milliseconds(800));
  push(milliseconds(1200));
  EXPECT_EQ(vision_.step(milliseconds(1200)), 3u);
  EXPECT_EQ(vision_.frames_processed(), 3u);
  EXPECT_EQ(detector_.calls(), 3u);
  Frame left;
  EXPECT_EQ(frames_.try_pop(left), QueueStatus::empty);
  std::vector<double> taken;
  for (const auto& e : events()) taken.push_back(e["frame"].get<double>());
  EXPECT_THAT(taken, ElementsAre(0.4, 0.8, 1.2));
  EXPECT_EQ(vision_.step(milliseconds(1300)), 0u);
  EXPECT_EQ(log_.size(), 3u);
}

TEST_F(ImageProcessingTest, StampsAnEstimateWithItsFramesTimeNotWhenItWasProcessed) {
  const Eigen::Vector3d p = centre("A") + Eigen::Vector3d(0, 0.01, 0);
  detector_.then_sees({sighting("A", p)});
  push(milliseconds(400));
  // The simulation moved on while the frame waited in the queue.
  env_.write([](EnvironmentModel& m) { m.time = milliseconds(700); });
  EXPECT_EQ(vision_.step(milliseconds(700)), 1u);
  const WorkpieceState a = part("A");
  EXPECT_EQ(a.stamp, milliseconds(400));  // 0.3 s old
  EXPECT_TRUE(a.pose.translation().isApprox(p));
  EXPECT_DOUBLE_EQ(last_event()["t"].get<double>(), 0.7);
  EXPECT_DOUBLE_EQ(last_event()["frame"].get<double>(), 0.4);
}

}  // namespace
}  // namespace cellwright::runtime
