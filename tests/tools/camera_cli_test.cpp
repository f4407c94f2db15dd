// A real camera in place of the twin's (issue 26): the twin records its own camera (`--record-camera DIR`, lossless
// PNG files), and a run of the vision scenario that reads the recording as its camera (`--camera
// overhead=file:DIR/frame_*.png,fps=2.5`) sees the parts where the live run saw them and ends the same way. A
// recording that ends early is the frame-lost fault, and the run still ends. Bad --camera texts and files are refused
// before anything runs (exit 2).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
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

struct Seen {
  double x = 0, y = 0;
  std::optional<double> yaw;
};

// Every vision event's sightings, by the frame's time (ms) and the workpiece.
std::map<long long, std::map<std::string, Seen>> sightings(const std::string& log) {
  std::map<long long, std::map<std::string, Seen>> out;
  std::istringstream lines(log);
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json e = nlohmann::json::parse(line);
    if (e["type"] != "vision") continue;
    auto& frame = out[std::llround(e["frame"].get<double>() * 1000)];
    for (const auto& s : e["seen"]) {
      Seen seen{s["x"].get<double>(), s["y"].get<double>(), std::nullopt};
      if (s.contains("yaw") && !s["yaw"].is_null()) seen.yaw = s["yaw"].get<double>();
      frame[s["workpiece"].get<std::string>()] = seen;
    }
  }
  return out;
}

std::string fmt_frame(int i) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06d.png", i);
  return name;
}

Outcome run_vision(const TwinCli& cli, const fs::path& out, const std::string& extra) {
  return cli.run("run " + shell_quote(source_path("scenes/vision.yaml")) + " --quiet -o " + shell_quote(out.string()) +
                 " " + extra);
}

TEST(CameraCli, ARunReadingTheTwinsRecordingAsItsCameraSeesWhatTheLiveRunSaw) {
  TwinCli cli("cw-camera-cli");
  const fs::path recording = cli.dir() / "recording";
  const Outcome live = run_vision(cli, cli.dir() / "live", "--record-camera " + shell_quote(recording.string()));
  ASSERT_EQ(live.status, 0) << live.out << live.err;
  const std::string camera =
      "--camera " + shell_quote("overhead=file:" + (recording / "frame_*.png").string() + ",fps=2.5");
  const Outcome replayed = run_vision(cli, cli.dir() / "replayed", camera);
  ASSERT_EQ(replayed.status, 0) << replayed.out << replayed.err;
  EXPECT_THAT(replayed.out, HasSubstr("ok   A: expected mill_side"));

  const auto a = sightings(slurp(cli.dir() / "live" / "events.jsonl"));
  const auto b = sightings(slurp(cli.dir() / "replayed" / "events.jsonl"));
  ASSERT_GT(a.size(), 20u);
  ASSERT_EQ(a.size(), b.size());
  int compared = 0;
  for (const auto& [t, parts] : a) {
    ASSERT_EQ(b.count(t), 1u) << "no frame at " << t << " ms in the replayed run";
    const auto& other = b.at(t);
    ASSERT_EQ(parts.size(), other.size()) << "at " << t << " ms";
    for (const auto& [name, s] : parts) {
      ASSERT_EQ(other.count(name), 1u) << name << " at " << t << " ms";
      const Seen& r = other.at(name);
      EXPECT_LE(std::hypot(s.x - r.x, s.y - r.y), 0.002) << name << " at " << t << " ms";
      ASSERT_EQ(s.yaw.has_value(), r.yaw.has_value());
      if (s.yaw) {
        EXPECT_LE(std::abs(*s.yaw - *r.yaw), 2.0) << name << " at " << t << " ms";
      }
      ++compared;
    }
  }
  EXPECT_GT(compared, 10);
  const auto outcome = [&](const char* dir) {
    return nlohmann::json::parse(slurp(cli.dir() / dir / "report.json"))["outcome"];
  };
  EXPECT_EQ(outcome("live"), outcome("replayed"));

  // The recording cut short: the frames after its end are lost, which the controller senses as the frame-lost
  // fault, and the run still ends.
  const fs::path cut = cli.dir() / "cut";
  fs::create_directories(cut);
  for (int i = 0; i < 8; ++i) {
    const std::string name = fmt_frame(i);
    fs::copy_file(recording / name, cut / name);
  }
  const Outcome shortened = run_vision(
      cli, cli.dir() / "short", "--camera " + shell_quote("overhead=file:" + (cut / "frame_*.png").string() + ",fps=2.5"));
  ASSERT_TRUE(shortened.status == 0 || shortened.status == 1) << shortened.out << shortened.err;
  const std::string log = slurp(cli.dir() / "short" / "events.jsonl");
  EXPECT_THAT(log, HasSubstr("\"symptom\":\"frame_lost\""));
  EXPECT_THAT(log, HasSubstr("ended after 8 frames"));
  // In the report: a fault the controller sensed that nothing injected (the recording ended), with its diagnosis.
  const nlohmann::json report = nlohmann::json::parse(slurp(cli.dir() / "short" / "report.json"));
  bool reported = false;
  for (const auto& d : report["unexplained_faults"]) {
    if (d["symptom"] == "frame_lost" && d["cause"] == "camera_dropout") reported = true;
  }
  EXPECT_TRUE(reported) << report.dump(2);
}

TEST(CameraCli, RefusesABadCameraBeforeAnythingRuns) {
  TwinCli cli("cw-camera-bad");
  const std::string scene = shell_quote(source_path("scenes/vision.yaml"));
  const auto refused = [&](const std::string& extra, const std::string& says) {
    const fs::path out = cli.dir() / "out";
    const Outcome o = cli.run("run " + scene + " --quiet -o " + shell_quote(out.string()) + " " + extra);
    EXPECT_EQ(o.status, 2) << extra << "\n" << o.out << o.err;
    EXPECT_THAT(o.err, HasSubstr(says)) << extra;
    EXPECT_FALSE(fs::exists(out / "events.jsonl")) << extra;
  };
  refused("--camera overhead", "no '=' between the camera's name and its source");
  refused("--camera overhead=/dev/video0", "no kind of source");
  refused("--camera overhead=usb:/dev/video0", "unknown kind of source 'usb'");
  refused("--camera nosuch=file:x.mp4", "has no camera 'nosuch'");
  refused("--camera " + shell_quote("overhead=file:" + (cli.dir() / "missing.mp4").string()), "missing.mp4");
  refused("--camera " + shell_quote("overhead=file:" + (cli.dir() / "none_*.png").string() + ",fps=2"),
          "no file matches");
  refused("--camera overhead=v4l2:/dev/video_cellwright_none --realtime", "no such device");
  refused("--camera overhead=v4l2:/dev/video0", "add --realtime");
  refused("--camera " + shell_quote("overhead=file:" + source_path("scenes/cell.yaml") + ",fps=0"), "fps must be");
  refused("--camera overhead=file:x.mp4 --perception truth", "perception is truth");
}

}  // namespace
