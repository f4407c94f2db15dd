// ScenarioRun's event log streamed to a file (RunOptions::events_file): the same bytes and the same report as a log
// kept in memory, and moved into the output directory by write_outputs.
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/sim/run.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

class StreamedLog : public ::testing::Test {
 protected:
  void SetUp() override {
    // Its own directory: ctest runs the tests of this file as separate processes at once.
    dir_ = fs::temp_directory_path() /
           fmt::format("cw_run_{}_{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(StreamedLog, HasTheBytesAndTheReportOfTheLogKeptInMemory) {
  const Scenario s = load_scenario(kScenes + "/single.yaml");
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok()) << pre.problems.front();

  ScenarioRun kept(s, pre);
  ASSERT_EQ(kept.runtime().run().outcome, runtime::Outcome::kFinished);
  const Report kept_report = kept.report();

  RunOptions options;
  options.events_file = dir_ / "events.jsonl.part";
  ScenarioRun streamed(s, pre, options);
  EXPECT_FALSE(streamed.runtime().log().keeps_lines());
  ASSERT_EQ(streamed.runtime().run().outcome, runtime::Outcome::kFinished);
  EXPECT_EQ(streamed.runtime().log().size(), kept.runtime().log().size());
  const Report streamed_report = streamed.report();
  EXPECT_EQ(to_json(s, streamed_report).dump(1), to_json(s, kept_report).dump(1));
  EXPECT_EQ(read_file(dir_ / "events.jsonl.part"), kept.runtime().log().text());

  streamed.write_outputs(dir_ / "out", streamed_report, cv::Mat());
  EXPECT_EQ(read_file(dir_ / "out" / kEventsFile), kept.runtime().log().text());
  EXPECT_FALSE(fs::exists(dir_ / "events.jsonl.part"));
  EXPECT_EQ(streamed.events_file(), dir_ / "out" / kEventsFile);
  EXPECT_TRUE(fs::is_regular_file(dir_ / "out" / kReportFile));
  EXPECT_TRUE(fs::is_regular_file(dir_ / "out" / kGanttFile));
  // The report can still be made after the move: it reads the file where it now is.
  EXPECT_EQ(to_json(s, streamed.report()).dump(1), to_json(s, kept_report).dump(1));
}

TEST_F(StreamedLog, AFileThatCannotBeWrittenIsRefusedBeforeAnythingRuns) {
  const Scenario s = load_scenario(kScenes + "/single.yaml");
  const Preflight pre = preflight(s, &twin_port());
  ASSERT_TRUE(pre.ok());
  RunOptions options;
  // Its directory is made if missing; here a file stands where the directory would be.
  write_file_atomically(dir_ / "blocker", "a file, not a directory");
  options.events_file = dir_ / "blocker" / "events.jsonl";
  try {
    ScenarioRun run(s, pre, options);
    FAIL() << "a log file that cannot be written was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("blocker"), std::string::npos) << e.what();
  }
  // A missing directory is made.
  options.events_file = dir_ / "new" / "dir" / "events.jsonl";
  ScenarioRun made(s, pre, options);
  EXPECT_TRUE(fs::is_regular_file(dir_ / "new" / "dir" / "events.jsonl"));
}

}  // namespace
}  // namespace cellwright::cell
