// What every `twin` command shares, as a user meets it: --version, a mistyped command named as such, exit codes in
// every --help, output directories checked before anything runs, options that would be ignored refused, an empty
// program refused, and long analyses that show progress, stop on Ctrl-C and say when a net is too large.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>

#include "tools/twin_cli.hpp"

namespace cellwright::testing {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

constexpr const char* kCommands[] = {"compile", "check", "analyze", "snapshot", "run", "step", "serve", "emulate", "campaign"};

TEST(Cli, VersionNamesTheProjectAndMuJoCo) {
  TwinCli cli("cw-cli");
  const Outcome r = cli.run("--version");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("twin 0."));
  EXPECT_THAT(r.out, HasSubstr("(MuJoCo 2."));
}

TEST(Cli, AnUnknownCommandIsNamedAsSuch) {
  TwinCli cli("cw-cli");
  const Outcome r = cli.run("frob scenes/exchange.yaml");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("twin: unknown command 'frob' (commands: compile, check, analyze, snapshot, run, step, serve, "
                               "emulate, campaign"));
  EXPECT_EQ(cli.run("").status, 2);  // no command at all is a usage error too
}

TEST(Cli, EveryCommandsHelpSaysItsExitCodes) {
  TwinCli cli("cw-cli");
  EXPECT_THAT(cli.run("--help").out, HasSubstr("exits 0"));
  for (const char* command : kCommands) {
    const Outcome r = cli.run(std::string(command) + " --help");
    EXPECT_EQ(r.status, 0) << command;
    EXPECT_THAT(r.out, HasSubstr("2 on bad input")) << command << ":\n" << r.out;
  }
}

// A bad -o is refused before the scenario is even read: exit 2, the directory named, nothing written.
TEST(Cli, OutputDirectoryIsCheckedBeforeAnythingRuns) {
  TwinCli cli("cw-cli");
  const fs::path file = cli.dir() / "taken";
  std::ofstream(file) << "a file, not a directory\n";
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  for (const std::string& command : {std::string("run ") + scenario, std::string("step ") + scenario}) {
    for (const fs::path& out : {file, file / "out"}) {
      const Outcome r = cli.run(command + " -o " + shell_quote(out.string()));
      EXPECT_EQ(r.status, 2) << command << " -o " << out << "\n" << r.out << r.err;
      EXPECT_THAT(r.err, HasSubstr(out.string())) << command;
      EXPECT_THAT(r.err, HasSubstr("not a directory")) << command;
      EXPECT_THAT(r.out, Not(HasSubstr("t ="))) << command;  // nothing ran
    }
  }
  const Outcome campaign = cli.run("campaign " + scenario + " --runs 2 -o " + shell_quote((file / "c").string()));
  EXPECT_EQ(campaign.status, 2) << campaign.out << campaign.err;
  EXPECT_THAT(campaign.err, HasSubstr("not a directory"));
  EXPECT_EQ(slurp(file), "a file, not a directory\n");
}

// Options that would be ignored are refused instead: the old --out beside -o/--output (which one was meant?), and a
// run's outputs or pace with --dry, a bring-up that runs no program and writes nothing. Exit 2, nothing written.
// A folder given where a file belongs is called a folder, with its path, by every reader a user reaches: the
// scenario, the cell, a robot's URDF, the program, the recovery tree and a PNML net.
TEST(Cli, AFolderGivenAsAFileIsCalledAFolderNotMissing) {
  TwinCli cli("cw-cli-folder");
  const fs::path folder = cli.dir() / "a-folder";
  fs::create_directories(folder);
  const std::string scenes = source_path("scenes");
  // A scenario naming `field: a-folder`, the rest as scenes/single.yaml (paths absolute).
  const auto scenario_with = [&](const std::string& field) {
    std::string text = "cell: " + scenes + "/cell.yaml\nprogram: " + scenes + "/single.task\n" +
                       "locations:\n  - {name: mill_side, at: mill.fixture, offset: [0.14, 0, -0.03]}\n" +
                       "robots: {r1: puma}\nbind: {P: mill_side}\nexpect: {A: mill_side}\n";
    const std::string line = field + ": " + folder.string() + "\n";
    const auto at = text.find(field + ": ");
    if (at != std::string::npos) {
      text.replace(at, text.find('\n', at) + 1 - at, line);
    } else {
      text += line;
    }
    const fs::path file = cli.dir() / (field + ".yaml");
    std::ofstream(file) << text;
    return shell_quote(file.string());
  };
  std::string cell = slurp(source_path("scenes/cell.yaml"));
  const std::string puma_urdf = "urdf: ../models/urdf/puma560.urdf";
  ASSERT_NE(cell.find(puma_urdf), std::string::npos);
  cell.replace(cell.find(puma_urdf), puma_urdf.size(), "urdf: " + folder.string());
  std::ofstream(cli.dir() / "urdf-cell.yaml") << cell;

  const std::string words = folder.string() + ": error: ";
  struct Case {
    std::string args, expected;
  };
  for (const Case& c : {Case{"run " + shell_quote(folder.string()), words + "cannot read the scenario: is a directory, not a file"},
                        Case{"run " + scenario_with("cell"), words + "cannot read the cell description: is a directory, not a file"},
                        Case{"run " + scenario_with("program"), words + "cannot read the program: is a directory, not a file"},
                        Case{"run " + scenario_with("recovery"), words + "cannot read the decision tree file: is a directory, not a file"},
                        Case{"snapshot " + shell_quote((cli.dir() / "urdf-cell.yaml").string()) + " -o x.png",
                             "URDF file '" + folder.string() + "' is a directory, not a file"},
                        Case{"snapshot " + shell_quote(folder.string()) + " -o x.png",
                             words + "cannot read the cell description: is a directory, not a file"},
                        Case{"check " + shell_quote(folder.string()), words + "cannot read the program: is a directory, not a file"},
                        Case{"analyze " + shell_quote(folder.string()), words + "cannot read: is a directory, not a file"}}) {
    const Outcome r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.expected)) << c.args;
    EXPECT_THAT(r.err, Not(HasSubstr("not found"))) << c.args;
  }
}

TEST(Cli, OptionsThatWouldBeIgnoredAreRefused) {
  TwinCli cli("cw-cli");
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const std::string a = shell_quote((cli.dir() / "a").string()), b = shell_quote((cli.dir() / "b").string());
  for (const std::string& args :
       {"run " + scenario + " -o " + a + " --out " + b, "step " + scenario + " --output " + a + " --out " + b,
        "campaign " + scenario + " --runs 1 -o " + a + " --out " + b,
        "compile " + shell_quote(source_path("scenes/exchange.task")) + " --robot-language --scenario " + scenario +
            " -o " + a + " --out " + b}) {
    const Outcome r = cli.run(args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr("--out: error: the old name of -o/--output, given with it")) << args;
  }
  for (const std::string& option : {"-o " + a, "--video " + shell_quote((cli.dir() / "v.mp4").string()),
                                    "--save-frames " + a, std::string("--realtime")}) {
    const Outcome r = cli.run("run " + scenario + " --dry " + option);
    EXPECT_EQ(r.status, 2) << option << "\n" << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr("--dry: error: a bring-up runs no program and writes nothing: ")) << option;
  }
  EXPECT_FALSE(fs::exists(cli.dir() / "a"));
  EXPECT_FALSE(fs::exists(cli.dir() / "b"));
  EXPECT_FALSE(fs::exists(cli.dir() / "v.mp4"));
}

TEST(Cli, AnEmptyProgramIsBadInputNamingTheFile) {
  TwinCli cli("cw-cli");
  const fs::path empty = cli.dir() / "empty.task";
  std::ofstream(empty) << "# a program still to be written\n\n";
  for (const char* command : {"check", "compile"}) {
    const Outcome r = cli.run(std::string(command) + " " + shell_quote(empty.string()));
    EXPECT_EQ(r.status, 2) << command << "\n" << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr(empty.string() + ":1:")) << command;
    EXPECT_THAT(r.err, HasSubstr("the program is empty")) << command;
  }
}

// Eight robots each signalling twelve times, explored without reduction: 13^8 markings, far beyond any limit.
fs::path big_program(const fs::path& dir) {
  std::string text = "robot";
  for (int r = 1; r <= 8; ++r) text += " r" + std::to_string(r);
  text += "\nsemaphore";
  for (int r = 1; r <= 8; ++r) text += " s" + std::to_string(r);
  text += "\n";
  for (int r = 1; r <= 8; ++r) {
    text += "sequence r" + std::to_string(r) + "\n";
    for (int k = 0; k < 12; ++k) text += "  signal s" + std::to_string(r) + "\n";
    text += "end\n";
  }
  const fs::path p = dir / "big.task";
  std::ofstream(p) << text;
  return p;
}

TEST(Cli, ANetTooLargeSaysSoWithTheFigures) {
  TwinCli cli("cw-cli");
  const Outcome r =
      cli.run("check --reduction none --max-states 2000 " + shell_quote(big_program(cli.dir()).string()));
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("state limit of 2000 markings reached"));
  EXPECT_THAT(r.err, HasSubstr("note: exploration stopped (state limit of 2000 markings reached; raise "
                               "--max-states): 2000 markings explored in "));
  EXPECT_THAT(r.err, HasSubstr(" markings/s; state limit 2000)"));
}

// Ctrl-C (here SIGTERM, which the same handling takes) during a long check: a clean stop with a message and 130,
// after the progress line the check shows once it has run a second.
TEST(Cli, ALongCheckShowsProgressAndStopsOnASignal) {
  TwinCli cli("cw-cli");
  BackgroundTwin twin({"check", "--reduction", "none", "--max-states", "200000000", big_program(cli.dir()).string()});
  ASSERT_TRUE(twin.wait_for("markings", std::chrono::seconds(60))) << twin.output();
  EXPECT_EQ(twin.stop(), 130) << twin.output();
  EXPECT_THAT(twin.output(), HasSubstr("checking: "));
  EXPECT_THAT(twin.output(), HasSubstr("stopped: interrupted after "));
  EXPECT_THAT(twin.output(), HasSubstr("twin check: interrupted by the user; the verdict covers only what was "
                                       "explored"));
}

}  // namespace
}  // namespace cellwright::testing
