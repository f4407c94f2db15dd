// The child processes of `twin campaign` and `twin test`: arguments, output files and a fresh directory per child, at
// most `jobs` at a time, each child's own time limit, done/crash/hang told apart, and an executable that cannot be
// started refused. (campaign_test and suite_test run them through their own runners too.)
#include "cellwright/cell/children.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cell/report_files.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class Scratch {
 public:
  explicit Scratch(const std::string& tag)
      : dir_(fs::temp_directory_path() / fmt::format("cw-children-{}-{}", tag, ::getpid())) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() { fs::remove_all(dir_); }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

std::string slurp(const fs::path& p) {
  std::ostringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

// A shell script taking (DIR, WHAT): does WHAT after listing DIR's files into DIR/seen.txt. `report` copies a whole
// report.json (report.full, made here), `partial` one without its faults' "detected" (report.partial).
fs::path script(const fs::path& dir) {
  test_reports::write_report(dir / "report.full", test_reports::run_report({"A is elsewhere"}));
  Report faulted = test_reports::run_report();
  faulted.faults.push_back(test_reports::fault_report("drop", true, 2.0));
  nlohmann::json partial = to_json(Scenario{}, faulted);
  partial["faults"][0].erase("detected");
  std::ofstream(dir / "report.partial") << partial.dump();
  const fs::path p = dir / "child.sh";
  std::ofstream(p) << "#!/bin/sh\n"
                      "ls \"$1\" > \"$1/seen.txt\"\n"
                      "echo \"out $2\"\necho \"  \" >&2\necho \"err $2\" >&2\n"
                      "case \"$2\" in\n"
                      "report) cp \"$1/../report.full\" \"$1/report.json\"; exit 1;;\n"
                      "partial) cp \"$1/../report.partial\" \"$1/report.json\"; exit 0;;\n"
                      "list) printf '[1]' > \"$1/report.json\";;\n"
                      "segv) kill -SEGV $$;;\n"
                      "sleep) exec sleep 30;;\n"
                      "esac\n";
  fs::permissions(p, fs::perms::owner_all);
  return p;
}

TEST(Children, EachEndIsToldApartAndTheCallbacksFollowThem) {
  Scratch scratch("ends");
  const fs::path exe = script(scratch.dir());
  std::vector<ChildSpec> specs;
  for (const char* what : {"report", "list", "segv", "sleep", "nothing", "partial"}) {
    ChildSpec c;
    c.dir = scratch.dir() / what;
    c.args = {c.dir.string(), what};
    c.timeout = std::string(what) == "sleep" ? 0.3 : 30;
    specs.push_back(c);
  }
  // A leftover of an earlier run in a child's directory is gone before it starts.
  fs::create_directories(specs[0].dir);
  std::ofstream(specs[0].dir / "old.txt") << "old";

  std::size_t running = 0, most = 0;
  std::vector<std::string> events;
  ChildCallbacks cb;
  cb.started = [&](std::size_t i) {
    events.push_back(fmt::format("start {}", i));
    most = std::max(most, ++running);
  };
  cb.ended = [&](std::size_t i, const ChildEnd& e) {
    events.push_back(fmt::format("end {} {}", i, to_string(e.status)));
    --running;
  };
  const std::vector<ChildEnd> ends = run_children(exe, specs, 2, cb);
  ASSERT_EQ(ends.size(), 6u);
  EXPECT_EQ(most, 2u);
  EXPECT_EQ(events.size(), 12u);
  EXPECT_EQ(events.front(), "start 0");

  EXPECT_EQ(slurp(specs[0].dir / "seen.txt"), "seen.txt\nstderr.txt\nstdout.txt\n");  // old.txt is gone
  EXPECT_EQ(slurp(specs[0].dir / kChildStdout), "out report\n");
  // Done whatever the exit status, when the report reads back.
  EXPECT_EQ(ends[0].status, RunStatus::kDone);
  EXPECT_EQ(ends[0].exit_code, 1);
  ASSERT_TRUE(ends[0].report);
  EXPECT_EQ(ends[0].report->failures, std::vector<std::string>{"A is elsewhere"});
  EXPECT_EQ(ends[0].first_error, "err report");  // the blank line before it says nothing

  EXPECT_EQ(ends[1].status, RunStatus::kCrash);  // a report that is not an object
  EXPECT_EQ(ends[1].problem, fmt::format("exit 0 with an unreadable report.json: {}: error: \"the report\" must be a "
                                         "JSON object, not [1]",
                                         (specs[1].dir / kReportFile).string()));
  EXPECT_FALSE(ends[1].report);

  EXPECT_EQ(ends[2].status, RunStatus::kCrash);
  EXPECT_EQ(ends[2].signal, SIGSEGV);
  EXPECT_THAT(ends[2].problem, HasSubstr("killed by signal 11"));

  EXPECT_EQ(ends[3].status, RunStatus::kHang);
  EXPECT_GE(ends[3].wall_time, 0.3);
  EXPECT_LT(ends[3].wall_time, 10.0);

  EXPECT_EQ(ends[4].status, RunStatus::kCrash);
  EXPECT_EQ(ends[4].problem, "exit 0 without report.json: err nothing");

  // A report.json without a field is no result: a crash naming the file and the field, not a run done.
  EXPECT_EQ(ends[5].status, RunStatus::kCrash);
  EXPECT_EQ(ends[5].problem, fmt::format("exit 0 with an unreadable report.json: {}: error: \"faults[0].detected\" is "
                                         "missing",
                                         (specs[5].dir / kReportFile).string()));
  EXPECT_FALSE(ends[5].report);
}

TEST(Children, AnExecutableThatCannotStartIsAnInputError) {
  Scratch scratch("exe");
  ChildSpec c;
  c.dir = scratch.dir() / "run";
  try {
    run_children(scratch.dir() / "no-such-twin", {c}, 1);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no-such-twin: error: cannot start it for"));
    EXPECT_THAT(e.what(), HasSubstr("No such file or directory"));
  }
}

}  // namespace
}  // namespace cellwright::cell
