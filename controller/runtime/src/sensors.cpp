#include "cellwright/runtime/sensors.hpp"

namespace cellwright::runtime {

std::optional<GripReading> DriverGripSensor::read_grip() {
  const std::optional<drivers::GripSense> s = driver_.grip_sense();
  if (!s) return std::nullopt;
  switch (*s) {
    case drivers::GripSense::open:
    case drivers::GripSense::closed_empty:
      return GripReading::nothing();
    case drivers::GripSense::closed_on_part:
      return GripReading{true, ""};
  }
  return std::nullopt;
}

GripSensor* grip_sensor_for(const drivers::RobotDriver& driver, GripSensor* twin,
                            std::vector<std::unique_ptr<GripSensor>>& owned) {
  if (!driver.capabilities().senses_grip) return twin;
  owned.push_back(std::make_unique<DriverGripSensor>(driver));
  return owned.back().get();
}

void TruthSensors::update(Truth truth) {
  truth_ = std::move(truth);
  for (const RobotTruth& r : truth_.robots) {
    Robot& robot = robots_[r.name];
    robot.owner = this;
    robot.name = r.name;
  }
}

Sensors TruthSensors::sensors() {
  Sensors s;
  for (auto& [name, robot] : robots_) {
    s.grip[name] = &robot;
    s.force[name] = &robot;
  }
  s.safety = this;
  s.parts = this;
  return s;
}

std::vector<PartReading> TruthSensors::read_parts() {
  std::vector<PartReading> out;
  out.reserve(truth_.workpieces.size());
  for (const WorkpieceTruth& w : truth_.workpieces) out.push_back({w.name, w.pose, w.velocity, w.present});
  return out;
}

const RobotTruth* TruthSensors::Robot::truth() const {
  for (const RobotTruth& r : owner->truth_.robots) {
    if (r.name == name) return &r;
  }
  return nullptr;
}

std::optional<GripReading> TruthSensors::Robot::read_grip() {
  const RobotTruth* r = truth();
  if (r == nullptr || !r->between_fingers) return std::nullopt;
  return GripReading::of(*r->between_fingers);
}

std::optional<Eigen::Vector3d> TruthSensors::Robot::read_force() {
  const RobotTruth* r = truth();
  return r == nullptr ? std::nullopt : r->wrist_force;
}

}  // namespace cellwright::runtime
