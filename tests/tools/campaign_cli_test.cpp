// `twin campaign` as a user runs it: bad input is refused with exit 2 and nothing written; a tiny campaign of the
// exchange (two runs with a drop each) runs `twin run` twice and writes its table, CSV and chart.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tools/twin_cli.hpp"

namespace {

namespace fs = std::filesystem;
using cellwright::testing::Outcome;
using cellwright::testing::shell_quote;
using cellwright::testing::slurp;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;

std::string exchange() { return shell_quote(source_path("scenes/exchange.yaml")); }

TEST(CampaignCli, BadInputIsRefusedWithExitTwoAndNothingWritten) {
  TwinCli cli("cw-campaign-cli-bad");
  const fs::path out = cli.dir() / "out";
  const std::string o = " -o " + shell_quote(out.string());
  struct Case {
    std::string args, message;
  };
  for (const Case& c : {
           Case{exchange() + " --faults drop,teleport", "unknown fault kind 'teleport'"},
           Case{exchange() + " --faults frame_lost", "'frame_lost' does not apply"},
           Case{exchange() + " --runs 0", "at least one run"},
           Case{exchange() + " --timeout 0", "must be > 0"},
           Case{shell_quote(source_path("scenes/no-such.yaml")), "no-such.yaml"},
       }) {
    const Outcome r = cli.run("campaign " + c.args + o);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << c.args;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  // An output directory under a file.
  std::ofstream(cli.dir() / "file") << "x";
  const Outcome r = cli.run("campaign " + exchange() + " --runs 1 -o " + shell_quote((cli.dir() / "file/out").string()));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("is not a directory"));
  // -o is required.
  EXPECT_EQ(cli.run("campaign " + exchange()).status, 2);
}

TEST(CampaignCli, TwoRunsOfTheExchangeWithADropEach) {
  TwinCli cli("cw-campaign-cli-run");
  if (cli.run("run --help").out.find("--fault") == std::string::npos) {
    GTEST_SKIP() << "`twin run` has no --fault option yet (the fault injection has not landed)";
  }
  const fs::path out = cli.dir() / "out";
  const Outcome r = cli.run("campaign " + exchange() + " --faults drop --runs 2 --seed 4 --jobs 2 --timeout 900 -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("# Fault campaign: exchange.yaml, 2 runs, seed 4"));
  EXPECT_THAT(r.out, HasSubstr("| drop | 2 |"));
  EXPECT_THAT(r.err, HasSubstr("2/2 runs"));  // the progress bar's last state
  for (const char* f : {"campaign.csv", "campaign.md", "campaign.png", "runs.csv"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  EXPECT_EQ(slurp(out / "campaign.md") + "outputs in " + out.string() + "\n", r.out);
  for (const char* run : {"0000", "0001"}) {
    const fs::path dir = out / "runs" / run;
    ASSERT_TRUE(fs::exists(dir / "report.json")) << run << ": " << slurp(dir / "stderr.txt");
    const nlohmann::json j = nlohmann::json::parse(slurp(dir / "report.json"));
    EXPECT_TRUE(j.contains("account"));
    EXPECT_TRUE(j.contains("faults"));
    EXPECT_TRUE(fs::exists(dir / "stdout.txt"));
    EXPECT_TRUE(fs::exists(dir / "events.jsonl"));
    // Nobody opens a campaign run's picture: its child renders none (the page says so).
    EXPECT_FALSE(fs::exists(dir / "final.png")) << run;
    EXPECT_THAT(slurp(dir / "index.html"), HasSubstr("No final snapshot was made for this run."));
  }
  const std::string csv = slurp(out / "campaign.csv");
  EXPECT_THAT(csv, HasSubstr("\ndrop,2,"));
  EXPECT_THAT(csv, HasSubstr("\nall,2,"));
  EXPECT_THAT(slurp(out / "runs.csv"), ::testing::Not(HasSubstr(",crash,")));
}

// Reads a CSV of a header and lines into a row per line's first field: field name -> value.
std::map<std::string, std::map<std::string, std::string>> csv_rows(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> header;
  std::map<std::string, std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> fields(1);  // (no quoted fields in these lines)
    for (char c : line) {
      if (c == ',') {
        fields.emplace_back();
      } else {
        fields.back() += c;
      }
    }
    if (header.empty()) {
      header = fields;
      continue;
    }
    for (std::size_t i = 0; i < fields.size() && i < header.size(); ++i) rows[fields[0]][header[i]] = fields[i];
  }
  return rows;
}

// A campaign whose runs cannot finish (the exchange cut at 26 s of simulated time: its part comes at 20 s, its program
// ends at 31 s) stalls in every run: the stalls are counted per kind and in all, listed, and on the progress line; no
// fault of a stalled run counts as recovered, though the drops (at 22 s) were recovered before the limit (issue 24:
// "9 recovered", an all-green chart and "hangs 0" for runs that sat idle until the limit).
TEST(CampaignCli, RunsThatEndAtTheirTimeLimitAreStallsNotRecoveries) {
  TwinCli cli("cw-campaign-cli-stall");
  const fs::path scenario = cli.dir() / "short.yaml", out = cli.dir() / "out";
  std::ofstream(scenario)
      << "cell: " << source_path("scenes/cell.yaml") << "\nprogram: " << source_path("scenes/exchange.task")
      << "\nrobots: {r1: puma, r2: melfa}\nbind: {B: output_drop}\nlimits: {sim_time: 26}\n"
         "expect: {A: output}\ntolerance: 0.03\noptions: {control_period: 0.01, settle_time: 1.0}\n";
  const Outcome r = cli.run("campaign " + shell_quote(scenario.string()) +
                            " --faults drop --runs 2 --seed 4 --jobs 2 -o " + shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  // What the runs' reports say: both ran to the limit; the drops' recoveries ended well before it.
  std::size_t recovered_before = 0;
  for (const char* run : {"0000", "0001"}) {
    const nlohmann::json j = nlohmann::json::parse(slurp(out / "runs" / run / "report.json"));
    EXPECT_EQ(j["outcome"], "timeout") << run;
    for (const nlohmann::json& f : j["faults"]) recovered_before += f["recovered"].get<bool>() ? 1 : 0;
  }
  EXPECT_GE(recovered_before, 1u);

  const std::string csv = slurp(out / "campaign.csv");
  auto rows = csv_rows(csv);  // a column that is not there reads as ""
  EXPECT_EQ(rows["all"]["recovered"], "0") << csv;
  EXPECT_EQ(rows["all"]["stalls"], "2") << csv;
  EXPECT_EQ(rows["all"]["ok_runs"], "0") << csv;
  EXPECT_EQ(rows["all"]["mean_recovery_time_s"], "") << csv;
  EXPECT_EQ(rows["drop"]["stalls"], "2") << csv;
  const std::string md = slurp(out / "campaign.md");
  EXPECT_THAT(md, HasSubstr("0 recovered, 0 stopped safely; 2 runs stalled;"));
  EXPECT_THAT(md, HasSubstr("\nRuns that stalled:\n\n- run 0000 "));
  EXPECT_THAT(md, HasSubstr("recovered before the stall, not counted: drop at "));
  EXPECT_THAT(r.err, HasSubstr("2/2 runs, 0 running, 0 crashes, 0 hangs, 2 stalls"));
}

}  // namespace
