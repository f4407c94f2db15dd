// `--video` as a user gives it: `twin run` and `twin step` write an MP4 a browser plays (H.264 in an MP4 whose
// index comes first) without changing the event log; a file that cannot be written is refused before anything runs;
// `twin campaign --video` records the failed runs only. And `twin step` takes the options of `twin run`.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
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

// An MP4 (ISO base media: 'ftyp' first) with an H.264 track ('avc1') whose index ('moov') precedes the media
// ('mdat'): what a browser's <video> plays as it loads.
void expect_browser_mp4(const fs::path& file) {
  ASSERT_TRUE(fs::is_regular_file(file)) << file;
  const std::string bytes = slurp(file);
  ASSERT_GT(bytes.size(), 1000u);
  EXPECT_EQ(bytes.substr(4, 4), "ftyp");
  EXPECT_NE(bytes.find("avc1"), std::string::npos) << "no H.264 track";
  const auto moov = bytes.find("moov"), mdat = bytes.find("mdat");
  ASSERT_NE(moov, std::string::npos);
  ASSERT_NE(mdat, std::string::npos);
  EXPECT_LT(moov, mdat) << "the index after the media: no +faststart";
}

TEST(VideoCli, RunWritesAPlayableVideoAndTheSameEventLogAsWithout) {
  TwinCli cli("cw-video-cli-run");
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const fs::path video = cli.dir() / "exchange.mp4";
  const Outcome plain = cli.run("run " + scenario + " --quiet -o " + shell_quote((cli.dir() / "plain").string()));
  ASSERT_EQ(plain.status, 0) << plain.out << plain.err;
  const Outcome recorded =
      cli.run("run " + scenario + " --quiet --video " + shell_quote(video.string()) +
              " --video-fps 4 --video-size 320x240 --output " + shell_quote((cli.dir() / "video").string()));
  ASSERT_EQ(recorded.status, 0) << recorded.out << recorded.err;
  EXPECT_THAT(recorded.out, HasSubstr("video in " + video.string()));
  expect_browser_mp4(video);
  EXPECT_EQ(slurp(cli.dir() / "video" / "events.jsonl"), slurp(cli.dir() / "plain" / "events.jsonl"));
}

TEST(VideoCli, AVideoThatCannotBeWrittenExitsTwoBeforeAnythingRuns) {
  TwinCli cli("cw-video-cli-bad");
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const fs::path out = cli.dir() / "out";
  const fs::path missing = cli.dir() / "no" / "such" / "run.mp4";
  Outcome r = cli.run("run " + scenario + " --quiet -o " + shell_quote(out.string()) + " --video " +
                      shell_quote(missing.string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(missing.string()));
  EXPECT_THAT(r.err, HasSubstr("does not exist"));
  EXPECT_FALSE(fs::exists(out)) << "something was written before the refusal";

  r = cli.run("run " + scenario + " --quiet --video " + shell_quote((cli.dir() / "run.avi").string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(".mp4"));
  r = cli.run("run " + scenario + " --quiet --video " + shell_quote((cli.dir() / "run.mp4").string()) +
              " --video-size 801x600");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("even"));
  r = cli.run("run " + scenario + " --quiet --video " + shell_quote((cli.dir() / "run.mp4").string()) +
              " --video-size big");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("--video-size"));
  EXPECT_FALSE(fs::exists(cli.dir() / "run.mp4"));
}

// `twin step` takes `twin run`'s options (but --realtime, --quiet and --dry) under the same names, and they act as
// in `twin run`: the same seed and fault give the same event log, the video is recorded.
TEST(VideoCli, StepTakesTheOptionsOfRun) {
  TwinCli cli("cw-video-cli-step");
  const Outcome help = cli.run("step --help");
  ASSERT_EQ(help.status, 0) << help.err;
  for (const char* option : {"-o,--output", "--perception", "--driver", "--fault", "--seed", "--save-frames",
                             "--video", "--video-fps", "--video-size", "--allow-collisions"}) {
    EXPECT_THAT(help.out, HasSubstr(option)) << help.out;
  }
  // No option --realtime (stepping is lock-step; --driver's help may still say real drivers need it), and the old
  // name --out works but is not shown.
  for (const char* option : {"\n  --realtime", "\n  --quiet", "\n  --dry", "\n  --out "}) {
    EXPECT_THAT(help.out, Not(HasSubstr(option))) << help.out;
  }

  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const std::string options = " --seed 5 --fault " + shell_quote("garbage:robot=melfa,command=grip,n=1");
  const Outcome run = cli.run("run " + scenario + options + " --quiet -o " + shell_quote((cli.dir() / "run").string()));
  ASSERT_NE(run.status, 2) << run.out << run.err;
  const std::string input = "c\n";
  const fs::path video = cli.dir() / "step.mp4";
  const Outcome step = cli.run("step " + scenario + options + " --out " + shell_quote((cli.dir() / "step").string()) +
                                   " --video " + shell_quote(video.string()) + " --video-fps 2 --video-size 160x120",
                               &input);
  EXPECT_EQ(step.status, run.status) << step.out << step.err;
  EXPECT_THAT(step.out, HasSubstr("ran to the end"));
  EXPECT_THAT(step.out, HasSubstr("video in " + video.string()));
  expect_browser_mp4(video);
  EXPECT_EQ(slurp(cli.dir() / "step" / "events.jsonl"), slurp(cli.dir() / "run" / "events.jsonl"));
}

TEST(VideoCli, CampaignRecordsTheFailedRunsOnly) {
  TwinCli cli("cw-video-cli-campaign");
  const fs::path out = cli.dir() / "campaign";
  // A video size that cannot be is refused before any run, not after the campaign.
  const Outcome bad = cli.run("campaign " + shell_quote(source_path("scenes/exchange.yaml")) +
                              " --runs 2 --video --video-size 161x120 --output " + shell_quote(out.string()));
  EXPECT_EQ(bad.status, 2) << bad.out << bad.err;
  EXPECT_THAT(bad.err, HasSubstr("even"));
  EXPECT_FALSE(fs::exists(out));
  // Garbage on a grip: recovered or not, depending on the draw; a few runs give both kinds.
  const Outcome r = cli.run("campaign " + shell_quote(source_path("scenes/exchange.yaml")) +
                            " --faults hardware,drop --runs 4 --seed 3 --jobs 2 --video --video-fps 4 --video-size 160x120 --output " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  int failed = 0, videos = 0;
  for (const auto& run : fs::directory_iterator(out / "runs")) {
    const std::string report = slurp(run.path() / "report.json");
    const bool ok = report.find("\"result\": \"ok\"") != std::string::npos;
    const bool has_video = fs::exists(run.path() / "video.mp4");
    EXPECT_EQ(has_video, !ok) << run.path();
    failed += ok ? 0 : 1;
    videos += has_video ? 1 : 0;
    if (has_video) expect_browser_mp4(run.path() / "video.mp4");
  }
  EXPECT_EQ(videos, failed);
  EXPECT_GT(failed, 0) << "no failed run to record: choose other faults or seed";
}

}  // namespace
