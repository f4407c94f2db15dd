#include "cellwright/twin/sim/world_plant.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/grip_sensor.hpp"
#include "cellwright/twin/sim/fault_injector.hpp"
#include "cellwright/vision/cell_detector.hpp"

namespace cellwright::twin::sim {

WorldPlant::WorldPlant(World& world, std::vector<FeedEvent> feed, std::vector<FaultSpec> faults,
                       std::uint64_t seed)
    : world_(world), feed_(std::move(feed)) {
  std::stable_sort(feed_.begin(), feed_.end(), [](const FeedEvent& a, const FeedEvent& b) { return a.time < b.time; });
  if (!faults.empty()) {
    injector_ = std::make_unique<FaultInjector>(world_, std::move(faults), seed);
    injector_->prepare(feed_);
  }
  sensors_.update(truth());
}

void WorldPlant::recycle_at(std::vector<std::string> conveyors) {
  exits_.clear();
  for (const std::string& name : conveyors) {
    const models::ConveyorSpec* c = world_.scene().cell().find_conveyor(name);
    CW_CHECK(c != nullptr, "recycle_at: no conveyor '{}'", name);
    exits_.emplace_back(*c);
  }
  bodies_.clear();
  for (const FeedEvent& f : feed_) {
    if (std::find(bodies_.begin(), bodies_.end(), f.workpiece) == bodies_.end()) bodies_.push_back(f.workpiece);
  }
}

void WorldPlant::take_out_delivered() {
  const WorldTruth w = world_.truth();
  for (const WorkpieceTruth& p : w.workpieces) {
    if (p.parked) continue;
    for (const BeltExit& e : exits_) {
      if (e.left(p.pose.translation())) {
        world_.park(p.name);
        arrivals_.push_back({p.name, e.conveyor().name, true});
        break;
      }
    }
  }
}

void WorldPlant::report_fault(InjectedFault fault) {
  std::lock_guard lock(reported_mutex_);
  reported_.push_back(std::move(fault));
}

std::vector<InjectedFault> WorldPlant::take_injected() {
  std::vector<InjectedFault> out;
  out.swap(injected_);
  return out;
}

void WorldPlant::advance(runtime::SimDuration dt) {
  // Due parts first, in order; one still blocked by the part before it waits (and so do the ones behind it).
  while (next_feed_ < feed_.size() && feed_[next_feed_].time <= world_.now()) {
    FeedEvent& f = feed_[next_feed_];
    FeedResult r = world_.feed(f.workpiece, f.conveyor, f.offset);
    // A shift: a body still in the cell is replaced by the next parked one, in the feed's order.
    for (std::size_t b = 0; r.status == FeedStatus::not_parked && b < bodies_.size() && !exits_.empty(); ++b) {
      if (bodies_[b] == f.workpiece) continue;
      r = world_.feed(bodies_[b], f.conveyor, f.offset);
      if (r.status != FeedStatus::not_parked) f.workpiece = bodies_[b];
    }
    if (r.status == FeedStatus::occupied) break;
    if (r.status == FeedStatus::not_parked && !exits_.empty()) break;  // no body has left the cell yet
    CW_CHECK(r.ok(), "feeding {} onto {} at {} ns: {}", f.workpiece, f.conveyor, f.time.count(), r.message);
    arrivals_.push_back({f.workpiece, f.conveyor});
    if (injector_) injector_->fed(f.workpiece);
    ++next_feed_;
  }
  world_.advance(dt);
  if (!exits_.empty()) take_out_delivered();
  if (injector_) injector_->update();
  for (std::string& w : world_.drain_warnings()) warnings_.push_back(std::move(w));
  elapsed_ += dt;
  const WorldTruth w = world_.truth();
  runtime::Truth now = truth_of(w);
  if (log_ != nullptr && !carried_.empty()) {
    // A coordinated carry, measured every period while two hands hold one part (carry_meter.hpp).
    std::vector<CarryHand> hands;
    for (std::size_t r = 0; r < w.robots.size() && r < now.robots.size(); ++r) {
      hands.push_back({now.robots[r].name, w.robots[r].tcp, now.robots[r].between_fingers.value_or(""),
                       now.robots[r].wrist_force.value_or(Eigen::Vector3d::Zero())});
    }
    std::vector<CarryPart> parts;
    for (const WorkpieceTruth& p : w.workpieces) {
      if (p.parked || std::find(carried_.begin(), carried_.end(), p.name) == carried_.end()) continue;
      if (const models::WorkpieceSpec* spec = world_.scene().cell().find_workpiece(p.name)) {
        parts.push_back({p.name, p.pose, spec->size});
      }
    }
    for (const runtime::events::Carry& c : carry_meter_.measure(elapsed_, hands, parts)) log_->log(c);
  }
  sensors_.update(std::move(now));
  // The injections of this period, logged by the plant itself on the simulation thread (fixed order in lock-step).
  {
    std::lock_guard lock(reported_mutex_);
    for (InjectedFault& f : reported_) injected_.push_back(std::move(f));
    reported_.clear();
  }
  if (injector_) {
    for (InjectedFault& f : injector_->take()) injected_.push_back(std::move(f));
  }
  if (log_ != nullptr) {
    for (const InjectedFault& f : injected_) log_->fault_injected(elapsed_, f.kind, f.robot, f.workpiece, f.detail);
    injected_.clear();
  }
}

runtime::Truth WorldPlant::truth() const {
  return truth_of(world_.truth());
}

runtime::Truth WorldPlant::truth_of(const WorldTruth& w) const {
  runtime::Truth t;
  t.time = w.time;
  std::vector<runtime::PartBox> boxes;  // what a gripper may hold: the parts in the cell
  for (const WorkpieceTruth& p : w.workpieces) {
    t.workpieces.push_back({p.name, p.pose, p.linear_velocity, !p.parked});
    const models::WorkpieceSpec* spec = world_.scene().cell().find_workpiece(p.name);
    if (!p.parked && spec != nullptr) boxes.push_back({p.name, p.pose, spec->size});
  }
  for (std::size_t r = 0; r < w.robots.size(); ++r) {
    runtime::RobotTruth rt;
    rt.name = w.robots[r].name;
    rt.joints = w.robots[r].joints;
    // The World names one holder per part, but during a hand-over two hands hold it. So, as a real gripper would tell:
    // both pad touch sensors read a force, and the part is the one the tool centre point is inside of.
    const RobotTruth& robot = w.robots[r];
    const std::string held =
        runtime::part_between_fingers(robot.finger_contact[0], robot.finger_contact[1], robot.tcp.translation(), boxes);
    rt.between_fingers = held;
    // The wrist force sensor measures in its site's frame: turned into the world's.
    const RobotIds& ids = world_.scene().robots()[r];
    const mjtNum* x = world_.data()->site_xmat + 9 * ids.wrist_site;
    Eigen::Matrix3d rot;
    rot << x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8];
    rt.wrist_force = Eigen::Vector3d(rot * robot.wrist_force);
    t.robots.push_back(std::move(rt));
  }
  if (injector_) t.obstacles = injector_->obstacles();
  return t;
}

std::vector<runtime::Collision> WorldPlant::new_collisions() {
  std::vector<runtime::Collision> out;
  for (const Collision& c : world_.new_collisions()) out.push_back({c.body1, c.body2, c.depth});
  return out;
}

std::optional<runtime::Image> WorldPlant::capture(const std::string& camera, std::string* why) {
  last_capture_.store(world_.now().count());
  if (injector_ && injector_->lose_frame(world_.now())) {
    if (why != nullptr) *why = fmt::format("camera '{}' delivered no frame", camera);
    return std::nullopt;
  }
  const models::CameraSpec* spec = world_.scene().cell().find_camera(camera);
  const int id = world_.scene().camera_id(camera);
  if (spec == nullptr || id < 0) {
    if (why != nullptr) *why = fmt::format("the cell has no camera '{}'", camera);
    return std::nullopt;
  }
  try {
    if (!renderer_) {
      const mjModel* m = world_.scene().model();
      renderer_ = std::make_unique<Renderer>(m, m->vis.global.offwidth, m->vis.global.offheight);
    }
    // Vision quality: no shadows, reflections or skybox; a third of the full render's cost, same detections
    // (docs/vision.md).
    return vision::to_image(
        renderer_->render_camera(world_.render_data(), id, spec->width, spec->height, RenderQuality::kVision));
  } catch (const std::runtime_error& e) {
    if (why != nullptr) *why = fmt::format("camera '{}' cannot render: {}", camera, e.what());
    return std::nullopt;
  }
}

void WorldPlant::release_thread_resources() {
  renderer_.reset();
}

WorldPlant::~WorldPlant() = default;

std::vector<runtime::Arrival> WorldPlant::new_arrivals() {
  std::vector<runtime::Arrival> out;
  out.swap(arrivals_);
  return out;
}

}  // namespace cellwright::twin::sim
