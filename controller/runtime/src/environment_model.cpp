#include "cellwright/runtime/environment_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

namespace cellwright::runtime {

namespace {

template <typename Vec>
auto find_named(Vec& v, std::string_view name) -> decltype(&v.front()) {
  for (auto& x : v) {
    if (x.name == name) return &x;
  }
  return nullptr;
}

// Yaw of a rotation about the world z axis (of its x axis projected on the floor).
double yaw_of(const Eigen::Matrix3d& r) {
  return std::atan2(r(1, 0), r(0, 0));
}

std::string xyz(const Eigen::Vector3d& p) {
  return fmt::format("({:.3f}, {:.3f}, {:.3f})", p.x(), p.y(), p.z());
}

// A grasp and the same grasp with the fingers turned half a turn about the approach axis (a parallel gripper is
// symmetric under it).
std::vector<Eigen::Isometry3d> both_ways(const Eigen::Vector3d& point, models::Approach approach, double yaw,
                                         const Eigen::Isometry3d& base) {
  const Eigen::Isometry3d first = models::grasp_pose(point, approach, yaw, base);
  Eigen::Isometry3d turned = first;
  turned.linear() = first.linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
  return {first, turned};
}

// A part held from the side can be put down with the tool axis in any horizontal direction: the direction from the
// robot's base first, then ever further turned away from it (30 degree steps), ranked by how far they turn.
void side_poses(const Eigen::Vector3d& point, const Eigen::Isometry3d& base, std::vector<Eigen::Isometry3d>& poses,
                std::vector<int>& rank) {
  const Eigen::Isometry3d straight = models::grasp_pose(point, models::Approach::kSide, 0.0, base);
  const Eigen::Vector3d d = straight.linear().col(2);
  const double a0 = std::atan2(d.y(), d.x());
  for (int k = 0; k < 12; ++k) {
    const double a = a0 + k * std::numbers::pi / 6;
    const Eigen::Vector3d z(std::cos(a), std::sin(a), 0);
    const Eigen::Vector3d y(-z.y(), z.x(), 0);
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear().col(0) = y.cross(z);
    p.linear().col(1) = y;
    p.linear().col(2) = z;
    p.translation() = point;
    Eigen::Isometry3d turned = p;
    turned.linear() = p.linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
    for (const auto& q : {p, turned}) {
      poses.push_back(q);
      rank.push_back(std::min(k, 12 - k));
    }
  }
}

MotionTarget fail(std::string reason) {
  MotionTarget t;
  t.resolution = MotionTarget::Resolution::kFail;
  t.reason = std::move(reason);
  return t;
}

MotionTarget wait(std::string reason) {
  MotionTarget t;
  t.resolution = MotionTarget::Resolution::kWait;
  t.reason = std::move(reason);
  return t;
}

MotionTarget ok(std::vector<Eigen::Isometry3d> poses, std::string what) {
  MotionTarget t;
  t.resolution = MotionTarget::Resolution::kOk;
  t.description = fmt::format("{}: tool at {}", what, xyz(poses.front().translation()));
  t.rank.assign(poses.size(), 0);
  t.poses = std::move(poses);
  return t;
}

const models::HandoverGrasp* grasp_of(const models::HandoverSpec& h, std::string_view robot) {
  for (const auto& g : h.grasps) {
    if (g.robot == robot) return &g;
  }
  return nullptr;
}

}  // namespace

const RobotState* EnvironmentModel::find_robot(std::string_view name) const {
  return find_named(robots, name);
}
RobotState* EnvironmentModel::find_robot(std::string_view name) {
  return find_named(robots, name);
}
const WorkpieceState* EnvironmentModel::find_workpiece(std::string_view name) const {
  return find_named(workpieces, name);
}
WorkpieceState* EnvironmentModel::find_workpiece(std::string_view name) {
  return find_named(workpieces, name);
}
const CellLocation* CellGeometry::find_location(std::string_view name) const {
  return find_named(locations, name);
}

EnvironmentModel make_environment_model(const models::CellDescription& cell) {
  auto g = std::make_shared<CellGeometry>();
  for (const models::RobotSpec& r : cell.robots) g->robots.push_back({r.name, r.base.transform(), r.home, r.park});
  for (const models::WorkpieceSpec& w : cell.workpieces) g->workpieces.push_back({w.name, w.shape, w.size});
  for (const models::LocationSpec& l : cell.locations) {
    g->locations.push_back({l.name, l.pose.transform(), l.grasp_height, l.approach_height});
  }
  for (const models::ConveyorSpec& c : cell.conveyors) {
    g->conveyors.push_back({c.name, c.pose.transform(), c.length, c.width, c.height, c.speed});
  }
  for (const models::MachineSpec& mc : cell.machines) {
    g->machines.push_back({mc.name, mc.pose.transform(), mc.fixture_top().transform()});
  }
  g->handover = cell.handover;

  EnvironmentModel m;
  m.geometry = g;  // from here on only read: the state below points into it
  for (const CellRobot& r : g->robots) {
    RobotState s;
    s.name = r.name;
    s.fixed = &r;
    s.joints = r.home;
    m.robots.push_back(std::move(s));
  }
  for (std::size_t i = 0; i < g->workpieces.size(); ++i) {
    WorkpieceState s;
    s.name = g->workpieces[i].name;
    s.fixed = &g->workpieces[i];
    s.pose = cell.workpieces[i].pose.transform();
    m.workpieces.push_back(std::move(s));
  }
  return m;
}

const char* to_string(Perception perception) {
  switch (perception) {
    case Perception::kTruth:
      return "truth";
    case Perception::kVision:
      return "vision";
    case Perception::kCad:
      return "cad";
  }
  return "?";
}

SensorReadings read_sensors(Sensors& sensors, const std::vector<std::string>& robots, SimDuration time) {
  SensorReadings r;
  r.time = time;
  if (sensors.parts != nullptr) r.parts = sensors.parts->read_parts();
  if (sensors.safety != nullptr) r.obstacles = sensors.safety->read_obstacles();
  for (const std::string& name : robots) {
    SensorReadings::Robot robot;
    robot.name = name;
    if (auto g = sensors.grip.find(name); g != sensors.grip.end() && g->second != nullptr) {
      robot.grip = g->second->read_grip();
    }
    if (auto f = sensors.force.find(name); f != sensors.force.end() && f->second != nullptr) {
      robot.wrist_force = f->second->read_force();
    }
    r.robots.push_back(std::move(robot));
  }
  return r;
}

void apply_readings(EnvironmentModel& model, const SensorReadings& readings, Perception perception) {
  model.time = readings.time;
  model.obstacles.clear();
  for (const Obstacle& o : readings.obstacles) model.obstacles.push_back({o.name, o.centre, o.size});
  static const std::vector<PartReading> kNoParts;
  for (const PartReading& w : readings.parts ? *readings.parts : kNoParts) {
    if (perception == Perception::kVision) break;
    WorkpieceState* s = model.find_workpiece(w.name);
    if (s == nullptr) continue;
    s->present = w.present;
    s->velocity = w.velocity;
    s->motion_known = true;
    if (perception == Perception::kTruth) {
      s->pose = w.pose;
      s->confidence = 1.0;
      s->stamp = readings.time;
      continue;
    }
    // kCad: a resting part near a location stands at its nominal pose there; otherwise the model keeps its pose.
    if (!s->held_by.empty() || !w.present || w.velocity.norm() > kCadRestSpeed) continue;
    const Eigen::Vector3d bottom = w.pose.translation() - Eigen::Vector3d(0, 0, s->size().z() / 2);
    const CellLocation* at = nullptr;
    double nearest = kCadSensorRadius;
    for (const CellLocation& l : model.geometry->locations) {
      const double d = (bottom - l.pose.translation()).norm();
      if (d <= nearest) {
        nearest = d;
        at = &l;
      }
    }
    if (at == nullptr) continue;
    Eigen::Isometry3d nominal = at->pose;
    nominal.translation().z() += s->size().z() / 2;
    if (!s->pose.isApprox(nominal)) {
      s->pose = nominal;
      s->confidence = 1.0;
      s->stamp = readings.time;
    }
  }
  for (const SensorReadings::Robot& r : readings.robots) {
    RobotState* s = model.find_robot(r.name);
    if (s == nullptr) continue;
    s->grip = r.grip;
    s->wrist_force = r.wrist_force;
  }
}

bool correct(EnvironmentModel& model, std::string_view workpiece, const Eigen::Isometry3d& pose, double confidence,
             SimDuration age, const std::optional<Eigen::Vector3d>& velocity) {
  WorkpieceState* w = model.find_workpiece(workpiece);
  if (w == nullptr || !w->held_by.empty()) return false;
  if (!std::isfinite(confidence) || confidence < 0.0 || confidence > 1.0 || age.count() < 0) return false;
  if (!pose.matrix().allFinite() || (velocity && !velocity->allFinite())) return false;
  w->pose = pose;
  w->motion_known = velocity.has_value();
  w->velocity = velocity.value_or(Eigen::Vector3d::Zero());
  w->confidence = confidence;
  w->stamp = model.time - age;
  w->present = true;
  return true;
}

MotionTarget resolve_target(const EnvironmentModel& model, const std::string& robot, const task::Target& target,
                            const TargetOptions& options) {
  const RobotState* r = model.find_robot(robot);
  if (r == nullptr) return fail(fmt::format("robot '{}' is not in the cell", robot));
  const std::string what = task::to_string(target);

  switch (target.kind) {
    case task::TargetKind::kHome: {
      MotionTarget t;
      t.resolution = MotionTarget::Resolution::kOk;
      t.joints = r->home();
      t.description = "home";
      return t;
    }
    case task::TargetKind::kPark: {
      if (r->park().empty()) {
        return fail(fmt::format("robot '{}' has no park pose: give it one with 'park:' in the cell description "
                                "(docs/cell-description.md)",
                                robot));
      }
      MotionTarget t;
      t.resolution = MotionTarget::Resolution::kOk;
      t.joints = r->park();
      t.description = "park";
      return t;
    }
    case task::TargetKind::kAbove:
    case task::TargetKind::kAt: {
      const bool above = target.kind == task::TargetKind::kAbove;
      if (const WorkpieceState* w = model.find_workpiece(target.object)) {
        const bool mine = r->hold && r->hold->workpiece == w->name;
        if (!w->present) return wait(fmt::format("workpiece {} is not in the cell yet", w->name));
        if (!w->held_by.empty() && w->held_by != robot) {
          return wait(fmt::format("workpiece {} is held by {}", w->name, w->held_by));
        }
        const double speed = w->velocity.norm();
        if (!mine && !w->motion_known) {
          return wait(fmt::format("workpiece {} has been seen once: whether it moves is not known yet", w->name));
        }
        if (!mine && speed > options.part_at_rest_speed) {
          return wait(fmt::format("workpiece {} is still moving ({:.4f} m/s)", w->name, speed));
        }
        const Eigen::Vector3d bottom = w->pose.translation() - Eigen::Vector3d(0, 0, w->size().z() / 2);
        CellLocation heights;  // the models::LocationSpec defaults, unless the part rests at a location
        double yaw = yaw_of(w->pose.linear());
        const CellLocation* near = nullptr;
        double nearest = options.at_location_tolerance;
        for (const CellLocation& l : model.geometry->locations) {
          const double d = (bottom - l.pose.translation()).norm();
          if (d <= nearest) {
            nearest = d;
            near = &l;
          }
        }
        if (near != nullptr) {
          heights = *near;
          // The cell says how fingers close there (e.g. clear of a stop bar): of the directions that close on the
          // part's faces, the one nearest the location's.
          const double want = yaw_of(near->pose.linear());
          if (w->shape() == models::Shape::kCylinder) {
            yaw = want;
          } else {
            // Any of the four: an aligned part is taken exactly as the location says, whatever its footprint.
            const double quarter = std::numbers::pi / 2;
            yaw += quarter * std::round((want - yaw) / quarter);
          }
        }
        double grasp = mine ? r->hold->tcp_above_bottom : heights.grasp_height;
        if (!mine && stands_upright(*w) && r->dropped_hold && r->dropped_hold->workpiece == w->name &&
            r->dropped_hold->approach == models::Approach::kDown && r->dropped_hold->tcp_above_bottom > 0 &&
            r->dropped_hold->tcp_above_bottom <= w->size().z()) {
          grasp = r->dropped_hold->tcp_above_bottom;  // taken again from above as it was held
        }
        const Eigen::Vector3d point = bottom + Eigen::Vector3d(0, 0, grasp + (above ? heights.approach_height : 0.0));
        const models::Approach approach = mine ? r->hold->approach : models::Approach::kDown;
        return ok(both_ways(point, approach, yaw, r->base()), what);
      }
      if (const CellLocation* l = model.find_location(target.object)) {
        // Only while the hand is still where it let go (the depart right after the put-down).
        const bool just_released =
            r->released_tcp && r->tcp && (r->tcp->translation() - r->released_tcp->translation()).norm() < 0.02;
        if (above && !r->hold && just_released) {
          const Eigen::Vector3d d = r->released_tcp->translation() - l->pose.translation();
          if (std::hypot(d.x(), d.y()) <= options.at_location_tolerance) {
            Eigen::Isometry3d lifted = *r->released_tcp;
            lifted.translation().z() += l->approach_height;
            return ok({lifted}, what);
          }
        }
        const double grasp = r->hold ? r->hold->tcp_above_bottom : l->grasp_height;
        const Eigen::Vector3d point =
            l->pose.translation() + Eigen::Vector3d(0, 0, grasp + (above ? l->approach_height : 0.0));
        const models::Approach approach = r->hold ? r->hold->approach : models::Approach::kDown;
        if (approach == models::Approach::kSide) {
          std::vector<Eigen::Isometry3d> poses;
          std::vector<int> rank;
          side_poses(point, r->base(), poses, rank);
          MotionTarget t = ok(std::move(poses), what);
          t.rank = std::move(rank);
          return t;
        }
        return ok(both_ways(point, approach, yaw_of(l->pose.linear()), r->base()), what);
      }
      return fail(fmt::format("{}: '{}' is neither a workpiece nor a location of the cell", what, target.object));
    }
    case task::TargetKind::kHandover:
    case task::TargetKind::kHandApproach:
    case task::TargetKind::kHandGrasp: {
      if (!model.geometry->handover) return fail(fmt::format("{}: the cell has no hand-over", what));
      const models::HandoverSpec& h = *model.geometry->handover;
      const models::HandoverGrasp* g = grasp_of(h, robot);
      if (g == nullptr) return fail(fmt::format("{}: robot {} has no grasp at hand-over '{}'", what, robot, h.name));
      const double yaw = h.pose.rpy.z();
      Eigen::Vector3d centre = h.pose.xyz;
      if (target.kind == task::TargetKind::kHandGrasp) {
        // Grasp the part where the giver actually presents it.
        const RobotState* giver = model.find_robot(target.object);
        if (giver == nullptr) return fail(fmt::format("{}: robot '{}' is not in the cell", what, target.object));
        if (giver->hold) {
          if (const WorkpieceState* w = model.find_workpiece(giver->hold->workpiece)) centre = w->pose.translation();
        }
      }
      const std::vector<Eigen::Isometry3d> at = both_ways(centre + g->offset, g->approach, yaw, r->base());
      if (target.kind != task::TargetKind::kHandApproach) return ok(at, what);
      // Back off along the approach axis; failing that, from below; failing that, half as far.
      const double c = options.handover_clearance;
      std::vector<Eigen::Isometry3d> poses;
      std::vector<int> rank;
      const std::vector<std::pair<int, std::function<Eigen::Vector3d(const Eigen::Isometry3d&)>>> moves = {
          {0, [c](const Eigen::Isometry3d& p) { return Eigen::Vector3d(-p.linear().col(2) * c); }},
          {1, [c](const Eigen::Isometry3d&) { return Eigen::Vector3d(0, 0, -c); }},
          {2, [c](const Eigen::Isometry3d& p) { return Eigen::Vector3d(-p.linear().col(2) * c / 2); }},
      };
      for (const auto& [rk, move] : moves) {
        for (Eigen::Isometry3d p : at) {
          p.translation() += move(p);
          poses.push_back(p);
          rank.push_back(rk);
        }
      }
      MotionTarget t = ok(std::move(poses), what);
      t.rank = std::move(rank);
      return t;
    }
  }
  return fail(fmt::format("{}: unknown target kind", what));
}

}  // namespace cellwright::runtime
