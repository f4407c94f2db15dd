// A robot that makes no progress is named and escalated, not left to the time limit (issue 24, docs/faults.md
// `no_progress`), seen through `twin run` as a user runs it:
//  - scenes/vision.yaml without the camera (--perception cad): the PUMA misses A, sets it aside, and its depart from the
//    belt drags what is caught in its closed fingers: the wrist force stops it, it is released, stops again. Before,
//    987 protective stops until the 120 s limit; now the fifth interruption is no_progress and the tree stops the cell.
//  - a three-robot relay (tests/data/relay) whose part is dropped by the first robot and set aside: the second and
//    third robots wait for a part of their class that will never come. Before, idle until the 150 s limit; now each
//    waits progress_timeout, the tree skips its work for the lost part, and the run ends.
//  - the relay without its part (--fault missing): the first robot waits for a part of its class that never comes; now
//    no_progress after progress_timeout, nothing lost upstream, the cell stopped safely, the missing part detected.
//  - the same relay with the second robot's fingers closing along the belt at the stop bar (blocked.yaml): the grip
//    never ends. Before, "controller_not_answering"; now an obstruction, from what the robot senses.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
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

std::vector<nlohmann::json> events_of(const fs::path& out, const std::string& type) {
  std::vector<nlohmann::json> found;
  std::istringstream lines(slurp(out / "events.jsonl"));
  std::string line;
  while (std::getline(lines, line)) {
    nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] == type) found.push_back(std::move(e));
  }
  return found;
}

TEST(ProgressCli, AnArmStoppedAgainAndAgainWithoutTheCameraIsNamedAndTheCellStoppedLongBeforeTheLimit) {
  TwinCli cli("cw-progress-cad");
  const fs::path out = cli.dir() / "cad";
  const Outcome r = cli.run("run " + shell_quote(source_path("scenes/vision.yaml")) + " --perception cad --quiet -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "stopped") << r.out;
  EXPECT_LT(report["end_time"].get<double>(), 60.0) << "the limit is 120 s";
  EXPECT_LT(events_of(out, "protective_stop").size(), 10u) << "987 before";
  bool named = false;
  for (const auto& d : events_of(out, "diagnosis")) {
    if (d["symptom"] == "no_progress") {
      named = true;
      EXPECT_EQ(d["robot"], "r1");
      EXPECT_EQ(d["cause"], "livelock");
      EXPECT_EQ(d["action"], "stop_cell");
    }
  }
  EXPECT_TRUE(named) << "no no_progress diagnosis";
  const auto stopped = events_of(out, "cell_stopped");
  ASSERT_EQ(stopped.size(), 1u);
  EXPECT_THAT(stopped[0].dump(), HasSubstr("livelock"));
  EXPECT_THAT(r.out, HasSubstr("livelock"));
}

TEST(ProgressCli, ARelayWhosePartWasSetAsideUpstreamGoesOnInsteadOfWaitingForTheLimit) {
  TwinCli cli("cw-progress-relay");
  const fs::path out = cli.dir() / "relay";
  const Outcome r = cli.run("run " + shell_quote(source_path("tests/data/relay/relay_scrap.yaml")) +
                            " --fault drop:robot=p1,carry=1 --quiet -o " + shell_quote(out.string()));
  EXPECT_EQ(r.status, 0) << r.out << r.err;  // the scenario expects A lost
  ASSERT_TRUE(fs::exists(out / "report.json")) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "finished") << r.out;
  EXPECT_LT(report["end_time"].get<double>(), 140.0) << "the limit is 150 s";
  const auto lost = events_of(out, "workpiece_lost");
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_EQ(lost[0]["workpiece"], "A");
  // r2 and r3 waited for a part of their class, named it, and skipped their work for the lost part.
  std::vector<std::string> who;
  for (const auto& d : events_of(out, "diagnosis")) {
    if (d["symptom"] != "no_progress") continue;
    who.push_back(d["robot"]);
    EXPECT_EQ(d["cause"], "part_lost_upstream");
    EXPECT_EQ(d["action"], "set_aside");
    EXPECT_EQ(d["path"], "waiting_for_part=yes part_lost=yes");
  }
  EXPECT_EQ(who, (std::vector<std::string>{"r2", "r3"}));
  std::vector<std::string> skippers;
  for (const auto& s : events_of(out, "skipped")) skippers.push_back(s["robot"]);
  EXPECT_THAT(skippers, ::testing::Contains("r2"));
  EXPECT_THAT(skippers, ::testing::Contains("r3"));
}

TEST(ProgressCli, APartThatNeverComesForAClassStopsTheCellAndIsTheMissingFaultsDetection) {
  TwinCli cli("cw-progress-missing");
  const fs::path out = cli.dir() / "missing";
  const Outcome r = cli.run("run " + shell_quote(source_path("tests/data/relay/relay.yaml")) +
                            " --fault missing:workpiece=A --quiet -o " + shell_quote(out.string()));
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "stopped") << r.out;
  EXPECT_LT(report["end_time"].get<double>(), 60.0) << "the limit is 150 s";
  ASSERT_EQ(report["faults"].size(), 1u);
  const nlohmann::json& f = report["faults"][0];
  EXPECT_EQ(f["kind"], "missing");
  EXPECT_EQ(f["detected"], true);
  EXPECT_EQ(f["symptom"], "no_progress");
  EXPECT_EQ(f["cause"], "part_never_ready");
  EXPECT_EQ(f["action"], "stop_cell");
  EXPECT_EQ(f["stopped_safely"], true);
}

TEST(ProgressCli, FingersBlockedAtAStopBarAreAnObstructionNotASilentController) {
  TwinCli cli("cw-progress-blocked");
  const fs::path out = cli.dir() / "blocked";
  const Outcome r = cli.run("run " + shell_quote(source_path("tests/data/relay/blocked.yaml")) + " --quiet -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("obstruction"));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("controller_not_answering")));
  const auto diagnoses = events_of(out, "diagnosis");
  ASSERT_FALSE(diagnoses.empty());
  for (const auto& d : diagnoses) {
    EXPECT_EQ(d["robot"], "r2");
    EXPECT_EQ(d["symptom"], "driver_timeout");
    EXPECT_THAT(d["path"].get<std::string>(), HasSubstr("motion_blocked=yes"));
  }
  EXPECT_EQ(diagnoses.back()["cause"], "obstruction");
  EXPECT_EQ(diagnoses.back()["action"], "stop_cell");
}

}  // namespace
