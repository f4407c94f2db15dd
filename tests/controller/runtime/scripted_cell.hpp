// A runtime fixture without MuJoCo: the paper's cell (scenes/cell.yaml) with ScriptedDrivers behind both arms and a
// ScriptedPlant carrying the parts kinematically, running a program from scenes/. Part A is put at the input
// conveyor's pick location (a scripted plant has no belts to bring it there).
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/runtime/scripted_plant.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::testing {

// Ticks (1 ms each) a scripted command takes: moves `move_ticks`, grips `grip_ticks`.
struct ScriptedTiming {
  std::uint64_t move_ticks = 120;
  std::uint64_t grip_ticks = 40;
  bool senses_grip = false;  // the double claims a gripper sensor of its own (ScriptedDriver::set_grip_sense)
};

inline const models::CellDescription& paper_cell() {
  static const models::CellDescription cell = [] {
    models::CellDescription c = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml");
    // Part A waits at the pick location, resting on the belt (centre half its height above the location).
    const models::LocationSpec* pick = c.find_location("input_pick");
    for (auto& w : c.workpieces) {
      if (w.name == "A") {
        w.pose.xyz = pick->pose.xyz + Eigen::Vector3d(0, 0, w.size.z() / 2);
        w.pose.rpy = Eigen::Vector3d::Zero();
      }
    }
    return c;
  }();
  return cell;
}

inline drivers::ScriptedDriverConfig scripted_arm(const models::RobotSpec& spec, ScriptedTiming timing) {
  drivers::ScriptedDriverConfig c;
  c.where = spec.where;
  c.capabilities.joints = spec.home.size();
  c.capabilities.joint_control = true;
  c.capabilities.gripper = true;
  c.capabilities.gripper_force = true;
  c.capabilities.gripper_max_width = 0.08;
  c.capabilities.gripper_max_force = 40;
  c.capabilities.max_joint_speed.assign(spec.home.size(), 2.0);
  c.capabilities.reads_joints = true;
  c.capabilities.queue_depth = 4;
  c.capabilities.senses_grip = timing.senses_grip;
  c.tick = std::chrono::milliseconds(1);
  c.home_ticks = 30;
  c.home_joints = spec.home;
  c.ticks_for = [timing](const drivers::Command& cmd) {
    return std::holds_alternative<drivers::Grip>(cmd) ? timing.grip_ticks : timing.move_ticks;
  };
  return c;
}

// Everything one run needs, owned together. r1/r2 of the program are bound to puma/melfa; location B to output_drop.
struct ScriptedCell {
  explicit ScriptedCell(const std::string& program = "exchange.task", std::map<std::string, ScriptedTiming> timing = {},
                        runtime::Mode mode = runtime::Mode::kLockstep) {
    const models::CellDescription& cell = paper_cell();
    for (const auto& r : cell.robots) {
      drivers.emplace(r.name, std::make_unique<drivers::ScriptedDriver>(scripted_arm(r, timing[r.name])));
    }
    std::map<std::string, drivers::ScriptedDriver*> raw;
    for (auto& [name, d] : drivers) raw[name] = d.get();
    plant = std::make_unique<runtime::ScriptedPlant>(cell, raw);

    config.program = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/" + program);
    config.net = task::to_net(config.program);
    config.cell = cell;
    config.binding.where = {"scenario.yaml", 1, 1};
    config.binding.robots["r1"] = {"puma", {"scenario.yaml", 5, 12}};
    config.binding.robots["r2"] = {"melfa", {"scenario.yaml", 5, 24}};
    if (std::find(config.program.locations.begin(), config.program.locations.end(), "B") !=
        config.program.locations.end()) {
      config.binding.objects["B"] = {"output_drop", {"scenario.yaml", 6, 10}};
    }
    for (auto& [name, d] : drivers) config.drivers[name] = d.get();
    config.plant = plant.get();
    config.sensors = plant->sensors();
    config.mode = mode;
    config.realtime_speed = 20.0;
    config.limits.sim_time = std::chrono::seconds(30);
  }

  drivers::ScriptedDriver& driver(const std::string& name) { return *drivers.at(name); }

  std::map<std::string, std::unique_ptr<drivers::ScriptedDriver>> drivers;
  std::unique_ptr<runtime::ScriptedPlant> plant;
  runtime::RunConfig config;
};

}  // namespace cellwright::testing
