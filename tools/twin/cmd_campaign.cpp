// `twin campaign SCENARIO [--faults K1,K2,...] [--runs N] [--seed S] [--jobs J] [--timeout SECONDS] -o DIR`: run N
// seeded variants of a scenario, each with a fault drawn from the kinds that apply, as `twin run` child processes,
// and add up what the controller made of them (docs/faults.md section 6). Exit 0 when the campaign ran (the figures
// are the verdict), 2 on bad input (refused before anything is written).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/twin/scenario/campaign.hpp"
#include "commands.hpp"
#include "progress_bar.hpp"

namespace cellwright::tools {

void add_campaign(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "campaign",
      "Fault campaign: run N seeded variants of a scenario, each with one fault (now and then two) drawn from the "
      "kinds that apply, as `twin run` child processes, and write per fault kind injected, detected, recovered, "
      "stopped safely, parts unaccounted and mean time to recover to DIR/campaign.csv, .md and .png. Exit 0 when it "
      "ran, 2 on bad input.");
  struct Args {
    std::string scenario;
    std::vector<std::string> faults;
    long long runs = 20;
    std::uint64_t seed = 1;
    unsigned jobs = 0;
    double timeout = twin::scenario::CampaignOptions::kDefaultTimeout;
    std::string out;
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
  cmd->add_option("-o,--out", args->out, "directory for campaign.csv/.md/.png and runs/NNNN")->required();
  cmd->callback([run, args] {
    *run = [args] {
      namespace ts = twin::scenario;
      const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe");
      const ts::CampaignOptions options =
          ts::plan_campaign(std::filesystem::absolute(args->scenario), args->faults, args->runs, args->seed,
                            args->jobs, args->timeout, args->out, exe);
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
      std::printf("%s", ts::format_markdown(summary, records).c_str());
      std::printf("outputs in %s\n", args->out.c_str());
      return 0;
    };
  });
}

}  // namespace cellwright::tools
