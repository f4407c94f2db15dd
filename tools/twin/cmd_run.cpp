// `twin run <scenario.yaml> [-o DIR] [--realtime] [--quiet] [--perception truth|vision|cad] [--save-frames DIR]
// [--driver ROBOT=KIND[:PORT]]... [--fault SPEC]... [--seed N] [--allow-collisions]
// [--video FILE.mp4 [--video-fps N] [--video-size WxH]] [--ros-domain N] [--dry]` (the options but --realtime, --quiet,
// --ros-domain and --dry shared with `twin step`: run_args.hpp): run a scenario's task program on the simulated cell
// (or with some robots real, mirrored in the twin), headless, and judge the outcome. Exit 0 when the run finished and
// every expected outcome holds, 1 when not, 2 on bad input or a predicted collision (refused before any thread starts,
// nothing written). In a twin built for real robots only (CW_SIM=OFF), every robot of the program on a real driver,
// with no twin (run_real.hpp); with the simulator, real robots are mirrored in the twin (docs/real-robots.md says why).
#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "cellwright/cell/dry_run.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/petri/analysis.hpp"
#include "commands.hpp"
#include "run_args.hpp"
#include "run_real.hpp"
#include "simulator.hpp"
#include "until_signal.hpp"
#if CW_SIM
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/distributed/ros_publisher.hpp"
#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/distributed/turn_link.hpp"
#endif

namespace cellwright::tools {

namespace {

#if CW_SIM
using runtime::SimDuration;

// The progress line: sim time, firings and what each robot is doing. Robot commands are taken from the runtime's view
// between steps (main thread) and printed by the simulation thread's progress callback, hence the mutex.
class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet), tty_(isatty(STDOUT_FILENO) == 1) {}

  bool tty() const { return tty_; }
  // How often (sim time) the callback prints: often on a terminal (the line is overwritten), every few seconds in a
  // log.
  SimDuration every() const { return tty_ ? std::chrono::milliseconds(200) : std::chrono::seconds(5); }

  void set_robots(const std::vector<runtime::RobotView>& robots) {
    std::string s;
    for (const auto& r : robots) {
      s += fmt::format("  {}: {}", r.robot,
                       r.done ? std::string("done") : fmt::format("{} {}", runtime::to_string(r.activity), r.command));
    }
    std::lock_guard lock(mutex_);
    robots_ = std::move(s);
  }

  void print(SimDuration t, std::uint64_t firings) {
    if (quiet_) return;
    std::string robots;
    {
      std::lock_guard lock(mutex_);
      robots = robots_;
    }
    const std::string line =
        fmt::format("t = {:7.2f} s  firings {:4}{}", std::chrono::duration<double>(t).count(), firings, robots);
    if (tty_) {
      // Overwrite the previous line; pad so a shorter line leaves nothing behind.
      std::printf("\r%-*s", static_cast<int>(std::max(width_, line.size())), line.c_str());
      width_ = line.size();
    } else {
      std::printf("%s\n", line.c_str());
    }
    std::fflush(stdout);
  }

  // Ends an overwritten line before other output.
  void finish() {
    if (!quiet_ && tty_ && width_ > 0) std::printf("\n");
    width_ = 0;
  }

 private:
  const bool quiet_, tty_;
  std::mutex mutex_;
  std::string robots_;
  std::size_t width_ = 0;
};

#endif  // CW_SIM

}  // namespace

void add_run(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("run",
                                 "Run a scenario's task program on the simulated cell, headless. Writes events.jsonl, "
                                 "report.json, gantt.png, final.png and index.html with -o. Exit 0 only if the run "
                                 "finished and every expected outcome holds; 1 if not (a run stopped with Ctrl-C "
                                 "included); 2 on bad input or a predicted collision.");
  struct Args {
    RunArgs run;
    bool realtime = false;
    double speed = 1.0;
    bool quiet = false;
    bool dry = false;
    std::string final_png = "always";
    std::optional<int> ros_domain;
    std::string agents = "local";
    std::optional<int> domain;
    double agent_wait = 10.0;
    double rejoin_wait = 0.0;
    bool no_twin = false;
  };
  auto args = std::make_shared<Args>();
  add_run_options(*cmd, args->run);
  cmd->add_flag("--realtime", args->realtime, "pace the simulation to the wall clock instead of lock-step");
  cmd->add_option("--speed", args->speed,
                  "with --realtime: simulation seconds per wall-clock second (default 1); above 1 only against "
                  "emulated controllers run as fast (twin emulate --scenario ... --speed X), never real arms")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--quiet", args->quiet, "no progress line");
  cmd->add_option("--final-png", args->final_png,
                  "with -o: when to render final.png, the cell at the end: always (default), failed (only when the "
                  "run fails: what `twin test` asks of its runs, whose passing outputs are removed) or never (what "
                  "`twin campaign` asks of its runs); without it the page says no final snapshot was made")
      ->check(CLI::IsMember({"always", "failed", "never"}));
  cmd->add_option("--ros-domain", args->ros_domain,
                  "publish the run for ROS 2 on this DDS domain (0..232): rt/joint_states, rt/tf, rt/tf_static, "
                  "rt/clock (simulation time) and the events on rt/cellwright/events, at most 50 times a second "
                  "(docs/distributed.md); off by default")
      ->check(CLI::Range(0, 232));
  cmd->add_flag("--dry", args->dry,
                "hardware bring-up: connect the real drivers, home, read positions and check every target of the "
                "program, and read every input of each device on real I/O; nothing else moves and no output is "
                "written. Exit 0 when all is well, 1 when not");
  cmd->add_option("--agents", args->agents,
                  "where robot control runs: local (threads of this process, the default), remote (an agent per "
                  "robot, twin agent --robot NAME --domain N SCENARIO, found over DDS: lock-step turns on the "
                  "twin's robots, or in real time the agents' real robots, followed by the twin here) or, in "
                  "lock-step, remote:ROBOT[,ROBOT...] (those robots on agents, the others here)")
      ->check([](const std::string& v) {
        return v == "local" || v == "remote" || v.rfind("remote:", 0) == 0
                   ? std::string()
                   : std::string("local, remote or remote:ROBOT[,ROBOT...] (those robots on agents, the others here)");
      });
  cmd->add_option("--domain", args->domain, "with --agents remote: the DDS domain of the cell's agents (0..232)");
  cmd->add_option("--agent-wait", args->agent_wait,
                  "with --agents remote: seconds to wait for every robot's agent before refusing to start (default 10)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--rejoin-wait", args->rejoin_wait,
                  "with --agents remote: seconds (wall clock) a robot whose agent was lost with work in hand waits "
                  "for a new agent (twin agent started again), which is re-homed and sent the interrupted command; "
                  "0 (the default): the cell is stopped at once")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-twin", args->no_twin,
                "with --agents remote in real time: task control alone, the twin not following the agents' robots "
                "(as in a twin built for real robots only: no --video or final.png, parts where the controller's "
                "model has them)");
  cmd->callback([run, args, cmd] {
    *run = [args, cmd] {
      using namespace cellwright::cell;
      // A bring-up runs no program: an option for a run's outputs or pace would be ignored, so it is refused.
      for (const char* name : {"--output", "--out", "--video", "--save-frames", "--realtime", "--speed", "--final-png",
                               "--camera", "--record-camera", "--ros-domain"}) {
        if (args->dry && cmd->count(name) > 0) {
          throw InputError({"--dry", 0, 0},
                           fmt::format("a bring-up runs no program and writes nothing: {} would be ignored", name));
        }
      }
      const RunArgs& a = args->run;
      const bool remote = args->agents.rfind("remote", 0) == 0;
      if (remote && !args->domain) {
        throw InputError({"--agents", 0, 0}, "remote agents are found on a DDS domain: give it with --domain N (the "
                                             "one their twin agent ... --domain N was given)");
      }
      for (const char* name : {"--domain", "--agent-wait", "--rejoin-wait", "--no-twin"}) {
        if (!remote && cmd->count(name) > 0) {
          throw InputError({name, 0, 0}, "it is for remote agents: add --agents remote (robot control runs in this "
                                         "process otherwise)");
        }
      }
      if (remote && args->dry) {
        throw InputError({"--dry", 0, 0}, "a bring-up connects the drivers here, and with --agents remote they are the "
                                          "agents': run twin commission or twin run --dry on each agent's host");
      }
      if (a.output.empty() && cmd->count("--final-png") > 0) {
        throw InputError({"--final-png", 0, 0}, "it chooses what -o DIR gets, and without -o nothing is written");
      }
      Scenario s = load_scenario_with(a);
      check_speed_for_real_arms(s, args->speed);
      // --agents remote:ROBOT,...: those robots on agents, the program's others here.
      std::vector<std::string> on_agents;
      if (args->agents == "remote") {
        for (const Binding& b : s.robots) on_agents.push_back(b.name);
      } else if (remote) {
        std::string list = args->agents.substr(std::string("remote:").size());
        for (std::size_t at = 0; at <= list.size();) {
          const std::size_t comma = std::min(list.find(',', at), list.size());
          const std::string robot = list.substr(at, comma - at);
          if (std::none_of(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.name == robot; })) {
            std::vector<std::string> names;
            for (const Binding& b : s.robots) names.push_back(b.name);
            throw InputError({"--agents", 0, 0}, fmt::format("'{}' is no robot of the program (its cell robots: {})",
                                                             robot, fmt::join(names, ", ")));
          }
          if (std::find(on_agents.begin(), on_agents.end(), robot) != on_agents.end()) {
            throw InputError({"--agents", 0, 0}, fmt::format("robot '{}' is named twice", robot));
          }
          on_agents.push_back(robot);
          at = comma + 1;
        }
      }
      const Preflight pre = preflight(s, simulator());
      if (!pre.ok(a.allow_collisions)) {
        std::fprintf(stderr, "%s: refused, nothing was run:\n", a.scenario.c_str());
        for (const std::string& p : pre.problems) std::fprintf(stderr, "  %s\n", p.c_str());
        if (!pre.collisions.empty() && pre.ok(true)) std::fprintf(stderr, "  (--allow-collisions runs it anyway)\n");
        if (!pre.analysis.ok()) {
          std::fprintf(stderr, "%s: %s", s.program_file.string().c_str(),
                       petri::format_report(pre.net, pre.analysis).c_str());
        }
        return 2;
      }
      for (const std::string& c : pre.collisions) {
        std::fprintf(stderr, "%s: warning: predicted collision (--allow-collisions): %s\n", a.scenario.c_str(),
                     c.c_str());
      }

      if (args->dry) {
        if (!uses_real_drivers(s) && !uses_real_devices(s)) {
          throw InputError({"--dry", 0, 0},
                           "a dry run is for real drivers and devices, and every robot and device of the program is "
                           "simulated: give one with --driver ROBOT=movemaster:PORT or val2:PORT, or --device "
                           "NAME=modbus:HOST:PORT");
        }
        const DryRunReport dry = dry_run(s, pre);
        std::printf("%s", format_dry_run(dry).c_str());
        return dry.ok() ? 0 : 1;
      }

#if CW_SIM
      constexpr bool kTwinHere = true;
#else
      constexpr bool kTwinHere = false;  // a twin for real robots only
#endif
      // Remote agents with the twin: a lock-step run whose robots take their turns in their agents (turn_link.hpp).
      // Real time (--realtime, --speed, or a scenario that asks for it), or no twin here: task control only, the
      // agents on their real drivers.
#if CW_SIM
      const bool remote_turns = remote && !args->realtime && cmd->count("--speed") == 0 &&
                                !run_options_for(a, s).realtime.value_or(s.options.realtime);
#else
      constexpr bool remote_turns = false;
#endif
      if (remote && !remote_turns && on_agents.size() != s.robots.size()) {
        throw InputError({"--agents", 0, 0},
                         "some robots on agents and some here is for lock-step runs (the twin's robots taking their "
                         "turns): in real time every robot of the program is on its agent (--agents remote), since "
                         "the twin follows an agent's robot one motion behind and a robot here would meet a lagging "
                         "copy at a hand-over");
      }
      if (remote_turns && args->no_twin) {
        throw InputError({"--no-twin", 0, 0}, "a lock-step run with agents takes their turns on the twin's robots: "
                                              "add --realtime for task control alone with agents on real drivers");
      }
      // Remote agents in real time, on their real drivers: the twin here follows their robots from their replicated
      // states (ScenarioRun's followed robots), unless --no-twin or there is no twin here.
      const bool remote_followed = remote && !remote_turns && kTwinHere && !args->no_twin;
      if (args->ros_domain && ((remote && !remote_turns) || !kTwinHere)) {
        throw InputError({"--ros-domain", 0, 0},
                         "the run is published for ROS 2 from the twin's run in this process; a run without the twin "
                         "(remote agents in real time, real robots only) is not published yet");
      }
      if (remote && !remote_turns && !remote_followed) {
        // Every robot of the program on its agent: task control here, nothing simulated.
        RemoteAgents agents;
        agents.domain = *args->domain;
        agents.wait = std::chrono::milliseconds(static_cast<long long>(args->agent_wait * 1000));
        agents.rejoin_wait = std::chrono::milliseconds(static_cast<long long>(args->rejoin_wait * 1000));
        return run_real_cell(*cmd, a, s, pre, args->speed, args->quiet, &agents);
      }
#if !CW_SIM
      // A twin for real robots only: every robot of the program on its real driver, nothing simulated.
      return run_real_cell(*cmd, a, s, pre, args->speed, args->quiet);
#else
      block_stop_signals();  // a stop from now on ends the run safely (run_until_signal below), never mid-write
      auto progress = std::make_shared<Progress>(args->quiet);
      RunOptions options = run_options_for(a, s);
      if (args->realtime || remote_followed) options.realtime = true;
      if (remote_followed) {
        // The agents' robot controls have the cell as the program's CAD (nothing here reaches their models): so does
        // task control here, whatever the twin's camera would see.
        if (options.perception && *options.perception != runtime::Perception::kCad) {
          throw InputError({"--perception", 0, 0},
                           fmt::format("perception {} would correct task control's model here, and the agents' robot "
                                       "controls (on their real drivers) do not share it: leave it out (cad)",
                                       runtime::to_string(*options.perception)));
        }
        options.perception = runtime::Perception::kCad;
        for (const Binding& b : s.robots) options.followed.push_back(b.name);
        options.followed_via = fmt::format("DDS domain {}", *args->domain);
      }
      if (cmd->count("--speed") > 0 && !options.realtime.value_or(s.options.realtime)) {
        throw InputError({"--speed", 0, 0}, "it paces a real-time run, and this run is lock-step (which runs as fast "
                                             "as it can): add --realtime");
      }
      options.speed = args->speed;
      options.on_progress = [progress](SimDuration t, std::uint64_t firings) { progress->print(t, firings); };
      options.progress_every = progress->every();
      // The event log goes to a file as it is written, never held whole: into the output directory (renamed to
      // events.jsonl at the end; a run that dies leaves events.jsonl.part), else into a temporary file.
      std::optional<TemporaryFile> scratch;
      if (a.output.empty()) {
        scratch.emplace("cellwright-events-", ".jsonl");
        options.events_file = scratch->path();
      }
      // The cell as ROS 2 sees it: a publisher watching the run (its observers added to the runtime's config).
      std::optional<distributed::Participant> ros_participant;
      std::optional<distributed::RosPublisher> ros;
      if (args->ros_domain) {
        ros_participant.emplace(distributed::DdsOptions{.domain = *args->ros_domain}, "cellwright_twin_run");
        ros.emplace(*ros_participant, s.cell);
      }
      // Every robot of the program on its agent, taking its turns there (the twin's drivers answered here).
      std::optional<distributed::Participant> agents_participant;
      std::optional<distributed::TurnCell> turns;
      if (remote_turns) {
        agents_participant.emplace(distributed::DdsOptions{.domain = *args->domain}, "cellwright_twin_run_turns");
        turns.emplace(*agents_participant);
      }
      // Every robot of the program on its agent in real time, followed by the twin (the runtime's links as without
      // it: distributed/link.hpp).
      std::optional<distributed::RemoteCell> agents;
      if (remote_followed) {
        agents_participant.emplace(distributed::DdsOptions{.domain = *args->domain}, "cellwright_task_control");
        agents.emplace(*agents_participant);
      }
      options.configure = [&](runtime::RunConfig& c) {
        if (ros) ros->attach(c);
        if (turns) {
          c.remote_robots = on_agents;
          c.attach_remote = turns->attach(s.program, c.period, c.perception);
        }
        if (agents) {
          for (const Binding& b : s.robots) c.remote_robots.push_back(b.name);
          c.attach_remote = agents->attach();
          // The run's clock runs at --speed times the wall clock; the wait is given in wall-clock seconds.
          c.rejoin_wait = std::chrono::duration_cast<SimDuration>(
              std::chrono::duration<double>(args->rejoin_wait * args->speed));
        }
      };
      ScenarioRun sr(s, pre, options);
      // The twin's copies follow what each agent's robot control writes of its robot (a second reader of the model
      // topic, beside the runtime's).
      std::vector<std::unique_ptr<distributed::RobotSubscriber>> followers;
      if (agents) {
        twin::sim::ReplicaMirror& mirror = *sr.replica_mirror();
        for (std::size_t i = 0; i < s.robots.size(); ++i) {
          const std::size_t copy = *mirror.index_of(s.robots[i].name);
          const Eigen::Isometry3d base = s.cell.find_robot(s.robots[i].name)->base.transform();
          followers.push_back(std::make_unique<distributed::RobotSubscriber>(
              *agents_participant, s.robots[i].name, i,
              [&mirror, copy, base](const distributed::ModelUpdate& u) {
                twin::sim::ReplicaState state;
                state.joints = u.state.joints;
                if (u.state.tcp) state.tool_in_base = base.inverse() * *u.state.tcp;
                if (u.state.hold) state.holding = u.state.hold->workpiece;
                mirror.push(copy, std::move(state));
              },
              nullptr));
          followers.back()->start();
        }
        if (!args->quiet) {
          std::printf("waiting up to %.1f s for the agents of %zu robots on DDS domain %d\n", args->agent_wait,
                      s.robots.size(), *args->domain);
          std::fflush(stdout);
        }
        agents->wait_for_agents(std::chrono::milliseconds(static_cast<long long>(args->agent_wait * 1000)));
        if (!args->quiet) {
          for (const Binding& b : s.robots) {
            std::printf("%s on its agent, DDS domain %d (real time; followed by the twin)\n", b.name.c_str(),
                        *args->domain);
          }
        }
      }
      if (turns) {
        turns->wait_for_agents(std::chrono::milliseconds(static_cast<long long>(args->agent_wait * 1000)));
        if (!args->quiet) {
          for (const std::string& robot : on_agents) {
            std::printf("%s on its agent, DDS domain %d (lock-step turns)\n", robot.c_str(), *args->domain);
          }
        }
      }
      if (ros) ros->start();

      if (!args->quiet) {
        std::string robots;
        for (const Binding& b : s.robots) robots += fmt::format(" {}={}", b.label, b.name);
        std::printf("%s: %s on %s,%s, %s, perception %s\n", a.scenario.c_str(), s.program_file.filename().c_str(),
                    s.cell.name.c_str(), robots.c_str(), sr.realtime() ? "real time" : "lock-step",
                    runtime::to_string(sr.perception()));
        std::printf("estimated cycle time %.2f s\n", sr.estimate().cycle_time);
        std::fflush(stdout);
      }

      // Lock-step runs go firing by firing, so that the progress line can say what each robot does; real-time runs
      // are paced by the wall clock. The limits (sim time, wall time) are the runtime's.
      // Ctrl-C (or SIGTERM) stops the cell safely at the next period; the outputs so far are written below.
      run_until_signal(
          [&] {
            if (sr.realtime()) {
              sr.runtime().run();
            } else {
              for (;;) {
                const runtime::StepState st = sr.runtime().step();
                if (st.ended) break;
                progress->set_robots(st.task.robots);
              }
            }
          },
          [&] { sr.runtime().request_stop("stopped by the user (signal)"); });
      progress->finish();
      for (auto& f : followers) f->stop();
      if (agents && !sr.settle_followers(std::chrono::seconds(30))) {
        std::fprintf(stderr, "warning: the twin's copies of the agents' robots had not caught up 30 s (simulated) "
                             "after the run; final.png and the parts' places show them where they were then\n");
      }
      if (ros && !ros->stop()) {
        std::fprintf(stderr, "warning: not every ROS 2 subscriber acknowledged the last samples within 2 s\n");
      }

      const Report report = sr.report();
      if (!a.output.empty()) {
        // The picture costs a renderer (its shaders compiled) and an encoding: made only when someone may look.
        const bool picture = args->final_png == "always" || (args->final_png == "failed" && !report.ok());
        sr.write_outputs(a.output, report, picture ? sr.snapshot(800, 600) : cv::Mat());
      }
      const std::filesystem::path video = sr.finish_video(report);
      std::printf("%s", format_summary(report).c_str());
      for (const auto& m : sr.mirrors()) {
        const twin::sim::MirroredDriver::Counts c = m->counts();
        std::printf(
            "  %s (real, mirrored in the twin): %d commands mirrored, %d corrections from read-backs, %d "
            "missed\n",
            m->robot().c_str(), c.mirrored, c.corrections, c.misses);
      }
      if (sr.replica_mirror() != nullptr) {
        const twin::sim::ReplicaMirror::Counts c = sr.replica_mirror()->counts();
        std::printf("  robots on agents (DDS domain %d), followed in the twin: %d states, %d moves and %d grips "
                    "followed, %d missed\n",
                    *args->domain, c.states, c.moves, c.grips, c.misses);
      }
      if (!a.output.empty()) std::printf("outputs in %s\n", a.output.c_str());
      if (!video.empty()) std::printf("video in %s\n", video.c_str());
      return report.ok() ? 0 : 1;
#endif  // CW_SIM
    };
  });
}

}  // namespace cellwright::tools
