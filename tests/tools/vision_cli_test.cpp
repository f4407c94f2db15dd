// `twin run` with the camera, as a user runs it: in scenes/vision.yaml workpiece A arrives 35-70 mm to the side of
// where the cell description puts it. With vision the PUMA picks it where the camera sees it and the run succeeds;
// with the camera off (perception cad: the controller knows only the cell description) the same pick misses and the
// run fails. Frames are saved with --save-frames (with and without vision), and a run's log is the same on every run
// and with or without saved frames.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
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

// White pixels in the band along a saved frame's top, where its simulated time is written.
int overlay_text_pixels(const cv::Mat& frame) {
  cv::Mat white;
  cv::inRange(frame(cv::Rect(0, 0, frame.cols, 22)), cv::Scalar(200, 200, 200), cv::Scalar(255, 255, 255), white);
  return cv::countNonZero(white);
}

std::string run_vision(const TwinCli& cli, const fs::path& out, const std::string& extra, Outcome& outcome) {
  outcome = cli.run("run " + shell_quote(source_path("scenes/vision.yaml")) + " --quiet -o " +
                    shell_quote(out.string()) + " " + extra);
  return fs::exists(out / "events.jsonl") ? slurp(out / "events.jsonl") : std::string();
}

TEST(VisionCli, PicksThePerturbedPartWhereTheCameraSeesItAndMissesItWithoutTheCamera) {
  TwinCli cli("cw-vision-cli");
  Outcome seen;
  const fs::path frames = cli.dir() / "frames";
  const std::string log = run_vision(cli, cli.dir() / "vision", "--save-frames " + shell_quote(frames.string()), seen);
  ASSERT_EQ(seen.status, 0) << seen.out << seen.err;
  EXPECT_THAT(seen.out, HasSubstr("ok   A: expected mill_side"));
  // The scenario's perturbation is logged as a misplacement, and the controller sensed it (camera: A off its place)
  // and picked it where it was seen: no false alarm.
  EXPECT_THAT(log, HasSubstr("\"type\":\"fault_injected\",\"kind\":\"misplace\""));
  EXPECT_THAT(log, HasSubstr("\"symptom\":\"part_misplaced\""));
  const nlohmann::json report = nlohmann::json::parse(slurp(cli.dir() / "vision" / "report.json"));
  EXPECT_EQ(report["false_alarms"], 0);

  // The camera saw A off its nominal place (the cell description puts it on the belt's centre line, y = -0.55), and
  // the model took the camera's word: the vision events carry A's position.
  bool saw_a_off_centre = false;
  bool saw_a_parked_part = false;  // B and C wait out of the camera's view to be fed after the run has ended
  std::istringstream lines(log);
  std::string line;
  int frames_logged = 0;
  while (std::getline(lines, line)) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] != "vision") continue;
    ++frames_logged;
    for (const auto& s : e["seen"]) {
      if (s["workpiece"] == "A" && std::abs(s["y"].get<double>() + 0.55) > 0.03) saw_a_off_centre = true;
      if (s["workpiece"] == "B" || s["workpiece"] == "C") saw_a_parked_part = true;
    }
  }
  EXPECT_TRUE(saw_a_off_centre);
  EXPECT_FALSE(saw_a_parked_part);
  // One frame every 400 ms of simulation time, each saved as a PNG.
  const double end = nlohmann::json::parse(slurp(cli.dir() / "vision" / "report.json"))["end_time"].get<double>();
  EXPECT_NEAR(frames_logged, end / 0.4, 2.0);
  int pngs = 0;
  for (const auto& f : fs::directory_iterator(frames)) pngs += f.path().extension() == ".png" ? 1 : 0;
  EXPECT_EQ(pngs, frames_logged);
  // A frame with A on the belt: the time in the band along the top, A's predicted pose (a yellow cross) beside the
  // detection's outline.
  int frames_with_a_prediction = 0;
  for (const auto& f : fs::directory_iterator(frames)) {
    const cv::Mat image = cv::imread(f.path().string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty()) << f.path();
    EXPECT_GT(overlay_text_pixels(image), 40) << f.path();
    cv::Mat yellow;
    cv::inRange(image(cv::Rect(0, 22, image.cols, image.rows - 22)), cv::Scalar(0, 200, 235), cv::Scalar(40, 240, 255),
                yellow);
    frames_with_a_prediction += cv::countNonZero(yellow) > 20 ? 1 : 0;
  }
  EXPECT_GT(frames_with_a_prediction, 0);

  // The same run again: the same bytes.
  Outcome again;
  EXPECT_EQ(run_vision(cli, cli.dir() / "again", "", again), log);

  // Vision off: the controller believes the cell description and the pick fails.
  Outcome blind;
  run_vision(cli, cli.dir() / "cad", "--perception cad", blind);
  EXPECT_EQ(blind.status, 1) << blind.out << blind.err;
  EXPECT_THAT(blind.out, HasSubstr("FAIL A: expected mill_side"));
  // The report says what this run used (--perception cad, not the scenario's vision), and every part's state is where
  // it physically is: a part a robot holds at the end is "held", whatever the controller declared.
  const nlohmann::json cad = nlohmann::json::parse(slurp(cli.dir() / "cad" / "report.json"));
  EXPECT_EQ(cad["perception"], "cad");
  EXPECT_THAT(blind.out, HasSubstr("perception cad; drivers: puma simulated"));
  const std::string page = slurp(cli.dir() / "cad" / "index.html");
  EXPECT_THAT(page, HasSubstr("perception cad"));
  EXPECT_THAT(page, ::testing::Not(HasSubstr("perception vision")));
  for (std::size_t i = 0; i < cad["workpieces"].size(); ++i) {
    const nlohmann::json& w = cad["workpieces"][i];
    const nlohmann::json& account = cad["account"][i];
    ASSERT_EQ(account["workpiece"], w["name"]);
    const std::string where = w["final_location"];
    if (where.starts_with("held by ")) {
      EXPECT_EQ(account["status"], "held") << account.dump();
      EXPECT_EQ(account["where"], where.substr(8)) << account.dump();
    }
    if (w["ok"] == true) {
      EXPECT_EQ(account["status"], "in_place") << account.dump();
    }
  }
}

// Without vision, --save-frames writes the camera's plain frames every vision period (0.4 s), stamped with their
// simulated time, and the run's log is the same as without them.
TEST(VisionCli, SavingFramesWithoutVisionWritesPlainCameraFrames) {
  TwinCli cli("cw-vision-cli-plain");
  const fs::path frames = cli.dir() / "frames";
  auto run = [&](const std::string& out, const std::string& extra) {
    const Outcome o = cli.run("run " + shell_quote(source_path("scenes/single.yaml")) + " --quiet -o " +
                              shell_quote((cli.dir() / out).string()) + extra);
    EXPECT_EQ(o.status, 0) << o.out << o.err;
    return slurp(cli.dir() / out / "events.jsonl");
  };
  const std::string log = run("with", " --save-frames " + shell_quote(frames.string()));
  EXPECT_THAT(log, ::testing::Not(HasSubstr("\"type\":\"vision\"")));  // no one looked at them
  const double end = nlohmann::json::parse(slurp(cli.dir() / "with" / "report.json"))["end_time"].get<double>();
  std::vector<fs::path> pngs;
  for (const auto& f : fs::directory_iterator(frames)) {
    if (f.path().extension() == ".png") pngs.push_back(f.path());
  }
  EXPECT_NEAR(static_cast<double>(pngs.size()), end / 0.4, 2.0);
  ASSERT_TRUE(fs::exists(frames / "frame_00000400.png"));
  const cv::Mat frame = cv::imread((frames / "frame_00000400.png").string(), cv::IMREAD_COLOR);
  ASSERT_EQ(frame.cols, 640);
  EXPECT_GT(overlay_text_pixels(frame), 40);  // "t = 0.400 s": about 90 px
  EXPECT_EQ(run("without", ""), log);
}

// A cell with no camera at all: --save-frames has nothing to save, so the run is refused before anything runs
// (exit 2, the reason named) and neither the frames directory's contents nor any output are written.
TEST(VisionCli, SavingFramesOfACellWithoutACameraIsRefused) {
  TwinCli cli("cw-vision-cli-nocam");
  std::string cell = slurp(source_path("scenes/cell.yaml"));
  const auto cameras = cell.find("\ncameras:"), lights = cell.find("\nlights:");
  ASSERT_NE(cameras, std::string::npos);
  ASSERT_NE(lights, std::string::npos);
  cell.erase(cameras, lights - cameras);
  for (const char* urdf : {"puma560.urdf", "melfa_rve2.urdf"}) {
    const std::string rel = std::string("../models/urdf/") + urdf;
    const auto at = cell.find(rel);
    ASSERT_NE(at, std::string::npos) << rel;
    cell.replace(at, rel.size(), source_path("models/urdf/" + std::string(urdf)));
  }
  std::ofstream(cli.dir() / "cell.yaml") << cell;
  std::string scenario = slurp(source_path("scenes/single.yaml"));
  const auto program = scenario.find("program: single.task");
  ASSERT_NE(program, std::string::npos);
  scenario.replace(program, std::string("program: single.task").size(), "program: " + source_path("scenes/single.task"));
  std::ofstream(cli.dir() / "single.yaml") << scenario;  // cell: cell.yaml, the copy beside it

  // The copy without frames runs, so what is refused below is the option, not the cell.
  const Outcome plain = cli.run("run " + shell_quote((cli.dir() / "single.yaml").string()) + " --quiet");
  EXPECT_EQ(plain.status, 0) << plain.out << plain.err;

  const fs::path frames = cli.dir() / "frames", out = cli.dir() / "out";
  const Outcome r = cli.run("run " + shell_quote((cli.dir() / "single.yaml").string()) + " --quiet -o " +
                            shell_quote(out.string()) + " --save-frames " + shell_quote(frames.string()));
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("--save-frames needs a camera, and the cell has none"));
  EXPECT_THAT(r.err, HasSubstr("single.yaml"));
  EXPECT_FALSE(fs::exists(out / "events.jsonl"));
  EXPECT_FALSE(fs::exists(out / "report.json"));
  EXPECT_TRUE(!fs::exists(frames) || fs::is_empty(frames));
}

}  // namespace
