// Bad input a new user meets, over the built `twin`: an output directory of the user's own is never written over
// unasked (`-o DIR` of run, step, campaign, test and compile --robot-language), a URDF that MuJoCo refuses is named at its own line, and robots
// that overlap at the start are one error wherever the cell is used.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
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
using ::testing::Not;

const std::string kSingle = shell_quote(source_path("scenes/single.yaml"));

// A directory of the user's own: their notes, an index.html and a report.json of their own.
fs::path users_directory(const fs::path& dir) {
  fs::create_directories(dir);
  std::ofstream(dir / "index.html") << "<p>my page</p>\n";
  std::ofstream(dir / "report.json") << "{\"mine\": true}\n";
  std::ofstream(dir / "notes.txt") << "mine\n";
  return dir;
}

// The names in `dir`, sorted.
std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

void expect_untouched(const fs::path& dir) {
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"index.html", "notes.txt", "report.json"}));
  EXPECT_EQ(slurp(dir / "index.html"), "<p>my page</p>\n");
  EXPECT_EQ(slurp(dir / "report.json"), "{\"mine\": true}\n");
}

TEST(OutputDirectoryCli, RunAndStepRefuseAUsersDirectoryNamingTheFilesAndWriteNothing) {
  TwinCli cli("cw-outdir-run");
  const fs::path mine = users_directory(cli.dir() / "mine");
  for (const std::string command : {"run", "step"}) {
    SCOPED_TRACE(command);
    const std::string quit = "q\n";
    const Outcome r = cli.run(command + " " + kSingle + " -o " + shell_quote(mine.string()), &quit);
    EXPECT_EQ(r.status, 2) << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr(mine.string() + ": error: is not an output directory of Cellwright's (it has no "
                                                  ".cellwright-output) and holds 2 files this command would "
                                                  "overwrite: report.json, index.html"));
    EXPECT_THAT(r.err, HasSubstr("--force"));
    expect_untouched(mine);
  }
}

TEST(OutputDirectoryCli, ForceWritesIntoItAndTheMarkedDirectoryIsOursFromThenOn) {
  TwinCli cli("cw-outdir-force");
  const fs::path mine = users_directory(cli.dir() / "mine");
  const Outcome forced = cli.run("run " + kSingle + " --quiet --final-png never --force -o " + shell_quote(mine.string()));
  EXPECT_EQ(forced.status, 0) << forced.out << forced.err;
  EXPECT_NE(slurp(mine / "index.html"), "<p>my page</p>\n");
  EXPECT_EQ(slurp(mine / "notes.txt"), "mine\n");  // what the run does not write is left alone
  const std::string marker = slurp(mine / ".cellwright-output");
  EXPECT_THAT(marker, HasSubstr("run"));
  EXPECT_THAT(marker, HasSubstr("--force"));
  // Marked: the next run replaces its own outputs without being asked.
  const Outcome again = cli.run("run " + kSingle + " --quiet --final-png never -o " + shell_quote(mine.string()));
  EXPECT_EQ(again.status, 0) << again.out << again.err;
}

TEST(OutputDirectoryCli, ANewOrEmptyDirectoryOrOneWithOtherFilesIsUsedAndMarked) {
  TwinCli cli("cw-outdir-new");
  const fs::path other = cli.dir() / "other";
  fs::create_directories(other);
  std::ofstream(other / "notes.txt") << "mine\n";  // nothing of the run's names: nothing is overwritten
  const Outcome r = cli.run("run " + kSingle + " --quiet --final-png never -o " + shell_quote(other.string()));
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_TRUE(fs::exists(other / ".cellwright-output"));
  EXPECT_TRUE(fs::exists(other / "report.json"));
  EXPECT_EQ(slurp(other / "notes.txt"), "mine\n");
}

TEST(OutputDirectoryCli, CampaignAndTestRefuseAUsersDirectory) {
  TwinCli cli("cw-outdir-campaign");
  const fs::path mine = cli.dir() / "mine";
  fs::create_directories(mine / "runs");
  std::ofstream(mine / "campaign.md") << "my campaign notes\n";
  const Outcome campaign = cli.run("campaign " + kSingle + " --runs 1 -o " + shell_quote(mine.string()));
  EXPECT_EQ(campaign.status, 2) << campaign.out << campaign.err;
  EXPECT_THAT(campaign.err, HasSubstr("holds 2 files this command would overwrite: campaign.md, runs"));
  EXPECT_EQ(names_in(mine), (std::vector<std::string>{"campaign.md", "runs"}));
  EXPECT_TRUE(fs::is_empty(mine / "runs"));

  // A suite writes OUT/NAME per scenario: a folder of the user's holding a "single" is refused, nothing run.
  const fs::path suite = cli.dir() / "suite";
  fs::create_directories(suite / "single");
  std::ofstream(suite / "single" / "mine.txt") << "mine\n";
  const Outcome test = cli.run("test " + kSingle + " -o " + shell_quote(suite.string()));
  EXPECT_EQ(test.status, 2) << test.out << test.err;
  EXPECT_THAT(test.err, HasSubstr((suite / "single").string() + ": error: exists and is not the outputs of an "
                                                                  "earlier run (it has no .cellwright-output)"));
  EXPECT_EQ(slurp(suite / "single" / "mine.txt"), "mine\n");
  EXPECT_FALSE(fs::exists(suite / ".cellwright-output"));
}

// `twin compile --robot-language -o DIR` writes one file a robot: a directory of the user's own holding a file of
// that name is refused before anything is written, --force writes into it and marks it, a new one is marked.
TEST(OutputDirectoryCli, CompileRobotLanguageRefusesAUsersDirectoryHoldingAProgramsName) {
  TwinCli cli("cw-outdir-compile");
  const fs::path mine = cli.dir() / "mine";
  fs::create_directories(mine);
  std::ofstream(mine / "puma.val2") << "my own VAL II program\n";
  const std::string compile = "compile " + shell_quote(source_path("scenes/exchange.task")) + " --scenario " +
                              shell_quote(source_path("scenes/exchange.yaml")) +
                              " --robot-language --driver puma=val2 --driver melfa=movemaster -o ";
  const Outcome r = cli.run(compile + shell_quote(mine.string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(mine.string() + ": error: is not an output directory of Cellwright's (it has no "
                                                ".cellwright-output) and holds 1 file this command would overwrite: "
                                                "puma.val2"));
  EXPECT_EQ(names_in(mine), std::vector<std::string>{"puma.val2"});
  EXPECT_EQ(slurp(mine / "puma.val2"), "my own VAL II program\n");

  const Outcome forced = cli.run(compile + shell_quote(mine.string()) + " --force");
  EXPECT_EQ(forced.status, 0) << forced.out << forced.err;
  EXPECT_EQ(names_in(mine), (std::vector<std::string>{".cellwright-output", "melfa.movemaster", "puma.val2"}));
  EXPECT_THAT(slurp(mine / "puma.val2"), Not(HasSubstr("my own")));

  const fs::path fresh = cli.dir() / "fresh";
  const Outcome made = cli.run(compile + shell_quote(fresh.string()));
  EXPECT_EQ(made.status, 0) << made.out << made.err;
  EXPECT_EQ(names_in(fresh), (std::vector<std::string>{".cellwright-output", "melfa.movemaster", "puma.val2"}));
}

// A URDF element that MuJoCo's compiler refuses is named at its own line in the URDF, with the cell's robot entry.
TEST(BadCellCli, SnapshotNamesTheUrdfLineMujocoRefuses) {
  TwinCli cli("cw-bad-urdf");
  std::string urdf = slurp(source_path("models/urdf/puma560.urdf"));
  const std::string box = R"(<geometry><box size="0.58 0.14 0.10"/></geometry>
    </collision>)";
  const auto at = urdf.find(box);
  ASSERT_NE(at, std::string::npos);
  urdf.replace(at, box.size(), R"(<geometry><box size="0.58 0 0.10"/></geometry>
    </collision>)");
  const auto collision = urdf.rfind("<collision>", at);
  const int line = 1 + static_cast<int>(std::count(urdf.begin(), urdf.begin() + static_cast<long>(collision), '\n'));
  std::ofstream(cli.dir() / "puma.urdf") << urdf;
  std::string cell = slurp(source_path("scenes/cell.yaml"));
  const std::string entry = "urdf: ../models/urdf/puma560.urdf";
  ASSERT_NE(cell.find(entry), std::string::npos);
  cell.replace(cell.find(entry), entry.size(), "urdf: puma.urdf");
  for (std::size_t p = cell.find("../models/"); p != std::string::npos; p = cell.find("../models/", p)) {
    cell.replace(p, 3, source_path(""));
  }
  std::ofstream(cli.dir() / "cell.yaml") << cell;
  const Outcome r = cli.run("snapshot " + shell_quote((cli.dir() / "cell.yaml").string()) + " -o " +
                            shell_quote((cli.dir() / "x.png").string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(fmt::format("{}:{}: error: robot 'puma' ({}:", (cli.dir() / "puma.urdf").string(),
                                           line, (cli.dir() / "cell.yaml").string())));
  EXPECT_THAT(r.err, HasSubstr("link 'link2' (its <collision>): MuJoCo rejects it: sizes must be positive"));
  EXPECT_FALSE(fs::exists(cli.dir() / "x.png"));
}

// Two robots whose arms overlap at home: one error naming both bodies and the depth, from snapshot (which still draws
// the picture, to show it) and from run (which runs nothing).
TEST(BadCellCli, RobotsThatOverlapAtTheStartAreOneError) {
  TwinCli cli("cw-overlap");
  const std::string cell = source_path("tests/data/overlap/cell.yaml");
  const fs::path png = cli.dir() / "x.png";
  const Outcome snapshot = cli.run("snapshot " + shell_quote(cell) + " -o " + shell_quote(png.string()));
  EXPECT_EQ(snapshot.status, 2) << snapshot.out << snapshot.err;
  const std::string error = "error: at the start, with every robot at home: robot 'p1''s link '";
  EXPECT_THAT(snapshot.err, HasSubstr(cell + ":7:5: " + error));
  EXPECT_THAT(snapshot.err, HasSubstr("and robot 'p2''s link '"));
  EXPECT_THAT(snapshot.err, HasSubstr(" mm; move a robot's base or change its home"));
  EXPECT_THAT(snapshot.err, HasSubstr("written all the same, to show the overlap"));
  EXPECT_TRUE(fs::exists(png));

  const fs::path out = cli.dir() / "out";
  const Outcome run = cli.run("run " + shell_quote(source_path("tests/data/overlap/overlap.yaml")) + " -o " +
                              shell_quote(out.string()));
  EXPECT_EQ(run.status, 2) << run.out << run.err;
  EXPECT_THAT(run.err, HasSubstr(cell + ":7:5: " + error));
  EXPECT_THAT(run.err, Not(HasSubstr("predicted collision")));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;  // one line, one cause
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
