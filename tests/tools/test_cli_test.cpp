// `twin test` as CI runs it: bad input is refused with exit 2 before anything runs; a folder of two small scenarios,
// one passing and one failing its expectation, gives exit 1, a line each, the totals, the failing one's outputs kept
// and the passing one's removed, and JUnit XML that parses; a passing suite in the default temporary folder leaves
// nothing behind; --video records the failing one.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tinyxml2.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
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

std::string q(const fs::path& p) {
  return shell_quote(p.string());
}

// A tiny scenario in `dir` as NAME.yaml, quick to run (its program only signals; about one simulated second): the
// cell of scenes/, and the expectation that workpiece A, which nothing moves, ends at `expect` (it is at `input`).
void tiny(const fs::path& dir, const std::string& name, const std::string& expect) {
  fs::create_directories(dir);
  std::ofstream(dir / "tiny.task") << "robot r1\nsemaphore s\n\nsequence r1\n  signal s\nend\n";
  std::ofstream(dir / (name + ".yaml")) << "cell: " << source_path("scenes/cell.yaml")
                                        << "\nprogram: tiny.task\nrobots: {r1: puma}\n"
                                           "limits: {sim_time: 10, wall_time: 120}\nexpect: {A: "
                                        << expect << "}\n";
}

// A JUnit file read back: its <testsuite> (null when the file does not parse as JUnit) and its test cases by name.
struct Junit {
  explicit Junit(const fs::path& file) {
    const std::string xml = slurp(file);
    if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) return;
    const tinyxml2::XMLElement* suites = doc.FirstChildElement("testsuites");
    suite = suites ? suites->FirstChildElement("testsuite") : nullptr;
    for (auto* c = suite ? suite->FirstChildElement("testcase") : nullptr; c; c = c->NextSiblingElement("testcase")) {
      cases[c->Attribute("name")] = c;
    }
  }
  tinyxml2::XMLDocument doc;
  const tinyxml2::XMLElement* suite = nullptr;
  std::map<std::string, const tinyxml2::XMLElement*> cases;
};

TEST(TestCli, BadInputIsRefusedWithExitTwoBeforeAnythingRuns) {
  TwinCli cli("cw-test-cli-bad");
  const fs::path out = cli.dir() / "out";
  const std::string o = " -o " + q(out);
  struct Case {
    std::string args, message;
  };
  fs::create_directories(cli.dir() / "empty");
  std::ofstream(cli.dir() / "file") << "x";
  for (const Case& c : {
           Case{q(source_path("scenes/cell.yaml")), "cell.yaml: error: not a scenario: a cell description"},
           Case{q(source_path("scenes/recovery.yaml")), "recovery.yaml: error: not a scenario: a decision tree"},
           Case{q(source_path("scenes/no-such.yaml")), "no-such.yaml: error: no such file or folder"},
           Case{q(cli.dir() / "empty"), "empty: error: no scenario found"},
           Case{q(source_path("scenes/single.yaml")) + " --timeout 0", "--timeout: error: must be > 0 s"},
           Case{q(source_path("scenes/single.yaml")) + " --junit " + q(cli.dir()), "error: not a file name"},
           Case{q(source_path("scenes/single.yaml")) + " --junit " + q(cli.dir() / "file" / "j.xml"),
                "is not a directory"},
           Case{q(source_path("scenes/single.yaml")) + " --jobs -1", "--jobs"},
       }) {
    const Outcome r = cli.run("test " + c.args + o);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << c.args;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  const Outcome r = cli.run("test " + q(source_path("scenes/single.yaml")) + " -o " + q(cli.dir() / "file" / "out"));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("is not a directory"));
  EXPECT_THAT(cli.run("test --help").out, HasSubstr("-o,--output"));
}

TEST(TestCli, OnePassingOneFailingScenario) {
  TwinCli cli("cw-test-cli-run");
  const fs::path suite = cli.dir() / "suite", out = cli.dir() / "out", junit = cli.dir() / "reports" / "junit.xml";
  tiny(suite, "good", "input");
  tiny(suite, "bad", "output");
  std::ofstream(suite / "notes.yaml") << "just: notes\n";

  const Outcome r = cli.run("test " + q(suite) + " -o " + q(out) + " --junit " + q(junit) + " --jobs 2");
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("skipped " + (suite / "notes.yaml").string() +
                               ": a mapping without the fields `cell` and `program`, not a scenario\n"));
  EXPECT_THAT(r.out, HasSubstr("2 scenarios, 2 at a time\n"));
  EXPECT_THAT(r.out, ::testing::ContainsRegex("PASS   good  sim +[0-9.]+ s  wall +[0-9.]+ s  placed 0\n"));
  EXPECT_THAT(r.out, ::testing::ContainsRegex(
                         "FAIL   bad   sim +[0-9.]+ s  wall +[0-9.]+ s  placed 0  workpiece A must end at output"));
  EXPECT_THAT(r.out, HasSubstr("outputs of bad kept in " + (out / "bad").string() + "\n"));
  EXPECT_THAT(r.out, HasSubstr("JUnit XML in " + junit.string() + "\n"));
  EXPECT_THAT(r.out, ::testing::EndsWith("1 passed, 1 failed\n"));
  EXPECT_THAT(r.err, HasSubstr("2/2 scenarios, 0 running, 1 failed"));  // the progress line's last state

  // The failing one's outputs kept, the passing one's removed.
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "final.png", "stdout.txt", "stderr.txt"}) {
    EXPECT_TRUE(fs::exists(out / "bad" / f)) << f;
  }
  EXPECT_FALSE(fs::exists(out / "good"));

  const Junit xml(junit);
  ASSERT_NE(xml.suite, nullptr) << slurp(junit);
  EXPECT_STREQ(xml.suite->Attribute("tests"), "2");
  EXPECT_STREQ(xml.suite->Attribute("failures"), "1");
  EXPECT_STREQ(xml.suite->Attribute("errors"), "0");
  const auto& cases = xml.cases;
  ASSERT_EQ(cases.size(), 2u);
  EXPECT_EQ(cases.at("good")->FirstChildElement("failure"), nullptr);
  const tinyxml2::XMLElement* failure = cases.at("bad")->FirstChildElement("failure");
  ASSERT_NE(failure, nullptr);
  EXPECT_THAT(failure->Attribute("message"), HasSubstr("output"));
  // The report's text, as `twin run` printed it.
  ASSERT_NE(cases.at("bad")->FirstChildElement("system-out"), nullptr);
  EXPECT_EQ(cases.at("bad")->FirstChildElement("system-out")->GetText(), slurp(out / "bad" / "stdout.txt"));
}

// One YAML file that does not parse no longer aborts the suite without a JUnit file: it is an ERROR case naming its
// line, the others run, and the exit status is 1 (a case did not pass), not 2.
TEST(TestCli, AYamlFileThatDoesNotParseIsAnErrorCaseAndTheOthersRun) {
  TwinCli cli("cw-test-cli-parse");
  const fs::path suite = cli.dir() / "suite", out = cli.dir() / "out", junit = cli.dir() / "junit.xml";
  tiny(suite, "good", "input");
  std::ofstream(suite / "broken.yaml") << "cell: cell.yaml\nprogram: [tiny.task\n";

  const Outcome r = cli.run("test " + q(suite) + " -o " + q(out) + " --junit " + q(junit) + " --jobs 2");
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  const std::string where = (suite / "broken.yaml").string() + ":3:1: error: not valid YAML";
  EXPECT_THAT(r.out, HasSubstr("2 scenarios, 2 at a time\n"));
  EXPECT_THAT(r.out, ::testing::ContainsRegex("ERROR  broken  sim +-    wall +0.0 s  placed -  "));
  EXPECT_THAT(r.out, HasSubstr(where));
  EXPECT_THAT(r.out, ::testing::ContainsRegex("PASS   good    sim +[0-9.]+ s"));
  EXPECT_THAT(r.out, Not(HasSubstr("outputs of broken")));  // it wrote none
  EXPECT_THAT(r.out, ::testing::EndsWith("1 passed, 1 failed (1 refused)\n"));

  const Junit xml(junit);  // written though a file did not parse
  ASSERT_NE(xml.suite, nullptr) << slurp(junit);
  EXPECT_STREQ(xml.suite->Attribute("tests"), "2");
  EXPECT_STREQ(xml.suite->Attribute("errors"), "1");
  const auto& cases = xml.cases;
  ASSERT_EQ(cases.count("broken"), 1u);
  const tinyxml2::XMLElement* error = cases.at("broken")->FirstChildElement("error");
  ASSERT_NE(error, nullptr);
  EXPECT_THAT(error->Attribute("message"), HasSubstr(where));
  EXPECT_EQ(cases.at("good")->FirstChildElement("error"), nullptr);
}

TEST(TestCli, APassingSuiteInTheTemporaryFolderLeavesNothingBehind) {
  TwinCli cli("cw-test-cli-tmp");
  const fs::path suite = cli.dir() / "suite", tmp = cli.dir() / "tmp";
  tiny(suite, "good", "input");
  fs::create_directories(tmp);
  ::setenv("TMPDIR", tmp.c_str(), 1);
  const Outcome r = cli.run("test " + q(suite / "good.yaml") + " --jobs 1");
  ::unsetenv("TMPDIR");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, ::testing::EndsWith("1 passed, 0 failed\n"));
  EXPECT_THAT(r.out, Not(HasSubstr("kept")));
  EXPECT_TRUE(fs::is_empty(tmp));
}

// --video: the failed scenario is run again with a video, which joins its kept outputs with the page that shows it;
// the passing one is not recorded. A video size that cannot be, or --video-fps without --video, is refused before
// anything runs.
TEST(TestCli, VideoOfEachFailedScenario) {
  TwinCli cli("cw-test-cli-video");
  const fs::path suite = cli.dir() / "suite", out = cli.dir() / "out";
  tiny(suite, "good", "input");
  tiny(suite, "bad", "output");
  const Outcome refused = cli.run("test " + q(suite) + " -o " + q(out) + " --video --video-size 161x120");
  EXPECT_EQ(refused.status, 2) << refused.out << refused.err;
  EXPECT_THAT(refused.err, HasSubstr("even"));
  EXPECT_FALSE(fs::exists(out));

  const Outcome alone = cli.run("test " + q(suite) + " -o " + q(out) + " --video-fps 5");
  EXPECT_EQ(alone.status, 2) << alone.out << alone.err;
  EXPECT_THAT(alone.err, HasSubstr("--video"));
  EXPECT_FALSE(fs::exists(out));

  const Outcome r =
      cli.run("test " + q(suite) + " -o " + q(out) + " --jobs 2 --video --video-fps 5 --video-size 160x120");
  ASSERT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("recording the video of 1 failed scenario\n"));
  EXPECT_THAT(r.out, HasSubstr("video of bad in " + (out / "bad" / "video.mp4").string() + "\n"));
  EXPECT_THAT(r.out, ::testing::EndsWith("1 passed, 1 failed\n"));
  const std::string video = slurp(out / "bad" / "video.mp4");
  ASSERT_GT(video.size(), 1000u);
  EXPECT_EQ(video.substr(4, 4), "ftyp");
  EXPECT_THAT(slurp(out / "bad" / "index.html"), HasSubstr("src=\"video.mp4\""));
  for (const char* f : {"events.jsonl", "report.json", "stdout.txt"}) EXPECT_TRUE(fs::exists(out / "bad" / f)) << f;
  EXPECT_FALSE(fs::exists(out / "bad" / ".video"));
  EXPECT_FALSE(fs::exists(out / "good"));
}

}  // namespace
