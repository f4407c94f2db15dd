// `twin run` of a cell of real robots with no twin (run_real.hpp).
#include "run_real.hpp"

#include <fmt/format.h>

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>

#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/real_run.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/streamed_log.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/distributed/link.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

int run_real_cell(const CLI::App& cmd, const RunArgs& a, const cell::Scenario& s, const cell::Preflight& pre,
                  double speed, bool quiet, const RemoteAgents* remote) {
  using namespace cellwright::cell;
  if (cmd.count("--camera") > 0) {
    throw InputError({"--camera", 0, 0}, "a camera's frames are for vision, and a run of real robots only has none "
                                         "(its perception is cad; docs/real-robots.md): leave it out");
  }
  for (const char* name : {"--video", "--save-frames", "--final-png", "--record-camera"}) {
    if (cmd.count(name) > 0) {
      throw InputError({name, 0, 0}, remote != nullptr
                                         ? "it needs the twin (a picture of the simulated cell), and a run whose robots "
                                           "are all agents (--agents remote) has no twin: leave it out"
                                         : "it needs the twin (a picture of the simulated cell), and this twin was "
                                           "built for real robots only (CW_SIM=OFF): leave it out");
    }
  }
  RealRunOptions options;
  options.speed = speed;
  if (a.perception == "truth") options.perception = runtime::Perception::kTruth;
  if (a.perception == "vision") options.perception = runtime::Perception::kVision;
  if (a.perception == "cad") options.perception = runtime::Perception::kCad;
  if (!quiet) {
    options.progress_every = std::chrono::seconds(5);
    options.on_progress = [](runtime::SimDuration t, std::uint64_t firings) {
      std::printf("t = %7.2f s  firings %4llu\n", std::chrono::duration<double>(t).count(),
                  static_cast<unsigned long long>(firings));
      std::fflush(stdout);
    };
  }
  block_stop_signals();  // a stop from now on ends the run safely (run_until_signal below), never mid-write
  // The event log goes to a file as it is written: into the output directory (events.jsonl at the end), else into
  // a temporary file. A run refused before it starts leaves nothing behind.
  std::optional<TemporaryFile> scratch;
  if (a.output.empty()) scratch.emplace("cellwright-events-", ".jsonl");
  StreamedLog log(a.output.empty() ? scratch->path() : streamed_events_file(a.output));
  options.log_stream = &log.stream();
  // --agents remote: every robot of the program on its agent, over DDS.
  std::optional<distributed::Participant> participant;
  std::optional<distributed::RemoteCell> agents;
  if (remote != nullptr) {
    participant.emplace(distributed::DdsOptions{.domain = remote->domain}, "cellwright_task_control");
    agents.emplace(*participant);
    for (const Binding& b : s.robots) options.remote_robots.push_back(b.name);
    options.attach_remote = agents->attach();
    // The run's clock runs at `speed` times the wall clock; the wait is given in wall-clock seconds.
    options.rejoin_wait = std::chrono::duration_cast<runtime::SimDuration>(
        std::chrono::duration<double, std::milli>(static_cast<double>(remote->rejoin_wait.count()) * speed));
  }
  std::optional<RealRun> run;
  try {
    run.emplace(s, pre.net, std::move(options));
    if (agents) {
      if (!quiet) {
        std::printf("waiting up to %.1f s for the agents of %zu robots on DDS domain %d\n",
                    static_cast<double>(remote->wait.count()) / 1000.0, s.robots.size(), remote->domain);
        std::fflush(stdout);
      }
      agents->wait_for_agents(remote->wait);  // InputError naming the robots whose agent is missing
    }
  } catch (...) {
    log.remove();
    throw;
  }
  if (!quiet) {
    const std::string pace = cmd.count("--speed") > 0 ? fmt::format(" x{:g}", speed) : std::string();
    const std::string robots = remote != nullptr ? fmt::format("robots on agents (DDS domain {})", remote->domain)
                                                 : std::string("real robots");
    std::printf("%s: %s on %s, %s without the twin, real time%s, perception cad\n", a.scenario.c_str(),
                s.program_file.filename().c_str(), s.cell.name.c_str(), robots.c_str(), pace.c_str());
    std::fflush(stdout);
  }
  // What the run uses, taken now: an emulator's pseudo-terminal may be gone by the end.
  RunSetup setup = setup_of(s);
  setup.perception = runtime::to_string(run->perception());
  setup.twin_truth = false;       // no twin: every detection no injection explains is an unexplained fault
  setup.parts_from_model = true;  // nothing saw the parts: where the controller believes them
  if (remote != nullptr) {
    for (DriverUse& d : setup.drivers) {
      d = DriverUse{d.robot, "agent", fmt::format("DDS domain {}", remote->domain), false};
    }
  }
  // Ctrl-C (or SIGTERM) stops the cell safely at the next period; the outputs so far are written below.
  run_until_signal([&] { run->run(); }, [&] { run->runtime().request_stop("stopped by the user (signal)"); });

  const Report report = log.report(run->runtime().log(), s, final_poses_of(run->model()), std::nullopt, setup);
  if (!a.output.empty()) {
    make_output_directory(a.output);
    log.move_into(a.output, run->runtime().log());
    write_report_outputs(a.output, s, report, cv::Mat());
  }
  std::printf("%s", format_summary(report).c_str());
  for (const RealRobot& r : run->robots()) {
    if (remote != nullptr) {
      std::printf("  %s: on its agent, DDS domain %d (its driver and sensing there)\n", r.robot.c_str(),
                  remote->domain);
    } else {
      std::printf("  %s (real %s, no twin): %s\n", r.robot.c_str(), r.driver.c_str(), describe_sensing(r).c_str());
    }
  }
  for (const RealDevice& d : run->devices()) {
    std::printf("  %s (real I/O, no twin): %s\n", d.device.c_str(), d.unit.c_str());
  }
  if (!a.output.empty()) std::printf("outputs in %s\n", a.output.c_str());
  return report.ok() ? 0 : 1;
}

}  // namespace cellwright::tools
