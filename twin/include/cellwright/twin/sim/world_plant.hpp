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
//  - Faults (docs/faults.md): given the scenario's faults, a FaultInjector (fault_injector.hpp) changes the feed and
//    the parts at the start when the plant is made, and after every World::advance injects what is due; capture()
//    delivers no frame while a frame_lost fault says so. The plant logs its injections itself (the runtime knows
//    nothing of them): at the end of every advance(), into the log given to log_injections_to(), as fault_injected
//    lines stamped with the plant's time (the sum of the dts advanced, which is the runtime's time of the period):
//    first the faults reported from other threads by report_fault() (the driver faults, in the order they were
//    reported, and the rig's own before the run), then the injector's. Without a log they wait for take_injected().
//    truth() lists the obstacles in the cell and each robot's wrist force (the World's wrist force sensor, turned
//    into the world frame).
//  - A coordinated carry (two robots holding one part): with a log, every advance() logs a `carry` event per part
//    two hands hold, measured by a CarryMeter (carry_meter.hpp) after the faults of the period, before the injections
//    are logged; only for the parts measure_carries_of() named (the workpieces of coordinated blocks: a hand-over,
//    where both hands hold a part for a moment, is no carry).
//  - sensors() are the twin's sensors for the runtime (runtime/sensors.hpp): each robot's grip sensor (between_fingers
//    above, named), its wrist force sensor, the safety sensor (the obstacles) and the parts' truth, all as truth() has
//    them at the end of the last advance().
//  - capture(camera) renders the World's camera offscreen (OSMesa), with a Renderer made on the first call, on the
//    calling thread, and freed by release_thread_resources() on the same thread (or by the destructor, which must then
//    run on that thread too).
//
// Threads: as Plant (plant.hpp); warnings() only while the simulation thread is not running; report_fault() and
// last_capture() from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "cellwright/runtime/event_log.hpp"
#include "cellwright/twin/sim/carry_meter.hpp"
#include "cellwright/runtime/plant.hpp"
#include "cellwright/runtime/sensors.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/faults.hpp"
#include "cellwright/twin/sim/belt_exit.hpp"
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

class FaultInjector;

// A fault injected on purpose (docs/faults.md), for the event log and the fault campaign only: the controller never
// reads it (it must find faults by what it senses).
struct InjectedFault {
  std::string kind;       // "drop", "slip", "misplace", "obstacle", "missing", "timeout", ... (docs/faults.md)
  std::string robot;      // cell robot it concerns, "" if none
  std::string workpiece;  // cell workpiece it concerns, "" if none
  std::string detail;     // what exactly was done, with the values
};

class WorldPlant final : public runtime::Plant {
 public:
  // The World must outlive the plant. Feed events are sorted by time (stable: equal times keep their order).
  // `faults` (the kinds the injector makes; others are ignored) need a World whose scene holds the obstacles of
  // FaultInjector::scene_options(faults); random amounts are drawn from `seed`.
  explicit WorldPlant(World& world, std::vector<FeedEvent> feed = {}, std::vector<FaultSpec> faults = {},
                      std::uint64_t seed = 1);

  void advance(runtime::SimDuration dt) override;
  runtime::Truth truth() const override;
  std::vector<runtime::Collision> new_collisions() override;
  std::vector<runtime::Arrival> new_arrivals() override;
  std::optional<runtime::Image> capture(const std::string& camera, std::string* why) override;
  void release_thread_resources() override;
  ~WorldPlant() override;

  // A shift of more parts than bodies (scenario Feed::count): a part carried to the `leave` point of one of these
  // conveyors (where parts fall off its end, or, with a stop, collect against it: its centre within 5 cm of the
  // point; the exact rule: belt_exit.hpp) has left the cell; it is parked out of the cell at once and reported by
  // new_arrivals() with `left`, and its body may be fed again. A feed event whose body is still in the cell (or will
  // never leave it: dropped on the floor) takes the next parked body of the feed instead; with none parked it waits
  // (and the events after it wait too). Call before the run.
  void recycle_at(std::vector<std::string> conveyors);

  // The workpieces whose carries by two robots are measured and logged (the parts coordinated blocks carry); none by
  // default. Call before the run.
  void measure_carries_of(std::vector<std::string> workpieces) { carried_ = std::move(workpieces); }

  // Every MuJoCo warning raised so far, as the World words them.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // A fault injected elsewhere (a FaultyDriver around a robot's driver, on its owner's thread; the rig's perturbation
  // before the run), logged at the end of the next advance(). Any thread.
  void report_fault(InjectedFault fault);
  // Where advance() logs the injections from now on (see the top); the log must outlive the plant's use. Call before
  // the run (the rig, once the Runtime that owns the log exists).
  void log_injections_to(runtime::EventLog* log) { log_ = log; }
  // The injections made so far and not logged (a plant with no log), in order. Simulation thread, or between runs.
  std::vector<InjectedFault> take_injected();
  // The twin's sensors, for RunConfig::sensors (valid while the plant lives).
  runtime::Sensors sensors() { return sensors_.sensors(); }
  // The simulation time of the last capture() (the frame image processing is detecting). Any thread.
  runtime::SimDuration last_capture() const { return runtime::SimDuration(last_capture_.load()); }

 private:
  World& world_;
  std::vector<FeedEvent> feed_;
  std::size_t next_feed_ = 0;
  std::vector<runtime::Arrival> arrivals_;
  std::vector<BeltExit> exits_;      // recycle_at(): the exit conveyors, their belts' frames fixed for the run
  std::vector<std::string> bodies_;  // recycle_at(): the fed bodies, in order of first arrival
  void take_out_delivered();
  runtime::Truth truth_of(const WorldTruth& w) const;
  CarryMeter carry_meter_;
  std::vector<std::string> carried_;  // measure_carries_of()
  std::vector<std::string> warnings_;
  std::unique_ptr<Renderer> renderer_;  // made by capture() on the simulation thread
  std::unique_ptr<FaultInjector> injector_;  // nullptr without faults
  std::mutex reported_mutex_;
  std::vector<InjectedFault> reported_;  // by report_fault(), under reported_mutex_
  std::vector<InjectedFault> injected_;  // not yet logged (no log)
  runtime::EventLog* log_ = nullptr;
  runtime::SimDuration elapsed_{0};  // the sum of the dts advanced
  runtime::TruthSensors sensors_;
  std::atomic<std::int64_t> last_capture_{0};     // ns
};

}  // namespace cellwright::twin::sim
