// `twin agent SCENARIO --robot NAME [--driver KIND:PORT] --domain N [--speed X] [--wait SECONDS]`: one robot of the
// scenario as a robot-control agent in this process, linked to task control (`twin run SCENARIO --agents remote
// --domain N`) over DDS (cell/agent's ScenarioAgent; docs/distributed.md). Serves one run: exit 0 when task control came
// and the run ended (task control left), 1 when the robot's control failed, 3 when task control was lost (its
// liveliness lapsed: killed, its host down, the network cut; the robot halted), 130 when stopped with Ctrl-C, 2 on bad
// input, a driver that cannot be brought up, or no task control within --wait.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/scenario_agent.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/distributed/link.hpp"
#include "commands.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

constexpr int kTaskControlLost = 3;  // the exit code when task control's liveliness lapsed

void add_agent(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "agent",
      "Run one robot's control as an agent in this process, on its real driver, for task control elsewhere (twin run "
      "SCENARIO --agents remote --domain N) over DDS. Serves one run. Exit 0 when the run ended, 1 when the robot's "
      "control failed, 3 when task control was lost (no sign of life from it for the liveliness lease: the robot is "
      "halted), 2 on bad input or when no task control came within --wait.");
  struct Args {
    std::string scenario, robot, driver;
    std::optional<int> domain;
    double speed = 1.0;
    double wait = 60.0;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("scenario", args->scenario, "the scenario task control runs (its cell, program and bindings)")
      ->required();
  cmd->add_option("--robot", args->robot, "the cell robot this agent drives (e.g. puma)")->required();
  cmd->add_option("--driver", args->driver,
                  "its driver, KIND:PORT (movemaster:PORT or val2:PORT, with the line settings `twin run --driver` "
                  "takes); default: the scenario's");
  cmd->add_option("--domain", args->domain, "the DDS domain of the cell (0..232), as task control's")->required();
  cmd->add_option("--speed", args->speed,
                  "simulation seconds per wall-clock second, as task control's --speed (above 1 only against "
                  "emulated controllers run as fast)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--wait", args->wait, "seconds to wait for task control (default 60)")->check(CLI::PositiveNumber);
  cmd->callback([run, args] {
    *run = [args] {
      cell::Scenario s = cell::load_scenario(args->scenario);
      if (!args->driver.empty() && s.cell.find_robot(args->robot) != nullptr) {
        cell::set_driver(s, args->robot + "=" + args->driver, {"--driver", 0, 0});
      }
      block_stop_signals();  // a stop from now on halts the robot (run_until_signal below)
      distributed::Participant participant({.domain = *args->domain}, "cellwright_agent_" + args->robot);
      cell::ScenarioAgentOptions options;
      options.speed = args->speed;
      cell::ScenarioAgent agent(s, args->robot, participant, options);
      std::printf("agent %s (%s in %s): %s, DDS domain %d: waiting for task control\n", args->robot.c_str(),
                  agent.robot().label.c_str(), s.program_file.filename().c_str(), agent.robot().driver.c_str(),
                  *args->domain);
      std::fflush(stdout);
      distributed::AgentSummary summary;
      bool stopped = false;
      run_until_signal(
          [&] {
            summary = agent.agent().serve(std::chrono::milliseconds(static_cast<long long>(args->wait * 1000)));
          },
          [&] {
            stopped = true;
            agent.agent().request_stop();
          });
      std::printf("agent %s: %llu commands, %llu updates of the other robots applied, %llu samples refused%s; robot "
                  "control %s%s\n",
                  args->robot.c_str(), static_cast<unsigned long long>(summary.commands),
                  static_cast<unsigned long long>(summary.updates_applied),
                  static_cast<unsigned long long>(summary.refusals.count),
                  summary.refusals.last.empty() ? "" : fmt::format(" (last: {})", summary.refusals.last).c_str(),
                  summary.phase.empty() ? "not started" : summary.phase.c_str(),
                  stopped ? ", stopped by the user (signal)" : "");
      if (stopped) return kInterrupted;
      if (!summary.task_control_lost.empty()) {
        std::printf("agent %s: task control lost: %s; the robot was halted\n", args->robot.c_str(),
                    summary.task_control_lost.c_str());
        std::fflush(stdout);
        return kTaskControlLost;
      }
      return summary.phase == "failed" ? 1 : 0;
    };
  });
}

}  // namespace cellwright::tools
