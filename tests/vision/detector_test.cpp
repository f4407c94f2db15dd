// Finding the workpieces in the overhead camera's picture of the paper's cell, checked against MuJoCo's ground truth:
// every part where it is (position within a few millimetres, yaw within a few degrees), parts out of view or covered
// are not reported with a wrong pose, same-coloured parts are told apart by prediction, and bad frames do not throw.
#include "cellwright/vision/detector.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scene.hpp"
#include "twin/mujoco_fixture.hpp"

namespace cellwright::vision {
namespace {

// The scenes and renders these tests look at.
using namespace cellwright::twin;

using ::testing::Contains;
using ::testing::HasSubstr;

const std::filesystem::path kSource = CW_SOURCE_DIR;
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180;

// Parts turned square to the camera's pixel grid have edges that fall anywhere inside a row or column of pixels
// without changing the picture: their position is known to half a pixel, 2.5 mm on the belt 2 m below the camera.
// Turned parts show steps along their edges that pin them down much better (the random placements below).
constexpr double kSquareToGridTolerance = 0.0025;

class DetectorTest : public testing::MujocoTest {
 protected:
  static const models::CellDescription& paper_cell() {
    static const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
    return cell;
  }
  static CameraModel overhead() { return CameraModel(*paper_cell().find_camera("overhead")); }

  static cv::Mat render(Scene& s, Renderer& r, RenderQuality quality = RenderQuality::kVision) {
    return r.render_camera(s.data(), s.camera_id("overhead"), 640, 480, quality);
  }
};

struct Truth {
  Eigen::Vector3d position;
  double yaw;
};

Truth truth(const Scene& s, const std::string& name) {
  const WorkpieceIds& w = *s.find_workpiece(name);
  const mjtNum* p = s.data()->xpos + 3 * w.body;
  const mjtNum* r = s.data()->xmat + 9 * w.body;
  return {Eigen::Vector3d(p[0], p[1], p[2]), std::atan2(r[3], r[0])};
}

// Puts a workpiece at rest with its bottom centre at (x, y, bottom), turned by yaw about z.
void place(Scene& s, const std::string& name, double x, double y, double bottom, double yaw) {
  const WorkpieceIds& w = *s.find_workpiece(name);
  mjtNum* q = s.data()->qpos + w.qpos_adr;
  q[0] = x;
  q[1] = y;
  q[2] = bottom + s.cell().find_workpiece(name)->size.z() / 2;
  q[3] = std::cos(yaw / 2);
  q[4] = 0;
  q[5] = 0;
  q[6] = std::sin(yaw / 2);
  for (int i = 0; i < 6; ++i) s.data()->qvel[w.dof_adr + i] = 0;
}

// Yaw error of a detection, degrees, modulo the part's symmetry.
double yaw_error(const Detection& d, double true_yaw) {
  if (!d.yaw) return 0;
  double e = std::fmod(*d.yaw - true_yaw, d.yaw_period);
  if (e < 0) e += d.yaw_period;
  if (e > d.yaw_period / 2) e -= d.yaw_period;
  return std::abs(e) / kDeg;
}

double position_error(const Scene& s, const Detection& d) {
  return (d.position - truth(s, d.workpiece).position).norm();
}

// Each workpiece somewhere random: one, chosen at random, on the machine's fixture, the others on the input belt,
// clear of each other and of the stop bar, turned at random.
void random_placement(Scene& s, std::mt19937& rng) {
  const models::CellDescription& cell = s.cell();
  const models::ConveyorSpec& belt = *cell.find_conveyor("input");
  const models::MachineSpec& mill = *cell.find_machine("mill");
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<std::size_t> order(cell.workpieces.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::pair<Eigen::Vector2d, double>> taken;  // centre, radius
  for (std::size_t k = 0; k < order.size(); ++k) {
    const models::WorkpieceSpec& w = cell.workpieces[order[k]];
    const double radius = 0.5 * w.size.head<2>().norm();
    const double yaw = 2 * kPi * unit(rng);
    if (k == 0) {
      const models::Pose top = mill.fixture_top();
      const Eigen::Vector2d room = mill.fixture_size.head<2>() / 2 - w.size.head<2>() / 2;
      place(s, w.name, top.xyz.x() + room.x() * (2 * unit(rng) - 1), top.xyz.y() + room.y() * (2 * unit(rng) - 1),
            top.xyz.z(), yaw);
      continue;
    }
    for (int attempt = 0;; ++attempt) {
      ASSERT_LT(attempt, 1000) << "no room on the belt";
      const double along = radius + (belt.leave - 2 * radius) * unit(rng);
      const double across = (belt.width / 2 - radius) * (2 * unit(rng) - 1);
      const Eigen::Vector3d p = belt.pose.transform() * Eigen::Vector3d(along - belt.length / 2, across, belt.height);
      bool clear = true;
      for (const auto& [c, r] : taken) clear = clear && (p.head<2>() - c).norm() > r + radius + 0.005;
      if (!clear) continue;
      taken.emplace_back(p.head<2>(), radius);
      place(s, w.name, p.x(), p.y(), p.z(), yaw);
      break;
    }
  }
  mj_forward(s.model(), s.data());
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

TEST_F(DetectorTest, FindsEveryPartOfTheInitialCell) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  // The picture for image processing, and the full one with shadows: the same parts, the same poses.
  for (const RenderQuality quality : {RenderQuality::kVision, RenderQuality::kFull}) {
    SCOPED_TRACE(quality == RenderQuality::kVision ? "vision render" : "full render");
    const DetectionResult found = detect(detector, render(s, renderer, quality));
    EXPECT_TRUE(found.frame_problem.empty());
    EXPECT_TRUE(found.rejected.empty());
    EXPECT_TRUE(found.not_seen.empty());
    ASSERT_EQ(found.detections.size(), 4u);
    for (const Detection& d : found.detections) {
      SCOPED_TRACE(describe(d));
      EXPECT_LT(position_error(s, d), kSquareToGridTolerance);
      EXPECT_LT(std::abs(d.position.z() - truth(s, d.workpiece).position.z()), 1e-3);
      EXPECT_LT(yaw_error(d, truth(s, d.workpiece).yaw), 2.0);
      EXPECT_GE(d.confidence, detector.options().min_confidence);
      EXPECT_FALSE(d.ambiguous);
    }
    const Detection& a = *found.find("A");
    EXPECT_EQ(a.support, "conveyor input");
    EXPECT_EQ(a.shape, models::Shape::kBox);
    EXPECT_NEAR(a.yaw_period, kPi / 2, 1e-12);  // a square footprint
    ASSERT_TRUE(a.yaw.has_value());
    const Detection& d = *found.find("D");
    EXPECT_EQ(d.support, "machine mill fixture");
    EXPECT_EQ(d.shape, models::Shape::kCylinder);
    EXPECT_FALSE(d.yaw.has_value()) << "a cylinder has no yaw";
  }
}

TEST_F(DetectorTest, SeededRandomPlacementsAreFoundToAFewMillimetresAndDegrees) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  std::mt19937 rng(20240501);
  std::vector<double> position_errors, yaw_errors;
  for (int trial = 0; trial < 25; ++trial) {
    random_placement(s, rng);
    const DetectionResult found = detect(detector, render(s, renderer));
    EXPECT_TRUE(found.not_seen.empty()) << "trial " << trial << ": " << found.not_seen.front();
    for (const Detection& d : found.detections) {
      position_errors.push_back(position_error(s, d));
      if (d.yaw) yaw_errors.push_back(yaw_error(d, truth(s, d.workpiece).yaw));
      EXPECT_LT(position_errors.back(), 0.003) << "trial " << trial << ": " << describe(d);
    }
  }
  ASSERT_EQ(position_errors.size(), 100u);
  // Issue 5's targets: median position error at most 2 mm, orientation at most 2 degrees.
  EXPECT_LT(median(position_errors), 0.002);
  EXPECT_LT(median(yaw_errors), 2.0);
  EXPECT_LT(*std::max_element(yaw_errors.begin(), yaw_errors.end()), 8.0);
}

TEST_F(DetectorTest, PartsQueuedAgainstTheStopAreFoundWhereTheyTouch) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  // A against the stop bar, B against A, C against B: each hides a side face of the next from the camera.
  const models::ConveyorSpec& belt = *paper_cell().find_conveyor("input");
  for (const auto& [name, k] : std::vector<std::pair<std::string, int>>{{"A", 0}, {"B", 1}, {"C", 2}}) {
    const Eigen::Vector3d p = belt.belt_point(belt.leave - 0.02 - 0.04 * k);
    place(s, name, p.x(), p.y(), p.z(), 0);
  }
  mj_forward(s.model(), s.data());
  const DetectionResult found = detect(detector, render(s, renderer));
  ASSERT_EQ(found.detections.size(), 4u);
  for (const Detection& d : found.detections) {
    SCOPED_TRACE(describe(d));
    EXPECT_LT(position_error(s, d), kSquareToGridTolerance);
    EXPECT_LT(yaw_error(d, truth(s, d.workpiece).yaw), 2.0);
  }
}

TEST_F(DetectorTest, APartTakenAwayIsNotSeenAndTheOthersStillAre) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  place(s, "B", 20, 20, 0, 0);  // far outside the camera's view
  mj_forward(s.model(), s.data());
  const DetectionResult found = detect(detector, render(s, renderer));
  EXPECT_EQ(found.find("B"), nullptr);
  EXPECT_THAT(found.not_seen, Contains("B"));
  EXPECT_EQ(found.detections.size(), 3u);
  for (const Detection& d : found.detections) EXPECT_LT(position_error(s, d), kSquareToGridTolerance);
}

TEST_F(DetectorTest, APartCutByTheImagesEdgeIsNotReportedWrongly) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  const CameraModel cam = overhead();
  const double top = paper_cell().find_workpiece("A")->size.z();
  // A on the floor at the image's right edge, its top centre moving from 8 pixels inside to 3 outside: while whole
  // in the picture it may be found (where it is); cut by the edge, it is not reported.
  int reported = 0;
  for (double u = 631.5; u <= 642.5; u += 1) {
    SCOPED_TRACE(fmt::format("top centre at column {}", u));
    const Eigen::Vector3d p = *cam.on_plane({u, 240}, top);
    place(s, "A", p.x(), p.y(), 0, 0.3);
    mj_forward(s.model(), s.data());
    const DetectionResult found = detect(detector, render(s, renderer));
    if (const Detection* a = found.find("A")) {
      ++reported;
      EXPECT_LT(position_error(s, *a), 0.003) << describe(*a);
    } else {
      EXPECT_THAT(found.not_seen, Contains("A"));
    }
    if (u >= 638.5) {
      EXPECT_EQ(found.find("A"), nullptr) << describe(*found.find("A"));
    }
  }
  EXPECT_GT(reported, 0) << "not even found whole";
}

// A grey plate hovering over a part, as an arm passing over it would: a scene with the plate, a detector that does
// not know it.
TEST_F(DetectorTest, ACoveredPartIsNeverReportedWithAWrongPose) {
  models::CellDescription with_plate = paper_cell();
  models::WorkpieceSpec plate;
  plate.name = "plate";
  plate.size = Eigen::Vector3d(0.1, 0.1, 0.004);
  plate.mass = 0.1;
  plate.rgba = Eigen::Vector4d(0.5, 0.5, 0.52, 1);
  plate.pose.xyz = Eigen::Vector3d(5, 5, 0.1);
  with_plate.workpieces.push_back(plate);
  Scene s = build_scene(with_plate);
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  const Truth a = truth(s, "A");
  int reported = 0, hidden = 0;
  for (int axis = 0; axis < 2; ++axis) {
    // From clear of the part, over it, to clear on the other side, 2 cm above its top.
    for (double offset = -0.075; offset <= 0.075; offset += 0.0025) {
      SCOPED_TRACE(fmt::format("plate moved {:.4f} m along {}", offset, axis == 0 ? "x" : "y"));
      Eigen::Vector3d p = a.position + Eigen::Vector3d(0, 0, 0.05);
      p[axis] += offset;
      place(s, "plate", p.x(), p.y(), p.z(), 0);
      mj_forward(s.model(), s.data());
      const DetectionResult found = detect(detector, render(s, renderer));
      if (const Detection* d = found.find("A")) {
        ++reported;
        EXPECT_LT(position_error(s, *d), 0.003) << describe(*d);
        EXPECT_LT(yaw_error(*d, a.yaw), 3.0) << describe(*d);
      } else {
        ++hidden;
      }
      // Over the part's centre, it is hidden.
      if (std::abs(offset) < 0.01) {
        EXPECT_EQ(found.find("A"), nullptr) << describe(*found.find("A"));
      }
    }
  }
  // Both happened: the sweep covered clear and hidden.
  EXPECT_GT(reported, 4);
  EXPECT_GT(hidden, 10);
}

TEST_F(DetectorTest, APartInTheAirIsNotReportedAsRestingSomewhere) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  // At the hand-over, between the arms, 0.52 m above the floor (held there by the arms in a real run).
  place(s, "A", 0.55, -0.2, 0.52, 0.4);
  mj_forward(s.model(), s.data());
  const DetectionResult found = detect(detector, render(s, renderer));
  EXPECT_EQ(found.find("A"), nullptr) << describe(*found.find("A"));
  ASSERT_FALSE(found.rejected.empty());
  EXPECT_EQ(found.rejected.front().workpiece, "A");
  EXPECT_THAT(found.rejected.front().reason, HasSubstr("lifted"));
}

TEST_F(DetectorTest, SameColouredPartsAreToldApartByPrediction) {
  models::CellDescription twins = paper_cell();
  for (models::WorkpieceSpec& w : twins.workpieces) {
    if (w.name == "B") w.rgba = twins.find_workpiece("A")->rgba;
  }
  Scene s = build_scene(twins);
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(twins, overhead());
  ASSERT_EQ(detector.class_workpieces().size(), 3u) << "A and B share a colour class";
  place(s, "A", -0.3, -0.55, 0.5, 0.2);
  place(s, "B", -0.7, -0.52, 0.5, 0.5);
  mj_forward(s.model(), s.data());
  const cv::Mat image = render(s, renderer);
  const Truth a = truth(s, "A"), b = truth(s, "B");

  // Predictions a few centimetres off still pick the nearer blob.
  const Eigen::Vector3d off(0.03, -0.02, 0);
  const DetectionResult right = detect(detector, image, {{"A", a.position + off}, {"B", b.position - off}});
  ASSERT_NE(right.find("A"), nullptr);
  ASSERT_NE(right.find("B"), nullptr);
  EXPECT_LT((right.find("A")->position - a.position).norm(), 0.003);
  EXPECT_LT((right.find("B")->position - b.position).norm(), 0.003);
  EXPECT_FALSE(right.find("A")->ambiguous);

  // Predictions the other way round: the names follow them.
  const DetectionResult swapped = detect(detector, image, {{"A", b.position}, {"B", a.position}});
  EXPECT_LT((swapped.find("A")->position - b.position).norm(), 0.003);
  EXPECT_LT((swapped.find("B")->position - a.position).norm(), 0.003);

  // No predictions: both found, flagged ambiguous.
  const DetectionResult unsure = detect(detector, image);
  ASSERT_NE(unsure.find("A"), nullptr);
  ASSERT_NE(unsure.find("B"), nullptr);
  EXPECT_TRUE(unsure.find("A")->ambiguous);
  EXPECT_TRUE(unsure.find("B")->ambiguous);
  EXPECT_FALSE(unsure.find("C")->ambiguous);
}

TEST_F(DetectorTest, OnlyThePartsHaveThePartsColours) {
  Scene s = build_scene(paper_cell());
  Renderer renderer(s.model(), 640, 480);
  const Detector detector(paper_cell(), overhead());
  const CameraModel cam = overhead();
  // A against the stop bar, so that the bar is next to a part.
  const models::ConveyorSpec& belt = *paper_cell().find_conveyor("input");
  const Eigen::Vector3d p = belt.belt_point(belt.leave - 0.02);
  place(s, "A", p.x(), p.y(), p.z(), 0);
  mj_forward(s.model(), s.data());
  for (const RenderQuality quality : {RenderQuality::kVision, RenderQuality::kFull}) {
    const cv::Mat labels = detector.classify(render(s, renderer, quality));
    // Where each class's parts are: their silhouettes (the corners' convex hull), two pixels wider.
    std::vector<cv::Mat> expected;
    for (const auto& members : detector.class_workpieces()) {
      expected.push_back(cv::Mat::zeros(labels.size(), CV_8U));
      for (std::size_t w : members) {
        const models::WorkpieceSpec& spec = paper_cell().workpieces[w];
        const WorkpieceIds& ids = *s.find_workpiece(spec.name);
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        pose.translation() = truth(s, spec.name).position;
        pose.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(s.data()->xmat + 9 * ids.body);
        std::vector<cv::Point> corners;
        for (int i = 0; i < 8; ++i) {
          const Eigen::Vector3d k((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
          const cv::Point2d px = *cam.project(pose * (k.cwiseProduct(spec.size / 2)));
          corners.emplace_back(cvRound(px.x), cvRound(px.y));
        }
        std::vector<cv::Point> hull;
        cv::convexHull(corners, hull);
        cv::fillConvexPoly(expected.back(), hull, cv::Scalar(255));
      }
      cv::dilate(expected.back(), expected.back(), cv::Mat::ones(5, 5, CV_8U));
    }
    int stray = 0, part = 0;
    std::string first;
    for (int v = 0; v < labels.rows; ++v) {
      for (int u = 0; u < labels.cols; ++u) {
        const int l = labels.at<unsigned char>(v, u);
        if (l == 0) continue;
        if (expected[static_cast<std::size_t>(l - 1)].at<unsigned char>(v, u) != 0) {
          ++part;
        } else if (stray++ == 0) {
          first = fmt::format("({}, {}) class {}", u, v, l);
        }
      }
    }
    EXPECT_EQ(stray, 0) << "pixels of the machine, the stop bar, the lamp or the floor taken for a part's colour, "
                           "the first at "
                        << first;
    EXPECT_GT(part, 200);
  }
}

TEST_F(DetectorTest, ABadFrameIsReportedNotThrown) {
  const Detector detector(paper_cell(), overhead());
  const DetectionResult small = detect(detector, cv::Mat(240, 320, CV_8UC3, cv::Scalar(0, 0, 0)));
  EXPECT_THAT(small.frame_problem, HasSubstr("320x240"));
  EXPECT_TRUE(small.detections.empty());
  EXPECT_EQ(small.not_seen.size(), 4u);
  const DetectionResult grey = detect(detector, cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)));
  EXPECT_FALSE(grey.frame_problem.empty());
  EXPECT_FALSE(detect(detector, cv::Mat()).frame_problem.empty());
  // A black frame (a camera that sees nothing): no parts, no problem with the frame.
  const DetectionResult black = detect(detector, cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0)));
  EXPECT_TRUE(black.frame_problem.empty());
  EXPECT_EQ(black.not_seen.size(), 4u);
}

TEST_F(DetectorTest, AGreyWorkpieceIsRefused) {
  models::CellDescription cell = paper_cell();
  cell.workpieces[1].rgba = Eigen::Vector4d(0.5, 0.5, 0.55, 1);
  try {
    const Detector detector(cell, overhead());
    FAIL() << "made a detector for a grey part";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("workpiece 'B'"));
    EXPECT_THAT(e.what(), HasSubstr("too grey"));
  }
}

}  // namespace
}  // namespace cellwright::vision
