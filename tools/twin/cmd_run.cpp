// `twin run <scenario.yaml> [-o DIR] [--realtime] [--quiet] [--perception truth|vision|cad] [--save-frames DIR]
// [--driver ROBOT=KIND[:PORT]]... [--fault SPEC]... [--seed N] [--dry] [--allow-collisions]`: run a scenario's task
// program on the simulated cell (or with some robots real, mirrored in the twin), headless, and judge the outcome.
// Exit 0 when the run finished and every expected outcome holds, 1 when not, 2 on bad input or a predicted collision
// (refused before any thread starts, nothing written).
#include <unistd.h>
#include <any>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/twin/scenario/dry_run.hpp"
#include "cellwright/twin/scenario/run.hpp"
#include "cellwright/twin/scenario/scenario.hpp"
#include "cellwright/vision/cell_detector.hpp"
#include "cellwright/vision/draw.hpp"
#include "commands.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

namespace {

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

}  // namespace

void add_run(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("run",
                                 "Run a scenario's task program on the simulated cell, headless. Writes events.jsonl, "
                                 "report.json, gantt.png and final.png with -o. Exit 0 only if the run finished and "
                                 "every expected outcome holds; 1 if not; 2 on bad input.");
  struct Args {
    std::string scenario;
    std::string out;
    bool realtime = false;
    bool quiet = false;
    std::string perception;
    std::string frames;
    std::vector<std::string> drivers;
    std::vector<std::string> faults;
    std::optional<std::uint64_t> seed;
    bool dry = false;
    bool allow_collisions = false;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("scenario", args->scenario, "scenario file (.yaml, docs/scenarios.md)")->required();
  cmd->add_option("-o,--out", args->out, "directory for the outputs (created if needed)");
  cmd->add_flag("--realtime", args->realtime, "pace the simulation to the wall clock instead of lock-step");
  cmd->add_flag("--quiet", args->quiet, "no progress line");
  cmd->add_option("--perception", args->perception,
                  "where the controller learns where the parts are, instead of the scenario's choice: truth (the "
                  "simulation), vision (the camera) or cad (the cell description only: vision off)")
      ->check(CLI::IsMember({"truth", "vision", "cad"}));
  cmd->add_option("--driver", args->drivers,
                  "put a robot on another driver, the rest of the scenario unchanged: ROBOT=sim, "
                  "ROBOT=movemaster:PORT or ROBOT=val2:PORT (repeatable; real drivers need --realtime)");
  cmd->add_option("--fault", args->faults,
                  "inject a fault, added to the scenario's faults: KIND:key=value,key=value with a list as a/b, e.g. "
                  "drop:robot=puma,carry=1 (docs/faults.md; repeatable)");
  cmd->add_option("--seed", args->seed, "the run's seed instead of the scenario's (random amounts of the faults, "
                                        "perturbations)");
  cmd->add_flag("--dry", args->dry,
                "hardware bring-up: connect the real drivers, home, read positions and check every target of the "
                "program; nothing else moves. Exit 0 when all is well, 1 when not");
  cmd->add_flag("--allow-collisions", args->allow_collisions,
                "run even though the preflight's motion sweep predicts collisions (printed as warnings)");
  cmd->add_option("--save-frames", args->frames,
                  "write each camera frame as DIR/frame_<ms>.png with its simulated time; with vision, the detections, the "
                  "predicted poses and the parts not seen drawn on it; without, plain frames every vision period");
  cmd->callback([run, args] {
    *run = [args] {
      using namespace cellwright::twin::scenario;
      for (const std::string& dir : {args->out, args->frames}) if (!dir.empty()) check_writable_dir(dir);  // before all
      Scenario s = load_scenario(args->scenario);
      for (const std::string& d : args->drivers) set_driver(s, d, {"--driver", 0, 0});
      for (const std::string& f : args->faults) s.faults.push_back(parse_fault_text(f, s.cell, "--fault"));
      if (args->seed) s.seed = *args->seed;
      const Preflight pre = preflight(s);
      if (!pre.ok(args->allow_collisions)) {
        std::fprintf(stderr, "%s: refused, nothing was run:\n", args->scenario.c_str());
        for (const std::string& p : pre.problems) std::fprintf(stderr, "  %s\n", p.c_str());
        if (!pre.collisions.empty() && pre.ok(true)) std::fprintf(stderr, "  (--allow-collisions runs it anyway)\n");
        if (!pre.analysis.ok()) {
          std::fprintf(stderr, "%s: %s", s.program_file.string().c_str(),
                       petri::format_report(pre.net, pre.analysis).c_str());
        }
        return 2;
      }
      for (const std::string& c : pre.collisions) {
        std::fprintf(stderr, "%s: warning: predicted collision (--allow-collisions): %s\n", args->scenario.c_str(),
                     c.c_str());
      }

      if (args->dry) {
        if (!uses_real_drivers(s)) {
          throw InputError({"--dry", 0, 0},
                           "a dry run is for real drivers, and every robot of the program is "
                           "simulated: give one with --driver ROBOT=movemaster:PORT or val2:PORT");
        }
        const DryRunReport dry = dry_run(s, pre.net);
        std::printf("%s", format_dry_run(dry).c_str());
        return dry.ok() ? 0 : 1;
      }

      block_stop_signals();  // a stop from now on ends the run safely (run_until_signal below), never mid-write
      auto progress = std::make_shared<Progress>(args->quiet);
      RunOptions options;
      if (args->realtime) options.realtime = true;
      if (args->perception == "truth") options.perception = runtime::Perception::kTruth;
      if (args->perception == "vision") options.perception = runtime::Perception::kVision;
      if (args->perception == "cad") options.perception = runtime::Perception::kCad;
      if (!args->frames.empty() && s.cell.cameras.empty()) {  // without vision: plain frames, of a camera still
        std::fprintf(stderr, "%s: --save-frames needs a camera, and the cell has none\n", args->scenario.c_str());
        return 2;
      }
      if (!args->frames.empty()) {
        const std::filesystem::path dir = args->frames;
        std::error_code ec;
        std::filesystem::create_directories(dir, ec);
        if (ec)
          throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the frames directory: {}", ec.message()));
        const models::CameraSpec* cam =
            s.cell.find_camera(s.vision ? s.vision->camera : s.cell.cameras.empty() ? "" : s.cell.cameras[0].name);
        options.on_frame = [dir, cam](const runtime::VisionFrame& f) {
          if (f.image.empty()) return;
          const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(f.time).count();
          cv::Mat drawn = vision::as_mat(f.image).clone();
          if (const auto* found = std::any_cast<vision::DetectionResult>(&f.result.detail)) {
            vision::draw_detections(drawn, *found);
          }
          std::vector<vision::PredictedPart> predicted;  // the model's poses before this frame corrected them
          for (const runtime::Prediction& p : f.predictions) predicted.push_back({p.workpiece, p.position});
          if (cam != nullptr) {
            vision::draw_frame_overlay(drawn, std::chrono::duration<double>(f.time).count(),
                                       vision::CameraModel(*cam, drawn.cols, drawn.rows), predicted, f.result.not_seen);
          }
          twin::write_png(drawn, dir / fmt::format("frame_{:06}.png", ms));
        };
      }
      options.on_progress = [progress](SimDuration t, std::uint64_t firings) { progress->print(t, firings); };
      options.progress_every = progress->every();
      // The event log goes to a file as it is written, never held whole: into the output directory (renamed to
      // events.jsonl at the end; a run that dies leaves events.jsonl.part), else into a temporary file.
      std::optional<TemporaryFile> scratch;
      if (args->out.empty()) {
        scratch.emplace("cellwright-events-", ".jsonl");
        options.events_file = scratch->path();
      } else {
        options.events_file = streamed_events_file(args->out);
      }
      ScenarioRun sr(s, pre.net, options);

      if (!args->quiet) {
        std::string robots;
        for (const Binding& b : s.robots) robots += fmt::format(" {}={}", b.label, b.name);
        std::printf("%s: %s on %s,%s, %s, perception %s\n", args->scenario.c_str(), s.program_file.filename().c_str(),
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

      const Report report = sr.report();
      if (!args->out.empty()) {
        sr.write_outputs(args->out, report, sr.snapshot(800, 600));
      }
      std::printf("%s", format_summary(report).c_str());
      for (const auto& m : sr.mirrors()) {
        const twin::sim::MirroredDriver::Counts c = m->counts();
        std::printf(
            "  %s (real, mirrored in the twin): %d commands mirrored, %d corrections from read-backs, %d "
            "missed\n",
            m->robot().c_str(), c.mirrored, c.corrections, c.misses);
      }
      if (!args->out.empty()) std::printf("outputs in %s\n", args->out.c_str());
      return report.ok() ? 0 : 1;
    };
  });
}

}  // namespace cellwright::tools
