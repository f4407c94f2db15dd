#include "cellwright/runtime/scripted_plant.hpp"
#include "cellwright/models/robot_model.hpp"

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/grip_sensor.hpp"

namespace cellwright::runtime {

ScriptedPlant::ScriptedPlant(const models::CellDescription& cell,
                             std::map<std::string, drivers::ScriptedDriver*> drivers, SimDuration tick)
    : tick_(tick) {
  CW_CHECK(tick.count() > 0, "scripted plant tick {} ns must be positive", tick.count());
  for (const auto& [name, driver] : drivers) {
    const models::RobotSpec* spec = cell.find_robot(name);
    CW_CHECK(spec != nullptr, "scripted plant: '{}' is not a robot of the cell", name);
    CW_CHECK(driver != nullptr, "scripted plant: no driver for '{}'", name);
    robots_.push_back(
        Robot{name, driver, models::robot_chain(*spec), spec->base.transform(), false, {}, {}});
  }
  for (const models::WorkpieceSpec& w : cell.workpieces) {
    names_.push_back(w.name);
    sizes_.push_back(w.size);
    poses_.push_back(w.pose.transform());
  }
  follows_.resize(names_.size());
  sensors_.update(truth());
}

Eigen::Isometry3d ScriptedPlant::tool_pose(const Robot& r) const {
  const std::vector<double> q = r.driver->joints();
  return r.base * r.chain.forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
}

void ScriptedPlant::advance(SimDuration dt) {
  CW_CHECK(dt.count() >= 0 && dt.count() % tick_.count() == 0,
           "scripted plant: dt {} ns is not a multiple of the "
           "tick {} ns",
           dt.count(), tick_.count());
  const auto ticks = static_cast<std::uint64_t>(dt.count() / tick_.count());
  for (Robot& r : robots_) r.driver->advance(ticks);
  time_ += dt;
  for (std::size_t i = 0; i < robots_.size(); ++i) {
    Robot& r = robots_[i];
    const bool closed = r.driver->gripper_closed();
    if (closed && !r.closed) {
      // Closing: the pads close on the part the grip sensor's rule names.
      const Eigen::Isometry3d tcp = tool_pose(r);
      std::vector<PartBox> boxes;
      for (std::size_t w = 0; w < poses_.size(); ++w) boxes.push_back({names_[w], poses_[w], sizes_[w]});
      const std::string name = part_between_fingers(true, true, tcp.translation(), boxes);
      for (std::size_t w = 0; w < names_.size(); ++w) {
        if (!name.empty() && names_[w] == name) r.held = w;
      }
      if (r.held) {
        r.held_offset = tcp.inverse() * poses_[*r.held];
        follows_[*r.held] = i;
      }
    } else if (!closed && r.closed && r.held) {
      const std::size_t w = *r.held;
      r.held.reset();
      if (follows_[w] == i) {
        follows_[w].reset();
        for (std::size_t j = 0; j < robots_.size(); ++j) {
          if (robots_[j].held == w) follows_[w] = j;  // another hand still holds it
        }
      }
    }
    r.closed = closed;
  }
  for (std::size_t w = 0; w < poses_.size(); ++w) {
    if (!follows_[w]) continue;
    const Robot& r = robots_[*follows_[w]];
    poses_[w] = tool_pose(r) * r.held_offset;
  }
  sensors_.update(truth());
}

Truth ScriptedPlant::truth() const {
  Truth t;
  t.time = time_;
  for (std::size_t w = 0; w < poses_.size(); ++w) t.workpieces.push_back({names_[w], poses_[w], {0, 0, 0}, true});
  for (const Robot& r : robots_) {
    RobotTruth rt;
    rt.name = r.name;
    rt.joints = r.driver->joints();
    rt.between_fingers = r.held ? names_[*r.held] : std::string();
    t.robots.push_back(std::move(rt));
  }
  return t;
}

Eigen::Isometry3d ScriptedPlant::workpiece_pose(const std::string& name) const {
  for (std::size_t w = 0; w < names_.size(); ++w) {
    if (names_[w] == name) return poses_[w];
  }
  CW_CHECK(false, "scripted plant: no workpiece '{}'", name);
  return {};
}

}  // namespace cellwright::runtime
