// `twin check` and `twin compile` as a user runs them on the example programs in scenes/.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tools/twin_cli.hpp"

namespace cellwright::testing {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

std::string scene(const std::string& name) {
  return shell_quote(source_path("scenes/" + name));
}

TEST(CheckCli, Table1ExchangeAndSinglePickPlacePass) {
  TwinCli cli("cw-check");
  for (const char* program : {"exchange.task", "pick_place.task", "regions.task"}) {
    const Outcome r = cli.run("check " + scene(program));
    EXPECT_EQ(r.status, 0) << program << "\n" << r.out << r.err;
    EXPECT_THAT(r.out, HasSubstr("OK")) << program;
  }
}

TEST(CheckCli, CrossedWaitsAreRefusedWithTheCounterexample) {
  TwinCli cli("cw-check");
  const Outcome r = cli.run("check " + scene("deadlock.task"));
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("deadlock"));
  // The counterexample is told in the program's terms: both robots stuck in their waits, with the lines.
  EXPECT_THAT(r.out, HasSubstr("r1: waiting for event s1"));
  EXPECT_THAT(r.out, HasSubstr("r2: waiting for event s2"));
  EXPECT_THAT(r.out, HasSubstr("line "));
}

TEST(CheckCli, JsonReportHasTheFiguresUsersScriptAgainst) {
  TwinCli cli("cw-check");
  const Outcome ok = cli.run("check --json " + scene("exchange.task"));
  ASSERT_EQ(ok.status, 0) << ok.err;
  const auto j = nlohmann::json::parse(ok.out);
  for (const char* key : {"states", "edges", "deadlocks", "bounded", "mutex_ok"}) EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_GT(j["states"].get<int>(), 1);
  EXPECT_EQ(j["deadlocks"].get<int>(), 0);
  EXPECT_TRUE(j["bounded"].get<bool>());
  EXPECT_TRUE(j["mutex_ok"].get<bool>());

  const Outcome bad = cli.run("check --json " + scene("deadlock.task"));
  EXPECT_EQ(bad.status, 1);
  EXPECT_EQ(nlohmann::json::parse(bad.out)["deadlocks"].get<int>(), 1);
}

TEST(CheckCli, StateLimitStopsWithAClearMessageAndNonZeroExit) {
  TwinCli cli("cw-check");
  const Outcome r = cli.run("check --max-states 3 " + scene("exchange.task"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.out, HasSubstr("state limit"));
}

// Issue 27's coordinated level: the shipped carry passes; the same block run by one robot only is refused before the
// run with the firing sequence that leaves the other waiting at the block's first barrier; a malformed block is bad
// input with its line.
TEST(CheckCli, ACoordinatedBlockOnlyOneRobotReachesIsRefused) {
  TwinCli cli("cw-check");
  const Outcome ok = cli.run("check " + scene("beam.task"));
  EXPECT_EQ(ok.status, 0) << ok.out << ok.err;
  EXPECT_THAT(ok.out, HasSubstr("OK"));
  const Outcome listing = cli.run("compile " + scene("beam.task"));
  EXPECT_EQ(listing.status, 0) << listing.err;
  EXPECT_THAT(listing.out, HasSubstr("carry (8:13): master left, follower right, carrying beam, 10 segments"));

  const auto one = cli.dir() / "one.task";
  std::ofstream(one) << "robot left right\nworkpiece beam\nlocation FIX\n"
                        "coordinated carry master left follower right\n  Pick beam\n  Place FIX\nend\n"
                        "sequence left\n  coordinate carry\nend\nsequence right\n  home\nend\n";
  const Outcome bad = cli.run("check " + shell_quote(one.string()));
  EXPECT_EQ(bad.status, 1) << bad.out << bad.err;
  EXPECT_THAT(bad.out, HasSubstr("deadlock after"));
  EXPECT_THAT(bad.out, HasSubstr("left: waiting for event carry.s1.right>left (line 9 'coordinate carry')"));

  const auto broken = cli.dir() / "broken.task";
  std::ofstream(broken) << "robot left right\nworkpiece beam\ncoordinated carry master left follower right\n"
                           "  Pick beam\nend\n";
  const Outcome refused = cli.run("check " + shell_quote(broken.string()));
  EXPECT_EQ(refused.status, 2);
  EXPECT_THAT(refused.err, HasSubstr("broken.task:5:1: error: coordinated block 'carry' (line 3) ends without a "
                                     "Place"));
}

TEST(CheckCli, BadProgramNamesFileLineAndProblem) {
  TwinCli cli("cw-check");
  const auto path = cli.dir() / "bad.task";
  std::ofstream(path) << "robot r1\nworkpiece A\nsequence r1\n  Pick Z\nend\n";
  const Outcome r = cli.run("check " + shell_quote(path.string()));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("bad.task:4:"));
  EXPECT_THAT(r.err, HasSubstr("'Z'"));
  const Outcome missing = cli.run("check " + shell_quote((cli.dir() / "nope.task").string()));
  EXPECT_EQ(missing.status, 2);
  EXPECT_THAT(missing.err, HasSubstr("nope.task"));
}

TEST(CheckCli, ReducedByDefaultWithTheSameVerdictsAsFullExploration) {
  TwinCli cli("cw-check");
  for (const char* program : {"exchange.task", "regions.task", "deadlock.task", "pipeline.task"}) {
    SCOPED_TRACE(program);
    const Outcome red = cli.run("check --json " + scene(program));
    const Outcome full = cli.run("check --json --reduction none " + scene(program));
    ASSERT_EQ(red.status, full.status) << red.out << red.err;
    const auto r = nlohmann::json::parse(red.out), f = nlohmann::json::parse(full.out);
    EXPECT_EQ(r["reduction"], "stubborn");
    EXPECT_EQ(f["reduction"], "none");
    EXPECT_EQ(r["reduced"], true);
    EXPECT_EQ(f["reduced"], false);
    for (const char* key : {"ok", "deadlocks", "final_states", "bounded", "mutex_ok"}) EXPECT_EQ(r[key], f[key]) << key;
    EXPECT_LE(r["states"].get<std::uint64_t>(), f["states"].get<std::uint64_t>());
    // The net reduction (commands that always follow one another fused) keeps the verdicts and the counts above;
    // its deadlock path is the program's own firing sequence, only not necessarily a shortest one.
    const bool agglomerated = !r["net_reduction"].get<std::string>().empty();
    EXPECT_TRUE(agglomerated) << "every shipped program has commands in a row";
    EXPECT_THAT(r["net_reduction"].get<std::string>(), HasSubstr("before exploring, the net was reduced from"));
    EXPECT_EQ(f["net_reduction"], "");
    EXPECT_EQ(r["deadlock_path_shortest"], !agglomerated);
    if (!f["deadlock_path"].is_null()) {
      EXPECT_GE(r["deadlock_path"].size(), f["deadlock_path"].size());
      EXPECT_EQ(r["deadlock_marking"], f["deadlock_marking"]);  // deadlock.task has one dead marking
    }
    // A fast check prints no progress line.
    EXPECT_EQ(red.err, "");
  }
  const Outcome text = cli.run("check " + scene("exchange.task"));
  EXPECT_EQ(text.status, 0) << text.out << text.err;
  EXPECT_THAT(text.out, HasSubstr("markings explored (reduced)"));
  const Outcome exact = cli.run("check --reduction none " + scene("exchange.task"));
  EXPECT_THAT(exact.out, HasSubstr("explored "));
  EXPECT_THAT(exact.out, Not(HasSubstr("(reduced)")));
}

// Issue 27's shapes as a user writes them: N free sequences sharing one region (each enters it twice), and N
// "philosophers" taking their own region and their neighbour's.
std::string shared_region(int n) {
  std::string s = "robot";
  for (int i = 1; i <= n; ++i) s += " r" + std::to_string(i);
  s += "\nworkpiece";
  for (int i = 1; i <= n; ++i) s += " A" + std::to_string(i);
  s += "\nlocation";
  for (int i = 1; i <= n; ++i) s += " F" + std::to_string(i) + " O" + std::to_string(i);
  s += "\nregion zone\n";
  for (int i = 1; i <= n; ++i) {
    const std::string k = std::to_string(i);
    s += "sequence r" + k + "\n  Pick A" + k + "\n  enter zone\n  Place F" + k + "\n  leave zone\n  home\n  enter zone\n" +
         "  Pick A" + k + "\n  leave zone\n  Place O" + k + "\nend\n";
  }
  return s;
}
std::string philosophers(int n) {
  std::string s = "robot";
  for (int i = 1; i <= n; ++i) s += " r" + std::to_string(i);
  s += "\nworkpiece";
  for (int i = 1; i <= n; ++i) s += " A" + std::to_string(i);
  s += "\nlocation";
  for (int i = 1; i <= n; ++i) s += " F" + std::to_string(i);
  s += "\nregion";
  for (int i = 1; i <= n; ++i) s += " Z" + std::to_string(i);
  s += "\n";
  for (int i = 1; i <= n; ++i) {
    const std::string k = std::to_string(i), next = std::to_string(i % n + 1);
    s += "sequence r" + k + "\n  Pick A" + k + "\n  enter Z" + k + "\n  enter Z" + next + "\n  Place F" + k +
         "\n  leave Z" + next + "\n  leave Z" + k + "\n  home\nend\n";
  }
  return s;
}

TEST(CheckCli, SharedRegionPassesAndPhilosophersAreRefusedFromTheNetsStructure) {
  TwinCli cli("cw-check");
  const auto shared = cli.dir() / "shared.task";
  std::ofstream(shared) << shared_region(12);
  const Outcome ok = cli.run("check " + shell_quote(shared.string()));
  EXPECT_EQ(ok.status, 0) << ok.out << ok.err;
  EXPECT_THAT(ok.out, HasSubstr("OK: no deadlock, bounded, mutual exclusion holds"));
  EXPECT_THAT(ok.out, HasSubstr("no deadlock: no marking the state equation allows is dead"));
  EXPECT_THAT(ok.out, HasSubstr("region zone: exclusive, by a place invariant (never more than 1 inside"));

  const auto table = cli.dir() / "philosophers.task";
  std::ofstream(table) << philosophers(50);
  const Outcome bad = cli.run("check --json " + shell_quote(table.string()));
  EXPECT_EQ(bad.status, 1) << bad.out << bad.err;
  const auto j = nlohmann::json::parse(bad.out);
  EXPECT_EQ(j["ok"], false);
  EXPECT_EQ(j["complete"], true);
  EXPECT_EQ(j["explored_all"], false);
  EXPECT_EQ(j["deadlock_path_shortest"], false);
  EXPECT_EQ(j["deadlocks_counted"], false);
  EXPECT_FALSE(j["deadlock_path"].empty());
  EXPECT_THAT(j["deadlock_description"].get<std::string>(), HasSubstr("r50: waiting for region Z1 free"));
}

TEST(CheckCli, ExplorationBudgetIsAnOptionAndBadValuesAreRefused) {
  TwinCli cli("cw-check");
  const auto shared = cli.dir() / "shared.task";
  std::ofstream(shared) << shared_region(3);
  // A budget of one marking: deadlock freedom comes from the state equation, not from exploring to the end.
  const Outcome small = cli.run("check --json --exploration-budget 1 " + shell_quote(shared.string()));
  ASSERT_EQ(small.status, 0) << small.out << small.err;
  const auto j = nlohmann::json::parse(small.out);
  EXPECT_FALSE(j["explored_all"].get<bool>());
  EXPECT_THAT(j["deadlock_proof"].get<std::string>(), HasSubstr("state equation"));
  // No budget: explored to the end, the same verdict.
  const Outcome none = cli.run("check --json --exploration-budget 0 " + shell_quote(shared.string()));
  ASSERT_EQ(none.status, 0) << none.out << none.err;
  const auto n = nlohmann::json::parse(none.out);
  EXPECT_TRUE(n["explored_all"].get<bool>());
  EXPECT_EQ(n["deadlock_proof"], "");
  for (const char* bad : {"-1", "many", "1.5", "''"}) {
    const Outcome r = cli.run(std::string("check --exploration-budget ") + bad + " " + scene("exchange.task"));
    EXPECT_EQ(r.status, 2) << bad;
    EXPECT_THAT(r.err, HasSubstr("--exploration-budget")) << bad << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr("a whole number of markings, 0 or more")) << bad << ": " << r.err;
  }
}

TEST(CheckCli, UnknownReductionIsBadInput) {
  TwinCli cli("cw-check");
  const Outcome r = cli.run("check --reduction symmetric " + scene("exchange.task"));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("symmetric"));
}

TEST(CompileCli, DotAndPnmlExportOfTheProgramNet) {
  TwinCli cli("cw-compile");
  const auto pnml = cli.dir() / "exchange.pnml";
  const Outcome r = cli.run("compile --dot --pnml " + shell_quote(pnml.string()) + " " + scene("exchange.task"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("digraph"));
  EXPECT_THAT(r.out, HasSubstr("r1"));
  // The PNML written is the same net: analysing it gives the figures `twin check` gives for the program.
  const Outcome from_pnml = cli.run("analyze --json " + shell_quote(pnml.string()));
  const Outcome from_program = cli.run("check --json --reduction none " + scene("exchange.task"));
  ASSERT_EQ(from_pnml.status, 0) << from_pnml.out << from_pnml.err;
  const auto a = nlohmann::json::parse(from_pnml.out), b = nlohmann::json::parse(from_program.out);
  for (const char* key : {"states", "edges", "deadlocks", "final_states"}) EXPECT_EQ(a[key], b[key]) << key;
}

TEST(CompileCli, ListingShowsEachRobotsPrimitives) {
  TwinCli cli("cw-compile");
  const Outcome r = cli.run("compile " + scene("exchange.task"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("move above(A)"));
  EXPECT_THAT(r.out, HasSubstr("close A"));
  EXPECT_THAT(r.out, HasSubstr("signal "));
}

// `--robot-language -o DIR`: each robot's program in its controller's language, a file per robot named in the
// output; `--out`, the option's old name, writes the same files; the option's misuses are refused with exit 2 and
// nothing written.
TEST(CompileCli, RobotLanguageWritesAProgramPerRobotIntoTheOutputDirectory) {
  TwinCli cli("cw-compile-rl");
  const std::string base = "compile " + scene("exchange.task") + " --scenario " + scene("exchange.yaml") +
                           " --robot-language --driver puma=val2 --driver melfa=movemaster ";
  const auto dir = cli.dir() / "programs";
  const Outcome r = cli.run(base + "-o " + shell_quote(dir.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("puma (r1): " + dir.string() + "/puma.val2"));
  EXPECT_THAT(r.out, HasSubstr("melfa (r2): " + dir.string() + "/melfa.movemaster"));
  const std::string val2 = slurp(dir / "puma.val2"), movemaster = slurp(dir / "melfa.movemaster");
  EXPECT_THAT(val2, HasSubstr("VAL II: written by twin compile --robot-language"));
  EXPECT_THAT(movemaster, HasSubstr("Movemaster EX: written by twin compile --robot-language"));

  const auto old = cli.dir() / "old";
  const Outcome by_old_name = cli.run(base + "--out " + shell_quote(old.string()));
  ASSERT_EQ(by_old_name.status, 0) << by_old_name.err;
  EXPECT_EQ(slurp(old / "puma.val2"), val2);
  EXPECT_EQ(slurp(old / "melfa.movemaster"), movemaster);

  const auto stray = cli.dir() / "stray";
  const Outcome without_language = cli.run("compile " + scene("exchange.task") + " -o " + shell_quote(stray.string()));
  EXPECT_EQ(without_language.status, 2);
  EXPECT_THAT(without_language.err, HasSubstr("-o/--output"));
  EXPECT_THAT(without_language.err, HasSubstr("--robot-language"));
  EXPECT_FALSE(std::filesystem::exists(stray));

  const Outcome without_output = cli.run(base);
  EXPECT_EQ(without_output.status, 2);
  EXPECT_THAT(without_output.err, HasSubstr("needs -o/--output DIR"));

  const auto file = cli.dir() / "a_file";
  std::ofstream(file) << "not a directory";
  const Outcome under_a_file = cli.run(base + "-o " + shell_quote((file / "programs").string()));
  EXPECT_EQ(under_a_file.status, 2);
  EXPECT_THAT(under_a_file.err, HasSubstr((file / "programs").string()));
  EXPECT_EQ(slurp(file), "not a directory");
}

}  // namespace
}  // namespace cellwright::testing
