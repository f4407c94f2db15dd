// One robot's control as an agent in a process of its own (`twin agent`, docs/distributed.md): the paper's robot
// control "as a remote brain", the same RobotControl the runtime runs as a thread, in front of the robot's driver,
// linked to task control over DDS.
//
//   task control (twin run --agents remote) ── command/status (link.hpp) ── RobotAgent ── RobotControl ── driver
//                                           <── model updates, events (replica.hpp) ──
//                                 other agents <── model updates ──> (each agent reads the others')
//
// The agent keeps its own environment model (the cell description's, Perception::kCad: held parts move with the
// hand), writes its robot's read-backs and holds into it as robot control does in one process, publishes each step's
// changes and applies the other robots' updates between its steps (so that robot control sees the cell as in one
// process, and a step's changes are its own). Its event log (robot control's events) goes to task control's log.
//
// Time: robot control runs on simulation time, which task control's run starts. The agent's clock starts at the time
// task control sent the first command (MotionCommand::sent) and then runs at `speed` times the wall clock, so its
// statuses and events are stamped on task control's time (to within the link's latency). Until that command the
// robot is not stepped (its bring-up, homing included, is its owner's: cell/rig's ScenarioAgent homes and cross-checks
// it before it serves).
//
// One agent serves one run: serve() waits for task control, steps robot control every period (and whenever the driver
// or a command wakes it) until task control leaves (its process ended: its endpoints unmatched), is lost (its
// liveliness lapsed: killed, its host down, the network cut; found within about DdsOptions::lease, before its matches
// go) or request_stop(); then it halts the robot (driver stop()) and flushes what it still has to send (without
// waiting for a lost task control's acknowledgements).
//
// Not done (docs/distributed.md): coordinated blocks (their board is shared memory in one process: a segment fails,
// naming it), lock-step, the machines of a program with devices (their fixtures as targets).
//
// Threads: construct and serve() on one thread; request_stop() from any thread (a signal watcher).
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <ostream>
#include <string>

#include "cellwright/distributed/link.hpp"
#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/runtime/sensors.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed {

struct AgentConfig {
  task::CompiledProgram program;
  models::CellDescription cell;
  runtime::Binding binding;
  std::string robot;                      // cell robot name (the topics')
  drivers::RobotDriver* driver = nullptr;  // not owned, connected or not (connect() is called); outlives the agent
  runtime::Sensors sensors;                // the robot's (its grip sensor, if any); not owned
  runtime::MotionOptions motion;
  runtime::SimDuration period = std::chrono::milliseconds(10);
  double speed = 1.0;                    // simulation seconds per wall-clock second
  std::ostream* log_stream = nullptr;    // the agent's events are also written here (JSONL), if set
};

// What a served run did.
struct AgentSummary {
  bool task_control_came = false;
  bool ended_by_stop = false;      // request_stop(), not task control leaving
  std::string task_control_lost;   // why, when task control was lost (AgentEndpoint::task_control_lost); else empty
  std::uint64_t commands = 0;      // commands taken
  std::uint64_t updates_applied = 0;  // other robots' model updates applied
  Refusals refusals;               // samples refused (commands and others' updates), the last reason
  std::string phase;               // robot control's phase at the end
};

class RobotAgent {
 public:
  // Checks the configuration: InputError when `robot` is not a cell robot bound in the program (naming the program's
  // robots) or the binding is wrong (runtime::resolve_names). Creates the DDS endpoints; moves nothing.
  RobotAgent(Participant& participant, AgentConfig config);
  ~RobotAgent();
  RobotAgent(const RobotAgent&) = delete;
  RobotAgent& operator=(const RobotAgent&) = delete;

  const std::string& label() const;  // the robot's program label
  std::size_t index() const;         // its program index

  // Serves one run (see the top). Throws InputError when the driver cannot be connected, or when task control has not
  // come within `wait` (naming the domain).
  AgentSummary serve(std::chrono::milliseconds wait);
  void request_stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::distributed
