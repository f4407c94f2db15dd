// FaultInjector: the physical faults of docs/faults.md made to happen in the World, on purpose, seeded and
// deterministic; and NoisyDetector, the detection noise of the camera faults. WorldPlant (world_plant.hpp) owns the
// injector and calls it; ScenarioRun (scenario/run.hpp) puts both in place from the scenario's faults.
//
// WHAT EACH KIND DOES (the spec's fields: scenario/faults.hpp)
//  - drop: at the robot's `carry`-th carry (a carry begins when both its finger pads touch a part and ends when they
//    have not for 0.1 s), once `after` s have passed since it began and the part is in the air (held, its bottom more
//    than 5 mm above whatever is below it: a part still on its support waits until it is lifted), the robot's
//    SimDriver loses its grip force for 0.3 s (SimDriver::release_grip: fingers driven open); the part falls. Then
//    the fingers obey the last command again (they close on nothing).
//  - slip: at the same moment, once there is room for the slide below the part (distance + 5 mm), the part slides
//    `distance` m straight down between the pads over 0.05 s (5 control periods, moved by the simulation as friction
//    would let it slide), still touching both pads: the grip sensor goes on reporting it held, only its pose in the
//    hand changes. A slip stops early if the part is no longer held or has no room left below.
//  - misplace: a part fed later arrives moved by `offset` along its own x and y and turned by `yaw` degrees (the
//    sides and the sense drawn from the seed; the x side flipped when it would overlap a neighbour at the start); a
//    part in the cell at the start is moved so at t = 0.
//  - unreachable: the part arrives (or starts) upright on the floor beside its conveyor (or out from the robots, for a
//    part not on a conveyor), `distance` m out, on the side away from the robots, and further out until its grasp
//    point is more than 5 cm beyond every robot's reach (KinematicChain::max_reach from joint 1).
//  - missing: a fed part is never fed (reported when it was due); a part in the cell at the start is parked at t = 0.
//  - obstacle: from `time` on, at the first control period in which the robot's tool moves faster than 5 cm/s, a
//    cube of `size` m (the scene's obstacle body, SceneOptions) is put with its centre `ahead` m in front of the tool
//    along the tool's velocity, jittered by up to 1 cm across it (seeded), never into the floor; it stays `duration`
//    s, listed by obstacles(), then goes back under the floor. It collides with robots (World::new_collisions).
//  - frame_lost: the first `count` frames captured from `time` on are not delivered (lose_frame()).
//  - detection_noise: reported at `time`; NoisyDetector does the noise.
//  The driver faults and lost_signal are not injected here (ScenarioRun: FaultyDriver, and a signal filter on
// RunConfig::signal_filter).
// Each injection that happens is reported once (take()), when it happens, with the values in `detail`; a fault whose
// moment never comes (no n-th carry, the run ends first, the robot has no simulation driver) is never reported.
//
// DETERMINISM. Every random amount is drawn from the seed at construction, fault by fault in the list's order; the
// rest follows the World's state at the control periods, so a lock-step run gives the same injections every time.
//
// THREADS. The simulation thread (the WorldPlant's caller) calls every member; NoisyDetector::detect is called on the
// image-processing thread and reads only its own state and the frame time it is given.
#pragma once

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "cellwright/runtime/part_detector.hpp"
#include "cellwright/runtime/plant.hpp"
#include "cellwright/twin/faults.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "cellwright/twin/sim/world_plant.hpp"

namespace cellwright::twin::sim {

// How long a drop takes the grip force away.
inline constexpr std::chrono::nanoseconds kDropRelease = std::chrono::milliseconds(300);
// The tool speed from which an obstacle fault's robot counts as moving.
inline constexpr double kObstacleToolSpeed = 0.05;  // m/s

class FaultInjector {
 public:
  // The obstacle bodies a scene needs for `faults` (one per obstacle fault, in order): pass to build_scene.
  static SceneOptions scene_options(const std::vector<FaultSpec>& faults);

  // Keeps the faults of the kinds it injects (the others are ignored). `world` must outlive it and hold the obstacles
  // of scene_options(faults) (InternalError otherwise). Moves nothing yet.
  FaultInjector(World& world, std::vector<FaultSpec> faults, std::uint64_t seed);

  // Before the run (WorldPlant's constructor): a fed part's misplace/unreachable offset joins its feed event, a
  // missing fed part's event is taken out; parts in the cell at the start are moved or parked now.
  void prepare(std::vector<FeedEvent>& feed);
  // After every World::advance: follows carries and tool motions, injects what is due.
  void update();
  // `workpiece` was just fed: its misplacement, if any, is reported now.
  void fed(const std::string& workpiece);
  // Whether the frame the plant is about to capture at `now` is lost (frame_lost); reports the fault at its first.
  bool lose_frame(std::chrono::nanoseconds now);

  // The injections since the last call, in the order they happened.
  std::vector<InjectedFault> take();
  // The obstacles in the cell now (the safety sensor's view).
  std::vector<runtime::Obstacle> obstacles() const;

 private:
  struct Carry {
    int part = -1;  // workpiece index held, -1 when not carrying
    std::uint64_t count = 0;
    std::chrono::nanoseconds since{0}, last_held{0};
  };
  struct Active {
    FaultSpec spec;
    bool done = false;  // injected, or its moment has passed
    // drop, slip: armed at the spec's carry
    int part = -1;
    std::chrono::nanoseconds due{0};
    double slip_left = 0;  // slip: m still to slide
    // misplace: the drawn offset; obstacle: the drawn jitter across the motion (two unit amounts in [-1, 1])
    Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
    double jitter[2] = {0, 0};
    std::size_t obstacle = 0;  // index of its obstacle body
    std::optional<std::chrono::nanoseconds> placed;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    std::uint64_t frames_lost = 0;
    double margin = 0, moved = 0;  // unreachable: m beyond every robot's reach, m out from where it was
  };

  void report(const FaultSpec& f, std::string detail);
  std::size_t robot_index(const std::string& name) const;
  // The pose on the floor out of every robot's reach for a part now at `from`, and how far beyond reach it is.
  Eigen::Isometry3d out_of_reach(const std::string& workpiece, const Eigen::Isometry3d& from,
                                 const models::ConveyorSpec* conveyor, double distance, double* margin,
                                 double* moved) const;
  void update_carries(const WorldTruth& truth);
  void update_obstacle(Active& a, const WorldTruth& truth);

  World& world_;
  std::vector<Active> faults_;
  std::vector<Carry> carries_;                          // by robot index
  std::vector<std::optional<Eigen::Vector3d>> tcp_;     // by robot index: the tool's position at the last update
  std::optional<std::chrono::nanoseconds> last_update_;
  std::vector<InjectedFault> out_;
  bool needs_truth_ = false;
};

// A PartDetector that adds detection noise (docs/faults.md, kind detection_noise) to another's sightings: while the
// frame's time is in [time, time + duration) of one of its faults, each sighting's centre moves by a normal amount of
// standard deviation `sigma` m along world x and y, and its yaw (when it has one) by one of `sigma_yaw` degrees, each
// amount limited to 3 standard deviations. The amounts come from its own generator seeded with `seed`, drawn in frame
// and sighting order: the same frames give the same noise. `frame_time` says the simulation time of the frame being
// detected (the plant's last capture).
class NoisyDetector final : public runtime::PartDetector {
 public:
  NoisyDetector(std::shared_ptr<const runtime::PartDetector> inner, std::vector<FaultSpec> faults,
                std::uint64_t seed, std::function<runtime::SimDuration()> frame_time);

  std::vector<std::string> workpieces() const override { return inner_->workpieces(); }
  runtime::Sightings detect(const runtime::Image& image,
                            const std::vector<runtime::Prediction>& predictions) const override;

 private:
  double normal() const;  // a standard normal amount (Box-Muller on the engine's raw output), within [-3, 3]

  std::shared_ptr<const runtime::PartDetector> inner_;
  std::vector<FaultSpec> faults_;  // detection_noise only
  std::function<runtime::SimDuration()> frame_time_;
  mutable std::mt19937_64 rng_;  // detect() is called on one thread only
};

}  // namespace cellwright::twin::sim
