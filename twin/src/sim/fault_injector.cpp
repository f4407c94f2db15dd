// The physical faults in the World, and the detection noise (fault_injector.hpp).
#include "cellwright/twin/sim/fault_injector.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/twin/sim/world_plant.hpp"

namespace cellwright::twin::sim {

namespace {

using namespace std::chrono_literals;

constexpr std::chrono::nanoseconds kCarryEnd = 100ms;  // pads apart this long: the carry is over
constexpr int kSlipPeriods = 5;                        // a slip takes this many updates
constexpr double kSlipClearance = 0.005;               // m of room left under a slipping part
constexpr double kAirborne = 0.005;                    // m above whatever is below: a held part is in the air
constexpr double kReachMargin = 0.05;                  // m beyond every robot's reach (unreachable)
constexpr double kJitter = 0.01;                       // m: an obstacle's jitter across the tool's motion

double seconds(std::chrono::nanoseconds t) {
  return std::chrono::duration<double>(t).count();
}

double unit(std::mt19937_64& rng) {  // [0, 1), from the engine's raw output (std distributions differ by library)
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

double yaw_of(const Eigen::Matrix3d& r) {
  return std::atan2(r(1, 0), r(0, 0));
}

}  // namespace

SceneOptions FaultInjector::scene_options(const std::vector<FaultSpec>& faults) {
  SceneOptions o;
  for (const FaultSpec& f : faults) {
    if (f.kind == FaultKind::obstacle) o.obstacles.push_back(f.size);
  }
  return o;
}

FaultInjector::FaultInjector(World& world, std::vector<FaultSpec> faults, std::uint64_t seed) : world_(world) {
  std::mt19937_64 rng(seed);
  std::size_t obstacles = 0;
  for (FaultSpec& f : faults) {
    Active a;
    a.spec = std::move(f);
    switch (a.spec.kind) {
      case FaultKind::misplace: {
        const double sx = unit(rng) < 0.5 ? -1 : 1, sy = unit(rng) < 0.5 ? -1 : 1, sr = unit(rng) < 0.5 ? -1 : 1;
        a.offset.translation() = Eigen::Vector3d(sx * a.spec.offset[0], sy * a.spec.offset[1], 0);
        a.offset.linear() =
            Eigen::AngleAxisd(sr * a.spec.yaw * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        break;
      }
      case FaultKind::obstacle:
        a.jitter[0] = 2 * unit(rng) - 1;
        a.jitter[1] = 2 * unit(rng) - 1;
        a.obstacle = obstacles++;
        CW_CHECK(a.obstacle < world_.scene().obstacles().size(),
                 "obstacle fault {} needs obstacle body {}, and the scene has {} (FaultInjector::scene_options)",
                 to_text(a.spec), a.obstacle + 1, world_.scene().obstacles().size());
        needs_truth_ = true;
        break;
      case FaultKind::drop:
      case FaultKind::slip:
        needs_truth_ = true;
        break;
      case FaultKind::unreachable:
      case FaultKind::missing:
      case FaultKind::frame_lost:
      case FaultKind::detection_noise:
        break;
      default:
        continue;  // injected elsewhere
    }
    faults_.push_back(std::move(a));
  }
  carries_.resize(world_.scene().robots().size());
  tcp_.resize(world_.scene().robots().size());
}

std::size_t FaultInjector::robot_index(const std::string& name) const {
  const RobotIds* ids = world_.scene().find_robot(name);
  CW_CHECK(ids != nullptr, "no robot '{}' in the scene", name);
  return static_cast<std::size_t>(ids - world_.scene().robots().data());
}

void FaultInjector::report(const FaultSpec& f, std::string detail) {
  out_.push_back({std::string(to_string(f.kind)), f.robot, f.workpiece, std::move(detail)});
}

Eigen::Isometry3d FaultInjector::out_of_reach(const std::string& workpiece, const Eigen::Isometry3d& from,
                                              const models::ConveyorSpec* conveyor, double distance, double* margin,
                                              double* moved) const {
  const models::CellDescription& cell = world_.scene().cell();
  const models::WorkpieceSpec& spec = *cell.find_workpiece(workpiece);
  Eigen::Vector3d robots = Eigen::Vector3d::Zero();
  for (const models::RobotSpec& r : cell.robots) robots += r.base.xyz / static_cast<double>(cell.robots.size());
  robots.z() = 0;
  Eigen::Vector3d p = from.translation();
  p.z() = 0;
  Eigen::Vector3d dir;
  if (conveyor != nullptr) {
    dir = conveyor->pose.rotation().col(1);  // across the belt
    dir.z() = 0;
    if ((p + dir - robots).norm() < (p - dir - robots).norm()) dir = -dir;
  } else {
    dir = p - robots;
    if (dir.norm() < 1e-6) dir = Eigen::Vector3d::UnitX();
  }
  dir.normalize();
  // Joint 1 and the reach of every robot.
  std::vector<std::pair<Eigen::Vector3d, double>> reach;
  for (const models::RobotSpec& r : cell.robots) {
    const models::KinematicChain chain = models::robot_chain(r);
    reach.emplace_back(r.base.transform() * chain.first_joint_origin(), chain.max_reach());
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw_of(from.linear()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (double d = distance;; d += 0.1) {
    pose.translation() = p + d * dir + Eigen::Vector3d(0, 0, spec.size.z() / 2);
    double least = std::numeric_limits<double>::infinity();
    for (const auto& [joint1, max_reach] : reach) {
      // The grasp point: the part's top is the nearest a gripper could take it.
      const Eigen::Vector3d grasp = pose.translation() + Eigen::Vector3d(0, 0, spec.size.z() / 2);
      least = std::min(least, (grasp - joint1).norm() - max_reach);
    }
    if (least > kReachMargin || d > distance + 5) {
      *margin = least;
      *moved = d;
      return pose;
    }
  }
}

void FaultInjector::prepare(std::vector<FeedEvent>& feed) {
  const models::CellDescription& cell = world_.scene().cell();
  const WorldTruth truth = world_.truth();
  const auto fed = [&](const std::string& w) {
    return std::find_if(feed.begin(), feed.end(), [&](const FeedEvent& e) { return e.workpiece == w; });
  };
  for (Active& a : faults_) {
    const FaultSpec& f = a.spec;
    if (f.kind != FaultKind::misplace && f.kind != FaultKind::unreachable && f.kind != FaultKind::missing) continue;
    const auto event = fed(f.workpiece);
    const models::WorkpieceSpec& spec = *cell.find_workpiece(f.workpiece);
    if (event != feed.end()) {
      // A part fed later: its feed event changes; the fault is reported when it arrives (or was due).
      const models::ConveyorSpec& c = *cell.find_conveyor(event->conveyor);
      if (f.kind == FaultKind::misplace) {
        event->offset = event->offset * a.offset;
      } else if (f.kind == FaultKind::unreachable) {
        Eigen::Isometry3d entry = Eigen::Isometry3d::Identity();
        entry.linear() = c.pose.rotation();
        entry.translation() = c.belt_point(c.enter) + Eigen::Vector3d(0, 0, spec.size.z() / 2);
        double margin = 0, moved = 0;
        const Eigen::Isometry3d target = out_of_reach(f.workpiece, entry * event->offset, &c, f.distance, &margin,
                                                      &moved);
        event->offset = entry.inverse() * target;
        a.offset = target;
        a.margin = margin;
        a.moved = moved;
      } else {
        a.due = event->time;
        feed.erase(event);
      }
      continue;
    }
    // A part in the cell at the start: moved now, reported at the first update.
    std::size_t w = 0;
    while (truth.workpieces[w].name != f.workpiece) ++w;
    const Eigen::Isometry3d now = truth.workpieces[w].pose;
    if (f.kind == FaultKind::missing) {
      world_.park(f.workpiece);
      report(f, fmt::format("workpiece '{}' taken out of the cell at the start", f.workpiece));
    } else if (f.kind == FaultKind::misplace) {
      // Not into a neighbour: the other side along the part's x when the drawn one would overlap.
      const double radius = 0.5 * std::hypot(spec.size.x(), spec.size.y());
      const auto overlaps = [&](const Eigen::Isometry3d& pose) {
        for (std::size_t o = 0; o < truth.workpieces.size(); ++o) {
          if (o == w || truth.workpieces[o].parked) continue;
          const models::WorkpieceSpec& other = cell.workpieces[o];
          const Eigen::Vector3d d = truth.workpieces[o].pose.translation() - pose.translation();
          if (std::abs(d.z()) < 0.5 * (spec.size.z() + other.size.z()) &&
              d.head<2>().norm() < radius + 0.5 * std::hypot(other.size.x(), other.size.y())) {
            return true;
          }
        }
        return false;
      };
      Eigen::Isometry3d target = now * a.offset;
      if (overlaps(target)) {
        a.offset.translation().x() = -a.offset.translation().x();
        target = now * a.offset;
      }
      world_.place(f.workpiece, target);
      report(f, fmt::format("workpiece '{}' moved by ({:.3f}, {:.3f}) m in its own frame and turned by {:.1f} "
                            "degrees where it starts, to ({:.3f}, {:.3f}, {:.3f}) m",
                            f.workpiece, a.offset.translation().x(), a.offset.translation().y(),
                            yaw_of(a.offset.linear()) * 180 / std::numbers::pi, target.translation().x(),
                            target.translation().y(), target.translation().z()));
    } else {
      const models::ConveyorSpec* c = cell.find_conveyor(spec.on);
      double margin = 0, moved = 0;
      const Eigen::Isometry3d target = out_of_reach(f.workpiece, now, c, f.distance, &margin, &moved);
      world_.place(f.workpiece, target);
      report(f, fmt::format("workpiece '{}' put on the floor at ({:.3f}, {:.3f}) m where it starts, {:.2f} m out{}, "
                            "{:.3f} m beyond the reach of every robot",
                            f.workpiece, target.translation().x(), target.translation().y(), moved,
                            c != nullptr ? fmt::format(" beside conveyor '{}'", c->name) : std::string(" from the "
                                                                                                       "robots"),
                            margin));
    }
    a.done = true;
  }
}

void FaultInjector::fed(const std::string& workpiece) {
  for (Active& a : faults_) {
    if (a.done || a.spec.workpiece != workpiece) continue;
    if (a.spec.kind == FaultKind::misplace) {
      report(a.spec, fmt::format("workpiece '{}' arrived moved by ({:.3f}, {:.3f}) m in its own frame and turned by "
                                 "{:.1f} degrees",
                                 workpiece, a.offset.translation().x(), a.offset.translation().y(),
                                 yaw_of(a.offset.linear()) * 180 / std::numbers::pi));
      a.done = true;
    } else if (a.spec.kind == FaultKind::unreachable) {
      report(a.spec, fmt::format("workpiece '{}' arrived on the floor at ({:.3f}, {:.3f}) m, {:.2f} m out beside its "
                                 "conveyor, {:.3f} m beyond the reach of every robot",
                                 workpiece, a.offset.translation().x(), a.offset.translation().y(), a.moved,
                                 a.margin));
      a.done = true;
    }
  }
}

bool FaultInjector::lose_frame(std::chrono::nanoseconds now) {
  for (Active& a : faults_) {
    if (a.done || a.spec.kind != FaultKind::frame_lost || seconds(now) < a.spec.time - 1e-9) continue;
    if (a.frames_lost++ == 0) {
      report(a.spec, fmt::format("the camera delivers no frame for {} frame{} from t={:.3f} s", a.spec.count,
                                 a.spec.count == 1 ? "" : "s", seconds(now)));
    }
    a.done = a.frames_lost >= a.spec.count;
    return true;
  }
  return false;
}

void FaultInjector::update_carries(const WorldTruth& truth) {
  const std::chrono::nanoseconds now = truth.time;
  for (std::size_t r = 0; r < carries_.size(); ++r) {
    Carry& c = carries_[r];
    if (c.part >= 0) {
      if (truth.workpieces[static_cast<std::size_t>(c.part)].held_by_robot(r)) {
        c.last_held = now;
      } else if (now - c.last_held >= kCarryEnd) {
        c.part = -1;
      }
    }
    if (c.part >= 0) continue;
    for (std::size_t w = 0; w < truth.workpieces.size(); ++w) {
      if (!truth.workpieces[w].held_by_robot(r)) continue;
      c.part = static_cast<int>(w);
      c.since = c.last_held = now;
      ++c.count;
      for (Active& a : faults_) {
        if (a.spec.kind != FaultKind::drop && a.spec.kind != FaultKind::slip) continue;
        const bool due = a.spec.carry == c.count || (a.spec.every > 0 && c.count > a.spec.carry &&
                                                     (c.count - a.spec.carry) % a.spec.every == 0);
        if (robot_index(a.spec.robot) != r || !due) continue;
        if (a.spec.every > 0 && a.done) {  // a fault at a set rate: armed again for this carry
          a.done = false;
          a.part = -1;
          a.slip_left = 0;
        }
        if (a.done || a.part >= 0) continue;
        a.part = c.part;
        a.due = now + std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(a.spec.after));
      }
      break;
    }
  }
}

void FaultInjector::update_obstacle(Active& a, const WorldTruth& truth) {
  const FaultSpec& f = a.spec;
  const std::chrono::nanoseconds now = truth.time;
  if (a.placed) {
    if (seconds(now - *a.placed) >= f.duration - 1e-9) {
      world_.place_obstacle(a.obstacle, std::nullopt);
      a.done = true;
    }
    return;
  }
  if (seconds(now) < f.time - 1e-9 || !last_update_) return;
  const std::size_t r = robot_index(f.robot);
  if (!tcp_[r]) return;
  const double dt = seconds(now - *last_update_);
  if (dt <= 0) return;
  const Eigen::Vector3d p = truth.robots[r].tcp.translation();
  const Eigen::Vector3d v = (p - *tcp_[r]) / dt;
  if (v.norm() <= kObstacleToolSpeed) return;
  const Eigen::Vector3d along = v.normalized();
  // Two directions across the motion.
  Eigen::Vector3d across1 = along.cross(Eigen::Vector3d::UnitZ());
  if (across1.norm() < 1e-6) across1 = along.cross(Eigen::Vector3d::UnitX());
  across1.normalize();
  const Eigen::Vector3d across2 = along.cross(across1).normalized();
  Eigen::Vector3d centre = p + f.ahead * along + kJitter * (a.jitter[0] * across1 + a.jitter[1] * across2);
  centre.z() = std::max(centre.z(), f.size / 2 + 0.001);
  world_.place_obstacle(a.obstacle, centre);
  a.placed = now;
  a.centre = centre;
  report(f, fmt::format("a {:.3f} m box at ({:.3f}, {:.3f}, {:.3f}) m, {:.3f} m ahead of the tool of '{}' moving at "
                        "{:.3f} m/s, for {:.2f} s",
                        f.size, centre.x(), centre.y(), centre.z(), f.ahead, f.robot, v.norm(), f.duration));
}

void FaultInjector::update() {
  const std::chrono::nanoseconds now = world_.now();
  // Missing fed parts and detection noise are reported at their time.
  for (Active& a : faults_) {
    if (a.done) continue;
    if (a.spec.kind == FaultKind::missing && now >= a.due) {
      report(a.spec, fmt::format("workpiece '{}' never fed (due at {:.3f} s)", a.spec.workpiece, seconds(a.due)));
      a.done = true;
    } else if (a.spec.kind == FaultKind::detection_noise && seconds(now) >= a.spec.time - 1e-9) {
      report(a.spec, fmt::format("detections off by sigma {} m and {} degrees from {:.3f} s for {} s", a.spec.sigma,
                                 a.spec.sigma_yaw, a.spec.time, a.spec.duration));
      a.done = true;
    }
  }
  if (!needs_truth_) return;
  const WorldTruth truth = world_.truth();
  update_carries(truth);
  for (Active& a : faults_) {
    if (a.done) continue;
    const FaultSpec& f = a.spec;
    if (f.kind == FaultKind::obstacle) {
      update_obstacle(a, truth);
      continue;
    }
    if ((f.kind != FaultKind::drop && f.kind != FaultKind::slip) || a.part < 0) continue;
    const std::size_t r = robot_index(f.robot);
    const Carry& c = carries_[r];
    const std::string& part = truth.workpieces[static_cast<std::size_t>(a.part)].name;
    const bool held = truth.workpieces[static_cast<std::size_t>(a.part)].held_by_robot(r);
    if (a.slip_left > 0) {  // sliding
      const double step = std::min(a.slip_left, f.distance / kSlipPeriods);
      if (!held || world_.clearance_below(part) < step + kSlipClearance) {
        a.done = true;
        continue;
      }
      world_.shift(part, Eigen::Vector3d(0, 0, -step));
      a.slip_left -= step;
      a.done = a.slip_left <= 1e-12;
      continue;
    }
    if (c.part != a.part) {  // the carry ended before the moment came
      a.done = true;
      continue;
    }
    // In the air: held, and room below it (a part just lifted off its support waits; it may touch something beside
    // it, e.g. a stop bar). A part slides only where there is room below it for the whole slide.
    const double room = f.kind == FaultKind::slip ? f.distance + kSlipClearance : kAirborne;
    if (now < a.due || !held || world_.clearance_below(part) < room) continue;
    const Eigen::Vector3d at = truth.workpieces[static_cast<std::size_t>(a.part)].pose.translation();
    const std::string when = fmt::format("carry {} of '{}', {:.3f} s after the grasp, at ({:.3f}, {:.3f}, {:.3f}) m",
                                         c.count, part, seconds(now - c.since), at.x(), at.y(), at.z());
    if (f.kind == FaultKind::drop) {
      SimDriver* driver = world_.driver(f.robot);
      a.done = true;
      if (driver == nullptr) continue;  // no simulated gripper to open: the moment never comes
      driver->release_grip(now + kDropRelease);
      out_.push_back({"drop", f.robot, part,
                      fmt::format("{}: the gripper lost its grip force for {:.1f} s", when, seconds(kDropRelease))});
    } else {
      a.slip_left = f.distance;
      out_.push_back({"slip", f.robot, part,
                      fmt::format("{}: the part slides {:.3f} m down in the fingers", when, f.distance)});
      const double step = f.distance / kSlipPeriods;
      world_.shift(part, Eigen::Vector3d(0, 0, -step));
      a.slip_left -= step;
    }
  }
  for (std::size_t r = 0; r < tcp_.size(); ++r) tcp_[r] = truth.robots[r].tcp.translation();
  last_update_ = now;
}

std::vector<InjectedFault> FaultInjector::take() {
  std::vector<InjectedFault> out;
  out.swap(out_);
  return out;
}

std::vector<runtime::Obstacle> FaultInjector::obstacles() const {
  std::vector<runtime::Obstacle> out;
  for (const Active& a : faults_) {
    if (a.spec.kind != FaultKind::obstacle || !a.placed || a.done) continue;
    const ObstacleIds& ids = world_.scene().obstacles()[a.obstacle];
    out.push_back({ids.name, a.centre, Eigen::Vector3d::Constant(ids.size)});
  }
  return out;
}

// ---- NoisyDetector ------------------------------------------------------------------------------------------------

NoisyDetector::NoisyDetector(std::shared_ptr<const runtime::PartDetector> inner, std::vector<FaultSpec> faults,
                             std::uint64_t seed, std::function<runtime::SimDuration()> frame_time)
    : inner_(std::move(inner)), frame_time_(std::move(frame_time)), rng_(seed) {
  for (FaultSpec& f : faults) {
    if (f.kind == FaultKind::detection_noise) faults_.push_back(std::move(f));
  }
}

double NoisyDetector::normal() const {
  const double u1 = 1.0 - unit(rng_);  // (0, 1]
  const double u2 = unit(rng_);
  const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  return std::clamp(z, -3.0, 3.0);
}

runtime::Sightings NoisyDetector::detect(const runtime::Image& image,
                                         const std::vector<runtime::Prediction>& predictions) const {
  runtime::Sightings s = inner_->detect(image, predictions);
  const double t = seconds(frame_time_());
  for (const FaultSpec& f : faults_) {
    if (t < f.time - 1e-9 || t >= f.time + f.duration - 1e-9) continue;
    for (runtime::Sighting& seen : s.seen) {
      const double dx = f.sigma * normal(), dy = f.sigma * normal();
      const double dyaw = f.sigma_yaw * std::numbers::pi / 180 * normal();
      seen.pose.translation() += Eigen::Vector3d(dx, dy, 0);
      if (seen.yaw) {
        *seen.yaw += dyaw;
        seen.pose.linear() = Eigen::AngleAxisd(dyaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * seen.pose.linear();
      }
    }
  }
  return s;
}

}  // namespace cellwright::twin::sim
