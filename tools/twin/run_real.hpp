// `twin run` of a cell of real robots with no twin (or of robots all on agents, `--agents remote`) (a `twin` built with CW_SIM=OFF, docs/real-robots.md): every robot
// of the program on its real driver (--driver ROBOT=movemaster|val2:PORT) and every device of the program on its
// Modbus unit (--device NAME=modbus:HOST:PORT or the scenario's `devices`), in real time, nothing simulated
// (cell/rig's RealRun). Writes what a simulated run writes with -o DIR but the final picture: events.jsonl,
// report.json, gantt.png and index.html, the parts where the controller's model has them, said so. Ctrl-C or SIGTERM
// stops the cell safely and writes the outputs so far.
#pragma once

#include <CLI/CLI.hpp>

#include <chrono>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "run_args.hpp"

namespace cellwright::tools {

// `twin run --agents remote --domain N`: every robot of the program is an agent in another process (`twin agent`,
// docs/distributed.md), found on DDS domain `domain` within `wait`.
struct RemoteAgents {
  int domain = 0;
  std::chrono::milliseconds wait{10000};
  // --rejoin-wait: how long (wall clock) a robot whose agent was lost waits for a new one; 0: the cell is stopped.
  std::chrono::milliseconds rejoin_wait{0};
};

// Runs scenario `s` (preflight's `pre` accepted) on its real robots. `cmd` is `twin run`'s command, whose options
// that need the twin (--video, --save-frames, --final-png) are refused when given. `speed`: --speed (simulation
// seconds per wall-clock second). Returns the exit code: 0 when the run finished and every expectation holds (as
// far as the controller's model can tell), 1 when not (a run stopped with Ctrl-C included). Throws InputError
// (nothing run, nothing left behind) as RealRun, or for a refused option.
// With `remote`, every robot of the program is an agent's (none is driven here) and the run refuses to start, naming
// the robots whose agent is missing, when they are not all there within remote->wait (InputError); the options that
// need the twin are refused as above, the twin having no robot to show.
int run_real_cell(const CLI::App& cmd, const RunArgs& args, const cell::Scenario& s, const cell::Preflight& pre,
                  double speed, bool quiet, const RemoteAgents* remote = nullptr);

}  // namespace cellwright::tools
