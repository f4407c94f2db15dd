// Drawing detections: the outline, the pose axes and the label land where the detection says, rejected blobs get a
// box, and nothing else in the picture changes.
#include "cellwright/vision/draw.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"
#include "twin/mujoco_fixture.hpp"

namespace cellwright::vision {
namespace {

// The scenes and renders these tests look at.
using namespace cellwright::twin;

const std::filesystem::path kSource = CW_SOURCE_DIR;

bool drawn(const cv::Mat& image, int u, int v) {
  return image.at<cv::Vec3b>(v, u) != cv::Vec3b(0, 0, 0);
}

bool white(const cv::Mat& image, int u, int v) {
  const cv::Vec3b p = image.at<cv::Vec3b>(v, u);
  return p[0] > 200 && p[1] > 200 && p[2] > 200;
}

// A square part seen from above at (100, 80), 20 pixels wide, its x axis to the right and y axis up.
Detection square_detection() {
  Detection d;
  d.workpiece = "A";
  d.yaw = 0;
  d.yaw_period = 1.5707963;
  d.confidence = 0.97;
  d.outline = {{90, 70}, {110, 70}, {110, 90}, {90, 90}};
  d.top_centre = {100, 80};
  d.axis_x = {115, 80};
  d.axis_y = {100, 65};
  return d;
}

TEST(DrawDetections, OutlinePoseAndLabelWhereTheDetectionSays) {
  cv::Mat image(200, 300, CV_8UC3, cv::Scalar(0, 0, 0));
  DetectionResult result;
  result.detections.push_back(square_detection());
  draw_detections(image, result);
  // On each side of the outline.
  EXPECT_TRUE(drawn(image, 100, 70));
  EXPECT_TRUE(drawn(image, 110, 80));
  EXPECT_TRUE(drawn(image, 100, 90));
  EXPECT_TRUE(drawn(image, 90, 80));
  // The x axis is red and the y axis green, halfway along them.
  const cv::Vec3b x = image.at<cv::Vec3b>(80, 106), y = image.at<cv::Vec3b>(74, 100);
  EXPECT_GT(x[2], 150);
  EXPECT_LT(x[1], 80);
  EXPECT_GT(y[1], 120);
  EXPECT_LT(y[2], 80);
  // Inside the outline away from the axes, and far away, nothing.
  EXPECT_FALSE(drawn(image, 95, 86));
  EXPECT_FALSE(drawn(image, 250, 180));
  // The label: white text to the right of the outline.
  int text = 0;
  for (int v = 60; v < 85; ++v) {
    for (int u = 112; u < 200; ++u) text += white(image, u, v) ? 1 : 0;
  }
  EXPECT_GT(text, 20);
}

TEST(DrawDetections, ACylinderGetsACrossAndRejectsABox) {
  cv::Mat image(200, 300, CV_8UC3, cv::Scalar(0, 0, 0));
  DetectionResult result;
  Detection d = square_detection();
  d.workpiece = "D";
  d.yaw.reset();
  d.yaw_period = 0;
  result.detections.push_back(d);
  result.rejected.push_back(Rejection{"B", cv::Rect(200, 120, 30, 20), 40, 0.5, "partly hidden"});
  draw_detections(image, result);
  // The cross: white across the centre both ways; no red axis.
  EXPECT_TRUE(white(image, 104, 80));
  EXPECT_TRUE(white(image, 100, 76));
  EXPECT_FALSE(drawn(image, 113, 80));
  // The rejected blob's box, all four sides.
  EXPECT_TRUE(drawn(image, 215, 120));
  EXPECT_TRUE(drawn(image, 215, 139));
  EXPECT_TRUE(drawn(image, 200, 130));
  EXPECT_TRUE(drawn(image, 229, 130));
  EXPECT_FALSE(drawn(image, 215, 130));
}

// A camera 2 m above the origin looking straight down: the origin is the image's centre (149.5, 99.5).
TEST(DrawFrameOverlay, TimeNotSeenAndThePredictionsWhereTheCameraProjectsThem) {
  cv::Mat image(200, 300, CV_8UC3, cv::Scalar(0, 0, 0));
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0, 0, 2);
  const CameraModel camera(pose, 0.8, 300, 200);
  draw_frame_overlay(image, 12.4, camera, {{"A", Eigen::Vector3d(0, 0, 0)}, {"B", Eigen::Vector3d(0.3, 0, 0)}},
                     {"B"});
  // The band along the top carries white text (the time and "not seen: B").
  int text = 0;
  for (int v = 0; v < 22; ++v) {
    for (int u = 0; u < 300; ++u) text += white(image, u, v) ? 1 : 0;
  }
  EXPECT_GT(text, 100);
  // A's yellow cross at the centre; B (to the right: +x is image right) circled in red, 12 px from its cross.
  const cv::Vec3b a = image.at<cv::Vec3b>(100, 150);
  EXPECT_GT(a[1], 150);
  EXPECT_GT(a[2], 150);
  EXPECT_LT(a[0], 80);
  const cv::Point2d b = *camera.project(Eigen::Vector3d(0.3, 0, 0));
  ASSERT_GT(b.x, 160);
  int red = 0;
  for (int v = static_cast<int>(b.y) - 14; v <= static_cast<int>(b.y) + 14; ++v) {
    for (int u = static_cast<int>(b.x) - 14; u <= static_cast<int>(b.x) + 14; ++u) {
      const cv::Vec3b p = image.at<cv::Vec3b>(v, u);
      red += p[2] > 150 && p[1] < 80 ? 1 : 0;
    }
  }
  EXPECT_GT(red, 30);
  // Nothing where no part is predicted.
  EXPECT_FALSE(drawn(image, 40, 170));
}

TEST(DrawDetections, RefusesAnImageThatIsNotBgr) {
  cv::Mat grey(20, 20, CV_8UC1, cv::Scalar(0));
  EXPECT_THROW(draw_detections(grey, DetectionResult{}), InternalError);
}

class DrawOnRenderTest : public testing::MujocoTest {};

TEST_F(DrawOnRenderTest, DetectionsOfARenderAreDrawnOnTheirParts) {
  const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
  Scene s = build_scene(cell);
  Renderer renderer(s.model(), 640, 480);
  const cv::Mat image = renderer.render_camera(s.data(), s.camera_id("overhead"), 640, 480, RenderQuality::kVision);
  const DetectionResult found = detect(Detector(cell, CameraModel(*cell.find_camera("overhead"))), image);
  ASSERT_EQ(found.detections.size(), 4u);
  cv::Mat drawn_on = image.clone();
  draw_detections(drawn_on, found);
  for (const Detection& d : found.detections) {
    SCOPED_TRACE(d.workpiece);
    // Some pixel on the outline's edges changed.
    int changed = 0;
    for (std::size_t i = 0; i < d.outline.size(); ++i) {
      const cv::Point2d mid = 0.5 * (d.outline[i] + d.outline[(i + 1) % d.outline.size()]);
      const cv::Point p(cvRound(mid.x), cvRound(mid.y));
      changed += drawn_on.at<cv::Vec3b>(p) != image.at<cv::Vec3b>(p) ? 1 : 0;
    }
    EXPECT_GE(changed, 2);
  }
}

}  // namespace
}  // namespace cellwright::vision
