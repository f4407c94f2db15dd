// The dry run for hardware bring-up (`twin run SCENARIO --driver melfa=movemaster:PORT --dry`, docs/real-robots.md):
// for every robot of the program on a real driver, connect, home, read the position, cross-check the read-back against
// the project's kinematics and the cell's home (commissioning.hpp), and check every target of the program without
// moving anything else.
//
// The targets are the program's moves as the runtime would make them, planned on the cell description (the
// preflight's motion plan, Preflight::plan from plan_motions: parts at their stops, held parts moving with the
// hand). Each is checked:
//  - against the project's kinematics of the robot (a joint configuration within the limits reaches it), and
//  - against what the controller can be told: the Movemaster's x,y,z,p,r must express it (the 5-axis rule, with the
//    driver's yaw tolerance); VAL II locations express every pose.
// Neither controller has a reach query that this project knows of (docs/real-robots.md), so the controller's own
// opinion of a target is only had by moving to it, which a dry run does not do.
//
// Robots on the sim driver are listed and left alone.
//
// Every device on real I/O (Scenario::devices, DeviceChoice::real) is checked on its Modbus unit: the unit is
// connected (one connection per HOST:PORT/UNIT) and each of the device's inputs read (a machine's busy and done, a
// photo-eye's input) and a conveyor's run coil read back; no output is written. A unit that cannot be reached or a
// read that fails is the device's problem, naming the unit. Devices on the twin's I/O are not listed.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

struct DryTarget {
  std::string command;     // "move above(A)"
  std::string source;      // the task-level command: "exchange.task:8:3 'Pick A'"
  std::string controller;  // what the controller would be sent: "MP 250.0,0.0,180.0,-90.0,0.0", "TRANS(...)"
  std::string problem;     // "" when the target can be reached and expressed
};

struct DryRobot {
  std::string label, robot;  // program label, cell robot
  std::string driver;        // "movemaster /dev/ttyUSB0", "sim"
  bool real = false;
  bool homed = false;
  std::optional<drivers::PositionReading> position;  // after homing
  std::string problem;                               // a step that failed: connect, home, read
  CrossCheck check;                                  // the read-back against the kinematics and the home
  std::vector<DryTarget> targets;
};

// One device on real I/O and what its unit answered.
struct DryDevice {
  std::string device;  // cell device name
  std::string unit;    // "modbus 127.0.0.1:1502 unit 1"
  struct Read {
    std::string what;  // "busy (input 2)", "run (coil 0)"
    bool value = false;
  };
  std::vector<Read> reads;  // every input of the device, and a conveyor's run coil, as read
  std::string problem;      // "" when the unit was reached and every read answered
};

struct DryRunReport {
  std::vector<DryRobot> robots;
  std::vector<DryDevice> devices;  // the devices on real I/O, in the cell's order
  // Every real robot homed, read and cross-checked, every target of theirs without a problem; every real device read.
  bool ok() const;
};

struct DryRunOptions {
  std::chrono::nanoseconds home_timeout = std::chrono::seconds(60);
  std::chrono::nanoseconds read_timeout = std::chrono::seconds(5);
};

// Runs the dry run. `preflight` is preflight(scenario, ...), passed (its plan is what is checked). Throws InputError
// when a real driver cannot be made or connected (the port does not exist, the controller does not answer), naming the
// driver's place and the problem. A device's unit that cannot be reached is no exception: its DryDevice's problem.
DryRunReport dry_run(const Scenario& scenario, const Preflight& preflight, const DryRunOptions& options = {});

// The report as text: per robot, what was done and each target with its verdict; per real device, its unit and what
// was read.
std::string format_dry_run(const DryRunReport& report);

}  // namespace cellwright::cell
