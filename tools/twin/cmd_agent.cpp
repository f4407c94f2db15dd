// `twin agent SCENARIO --robot NAME [--driver KIND:PORT] --domain N [--speed X] [--wait SECONDS] [--perception P]`:
// one robot of the scenario as a robot-control agent in this process, linked to task control (`twin run SCENARIO
// --agents remote --domain N`) over DDS (cell/agent's ScenarioAgent; docs/distributed.md): on its real driver (real
// time), or, on the twin's simulated driver, taking its turns of a lock-step run with the twin. Serves one run: exit 0
// when task control came and the run ended (task control left, or sent its end), 1 when the robot's control failed, 3
// when task control was lost (no sign of life from it for the lease: killed, its host down, the network cut; a robot
// on a real driver is halted) or a lock-step run's messages could not be taken, 130 when stopped with Ctrl-C, 2 on bad
// input, a driver that cannot be brought up, or no task control within --wait.
#include <fmt/format.h>

#include <algorithm>
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
      "Run one robot's control as an agent in this process, for task control elsewhere (twin run SCENARIO --agents "
      "remote --domain N) over DDS: on its real driver (--driver, real time), or on the twin's robot in a lock-step run "
      "(no --driver, the scenario's sim driver). Serves one run. Exit 0 when the run ended, 1 when the robot's control "
      "failed, 3 when task control was lost (no sign of life from it for the lease: a real robot is halted), 2 on bad "
      "input or when no task control came within --wait.");
  struct Args {
    std::string scenario, robot, driver;
    std::optional<int> domain;
    double speed = 1.0;
    double wait = 60.0;
    std::string perception;
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
  cmd->add_option("--perception", args->perception,
                  "a robot on the twin: the run's perception, as its --perception (default the scenario's)")
      ->check(CLI::IsMember({"truth", "vision", "cad"}));
  cmd->callback([run, args, cmd] {
    *run = [args, cmd] {
      cell::Scenario s = cell::load_scenario(args->scenario);
      if (!args->driver.empty() && s.cell.find_robot(args->robot) != nullptr) {
        cell::set_driver(s, args->robot + "=" + args->driver, {"--driver", 0, 0});
      }
      block_stop_signals();  // a stop from now on halts the robot (run_until_signal below)
      distributed::Participant participant({.domain = *args->domain}, "cellwright_agent_" + args->robot);
      cell::ScenarioAgentOptions options;
      options.speed = args->speed;
      if (args->perception == "truth") options.perception = runtime::Perception::kTruth;
      if (args->perception == "vision") options.perception = runtime::Perception::kVision;
      if (args->perception == "cad") options.perception = runtime::Perception::kCad;
      // Whether the robot is the twin's (the scenario gives it no real driver): checked before anything connects.
      const auto choice = std::find_if(s.drivers.begin(), s.drivers.end(),
                                       [&](const cell::DriverChoice& c) { return c.robot == args->robot; });
      const bool on_twin = choice == s.drivers.end() || !choice->real();
      if (on_twin && cmd->count("--speed") > 0) {
        throw InputError({"--speed", 0, 0}, fmt::format("robot '{}' is on the twin, whose lock-step run sets the pace: "
                                                        "--speed is for an agent on a real driver (--driver)",
                                                        args->robot));
      }
      if (!on_twin && cmd->count("--perception") > 0) {
        throw InputError({"--perception", 0, 0}, "it is for a robot on the twin (an agent on a real driver perceives "
                                                 "with its own sensors: perception cad)");
      }
      cell::ScenarioAgent agent(s, args->robot, participant, options);
      std::printf("agent %s (%s in %s): %s, DDS domain %d: waiting for task control\n", args->robot.c_str(),
                  agent.robot().label.c_str(), s.program_file.filename().c_str(), agent.robot().driver.c_str(),
                  *args->domain);
      std::fflush(stdout);
      const auto wait = std::chrono::milliseconds(static_cast<long long>(args->wait * 1000));
      if (agent.on_twin()) {
        distributed::TurnAgentSummary summary;
        bool stopped = false;
        run_until_signal([&] { summary = agent.turn_agent().serve(wait); },
                         [&] {
                           stopped = true;
                           agent.turn_agent().request_stop();
                         });
        std::printf("agent %s: %llu turns, %llu driver calls, %llu samples refused%s; robot control %s%s%s\n",
                    args->robot.c_str(), static_cast<unsigned long long>(summary.turns),
                    static_cast<unsigned long long>(summary.calls),
                    static_cast<unsigned long long>(summary.refusals.count),
                    summary.refusals.last.empty() ? "" : fmt::format(" (last: {})", summary.refusals.last).c_str(),
                    summary.phase.empty() ? "not started" : summary.phase.c_str(),
                    stopped ? ", stopped by the user (signal)" : "",
                    summary.error.empty() ? "" : fmt::format("; ended early: {}", summary.error).c_str());
        if (stopped) return kInterrupted;
        if (summary.phase == "failed") return 1;
        return summary.error.empty() ? 0 : kTaskControlLost;
      }
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
