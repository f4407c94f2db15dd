// The sensor port (sensors.hpp): the runtime learns what is between a robot's fingers from the grip sensor the rig
// wires, not from the plant's truth. A robot with no grip sensor has its closes taken as done; a robot whose driver
// senses its grip (a real robot, mirrored in the twin) is judged by its driver's sensor, whatever its twin copy holds.
#include "cellwright/runtime/sensors.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::ScriptedCell;
using cellwright::testing::ScriptedTiming;
using ::testing::HasSubstr;

// The sensor lines of robot `robot`'s close commands: their conditions, in order.
std::vector<std::string> close_conditions(const EventLog& log, const std::string& robot) {
  std::vector<std::string> out;
  for (const std::string& line : log.lines()) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] != "sensor" || e["robot"] != robot) continue;
    const std::string c = e["condition"];
    if (c == "gripped" || c == "closed_on_nothing" || c == "closed_on_wrong_part" || c == "grip_not_sensed") {
      out.push_back(c + (e["workpiece"].get<std::string>().empty() ? "" : " " + e["workpiece"].get<std::string>()));
    }
  }
  return out;
}

RecoveryOptions without_recovery() {
  RecoveryOptions o;
  o.enabled = false;
  return o;
}

TEST(RuntimeSensors, TheTwinsGripSensorNamesThePartGripped) {
  ScriptedCell cell;
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason;
  EXPECT_EQ(close_conditions(rt.log(), "r1"), std::vector<std::string>{"gripped A"});
}

TEST(RuntimeSensors, ARobotWithNoGripSensorHasItsCloseTakenAsDone) {
  // The plant's truth still knows what puma holds; the rig wired no grip sensor for it (a real robot whose driver
  // cannot tell): robot control cannot check the close, and says so.
  ScriptedCell cell;
  cell.config.sensors.grip.erase("puma");
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason;
  EXPECT_EQ(close_conditions(rt.log(), "r1"), std::vector<std::string>{"grip_not_sensed A"});
  EXPECT_EQ(close_conditions(rt.log(), "r2"), std::vector<std::string>{"gripped A"});  // melfa's is still wired
}

TEST(RuntimeSensors, AGripSensorReadFromTheDriverDecidesOverTheTwinCopy) {
  // puma is a real robot mirrored in the twin: its twin copy (the scripted plant) closes on A, while the real
  // gripper's own sensor reports the jaws shut on nothing. The rig wires the real side's sensor: a failed grip.
  ScriptedCell cell("exchange.task", {{"puma", ScriptedTiming{120, 40, true}}});
  cell.driver("puma").set_grip_sense(drivers::GripSense::closed_empty);
  std::vector<std::unique_ptr<GripSensor>> owned;
  cell.config.sensors.grip["puma"] =
      grip_sensor_for(*cell.config.drivers.at("puma"), cell.config.sensors.grip.at("puma"), owned);
  cell.config.motion.recovery = without_recovery();
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFailed);
  EXPECT_THAT(r.reason, HasSubstr("closed on nothing (expected A)"));
  EXPECT_EQ(close_conditions(rt.log(), "r1"), std::vector<std::string>{"closed_on_nothing"});
  // ... though the twin's copy holds A: the truth the report judges by says so.
  for (const RobotTruth& t : cell.plant->truth().robots) {
    if (t.name == "puma") {
      EXPECT_EQ(t.between_fingers, std::optional<std::string>("A"));
    }
  }
}

TEST(RuntimeSensors, AJawSwitchThatFeelsSomethingGripsThePartExpected) {
  // The real gripper's sensor can tell "closed on something" but not what: the part the command expected.
  ScriptedCell cell("exchange.task", {{"puma", ScriptedTiming{120, 40, true}}});
  cell.driver("puma").set_grip_sense(drivers::GripSense::closed_on_part);
  std::vector<std::unique_ptr<GripSensor>> owned;
  cell.config.sensors.grip["puma"] = grip_sensor_for(*cell.config.drivers.at("puma"), nullptr, owned);
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason;
  EXPECT_EQ(close_conditions(rt.log(), "r1"), std::vector<std::string>{"gripped A"});
}

TEST(RuntimeSensors, ADriverThatCannotSenseItsGripKeepsTheTwinCopysSensor) {
  ScriptedCell cell;  // the scripted drivers claim no gripper sensor
  GripSensor* twin = cell.config.sensors.grip.at("puma");
  std::vector<std::unique_ptr<GripSensor>> owned;
  EXPECT_EQ(grip_sensor_for(*cell.config.drivers.at("puma"), twin, owned), twin);
  EXPECT_TRUE(owned.empty());
  EXPECT_EQ(grip_sensor_for(*cell.config.drivers.at("puma"), nullptr, owned), nullptr);
}

TEST(RuntimeSensors, ADriverGripSensorReadsCannotTellUntilTheDriverCan) {
  ScriptedCell cell("exchange.task", {{"puma", ScriptedTiming{120, 40, true}}});
  DriverGripSensor sensor(cell.driver("puma"));
  EXPECT_FALSE(sensor.read_grip().has_value());
  cell.driver("puma").set_grip_sense(drivers::GripSense::open);
  EXPECT_EQ(sensor.read_grip(), std::optional(GripReading::nothing()));
  cell.driver("puma").set_grip_sense(drivers::GripSense::closed_on_part);
  ASSERT_TRUE(sensor.read_grip().has_value());
  EXPECT_TRUE(sensor.read_grip()->holds("A"));
  EXPECT_EQ(sensor.read_grip()->describe(), "something");
}

}  // namespace
}  // namespace cellwright::runtime
