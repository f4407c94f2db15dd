// The cell's detector as the runtime's PartDetector (CellDetector), inside the image-processing thread's unit: frames
// in, environment model corrected, one vision event per frame. The frames are drawn here (each part's silhouette in its
// colour on a grey floor, through the cell camera's model), so that the test knows exactly where the parts are and
// needs no renderer.
#include "cellwright/vision/cell_detector.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <nlohmann/json.hpp>
#include <numbers>

#include "cellwright/runtime/image_processing.hpp"
#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::paper_cell;
using std::chrono::milliseconds;
using ::testing::HasSubstr;

Eigen::Isometry3d at(double x, double y, double z, double yaw_deg) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(x, y, z);
  p.linear() = Eigen::AngleAxisd(yaw_deg * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

class CellDetectorTest : public ::testing::Test {
 protected:
  // The drawn frames have no shading, so the detector's silhouette fit is not as tight as on a rendered frame.
  static vision::DetectorOptions lenient() {
    vision::DetectorOptions o;
    o.min_confidence = 0.5;
    return o;
  }
  static constexpr int kShift = 8;  // fractional bits of the drawn polygon's corners
  static constexpr double kSub = 1 << kShift;

  CellDetectorTest()
      : cell_(paper_cell()),
        camera_(*cell_.find_camera("overhead")),
        detector_(std::make_shared<const vision::Detector>(cell_, camera_, lenient())),
        env_(make_environment_model(cell_)),
        frames_(4),
        vision_(detector_, env_, frames_, log_, VisionOptions{"overhead", milliseconds(400)}) {}

  // A frame showing box workpiece `name` with its centre at `pose`, nothing else.
  cv::Mat draw(const std::string& name, const Eigen::Isometry3d& pose) const {
    cv::Mat image(camera_.height(), camera_.width(), CV_8UC3, cv::Scalar(128, 128, 128));
    const models::WorkpieceSpec& w = *cell_.find_workpiece(name);
    std::vector<cv::Point> corners;
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d c((i & 1 ? 0.5 : -0.5) * w.size.x(), (i & 2 ? 0.5 : -0.5) * w.size.y(),
                              (i & 4 ? 0.5 : -0.5) * w.size.z());
      const cv::Point2d px = *camera_.project(pose * c);
      corners.emplace_back(cvRound(px.x * kSub), cvRound(px.y * kSub));  // sub-pixel corners, as a renderer has them
    }
    std::vector<cv::Point> hull;
    cv::convexHull(corners, hull);
    const Eigen::Vector4d& c = w.rgba;
    cv::fillConvexPoly(image, hull, cv::Scalar(c[2] * 255, c[1] * 255, c[0] * 255), cv::LINE_8, kShift);
    return image;
  }

  // A frame taken at `t`; the model's clock (the simulation's) moves on to `t`.
  void push(SimDuration t, cv::Mat image, std::string problem = "") {
    env_.write([&](EnvironmentModel& m) { m.time = t; });
    ASSERT_EQ(frames_.try_push(Frame{t, vision::to_image(image), std::move(problem)}), QueueStatus::ok);
  }

  WorkpieceState part(const std::string& name) {
    return env_.read([&](const EnvironmentModel& m) { return *m.find_workpiece(name); });
  }

  nlohmann::json last_event() const { return nlohmann::json::parse(log_.lines().back()); }

  models::CellDescription cell_;
  vision::CameraModel camera_;
  vision::CellDetector detector_;
  SharedEnvironment env_;
  MessageQueue<Frame> frames_;
  EventLog log_;
  ImageProcessing vision_;
};

TEST_F(CellDetectorTest, CorrectsThePoseAndLearnsThePartIsAtRestFromTwoFrames) {
  // A lies on the input belt 4 cm to the side of where the cell description has it, turned by 15 degrees.
  const Eigen::Isometry3d nominal = part("A").pose;
  const Eigen::Isometry3d real =
      at(nominal.translation().x(), nominal.translation().y() + 0.04, nominal.translation().z(), 15);
  push(milliseconds(400), draw("A", real));
  EXPECT_EQ(vision_.step(milliseconds(400)), 1u);
  WorkpieceState a = part("A");
  // Within 5 mm: the drawn part is ~10 pixels across (the detector's accuracy is measured on rendered frames).
  EXPECT_LT((a.pose.translation() - real.translation()).head<2>().norm(), 0.005) << a.pose.translation().transpose();
  EXPECT_GT(a.confidence, 0.75);
  EXPECT_FALSE(a.motion_known);  // seen once: it may be riding the belt
  const nlohmann::json e = last_event();
  EXPECT_EQ(e["type"], "vision");
  ASSERT_EQ(e["seen"].size(), 1u);
  EXPECT_EQ(e["seen"][0]["workpiece"], "A");
  EXPECT_THAT(e["not_seen"].dump(), HasSubstr("\"B\""));

  push(milliseconds(800), draw("A", real));
  vision_.step(milliseconds(800));
  a = part("A");
  EXPECT_TRUE(a.motion_known);
  EXPECT_LT(a.velocity.norm(), 1e-9);
  EXPECT_EQ(a.stamp, milliseconds(800));
}

TEST_F(CellDetectorTest, MeasuresTheSpeedOfAPartRidingTheBelt) {
  const Eigen::Isometry3d start = part("A").pose;
  push(milliseconds(400), draw("A", start));
  Eigen::Isometry3d later = start;
  later.translation().x() += 0.02;  // 2 cm in 0.4 s: the belt's 5 cm/s
  push(milliseconds(800), draw("A", later));
  EXPECT_EQ(vision_.step(milliseconds(800)), 2u);
  const WorkpieceState a = part("A");
  EXPECT_TRUE(a.motion_known);
  EXPECT_NEAR(a.velocity.x(), 0.05, 0.01);
  // Both frames were processed at 0.8 s: the first one's estimate was 0.4 s old when it was taken into the model.
  EXPECT_EQ(vision_.frames_processed(), 2u);
}

TEST_F(CellDetectorTest, KeepsTheLastEstimateOfAPartUnderARobotsToolOrHeld) {
  const Eigen::Isometry3d before = part("A").pose;
  Eigen::Isometry3d moved = before;
  moved.translation().y() += 0.03;
  env_.write([&](EnvironmentModel& m) {
    Eigen::Isometry3d tool = before;
    tool.translation().z() += 0.2;
    m.find_robot("puma")->tcp = tool;  // hovering over A
  });
  push(milliseconds(400), draw("A", moved));
  vision_.step(milliseconds(400));
  EXPECT_TRUE(part("A").pose.isApprox(before));
  EXPECT_THAT(last_event()["not_seen"].dump(), HasSubstr("\"A\""));

  env_.write([&](EnvironmentModel& m) {
    m.find_robot("puma")->tcp.reset();
    m.find_workpiece("A")->held_by = "puma";
  });
  push(milliseconds(800), draw("A", moved));
  vision_.step(milliseconds(800));
  EXPECT_TRUE(part("A").pose.isApprox(before));  // the hand has it: the hold is authoritative
}

TEST_F(CellDetectorTest, AFrameThatCouldNotBeMadeChangesNothingAndSaysWhy) {
  const Eigen::Isometry3d before = part("A").pose;
  push(milliseconds(400), cv::Mat(), "the cell has no camera 'overhead'");
  push(milliseconds(800), cv::Mat(10, 10, CV_8UC3, cv::Scalar(0, 0, 255)));  // wrong size
  EXPECT_EQ(vision_.step(milliseconds(800)), 2u);
  EXPECT_TRUE(part("A").pose.isApprox(before));
  // One vision event per frame, each with its problem; the frame that did not come is also the symptom frame_lost
  // (docs/faults.md), the unusable one is not (a frame came).
  std::vector<nlohmann::json> frames, faults;
  for (const std::string& l : log_.lines()) {
    const nlohmann::json e = nlohmann::json::parse(l);
    (e["type"] == "vision" ? frames : faults).push_back(e);
  }
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_THAT(frames[0]["problem"].get<std::string>(), HasSubstr("no camera"));
  EXPECT_FALSE(frames[1]["problem"].get<std::string>().empty());
  ASSERT_EQ(faults.size(), 3u);
  EXPECT_EQ(faults[0]["symptom"], "frame_lost");
  EXPECT_EQ(faults[1]["type"], "diagnosis");
  EXPECT_EQ(faults[2]["type"], "recovery_end");
}

}  // namespace
}  // namespace cellwright::runtime
