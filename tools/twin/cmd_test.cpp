// `twin test [DIR|SCENARIO...] [-o DIR] [--junit FILE] [--jobs N] [--keep] [--seed S] [--timeout SECONDS]
// [--video [--video-fps N] [--video-size WxH]]`: a regression suite for CI (docs/scenarios.md, "Regression suites"):
// every scenario given (default: the scenarios in scenes/) runs as a `twin run` child with its expectations, a few at
// a time; one line per scenario, a closing "N passed, N failed", JUnit XML with --junit; with --video, each failed
// scenario is run again with a video that joins its kept outputs. Exit 0 when all pass, 1 when one does not, 2 on
// bad input (refused before anything runs).
#if CW_SIM
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/files.hpp"
#include "cellwright/cell/suite.hpp"
#include "cellwright/cell/outputs.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"
#include "run_args.hpp"

namespace cellwright::tools {

namespace {

// --video: the failed scenarios run again with a video each, a line for each as its video is made or not.
void record_videos(std::vector<cell::CaseResult>& results, const cell::SuiteOptions& options,
                   const VideoFlag& flag) {
  namespace ts = cell;
  ts::VideoSettings video;
  video.fps = flag.fps;
  video.size = flag.size;
  ProgressBar bar;
  ts::VideoCallbacks callbacks;
  bool announced = false;  // the library chooses the scenarios to record and says how many in its first report
  callbacks.progress = [&](std::size_t done, std::size_t total) {
    if (!announced) {
      std::printf("recording the video%s of %zu failed scenario%s\n", total == 1 ? "" : "s", total,
                  total == 1 ? "" : "s");
      std::fflush(stdout);
      announced = true;
    }
    bar.update(fmt::format("{}/{} videos", done, total), done, total);
  };
  callbacks.ended = [&](const ts::CaseResult& r) {
    bar.clear();
    if (r.video.empty()) {
      std::printf("no video of %s: %s\n", r.test.name.c_str(), r.video_note.c_str());
    } else {
      const std::string note = r.video_note.empty() ? std::string() : " (" + r.video_note + ")";
      std::printf("video of %s in %s%s\n", r.test.name.c_str(), r.video.c_str(), note.c_str());
    }
    std::fflush(stdout);
  };
  try {
    ts::record_videos(results, options, video, callbacks);
  } catch (const std::exception& e) {  // the verdicts stand: the videos not made are named, the suite goes on
    bar.clear();
    std::printf("no more videos: %s\n", e.what());
  }
  bar.finish();
}

}  // namespace

void add_test(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "test",
      "Regression suite: run every scenario given (files, or folders: their .yaml scenarios, not their subfolders; "
      "default scenes/) as `twin run` children, a few at a time, and judge each by its expectations. One line per "
      "scenario, then 'N passed, N failed'; JUnit XML with --junit. A failing scenario's outputs are kept (with "
      "--video, with a video of it). Exit 0 when all pass, 1 when one does not, 2 on bad input (nothing run).");
  struct Args {
    std::vector<std::string> paths;
    std::string out;
    std::string junit;
    unsigned jobs = 0;
    bool keep = false;
    bool force = false;
    std::optional<std::uint64_t> seed;
    std::optional<double> timeout;
    VideoFlag video;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("paths", args->paths, "scenario files and folders of them (default: scenes)");
  cmd->add_option("-o,--output", args->out,
                  "directory for each scenario's outputs, as DIR/NAME (default: a temporary directory, removed "
                  "unless a scenario failed)");
  cmd->add_option("--junit", args->junit, "write the verdicts as JUnit XML to FILE (for Jenkins, GitLab)");
  cmd->add_option("--jobs", args->jobs, "scenarios at a time (default: the number of cores)");
  cmd->add_flag("--keep", args->keep, "keep the outputs of passing scenarios too");
  cmd->add_flag("--force", args->force,
                "write into the -o directory even though it is not Cellwright's (no .cellwright-output in it) and "
                "holds folders of the scenarios' names, replacing them");
  cmd->add_option("--seed", args->seed, "passed to every run: its seed instead of the scenario's");
  cmd->add_option("--timeout", args->timeout,
                  "s of wall time after which a scenario is killed and counts as hung (default: the scenario's own "
                  "wall-time limit plus 60 s, 600 s when it has none)");
  add_video_flag(*cmd, args->video,
                 "record a video of each failed scenario (FAIL: an expectation did not hold) as DIR/NAME/video.mp4, "
                 "shown by its report page: the scenario is run again after the suite (lock-step, the same run)");
  cmd->callback([run, args] {
    *run = [args] {
      namespace ts = cell;
      namespace fs = std::filesystem;
      const auto start = std::chrono::steady_clock::now();
      std::vector<fs::path> paths(args->paths.begin(), args->paths.end());
      if (paths.empty()) paths.emplace_back("scenes");
      check_video_flag(args->video);  // the size, the rate and ffmpeg checked now, not after the suite has run
      const ts::Discovery found = ts::discover(paths);
      if (!args->junit.empty()) ts::check_writable_file(args->junit);
      const bool temporary = args->out.empty();
      const fs::path out = temporary ? ts::make_temporary_output_dir() : fs::path(args->out);
      std::vector<ts::SuiteCase> cases;
      try {
        cases = ts::plan_suite(found, out, args->timeout, args->force);
      } catch (...) {
        if (temporary) fs::remove_all(out);
        throw;
      }
      ts::make_output_directory(out);  // marked as Cellwright's before the runs write into it

      ts::SuiteOptions options;
      options.executable = fs::read_symlink("/proc/self/exe");
      options.jobs = args->jobs > 0 ? args->jobs : std::max(1u, std::thread::hardware_concurrency());
      options.seed = args->seed;
      options.keep = args->keep;
      for (const ts::Skipped& s : found.skipped) std::printf("skipped %s: %s\n", s.path.c_str(), s.why.c_str());
      std::printf("%zu scenario%s, %u at a time\n", cases.size(), cases.size() == 1 ? "" : "s",
                  std::min<unsigned>(options.jobs, static_cast<unsigned>(cases.size())));
      std::fflush(stdout);

      std::size_t width = 0;
      for (const ts::SuiteCase& c : cases) width = std::max(width, c.name.size());
      ProgressBar bar;
      ts::SuiteCallbacks callbacks;
      callbacks.ended = [&](const ts::CaseResult& r) {
        bar.clear();
        std::printf("%s\n", ts::format_result(r, width).c_str());
        std::fflush(stdout);
      };
      callbacks.progress = [&](const ts::SuiteProgress& p) { bar.update(ts::format_progress(p), p.done, p.total); };
      std::vector<ts::CaseResult> results = ts::run_suite(cases, options, callbacks);
      bar.finish();
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      // The JUnit file is written as soon as the verdicts are known (a CI job that runs out of time while the
      // videos are made still has it), and again with the videos.
      auto write_junit = [&] {
        if (args->junit.empty()) return;
        const fs::path junit = args->junit;
        if (junit.has_parent_path()) fs::create_directories(junit.parent_path());
        write_file_atomically(junit, ts::format_junit(results, wall));
      };
      write_junit();
      if (args->video.on) {
        record_videos(results, options, args->video);
        write_junit();
      }
      if (!args->junit.empty()) std::printf("JUnit XML in %s\n", args->junit.c_str());
      const bool all_passed =
          std::all_of(results.begin(), results.end(), [](const ts::CaseResult& r) { return r.passed(); });
      for (const ts::CaseResult& r : results) {
        if (!r.passed() && r.kept) std::printf("outputs of %s kept in %s\n", r.test.name.c_str(), r.test.dir.c_str());
      }
      if (temporary && all_passed && !args->keep) {
        std::error_code ec;
        fs::remove_all(out, ec);
      } else if (args->keep) {
        std::printf("outputs in %s\n", out.c_str());
      }
      std::printf("%s\n", ts::format_totals(results).c_str());
      return all_passed ? 0 : 1;
    };
  });
}

}  // namespace cellwright::tools

#else  // a twin for real robots only: the command needs the simulator

#include "simulator.hpp"

namespace cellwright::tools {

void add_test(CLI::App& app, Command* run) {
  add_unavailable(app, run, "test", "Run a folder of scenarios as a regression suite");
}

}  // namespace cellwright::tools

#endif  // CW_SIM
