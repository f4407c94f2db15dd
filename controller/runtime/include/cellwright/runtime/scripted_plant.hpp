// ScriptedPlant: a Plant without physics, for tests, benchmarks and dry runs without MuJoCo. It advances
// ScriptedDrivers (drivers/scripted_driver.hpp) tick by tick and keeps a kinematic world: each robot's tool pose is
// the forward kinematics of its scripted joints; a closed gripper's pads touch whatever is there, and the part
// between the fingers is the one the twin's grip sensor would name (grip_sensor.hpp): it is attached to the tool and
// follows it; when the gripper opens the part stays where it was let go. There is no gravity, no contact and no
// collision. Its sensors (sensors()) are the twin's kinds: each robot's grip sensor (the part it holds, "" none), no
// wrist force (nullopt), the safety sensor (no obstacles) and the parts' truth, taken at the end of each advance().
//
// Threads: as Plant (plant.hpp). The drivers are advanced from advance() only.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/runtime/plant.hpp"
#include "cellwright/runtime/sensors.hpp"

namespace cellwright::runtime {

class ScriptedPlant final : public Plant {
 public:
  // `drivers`: the scripted driver of each cell robot, by name (not owned; they must outlive the plant); `tick` the
  // drivers' ScriptedDriverConfig::tick, which must divide every dt given to advance(). Arm joints are read from the
  // drivers, so their home_joints should be the cell's home. Throws InternalError for a name that is not a cell
  // robot or a tick that is not positive; InputError when a robot's URDF cannot be read.
  ScriptedPlant(const models::CellDescription& cell, std::map<std::string, drivers::ScriptedDriver*> drivers,
                SimDuration tick = std::chrono::milliseconds(1));

  void advance(SimDuration dt) override;
  Truth truth() const override;
  std::vector<Collision> new_collisions() override { return {}; }
  std::vector<Arrival> new_arrivals() override { return {}; }

  // The plant's sensors, for RunConfig::sensors (valid while the plant lives).
  Sensors sensors() { return sensors_.sensors(); }

  // Where workpiece `name` is now (its centre, world); InternalError if there is none.
  Eigen::Isometry3d workpiece_pose(const std::string& name) const;

 private:
  struct Robot {
    std::string name;
    drivers::ScriptedDriver* driver = nullptr;
    models::KinematicChain chain;
    Eigen::Isometry3d base;
    bool closed = false;
    std::optional<std::size_t> held;                                // workpiece index
    Eigen::Isometry3d held_offset = Eigen::Isometry3d::Identity();  // part pose in the tool frame
  };
  // Which robot a part follows: the one that grasped it last and still holds it.
  Eigen::Isometry3d tool_pose(const Robot& r) const;

  SimDuration tick_;
  SimDuration time_{0};
  std::vector<Robot> robots_;
  std::vector<std::string> names_;
  std::vector<Eigen::Vector3d> sizes_;
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<std::optional<std::size_t>> follows_;  // per workpiece: robot index
  TruthSensors sensors_;
};

}  // namespace cellwright::runtime
