// WorldPlant: the MuJoCo World (twin/sim/world.hpp) as the runtime's Plant, with an optional workpiece feed.
//
//  - advance(dt) feeds the parts that are due (each FeedEvent at its time; a feed the World refuses because the
//    conveyor's entry is still occupied is retried every period until it succeeds), then steps the World by dt.
//  - truth() converts the World's truth: workpiece poses and linear velocities, present unless parked; robot joints;
//    between_fingers by the grip sensor's rule (runtime/grip_sensor.hpp) on the two finger pads' touch sensors: the
//    part whose box (grown by 1 cm) holds the tool centre point (the nearest, if several), else "". (The World's
//    held_by names one holder per part, but during a hand-over both hands hold it.)
//  - new_collisions() names the two bodies and the depth of the deepest contact; new_arrivals() lists the parts fed
//    since the last call, where = the conveyor.
//  - MuJoCo warnings are drained every advance and kept (warnings()): a run that raised any is suspect, and tests
//    fail on them.
//  - capture(camera) renders the World's camera offscreen (OSMesa), with a Renderer made on the first call, on the
//    calling thread, and freed by release_thread_resources() on the same thread (or by the destructor, which must then
//    run on that thread too).
//
// Threads: as Plant (plant.hpp); warnings() and feed_log() only while the simulation thread is not running.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cellwright/runtime/plant.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace cellwright::twin::sim {

struct FeedEvent {
  runtime::SimDuration time{0};
  std::string workpiece;  // parked in the World (WorldOptions::parked)
  std::string conveyor;
  // Moves and turns the part from the conveyor's entry point, in the conveyor's frame (x along the belt): a
  // scenario's perturbation.
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
};

class WorldPlant final : public runtime::Plant {
 public:
  // The World must outlive the plant. Feed events are sorted by time (stable: equal times keep their order).
  explicit WorldPlant(World& world, std::vector<FeedEvent> feed = {});

  void advance(runtime::SimDuration dt) override;
  runtime::Truth truth() const override;
  std::vector<runtime::Collision> new_collisions() override;
  std::vector<runtime::Arrival> new_arrivals() override;
  std::optional<runtime::Image> capture(const std::string& camera, std::string* why) override;
  void release_thread_resources() override;
  ~WorldPlant() override;

  // Every MuJoCo warning raised so far, as the World words them.
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  World& world_;
  std::vector<FeedEvent> feed_;
  std::size_t next_feed_ = 0;
  std::vector<runtime::Arrival> arrivals_;
  std::vector<std::string> warnings_;
  std::unique_ptr<Renderer> renderer_;  // made by capture() on the simulation thread
};

}  // namespace cellwright::twin::sim
