#include "cellwright/twin/sim/world.hpp"

#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/twin/sim/contact_pairs.hpp"
#include "resting_parts.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

namespace cellwright::twin::sim {

namespace {

constexpr std::size_t npos = std::numeric_limits<std::size_t>::max();
constexpr double kParkingGap = 0.1;         // m between parked parts, and from the cell to the parking row
constexpr double kFeedClearance = 0.005;    // m: a part closer than this to the feed spot blocks it
constexpr double kUprightCos = 0.98480775;  // cos(10 degrees)
constexpr std::chrono::nanoseconds kCollisionQuiet = std::chrono::milliseconds(100);  // see check_contacts()
constexpr double kRestGap = 0.002;  // m: a part this close above a surface rests on it (chatter, see truth())
// The part-present sensors (world.hpp): how close a part's front face is to the stop bar, and its bottom to the belt.
constexpr double kSensorReach = 0.005;
constexpr double kSensorHeight = 0.005;
// An accumulating belt stops when a part's front face comes this close to the bar (world.hpp, "Belts").
constexpr double kBlockReach = 0.0005;
// A part moving faster is passing, not resting: the runtime's rule for a part ready to be grasped.
const double kSensorRestSpeed = runtime::TargetOptions{}.part_at_rest_speed;
// Its speed is averaged (a first-order filter with this time constant): a part pressed against the stop by the belt
// chatters at a few cm/s for a few tens of micrometres, which must not flicker the sensor.
constexpr double kSensorSpeedTime = 0.1;  // s

const char* warning_text(int i) {
  switch (i) {
    case mjWARN_INERTIA:
      return "an inertia matrix is too close to singular";
    case mjWARN_CONTACTFULL:
      return "the contact buffer is full (contacts were dropped)";
    case mjWARN_CNSTRFULL:
      return "the constraint buffer is full (constraints were dropped)";
    case mjWARN_VGEOMFULL:
      return "the visual geom buffer is full";
    case mjWARN_BADQPOS:
      return "bad qpos (NaN or huge): MuJoCo reset the simulation";
    case mjWARN_BADQVEL:
      return "bad qvel (NaN or huge): MuJoCo reset the simulation";
    case mjWARN_BADQACC:
      return "bad qacc (NaN or huge): MuJoCo reset the simulation";
    case mjWARN_BADCTRL:
      return "bad ctrl (NaN or huge)";
    default:
      return "unknown warning";
  }
}

bool resets_simulation(int i) {
  return i == mjWARN_BADQPOS || i == mjWARN_BADQVEL || i == mjWARN_BADQACC;
}

std::string name_of(const mjModel* m, mjtObj type, int id) {
  const char* n = mj_id2name(m, type, id);
  return n ? n : "";
}

Eigen::Isometry3d free_pose(const mjData* d, int qpos_adr) {
  const mjtNum* q = d->qpos + qpos_adr;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() << q[0], q[1], q[2];
  t.linear() = Eigen::Quaterniond(q[3], q[4], q[5], q[6]).normalized().toRotationMatrix();
  return t;
}

// A part as seen in another frame (a conveyor's, a fixture's): its centre and half its extents along that frame's
// axes, however it is turned.
struct Lying {
  Eigen::Vector3d centre;
  Eigen::Vector3d half;
  double bottom() const { return centre.z() - half.z(); }
};

Lying lying(const Eigen::Isometry3d& pose, const Eigen::Vector3d& size) {
  const Eigen::Matrix3d r = pose.linear().cwiseAbs();
  return {pose.translation(), 0.5 * (r * size)};
}

}  // namespace

World::World(Scene scene, WorldOptions options)
    : scene_(std::move(scene)),
      physics_(nullptr, mj_deleteModel),
      options_(std::move(options)), signals_(std::max<std::size_t>(options_.signals, 1)) {
  const mjModel* m = scene_.model();
  const double ns = m->opt.timestep * 1e9;
  if (!(ns >= 1.0) || std::abs(ns - std::round(ns)) > 1e-6) {
    throw InputError(options_.where, fmt::format("the cell's timestep {} s is not a whole number of nanoseconds; the "
                                                 "simulation clock counts whole steps",
                                                 m->opt.timestep));
  }
  if (options_.signals == 0) throw InputError(options_.where, "the cell needs at least one digital signal");
  timestep_ = std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(ns)));
  scene_.reset();
  drivers_.resize(scene_.robots().size());
  parked_.assign(scene_.workpieces().size(), false);
  classify_bodies();
  physics_.reset(mj_copyModel(nullptr, m));
  CW_CHECK(physics_ != nullptr, "mj_copyModel failed");
  pairs_ = std::make_unique<ContactPairs>(physics_.get());  // from the scene's collision masks, before any sleeps
  resting_ = std::make_unique<RestingParts>(scene_, physics_.get());

  // The parking row: on the floor, beyond everything the cell holds in +x, along y.
  double max_x = -std::numeric_limits<double>::infinity(), min_y = std::numeric_limits<double>::infinity();
  const mjData* d = scene_.data();
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_type[g] == mjGEOM_PLANE) continue;
    if (bodies_[static_cast<std::size_t>(m->geom_bodyid[g])].workpiece >= 0) continue;
    if (m->body_mocapid[m->geom_bodyid[g]] >= 0) continue;  // an obstacle, waiting under the floor
    max_x = std::max(max_x, d->geom_xpos[3 * g] + m->geom_rbound[g]);
    min_y = std::min(min_y, d->geom_xpos[3 * g + 1] - m->geom_rbound[g]);
  }
  // And out of sight of the cell's cameras (a parked part is not in the cell; vision must not find it): beyond the
  // floor a camera sees, bounded by its tilt plus its half diagonal field of view, measured from the point below it.
  // A camera whose view reaches within 5 degrees of the horizon sees the floor too far to hide the row from it.
  for (const models::CameraSpec& c : scene_.cell().cameras) {
    if (c.pose.xyz.z() <= 0) continue;
    const Eigen::Vector3d look = -c.pose.rotation().col(2);  // MuJoCo cameras look along their -z
    const double tilt = std::acos(std::clamp(-look.z(), -1.0, 1.0));
    const double half_diagonal = std::atan(std::tan(c.fovy / 2) * std::hypot(1.0, double(c.width) / c.height));
    if (tilt + half_diagonal >= std::numbers::pi / 2 - 5 * std::numbers::pi / 180) continue;
    max_x = std::max(max_x, c.pose.xyz.x() + c.pose.xyz.z() * std::tan(tilt + half_diagonal));
  }
  parking_origin_ = Eigen::Vector3d(max_x + kParkingGap, min_y, 0.0);

  for (const std::string& name : options_.parked) {
    const std::size_t w = workpiece_index(name);
    if (w == npos) {
      throw InputError(options_.where,
                       fmt::format("parked workpiece '{}' is not a workpiece of cell '{}'", name, scene_.cell().name));
    }
    place_at_rest(w, parking_pose(w));
    parked_[w] = true;
    resting_->put_to_sleep(w, scene_.data());
  }
  const models::CellDescription& cell = scene_.cell();
  for (const models::ConveyorSpec& c : cell.conveyors) {
    world_to_conveyor_.push_back(c.pose.transform().inverse());
    state_.conveyors.push_back({c.name, true, true, false, false});
    if (!c.stop_eye) continue;
    if (static_cast<std::size_t>(c.sensor) > signals_.size()) {
      throw InputError(c.sensor_where, fmt::format("conveyor '{}': its sensor's signal {} is not one of the cell's {} "
                                                   "digital signals",
                                                   c.name, c.sensor, signals_.size()));
    }
    ++stop_eyes_;
  }
  for (const models::MachineSpec& mc : cell.machines) {
    world_to_fixture_.push_back(mc.fixture_top().transform().inverse());
    MachineDevice md;
    md.name = mc.name;
    state_.machines.push_back(std::move(md));
  }
  belt_run_.assign(cell.conveyors.size(), true);  // the belts run from the start, as they always did
  machine_start_.assign(cell.machines.size(), false);
  start_edges_.assign(cell.machines.size(), 0);
  taken_edges_.assign(cell.machines.size(), 0);
  busy_steps_.assign(cell.machines.size(), 0);
  held_.assign(cell.conveyors.size(), false);
  processed_.assign(scene_.workpieces().size(), false);
  sensed_velocity_.assign(scene_.workpieces().size(), Eigen::Vector3d::Zero());
  update_devices(false);
  for (int i = 0; i < mjNWARNING; ++i) warning_counts_[static_cast<std::size_t>(i)] = d->warning[i].number;
}

World::~World() = default;

void World::classify_bodies() {
  const mjModel* m = scene_.model();
  bodies_.assign(static_cast<std::size_t>(m->nbody), BodyInfo{});
  for (int b = 0; b < m->nbody; ++b) {
    BodyInfo& info = bodies_[static_cast<std::size_t>(b)];
    info.fixed = m->body_weldid[b] == 0;
    // A robot's bodies are its base and everything below it; the gripper is the flange and below.
    for (int a = b; a > 0; a = m->body_parentid[a]) {
      for (std::size_t r = 0; r < scene_.robots().size(); ++r) {
        const RobotIds& ids = scene_.robots()[r];
        if (a == ids.flange_body) info.gripper = true;
        if (a == ids.base_body) info.robot = static_cast<int>(r);
      }
      if (info.robot >= 0) break;
    }
    if (info.robot < 0) info.gripper = false;
  }
  for (const RobotIds& ids : scene_.robots()) {
    for (int side = 0; side < 2; ++side) {
      BodyInfo& info =
          bodies_[static_cast<std::size_t>(m->jnt_bodyid[ids.finger_joint[static_cast<std::size_t>(side)]])];
      info.finger = true;
      info.finger_side = side;
    }
  }
  for (std::size_t w = 0; w < scene_.workpieces().size(); ++w) {
    bodies_[static_cast<std::size_t>(scene_.workpieces()[w].body)].workpiece = static_cast<int>(w);
  }
}

std::size_t World::workpiece_index(std::string_view name) const {
  for (std::size_t w = 0; w < scene_.workpieces().size(); ++w) {
    if (scene_.workpieces()[w].name == name) return w;
  }
  return npos;
}

Eigen::Isometry3d World::parking_pose(std::size_t workpiece) const {
  double y = parking_origin_.y();
  for (std::size_t w = 0; w < workpiece; ++w) y += scene_.cell().workpieces[w].size.y() + kParkingGap;
  const Eigen::Vector3d& size = scene_.cell().workpieces[workpiece].size;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(parking_origin_.x() + size.x() / 2, y + size.y() / 2, size.z() / 2);
  return pose;
}

void World::place_at_rest(std::size_t workpiece, const Eigen::Isometry3d& pose) {
  resting_->wake(workpiece);
  mjData* d = scene_.data();
  const WorkpieceIds& ids = scene_.workpieces()[workpiece];
  const Eigen::Quaterniond q(pose.linear());
  mjtNum* qpos = d->qpos + ids.qpos_adr;
  qpos[0] = pose.translation().x();
  qpos[1] = pose.translation().y();
  qpos[2] = pose.translation().z();
  qpos[3] = q.w();
  qpos[4] = q.x();
  qpos[5] = q.y();
  qpos[6] = q.z();
  for (int i = 0; i < 6; ++i) {
    d->qvel[ids.dof_adr + i] = 0;
    d->qacc_warmstart[ids.dof_adr + i] = 0;
  }
  // Positions, contacts and sensors follow the move at once (the state itself is only what was set above).
  pairs_->forward(scene_.data());
}

SimDriver& World::add_sim_driver(std::string_view robot, SimDriverOptions options) {
  const RobotIds* ids = scene_.find_robot(robot);
  if (!ids) {
    throw InputError(options_.where,
                     fmt::format("no robot '{}' in cell '{}' for a simulation driver", robot, scene_.cell().name));
  }
  const auto r = static_cast<std::size_t>(ids - scene_.robots().data());
  if (drivers_[r]) throw InputError(options_.where, fmt::format("robot '{}' has a simulation driver already", robot));
  drivers_[r] = std::make_unique<SimDriver>(scene_, r, signals_, std::move(options));
  return *drivers_[r];
}

SimDriver* World::driver(std::string_view robot) {
  const RobotIds* ids = scene_.find_robot(robot);
  if (!ids) return nullptr;
  return drivers_[static_cast<std::size_t>(ids - scene_.robots().data())].get();
}

void World::advance(std::chrono::nanoseconds dt) {
  CW_CHECK(dt.count() >= 0 && dt.count() % timestep_.count() == 0,
           "advance({} ns) is not a whole number of {} ns timesteps", dt.count(), timestep_.count());
  step(dt.count() / timestep_.count());
}

void World::step(std::int64_t n) {
  CW_CHECK(n >= 0, "cannot step {} times", n);
  const mjModel* m = physics_.get();
  mjData* d = scene_.data();
  for (std::int64_t i = 0; i < n; ++i) {
    if (commands_changed_.load(std::memory_order_acquire)) apply_commands();
    // MuJoCo's sensors (touch, wrist force and torque) are computed on the last step of the call, which truth()
    // reads, and on steps after which a driver reads its fingers' touch; the sensor stage is 7 % of a step.
    bool touch_read = false;
    for (auto& driver : drivers_) {
      if (driver) touch_read = driver->step(now(), m, d, sensors_fresh_) || touch_read;
    }
    sensors_fresh_ = touch_read || i + 1 == n;
    if (!sensors_fresh_) physics_->opt.disableflags |= mjDSBL_SENSOR;
    pairs_->step(d);
    physics_->opt.disableflags &= ~mjDSBL_SENSOR;
    scene_.wrap_belts(d);
    resting_->after_step(d, parked_);
    ++steps_;
    check_contacts();
    check_warnings();
    if (stop_eyes_ != 0 || !state_.machines.empty()) {
      // The parts' averaged velocities, for the stop eyes' and the fixtures' rest test.
      const double a = std::min(1.0, std::chrono::duration<double>(timestep_).count() / kSensorSpeedTime);
      for (std::size_t w = 0; w < sensed_velocity_.size(); ++w) {
        const Eigen::Vector3d v = Eigen::Map<const Eigen::Vector3d>(d->qvel + scene_.workpieces()[w].dof_adr);
        sensed_velocity_[w] =
            parked_[w] ? Eigen::Vector3d::Zero() : Eigen::Vector3d(sensed_velocity_[w] + a * (v - sensed_velocity_[w]));
      }
    }
    update_devices(true);
  }
}

void World::update_devices(bool stepped) {
  update_sensors();
  update_machines(stepped);
  drive_belts();
  {
    const std::lock_guard lock(device_mutex_);
    if (!(published_ == state_)) published_ = state_;
  }
  published_time_.store(now().count(), std::memory_order_release);
}

void World::update_sensors() {
  const mjData* d = scene_.data();
  const models::CellDescription& cell = scene_.cell();
  for (std::size_t i = 0; i < cell.conveyors.size(); ++i) {
    const models::ConveyorSpec& c = cell.conveyors[i];
    if (!c.stop_eye && !c.drop_eye) continue;
    bool stop = false, drop = false, near = false, at = false;
    for (std::size_t w = 0; w < cell.workpieces.size(); ++w) {
      if (parked_[w]) continue;
      const Lying l = lying(world_to_conveyor_[i] * free_pose(d, scene_.workpieces()[w].qpos_adr),
                            cell.workpieces[w].size);
      const Eigen::Vector3d& p = l.centre;  // in the conveyor's frame: x along the belt from its centre, z up
      if (std::abs(p.y()) > c.width / 2 || std::abs(l.bottom() - c.height) > kSensorHeight) continue;
      const double s = p.x() + c.length / 2;  // distance from the belt's upstream end
      // The stop eye: the front face at the bar, at rest. The drop eye: a beam across the belt at `enter`.
      const double gap = std::abs(s + l.half.x() - c.leave);
      near = near || gap <= kSensorReach;
      at = at || gap <= kBlockReach;
      stop = stop || (c.stop_eye && gap <= kSensorReach && sensed_velocity_[w].norm() < kSensorRestSpeed);
      drop = drop || (c.drop_eye && std::abs(s - c.enter) <= l.half.x());
    }
    // Accumulation holds the belt from a part reaching the bar until no part is near it any more: the hysteresis
    // keeps the belt from restarting when the part, no longer pressed on the bar, eases back from it.
    held_[i] = c.stop_eye && (held_[i] ? near : at);
    state_.conveyors[i].stop_eye = stop;
    state_.conveyors[i].drop_eye = drop;
    if (c.sensor != 0) signals_.set(c.sensor, stop);
  }
}

void World::apply_commands() {
  commands_changed_.store(false, std::memory_order_relaxed);
  const std::lock_guard lock(device_mutex_);
  for (std::size_t i = 0; i < belt_run_.size(); ++i) state_.conveyors[i].run = belt_run_[i];
  for (std::size_t m = 0; m < machine_start_.size(); ++m) {
    state_.machines[m].start = machine_start_[m];
    taken_edges_[m] += std::exchange(start_edges_[m], 0);
  }
  drive_belts();
}

void World::drive_belts() {
  mjData* d = scene_.data();
  const models::CellDescription& cell = scene_.cell();
  for (std::size_t i = 0; i < cell.conveyors.size(); ++i) {
    ConveyorDevice& c = state_.conveyors[i];
    c.running = c.run && !(cell.conveyors[i].accumulate && held_[i]);
    const ConveyorIds& ids = scene_.conveyors()[i];
    d->ctrl[ids.belt_actuator] = c.running ? ids.speed : 0.0;
  }
}

bool World::on_fixture(std::size_t machine, std::size_t workpiece) const {
  if (parked_[workpiece]) return false;
  const Lying l = lying(world_to_fixture_[machine] * free_pose(scene_.data(), scene_.workpieces()[workpiece].qpos_adr),
                        scene_.cell().workpieces[workpiece].size);
  const Eigen::Vector3d& fixture = scene_.cell().machines[machine].fixture_size;
  return std::abs(l.centre.x()) <= fixture.x() / 2 && std::abs(l.centre.y()) <= fixture.y() / 2 &&
         std::abs(l.bottom()) <= kSensorHeight;
}

void World::update_machines(bool stepped) {
  const models::CellDescription& cell = scene_.cell();
  for (std::size_t m = 0; m < state_.machines.size(); ++m) {
    MachineDevice& md = state_.machines[m];
    const int starts = std::exchange(taken_edges_[m], 0);
    const std::size_t w = md.part.empty() ? npos : workpiece_index(md.part);
    if (md.state == MachineState::idle) {
      for (std::size_t o = 0; o < processed_.size(); ++o) {
        if (on_fixture(m, o) && sensed_velocity_[o].norm() < kSensorRestSpeed) {
          md.state = MachineState::loaded;
          md.part = scene_.workpieces()[o].name;
          break;
        }
      }
      continue;  // a start while empty is ignored
    }
    if (!on_fixture(m, w)) {
      // The part left the fixture: after the cycle, that is the unload; before its end, the cycle is aborted.
      if (md.state == MachineState::done) ++md.unloads;
      md.state = MachineState::idle;
      md.part.clear();
      md.busy_left = std::chrono::nanoseconds(0);
      continue;
    }
    if (md.state == MachineState::loaded && starts > 0) {
      md.state = MachineState::busy;
      const double steps = cell.machines[m].process_time / std::chrono::duration<double>(timestep_).count();
      busy_steps_[m] = std::max<std::int64_t>(1, std::llround(steps));
    } else if (md.state == MachineState::busy && stepped && --busy_steps_[m] == 0) {
      md.state = MachineState::done;
      ++md.cycles;
      processed_[w] = true;
      state_.processed.push_back(md.part);
      paint_processed(w, cell.machines[m].processed_rgba);
    }
    md.busy_left = md.state == MachineState::busy ? timestep_ * busy_steps_[m] : std::chrono::nanoseconds(0);
  }
}

void World::paint_processed(std::size_t workpiece, const Eigen::Vector4d& rgba) {
  mjtNum* slot = scene_.data()->userdata + kColourSlot * static_cast<std::ptrdiff_t>(workpiece);
  CW_CHECK(kColourSlot * static_cast<int>(workpiece + 1) <= scene_.model()->nuserdata,
           "the scene has no colour slot for workpiece {}", workpiece);
  slot[0] = scene_.workpieces()[workpiece].geom + 1;
  for (int k = 0; k < 4; ++k) slot[1 + k] = rgba[k];
}

void World::set_belt_run(std::size_t conveyor, bool run) {
  const std::lock_guard lock(device_mutex_);
  CW_CHECK(conveyor < belt_run_.size(), "no conveyor {} (the cell has {})", conveyor, belt_run_.size());
  belt_run_[conveyor] = run;
  commands_changed_.store(true, std::memory_order_release);
}

bool World::belt_run(std::size_t conveyor) const {
  const std::lock_guard lock(device_mutex_);
  CW_CHECK(conveyor < belt_run_.size(), "no conveyor {} (the cell has {})", conveyor, belt_run_.size());
  return belt_run_[conveyor];
}

void World::set_machine_start(std::size_t machine, bool on) {
  const std::lock_guard lock(device_mutex_);
  CW_CHECK(machine < machine_start_.size(), "no machine {} (the cell has {})", machine, machine_start_.size());
  if (on && !machine_start_[machine]) ++start_edges_[machine];
  machine_start_[machine] = on;
  commands_changed_.store(true, std::memory_order_release);
}

bool World::machine_start(std::size_t machine) const {
  const std::lock_guard lock(device_mutex_);
  CW_CHECK(machine < machine_start_.size(), "no machine {} (the cell has {})", machine, machine_start_.size());
  return machine_start_[machine];
}

DeviceStates World::devices() const {
  DeviceStates out;
  {
    const std::lock_guard lock(device_mutex_);
    out = published_;
  }
  out.time = std::chrono::nanoseconds(published_time_.load(std::memory_order_acquire));
  return out;
}

bool World::processed(std::string_view workpiece) const {
  const std::size_t w = workpiece_index(workpiece);
  CW_CHECK(w != npos, "no workpiece '{}'", workpiece);
  return processed_[w];
}

void World::check_contacts() {
  const mjModel* m = scene_.model();
  const mjData* d = scene_.data();
  // Pairs of bodies in unintended contact in this step, with their deepest contact.
  std::vector<std::pair<std::pair<int, int>, int>> now_touching;
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if (con.exclude != 0) continue;  // in the margin gap, not touching
    int b1 = m->geom_bodyid[con.geom1], b2 = m->geom_bodyid[con.geom2];
    const BodyInfo* i1 = &bodies_[static_cast<std::size_t>(b1)];
    const BodyInfo* i2 = &bodies_[static_cast<std::size_t>(b2)];
    if (i1->robot < 0 && i2->robot < 0) continue;  // no robot involved
    if (i1->robot < 0) {
      std::swap(b1, b2);
      std::swap(i1, i2);
    }
    // i1 is a robot's body now.
    bool counts = false;
    if (i2->robot >= 0) {
      counts = i2->robot != i1->robot;
    } else if (i2->workpiece >= 0) {
      counts = !i1->gripper;
    } else {
      counts = true;  // the cell's geometry
    }
    if (!counts) continue;
    const std::pair<int, int> key{std::min(b1, b2), std::max(b1, b2)};
    const auto it =
        std::find_if(now_touching.begin(), now_touching.end(), [&](const auto& e) { return e.first == key; });
    if (it == now_touching.end()) {
      now_touching.emplace_back(key, c);
    } else if (con.dist < d->contact[it->second].dist) {
      it->second = c;
    }
  }
  // A pair is reported when it starts touching, and again only after it has been apart for kCollisionQuiet: a
  // contact that chatters (touching every few steps while two bodies press on each other) is one collision.
  const std::int64_t quiet = kCollisionQuiet / timestep_;
  std::set<std::pair<int, int>> touching;
  for (const auto& [key, c] : now_touching) {
    touching.insert(key);
    const auto last = last_touch_.find(key);
    const bool reported = last != last_touch_.end() && steps_ - last->second <= quiet;
    last_touch_[key] = steps_;
    if (reported) continue;
    const mjContact& con = d->contact[c];
    Collision col;
    col.time = now();
    col.body1 = name_of(m, mjOBJ_BODY, key.first);
    col.body2 = name_of(m, mjOBJ_BODY, key.second);
    const bool in_order = m->geom_bodyid[con.geom1] == key.first;
    col.geom1 = name_of(m, mjOBJ_GEOM, in_order ? con.geom1 : con.geom2);
    col.geom2 = name_of(m, mjOBJ_GEOM, in_order ? con.geom2 : con.geom1);
    const int r1 = bodies_[static_cast<std::size_t>(key.first)].robot;
    const int r2 = bodies_[static_cast<std::size_t>(key.second)].robot;
    if (r1 >= 0) col.robot1 = scene_.robots()[static_cast<std::size_t>(r1)].name;
    if (r2 >= 0) col.robot2 = scene_.robots()[static_cast<std::size_t>(r2)].name;
    col.position = Eigen::Vector3d(con.pos[0], con.pos[1], con.pos[2]);
    col.depth = std::max(0.0, -con.dist);
    collisions_.push_back(std::move(col));
  }
  touching_ = std::move(touching);
  // Pairs apart for longer than the quiet time are forgotten.
  std::erase_if(last_touch_, [&](const auto& e) { return steps_ - e.second > quiet; });
}

void World::check_warnings() {
  const mjData* d = scene_.data();
  bool reset = false, full = false;
  for (int i = 0; i < mjNWARNING; ++i) {
    const int count = d->warning[i].number;
    int& seen = warning_counts_[static_cast<std::size_t>(i)];
    if (count < seen) seen = 0;  // MuJoCo reset the data (and its counters) after a numerical failure
    if (count == seen) continue;
    warnings_.push_back(fmt::format("t={:.3f} s: MuJoCo warning: {} (raised {} time{}; last info {})", time(),
                                    warning_text(i), count - seen, count - seen == 1 ? "" : "s",
                                    d->warning[i].lastinfo));
    seen = count;
    reset = reset || resets_simulation(i);
    full = full || i == mjWARN_CNSTRFULL || i == mjWARN_CONTACTFULL;
  }
  if (!reset && !full) return;
  // Dropped contacts or constraints are as bad as a reset: parts fall through what holds them, grasps let go.
  const mjModel* m = scene_.model();
  const std::string message =
      reset ? fmt::format("the simulation was reset by MuJoCo at t={:.3f} s after a numerical failure", time())
            : fmt::format("the physics dropped contacts or constraints at t={:.3f} s: the cell needed more than "
                          "the scene's buffers hold ({} constraint rows, {} contacts; kNjmax and kNconmax in "
                          "twin/src/scene.cpp)",
                          time(), m->njmax, m->nconmax);
  for (auto& driver : drivers_) {
    if (driver) driver->fault(message, now(), d);
  }
}

std::vector<Collision> World::new_collisions() {
  std::vector<Collision> out;
  out.swap(collisions_);
  return out;
}

std::vector<std::pair<std::string, std::string>> World::touching_pairs() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [a, b] : touching_) {
    out.emplace_back(name_of(scene_.model(), mjOBJ_BODY, a), name_of(scene_.model(), mjOBJ_BODY, b));
  }
  return out;
}

std::vector<std::string> World::drain_warnings() {
  std::vector<std::string> out;
  out.swap(warnings_);
  return out;
}

FeedResult World::feed(std::string_view workpiece, std::string_view conveyor, const Eigen::Isometry3d& offset) {
  const std::size_t w = workpiece_index(workpiece);
  if (w == npos) return {FeedStatus::unknown_workpiece, fmt::format("no workpiece '{}' to feed", workpiece)};
  const models::ConveyorSpec* c = scene_.cell().find_conveyor(conveyor);
  if (!c) return {FeedStatus::unknown_conveyor, fmt::format("no conveyor '{}' to feed '{}' onto", conveyor, workpiece)};
  if (!parked_[w]) {
    return {FeedStatus::not_parked, fmt::format("workpiece '{}' is in the cell already, not parked", workpiece)};
  }
  const models::WorkpieceSpec& spec = scene_.cell().workpieces[w];
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = c->pose.rotation();
  pose.translation() = c->belt_point(c->enter) + Eigen::Vector3d(0, 0, spec.size.z() / 2);
  pose = pose * offset;
  const double radius = 0.5 * std::hypot(spec.size.x(), spec.size.y());
  const mjData* d = scene_.data();
  for (std::size_t o = 0; o < scene_.workpieces().size(); ++o) {
    if (o == w || parked_[o]) continue;
    const models::WorkpieceSpec& other = scene_.cell().workpieces[o];
    const Eigen::Vector3d p = free_pose(d, scene_.workpieces()[o].qpos_adr).translation();
    const double gap =
        (p - pose.translation()).head<2>().norm() - radius - 0.5 * std::hypot(other.size.x(), other.size.y());
    const bool level = std::abs(p.z() - pose.translation().z()) < 0.5 * (spec.size.z() + other.size.z());
    if (level && gap < kFeedClearance) {
      return {FeedStatus::occupied,
              fmt::format("workpiece '{}' is still at the entry of conveyor '{}' ({:.3f} m from where '{}' would go)",
                          other.name, c->name, (p - pose.translation()).norm(), workpiece)};
    }
  }
  place_at_rest(w, pose);
  parked_[w] = false;
  update_devices(false);
  return {};
}

FeedResult World::park(std::string_view workpiece) {
  const std::size_t w = workpiece_index(workpiece);
  if (w == npos) return {FeedStatus::unknown_workpiece, fmt::format("no workpiece '{}' to park", workpiece)};
  place_at_rest(w, parking_pose(w));
  parked_[w] = true;
  resting_->put_to_sleep(w, scene_.data());
  update_devices(false);
  return {};
}

FeedResult World::place(std::string_view workpiece, const Eigen::Isometry3d& pose) {
  const std::size_t w = workpiece_index(workpiece);
  if (w == npos) return {FeedStatus::unknown_workpiece, fmt::format("no workpiece '{}' to place", workpiece)};
  place_at_rest(w, pose);
  parked_[w] = false;
  update_devices(false);
  return {};
}

void World::shift(std::string_view workpiece, const Eigen::Vector3d& delta) {
  const std::size_t w = workpiece_index(workpiece);
  CW_CHECK(w != npos, "no workpiece '{}'", workpiece);
  resting_->wake(w);
  mjtNum* qpos = scene_.data()->qpos + scene_.workpieces()[w].qpos_adr;
  for (int i = 0; i < 3; ++i) qpos[i] += delta[i];
  pairs_->forward(scene_.data());
}

double World::clearance_below(std::string_view workpiece) const {
  const std::size_t w = workpiece_index(workpiece);
  CW_CHECK(w != npos, "no workpiece '{}'", workpiece);
  const WorkpieceIds& ids = scene_.workpieces()[w];
  const Eigen::Vector3d c = free_pose(scene_.data(), ids.qpos_adr).translation();
  const mjtNum from[3] = {c.x(), c.y(), c.z()};
  const mjtNum down[3] = {0, 0, -1};
  int hit = -1;
  const mjtNum d = mj_ray(scene_.model(), scene_.data(), from, down, nullptr, 1, ids.body, &hit);
  if (hit < 0 || d < 0) return std::numeric_limits<double>::infinity();
  return d - scene_.cell().workpieces[w].size.z() / 2;
}

void World::place_obstacle(std::size_t index, const std::optional<Eigen::Vector3d>& centre) {
  CW_CHECK(index < scene_.obstacles().size(), "no obstacle {} (the scene has {})", index,
           scene_.obstacles().size());
  mjData* d = scene_.data();
  const Eigen::Vector3d p = centre.value_or(Eigen::Vector3d(0, 0, -1));
  mjtNum* pos = d->mocap_pos + 3 * scene_.obstacles()[index].mocap;
  for (int i = 0; i < 3; ++i) pos[i] = p[i];
  resting_->wake_all();  // it may appear where a part sleeps
  pairs_->forward(scene_.data());
}

bool World::parked(std::string_view workpiece) const {
  const std::size_t w = workpiece_index(workpiece);
  CW_CHECK(w != npos, "no workpiece '{}'", workpiece);
  return parked_[w];
}

bool World::asleep(std::string_view workpiece) const {
  const std::size_t w = workpiece_index(workpiece);
  CW_CHECK(w != npos, "no workpiece '{}'", workpiece);
  return resting_->asleep(w);
}

WorldTruth World::truth() const {
  const mjModel* m = scene_.model();
  const mjData* d = scene_.data();
  const models::CellDescription& cell = scene_.cell();
  WorldTruth t;
  t.time = now();

  for (const RobotIds& ids : scene_.robots()) {
    RobotTruth r;
    r.name = ids.name;
    for (std::size_t j = 0; j < ids.qpos_adr.size(); ++j) {
      r.joints.push_back(d->qpos[ids.qpos_adr[j]]);
      r.joint_velocities.push_back(d->qvel[ids.dof_adr[j]]);
    }
    const mjtNum* p = d->site_xpos + 3 * ids.tcp_site;
    const mjtNum* x = d->site_xmat + 9 * ids.tcp_site;
    r.tcp.translation() << p[0], p[1], p[2];
    r.tcp.linear() << x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8];
    r.finger_opening = d->qpos[ids.finger_qpos_adr[0]] + d->qpos[ids.finger_qpos_adr[1]];
    for (std::size_t side = 0; side < 2; ++side) {
      r.finger_touch[side] = d->sensordata[m->sensor_adr[ids.finger_touch_sensor[side]]];
      r.finger_contact[side] = r.finger_touch[side] > kTouchThreshold;
    }
    const mjtNum* f = d->sensordata + m->sensor_adr[ids.wrist_force_sensor];
    const mjtNum* tq = d->sensordata + m->sensor_adr[ids.wrist_torque_sensor];
    r.wrist_force = Eigen::Vector3d(f[0], f[1], f[2]);
    r.wrist_torque = Eigen::Vector3d(tq[0], tq[1], tq[2]);
    t.robots.push_back(std::move(r));
  }

  for (const ConveyorIds& c : scene_.conveyors()) t.conveyors.push_back({c.name, d->qvel[c.belt_dof_adr]});

  // Per workpiece: which fingers touch it, and its strongest support from below.
  const std::size_t nw = scene_.workpieces().size();
  std::vector<std::vector<std::array<bool, 2>>> fingers(nw, std::vector<std::array<bool, 2>>(scene_.robots().size()));
  std::vector<double> support_force(nw, 0.0);
  std::vector<int> support_geom(nw, -1);
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if (con.exclude != 0) continue;
    for (int side = 0; side < 2; ++side) {
      const int g = side == 0 ? con.geom1 : con.geom2;
      const int other = side == 0 ? con.geom2 : con.geom1;
      const BodyInfo& part = bodies_[static_cast<std::size_t>(m->geom_bodyid[g])];
      if (part.workpiece < 0) continue;
      const auto w = static_cast<std::size_t>(part.workpiece);
      const BodyInfo& o = bodies_[static_cast<std::size_t>(m->geom_bodyid[other])];
      if (o.finger) {
        fingers[w][static_cast<std::size_t>(o.robot)][static_cast<std::size_t>(o.finger_side)] = true;
      }
      const double up = upward_force(m, d, c, side);
      if (up > support_force[w]) {
        support_force[w] = up;
        support_geom[w] = other;
      }
    }
  }

  for (std::size_t w = 0; w < nw; ++w) {
    const WorkpieceIds& ids = scene_.workpieces()[w];
    const models::WorkpieceSpec& spec = cell.workpieces[w];
    WorkpieceTruth p;
    p.name = ids.name;
    p.pose = free_pose(d, ids.qpos_adr);
    const mjtNum* v = d->qvel + ids.dof_adr;
    p.linear_velocity = Eigen::Vector3d(v[0], v[1], v[2]);
    p.angular_velocity = p.pose.linear() * Eigen::Vector3d(v[3], v[4], v[5]);  // free joints: local frame
    p.upright = p.pose.linear()(2, 2) >= kUprightCos;
    p.parked = parked_[w];
    for (std::size_t r = 0; r < scene_.robots().size(); ++r) {
      if (fingers[w][r][0] && fingers[w][r][1]) p.holders.push_back(r);
    }
    if (!p.holders.empty()) p.held_by = p.holders.front();
    // A sleeping part touches nothing (RestingParts): its support is the one it slept on.
    if (resting_->asleep(w) && !p.parked) support_geom[w] = resting_->support_geom(w);
    if (!p.parked && !p.held_by && support_geom[w] < 0 && p.upright) {
      // Nothing pushes it up, yet it may rest there: a part held against a stop by the belt and the part behind it
      // chatters a fraction of a millimetre off the belt. Then the support is what lies just under its centre.
      const mjtNum from[3] = {p.pose.translation().x(), p.pose.translation().y(), p.pose.translation().z()};
      const mjtNum down[3] = {0, 0, -1};
      int hit = -1;
      const mjtNum distance = mj_ray(m, d, from, down, nullptr, 1, ids.body, &hit);
      if (hit >= 0 && distance >= 0 && distance - spec.size.z() / 2 <= kRestGap) support_geom[w] = hit;
    }
    if (p.parked) {
      p.support = SupportKind::parked;
    } else if (p.held_by) {
      p.support = SupportKind::gripper;
      p.support_name = scene_.robots()[*p.held_by].name;
    } else if (support_geom[w] >= 0) {
      const int g = support_geom[w];
      const int b = m->geom_bodyid[g];
      const BodyInfo& o = bodies_[static_cast<std::size_t>(b)];
      if (o.workpiece >= 0) {
        p.support = SupportKind::workpiece;
        p.support_name = scene_.workpieces()[static_cast<std::size_t>(o.workpiece)].name;
      } else if (o.robot >= 0) {
        p.support = SupportKind::robot;
        p.support_name = scene_.robots()[static_cast<std::size_t>(o.robot)].name;
      } else {
        p.support = SupportKind::other;
        p.support_name = name_of(m, mjOBJ_GEOM, g);
        if (p.support_name.empty()) p.support_name = name_of(m, mjOBJ_BODY, b);
        for (const ConveyorIds& c : scene_.conveyors()) {
          if (b == c.body || b == c.belt_body) {
            p.support = SupportKind::conveyor;
            p.support_name = c.name;
          }
        }
        for (const MachineIds& mc : scene_.machines()) {
          if (b == mc.body) {
            p.support = SupportKind::machine;
            p.support_name = mc.name;
          }
        }
        if (m->geom_type[g] == mjGEOM_PLANE) {
          p.support = SupportKind::floor;
          p.support_name = name_of(m, mjOBJ_GEOM, g);
        }
      }
    }
    if (!p.parked) {
      // The bottom centre of an upright part, against the locations' points.
      const Eigen::Vector3d bottom = p.pose.translation() - Eigen::Vector3d(0, 0, spec.size.z() / 2);
      double best = std::numeric_limits<double>::infinity();
      for (const models::LocationSpec& l : cell.locations) {
        const Eigen::Vector3d diff = bottom - l.pose.xyz;
        const double horizontal = diff.head<2>().norm();
        if (horizontal <= options_.location_tolerance && std::abs(diff.z()) <= options_.location_height_tolerance &&
            horizontal < best) {
          best = horizontal;
          p.location = l.name;
        }
      }
    }
    t.workpieces.push_back(std::move(p));
  }
  return t;
}

std::string_view to_string(SupportKind kind) {
  switch (kind) {
    case SupportKind::none:
      return "none";
    case SupportKind::gripper:
      return "gripper";
    case SupportKind::conveyor:
      return "conveyor";
    case SupportKind::machine:
      return "machine";
    case SupportKind::floor:
      return "floor";
    case SupportKind::workpiece:
      return "workpiece";
    case SupportKind::robot:
      return "robot";
    case SupportKind::other:
      return "other";
    case SupportKind::parked:
      return "parked";
  }
  return "?";
}

std::string_view to_string(MachineState state) {
  switch (state) {
    case MachineState::idle:
      return "idle";
    case MachineState::loaded:
      return "loaded";
    case MachineState::busy:
      return "busy";
    case MachineState::done:
      return "done";
  }
  return "?";
}

std::string_view to_string(FeedStatus status) {
  switch (status) {
    case FeedStatus::ok:
      return "ok";
    case FeedStatus::unknown_workpiece:
      return "unknown_workpiece";
    case FeedStatus::unknown_conveyor:
      return "unknown_conveyor";
    case FeedStatus::not_parked:
      return "not_parked";
    case FeedStatus::occupied:
      return "occupied";
  }
  return "?";
}

}  // namespace cellwright::twin::sim
