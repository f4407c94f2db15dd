// `twin agent --robot NAME [--driver KIND:PORT] --domain N SCENARIO` (docs/distributed.md): one robot of a scenario
// as a robot-control agent in a process of its own (distributed/agent.hpp), on its real driver: a Movemaster EX or a
// VAL II on a serial port (the project's emulators serve one on a pseudo-terminal), as `twin run` drives a real robot
// (cell/rig's real_drivers.hpp). The agent reads the same scenario as task control (the cell, the program, the
// bindings, the motion options and the control period), and builds, checks and homes its driver here, before it
// serves, so that a port that cannot be opened or a controller whose home is not the cell's is an error before task
// control sends anything (commissioning.hpp's bring_up_checked).
//
// A robot on the twin's simulated driver (the scenario's `sim`, no --driver) is an agent of a lock-step run with the
// twin (distributed/turn_link.hpp): its robot control takes its turns here and drives the twin's robot through the
// run's process; nothing is connected here. Its perception is the run's (`perception`, the scenario's by default).
//
// Threads: construct on one thread; agent().serve() there, agent().request_stop() from any.
#pragma once

#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/cell/real_run.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/distributed/agent.hpp"
#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/turn_link.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"

namespace cellwright::cell {

struct ScenarioAgentOptions {
  double speed = 1.0;                  // simulation seconds per wall-clock second, as task control's --speed
  std::ostream* log_stream = nullptr;  // the agent's own copy of its events (JSONL), if set
  std::optional<runtime::Perception> perception;  // a robot on the twin: the run's perception (default the scenario's)
};

class ScenarioAgent {
 public:
  // Throws InputError (nothing connected, or the driver disconnected again) when `robot` is not a cell robot the
  // program uses (a program label is named with the cell robot it is bound to), when the driver cannot be connected or
  // its bring-up cross-check fails.
  ScenarioAgent(const Scenario& scenario, const std::string& robot, distributed::Participant& participant,
                ScenarioAgentOptions options = {});
  ~ScenarioAgent();
  ScenarioAgent(const ScenarioAgent&) = delete;
  ScenarioAgent& operator=(const ScenarioAgent&) = delete;

  // Whether the robot is on the twin (a lock-step agent: turn_agent()) or on its real driver (agent()).
  bool on_twin() const { return turn_agent_ != nullptr; }
  distributed::RobotAgent& agent() { return *agent_; }
  distributed::TurnAgent& turn_agent() { return *turn_agent_; }
  const RealRobot& robot() const { return robot_; }

 private:
  std::unique_ptr<drivers::SerialDriver> driver_;
  std::vector<std::unique_ptr<runtime::GripSensor>> grip_sensors_;
  RealRobot robot_;
  std::unique_ptr<distributed::RobotAgent> agent_;
  std::unique_ptr<distributed::TurnAgent> turn_agent_;
};

}  // namespace cellwright::cell
