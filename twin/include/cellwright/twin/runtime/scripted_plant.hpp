// ScriptedPlant: a Plant without physics, for tests, benchmarks and dry runs without MuJoCo. It advances
// ScriptedDrivers (drivers/scripted_driver.hpp) tick by tick and keeps a kinematic world: each robot's tool pose is
// the forward kinematics of its scripted joints; when a gripper closes, the part whose centre is within
// `grasp_radius` of the tool centre point is attached to the tool (it is then "between the fingers") and follows it;
// when the gripper opens the part stays where it was let go. There is no gravity, no contact and no collision.
//
// Threads: as Plant (plant.hpp). The drivers are advanced from advance() only.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/twin/cell.hpp"
#include "cellwright/twin/runtime/plant.hpp"

namespace cellwright::twin::runtime {

class ScriptedPlant final : public Plant {
 public:
  // `drivers`: the scripted driver of each cell robot, by name (not owned; they must outlive the plant). Every
  // driver's tick must divide the periods advance() is called with. Throws InternalError for a name that is not a
  // cell robot; InputError when a robot's URDF cannot be read.
  ScriptedPlant(const CellDescription& cell, std::map<std::string, drivers::ScriptedDriver*> drivers,
                double grasp_radius = 0.03);

  void advance(SimDuration dt) override;
  Truth truth() const override;
  std::vector<Collision> new_collisions() override { return {}; }
  std::vector<Arrival> new_arrivals() override { return {}; }

  // Where workpiece `name` is now (its centre, world); InternalError if there is none.
  Eigen::Isometry3d workpiece_pose(const std::string& name) const;

 private:
  struct Robot {
    std::string name;
    drivers::ScriptedDriver* driver = nullptr;
    models::KinematicChain chain;
    Eigen::Isometry3d base;
    bool closed = false;
    std::optional<std::size_t> held;                          // workpiece index
    Eigen::Isometry3d held_offset = Eigen::Isometry3d::Identity();  // part pose in the tool frame
  };
  Eigen::Isometry3d tool_pose(const Robot& r) const;

  double grasp_radius_;
  SimDuration time_{0};
  std::vector<Robot> robots_;
  std::vector<std::string> names_;
  std::vector<Eigen::Isometry3d> poses_;
};

}  // namespace cellwright::twin::runtime
