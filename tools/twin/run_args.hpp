// The options `twin run` and `twin step` share: one definition, so that both take the same names with the same
// meaning (`twin step` takes every option of `twin run` but those that stepping has no use for: --realtime, since
// stepping is lock-step; --quiet, since stepping prints the state after each step, not a progress line; --dry, a
// bring-up of real drivers that runs no program).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"
#if CW_SIM
#include "cellwright/cell/sim/run.hpp"
#endif

namespace cellwright::tools {

struct RunArgs {
  std::string scenario;
  std::string output;  // -o/--output DIR
  std::string perception;
  std::string frames;  // --save-frames DIR
  std::vector<std::string> drivers;
  std::vector<std::string> faults;
  std::optional<std::uint64_t> seed;
  std::string video;  // --video FILE.mp4
  int video_fps = 20;
  std::string video_size = "800x600";
  bool allow_collisions = false;  // run although the preflight sweep predicts collisions
  bool force = false;             // --force: write into an -o directory that is not Cellwright's
  std::vector<std::string> cameras;  // --camera NAME=SOURCE: vision's frames from a real camera or a recording
  std::string record_camera;         // --record-camera DIR: the camera's frames as lossless PNG files
  std::vector<std::string> devices;  // --device NAME=modbus:HOST:PORT[/UNIT]: a device on real I/O
};

// Adds the shared options to `cmd`, stored in `args` (which must outlive the parse): the scenario, -o/--output
// (--out, the old name, still accepted and not shown), --force, --perception, --driver, --fault, --seed, --save-frames,
// --video, --video-fps, --video-size, --allow-collisions, --camera, --record-camera, --device.
void add_run_options(CLI::App& cmd, RunArgs& args);

// The scenario with --driver, --device (set_devices), --fault and --seed applied, after checking that the -o and
// --save-frames directories can be written (check_writable_dir; for -o also that it is Cellwright's or holds none of the run's files, unless
// --force: cell::check_output_directory), before anything is loaded or run, so that a bad one costs no run.
// InputError (as check_output_directory, check_writable_dir, load_scenario, set_driver, set_devices, parse_fault_text) on bad
// input.
cell::Scenario load_scenario_with(const RunArgs& args);

// Refuses --speed above 1 (simulation seconds per wall-clock second) when a program robot of `s` is on a real driver
// whose port is not a pseudo-terminal (cell::setup_of: not emulated, so a real arm, which moves at its own pace):
// InputError naming --speed, the robot and its port. Checked before anything connects.
void check_speed_for_real_arms(const cell::Scenario& s, double speed);

#if CW_SIM
// The run's options from the shared options, for scenario `s`: perception, the frames callback (its directory
// made), the video (checked: InputError naming the option), and the event log streamed into the output directory
// when there is one. Throws InputError when --save-frames is given and the cell has no camera.
cell::RunOptions run_options_for(const RunArgs& args, const cell::Scenario& s);

// The video's options from --video, --video-fps and --video-size, the size and rate checked (InputError naming
// the option); the file is checked when the video opens.
twin::VideoOptions video_options_for(const RunArgs& args);

#endif  // CW_SIM

// `--video` as a flag, for the commands that record the runs that failed after the fact (`twin campaign`, `twin
// test`): the flag and the rate and size of the videos.
struct VideoFlag {
  bool on = false;
  int fps = 20;
  std::string size = "800x600";
};

// Adds --video (a flag, described by `help`), --video-fps and --video-size to `cmd`, stored in `video` (which must
// outlive the parse).
void add_video_flag(CLI::App& cmd, VideoFlag& video, const std::string& help);

#if CW_SIM
// With --video given: the size and rate checked (as video_options_for) and ffmpeg found (VideoWriter::check_encoder),
// before anything runs. InputError naming the option otherwise; nothing without --video.
void check_video_flag(const VideoFlag& video);

// Runs the scenario of `args` (with its faults and seed) lock-step, quietly, with its video (args.video must be set)
// and, with args.output, the outputs of `twin run -o` (final.png included, the page showing the video): `twin
// campaign --video` re-runs a failed run this way into its directory, whose child wrote no final.png, which gives the
// run it had (the same events, lock-step). Returns the report. InputError as `twin run`, or when preflight refuses the scenario.
cell::Report run_for_video(const RunArgs& args);
#endif  // CW_SIM

}  // namespace cellwright::tools
