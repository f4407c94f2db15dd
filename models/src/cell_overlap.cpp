// Bodies of the cell that overlap at the start (cell.hpp, check_overlaps): a separating-axis test on oriented boxes,
// exact for upright cylinders against upright boxes and cylinders (a circle against a rectangle in the plane, an
// interval along z); a cylinder that is turned over is taken as its bounding box, which can only overstate its
// extent.
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "cellwright/models/cell.hpp"

namespace cellwright::models {

namespace {

struct Body {
  std::string text;                                      // "workpiece 'A'"
  std::string owner;                                     // the cell object: parts of one object are not a pair
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();      // world
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();    // columns: the body's x, y, z in the world
  Eigen::Vector3d half = Eigen::Vector3d::Zero();        // half extents (a cylinder: radius, radius, half height)
  bool cylinder = false;
  SourceLocation where;

  bool upright() const { return std::abs(axes(2, 2)) > 1 - 1e-9; }
};

Body box(std::string text, std::string owner, const Pose& pose, const Eigen::Vector3d& local_centre,
         const Eigen::Vector3d& size, const SourceLocation& where) {
  Body b;
  b.text = std::move(text);
  b.owner = std::move(owner);
  b.axes = pose.rotation();
  b.centre = pose.transform() * local_centre;
  b.half = size / 2;
  b.where = where;
  return b;
}

// How deep two oriented boxes overlap: the smallest overlap of their projections over the 15 separating axes
// (negative: apart).
double box_box(const Body& a, const Body& b) {
  std::vector<Eigen::Vector3d> axes;
  for (int i = 0; i < 3; ++i) axes.push_back(a.axes.col(i));
  for (int i = 0; i < 3; ++i) axes.push_back(b.axes.col(i));
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d c = a.axes.col(i).cross(b.axes.col(j));
      if (c.norm() > 1e-9) axes.push_back(c.normalized());  // parallel edges: the face axes already cover them
    }
  }
  const Eigen::Vector3d d = b.centre - a.centre;
  double depth = INFINITY;
  for (const Eigen::Vector3d& l : axes) {
    double ra = 0, rb = 0;
    for (int i = 0; i < 3; ++i) {
      ra += a.half[i] * std::abs(a.axes.col(i).dot(l));
      rb += b.half[i] * std::abs(b.axes.col(i).dot(l));
    }
    depth = std::min(depth, ra + rb - std::abs(d.dot(l)));
  }
  return depth;
}

// An upright cylinder `c` against an upright box or cylinder `o`: the overlap along z and in the plane.
double upright(const Body& c, const Body& o) {
  const double z = std::min(c.centre.z() + c.half.z(), o.centre.z() + o.half.z()) -
                   std::max(c.centre.z() - c.half.z(), o.centre.z() - o.half.z());
  const Eigen::Vector2d d = (c.centre - o.centre).head<2>();
  double plane = 0;
  if (o.cylinder) {
    plane = c.half.x() + o.half.x() - d.norm();
  } else {
    // The circle's centre in the box's frame, against the rectangle.
    const Eigen::Vector2d p(d.dot(o.axes.col(0).head<2>()), d.dot(o.axes.col(1).head<2>()));
    const Eigen::Vector2d h = o.half.head<2>();
    const Eigen::Vector2d outside = (p.cwiseAbs() - h).cwiseMax(0.0);
    if (outside.norm() > 0) {
      plane = c.half.x() - outside.norm();
    } else {
      plane = c.half.x() + std::min(h.x() - std::abs(p.x()), h.y() - std::abs(p.y()));
    }
  }
  return std::min(z, plane);
}

double depth(const Body& a, const Body& b) {
  if ((a.cylinder || b.cylinder) && a.upright() && b.upright()) return a.cylinder ? upright(a, b) : upright(b, a);
  return box_box(a, b);  // a turned cylinder: its bounding box
}

}  // namespace

std::vector<Overlap> check_overlaps(const CellDescription& cell) {
  std::vector<Body> bodies;
  for (const RobotSpec& r : cell.robots) {
    if (r.base.xyz.z() <= 1e-3) continue;  // only a pedestal is known of a robot's base without its URDF geometry
    Pose p;
    p.xyz = Eigen::Vector3d(r.base.xyz.x(), r.base.xyz.y(), 0);
    p.rpy = Eigen::Vector3d(0, 0, r.base.rpy.z());
    bodies.push_back(box(fmt::format("the pedestal of robot '{}'", r.name), r.name, p,
                         Eigen::Vector3d(0, 0, r.base.xyz.z() / 2),
                         Eigen::Vector3d(kPedestalSide, kPedestalSide, r.base.xyz.z()), r.where));
  }
  for (const ConveyorSpec& c : cell.conveyors) {
    bodies.push_back(box(fmt::format("conveyor '{}'", c.name), c.name, c.pose, Eigen::Vector3d(0, 0, c.height / 2),
                         Eigen::Vector3d(c.length, c.width, c.height), c.where));
  }
  for (const MachineSpec& m : cell.machines) {
    bodies.push_back(box(fmt::format("machine '{}'", m.name), m.name, m.pose, Eigen::Vector3d(0, 0, m.size.z() / 2),
                         m.size, m.where));
    bodies.push_back(box(fmt::format("the fixture of machine '{}'", m.name), m.name, m.pose,
                         Eigen::Vector3d(0, 0, m.size.z() + m.fixture_size.z() / 2), m.fixture_size, m.where));
  }
  for (const WorkpieceSpec& w : cell.workpieces) {
    Body b = box(fmt::format("workpiece '{}'", w.name), w.name, w.pose, Eigen::Vector3d::Zero(), w.size, w.where);
    b.cylinder = w.shape == Shape::kCylinder;
    bodies.push_back(std::move(b));
  }

  std::vector<Overlap> out;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    for (std::size_t j = i + 1; j < bodies.size(); ++j) {
      const Body& a = bodies[i];
      const Body& b = bodies[j];
      if (a.owner == b.owner) continue;
      const double d = depth(a, b);
      if (d <= bounds::kOverlap) continue;
      // The one listed later is the one placed into the other.
      const bool b_later = b.where.line >= a.where.line;
      const Body& placed = b_later ? b : a;
      const Body& other = b_later ? a : b;
      out.push_back({placed.text, fmt::format("{} (line {})", other.text, other.where.line), d, placed.where});
    }
  }
  return out;
}

}  // namespace cellwright::models
