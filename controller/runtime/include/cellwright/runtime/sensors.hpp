// The runtime's sensor port (as ros2_control's SensorInterface): what the controller learns of the cell besides its
// drivers' position read-backs and its camera. The rig wires the sensors (RunConfig::sensors): a simulated cell's come
// from the twin (its World's finger pad touch sensors, wrist force sensors, safety sensor and part truth: twin/sim's
// WorldPlant; in tests the ScriptedPlant's), a real cell's from its robots' drivers and I/O. The runtime reads the
// sensors, never the plant's truth, to update the environment model; a sensor not wired is a sensor the cell does
// not have ("cannot tell"), which the controller handles as such (robot_control.hpp: a close whose grip cannot be
// sensed is taken as done).
//
//  grip     per cell robot: what is between the finger pads. GripReading below; nullopt = cannot tell now.
//  force    per cell robot: the wrist force sensor (N, world frame, the gripper's and its load's weight included);
//           nullopt = cannot tell now. The safety layer's force limit watches it (safety.hpp).
//  safety   the cell's safety sensor (a 3D camera or laser scanner watching the working space): the objects it sees
//           that are not in the cell description (Obstacle, plant.hpp); the safety layer's distance check uses them.
//  parts    the parts' presence, pose and motion (for Perception kTruth and kCad, environment_model.hpp: a perfect
//           part sensor, or the cell's presence sensors); nullptr = none: the model keeps what it knows of the parts.
//
// WHO CALLS WHEN. The simulation thread reads every wired sensor once per control period (after the plant, if any,
// has advanced: the readings are those at the end of the period, stamped with its time), in a fixed order (parts,
// safety, then per cell robot in the cell's order grip and force), and writes them into the environment model. With
// no plant it does the same (a cell of real robots). Nothing else calls a sensor during a run.
//
// THREADS. A sensor is read on the simulation thread only, while robot-control threads (and a real driver's
// communication thread) run: a read must be short, must not block, and returns the latest value the sensor holds
// (a driver's sensor is a reading its communication thread keeps, never a request to the controller). Sensors must
// outlive the Runtime; they are not owned.
#pragma once

#include <Eigen/Geometry>

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/runtime/plant.hpp"

namespace cellwright::runtime {

// What a grip sensor tells when it can tell.
struct GripReading {
  bool on_part = false;  // the fingers are on something: both pads touch, or the jaws stopped before shutting
  // The part between them when the sensor can name it (the twin's), "" when it cannot (a real jaw switch knows only
  // "closed on something") or when on_part is false.
  std::string part;

  // Nothing between the fingers (open, or closed on nothing).
  static GripReading nothing() { return {}; }
  // Part `name` between the fingers; "" for nothing.
  static GripReading of(std::string name) { return {!name.empty(), std::move(name)}; }
  // Whether the fingers are on `name`, as far as the sensor can tell (a sensor that cannot name parts: on anything).
  bool holds(std::string_view name) const { return on_part && (part.empty() || part == name); }
  // What the log and messages call it: the part, "something" for an unnamed one, "" for nothing.
  std::string describe() const { return !on_part ? std::string() : part.empty() ? std::string("something") : part; }
  bool operator==(const GripReading& o) const { return on_part == o.on_part && part == o.part; }
};

class GripSensor {
 public:
  virtual ~GripSensor() = default;
  // What is between the fingers now; nullopt when the sensor cannot tell now.
  virtual std::optional<GripReading> read_grip() = 0;
};

class ForceSensor {
 public:
  virtual ~ForceSensor() = default;
  // The force on the flange now (N, world frame); nullopt when the sensor cannot tell now.
  virtual std::optional<Eigen::Vector3d> read_force() = 0;
};

class SafetySensor {
 public:
  virtual ~SafetySensor() = default;
  // The objects in the cell now that are not in the cell description (workpieces and robots are not obstacles).
  virtual std::vector<Obstacle> read_obstacles() = 0;
};

// One part as the part sensor has it.
struct PartReading {
  std::string name;                                        // the cell's workpiece name
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // centre of the part, world frame
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      // m/s, world frame
  bool present = true;  // false while a fed part has not arrived yet (or has left the cell)
};

class PartSensor {
 public:
  virtual ~PartSensor() = default;
  // Every part the sensor knows of, now.
  virtual std::vector<PartReading> read_parts() = 0;
};

// The sensors the rig wires into a run (not owned). A robot missing from `grip` or `force` has no such sensor.
struct Sensors {
  std::map<std::string, GripSensor*> grip;    // by cell robot name
  std::map<std::string, ForceSensor*> force;  // by cell robot name
  SafetySensor* safety = nullptr;             // nullptr: no safety sensor (no obstacles are ever known)
  PartSensor* parts = nullptr;                // nullptr: no part sensor
};

// A gripper's own sensor as its driver reads it (drivers::RobotDriver::grip_sense(): a real controller's jaw switch,
// or a test double's): "closed on something" names no part. Wire it only for a driver whose
// capabilities().senses_grip is true. The driver must outlive the sensor.
class DriverGripSensor final : public GripSensor {
 public:
  explicit DriverGripSensor(const drivers::RobotDriver& driver) : driver_(driver) {}
  std::optional<GripReading> read_grip() override;

 private:
  const drivers::RobotDriver& driver_;
};

// The rig's rule for the grip sensor of a robot on `driver` (a real robot's, or a real robot mirrored in the twin):
// its driver's own sensor (a DriverGripSensor, made and kept in `owned`) when capabilities().senses_grip, else
// `twin` (the twin copy's sensor, or nullptr: none, "cannot tell").
GripSensor* grip_sensor_for(const drivers::RobotDriver& driver, GripSensor* twin,
                            std::vector<std::unique_ptr<GripSensor>>& owned);

// The sensors of a simulated plant, served from the plant's truth taken at the end of each advance() (the plant calls
// update()): each robot's grip (RobotTruth::between_fingers) and wrist force, the safety sensor's obstacles, and the
// parts. A sensor whose truth cannot tell (nullopt) reads nullopt. Used by the ScriptedPlant and the twin's WorldPlant.
// Threads: update() and the reads on the simulation thread; sensors() before the run.
class TruthSensors final : public SafetySensor, public PartSensor {
 public:
  // Takes the state now (the plant's constructor, then every advance()).
  void update(Truth truth);
  // Every robot of the last update with a grip and a force sensor, the safety and the part sensor. The pointers stay
  // valid while this object lives (robots are added by update(), never removed).
  Sensors sensors();

  std::vector<Obstacle> read_obstacles() override { return truth_.obstacles; }
  std::vector<PartReading> read_parts() override;

 private:
  struct Robot final : GripSensor, ForceSensor {
    const TruthSensors* owner = nullptr;
    std::string name;
    const RobotTruth* truth() const;
    std::optional<GripReading> read_grip() override;
    std::optional<Eigen::Vector3d> read_force() override;
  };
  Truth truth_;
  std::map<std::string, Robot> robots_;
};

}  // namespace cellwright::runtime
