// The regression suite's parts: which YAML files are scenarios (by content: the shipped scenes/ and made-up folders
// with cell descriptions, decision trees, other YAML and subfolders), the plan (names, output folders, time limits),
// the verdicts of children that pass, fail, are refused, crash or hang (a stand-in executable), the lines, and the
// JUnit XML parsed back with tinyxml2.
#include "cellwright/cell/suite.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tinyxml2.h>

#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cell/report_files.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kScenes = fs::path(CW_SOURCE_DIR) / "scenes";

// A scratch directory, removed afterwards.
class Scratch {
 public:
  explicit Scratch(const std::string& tag)
      : dir_(fs::temp_directory_path() / fmt::format("cw-suite-{}-{}", tag, ::getpid())) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() { fs::remove_all(dir_); }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

std::string slurp(const fs::path& p) {
  std::ostringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

std::vector<std::string> names(const std::vector<FoundScenario>& found) {
  std::vector<std::string> n;
  for (const FoundScenario& f : found) n.push_back(f.path.filename().string());
  return n;
}

std::map<std::string, std::string> skipped(const Discovery& d) {
  std::map<std::string, std::string> m;
  for (const Skipped& s : d.skipped) m[s.path.filename().string()] = s.why;
  return m;
}

// The message of the InputError `f` throws ("" if it throws none).
template <typename F>
std::string input_error(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return std::string();
}

// --- Discovery -------------------------------------------------------------------------------------------------------

TEST(SuiteDiscovery, TheShippedScenesAreTheScenariosNotTheCellTheTreeOrTheSoak) {
  const Discovery d = discover({kScenes});
  EXPECT_THAT(names(d.scenarios), ElementsAre("beam.yaml", "exchange.yaml", "machine.yaml", "pipeline.yaml",
                                              "pipeline_shift.yaml", "pipeline_single.yaml", "relay.yaml",
                                              "relay_belt.yaml", "relay_single.yaml", "single.yaml", "vision.yaml"));
  const auto s = skipped(d);
  ASSERT_EQ(s.size(), 5u);
  EXPECT_EQ(s.at("cell.yaml"), "a cell description (docs/cell-description.md), not a scenario");
  EXPECT_EQ(s.at("beam_cell.yaml"), "a cell description (docs/cell-description.md), not a scenario");
  EXPECT_EQ(s.at("relay_cell.yaml"), "a cell description (docs/cell-description.md), not a scenario");
  EXPECT_EQ(s.at("recovery.yaml"), "a decision tree (docs/faults.md), not a scenario");
  EXPECT_EQ(s.at("soak"), "a subfolder (not entered unless named)");
  // Named, the subfolder is entered: its scenario is found after the folder's.
  const Discovery both = discover({kScenes, kScenes / "soak"});
  EXPECT_EQ(both.scenarios.size(), 12u);
  EXPECT_EQ(both.scenarios.back().path, kScenes / "soak" / "shift_1000.yaml");
  // The scenarios' wall-time limits (single.yaml: 600 s, the soak: 3600 s).
  EXPECT_EQ(both.scenarios[9].wall_time, 600);
  EXPECT_EQ(both.scenarios.back().wall_time, 3600);
}

TEST(SuiteDiscovery, KindsOfYamlAreToldApartByContent) {
  Scratch scratch("kinds");
  const fs::path d = scratch.dir();
  // Names that would mislead a classifier by name: the scenario is called cell.yaml, the cell description run.yaml.
  write(d / "cell.yaml", "cell: other.yaml\nprogram: p.task\nlimits: {wall_time: 30}\n");
  write(d / "run.yml", "name: c\nrobots:\n  - {name: puma}\n");
  write(d / "tree.yaml", "grip_lost: {cause: dropped, action: set_aside}\n");
  write(d / "notes.yaml", "program: p.task\n");  // no cell: not a scenario
  write(d / "list.yaml", "- 1\n- 2\n");
  write(d / "empty.yaml", "");
  write(d / "readme.txt", "cell: x\nprogram: y\n");  // not .yaml: not looked at
  write(d / ".hidden.yaml", "cell: x\nprogram: y\n");
  write(d / "sub" / "inner.yaml", "cell: x\nprogram: y\n");

  EXPECT_EQ(classify_yaml(d / "cell.yaml").kind, YamlKind::kScenario);
  EXPECT_EQ(classify_yaml(d / "cell.yaml").wall_time, 30);
  EXPECT_EQ(classify_yaml(d / "run.yml").kind, YamlKind::kCell);
  EXPECT_EQ(classify_yaml(d / "tree.yaml").kind, YamlKind::kDecisionTree);
  EXPECT_EQ(classify_yaml(d / "notes.yaml").kind, YamlKind::kOther);
  EXPECT_EQ(classify_yaml(d / "list.yaml").kind, YamlKind::kOther);
  EXPECT_EQ(classify_yaml(kScenes / "cell.yaml").kind, YamlKind::kCell);
  EXPECT_EQ(classify_yaml(kScenes / "recovery.yaml").kind, YamlKind::kDecisionTree);
  EXPECT_EQ(classify_yaml(kScenes / "exchange.yaml").kind, YamlKind::kScenario);

  const Discovery found = discover({d});
  EXPECT_THAT(names(found.scenarios), ElementsAre("cell.yaml"));
  const auto s = skipped(found);
  EXPECT_EQ(s.size(), 6u);
  EXPECT_THAT(s.at("run.yml"), HasSubstr("a cell description"));
  EXPECT_THAT(s.at("tree.yaml"), HasSubstr("a decision tree"));
  EXPECT_THAT(s.at("notes.yaml"), HasSubstr("without the fields `cell` and `program`"));
  EXPECT_THAT(s.at("list.yaml"), HasSubstr("a list"));
  EXPECT_THAT(s.at("empty.yaml"), HasSubstr("empty"));
  EXPECT_THAT(s.at("sub"), HasSubstr("subfolder"));

  // A file named twice, or named and in a folder named, runs once.
  EXPECT_EQ(discover({d / "cell.yaml", d, d / "cell.yaml"}).scenarios.size(), 1u);
  // A scenario named explicitly is taken whatever its extension.
  EXPECT_EQ(discover({d / "readme.txt"}).scenarios.size(), 1u);
}

TEST(SuiteDiscovery, BadInputIsRefusedNamingTheFile) {
  Scratch scratch("bad");
  const fs::path d = scratch.dir();
  write(d / "ok" / "a.yaml", "cell: x\nprogram: y\n");
  EXPECT_THAT(input_error([&] { discover({kScenes / "cell.yaml"}); }),
              HasSubstr("cell.yaml: error: not a scenario: a cell description (docs/cell-description.md)"));
  EXPECT_THAT(input_error([&] { discover({kScenes / "recovery.yaml"}); }),
              HasSubstr("recovery.yaml: error: not a scenario: a decision tree"));
  EXPECT_THAT(input_error([&] {
                discover({d / "ok", d / "missing.yaml"});
              }),
              HasSubstr("missing.yaml: error: no such file or folder"));
  fs::create_directories(d / "none");
  write(d / "none" / "tree.yaml", "grip_lost: {cause: dropped, action: set_aside}\n");
  EXPECT_THAT(input_error([&] { discover({d / "none"}); }), HasSubstr("none: error: no scenario found"));
  if (::geteuid() != 0) {  // root reads any folder
    fs::create_directories(d / "locked");
    fs::permissions(d / "locked", fs::perms::none);
    EXPECT_THAT(input_error([&] { discover({d / "locked"}); }), HasSubstr("locked: error: cannot read the folder"));
    fs::permissions(d / "locked", fs::perms::owner_all);
  }
}

// A YAML file that does not parse, in a folder or named, is a case of its own that will be an ERROR (it is not run),
// with the parse error's line; the other scenarios are still found. Only a folder with nothing to run is refused.
TEST(SuiteDiscovery, AYamlFileThatDoesNotParseIsACaseOfItsOwn) {
  Scratch scratch("broken");
  const fs::path d = scratch.dir();
  write(d / "a.yaml", "cell: x\nprogram: y\n");
  write(d / "b.yaml", "cell: x\nprogram: [y\n");
  write(d / "c.yaml", "cell: x\nprogram: y\n");
  const Discovery found = discover({d});
  EXPECT_THAT(names(found.scenarios), ElementsAre("a.yaml", "b.yaml", "c.yaml"));
  EXPECT_EQ(found.scenarios[0].error, "");
  EXPECT_THAT(found.scenarios[1].error, ::testing::StartsWith((d / "b.yaml").string() + ":3:1: error: not valid YAML"));
  EXPECT_EQ(found.scenarios[2].error, "");
  const Discovery named = discover({d / "b.yaml"});
  ASSERT_EQ(named.scenarios.size(), 1u);
  EXPECT_THAT(named.scenarios[0].error, HasSubstr("b.yaml:3:1: error: not valid YAML"));
  // Its case carries the error and reserves its name; it writes nothing, so its output folder is not checked.
  write(d / "out" / "b" / "precious.txt", "keep me");
  const std::vector<SuiteCase> cases = plan_suite(found, d / "out", std::nullopt);
  ASSERT_EQ(cases.size(), 3u);
  EXPECT_EQ(cases[1].name, "b");
  EXPECT_EQ(cases[1].error, found.scenarios[1].error);
}

// --- Planning --------------------------------------------------------------------------------------------------------

TEST(SuitePlan, NamesAreUniqueAndTimeLimitsFollowTheScenarios) {
  Scratch scratch("plan");
  const fs::path out = scratch.dir() / "out";
  Discovery found;
  found.scenarios = {{"a/x.yaml", 0, ""}, {"b/x.yaml", 100, ""}, {"b/y.yaml", 0, ""}};
  const std::vector<SuiteCase> cases = plan_suite(found, out, std::nullopt);
  ASSERT_EQ(cases.size(), 3u);
  EXPECT_EQ(cases[0].name, "x");
  EXPECT_EQ(cases[1].name, "x-2");
  EXPECT_EQ(cases[2].name, "y");
  EXPECT_EQ(cases[1].dir, out / "x-2");
  EXPECT_EQ(cases[0].timeout, 600);
  EXPECT_EQ(cases[1].timeout, 160);
  EXPECT_EQ(plan_suite(found, out, 5.0)[1].timeout, 5);
  EXPECT_FALSE(fs::exists(out));  // nothing made

  EXPECT_THAT(input_error([&] { plan_suite(found, out, 0.0); }), HasSubstr("--timeout: error: must be > 0 s"));
  // An earlier run's outputs are replaced; anything else is refused.
  write(out / "x" / "stdout.txt", "");
  write(out / "y" / "precious.txt", "keep me");
  EXPECT_THAT(input_error([&] { plan_suite(found, out, std::nullopt); }),
              HasSubstr("y: error: exists and is not the outputs of an earlier run"));
  write(scratch.dir() / "file", "x");
  EXPECT_THAT(input_error([&] { plan_suite(found, scratch.dir() / "file" / "out", std::nullopt); }),
              HasSubstr("is not a directory"));
}

TEST(SuitePlan, TheJunitFileMustBeWritable) {
  Scratch scratch("junit");
  EXPECT_NO_THROW(check_writable_file(scratch.dir() / "reports" / "junit.xml"));
  EXPECT_THAT(input_error([&] { check_writable_file(scratch.dir()); }), HasSubstr("not a file name"));
  write(scratch.dir() / "file", "x");
  EXPECT_THAT(input_error([&] { check_writable_file(scratch.dir() / "file" / "junit.xml"); }),
              HasSubstr("is not a directory"));
}

// --- Running ---------------------------------------------------------------------------------------------------------

// A stand-in for `twin` (`run SCENARIO -o DIR --quiet [--seed S]`): a shell script that records its arguments and
// does what the scenario's name says; "pass" and "fail" copy their report.json from beside it (made here).
fs::path fake_twin(const fs::path& dir) {
  test_reports::write_report(dir / "pass.json", test_reports::run_report({}, "finished", 12.5, 2));
  test_reports::write_report(
      dir / "fail.json",
      test_reports::run_report(
          {"workpiece A: expected on output, is on input <stop> & \"late\"", "run outcome timeout"}, "timeout", 20));
  const fs::path p = dir / "fake-twin.sh";
  write(p,
        "#!/bin/sh\n"
        "reports=$(dirname \"$0\")\n"
        "out=\"$4\"\n"
        "echo \"$@\" > \"$out/args.txt\"\n"
        "case \"$(basename \"$2\" .yaml)\" in\n"
        "pass)\n"
        "  cp \"$reports/pass.json\" \"$out/report.json\"\n"
        "  echo 'result: ok, 2 parts placed'\n"
        "  exit 0;;\n"
        "fail)\n"
        "  cp \"$reports/fail.json\" \"$out/report.json\"\n"
        "  printf 'result: FAILED\\a\\033[0m \\377 end\\n'\n"
        "  exit 1;;\n"
        "refused)\n"
        "  echo \"$2:3:1: error: unknown field 'robts'\" >&2\n"
        "  exit 2;;\n"
        "crash) kill -SEGV $$;;\n"
        "hang) exec sleep 30;;\n"
        "esac\n");
  fs::permissions(p, fs::perms::owner_all);
  return p;
}

// A case of the stand-ins: scenes/NAME.yaml (the stand-in acts on the name alone), its outputs in OUT/NAME.
SuiteCase stand_in_case(const fs::path& scenes, const std::string& name, const fs::path& out, double timeout = 30) {
  SuiteCase c;
  c.scenario = scenes / (name + ".yaml");
  c.name = name;
  c.dir = out / name;
  c.timeout = timeout;
  return c;
}

std::vector<SuiteCase> fake_cases(const fs::path& out) {
  std::vector<SuiteCase> cases;
  for (const std::string name : {"pass", "fail", "refused", "crash", "hang"}) {
    cases.push_back(stand_in_case("scenes", name, out, name == "hang" ? 0.5 : 30));
  }
  return cases;
}

// The suite of five stand-ins, run once for the tests below.
class SuiteRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scratch_ = new Scratch("run");
    SuiteOptions o;
    o.executable = fake_twin(scratch_->dir());
    o.jobs = 2;
    o.seed = 7;
    SuiteCallbacks cb;
    cb.progress = [](const SuiteProgress& p) { progress_->push_back(p); };
    cb.ended = [](const CaseResult& r) { ended_->push_back(r.test.name); };
    progress_ = new std::vector<SuiteProgress>;
    ended_ = new std::vector<std::string>;
    const auto start = std::chrono::steady_clock::now();
    results_ = new std::vector<CaseResult>(run_suite(fake_cases(scratch_->dir() / "out"), o, cb));
    wall_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  static void TearDownTestSuite() {
    delete results_;
    delete progress_;
    delete ended_;
    delete scratch_;
  }
  static const CaseResult& result(const std::string& name) {
    for (const CaseResult& r : *results_) {
      if (r.test.name == name) return r;
    }
    throw std::runtime_error("no result " + name);
  }

  static Scratch* scratch_;
  static std::vector<CaseResult>* results_;
  static std::vector<SuiteProgress>* progress_;
  static std::vector<std::string>* ended_;
  static double wall_;
};
Scratch* SuiteRun::scratch_ = nullptr;
std::vector<CaseResult>* SuiteRun::results_ = nullptr;
std::vector<SuiteProgress>* SuiteRun::progress_ = nullptr;
std::vector<std::string>* SuiteRun::ended_ = nullptr;
double SuiteRun::wall_ = 0;

TEST_F(SuiteRun, EachChildGetsItsScenarioOutputAndSeed) {
  ASSERT_EQ(results_->size(), 5u);
  const fs::path out = scratch_->dir() / "out";
  EXPECT_EQ(slurp(out / "fail" / "args.txt"),
            fmt::format("run {} -o {} --quiet --final-png failed --seed 7\n", fs::absolute("scenes/fail.yaml").string(),
                        (out / "fail").string()));
  EXPECT_LT(wall_, 20.0);  // the hang was killed at its limit, not waited for
}

TEST_F(SuiteRun, VerdictsFromExitStatusAndReport) {
  const CaseResult& pass = result("pass");
  EXPECT_EQ(pass.verdict, Verdict::kPass);
  EXPECT_TRUE(pass.message.empty());
  EXPECT_EQ(pass.sim_time, 12.5);
  EXPECT_EQ(pass.placed, 2u);

  const CaseResult& fail = result("fail");
  EXPECT_EQ(fail.verdict, Verdict::kFail);
  EXPECT_EQ(fail.message, "workpiece A: expected on output, is on input <stop> & \"late\"");
  EXPECT_EQ(fail.failures.size(), 2u);
  EXPECT_EQ(fail.sim_time, 20);
  EXPECT_EQ(fail.placed, 0u);

  const CaseResult& refused = result("refused");
  EXPECT_EQ(refused.verdict, Verdict::kError);
  EXPECT_THAT(refused.message, HasSubstr("refused: "));
  EXPECT_THAT(refused.message, HasSubstr("refused.yaml:3:1: error: unknown field 'robts'"));
  EXPECT_FALSE(refused.sim_time);

  const CaseResult& crash = result("crash");
  EXPECT_EQ(crash.verdict, Verdict::kCrash);
  EXPECT_THAT(crash.message, HasSubstr("killed by signal 11"));

  const CaseResult& hang = result("hang");
  EXPECT_EQ(hang.verdict, Verdict::kHang);
  EXPECT_THAT(hang.message, HasSubstr("killed"));
  EXPECT_GE(hang.end.wall_time, 0.5);
}

TEST_F(SuiteRun, APassingScenariosOutputsGoTheOthersStay) {
  const fs::path out = scratch_->dir() / "out";
  EXPECT_FALSE(fs::exists(out / "pass"));
  EXPECT_FALSE(result("pass").kept);
  for (const char* name : {"fail", "refused", "crash", "hang"}) {
    EXPECT_TRUE(result(name).kept) << name;
    EXPECT_TRUE(fs::exists(out / name / "stdout.txt")) << name;
  }
  EXPECT_TRUE(fs::exists(out / "fail" / "report.json"));
}

TEST_F(SuiteRun, ProgressCountsAndNeverMoreThanTheJobs) {
  ASSERT_FALSE(progress_->empty());
  for (const SuiteProgress& p : *progress_) {
    EXPECT_LE(p.running, 2u);
    EXPECT_EQ(p.total, 5u);
  }
  EXPECT_EQ(progress_->back().done, 5u);
  EXPECT_EQ(progress_->back().failed, 4u);
  EXPECT_EQ(progress_->back().running, 0u);
  EXPECT_EQ(ended_->size(), 5u);
  SuiteProgress p;
  p.done = 3;
  p.total = 6;
  p.running = 2;
  p.failed = 1;
  EXPECT_EQ(format_progress(p, 10), "[#####.....] 3/6 scenarios, 2 running, 1 failed");
}

TEST_F(SuiteRun, OneLinePerScenarioAndTheTotals) {
  EXPECT_THAT(format_result(result("pass"), 7),
              ::testing::MatchesRegex("PASS   pass     sim    12.50 s  wall +[0-9.]+ s  placed 2"));
  EXPECT_THAT(
      format_result(result("fail"), 7),
      ::testing::MatchesRegex("FAIL   fail     sim    20.00 s  wall +[0-9.]+ s  placed 0  workpiece A: expected "
                              "on output, is on input <stop> & \"late\""));
  EXPECT_THAT(format_result(result("hang"), 7),
              ::testing::MatchesRegex("HANG   hang     sim        -    wall +[0-9.]+ s  placed -  still running after "
                                      "[0-9]+ s: killed"));
  EXPECT_EQ(format_totals(*results_), "1 passed, 4 failed (1 crashed, 1 hung, 1 refused)");
  EXPECT_EQ(format_totals({result("pass"), result("fail")}), "1 passed, 1 failed");
}

// The attribute of an element, "" when it has none.
std::string attr(const tinyxml2::XMLElement* e, const char* name) {
  const char* v = e->Attribute(name);
  return v ? v : "";
}

TEST_F(SuiteRun, JunitXmlParsesBackWithEveryVerdict) {
  const std::string xml = format_junit(*results_, 42.5);
  tinyxml2::XMLDocument doc;
  ASSERT_EQ(doc.Parse(xml.c_str(), xml.size()), tinyxml2::XML_SUCCESS) << doc.ErrorStr() << "\n" << xml;
  const tinyxml2::XMLElement* suites = doc.FirstChildElement("testsuites");
  ASSERT_NE(suites, nullptr);
  EXPECT_EQ(attr(suites, "tests"), "5");
  EXPECT_EQ(attr(suites, "failures"), "1");
  EXPECT_EQ(attr(suites, "errors"), "3");
  const tinyxml2::XMLElement* suite = suites->FirstChildElement("testsuite");
  ASSERT_NE(suite, nullptr);
  EXPECT_EQ(attr(suite, "name"), "twin test");
  EXPECT_EQ(attr(suite, "tests"), "5");
  EXPECT_EQ(attr(suite, "failures"), "1");
  EXPECT_EQ(attr(suite, "errors"), "3");
  EXPECT_EQ(attr(suite, "skipped"), "0");
  EXPECT_EQ(attr(suite, "time"), "42.500");

  std::map<std::string, const tinyxml2::XMLElement*> cases;
  for (auto* c = suite->FirstChildElement("testcase"); c; c = c->NextSiblingElement("testcase")) {
    cases[attr(c, "name")] = c;
    EXPECT_EQ(attr(c, "classname"), "scenes");
    EXPECT_EQ(attr(c, "file"), "scenes/" + attr(c, "name") + ".yaml");
    EXPECT_GE(std::stod(attr(c, "time")), 0.0);
  }
  ASSERT_EQ(cases.size(), 5u);

  const tinyxml2::XMLElement* pass = cases.at("pass");
  EXPECT_EQ(pass->FirstChildElement("failure"), nullptr);
  EXPECT_EQ(pass->FirstChildElement("error"), nullptr);
  ASSERT_NE(pass->FirstChildElement("system-out"), nullptr);
  EXPECT_STREQ(pass->FirstChildElement("system-out")->GetText(), "result: ok, 2 parts placed\n");

  const tinyxml2::XMLElement* fail = cases.at("fail")->FirstChildElement("failure");
  ASSERT_NE(fail, nullptr);
  EXPECT_EQ(attr(fail, "type"), "fail");
  EXPECT_EQ(attr(fail, "message"), "workpiece A: expected on output, is on input <stop> & \"late\"");
  const std::string body = fail->GetText();
  EXPECT_THAT(body, HasSubstr("run outcome timeout\n"));
  EXPECT_THAT(body, HasSubstr("outputs in " + (scratch_->dir() / "out" / "fail").string()));
  // The report's text; the control characters and the byte that is not UTF-8 replaced (XML 1.0 allows none).
  EXPECT_STREQ(cases.at("fail")->FirstChildElement("system-out")->GetText(),
               "result: FAILED\xEF\xBF\xBD\xEF\xBF\xBD[0m \xEF\xBF\xBD end\n");
  EXPECT_EQ(xml.find("&#7;"), std::string::npos);
  EXPECT_EQ(xml.find("&#27;"), std::string::npos);

  for (const char* name : {"refused", "crash", "hang"}) {
    const tinyxml2::XMLElement* e = cases.at(name)->FirstChildElement("error");
    ASSERT_NE(e, nullptr) << name;
    EXPECT_EQ(attr(e, "type"), name == std::string("refused") ? "error" : name);
    EXPECT_EQ(attr(e, "message"), result(name).message);
  }
  ASSERT_NE(cases.at("refused")->FirstChildElement("system-err"), nullptr);
  EXPECT_THAT(cases.at("refused")->FirstChildElement("system-err")->GetText(), HasSubstr("unknown field 'robts'"));
}

// One YAML file that does not parse costs its own verdict only: an ERROR naming its line, in the lines, the totals and
// the JUnit XML, without a run or outputs; the other scenarios run.
TEST(SuiteErrors, AFileThatDoesNotParseIsAnErrorAndTheOthersRun) {
  Scratch scratch("parse");
  const fs::path suite = scratch.dir() / "suite", out = scratch.dir() / "out";
  write(suite / "pass.yaml", "cell: x\nprogram: y\n");
  write(suite / "broken.yaml", "cell: x\nprogram: [y\n");
  const std::vector<SuiteCase> cases = plan_suite(discover({suite}), out, std::nullopt);
  SuiteOptions o;
  o.executable = fake_twin(scratch.dir());
  std::vector<std::string> ended;
  SuiteCallbacks cb;
  cb.ended = [&](const CaseResult& r) { ended.push_back(r.test.name); };
  const std::vector<CaseResult> results = run_suite(cases, o, cb);
  ASSERT_EQ(results.size(), 2u);
  EXPECT_THAT(ended, ElementsAre("broken", "pass"));  // the error is known before anything runs
  const CaseResult& broken = results[0];
  EXPECT_EQ(broken.test.name, "broken");
  EXPECT_EQ(broken.verdict, Verdict::kError);
  const std::string where = (suite / "broken.yaml").string() + ":3:1: error: not valid YAML";
  EXPECT_THAT(broken.message, ::testing::StartsWith(where));
  EXPECT_FALSE(broken.kept);
  EXPECT_FALSE(fs::exists(out / "broken"));  // nothing ran, nothing was written
  EXPECT_EQ(results[1].verdict, Verdict::kPass);

  EXPECT_THAT(format_result(broken, 6),
              ::testing::StartsWith("ERROR  broken  sim        -    wall    0.0 s  placed -  " + where));
  EXPECT_EQ(format_totals(results), "1 passed, 1 failed (1 refused)");
  const std::string xml = format_junit(results, 1);
  tinyxml2::XMLDocument doc;
  ASSERT_EQ(doc.Parse(xml.c_str(), xml.size()), tinyxml2::XML_SUCCESS) << xml;
  const tinyxml2::XMLElement* s = doc.FirstChildElement("testsuites")->FirstChildElement("testsuite");
  EXPECT_STREQ(s->Attribute("tests"), "2");
  EXPECT_STREQ(s->Attribute("errors"), "1");
  const tinyxml2::XMLElement* c = s->FirstChildElement("testcase");
  EXPECT_STREQ(c->Attribute("name"), "broken");
  const tinyxml2::XMLElement* e = c->FirstChildElement("error");
  ASSERT_NE(e, nullptr);
  EXPECT_STREQ(e->Attribute("type"), "error");
  EXPECT_THAT(e->Attribute("message"), ::testing::StartsWith(where));
  EXPECT_THAT(e->GetText(), Not(HasSubstr("outputs in")));
}

// A stand-in for `twin run SCENARIO -o DIR --quiet [--video FILE --video-fps F --video-size WxH] --seed S`: every
// scenario fails but "pass"; with --video it records its arguments beside DIR (DIR/.. is the first run's directory),
// writes the video and a page naming it, and an event log that is the first run's ("same"), another ("differs"), or
// makes no video and says why ("novideo").
fs::path fake_video_twin(const fs::path& dir) {
  test_reports::write_report(dir / "pass.json", test_reports::run_report());
  test_reports::write_report(dir / "fail.json", test_reports::run_report({"A is elsewhere"}));
  const fs::path p = dir / "fake-video-twin.sh";
  write(p,
        "#!/bin/sh\n"
        "reports=$(dirname \"$0\")\n"
        "name=$(basename \"$2\" .yaml); out=\"$4\"\n"
        "echo \"$@\" > \"$out/args.txt\"\n"
        "if [ \"$name\" = pass ]; then cp \"$reports/pass.json\" \"$out/report.json\"; exit 0; fi\n"
        "cp \"$reports/fail.json\" \"$out/report.json\"\n"
        "echo 'first run' > \"$out/events.jsonl\"; echo 'page without video' > \"$out/index.html\"\n"
        "if [ \"$6\" = --video ]; then\n"
        "  echo \"$@\" > \"$out/../video-args.txt\"\n"
        "  case $name in\n"
        "  novideo) echo 'twin: error: ffmpeg: Unknown encoder libx264' >&2; exit 2;;\n"
        "  differs) echo 'another run' > \"$out/events.jsonl\";;\n"
        "  esac\n"
        "  echo 'mp4 bytes' > \"$7\"; echo '<video src=\"video.mp4\">' > \"$out/index.html\"\n"
        "fi\n"
        "exit 1\n");
  fs::permissions(p, fs::perms::owner_all);
  return p;
}

TEST(SuiteVideos, EachFailedScenarioIsRunAgainAndItsVideoJoinsItsOutputs) {
  Scratch scratch("video");
  const fs::path out = scratch.dir() / "out";
  std::vector<SuiteCase> cases;
  for (const char* name : {"pass", "same", "differs", "novideo"}) cases.push_back(stand_in_case(kScenes, name, out));
  SuiteOptions o;
  o.executable = fake_video_twin(scratch.dir());
  o.jobs = 2;
  o.seed = 7;
  std::vector<CaseResult> results = run_suite(cases, o);
  ASSERT_EQ(results.size(), 4u);
  ASSERT_EQ(results[1].verdict, Verdict::kFail);

  VideoSettings video;
  video.fps = 5;
  video.size = "160x120";
  std::vector<std::string> ended;
  std::size_t last_done = 0, last_total = 0;
  VideoCallbacks cb;
  cb.ended = [&](const CaseResult& r) { ended.push_back(r.test.name); };
  cb.progress = [&](std::size_t done, std::size_t total) {
    last_done = done;
    last_total = total;
  };
  record_videos(results, o, video, cb);
  std::sort(ended.begin(), ended.end());
  EXPECT_THAT(ended, ElementsAre("differs", "novideo", "same"));  // the passing one is not run again
  EXPECT_EQ(last_done, 3u);
  EXPECT_EQ(last_total, 3u);

  const CaseResult& same = results[1];
  EXPECT_EQ(same.video, out / "same" / "video.mp4");
  EXPECT_EQ(same.video_note, "");
  EXPECT_EQ(slurp(out / "same" / "video.mp4"), "mp4 bytes\n");
  EXPECT_EQ(slurp(out / "same" / "index.html"), "<video src=\"video.mp4\">\n");  // the page that shows it
  EXPECT_EQ(slurp(out / "same" / "args.txt"),  // the first run's outputs are kept as they were
            fmt::format("run {} -o {} --quiet --final-png failed --seed 7\n", (kScenes / "same.yaml").string(), (out / "same").string()));
  EXPECT_FALSE(fs::exists(out / "same" / ".video"));
  const fs::path rerun = out / "same" / ".video";
  EXPECT_EQ(slurp(out / "same" / "video-args.txt"),
            fmt::format("run {} -o {} --quiet --video {} --video-fps 5 --video-size 160x120 --seed 7\n",
                        (kScenes / "same.yaml").string(), rerun.string(), (rerun / "video.mp4").string()));

  // Another run: the video is kept, but the first run's page stays with its report; the re-run's goes beside it.
  const CaseResult& differs = results[2];
  EXPECT_EQ(differs.video, out / "differs" / "video.mp4");
  EXPECT_THAT(differs.video_note, HasSubstr("shows another run"));
  EXPECT_EQ(slurp(out / "differs" / "index.html"), "page without video\n");
  EXPECT_EQ(slurp(out / "differs" / "video.html"), "<video src=\"video.mp4\">\n");
  EXPECT_EQ(slurp(out / "differs" / "events.jsonl"), "first run\n");

  const CaseResult& novideo = results[3];
  EXPECT_TRUE(novideo.video.empty());
  EXPECT_THAT(novideo.video_note,
              ::testing::StartsWith("twin: error: ffmpeg: Unknown encoder libx264 (its stderr in "));
  EXPECT_EQ(slurp(out / "novideo" / "video-stderr.txt"), "twin: error: ffmpeg: Unknown encoder libx264\n");
  EXPECT_EQ(slurp(out / "novideo" / "index.html"), "page without video\n");  // the first run's page stays
  EXPECT_FALSE(fs::exists(out / "novideo" / "video.mp4"));
  EXPECT_FALSE(fs::exists(out / "novideo" / ".video"));

  // The JUnit failure names the video, and says what to know of it.
  const std::string xml = format_junit(results, 1);
  EXPECT_THAT(xml, HasSubstr("video in " + (out / "same" / "video.mp4").string()));
  EXPECT_EQ(xml.find("video in " + (out / "novideo").string()), std::string::npos);
  EXPECT_THAT(xml, HasSubstr("video: the re-run's event log differs"));
}

TEST(SuiteVideos, ReRunsThatCannotStartLeaveNothingBehind) {
  Scratch scratch("video-nostart");
  const fs::path out = scratch.dir() / "out";
  const SuiteCase c = stand_in_case(kScenes, "same", out);
  SuiteOptions o;
  o.executable = fake_video_twin(scratch.dir());
  std::vector<CaseResult> results = run_suite({c}, o);
  ASSERT_EQ(results[0].verdict, Verdict::kFail);
  o.executable = scratch.dir() / "no-such-twin";
  EXPECT_THROW(record_videos(results, o, VideoSettings{}), InputError);
  EXPECT_FALSE(fs::exists(c.dir / ".video"));
  EXPECT_TRUE(results[0].video.empty());
  EXPECT_EQ(slurp(c.dir / "index.html"), "page without video\n");
}

TEST(SuiteVideos, TheReRunsTimeLimitFollowsTheFirstRun) {
  CaseResult r;
  r.test.timeout = 600;  // a scenario without a wall-time limit
  r.end.wall_time = 5;
  EXPECT_EQ(video_timeout(r, 25), 125);
  r.end.wall_time = 0.5;
  EXPECT_EQ(video_timeout(r, 25), 60);  // at least a minute: ffmpeg and the renderer start
  r.test.timeout = 2;
  EXPECT_EQ(video_timeout(r, 25), 50);  // never more than the slowdown times the scenario's limit
}

TEST(SuiteJudge, ExitStatusAndReportMustAgreeToPass) {
  Scratch scratch("judge");
  SuiteCase c;
  c.name = "x";
  c.dir = scratch.dir();
  ChildEnd end;
  end.status = RunStatus::kDone;
  end.exit_code = 0;
  end.report = test_reports::run_report({"A is elsewhere"});
  EXPECT_EQ(judge(c, end).verdict, Verdict::kFail);
  end.report = test_reports::run_report();
  EXPECT_EQ(judge(c, end).verdict, Verdict::kPass);
  end.exit_code = 1;
  EXPECT_EQ(judge(c, end).verdict, Verdict::kFail);
  EXPECT_EQ(judge(c, end).message, "exit 1, outcome finished (the report says ok)");
  end.exit_code = 3;
  EXPECT_EQ(judge(c, end).verdict, Verdict::kError);
}

}  // namespace
}  // namespace cellwright::cell
