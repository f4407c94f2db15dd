// Plant: what the runtime's simulation thread steps. It is the physics side of the twin seen from the runtime: the
// MuJoCo World (twin/sim, adapted by WorldPlant in world_plant.hpp) or, in tests and benchmarks without
// MuJoCo, a ScriptedPlant (scripted_plant.hpp) that advances ScriptedDrivers.
//
// Every period the simulation thread calls advance(period), then new_collisions() and new_arrivals(), which it logs,
// and, in the period after a fault detection, truth(), whose physical state it logs for the report to judge the
// detection by. The controller learns nothing from the plant's truth: what it senses comes through the sensor port
// (sensors.hpp), which a simulated plant implements for the rig to wire (its sensors are read after advance()). The simulated robots' drivers are advanced by the plant inside
// advance() (a SimDriver by the World, a ScriptedDriver by the ScriptedPlant), so a command submitted by a
// robot-control thread starts at the next advance().
//
// Threads: the simulation thread calls every member, one call at a time. In lock-step mode no other participant
// runs meanwhile; in real-time mode robot-control threads call the drivers concurrently, which the drivers allow.
// Outside a run (before Runtime::run(), while Runtime::step() has returned, after the run) the caller may use the
// plant directly (e.g. render a snapshot of the World).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/runtime/clock.hpp"

namespace cellwright::runtime {

// One workpiece as the physics has it.
struct WorkpieceTruth {
  std::string name;                                        // the cell's workpiece name
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // centre of the part, world frame
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      // linear velocity of the centre, m/s, world frame
  bool present = true;  // false while a fed part has not arrived yet (or has been carried out of the cell)
};

// One robot as the physics has it.
// (The grip and the wrist force are what a simulated plant's sensors report, sensors.hpp's TruthSensors.)
struct RobotTruth {
  std::string name;            // the cell's robot name
  std::vector<double> joints;  // arm joints, base to tip (radians); empty if the plant cannot tell. For reports
                               // only: the controller learns where a robot is from its driver
  // The workpiece between the finger pads, touching both, when the plant can tell: a name, or "" for none.
  // nullopt when the plant has no way to know (then a close cannot be checked and is taken as done).
  std::optional<std::string> between_fingers;
  // The wrist force sensor: the force on the flange (N, world frame, the weight of the gripper and of what it holds
  // included), nullopt when the plant has none. The safety layer's force limit watches it (safety.hpp).
  std::optional<Eigen::Vector3d> wrist_force;
};

// An object in the cell that is not in the cell description (a tool left behind, a person's hand, a fallen box), as
// the cell's safety sensor (a 3D camera or laser scanner watching the working space) reports it: an axis-aligned box.
// Workpieces and robots are not obstacles.
struct Obstacle {
  std::string name;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // world, m
  Eigen::Vector3d size = Eigen::Vector3d::Zero();    // full extents, m
};

// The physics' state at one instant.
struct Truth {
  SimDuration time{0};
  std::vector<WorkpieceTruth> workpieces;
  std::vector<RobotTruth> robots;
  std::vector<Obstacle> obstacles;  // what the safety sensor sees now
};

// A camera picture: 8-bit BGR (blue, green, red per pixel), rows top first, no padding. A plain value, so that the
// runtime needs no image library; the vision library views it without copying.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bgr;  // width * height * 3 bytes

  bool empty() const { return bgr.empty(); }
};

// A contact that began between two bodies that should not touch (robot and robot, robot and cell), named by the
// bodies (e.g. "puma/link3" and "machine/mill").
struct Collision {
  std::string a, b;
  double depth = 0;  // penetration, metres (>= 0)
};

// A workpiece that came into the cell (fed on a conveyor) or reached a place, or, with `left`, one that left the cell
// (carried off the end of a conveyor that takes parts out of it), as the plant reports it.
struct Arrival {
  std::string workpiece;
  std::string where;  // e.g. the conveyor's name
  bool left = false;
};

class Plant {
 public:
  virtual ~Plant() = default;

  // Advances the physics (and the simulated controllers) by `dt` of simulation time. Never throws for anything a
  // robot or the physics did; a numerical failure shows as driver faults.
  virtual void advance(SimDuration dt) = 0;

  // The state now: for reports (the physical state after a detection, the final places), never for the controller.
  virtual Truth truth() const = 0;

  // Collisions that began since the previous call, in a fixed order (deterministic for a given run).
  virtual std::vector<Collision> new_collisions() = 0;

  // Arrivals since the previous call, in a fixed order.
  virtual std::vector<Arrival> new_arrivals() = 0;

  // An image of the plant now from its camera `camera` at that camera's resolution; nullopt when the plant has no such
  // camera or cannot render (the problem is in *why). Made on the calling thread, which is the simulation thread: a
  // rendering context lives there (see release_thread_resources). The default plant has no cameras.
  virtual std::optional<Image> capture(const std::string& camera, std::string* why) {
    if (why != nullptr) *why = "this plant has no cameras";
    (void)camera;
    return std::nullopt;
  }

  // Called by the simulation thread as it stops: frees what capture() made on it (an OpenGL context must be freed on
  // the thread that made it).
  virtual void release_thread_resources() {}
};

}  // namespace cellwright::runtime
