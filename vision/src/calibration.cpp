#include "cellwright/vision/calibration.hpp"

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <optional>

#include "cellwright/common/files.hpp"
#include "cellwright/models/yaml_fields.hpp"

namespace cellwright::vision {

namespace {

using models::yaml::Doc;
using models::yaml::Fields;

constexpr double kDeg = M_PI / 180.0;

Eigen::Isometry3d pose_of(const Doc& doc, const YAML::Node& n, const std::string& what) {
  Fields f(doc, n, what, {"xyz", "rpy"});
  const Eigen::Vector3d xyz = f.vec3_within("xyz", {-100, 100, false, "m"});
  const Eigen::Vector3d rpy =
      f.has("rpy") ? Eigen::Vector3d(f.vec3_within("rpy", {-360, 360, false, "degrees"}) * kDeg)
                   : Eigen::Vector3d::Zero();
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = xyz;
  p.linear() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return p;
}

}  // namespace

std::vector<cv::Point3d> CalibrationTarget::corner_points() const {
  std::vector<cv::Point3d> out;
  for (int y = 0; y < corners.height; ++y) {
    for (int x = 0; x < corners.width; ++x) out.emplace_back(x * square, y * square, 0.0);
  }
  return out;
}

CalibrationTarget read_target(const std::filesystem::path& file) {
  const Doc doc(file.string());
  const YAML::Node root = models::yaml::load(read_file(file), doc, "not valid YAML");
  if (!root.IsDefined() || root.IsNull()) throw InputError({file.string(), 0, 0}, "the calibration target is empty");
  Fields top(doc, root, "the calibration target", {"checkerboard", "pose"});
  Fields board(doc, top.node("checkerboard"), "the checkerboard", {"corners", "square"});
  CalibrationTarget t;
  t.source = file;
  const YAML::Node& corners = board.node("corners");
  if (!corners.IsSequence() || corners.size() != 2) {
    doc.fail(corners, "field 'corners' of the checkerboard must be two whole numbers, the inner corners along x and y");
  }
  int count[2] = {0, 0};
  for (std::size_t i = 0; i < 2; ++i) {
    const double v = board.number_of(corners[i], "a count of inner corners");
    if (v != std::floor(v) || v < 3 || v > 100) {
      doc.fail(corners[i], fmt::format("a count of inner corners must be a whole number 3..100, got {}", v));
    }
    count[i] = static_cast<int>(v);
  }
  if (count[0] == count[1]) {
    doc.fail(corners, "the checkerboard's two counts of inner corners must differ (a square board reads the same "
                      "turned a quarter)");
  }
  t.corners = {count[0], count[1]};
  t.square = board.within("square", {0, 1, true, "m"});
  t.pose = pose_of(doc, top.node("pose"), top.field("pose"));
  return t;
}

CameraPoseFit locate_camera(const cv::Mat& image, const CameraModel& camera, const CalibrationTarget& target,
                            const SourceLocation& where) {
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  std::vector<cv::Point2f> found;
  if (!cv::findChessboardCorners(grey, target.corners, found,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
    throw InputError(where, fmt::format("no checkerboard of {} x {} inner corners (the target {}) is in the frame",
                                        target.corners.width, target.corners.height, target.source.string()));
  }
  cv::cornerSubPix(grey, found, {5, 5}, {-1, -1},
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
  const std::vector<cv::Point3d> board = target.corner_points();
  const Eigen::Matrix3d k = camera.intrinsics();
  const cv::Matx33d kcv(k(0, 0), k(0, 1), k(0, 2), k(1, 0), k(1, 1), k(1, 2), k(2, 0), k(2, 1), k(2, 2));
  const int w = target.corners.width, h = target.corners.height;
  std::optional<CameraPoseFit> best;
  double best_distance = std::numeric_limits<double>::infinity();
  // The readings of the board: as found, turned half a turn, and mirrored either way (a fit from behind, dropped by
  // its error).
  for (int reading = 0; reading < 4; ++reading) {
    std::vector<cv::Point2f> image_points(found.size());
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int sx = (reading & 1) != 0 ? w - 1 - x : x;
        const int sy = (reading & 2) != 0 ? h - 1 - y : y;
        image_points[static_cast<std::size_t>(y * w + x)] = found[static_cast<std::size_t>(sy * w + sx)];
      }
    }
    cv::Vec3d rvec, tvec;
    if (!cv::solvePnP(board, image_points, kcv, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_ITERATIVE)) continue;
    std::vector<cv::Point2d> projected;
    cv::projectPoints(board, rvec, tvec, kcv, cv::noArray(), projected);
    double sq = 0;
    for (std::size_t i = 0; i < projected.size(); ++i) {
      const cv::Point2d d = projected[i] - cv::Point2d(image_points[i]);
      sq += d.dot(d);
    }
    const double rms = std::sqrt(sq / static_cast<double>(projected.size()));
    if (rms > 2.0 || tvec[2] <= 0) continue;  // not this reading
    cv::Matx33d r;
    cv::Rodrigues(rvec, r);
    Eigen::Isometry3d camera_from_target = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) camera_from_target.linear()(i, j) = r(i, j);
      camera_from_target.translation()(i) = tvec[i];
    }
    // OpenCV's camera frame (y down, z forward) to MuJoCo's (y up, z backward): half a turn about x.
    Eigen::Isometry3d flip = Eigen::Isometry3d::Identity();
    flip.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
    const Eigen::Isometry3d world_from_camera = target.pose * camera_from_target.inverse() * flip;
    const double distance =
        (world_from_camera.translation() - camera.pose().translation()).norm() +
        Eigen::AngleAxisd(world_from_camera.linear().transpose() * camera.pose().linear()).angle();
    if (distance < best_distance) {
      best_distance = distance;
      best = CameraPoseFit{world_from_camera, rms, projected.size()};
    }
  }
  if (!best) {
    throw InputError(where, fmt::format("the checkerboard of the target {} was found, but no camera pose fits its "
                                        "corners within 2 px",
                                        target.source.string()));
  }
  return *best;
}

}  // namespace cellwright::vision
