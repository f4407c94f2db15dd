// `twin agent --robot NAME [--driver KIND:PORT] --domain N SCENARIO` (docs/distributed.md): one robot of a scenario
// as a robot-control agent in a process of its own (distributed/agent.hpp), on its real driver: a Movemaster EX or a
// VAL II on a serial port (the project's emulators serve one on a pseudo-terminal), as `twin run` drives a real robot
// (cell/rig's real_drivers.hpp). The agent reads the same scenario as task control (the cell, the program, the
// bindings, the motion options and the control period), and builds, checks and homes its driver here, before it
// serves, so that a port that cannot be opened or a controller whose home is not the cell's is an error before task
// control sends anything (commissioning.hpp's bring_up_checked).
//
// Threads: construct on one thread; agent().serve() there, agent().request_stop() from any.
#pragma once

#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/cell/real_run.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/distributed/agent.hpp"
#include "cellwright/distributed/link.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"

namespace cellwright::cell {

struct ScenarioAgentOptions {
  double speed = 1.0;                  // simulation seconds per wall-clock second, as task control's --speed
  std::ostream* log_stream = nullptr;  // the agent's own copy of its events (JSONL), if set
};

class ScenarioAgent {
 public:
  // Throws InputError (nothing connected, or the driver disconnected again) when `robot` is not a cell robot the
  // program uses (a program label is named with the cell robot it is bound to), when its driver is the twin's (`sim`:
  // give it one with --driver KIND:PORT), when the driver cannot be connected or its bring-up cross-check fails.
  ScenarioAgent(const Scenario& scenario, const std::string& robot, distributed::Participant& participant,
                ScenarioAgentOptions options = {});
  ~ScenarioAgent();
  ScenarioAgent(const ScenarioAgent&) = delete;
  ScenarioAgent& operator=(const ScenarioAgent&) = delete;

  distributed::RobotAgent& agent() { return *agent_; }
  const RealRobot& robot() const { return robot_; }

 private:
  std::unique_ptr<drivers::SerialDriver> driver_;
  std::vector<std::unique_ptr<runtime::GripSensor>> grip_sensors_;
  RealRobot robot_;
  std::unique_ptr<distributed::RobotAgent> agent_;
};

}  // namespace cellwright::cell
