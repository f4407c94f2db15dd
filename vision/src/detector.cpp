// Workpiece detection by colour and silhouette fitting (detector.hpp; docs/vision.md explains the method).
#include "cellwright/vision/detector.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::vision {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Shades a colour is seen in: diffuse and ambient light scale it (kShadeMin..kShadeMax times the material colour),
// specular highlights add up to kHighlight of white, and each channel clips at full scale.
constexpr double kShadeMin = 0.1, kShadeMax = 2.0, kHighlight = 0.1;

// Soft edge of a fitted silhouette, pixels either side of the outline (coverage()): smooth enough for the fit to
// move by fractions of a pixel, sharp like the renderer's (and a camera's) edges.
constexpr double kEdge = 0.6;
// A fit has converged when its step is smaller than this (about a hundredth of a pixel at the cell's scale).
constexpr double kTinyMove = 2e-5, kTinyTurn = 0.005 * kDeg;
// Pixels nearer than this to a silhouette's edge take part in a fitting step; a step turns the part at most
// kMaxTurn.
constexpr double kBand = 2.5;
constexpr double kMaxTurn = 8 * kDeg;
// After a fit, yaws this far either side are tried in case it stopped in a local minimum.
constexpr int kScanSteps = 8;
constexpr double kScanStep = 1 * kDeg;
// A cylinder's end circles as polygons of this many corners.
constexpr int kCircleCorners = 32;
// The conveyors' stop bars as scene.cpp builds them: 10 mm thick, 40 mm high, across the belt, their upstream face
// at `leave`.
constexpr double kStopThickness = 0.01, kStopHeight = 0.04;

double hue_of(const Eigen::Vector3d& rgb) {
  const double mx = rgb.maxCoeff(), mn = rgb.minCoeff(), c = mx - mn;
  if (c <= 0) return 0;
  double h = 0;
  if (mx == rgb[0]) {
    h = 60 * std::fmod((rgb[1] - rgb[2]) / c + 6, 6.0);
  } else if (mx == rgb[1]) {
    h = 60 * ((rgb[2] - rgb[0]) / c + 2);
  } else {
    h = 60 * ((rgb[0] - rgb[1]) / c + 4);
  }
  return h;
}

// Signed difference a - b of two angles in degrees, in (-180, 180].
double hue_diff(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  return d;
}

struct HueInterval {
  double centre = 0, lo = 0, hi = 0;  // degrees: [centre + lo, centre + hi]
  bool contains(double h) const {
    const double d = hue_diff(h, centre);
    return d >= lo && d <= hi;
  }
  bool overlaps(const HueInterval& o) const {
    return contains(o.centre + o.lo) || contains(o.centre + o.hi) || o.contains(centre + lo) || o.contains(centre + hi);
  }
};

// A workpiece shape as fitted: corners in the part's frame (centre origin) whose projections' convex hull is its
// silhouette.
struct ShapeModel {
  models::Shape shape = models::Shape::kBox;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> corners;
  double period = 0;  // yaw symmetry, 0 for none (a cylinder)
  bool same(const models::WorkpieceSpec& w) const { return w.shape == shape && (w.size - size).norm() < 1e-9; }
};

ShapeModel make_shape(const models::WorkpieceSpec& w) {
  ShapeModel m;
  m.shape = w.shape;
  m.size = w.size;
  const Eigen::Vector3d h = w.size / 2;
  if (w.shape == models::Shape::kBox) {
    for (int i = 0; i < 8; ++i) {
      m.corners.emplace_back((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(), (i & 4) ? h.z() : -h.z());
    }
    m.period = std::abs(w.size.x() - w.size.y()) < 1e-9 ? kPi / 2 : kPi;
  } else {
    // The polygon with the circle's area, so that its outline is on average the circle's.
    const double a = 2 * kPi / kCircleCorners;
    const double r = h.x() * std::sqrt(a / std::sin(a));
    for (int i = 0; i < kCircleCorners; ++i) {
      const double t = a * i;
      for (double z : {-h.z(), h.z()}) m.corners.emplace_back(r * std::cos(t), r * std::sin(t), z);
    }
    m.period = 0;
  }
  return m;
}

// Convex hull (counter-clockwise in x right, y down pixels: clockwise on screen) by Andrew's monotone chain.
std::vector<cv::Point2d> convex_hull(std::vector<cv::Point2d> p) {
  std::sort(p.begin(), p.end(),
            [](const cv::Point2d& a, const cv::Point2d& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  if (p.size() < 3) return p;
  auto cross = [](const cv::Point2d& o, const cv::Point2d& a, const cv::Point2d& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  std::vector<cv::Point2d> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

// Half planes of a convex polygon: n . p - d is the signed distance of p from each edge's line, positive outside.
struct Edges {
  std::vector<Eigen::Vector3d> lines;  // (nx, ny, d)
  bool ok = false;
};

Edges edges_of(const std::vector<cv::Point2d>& poly) {
  Edges e;
  if (poly.size() < 3) return e;
  double area = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const cv::Point2d& a = poly[i];
    const cv::Point2d& b = poly[(i + 1) % poly.size()];
    area += a.x * b.y - a.y * b.x;
  }
  const double orient = area > 0 ? 1.0 : -1.0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const cv::Point2d& a = poly[i];
    const cv::Point2d& b = poly[(i + 1) % poly.size()];
    Eigen::Vector2d n(b.y - a.y, -(b.x - a.x));
    const double len = n.norm();
    if (len < 1e-12) continue;
    n *= orient / len;
    e.lines.emplace_back(n.x(), n.y(), n.x() * a.x + n.y() * a.y);
  }
  e.ok = e.lines.size() >= 3 && std::abs(area) > 1e-9;
  return e;
}

// How much a pixel whose centre is sd pixels outside a silhouette's edge counts as covered: 1 well inside, 0 well
// outside, a smooth step across kEdge either side of the edge.
double coverage(double sd) {
  if (sd <= -kEdge) return 1;
  if (sd >= kEdge) return 0;
  const double t = 0.5 - 0.5 * sd / kEdge;
  return t * t * (3 - 2 * t);
}

double signed_distance(const Edges& e, double u, double v) {
  double s = -kInf;
  for (const auto& l : e.lines) s = std::max(s, l.x() * u + l.y() * v - l.z());
  return s;
}

// A pixel of a fitting window: its centre and what it shows (1 the blob, 0 not a part).
struct Sample {
  float u, v;
  float target;
};

struct Pose2 {
  double x = 0, y = 0, yaw = 0;
};

struct Fit {
  Pose2 pose;
  double cost = kInf;
  double iou = 0;
  std::size_t support = 0;
  std::size_t shape = 0;
  std::vector<cv::Point2d> outline;
};

}  // namespace

struct Detector::Impl {
  CameraModel camera;
  DetectorOptions options;
  std::vector<models::WorkpieceSpec> workpieces;
  std::vector<Support> supports;
  std::vector<ShapeModel> shapes;
  std::vector<std::size_t> shape_of;  // per workpiece
  std::vector<std::vector<std::size_t>> class_members;
  std::vector<std::size_t> class_of;           // per workpiece
  std::array<unsigned char, 256> hue_class{};  // per hue on OpenCV's full scale (0..255): 0 or 1 + class
  cv::Mat static_occluders;                    // 255 where a stop bar is in the image

  Impl(CameraModel cam, DetectorOptions opts) : camera(std::move(cam)), options(opts) {}

  std::vector<cv::Point2d> silhouette(const ShapeModel& s, const Pose2& p, double z) const {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d c(p.x, p.y, z);
    std::vector<cv::Point2d> pts;
    pts.reserve(s.corners.size());
    for (const auto& k : s.corners) {
      const auto px = camera.project(c + r * k);
      if (!px) return {};
      pts.push_back(*px);
    }
    return convex_hull(std::move(pts));
  }

  // Whether p is inside a support's block (a part cannot rest there: on a machine's top where its fixture is).
  bool inside_support(const Eigen::Vector3d& p) const {
    for (const Support& s : supports) {
      if (!std::isfinite(s.half.x()) || p.z() <= s.bottom || p.z() >= s.height) continue;
      if (on_support(s, p.x(), p.y(), 0)) return true;
    }
    return false;
  }

  // Whether the segment from the camera to p passes through a support's block (shrunk by a millimetre, so that
  // a part resting on it is not hidden by it).
  bool hidden_by_support(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d c = camera.position();
    for (const Support& s : supports) {
      if (!std::isfinite(s.half.x())) continue;
      // The segment in the block's frame, clipped slab by slab.
      const Eigen::Vector2d a = Eigen::Rotation2Dd(-s.yaw) * (c.head<2>() - s.centre);
      const Eigen::Vector2d b = Eigen::Rotation2Dd(-s.yaw) * (p.head<2>() - s.centre);
      const Eigen::Vector3d from(a.x(), a.y(), c.z()), to(b.x(), b.y(), p.z());
      const Eigen::Vector3d lo(-s.half.x() + 1e-3, -s.half.y() + 1e-3, s.bottom + 1e-3);
      const Eigen::Vector3d hi(s.half.x() - 1e-3, s.half.y() - 1e-3, s.height - 1e-3);
      double t0 = 0, t1 = 1;
      for (int i = 0; i < 3 && t0 <= t1; ++i) {
        const double dir = to[i] - from[i];
        if (std::abs(dir) < 1e-12) {
          if (from[i] < lo[i] || from[i] > hi[i]) t0 = 2;
          continue;
        }
        double ta = (lo[i] - from[i]) / dir, tb = (hi[i] - from[i]) / dir;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      if (t0 <= t1) return true;
    }
    return false;
  }

  bool on_support(const Support& s, double x, double y, double margin) const {
    if (!std::isfinite(s.half.x())) return true;
    const Eigen::Vector2d d = Eigen::Rotation2Dd(-s.yaw) * (Eigen::Vector2d(x, y) - s.centre);
    return std::abs(d.x()) <= s.half.x() + margin && std::abs(d.y()) <= s.half.y() + margin;
  }
};

namespace {

using Impl = Detector::Impl;

// Residuals target - coverage of the silhouette at `pose`, for every sample.
bool residuals(const Impl& d, const ShapeModel& s, const Pose2& pose, double z, const std::vector<Sample>& samples,
               Eigen::VectorXd& r) {
  const Edges e = edges_of(d.silhouette(s, pose, z));
  if (!e.ok) return false;
  r.resize(static_cast<Eigen::Index>(samples.size()));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double sd = signed_distance(e, samples[i].u, samples[i].v);
    r[static_cast<Eigen::Index>(i)] = samples[i].target - coverage(sd);
  }
  return true;
}

// Levenberg-Marquardt on the pose parameters (x, y, and the yaw when fit_yaw), numeric Jacobian. Each iteration
// works on the samples near the silhouette's edge (kBand): the others are fully in or out and stay so while a step
// moves the edge less than kBand - kEdge, which max_move (m) ensures. Returns the cost over all samples.
double refine(const Impl& d, const ShapeModel& s, Pose2& pose, double z, const std::vector<Sample>& samples,
              bool fit_yaw, int iterations, double max_move) {
  const int n = fit_yaw ? 3 : 2;
  const std::array<double, 3> step{2e-4, 2e-4, 0.2 * kDeg};
  double lambda = 1e-2;
  std::vector<Sample> band;
  Eigen::VectorXd r, r2;
  for (int it = 0; it < iterations; ++it) {
    const Edges e = edges_of(d.silhouette(s, pose, z));
    if (!e.ok) return kInf;
    band.clear();
    for (const Sample& x : samples) {
      if (std::abs(signed_distance(e, x.u, x.v)) < kBand) band.push_back(x);
    }
    if (band.empty() || !residuals(d, s, pose, z, band, r)) break;
    double cost = r.squaredNorm();
    Eigen::MatrixXd j(r.size(), n);
    for (int k = 0; k < n; ++k) {
      Pose2 p = pose;
      (k == 0 ? p.x : k == 1 ? p.y : p.yaw) += step[static_cast<std::size_t>(k)];
      if (!residuals(d, s, p, z, band, r2)) return kInf;
      j.col(k) = (r2 - r) / step[static_cast<std::size_t>(k)];
    }
    const Eigen::MatrixXd jtj = j.transpose() * j;
    const Eigen::VectorXd jtr = j.transpose() * r;
    bool improved = false, converged = false;
    for (int tries = 0; tries < 6 && !improved; ++tries) {
      Eigen::MatrixXd a = jtj;
      for (int k = 0; k < n; ++k) a(k, k) += lambda * (jtj(k, k) + 1e-9);
      Eigen::VectorXd delta = a.ldlt().solve(-jtr);
      if (!delta.allFinite()) break;
      const double move = delta.head<2>().norm();
      if (move > max_move) delta *= max_move / move;
      if (fit_yaw && std::abs(delta[2]) > kMaxTurn) delta[2] = std::copysign(kMaxTurn, delta[2]);
      Pose2 p = pose;
      p.x += delta[0];
      p.y += delta[1];
      if (fit_yaw) p.yaw += delta[2];
      if (residuals(d, s, p, z, band, r2) && r2.squaredNorm() < cost) {
        pose = p;
        cost = r2.squaredNorm();
        lambda = std::max(1e-6, lambda / 3);
        improved = true;
        // Converged: the step is a hundredth of a pixel.
        converged = delta.head<2>().norm() < kTinyMove && (!fit_yaw || std::abs(delta[2]) < kTinyTurn);
      } else {
        lambda *= 4;
      }
    }
    if (!improved || converged) break;
  }
  return residuals(d, s, pose, z, samples, r) ? r.squaredNorm() : kInf;
}

// Intersection over union of the silhouette (pixel centres inside it) and the blob, over the samples.
double iou(const std::vector<cv::Point2d>& outline, const std::vector<Sample>& samples) {
  const Edges e = edges_of(outline);
  if (!e.ok) return 0;
  double both = 0, either = 0;
  for (const Sample& s : samples) {
    const bool in_model = signed_distance(e, s.u, s.v) < 0;
    const bool in_blob = s.target > 0.5f;
    both += (in_model && in_blob) ? 1 : 0;
    either += (in_model || in_blob) ? 1 : 0;
  }
  return either > 0 ? both / either : 0;
}

double wrap_yaw(double yaw, double period) {
  if (period <= 0) return 0;
  double y = std::fmod(yaw, period);
  if (y < 0) y += period;
  if (y >= period) y -= period;
  return y;
}

std::string two_places(double v) {
  return fmt::format("{:.2f}", v);
}

}  // namespace

Detector::Detector(const models::CellDescription& cell, CameraModel camera, DetectorOptions options) {
  auto impl = std::make_shared<Impl>(std::move(camera), options);
  Impl& d = *impl;
  d.workpieces = cell.workpieces;

  // Colour classes: the hue interval of each workpiece's shades; overlapping intervals share a class.
  std::vector<HueInterval> hues;
  for (const models::WorkpieceSpec& w : cell.workpieces) {
    const Eigen::Vector3d rgb = w.rgba.head<3>();
    HueInterval h;
    h.centre = hue_of(rgb);
    h.lo = kInf;
    h.hi = -kInf;
    for (double k = kShadeMin; k <= kShadeMax + 1e-9; k += 0.05) {
      for (double s = 0; s <= kHighlight + 1e-9; s += kHighlight / 4) {
        const Eigen::Vector3d c = (k * rgb + Eigen::Vector3d::Constant(s)).cwiseMin(1.0);
        const double mx = c.maxCoeff(), chroma = mx - c.minCoeff();
        if (mx <= 0 || chroma / mx < options.min_saturation || chroma * 255 < options.min_chroma) continue;
        const double dh = hue_diff(hue_of(c), h.centre);
        h.lo = std::min(h.lo, dh);
        h.hi = std::max(h.hi, dh);
      }
    }
    if (h.lo > h.hi) {
      throw InputError(w.where, fmt::format("workpiece '{}': its colour ({:.2f}, {:.2f}, {:.2f}) is too grey for the "
                                            "camera to tell it from the cell (saturation below {})",
                                            w.name, rgb[0], rgb[1], rgb[2], options.min_saturation));
    }
    h.lo -= options.hue_margin;
    h.hi += options.hue_margin;
    hues.push_back(h);
  }
  const std::size_t n = cell.workpieces.size();
  std::vector<std::size_t> root(n);
  for (std::size_t i = 0; i < n; ++i) root[i] = i;
  auto find = [&](std::size_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if (hues[i].overlaps(hues[j])) root[find(j)] = find(i);
    }
  }
  d.class_of.assign(n, 0);
  std::vector<std::size_t> class_of_root(n, n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = find(i);
    if (class_of_root[r] == n) {
      class_of_root[r] = d.class_members.size();
      d.class_members.emplace_back();
    }
    d.class_of[i] = class_of_root[r];
    d.class_members[d.class_of[i]].push_back(i);
  }
  for (int h = 0; h < 256; ++h) {
    const double deg = h * 360.0 / 256.0;
    for (std::size_t i = 0; i < n; ++i) {
      // OpenCV rounds hues to 1.4 degree steps: a step either side still counts.
      const HueInterval& hi = hues[i];
      if (hi.contains(deg) || hi.contains(deg - 0.7) || hi.contains(deg + 0.7)) {
        d.hue_class[static_cast<std::size_t>(h)] = static_cast<unsigned char>(1 + d.class_of[i]);
      }
    }
  }

  // Shapes to fit: one per distinct shape and size.
  for (const models::WorkpieceSpec& w : cell.workpieces) {
    auto it = std::find_if(d.shapes.begin(), d.shapes.end(), [&](const ShapeModel& s) { return s.same(w); });
    if (it == d.shapes.end()) {
      d.shapes.push_back(make_shape(w));
      it = d.shapes.end() - 1;
    }
    d.shape_of.push_back(static_cast<std::size_t>(it - d.shapes.begin()));
  }

  // Supports: belts, machine fixtures and tops, the floor.
  for (const models::ConveyorSpec& c : cell.conveyors) {
    const Eigen::Vector3d top = c.pose.transform() * Eigen::Vector3d(0, 0, c.height);
    d.supports.push_back(Support{"conveyor " + c.name, top.z(), top.head<2>(), c.pose.rpy.z(),
                                 Eigen::Vector2d(c.length / 2, c.width / 2), c.pose.xyz.z()});
  }
  for (const models::MachineSpec& m : cell.machines) {
    const models::Pose f = m.fixture_top();
    const Eigen::Vector3d top = m.pose.transform() * Eigen::Vector3d(0, 0, m.size.z());
    d.supports.push_back(Support{"machine " + m.name + " fixture", f.xyz.z(), f.xyz.head<2>(), f.rpy.z(),
                                 m.fixture_size.head<2>() / 2, top.z()});
    d.supports.push_back(Support{"machine " + m.name + " top", top.z(), top.head<2>(), m.pose.rpy.z(),
                                 m.size.head<2>() / 2, m.pose.xyz.z()});
  }
  d.supports.push_back(Support{"floor", 0, Eigen::Vector2d::Zero(), 0, Eigen::Vector2d(kInf, kInf), 0});

  // Static occluders: the stop bars stand above the belt and hide the lower side of a part held against them.
  d.static_occluders = cv::Mat::zeros(d.camera.height(), d.camera.width(), CV_8U);
  for (const models::ConveyorSpec& c : cell.conveyors) {
    if (!c.stop) continue;
    const Eigen::Vector3d centre(c.leave - c.length / 2 + kStopThickness / 2, 0, c.height + kStopHeight / 2);
    const Eigen::Vector3d half(kStopThickness / 2, c.width / 2, kStopHeight / 2);
    std::vector<cv::Point2d> pts;
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d k((i & 1) ? half.x() : -half.x(), (i & 2) ? half.y() : -half.y(),
                              (i & 4) ? half.z() : -half.z());
      if (const auto px = d.camera.project(c.pose.transform() * (centre + k))) pts.push_back(*px);
    }
    if (pts.size() != 8) continue;
    std::vector<cv::Point> poly;
    for (const auto& p : convex_hull(pts)) poly.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::fillConvexPoly(d.static_occluders, poly, cv::Scalar(255));
  }
  cv::dilate(d.static_occluders, d.static_occluders, cv::Mat::ones(3, 3, CV_8U));
  impl_ = std::move(impl);
}

const CameraModel& Detector::camera() const {
  return impl_->camera;
}
const DetectorOptions& Detector::options() const {
  return impl_->options;
}
const std::vector<models::WorkpieceSpec>& Detector::workpieces() const {
  return impl_->workpieces;
}
const std::vector<Support>& Detector::supports() const {
  return impl_->supports;
}
const std::vector<std::vector<std::size_t>>& Detector::class_workpieces() const {
  return impl_->class_members;
}

cv::Mat Detector::classify(const cv::Mat& bgr) const {
  CW_CHECK(bgr.type() == CV_8UC3, "classify needs an 8-bit, 3-channel image");
  const Impl& d = *impl_;
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV_FULL);
  cv::Mat labels(bgr.rows, bgr.cols, CV_8U);
  const int min_s = static_cast<int>(std::ceil(d.options.min_saturation * 255));
  const int min_sv = d.options.min_chroma * 255;  // chroma = s * v / 255
  for (int v = 0; v < hsv.rows; ++v) {
    const cv::Vec3b* in = hsv.ptr<cv::Vec3b>(v);
    unsigned char* out = labels.ptr<unsigned char>(v);
    for (int u = 0; u < hsv.cols; ++u) {
      const int s = in[u][1], val = in[u][2];
      out[u] = (s >= min_s && s * val >= min_sv) ? d.hue_class[in[u][0]] : 0;
    }
  }
  return labels;
}

Eigen::Isometry3d Detection::pose() const {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = position;
  p.linear() = Eigen::AngleAxisd(yaw.value_or(0.0), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

const Detection* DetectionResult::find(std::string_view workpiece) const {
  for (const Detection& d : detections) {
    if (d.workpiece == workpiece) return &d;
  }
  return nullptr;
}

namespace {

// A blob of one colour class with its best fit for each shape of the class.
struct Blob {
  std::size_t colour = 0;
  int pixels = 0;
  cv::Rect box;
  cv::Point2d centroid;
  std::vector<cv::Point> contour;
  cv::Mat own;            // 8 bits, the size of box: non-zero on the blob's pixels
  std::vector<Fit> fits;  // indexed like Impl::shapes; cost kInf when not tried
  bool edge = false;      // its fitting window reaches out of the image
  bool taken = false;
};

// Fits one shape to a blob on every support under it.
Fit fit_blob(const Impl& d, const Blob& blob, const cv::Mat& labels, std::size_t shape_index, bool& edge) {
  const ShapeModel& shape = d.shapes[shape_index];
  Fit best;
  for (std::size_t si = 0; si < d.supports.size(); ++si) {
    const Support& sup = d.supports[si];
    const double z = sup.height + shape.size.z() / 2;
    const auto top = d.camera.on_plane(blob.centroid, sup.height + shape.size.z());
    if (!top) continue;
    const double margin = 0.5 * shape.size.head<2>().norm() + 0.01;
    if (!d.on_support(sup, top->x(), top->y(), margin)) continue;
    // A part there would be hidden by another support (the conveyor or machine the blob is on, seen from above):
    // the blob is not that part.
    if (d.hidden_by_support(*top)) continue;

    // The fitting window: the blob's box grown by the part's size in pixels, so that the whole silhouette is in it.
    const double px_per_m = d.camera.focal() / std::max(1e-3, d.camera.depth(Eigen::Vector3d(top->x(), top->y(), z)));
    const int grow = static_cast<int>(std::ceil(0.5 * shape.size.norm() * px_per_m)) + 2;
    const cv::Rect window(blob.box.x - grow, blob.box.y - grow, blob.box.width + 2 * grow, blob.box.height + 2 * grow);
    std::vector<Sample> samples;
    samples.reserve(static_cast<std::size_t>(window.area()));
    for (int v = window.y; v < window.y + window.height; ++v) {
      for (int u = window.x; u < window.x + window.width; ++u) {
        float target = 0;
        if (u >= 0 && v >= 0 && u < labels.cols && v < labels.rows) {
          if (blob.box.contains(cv::Point(u, v)) && blob.own.at<unsigned char>(v - blob.box.y, u - blob.box.x) != 0) {
            target = 1;
          } else if (labels.at<unsigned char>(v, u) != 0 || d.static_occluders.at<unsigned char>(v, u) != 0) {
            continue;  // another part or a stop bar: it may hide this part, so it says nothing
          }
        } else {
          edge = true;  // outside the image: counted as not the part, so a part cut by the edge fits badly
        }
        samples.push_back({static_cast<float>(u), static_cast<float>(v), target});
      }
    }

    // Start at the blob's centroid on the plane of the part's top; try yaws over the symmetry period.
    std::vector<Pose2> starts;
    if (shape.period > 0) {
      constexpr int kSeeds = 8;
      for (int k = 0; k < kSeeds; ++k) starts.push_back({top->x(), top->y(), shape.period * k / kSeeds});
    } else {
      starts.push_back({top->x(), top->y(), 0});
    }
    Pose2 centre = starts.front();
    const double max_move = (kBand - kEdge - 0.4) / px_per_m;
    refine(d, shape, centre, z, samples, false, 6, max_move);
    std::vector<std::pair<double, Pose2>> seeded;
    Eigen::VectorXd r;
    for (Pose2 p : starts) {
      p.x = centre.x;
      p.y = centre.y;
      seeded.emplace_back(residuals(d, shape, p, z, samples, r) ? r.squaredNorm() : kInf, p);
    }
    std::sort(seeded.begin(), seeded.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (std::size_t k = 0; k < std::min<std::size_t>(2, seeded.size()); ++k) {
      // The runner-up only when it is a different yaw that fits almost as well.
      if (k == 1 && (std::abs(hue_diff(seeded[1].second.yaw / kDeg, seeded[0].second.yaw / kDeg)) < 10 ||
                     seeded[1].first > 1.5 * seeded[0].first)) {
        break;
      }
      Pose2 p = seeded[k].second;
      double c = refine(d, shape, p, z, samples, shape.period > 0, 25, max_move);
      if (!std::isfinite(c)) continue;
      if (shape.period > 0) {
        // Nearly axis-aligned edges make steps in the pixel grid that trap the fit a few degrees off: look around.
        Pose2 scan = p;
        double scan_cost = c;
        for (int step = -kScanSteps; step <= kScanSteps; ++step) {
          Pose2 q = p;
          q.yaw += step * kScanStep;
          if (step != 0 && residuals(d, shape, q, z, samples, r) && r.squaredNorm() < scan_cost) {
            scan = q;
            scan_cost = r.squaredNorm();
          }
        }
        if (scan_cost < c) {
          const double c2 = refine(d, shape, scan, z, samples, true, 25, max_move);
          if (c2 < c) {
            p = scan;
            c = c2;
          }
        }
      }
      // Where the fit put it, it must rest on the support in view: not inside another support, not behind one.
      if (d.inside_support(Eigen::Vector3d(p.x, p.y, sup.height + 1e-3)) ||
          d.hidden_by_support(Eigen::Vector3d(p.x, p.y, z + shape.size.z() / 2))) {
        continue;
      }
      const std::vector<cv::Point2d> outline = d.silhouette(shape, p, z);
      const double score = iou(outline, samples);
      if (best.support != si || !std::isfinite(best.cost) ? score > best.iou : c < best.cost) {
        best.pose = p;
        best.cost = c;
        best.iou = score;
        best.support = si;
        best.shape = shape_index;
        best.outline = outline;
      }
    }
  }
  return best;
}

}  // namespace

DetectionResult detect(const Detector& detector, const cv::Mat& bgr, const std::vector<Prediction>& predictions) {
  const Impl& d = *detector.impl_;
  DetectionResult result;
  auto all_not_seen = [&] {
    for (const models::WorkpieceSpec& w : d.workpieces) result.not_seen.push_back(w.name);
  };
  if (bgr.empty() || bgr.type() != CV_8UC3) {
    result.frame_problem = "the image is empty or not 8-bit BGR";
    all_not_seen();
    return result;
  }
  if (bgr.cols != d.camera.width() || bgr.rows != d.camera.height()) {
    result.frame_problem =
        fmt::format("the image is {}x{}, the camera's {}x{}", bgr.cols, bgr.rows, d.camera.width(), d.camera.height());
    all_not_seen();
    return result;
  }

  const cv::Mat labels = detector.classify(bgr);
  // Blobs: connected pixels of one colour class. Parts are small and few: find the connected regions of any class
  // once over the image, then split each region by class.
  std::vector<Blob> blobs;
  cv::Mat region, stats, centroids;
  const int regions = cv::connectedComponentsWithStats(labels, region, stats, centroids, 8, CV_32S);
  for (int k = 1; k < regions; ++k) {
    if (stats.at<int>(k, cv::CC_STAT_AREA) < d.options.min_pixels) continue;
    const cv::Rect box(stats.at<int>(k, cv::CC_STAT_LEFT), stats.at<int>(k, cv::CC_STAT_TOP),
                       stats.at<int>(k, cv::CC_STAT_WIDTH), stats.at<int>(k, cv::CC_STAT_HEIGHT));
    const cv::Mat in_region = region(box) == k;
    for (std::size_t c = 0; c < d.class_members.size(); ++c) {
      cv::Mat mask = (labels(box) == static_cast<int>(c + 1)) & in_region;
      if (cv::countNonZero(mask) < d.options.min_pixels) continue;
      cv::Mat part, part_stats, part_centroids;
      const int count = cv::connectedComponentsWithStats(mask, part, part_stats, part_centroids, 8, CV_32S);
      for (int j = 1; j < count; ++j) {
        const int area = part_stats.at<int>(j, cv::CC_STAT_AREA);
        if (area < d.options.min_pixels) continue;
        Blob b;
        b.colour = c;
        b.pixels = area;
        const cv::Rect local(part_stats.at<int>(j, cv::CC_STAT_LEFT), part_stats.at<int>(j, cv::CC_STAT_TOP),
                             part_stats.at<int>(j, cv::CC_STAT_WIDTH), part_stats.at<int>(j, cv::CC_STAT_HEIGHT));
        b.box = local + box.tl();
        b.centroid = cv::Point2d(part_centroids.at<double>(j, 0) + box.x, part_centroids.at<double>(j, 1) + box.y);
        b.own = part(local) == j;
        std::vector<std::vector<cv::Point>> contours;
        cv::findContours(b.own.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE, b.box.tl());
        if (!contours.empty()) {
          b.contour = *std::max_element(contours.begin(), contours.end(),
                                        [](const auto& x, const auto& y) { return x.size() < y.size(); });
        }
        b.fits.assign(d.shapes.size(), Fit{});
        std::vector<bool> tried(d.shapes.size(), false);
        for (std::size_t w : d.class_members[c]) {
          const std::size_t si = d.shape_of[w];
          if (!tried[si]) b.fits[si] = fit_blob(d, b, labels, si, b.edge);
          tried[si] = true;
        }
        blobs.push_back(std::move(b));
      }
    }
  }

  auto confident = [&](const Blob& b, std::size_t shape) { return b.fits[shape].iou >= d.options.min_confidence; };
  auto prediction_of = [&](const std::string& name) -> const Prediction* {
    for (const Prediction& p : predictions) {
      if (p.workpiece == name) return &p;
    }
    return nullptr;
  };
  auto position_of = [&](const Fit& f) {
    const ShapeModel& s = d.shapes[f.shape];
    return Eigen::Vector3d(f.pose.x, f.pose.y, d.supports[f.support].height + s.size.z() / 2);
  };

  std::vector<std::optional<Detection>> found(d.workpieces.size());
  auto make_detection = [&](std::size_t w, Blob& b, bool ambiguous) {
    const std::size_t si = d.shape_of[w];
    const Fit& f = b.fits[si];
    const ShapeModel& s = d.shapes[si];
    Detection det;
    det.workpiece = d.workpieces[w].name;
    det.shape = s.shape;
    det.position = position_of(f);
    if (s.period > 0) det.yaw = wrap_yaw(f.pose.yaw, s.period);
    det.yaw_period = s.period;
    det.support = d.supports[f.support].name;
    det.confidence = f.iou;
    det.ambiguous = ambiguous;
    det.pixels = b.pixels;
    det.centroid = b.centroid;
    det.contour = b.contour;
    det.outline = f.outline;
    const Eigen::Vector3d top = det.position + Eigen::Vector3d(0, 0, s.size.z() / 2);
    const Eigen::Matrix3d r = Eigen::AngleAxisd(f.pose.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    constexpr double kAxis = 0.03;
    det.top_centre = d.camera.project(top).value_or(b.centroid);
    det.axis_x = d.camera.project(top + r * Eigen::Vector3d(kAxis, 0, 0)).value_or(det.top_centre);
    det.axis_y = d.camera.project(top + r * Eigen::Vector3d(0, kAxis, 0)).value_or(det.top_centre);
    b.taken = true;
    found[w] = std::move(det);
  };

  for (std::size_t c = 0; c < d.class_members.size(); ++c) {
    const std::vector<std::size_t>& members = d.class_members[c];
    std::vector<Blob*> mine;
    for (Blob& b : blobs) {
      if (b.colour == c) mine.push_back(&b);
    }
    // Pairs (distance to the prediction, blob, workpiece) of confident fits, nearest first; workpieces without a
    // prediction come after, best fits first.
    struct Pair {
      bool predicted;
      double key;
      Blob* blob;
      std::size_t workpiece;
    };
    std::vector<Pair> pairs;
    for (std::size_t w : members) {
      const Prediction* p = prediction_of(d.workpieces[w].name);
      for (Blob* b : mine) {
        const std::size_t si = d.shape_of[w];
        if (!confident(*b, si)) continue;
        if (p != nullptr) {
          pairs.push_back({true, (position_of(b->fits[si]) - p->position).norm(), b, w});
        } else {
          pairs.push_back({false, -b->fits[si].iou, b, w});
        }
      }
    }
    std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
      if (a.predicted != b.predicted) return a.predicted;
      return a.key < b.key;
    });
    const bool several = members.size() > 1;
    for (const Pair& p : pairs) {
      if (p.blob->taken || found[p.workpiece]) continue;
      make_detection(p.workpiece, *p.blob, several && !p.predicted);
    }
    for (Blob* b : mine) {
      if (b->taken) continue;
      // The best candidate, for the report.
      std::size_t best_w = members.front();
      for (std::size_t w : members) {
        if (b->fits[d.shape_of[w]].iou > b->fits[d.shape_of[best_w]].iou) best_w = w;
      }
      const Fit& f = b->fits[d.shape_of[best_w]];
      Rejection r;
      r.workpiece = d.workpieces[best_w].name;
      r.box = b->box;
      r.pixels = b->pixels;
      r.confidence = std::isfinite(f.cost) ? f.iou : 0;
      if (!std::isfinite(f.cost)) {
        r.reason = "not over any support the cell describes";
      } else if (f.iou < d.options.min_confidence) {
        r.reason = fmt::format("its outline does not fit a {} resting on {}: confidence {} < {} ({})",
                               d.workpieces[best_w].shape == models::Shape::kBox ? "box" : "cylinder",
                               d.supports[f.support].name, two_places(f.iou), two_places(d.options.min_confidence),
                               b->edge ? "cut by the image's edge" : "partly hidden, merged with another, or lifted");
      } else {
        r.reason = fmt::format("another blob of this colour was matched to {}",
                               members.size() == 1 ? d.workpieces[members.front()].name : "each of its workpieces");
      }
      result.rejected.push_back(std::move(r));
    }
  }
  for (std::size_t w = 0; w < d.workpieces.size(); ++w) {
    if (found[w]) {
      result.detections.push_back(std::move(*found[w]));
    } else {
      result.not_seen.push_back(d.workpieces[w].name);
    }
  }
  return result;
}

std::string describe(const Detection& d) {
  const std::string yaw = d.yaw ? fmt::format("yaw {:.1f} deg", *d.yaw / kDeg) : std::string("no yaw (cylinder)");
  return fmt::format("{} at ({:.4f}, {:.4f}, {:.4f}) m, {}, on {}, confidence {:.2f}{}", d.workpiece, d.position.x(),
                     d.position.y(), d.position.z(), yaw, d.support, d.confidence,
                     d.ambiguous ? " (identity ambiguous: same colour)" : "");
}

}  // namespace cellwright::vision
