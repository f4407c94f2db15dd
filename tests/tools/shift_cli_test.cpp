// A shift as a user runs it: `twin run scenes/pipeline_shift.yaml`, a loop over a workpiece class fed by three bodies
// ten times. Every part fed is placed, the loop runs its count, each Pick takes a part that has arrived and nobody
// else has, and the report gives the steady-state flow.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "tools/twin_cli.hpp"

namespace {

namespace fs = std::filesystem;
using cellwright::testing::Outcome;
using cellwright::testing::shell_quote;
using cellwright::testing::slurp;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;
using ::testing::Not;

TEST(ShiftCli, TenPartsOfAClassThroughThePipelinedLoopWithThreeBodies) {
  TwinCli cli("cw-run-shift");
  const fs::path out = cli.dir() / "out";
  const Outcome r = cli.run("run " + shell_quote(source_path("scenes/pipeline_shift.yaml")) + " -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("parts placed 10 (fed 10"));
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["result"], "ok");
  EXPECT_EQ(report["flow"]["placed"], 10);
  EXPECT_EQ(report["flow"]["fed"], 10);
  EXPECT_GE(report["flow"]["delivered"].get<int>(), 9);  // the last may still ride the output belt at the end
  EXPECT_GT(report["flow"]["steady_throughput_parts_per_min"].get<double>(), 0.0);
  EXPECT_TRUE(report["collisions"].empty()) << report["collisions"].dump();

  const std::string log = slurp(out / "events.jsonl");
  EXPECT_THAT(log, Not(HasSubstr("fault_detected")));
  // repeat 9: the loop's leader decided "again" 8 times, then "exit", and its follower took each decision.
  int agains_r1 = 0, agains_r2 = 0;
  // Who has which body now: a body is bound by one robot at a time, except at the hand-over, where the taker binds
  // the giver's part (the giver lets go right after).
  std::set<std::string> bodies;
  int picks = 0, takes = 0;
  std::istringstream lines(log);
  std::string line;
  std::string r1_has, r2_has;
  while (std::getline(lines, line)) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] == "fire" && e["transition"].get<std::string>().rfind("r1.again", 0) == 0) ++agains_r1;
    if (e["type"] == "fire" && e["transition"].get<std::string>().rfind("r2.again", 0) == 0) ++agains_r2;
    if (e["type"] == "sensor" && e["condition"] == "bound") {
      const std::string body = e["workpiece"].get<std::string>();
      bodies.insert(body);
      if (e["robot"] == "r1") {
        ++picks;
        EXPECT_NE(body, r2_has) << "r1 took the part r2 holds: " << line;
        r1_has = body;
      } else {
        ++takes;
        EXPECT_EQ(body, r1_has) << "r2 took another part than r1 handed over: " << line;
        r2_has = body;
      }
    }
  }
  EXPECT_EQ(agains_r1, 8);
  EXPECT_EQ(agains_r2, 8);
  EXPECT_EQ(picks, 10);
  EXPECT_EQ(takes, 10);
  EXPECT_EQ(bodies, (std::set<std::string>{"A", "B", "C"}));
}

}  // namespace
