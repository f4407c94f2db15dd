#include "cellwright/twin/sim/world_plant.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/grip_sensor.hpp"
#include "cellwright/vision/cell_detector.hpp"

namespace cellwright::twin::sim {

WorldPlant::WorldPlant(World& world, std::vector<FeedEvent> feed) : world_(world), feed_(std::move(feed)) {
  std::stable_sort(feed_.begin(), feed_.end(), [](const FeedEvent& a, const FeedEvent& b) { return a.time < b.time; });
}

void WorldPlant::advance(runtime::SimDuration dt) {
  // Due parts first, in order; one still blocked by the part before it waits (and so do the ones behind it).
  while (next_feed_ < feed_.size() && feed_[next_feed_].time <= world_.now()) {
    const FeedEvent& f = feed_[next_feed_];
    const FeedResult r = world_.feed(f.workpiece, f.conveyor, f.offset);
    if (r.status == FeedStatus::occupied) break;
    CW_CHECK(r.ok(), "feeding {} onto {} at {} ns: {}", f.workpiece, f.conveyor, f.time.count(), r.message);
    arrivals_.push_back({f.workpiece, f.conveyor});
    ++next_feed_;
  }
  world_.advance(dt);
  for (std::string& w : world_.drain_warnings()) warnings_.push_back(std::move(w));
}

runtime::Truth WorldPlant::truth() const {
  const WorldTruth w = world_.truth();
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
    t.robots.push_back(std::move(rt));
  }
  return t;
}

std::vector<runtime::Collision> WorldPlant::new_collisions() {
  std::vector<runtime::Collision> out;
  for (const Collision& c : world_.new_collisions()) out.push_back({c.body1, c.body2, c.depth});
  return out;
}

std::optional<runtime::Image> WorldPlant::capture(const std::string& camera, std::string* why) {
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
