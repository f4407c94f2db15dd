// The options `twin run` and `twin step` share (run_args.hpp).
#include "run_args.hpp"

#include <fmt/format.h>

#include <any>
#include <chrono>
#include <filesystem>
#include <system_error>

#include "cellwright/common/error.hpp"
#include "cellwright/cell/outputs.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/twin/faults.hpp"
#if CW_SIM
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/vision/cell_detector.hpp"
#include "cellwright/vision/draw.hpp"
#include "cellwright/vision/png.hpp"
#endif

namespace cellwright::tools {

void add_run_options(CLI::App& cmd, RunArgs& args) {
  cmd.add_option("scenario", args.scenario, "scenario file (.yaml, docs/scenarios.md)")->required();
  cmd.add_option("-o,--output", args.output,
                 "directory for the outputs (created if needed): events.jsonl, report.json, gantt.png, final.png and "
                 "index.html, the report page");
  // The old name, for scripts written before the options were made the same everywhere; not shown in --help.
  cmd.add_option("--out", args.output)->group("");
  cmd.add_flag("--force", args.force,
               "write into the -o directory even though it is not Cellwright's (no .cellwright-output in it) and holds "
               "files of those names, replacing them");
  cmd.add_option("--perception", args.perception,
                 "where the controller learns where the parts are, instead of the scenario's choice: truth (the "
                 "simulation), vision (the camera) or cad (the cell description only: vision off)")
      ->check(CLI::IsMember({"truth", "vision", "cad"}));
  cmd.add_option("--driver", args.drivers,
                 "put a robot on another driver, the rest of the scenario unchanged: ROBOT=sim, "
                 "ROBOT=movemaster:PORT or ROBOT=val2:PORT (repeatable; real drivers need --realtime)");
  cmd.add_option("--fault", args.faults,
                 "inject a fault, added to the scenario's faults: KIND:key=value,key=value with a list as a/b, e.g. "
                 "drop:robot=puma,carry=1 (docs/faults.md; repeatable)");
  cmd.add_option("--seed", args.seed,
                 "the run's seed instead of the scenario's (random amounts of the faults, perturbations)");
  cmd.add_option("--save-frames", args.frames,
                 "write each camera frame as DIR/frame_<ms>.png (8 digits) with its simulated time; with vision, the "
                 "detections, the predicted poses and the parts not seen drawn on it; without, plain frames every "
                 "vision period");
  CLI::Option* video = cmd.add_option("--video", args.video,
                 "record the overview camera as FILE.mp4 (H.264, plays in a browser): simulated time, each robot's "
                 "command and the verdict drawn on it; the event log is the same with or without");
  cmd.add_option("--video-fps", args.video_fps, "video frames per second of simulated time (default 20)")
      ->check(CLI::Range(1, 120))
      ->needs(video);
  cmd.add_option("--video-size", args.video_size, "video width x height in pixels, both even (default 800x600)")
      ->needs(video);
  cmd.add_option("--camera", args.cameras,
                 "take vision's frames from a real camera instead of the twin's: NAME=v4l2:/dev/videoN (with "
                 "--realtime) or a recording, NAME=file:VIDEO or NAME=file:GLOB,fps=N (image files in sorted order; "
                 "frame i is the picture of time i/fps); NAME the camera vision looks through (docs/vision.md)");
  cmd.add_option("--device", args.devices,
                 "put a device of the cell on real I/O, instead of the scenario's choice: NAME=modbus:HOST:PORT[/UNIT] "
                 "(Modbus TCP, unit 1 by default) or NAME=twin; NAME a machine, conveyor or photo-eye the cell's io "
                 "keys wire; repeatable; real I/O needs --realtime; docs/devices.md)");
  cmd.add_option("--record-camera", args.record_camera,
                 "write each frame of vision's camera (plain, as captured) as DIR/frame_<i>.png (6 digits, i the "
                 "vision period it belongs to): lossless, to be read back with --camera NAME=file:DIR/frame_*.png,"
                 "fps=1/PERIOD");
  cmd.add_flag("--allow-collisions", args.allow_collisions,
               "run even though the preflight's motion sweep predicts collisions (printed as warnings)");
}

cell::Scenario load_scenario_with(const RunArgs& args) {
  using namespace cell;
  if (!args.output.empty()) check_output_directory(args.output, run_output_files(), args.force);
  if (!args.frames.empty()) check_writable_dir(args.frames);
  if (!args.record_camera.empty()) check_writable_dir(args.record_camera);
  Scenario s = load_scenario(args.scenario);
  for (const std::string& d : args.drivers) set_driver(s, d, {"--driver", 0, 0});
  set_devices(s, args.devices, {"--device", 0, 0});
  for (const std::string& f : args.faults) s.faults.push_back(parse_fault_text(f, s.cell, "--fault"));
  if (args.seed) s.seed = *args.seed;
  return s;
}

void check_speed_for_real_arms(const cell::Scenario& s, double speed) {
  if (speed <= 1.0) return;
  for (const cell::DriverUse& d : cell::setup_of(s).drivers) {
    if (d.kind == "sim" || d.emulated) continue;
    throw InputError({"--speed", 0, 0},
                     fmt::format("{:g} paces the run faster than the wall clock, and robot '{}' is a real arm ({} on "
                                 "{}, not an emulator's pseudo-terminal), which moves at its own pace: every motion "
                                 "would take {:g} times longer on the run's clock than planned; leave --speed out (or "
                                 "at most 1) with real arms",
                                 speed, d.robot, d.kind, d.port, speed));
  }
}

#if CW_SIM
namespace {

// "800x600" as width and height; InputError naming --video-size otherwise (the sizes themselves are checked by the
// video writer when it opens).
std::pair<int, int> parse_size(const std::string& text) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x') {
    throw InputError({"--video-size", 0, 0}, fmt::format("'{}' is not WIDTHxHEIGHT, e.g. 800x600", text));
  }
  return {w, h};
}

}  // namespace

cell::RunOptions run_options_for(const RunArgs& args, const cell::Scenario& s) {
  using namespace cell;
  RunOptions options;
  if (args.perception == "truth") options.perception = runtime::Perception::kTruth;
  if (args.perception == "vision") options.perception = runtime::Perception::kVision;
  if (args.perception == "cad") options.perception = runtime::Perception::kCad;
  // Every check before anything is made (the frames directory below).
  if (!args.video.empty()) options.video = video_options_for(args);
  if (!args.frames.empty() && s.cell.cameras.empty()) {  // without vision: plain frames, of a camera still
    throw InputError({args.scenario, 0, 0}, "--save-frames needs a camera, and the cell has none");
  }
  if (!args.frames.empty()) {
    const std::filesystem::path dir = args.frames;
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) {
      throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the frames directory: {}", ec.message()));
    }
    const models::CameraSpec* cam = s.cell.find_camera(s.vision ? s.vision->camera : s.cell.cameras[0].name);
    options.on_frame = [dir, cam](const runtime::VisionFrame& f) {
      if (f.image.empty()) return;
      const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(f.time).count();
      cv::Mat drawn = vision::as_mat(f.image).clone();
      if (const auto* found = std::any_cast<vision::DetectionResult>(&f.result.detail)) {
        vision::draw_detections(drawn, *found);
      }
      std::vector<vision::PredictedPart> predicted;  // the model's poses before this frame corrected them
      for (const runtime::Prediction& p : f.predictions) predicted.push_back({p.workpiece, p.position});
      if (cam != nullptr) {
        vision::draw_frame_overlay(drawn, std::chrono::duration<double>(f.time).count(),
                                   vision::CameraModel(*cam, drawn.cols, drawn.rows), predicted, f.result.not_seen);
      }
      vision::write_png(drawn, dir / fmt::format("frame_{:08}.png", ms));
    };
  }
  if (!args.record_camera.empty()) {
    if (s.cell.cameras.empty()) throw InputError({args.scenario, 0, 0}, "--record-camera needs a camera, and the cell has none");
    const std::filesystem::path dir = args.record_camera;
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the directory: {}", ec.message()));
    const double period = s.vision ? s.vision->period : cell::VisionSettings{}.period;
    // Frame i belongs to period i: replayed at fps = 1 / period, frame round(t * fps) is the one taken at t.
    options.on_frame = [dir, period, saving = std::move(options.on_frame)](const runtime::VisionFrame& f) {
      if (saving) saving(f);
      if (f.image.empty()) return;
      const auto i = std::llround(std::chrono::duration<double>(f.time).count() / period);
      vision::write_png(vision::as_mat(f.image), dir / fmt::format("frame_{:06}.png", i));
    };
  }
  options.cameras = args.cameras;
  if (!args.output.empty()) options.events_file = streamed_events_file(args.output);
  return options;
}

twin::VideoOptions video_options_for(const RunArgs& args) {
  twin::VideoOptions video;
  video.path = args.video;
  video.fps = args.video_fps;
  std::tie(video.width, video.height) = parse_size(args.video_size);
  twin::VideoWriter::check_format({"--video-size", 0, 0}, video.width, video.height, video.fps);
  return video;
}

#endif  // CW_SIM

void add_video_flag(CLI::App& cmd, VideoFlag& video, const std::string& help) {
  CLI::Option* flag = cmd.add_flag("--video", video.on, help);
  cmd.add_option("--video-fps", video.fps, "with --video: frames per second of simulated time (default 20)")
      ->check(CLI::Range(1, 120))
      ->needs(flag);
  cmd.add_option("--video-size", video.size, "with --video: width x height in pixels, both even (default 800x600)")
      ->needs(flag);
}

#if CW_SIM
void check_video_flag(const VideoFlag& video) {
  if (!video.on) return;
  RunArgs args;
  args.video_fps = video.fps;
  args.video_size = video.size;
  (void)video_options_for(args);
  twin::VideoWriter::check_encoder({"--video", 0, 0});
}

cell::Report run_for_video(const RunArgs& args) {
  using namespace cell;
  CW_CHECK(!args.video.empty(), "run_for_video needs a video file");
  const Scenario s = load_scenario_with(args);
  const Preflight pre = preflight(s, &twin_port());
  if (!pre.ok(args.allow_collisions)) throw InputError({args.scenario, 0, 0}, "preflight refuses the scenario");
  ScenarioRun sr(s, pre, run_options_for(args, s));
  sr.runtime().run();
  const Report report = sr.report();
  if (!args.output.empty()) sr.write_outputs(args.output, report, sr.snapshot(800, 600));
  sr.finish_video(report);
  return report;
}

#endif  // CW_SIM

}  // namespace cellwright::tools
