// `twin step <scenario.yaml>`: step the concurrent processes one firing at a time from the terminal, as the paper's
// simulator does for debugging. Commands are read from standard input, one per line (a pipe works as well as a
// terminal): Enter or `n` next firing, `c` continue to the end, `s FILE` save a snapshot PNG, `m` show the marking,
// `q` quit (the cell is stopped safely; with -o the outputs so far are written), `h` help. Ctrl-C (SIGINT) or SIGTERM,
// at the prompt or while a step or `c` runs, does what `q` does. It takes the options of `twin run` but --realtime,
// --quiet and --dry (run_args.hpp). Exit status as `twin run` once the run has ended; 0 when quit before; 130 when
// interrupted by a signal; 2 on bad input.
#if CW_SIM
#include <poll.h>
#include <unistd.h>

#include <cerrno>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/vision/png.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/scenario.hpp"
#include "commands.hpp"
#include "run_args.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

namespace {

const char* const kHelp =
    "commands: Enter or n = next firing, c = continue to the end, s FILE = save a snapshot PNG, m = show the "
    "marking, q = quit, h = this help\n";

// "r1 line 8 'Pick A' (grasp A): r1 begin close A" for transition t (describe_path without its numbering).
std::string describe_transition(const petri::Net& net, petri::TransitionId t) {
  std::string s = petri::describe_path(net, {t});
  if (const auto dot = s.find(". "); dot != std::string::npos && dot < 6) s = s.substr(dot + 2);
  return fmt::format("{}: {}", net.transitions()[t].id, s);
}

void print_marking(const petri::Net& net, const petri::Marking& m) {
  std::printf("  marking: %s\n", petri::describe_marking(net, m).c_str());
}

void print_state(const petri::Net& net, const runtime::StepState& st, bool with_firings) {
  std::printf("t = %.3f s, %llu firings\n", std::chrono::duration<double>(st.time).count(),
              static_cast<unsigned long long>(st.task.firings));
  if (with_firings) {
    for (const std::string& id : st.task.last_fired) {
      if (auto t = net.find_transition(id)) std::printf("  fired %s\n", describe_transition(net, *t).c_str());
    }
  }
  print_marking(net, st.task.marking);
  for (std::size_t i = 0; i < st.task.robots.size(); ++i) {
    const runtime::RobotView& task_view = st.task.robots[i];
    std::string line = fmt::format("  {}: {}", task_view.robot,
                                   task_view.done ? std::string("done")
                                                  : fmt::format("{} {}", runtime::to_string(task_view.activity),
                                                                task_view.command.empty() ? "-" : task_view.command));
    if (i < st.robots.size()) {
      const runtime::RobotControlView& rc = st.robots[i];
      line += fmt::format("  [{} {}, driver {}{}]", rc.cell, runtime::to_string(rc.phase),
                          drivers::to_string(rc.driver), rc.detail.empty() ? "" : ": " + rc.detail);
    }
    std::printf("%s\n", line.c_str());
  }
  std::fflush(stdout);
}

// Reads one command line from standard input (the file descriptor itself, not std::cin, so that a signal can end the
// wait): true with the line, false at the end of the input or once `stop` (StopWatcher::wake_fd) is readable.
// `pending` keeps what was read past the line.
bool read_command(int stop, std::string& pending, std::string& line) {
  for (;;) {
    if (const auto end = pending.find('\n'); end != std::string::npos) {
      line = pending.substr(0, end);
      pending.erase(0, end + 1);
      return true;
    }
    pollfd fds[2] = {{STDIN_FILENO, POLLIN, 0}, {stop, POLLIN, 0}};
    if (::poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (fds[1].revents != 0) return false;
    char buf[4096];
    const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {  // the end of the input: a last line without its newline still counts
      if (pending.empty()) return false;
      line = std::move(pending);
      pending.clear();
      return true;
    }
    pending.append(buf, static_cast<std::size_t>(n));
  }
}

}  // namespace

void add_step(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("step",
                                 "Step a scenario one firing at a time, reading commands from standard input: Enter/n "
                                 "next firing, c continue, s FILE snapshot, m marking, q quit (Ctrl-C does what q does). "
                                 "Exit 0 when the run ended with every expected outcome holding or was quit; 1 if not; "
                                 "130 when interrupted by Ctrl-C; 2 on bad input.");
  auto args = std::make_shared<RunArgs>();
  add_run_options(*cmd, *args);
  cmd->callback([run, args] {
    *run = [args] {
      using namespace cellwright::cell;
      const std::string& scenario = args->scenario;
      const std::string& out = args->output;
      const Scenario s = load_scenario_with(*args);
      if (uses_real_drivers(s)) {
        throw InputError({"--driver", 0, 0},
                         "twin step runs the program lock-step on simulated robots, and a real robot keeps its own "
                         "time: run it with twin run --realtime (or twin run --dry for a bring-up)");
      }
      const Preflight pre = preflight(s, &twin_port());
      if (!pre.ok(args->allow_collisions)) {
        std::fprintf(stderr, "%s: refused, nothing was run:\n", scenario.c_str());
        for (const std::string& p : pre.problems) std::fprintf(stderr, "  %s\n", p.c_str());
        if (!pre.collisions.empty() && pre.ok(true)) std::fprintf(stderr, "  (--allow-collisions runs it anyway)\n");
        return 2;
      }
      for (const std::string& c : pre.collisions) {
        std::fprintf(stderr, "%s: warning: predicted collision (--allow-collisions): %s\n", scenario.c_str(), c.c_str());
      }
      // With -o the event log streams into the output directory, as in `twin run`; without, a stepped run (short, by
      // hand) keeps it in memory.
      RunOptions options = run_options_for(*args, s);
      options.realtime = false;  // stepping is lock-step
      // Files to remove once the run is gone (declared before it, so destroyed after it: the log and the video
      // closed first): what a quit before the first step would leave half-made.
      struct RemovedAtExit {
        std::vector<std::filesystem::path> files;
        ~RemovedAtExit() {
          std::error_code ec;
          for (const std::filesystem::path& f : files) std::filesystem::remove(f, ec);
        }
      } unrun;
      // The marker that makes -o Cellwright's: left only by a run that wrote something.
      const std::filesystem::path marker = out.empty() ? std::filesystem::path() : std::filesystem::path(out) / kMarkerFile;
      const bool marker_was_there = !marker.empty() && std::filesystem::exists(marker);
      block_stop_signals();  // before any thread starts (a video's encoder): each inherits the mask
      ScenarioRun sr(s, pre, options);
      // Ctrl-C or SIGTERM: a step or `c` under way stops at the next period (the cell stopped safely), and the prompt
      // takes it as `q`.
      const StopWatcher watcher([&sr] { sr.runtime().request_stop("stopped by the user (signal)"); });
      const petri::Net& net = sr.runtime().config().net;
      const bool interactive = isatty(STDIN_FILENO) == 1;

      std::printf("%s: %s on %s, stepping one firing at a time\n", scenario.c_str(), s.program_file.filename().c_str(),
                  s.cell.name.c_str());
      std::printf("estimated cycle time %.2f s\n", sr.estimate().cycle_time);
      print_marking(net, net.initial_marking());
      std::printf("%s", kHelp);
      std::fflush(stdout);

      std::optional<runtime::StepState> last;
      auto finish = [&](const runtime::StepState& st) {
        print_state(net, st, false);
        const Report report = sr.report();
        if (!out.empty()) sr.write_outputs(out, report, sr.snapshot(800, 600));
        const std::filesystem::path video = sr.finish_video(report);
        std::printf("%s", format_summary(report).c_str());
        if (!out.empty()) std::printf("outputs in %s\n", out.c_str());
        if (!video.empty()) std::printf("video in %s\n", video.c_str());
        return watcher.stopped() ? kInterrupted : report.ok() ? 0 : 1;
      };
      std::string line, pending;
      for (;;) {
        if (interactive) {
          std::printf("(step) ");
          std::fflush(stdout);
        }
        if (watcher.stopped() || !read_command(watcher.wake_fd(), pending, line)) line = "q";  // end of input quits
        if (!line.empty() && line.back() == '\r') line.pop_back();
        const std::string word = line.substr(0, line.find(' '));
        const std::string rest = line.find(' ') == std::string::npos ? "" : line.substr(line.find(' ') + 1);
        if (word.empty() || word == "n") {
          last = sr.runtime().step();
          if (last->ended) {
            std::printf("the run has ended (%s)\n", runtime::to_string(last->result->outcome));
            return finish(*last);
          }
          print_state(net, *last, true);
        } else if (word == "c") {
          sr.runtime().run();
          last = sr.runtime().step();  // the ended state: the same result again, with the views
          std::printf("ran to the end (%s)\n", runtime::to_string(last->result->outcome));
          return finish(*last);
        } else if (word == "m") {
          print_marking(net, last ? last->task.marking : net.initial_marking());
          std::fflush(stdout);
        } else if (word == "s") {
          if (rest.empty()) {
            std::printf("s needs a file name: s FILE.png\n");
          } else {
            try {
              vision::write_png(sr.snapshot(800, 600), rest);
              std::printf("saved %s\n", rest.c_str());
            } catch (const InputError& e) {
              std::printf("%s\n", e.what());
            }
          }
          std::fflush(stdout);
        } else if (word == "q") {
          if (watcher.stopped()) std::printf("interrupted by the user (signal): ");
          std::printf("quit at t = %.3f s\n", last ? std::chrono::duration<double>(last->time).count() : 0.0);
          if (!last) {  // nothing ran: nothing to write, and neither the log begun nor the video left behind
            for (const std::filesystem::path& f : {sr.events_file(), std::filesystem::path(args->video)}) {
              if (!f.empty()) unrun.files.push_back(f);
            }
            if (!marker.empty() && !marker_was_there) unrun.files.push_back(marker);
            return watcher.stopped() ? kInterrupted : 0;
          }
          // The cell is stopped safely at the next period; what was logged so far is kept and written.
          sr.runtime().request_stop("quit by the user (twin step)");
          last = sr.runtime().step();
          (void)finish(*last);
          return watcher.stopped() ? kInterrupted : 0;
        } else if (word == "h" || word == "?") {
          std::printf("%s", kHelp);
        } else {
          std::printf("unknown command '%s'; %s", line.c_str(), kHelp);
          std::fflush(stdout);
        }
      }
    };
  });
}

}  // namespace cellwright::tools

#else  // a twin for real robots only: the command needs the simulator

#include "simulator.hpp"

namespace cellwright::tools {

void add_step(CLI::App& app, Command* run) {
  add_unavailable(app, run, "step", "Run a scenario one firing at a time");
}

}  // namespace cellwright::tools

#endif  // CW_SIM
