// `twin campaign SCENARIO [--faults K1,K2,...] [--runs N] [--seed S] [--jobs J] [--timeout SECONDS] [--video] -o DIR`:
// run N seeded variants of a scenario, each with a fault drawn from the kinds that apply, as `twin run` child
// processes, and add up what the controller made of them (docs/faults.md section 6). Exit 0 when the campaign ran
// (the figures are the verdict), 2 on bad input (refused before anything is written).
#if CW_SIM
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/cell/campaign.hpp"
#include "cellwright/cell/outputs.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"
#include "run_args.hpp"

namespace cellwright::tools {

namespace {

// `--video`: each run that ended with a negative verdict is run again in this process, with its faults and seed and a
// video into its run directory. Lock-step runs are deterministic, so the video shows the run the campaign counted.
// Crashes and hangs are not re-run (they would crash or hang this process); only failed runs pay for a video.
void record_failed_runs(const cell::CampaignOptions& options,
                        const std::vector<cell::RunRecord>& records, const VideoFlag& video) {
  for (const cell::RunRecord& r : records) {
    if (r.status != cell::RunStatus::kDone || r.exit_code != 1) continue;
    RunArgs a;
    a.scenario = options.scenario.string();
    for (const cell::DrawnFault& f : r.variant.faults) a.faults.push_back(f.spec);
    a.seed = r.variant.seed;
    a.video = (r.dir / "video.mp4").string();
    a.output = r.dir.string();  // all of its outputs again, final.png (which its child did not make) and the page
    a.video_fps = video.fps;
    a.video_size = video.size;
    const auto start = std::chrono::steady_clock::now();
    try {
      (void)run_for_video(a);
    } catch (const std::exception& e) {  // one video that cannot be made does not cost the others
      std::fprintf(stderr, "run %zu failed: no video: %s\n", r.variant.index, e.what());
      continue;
    }
    std::fprintf(stderr, "run %zu failed: video in %s (%.1f s)\n", r.variant.index, a.video.c_str(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
}

}  // namespace

void add_campaign(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "campaign",
      "Fault campaign: run N seeded variants of a scenario, each with one fault (now and then two) drawn from the "
      "kinds that apply, as `twin run` child processes, and write per fault kind injected, detected, recovered, "
      "stopped safely, stalled runs (at their time limit), parts unaccounted and mean time to recover to "
      "DIR/campaign.csv, .md and .png. Exit 0 when it ran, 2 on bad input.");
  struct Args {
    std::string scenario;
    std::vector<std::string> faults;
    long long runs = 20;
    std::uint64_t seed = 1;
    unsigned jobs = 0;
    double timeout = cell::CampaignOptions::kDefaultTimeout;
    std::string out;
    bool force = false;
    VideoFlag video;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("scenario", args->scenario, "scenario file (.yaml, docs/scenarios.md)")->required();
  cmd->add_option("--faults", args->faults,
                  "fault kinds to draw from, comma-separated (docs/faults.md; default: every kind that applies)")
      ->delimiter(',');
  cmd->add_option("--runs", args->runs, "number of runs (default 20)");
  cmd->add_option("--seed", args->seed, "the campaign's seed: run i is drawn from (seed, i) (default 1)");
  cmd->add_option("--jobs", args->jobs, "runs at a time (default: the number of cores)");
  cmd->add_option("--timeout", args->timeout,
                  "s of wall time after which a run is killed and counted as a hang (default 600)");
  cmd->add_option("-o,--output", args->out, "directory for campaign.csv/.md/.png and runs/NNNN (required)");
  cmd->add_option("--out", args->out)->group("");  // the old name, still accepted and not shown
  cmd->add_flag("--force", args->force,
                "write into the -o directory even though it is not Cellwright's (no .cellwright-output in it) and "
                "holds files of those names, replacing them (runs/ included)");
  add_video_flag(*cmd, args->video,
                 "record a video of each failed run (exit 1: an outcome did not hold) as runs/NNNN/video.mp4: the run "
                 "is run again, lock-step, after the campaign");
  cmd->callback([run, args] {
    *run = [args] {
      namespace ts = cell;
      if (args->out.empty()) throw InputError({"-o/--output", 0, 0}, "the campaign needs an output directory");
      ts::check_output_directory(args->out, ts::campaign_output_files(), args->force);
      check_video_flag(args->video);  // the size, the rate and ffmpeg checked now, not after the campaign has run
      const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe");
      const ts::CampaignOptions options =
          ts::plan_campaign(std::filesystem::absolute(args->scenario), args->faults, args->runs, args->seed,
                            args->jobs, args->timeout, args->out, exe, ts::twin_port());
      std::fprintf(stderr, "%s: %zu runs of %s, %u at a time, seed %llu\n", args->scenario.c_str(), options.runs,
                   fmt::format("{}", fmt::join(options.kinds, ", ")).c_str(), options.jobs,
                   static_cast<unsigned long long>(options.seed));
      ProgressBar bar;
      const std::vector<ts::RunRecord> records = ts::run_campaign(
          options, [&bar](const ts::CampaignProgress& p) { bar.update(ts::format_progress(p), p.done, p.total); });
      bar.finish();
      const ts::CampaignSummary summary =
          ts::aggregate(records, options.kinds, options.scenario.filename().string(), options.seed);
      ts::write_campaign(options.out, summary, records);
      if (args->video.on) record_failed_runs(options, records, args->video);
      std::printf("%s", ts::format_markdown(summary, records).c_str());
      std::printf("outputs in %s\n", args->out.c_str());
      return 0;
    };
  });
}

}  // namespace cellwright::tools

#else  // a twin for real robots only: the command needs the simulator

#include "simulator.hpp"

namespace cellwright::tools {

void add_campaign(CLI::App& app, Command* run) {
  add_unavailable(app, run, "campaign", "Run many seeded variants of a scenario with faults");
}

}  // namespace cellwright::tools

#endif  // CW_SIM
