// The camera model: intrinsics from the field of view and resolution, extrinsics from the camera's pose, the same
// as MuJoCo's compiled camera; pixels and rays round trip; and it agrees with what MuJoCo renders: the top face of a
// part, rendered, covers exactly the pixels inside its projected outline, and its centroid is the projection of its
// centre.
#include "cellwright/vision/camera_model.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <vector>

#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"
#include "twin/mujoco_fixture.hpp"

namespace cellwright::vision {
namespace {

// The scenes and renders these tests look at.
using namespace cellwright::twin;

const std::filesystem::path kSource = CW_SOURCE_DIR;
constexpr double kPi = std::numbers::pi;

class CameraModelTest : public testing::MujocoTest {
 protected:
  static const models::CellDescription& paper_cell() {
    static const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
    return cell;
  }
  static const models::CameraSpec& overhead() { return *paper_cell().find_camera("overhead"); }
};

// Puts a workpiece at rest with its bottom centre at (x, y, bottom), turned by yaw about z.
void place(Scene& s, const std::string& name, double x, double y, double bottom, double yaw) {
  const WorkpieceIds& w = *s.find_workpiece(name);
  const double half_height = s.cell().find_workpiece(name)->size.z() / 2;
  mjtNum* q = s.data()->qpos + w.qpos_adr;
  q[0] = x;
  q[1] = y;
  q[2] = bottom + half_height;
  q[3] = std::cos(yaw / 2);
  q[4] = 0;
  q[5] = 0;
  q[6] = std::sin(yaw / 2);
  for (int i = 0; i < 6; ++i) s.data()->qvel[w.dof_adr + i] = 0;
}

TEST_F(CameraModelTest, IntrinsicsFromFieldOfViewAndResolution) {
  const CameraModel cam(overhead());
  EXPECT_EQ(cam.width(), 640);
  EXPECT_EQ(cam.height(), 480);
  // fovy 60 degrees over 480 rows: f = 240 / tan(30 deg).
  EXPECT_NEAR(cam.focal(), 240.0 / std::tan(kPi / 6), 1e-9);
  EXPECT_NEAR(cam.principal_point().x, 319.5, 1e-12);
  EXPECT_NEAR(cam.principal_point().y, 239.5, 1e-12);
  // At another resolution the field of view still spans the height.
  const CameraModel small(overhead(), 320, 200);
  EXPECT_NEAR(small.focal(), 100.0 / std::tan(kPi / 6), 1e-9);
  // The camera looks straight down from 2.6 m: the point below it is the image centre, 2.6 m deep.
  const auto centre = cam.project(Eigen::Vector3d(0.35, 0, 0));
  ASSERT_TRUE(centre.has_value());
  EXPECT_NEAR(centre->x, 319.5, 1e-9);
  EXPECT_NEAR(centre->y, 239.5, 1e-9);
  EXPECT_NEAR(cam.depth(Eigen::Vector3d(0.35, 0, 0)), 2.6, 1e-9);
  // The cell's +y (where the machine stands) is up in the image, +x to the right.
  EXPECT_LT(cam.project(Eigen::Vector3d(0.35, 0.5, 0))->y, 239.5);
  EXPECT_GT(cam.project(Eigen::Vector3d(0.85, 0, 0))->x, 319.5);
  // OpenCV's form: K [R t] maps a world point to the same pixel.
  const Eigen::Vector3d p(0.2, -0.4, 0.5);
  const Eigen::Vector3d h = cam.intrinsics() * (cam.camera_from_world() * p);
  EXPECT_NEAR(h.x() / h.z(), cam.project(p)->x, 1e-9);
  EXPECT_NEAR(h.y() / h.z(), cam.project(p)->y, 1e-9);
}

TEST_F(CameraModelTest, AgreesWithMujocosCompiledCamera) {
  Scene s = build_scene(paper_cell());
  const CameraModel from_spec(overhead());
  const CameraModel from_mujoco =
      twin::camera_model(s.model(), s.data(), s.camera_id("overhead"), overhead().width, overhead().height);
  EXPECT_LT((from_spec.pose().matrix() - from_mujoco.pose().matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(from_spec.focal(), from_mujoco.focal(), 1e-9);
  const Eigen::Vector3d p(-0.7, -0.55, 0.53);
  EXPECT_NEAR(from_spec.project(p)->x, from_mujoco.project(p)->x, 1e-6);
  EXPECT_NEAR(from_spec.project(p)->y, from_mujoco.project(p)->y, 1e-6);
}

TEST_F(CameraModelTest, PixelsAndRaysRoundTrip) {
  const CameraModel cam(overhead());
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.5, 639.5), v(-0.5, 479.5), height(0, 1.5), depth(0.5, 3);
  for (int i = 0; i < 200; ++i) {
    const cv::Point2d px(u(rng), v(rng));
    const Ray r = cam.ray(px);
    EXPECT_NEAR(r.direction.norm(), 1, 1e-12);
    const auto back = cam.project(r.origin + depth(rng) * r.direction);
    ASSERT_TRUE(back.has_value());
    EXPECT_NEAR(back->x, px.x, 1e-9);
    EXPECT_NEAR(back->y, px.y, 1e-9);
    const double h = height(rng);
    const auto on = cam.on_plane(px, h);
    ASSERT_TRUE(on.has_value());
    EXPECT_NEAR(on->z(), h, 1e-9);
    EXPECT_NEAR(cam.project(*on)->x, px.x, 1e-9);
    EXPECT_NEAR(cam.project(*on)->y, px.y, 1e-9);
    EXPECT_TRUE(cam.in_image(px));
  }
  // Behind the camera nothing projects, and a plane above the camera is not met.
  EXPECT_FALSE(cam.project(Eigen::Vector3d(0.35, 0, 3.0)).has_value());
  EXPECT_FALSE(cam.on_plane({100, 100}, 3.0).has_value());
  EXPECT_FALSE(cam.in_image({640, 10}));
}

// The pixels of a part's top face in a render: the part's hue and bright (the camera looks down on lit tops; the
// side faces are in half light).
cv::Mat top_face_pixels(const cv::Mat& bgr) {
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV_FULL);
  cv::Mat mask;
  // Red (part A): hue near 0 on the 0..255 scale, saturated, bright.
  cv::Mat low, high;
  cv::inRange(hsv, cv::Scalar(0, 150, 170), cv::Scalar(8, 255, 255), low);
  cv::inRange(hsv, cv::Scalar(248, 150, 170), cv::Scalar(255, 255, 255), high);
  return low | high;
}

TEST_F(CameraModelTest, RenderedTopFaceIsWhereTheModelProjectsIt) {
  Scene s = build_scene(paper_cell());
  const CameraModel cam(overhead());
  Renderer renderer(s.model(), cam.width(), cam.height());
  const models::WorkpieceSpec& a = *paper_cell().find_workpiece("A");
  // Part A on the floor at places all over the image (near the centre, towards the corners), turned.
  const std::vector<std::array<double, 3>> places{
      {0.35, 0, 0.3}, {-0.9, 0.9, 0.1}, {1.5, -0.9, 1.0}, {-0.5, -1.0, 2.0}, {1.2, 1.1, 0.7}};
  for (const auto& [x, y, yaw] : places) {
    SCOPED_TRACE(fmt::format("A at ({}, {}), yaw {}", x, y, yaw));
    s.reset();
    place(s, "A", x, y, 0, yaw);
    mj_forward(s.model(), s.data());
    const cv::Mat image =
        renderer.render_camera(s.data(), s.camera_id("overhead"), cam.width(), cam.height(), RenderQuality::kVision);
    const cv::Mat top = top_face_pixels(image);

    // The projected top face.
    const Eigen::Isometry3d pose =
        Eigen::Translation3d(x, y, a.size.z() / 2) * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
    std::vector<cv::Point2f> corners;
    for (const auto& [cx, cy] : std::vector<std::pair<double, double>>{{1, 1}, {-1, 1}, {-1, -1}, {1, -1}}) {
      const auto p = cam.project(pose * Eigen::Vector3d(cx * a.size.x() / 2, cy * a.size.y() / 2, a.size.z() / 2));
      ASSERT_TRUE(p.has_value());
      corners.emplace_back(static_cast<float>(p->x), static_cast<float>(p->y));
    }
    const cv::Rect box = cv::boundingRect(corners) + cv::Size(4, 4) - cv::Point(2, 2);
    int inside = 0;
    for (int v = box.y; v < box.y + box.height; ++v) {
      for (int u = box.x; u < box.x + box.width; ++u) {
        const double d = cv::pointPolygonTest(corners, cv::Point2f(static_cast<float>(u), static_cast<float>(v)), true);
        const bool lit = top.at<unsigned char>(v, u) != 0;
        // Pixels whose centres are clearly inside the outline are the top face; clearly outside, they are not.
        if (d > 0.3) {
          EXPECT_TRUE(lit) << "pixel (" << u << ", " << v << ") is inside the projected top face but not rendered so";
          ++inside;
        }
        if (d < -0.3) {
          EXPECT_FALSE(lit) << "pixel (" << u << ", " << v << ") is outside the projected top face";
        }
      }
    }
    EXPECT_GT(inside, 30);

    // The centroid of the rendered top face is the projection of its centre (the top face is parallel to the image
    // plane: its projection is an undistorted square).
    const cv::Moments m = cv::moments(top(box), true);
    ASSERT_GT(m.m00, 0);
    const cv::Point2d centroid(box.x + m.m10 / m.m00, box.y + m.m01 / m.m00);
    const cv::Point2d expected = *cam.project(pose * Eigen::Vector3d(0, 0, a.size.z() / 2));
    EXPECT_LT(cv::norm(centroid - expected), 0.25) << "centroid " << centroid << ", projected " << expected;
  }
}

}  // namespace
}  // namespace cellwright::vision
