// Offscreen snapshots: the overhead camera sees each workpiece where the scene has it (checked by projecting the
// part into the image with the camera's intrinsics and extrinsics from the cell description), PNGs are written
// atomically, and bad requests are refused clearly.
#include "cellwright/twin/render.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "cellwright/twin/scene.hpp"
#include "twin/mujoco_fixture.hpp"

namespace cellwright::twin {
namespace {

using ::testing::HasSubstr;

const std::filesystem::path kSource = CW_SOURCE_DIR;

class RenderTest : public testing::MujocoTest {
 protected:
  static const models::CellDescription& paper_cell() {
    static const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
    return cell;
  }
};

// Pixel (column, row from the top) where a world point appears in a pinhole camera described by the cell: MuJoCo's
// camera looks along its -z axis with image up along +y; the vertical field of view spans the image height.
cv::Point2d project(const models::CameraSpec& cam, const Eigen::Vector3d& world) {
  const Eigen::Vector3d c = cam.pose.rotation().transpose() * (world - cam.pose.xyz);
  const double f = 0.5 * cam.height / std::tan(0.5 * cam.fovy);
  return {0.5 * cam.width + f * c.x() / -c.z(), 0.5 * cam.height - f * c.y() / -c.z()};
}

// Mean colour (r, g, b in 0..1) of the 3 x 3 pixels around p.
Eigen::Vector3d colour_at(const cv::Mat& bgr, cv::Point2d p) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const int u = static_cast<int>(std::lround(p.x)), v = static_cast<int>(std::lround(p.y));
  for (int dv = -1; dv <= 1; ++dv) {
    for (int du = -1; du <= 1; ++du) {
      const cv::Vec3b px = bgr.at<cv::Vec3b>(v + dv, u + du);
      sum += Eigen::Vector3d(px[2], px[1], px[0]) / 255.0;
    }
  }
  return sum / 9.0;
}

// Similarity of hue and saturation, ignoring brightness (shading): cosine of the angle between the colours.
double similarity(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.normalized().dot(b.normalized());
}

Eigen::Vector3d part_top(const Scene& s, const WorkpieceIds& w, const models::WorkpieceSpec& spec) {
  const mjtNum* p = s.data()->xpos + 3 * w.body;
  return Eigen::Vector3d(p[0], p[1], p[2] + spec.size.z() / 2);
}

// Every part looks, in the overhead image, the colour it has (and more like it than like any other part's).
void expect_parts_seen(const Scene& s, const cv::Mat& image) {
  const models::CellDescription& cell = s.cell();
  const models::CameraSpec& cam = *cell.find_camera("overhead");
  for (const models::WorkpieceSpec& spec : cell.workpieces) {
    SCOPED_TRACE("workpiece " + spec.name);
    const cv::Point2d px = project(cam, part_top(s, *s.find_workpiece(spec.name), spec));
    ASSERT_GT(px.x, 2);
    ASSERT_GT(px.y, 2);
    ASSERT_LT(px.x, image.cols - 3);
    ASSERT_LT(px.y, image.rows - 3);
    const Eigen::Vector3d seen = colour_at(image, px);
    const Eigen::Vector3d own = spec.rgba.head<3>();
    EXPECT_GT(similarity(seen, own), 0.97) << "seen " << seen.transpose() << " at " << px;
    for (const models::WorkpieceSpec& other : cell.workpieces) {
      if (other.name == spec.name) continue;
      EXPECT_GT(similarity(seen, own), similarity(seen, other.rgba.head<3>())) << "looks like " << other.name;
    }
    // 10 cm to the side is not the part (so the check above could fail).
    const cv::Point2d beside =
        project(cam, part_top(s, *s.find_workpiece(spec.name), spec) + Eigen::Vector3d(0, 0.1, 0));
    EXPECT_LT(similarity(colour_at(image, beside), own), 0.95) << "the part's colour is everywhere";
  }
}

TEST_F(RenderTest, OverheadCameraSeesEachWorkpieceWhereTheSceneHasIt) {
  Scene s = build_scene(paper_cell());
  const models::CameraSpec& cam = *paper_cell().find_camera("overhead");
  Renderer renderer(s.model(), cam.width, cam.height);
  const cv::Mat image = renderer.render_camera(s.data(), s.camera_id("overhead"), cam.width, cam.height);
  ASSERT_EQ(image.cols, 640);
  ASSERT_EQ(image.rows, 480);
  ASSERT_EQ(image.type(), CV_8UC3);
  expect_parts_seen(s, image);

  // Two seconds later the belt has moved the parts 10 cm: the camera sees them there, and A is gone from where it was.
  const WorkpieceIds& a = *s.find_workpiece("A");
  const Eigen::Vector3d a_before = part_top(s, a, paper_cell().workpieces[0]);
  s.step(static_cast<int>(2.0 / s.model()->opt.timestep));
  EXPECT_GT(part_top(s, a, paper_cell().workpieces[0]).x() - a_before.x(), 0.09);
  const cv::Mat later = renderer.render_camera(s.data(), s.camera_id("overhead"), cam.width, cam.height);
  expect_parts_seen(s, later);
  EXPECT_LT(similarity(colour_at(later, project(cam, a_before)), paper_cell().workpieces[0].rgba.head<3>()), 0.95);
}

// Whether OSMesa's library is mapped into this process.
bool osmesa_loaded() {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line)) {
    if (line.find("libOSMesa") != std::string::npos) return true;
  }
  return false;
}

// A process that renders nothing does not load OSMesa (and with it llvmpipe and libLLVM, about 0.1 s of CPU at every
// start): the first Renderer loads it. The check runs in a fresh process (the "threadsafe" death-test style
// re-executes this program for this test alone), where no other test has made a Renderer yet.
TEST_F(RenderTest, OSMesaIsLoadedByTheFirstRendererOnly) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        Scene s = build_scene(paper_cell());
        s.step(10);
        if (osmesa_loaded()) {
          std::fputs("OSMesa loaded before any Renderer was made\n", stderr);
          std::exit(3);
        }
        {
          Renderer renderer(s.model(), 64, 48);
          if (renderer.render_overview(s.data(), 64, 48).empty()) std::exit(4);
        }
        std::exit(osmesa_loaded() ? 0 : 5);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST_F(RenderTest, RenderingIsRepeatable) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 320, 240);
  const cv::Mat first = renderer.render_overview(s.data(), 320, 240);
  const cv::Mat second = renderer.render_overview(s.data(), 320, 240);
  EXPECT_EQ(cv::norm(first, second, cv::NORM_INF), 0.0);
  // A smaller image than the renderer's maximum has the size asked for.
  const cv::Mat small = renderer.render_camera(s.data(), s.camera_id("overhead"), 160, 120);
  EXPECT_EQ(small.cols, 160);
  EXPECT_EQ(small.rows, 120);
}

TEST_F(RenderTest, OverviewShowsTheCell) {
  Scene s = build_scene(paper_cell());
  const cv::Mat image = render_view(s, kOverviewCamera, 640, 480);
  ASSERT_EQ(image.cols, 640);
  // The red part, the MELFA's dark pedestal and the cream PUMA are all in the picture: count pixels of each colour.
  auto count = [&](const Eigen::Vector3d& rgb, double min_similarity, double min_brightness) {
    int n = 0;
    for (int v = 0; v < image.rows; ++v) {
      for (int u = 0; u < image.cols; ++u) {
        const cv::Vec3b px = image.at<cv::Vec3b>(v, u);
        const Eigen::Vector3d c(px[2] / 255.0, px[1] / 255.0, px[0] / 255.0);
        if (c.norm() > min_brightness && similarity(c, rgb) > min_similarity) ++n;
      }
    }
    return n;
  };
  EXPECT_GT(count({0.85, 0.1, 0.1}, 0.97, 0.3), 10) << "no red workpiece";
  EXPECT_GT(count({0.1, 0.3, 0.85}, 0.97, 0.3), 10) << "no blue workpiece";
  EXPECT_GT(count({0.3, 0.5, 0.35}, 0.99, 0.2), 500) << "no machine";
}

TEST_F(RenderTest, UnknownCameraAndBadSizesAreRefused) {
  Scene s = build_scene(paper_cell());
  try {
    render_view(s, "side", 64, 48);
    FAIL() << "rendered an unknown camera";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the cell has no camera 'side' (cameras: overview, overhead)"));
    EXPECT_EQ(e.where().file, paper_cell().source.string());
  }
  EXPECT_THROW(render_view(s, "overhead", 0, 48), InputError);
  EXPECT_THROW(render_view(s, "overhead", 64, 5000), InputError);
  Renderer renderer(s.model(), 64, 48);
  EXPECT_THROW(renderer.render_camera(s.data(), s.camera_id("overhead"), 65, 48), InternalError);
}

TEST_F(RenderTest, ARendererStaysOnItsThread) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 64, 48);
  bool refused = false;
  std::thread other([&] {
    try {
      renderer.render_overview(s.data(), 64, 48);
    } catch (const InternalError&) {
      refused = true;
    }
  });
  other.join();
  EXPECT_TRUE(refused);
}

}  // namespace
}  // namespace cellwright::twin
