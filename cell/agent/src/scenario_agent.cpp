// One robot of a scenario as an agent (scenario_agent.hpp).
#include "cellwright/cell/scenario_agent.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <utility>

#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/real_drivers.hpp"
#include "cellwright/cell/run_wiring.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::cell {

ScenarioAgent::ScenarioAgent(const Scenario& s, const std::string& robot, distributed::Participant& participant,
                             ScenarioAgentOptions options) {
  const auto bound = std::find_if(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.name == robot; });
  if (bound == s.robots.end()) {
    std::vector<std::string> known;
    for (const Binding& b : s.robots) known.push_back(fmt::format("{} ({} in the program)", b.name, b.label));
    const auto label = std::find_if(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.label == robot; });
    throw InputError(SourceLocation{"--robot"},
                     label != s.robots.end()
                         ? fmt::format("'{}' is a label of program {}; the agent is named by its cell robot: --robot {}",
                                       robot, s.program_file.filename().string(), label->name)
                         : fmt::format("'{}' is not a robot that {} uses in {} (its robots: {})", robot,
                                       s.program_file.filename().string(), s.source.filename().string(),
                                       fmt::join(known, ", ")));
  }
  const auto choice = std::find_if(s.drivers.begin(), s.drivers.end(),
                                   [&](const DriverChoice& c) { return c.robot == robot; });
  if (choice == s.drivers.end() || !choice->real()) {
    // On the twin: its turns in a lock-step run, the twin's driver in the run's process.
    const runtime::RunConfig run = scenario_run_config(s, task::to_net(s.program));
    distributed::TurnAgentConfig config;
    config.program = s.program;
    config.cell = s.cell;
    config.binding = run.binding;
    config.robot = robot;
    config.motion = run.motion;
    config.period = run.period;
    config.perception = options.perception.value_or(s.perception);
    config.log_stream = options.log_stream;
    turn_agent_ = std::make_unique<distributed::TurnAgent>(participant, std::move(config));
    robot_ = {bound->label, robot, "the twin's robot (lock-step turns)", false};
    return;
  }
  const models::RobotSpec& spec = *s.cell.find_robot(robot);
  driver_ = make_real_driver(*choice, spec);
  connect_real_driver(*driver_, *choice);
  bring_up_checked(*driver_, *choice, spec);  // homes, reads and cross-checks: refuses here
  robot_ = {bound->label, robot,
            fmt::format("{} on {}", to_string(choice->kind), choice->serial ? choice->serial->port : ""),
            driver_->capabilities().senses_grip};

  const runtime::RunConfig run = scenario_run_config(s, task::to_net(s.program));
  distributed::AgentConfig config;
  config.program = s.program;
  config.cell = s.cell;
  config.binding = run.binding;
  config.robot = robot;
  config.driver = driver_.get();
  if (runtime::GripSensor* grip = runtime::grip_sensor_for(*driver_, nullptr, grip_sensors_)) {
    config.sensors.grip[robot] = grip;
  }
  config.motion = run.motion;
  config.period = run.period;
  config.speed = options.speed;
  config.log_stream = options.log_stream;
  agent_ = std::make_unique<distributed::RobotAgent>(participant, std::move(config));
}

ScenarioAgent::~ScenarioAgent() {
  agent_.reset();  // before the driver it steps
  if (driver_) driver_->disconnect();
}

}  // namespace cellwright::cell
