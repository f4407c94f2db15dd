// `twin run` and `twin step` as a user runs them, end to end on the simulated cell: the paper's exchange (Table 1)
// moves workpiece A physically to the output conveyor, the event log follows the program's net and is byte-identical
// from run to run, a wrong expectation fails the run, and bad input is refused before anything runs.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
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

// A copy of scenes/exchange.yaml in `dir` with the cell and program given by absolute path and `edit` applied
// (each pair: text to find, replacement).
fs::path exchange_copy(const fs::path& dir, const std::vector<std::pair<std::string, std::string>>& edits) {
  std::string text = slurp(source_path("scenes/exchange.yaml"));
  auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << "exchange.yaml no longer contains: " << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  };
  replace("cell: cell.yaml", "cell: " + source_path("scenes/cell.yaml"));
  replace("program: exchange.task", "program: " + source_path("scenes/exchange.task"));
  for (const auto& [from, to] : edits) replace(from, to);
  const fs::path p = dir / "scenario.yaml";
  std::ofstream(p) << text;
  return p;
}

std::vector<nlohmann::json> read_events(const fs::path& file) {
  std::vector<nlohmann::json> out;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) out.push_back(nlohmann::json::parse(line));
  return out;
}

// Time of the first `fire` of a transition, or -1.
double fired_at(const std::vector<nlohmann::json>& events, const std::string& transition) {
  for (const auto& e : events) {
    if (e["type"] == "fire" && e["transition"] == transition) return e["t"].get<double>();
  }
  return -1;
}

TEST(RunCli, ExchangeMovesThePartToTheOutputConveyorAndRepeatsExactly) {
  TwinCli cli("cw-run-cli");
  const fs::path a = cli.dir() / "a", b = cli.dir() / "b";
  const Outcome first =
      cli.run("run " + shell_quote(source_path("scenes/exchange.yaml")) + " --quiet -o " + shell_quote(a.string()));
  ASSERT_EQ(first.status, 0) << first.out << first.err;
  EXPECT_THAT(first.out, HasSubstr("estimated cycle time"));
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "final.png"}) {
    EXPECT_TRUE(fs::is_regular_file(a / f)) << f;
    EXPECT_GT(fs::file_size(a / f), 0u) << f;
  }
  // No temporary files are left behind by the atomic writes, nor the log streamed during the run.
  for (const auto& entry : fs::directory_iterator(a)) {
    EXPECT_THAT(entry.path().filename().string(), Not(HasSubstr("tmp"))) << entry.path();
    EXPECT_THAT(entry.path().filename().string(), Not(HasSubstr(".part"))) << entry.path();
  }

  const nlohmann::json report = nlohmann::json::parse(slurp(a / "report.json"));
  EXPECT_EQ(report["result"], "ok");
  EXPECT_EQ(report["outcome"], "finished");
  EXPECT_TRUE(report["collisions"].empty()) << report["collisions"].dump();
  const nlohmann::json& part = report["workpieces"][0];
  EXPECT_EQ(part["name"], "A");
  EXPECT_EQ(part["final_location"], "output");
  EXPECT_EQ(part["ok"], true);
  EXPECT_GT(part["cycle_time"].get<double>(), 0.0);
  EXPECT_GT(report["cycle_time"]["estimated"].get<double>(), 0.0);
  EXPECT_GT(report["cycle_time"]["measured"].get<double>(), 0.0);

  // The part moved by contact: each robot closed its gripper on A (the sensor saw it between the pads).
  const auto events = read_events(a / "events.jsonl");
  std::map<std::string, int> gripped;
  for (const auto& e : events) {
    if (e["type"] == "sensor" && e["condition"] == "gripped" && e["workpiece"] == "A") ++gripped[e["robot"]];
  }
  EXPECT_EQ(gripped["r1"], 1);
  EXPECT_EQ(gripped["r2"], 1);
  // A clean run raises no alarm: no detector fired, the safety layer never stopped a robot (docs/faults.md).
  EXPECT_EQ(report["false_alarms"], 0);
  for (const auto& e : events) {
    EXPECT_NE(e["type"], "fault_detected") << e.dump();
    EXPECT_NE(e["type"], "protective_stop") << e.dump();
  }

  // The event order respects the net: each robot fires its transitions in program order, a command runs between the
  // transition that starts it and the next one, and the hand-over handshake (docs/task-language.md's listing) goes
  // ready -> grasp -> gripped -> release -> released -> depart.
  std::map<std::string, int> next;
  std::map<std::string, double> last_fire;
  for (const auto& e : events) {
    if (e["type"] == "fire") {
      const std::string robot = e["robot"], id = e["transition"];
      EXPECT_EQ(id, robot + ".t" + std::to_string(next[robot]++));
      last_fire[robot] = e["t"];
    } else if (e["type"] == "command_start" || e["type"] == "command_end") {
      const std::string robot = e["robot"];
      EXPECT_EQ(e["primitive"].get<int>(), next[robot] - 1) << e.dump();
    }
  }
  EXPECT_EQ(next["r1"], 15);                                         // 14 primitives + the end
  EXPECT_EQ(next["r2"], 17);                                         // 16 primitives + the end
  EXPECT_LE(fired_at(events, "r1.t8"), fired_at(events, "r2.t5"));   // ready, then r2 grasps at the hand
  EXPECT_LE(fired_at(events, "r2.t7"), fired_at(events, "r1.t10"));  // gripped, then r1 opens
  EXPECT_LE(fired_at(events, "r1.t11"), fired_at(events, "r2.t9"));  // released, then r2 departs

  // The same scenario and seed give the same bytes.
  const Outcome second =
      cli.run("run " + shell_quote(source_path("scenes/exchange.yaml")) + " --quiet -o " + shell_quote(b.string()));
  ASSERT_EQ(second.status, 0) << second.out << second.err;
  EXPECT_EQ(slurp(a / "events.jsonl"), slurp(b / "events.jsonl"));
  EXPECT_EQ(slurp(a / "report.json"), slurp(b / "report.json"));
}

// The pipelined cell, with both arms and with one: three parts fed onto the input conveyor all end where the scenario
// expects them, without a collision.
class PipelinedScenario : public ::testing::TestWithParam<const char*> {};

TEST_P(PipelinedScenario, DeliversEveryFedPartWithoutACollision) {
  TwinCli cli("cw-run-pipeline");
  const fs::path out = cli.dir() / "out";
  const Outcome r = cli.run("run " + shell_quote(source_path(std::string("scenes/") + GetParam())) + " --quiet -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["result"], "ok");
  EXPECT_EQ(report["parts_completed"], 3);
  EXPECT_GT(report["throughput_parts_per_min"].get<double>(), 0.0);
  EXPECT_TRUE(report["collisions"].empty()) << report["collisions"].dump();
  int expected = 0;
  for (const auto& w : report["workpieces"]) {
    if (!w.contains("expected") || w["expected"].is_null()) continue;
    ++expected;
    EXPECT_EQ(w["ok"], true) << w.dump();
  }
  EXPECT_EQ(expected, 3);
  // No detector fired on the clean run, and every part is accounted in place.
  EXPECT_EQ(report["false_alarms"], 0);
  EXPECT_EQ(report["unaccounted"], 0);
  EXPECT_THAT(slurp(out / "events.jsonl"), Not(HasSubstr("fault_detected")));
  EXPECT_THAT(slurp(out / "events.jsonl"), Not(HasSubstr("protective_stop")));
}

INSTANTIATE_TEST_SUITE_P(RunCli, PipelinedScenario, ::testing::Values("pipeline.yaml", "pipeline_single.yaml"));

// A named part relayed between robots (docs/scenarios.md, "Relaying a part between robots"), run in lock-step: over
// the stand of scenes/relay.yaml (the PUMA puts A down, the MELFA takes it to the output conveyor), and over two belts
// between three arms (tests/data/relay/relay_named.yaml: each taker waits until the belt has brought A to rest at its
// stop). Both were refused before: the scenario's stand was unknown, the belt's taker was checked where A was let go.
class RelayScenario : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(RelayScenario, TheTakerTakesThePartWhereTheGiverLeftItAndItEndsWhereExpected) {
  TwinCli cli("cw-run-relay");
  const fs::path out = cli.dir() / "out";
  const Outcome r =
      cli.run("run " + shell_quote(source_path(GetParam().first)) + " --quiet -o " + shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["result"], "ok");
  EXPECT_EQ(report["parts_completed"], 1);
  EXPECT_TRUE(report["collisions"].empty()) << report["collisions"].dump();
  int a = 0;
  for (const auto& w : report["workpieces"]) {
    if (w["name"] != "A") continue;
    ++a;
    EXPECT_EQ(w["ok"], true) << w.dump();
  }
  EXPECT_EQ(a, 1);
  EXPECT_THAT(r.out, HasSubstr(GetParam().second));
  EXPECT_THAT(slurp(out / "events.jsonl"), Not(HasSubstr("fault_detected")));
}

INSTANTIATE_TEST_SUITE_P(RunCli, RelayScenario,
                         ::testing::Values(std::make_pair("scenes/relay.yaml", "A: expected output, is output"),
                                           std::make_pair("tests/data/relay/relay_named.yaml",
                                                          "A: expected t3_top, is t3_top")));

TEST(RunCli, WrongExpectedOutcomeExitsOneNamingIt) {
  TwinCli cli("cw-run-cli-wrong");
  const fs::path scenario = exchange_copy(cli.dir(), {{"  A: output", "  A: machine_fixture"}});
  const Outcome r =
      cli.run("run " + shell_quote(scenario.string()) + " --quiet -o " + shell_quote((cli.dir() / "out").string()));
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("FAILED"));
  EXPECT_THAT(r.out, HasSubstr("workpiece A must end at machine_fixture"));
  const nlohmann::json report = nlohmann::json::parse(slurp(cli.dir() / "out/report.json"));
  EXPECT_EQ(report["result"], "failed");
  EXPECT_EQ(report["workpieces"][0]["ok"], false);
}

// Bad input is refused with exit 2 and the reason, before anything runs: no output directory appears.
class RefusedScenario
    : public ::testing::TestWithParam<std::pair<std::vector<std::pair<std::string, std::string>>, std::string>> {};

TEST_P(RefusedScenario, ExitsTwoWithTheReasonAndWritesNothing) {
  TwinCli cli("cw-run-cli-bad");
  const auto& [edits, reason] = GetParam();
  const fs::path scenario = exchange_copy(cli.dir(), edits);
  const fs::path out = cli.dir() / "out";
  const Outcome r = cli.run("run " + shell_quote(scenario.string()) + " -o " + shell_quote(out.string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(reason));
  EXPECT_FALSE(fs::exists(out));
  EXPECT_THAT(r.out, Not(HasSubstr("t =")));  // no progress: nothing ran
}

INSTANTIATE_TEST_SUITE_P(
    BadInput, RefusedScenario,
    ::testing::Values(
        std::make_pair(std::vector<std::pair<std::string, std::string>>{{"exchange.task", "missing.task"}},
                       "missing.task"),
        std::make_pair(std::vector<std::pair<std::string, std::string>>{{"r2: melfa", "r2: kuka"}},
                       "robot 'r2' is bound to 'kuka', which is not a robot of the cell"),
        std::make_pair(std::vector<std::pair<std::string, std::string>>{{"B: output_drop", "B: nowhere"}},
                       "location 'B' is bound to 'nowhere', which is not a location of the cell"),
        std::make_pair(std::vector<std::pair<std::string, std::string>>{{"exchange.task", "deadlock.task"},
                                                                        {"bind: {B: output_drop}", ""}},
                       "fails the check"),
        std::make_pair(std::vector<std::pair<std::string, std::string>>{{"  A: output", "  A: the_moon"}},
                       "expected at 'the_moon'")));

TEST(RunCli, MissingScenarioFileExitsTwo) {
  TwinCli cli("cw-run-cli-missing");
  const Outcome r = cli.run("run " + shell_quote((cli.dir() / "none.yaml").string()));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("none.yaml"));
}

TEST(StepCli, StepsThroughAPipeShowingFiringsMarkingAndRobots) {
  TwinCli cli("cw-step-cli");
  const std::string input = "n\nn\nm\ns " + (cli.dir() / "snap.png").string() + "\nq\n";
  const Outcome r = cli.run(
      "step " + shell_quote(source_path("scenes/exchange.yaml")) + " -o " + shell_quote((cli.dir() / "out").string()),
      &input);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  // First step: r1 starts its Pick (open), r2 passes its step-1 signal and waits at the barrier.
  EXPECT_THAT(r.out, HasSubstr("fired r1.t0: r1 line 8 'Pick A' (approach A): r1 begin open"));
  EXPECT_THAT(r.out, HasSubstr("fired r2.t1"));
  // Second step: the open is done and r1 starts its move above A.
  EXPECT_THAT(r.out, HasSubstr("fired r1.t1: r1 line 8 'Pick A' (approach A): r1 begin move above(A)"));
  EXPECT_THAT(r.out, HasSubstr("marking: r1: executing approach A (line 8 'Pick A'); r2: waiting for event "
                               "step1.r1>r2"));
  EXPECT_THAT(r.out, HasSubstr("r1: busy move above(A)"));
  EXPECT_THAT(r.out, HasSubstr("r2: waiting wait step1.r1>r2"));
  EXPECT_THAT(r.out, HasSubstr("saved " + (cli.dir() / "snap.png").string()));
  EXPECT_GT(fs::file_size(cli.dir() / "snap.png"), 0u);
  EXPECT_THAT(r.out, HasSubstr("quit at t = "));
  // Exactly two steps were taken ("t = ..., N firings" twice), then the quit's final state and the summary say the
  // time of the second step again: nothing ran after the quit.
  const std::regex step_line("t = [0-9.]+ s, [0-9]+ firings");
  EXPECT_EQ(std::distance(std::sregex_iterator(r.out.begin(), r.out.end(), step_line), std::sregex_iterator()), 4);
  EXPECT_THAT(r.out, HasSubstr("stopped at t = 0.36 s, 4 firings"));
  // Quitting stops the cell safely and writes what was logged so far, the report and the charts.
  EXPECT_THAT(r.out, HasSubstr("the cell was stopped: quit by the user (twin step)"));
  const auto events = read_events(cli.dir() / "out" / "events.jsonl");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["outcome"], "stopped");
  EXPECT_TRUE(fs::is_regular_file(cli.dir() / "out" / "report.json"));
  EXPECT_TRUE(fs::is_regular_file(cli.dir() / "out" / "gantt.png"));
}

TEST(StepCli, UnknownCommandsAreExplainedAndEndOfInputQuits) {
  TwinCli cli("cw-step-cli-eof");
  const std::string input = "jump\ns\n";
  const Outcome r = cli.run("step " + shell_quote(source_path("scenes/exchange.yaml")), &input);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("unknown command 'jump'"));
  EXPECT_THAT(r.out, HasSubstr("s needs a file name"));
  EXPECT_THAT(r.out, HasSubstr("quit at t = 0.000 s"));
}

// Quitting before the first step ran nothing: nothing is written, and nothing half-made (the log begun, the video
// opened) is left in the output directory.
TEST(StepCli, QuitBeforeAnyStepLeavesNothingBehind) {
  TwinCli cli("cw-step-cli-noop");
  const fs::path out = cli.dir() / "out";
  const std::string input = "q\n";
  const Outcome r = cli.run("step " + shell_quote(source_path("scenes/exchange.yaml")) + " -o " +
                                shell_quote(out.string()) + " --video " + shell_quote((out / "step.mp4").string()),
                            &input);
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("quit at t = 0.000 s"));
  std::vector<std::string> left;
  if (fs::exists(out)) {
    for (const auto& f : fs::directory_iterator(out)) left.push_back(f.path().filename().string());
  }
  EXPECT_THAT(left, ::testing::IsEmpty());
}

// `--final-png failed` (what `twin test` asks of its runs) renders final.png only for a run that fails: a passing run
// writes its other outputs and a page that says no final snapshot was made; without -o the option is refused.
TEST(RunCli, FinalPngOnlyWhenFailedLeavesAPassingRunWithoutThePicture) {
  TwinCli cli("cw-run-final-png");
  const fs::path out = cli.dir() / "out";
  const Outcome r = cli.run("run " + shell_quote(source_path("scenes/exchange.yaml")) + " --quiet --final-png failed -o " +
                            shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "index.html"}) {
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  }
  EXPECT_FALSE(fs::exists(out / "final.png"));
  EXPECT_THAT(slurp(out / "index.html"), HasSubstr("No final snapshot was made for this run."));
  const Outcome alone = cli.run("run " + shell_quote(source_path("scenes/exchange.yaml")) + " --final-png never");
  EXPECT_EQ(alone.status, 2) << alone.out << alone.err;
  EXPECT_THAT(alone.err, HasSubstr("--final-png"));
}

// Ctrl-C at the prompt does what `q` does: the cell stopped safely and the outputs so far written (not an event log
// left as events.jsonl.part and nothing else), with the status of an interrupted command. A real SIGINT to the process.
TEST(StepCli, CtrlCAtThePromptWritesWhatQuitWrites) {
  TwinCli cli("cw-step-sigint");
  const fs::path out = cli.dir() / "out";
  cellwright::testing::BackgroundTwin step({"step", source_path("scenes/exchange.yaml"), "-o", out.string()}, true);
  ASSERT_TRUE(step.send("n\nn\n"));
  // The second step's firing printed: it waits at the prompt, its input still open.
  ASSERT_TRUE(step.wait_for("fired r1.t1", std::chrono::seconds(60))) << step.output();
  EXPECT_EQ(step.stop(SIGINT), 130) << step.output();
  EXPECT_THAT(step.output(), HasSubstr("interrupted by the user (signal): quit at t = 0.360 s"));
  EXPECT_THAT(step.output(), HasSubstr("the cell was stopped: stopped by the user (signal)"));
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "final.png", "index.html"}) {
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  }
  EXPECT_FALSE(fs::exists(out / "events.jsonl.part"));
  const auto events = read_events(out / "events.jsonl");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["outcome"], "stopped");
}

// A real robot keeps its own time, so it cannot be stepped: refused with what to run instead.
TEST(StepCli, RealDriversAreRefusedWithWhatToRunInstead) {
  TwinCli cli("cw-step-cli-real");
  const std::string input = "n\n";
  const Outcome r = cli.run("step " + shell_quote(source_path("scenes/exchange.yaml")) +
                                " --driver melfa=movemaster:/dev/ttyS0",
                            &input);
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("twin step runs the program lock-step on simulated robots"));
  EXPECT_THAT(r.err, HasSubstr("twin run --realtime"));
}

TEST(StepCli, BadScenarioExitsTwo) {
  TwinCli cli("cw-step-cli-bad");
  const fs::path scenario = exchange_copy(cli.dir(), {{"r2: melfa", "r2: kuka"}});
  const std::string input = "n\n";
  const Outcome r = cli.run("step " + shell_quote(scenario.string()), &input);
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("kuka"));
}

}  // namespace

namespace {

// Ctrl-C or SIGTERM during a run stops the cell safely and still writes what a finished run writes: the event log up
// to the stop, the report and the charts.
TEST(RunCli, ASignalStopsTheCellSafelyAndTheOutputsSoFarAreWritten) {
  TwinCli cli("cw-run-signal");
  const fs::path out = cli.dir() / "out";
  // In real time the pipeline takes a minute: the signal certainly comes first.
  cellwright::testing::BackgroundTwin run(
      {"run", source_path("scenes/pipeline.yaml"), "--realtime", "-o", out.string()});
  ASSERT_TRUE(run.wait_for("estimated cycle time", std::chrono::seconds(60))) << run.output();
  EXPECT_EQ(run.stop(), 1) << run.output();
  EXPECT_THAT(run.output(), HasSubstr("the cell was stopped: stopped by the user"));
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "final.png"}) {
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  }
  const auto events = read_events(out / "events.jsonl");
  ASSERT_GE(events.size(), 3U);
  EXPECT_EQ(events.front()["type"], "run_start");
  EXPECT_EQ(events[events.size() - 2]["type"], "cell_stopped");
  EXPECT_EQ(events.back()["outcome"], "stopped");
  const nlohmann::json report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["outcome"], "stopped");
  EXPECT_EQ(report["result"], "failed");
}

// The same while a video is recorded into the output directory (which does not exist before the run): the stop
// ends the run, not the process (the video's encoder thread and ffmpeg included), the outputs are written, the page
// shows the video beside it, and the video is closed with the verdict.
TEST(RunCli, ASignalDuringAVideoStopsTheRunAndKeepsTheVideo) {
  TwinCli cli("cw-run-signal-video");
  const fs::path out = cli.dir() / "new" / "out";
  // With a video a lock-step run goes at about a frame's encoding per 50 ms simulated: the signal comes first.
  cellwright::testing::BackgroundTwin run({"run", source_path("scenes/exchange.yaml"), "-o", out.string(), "--video",
                                           (out / "run.mp4").string(), "--video-size", "320x240"});
  ASSERT_TRUE(run.wait_for("estimated cycle time", std::chrono::seconds(60))) << run.output();
  EXPECT_EQ(run.stop(), 1) << run.output();
  EXPECT_THAT(run.output(), HasSubstr("the cell was stopped: stopped by the user"));
  EXPECT_THAT(run.output(), HasSubstr("video in " + (out / "run.mp4").string()));
  for (const char* f : {"events.jsonl", "report.json", "gantt.png", "final.png", "index.html", "run.mp4"}) {
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  }
  EXPECT_THAT(slurp(out / "index.html"), HasSubstr("src=\"run.mp4\""));
  const std::string video = slurp(out / "run.mp4");
  ASSERT_GT(video.size(), 1000U);
  EXPECT_EQ(video.substr(4, 4), "ftyp");
  EXPECT_NE(video.find("moov"), std::string::npos) << "the MP4 was not closed";
}

}  // namespace
