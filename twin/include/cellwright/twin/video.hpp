// Video of a run (`twin run --video FILE.mp4`): the overview camera rendered offscreen at fixed simulation times,
// the simulated time and each robot's command drawn on every frame and the verdict on the last ones, encoded as
// H.264 (yuv420p) in an MP4 whose index comes first (+faststart), so that a browser plays it, also while it loads.
//
//  - VideoWriter encodes images into the file by piping them, raw, into the `ffmpeg` program (libx264, yuv420p,
//    MP4). A program rather than FFmpeg's libraries: linked into the twin, libavcodec and its ~190 shared libraries
//    cost every run, with a video or not, 56 MB of memory and 0.8 s at start (docs/scenarios.md); the program
//    costs only the runs that record, and its memory and its crashes are its own. It knows nothing of MuJoCo.
//  - VideoRecorder is what a run uses: the simulation thread hands it the state of the world at each frame time (a
//    copy of the joint and mocap positions, cheap: the physics and the event log stay untouched); its own thread
//    sets a private mjData to that state, renders it with its own Renderer (OSMesa: the context belongs to that
//    thread), draws the text and encodes.
//
// Errors: a file that cannot be written (no such directory, not a .mp4 name, no permission) is refused when the
// writer opens, before the run starts, as InputError naming the file. An error while recording (the disk full, a
// render failing) stops the recording, never the run; finish() reports it as InputError naming the file.
#pragma once

#include <mujoco/mujoco.h>

#include <opencv2/core.hpp>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/clock.hpp"

namespace cellwright::twin {

namespace sim {
struct DeviceStates;
}

class VideoWriter {
 public:
  VideoWriter();
  ~VideoWriter();  // finishes an open file as close() does, errors ignored
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  // Creates (or replaces) `path` for width x height images at `fps` frames per second. Throws InputError naming the
  // path when the name does not end in .mp4, its directory does not exist or the file cannot be written, when
  // width or height is not even and within 2..4096 (yuv420p halves both), fps is not within 1..120, or the ffmpeg
  // program cannot be started. Any file open before is closed first.
  void open(const std::filesystem::path& path, int width, int height, int fps);

  // The checks of open() on the size and rate alone: InputError at `where` when width or height is not even and
  // within 2..4096 or fps not within 1..120 (`twin campaign --video` checks them before its runs).
  static void check_format(const SourceLocation& where, int width, int height, int fps);
  // Whether the ffmpeg program is there to be started: InputError at `where` when no executable ffmpeg is on $PATH
  // (`twin campaign --video` checks it before its runs, not when the first failed run is recorded).
  static void check_encoder(const SourceLocation& where);

  bool is_open() const;
  // Appends one frame (CV_8UC3, BGR, the size given to open), shown 1/fps s after the previous one. Throws
  // InputError naming the file if encoding or writing fails; InternalError if not open or the image does not fit.
  void add(const cv::Mat& image);
  // Frames added since open().
  std::int64_t frames() const { return frames_; }
  // Ends ffmpeg's input and waits for it to flush the encoder and write the index (moved to the front of the file).
  // Throws InputError naming the file, with ffmpeg's message, if it failed. Nothing when not open.
  void close();

 private:
  void release();

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::filesystem::path path_;
  std::int64_t frames_ = 0;
};

struct VideoOptions {
  std::filesystem::path path;  // an .mp4 file
  int fps = 20;                // frames per second of simulated time (and of the video)
  int width = 800, height = 600;
  double hold = 2.0;  // s: the final state, with the verdict, held this long at the end
};

// The lines drawn on a frame: the first is the time, the rest one per robot; the verdict goes at the bottom.
struct Overlay {
  std::vector<std::string> lines;
  std::string verdict;      // empty: none (every frame but the last ones)
  bool verdict_ok = false;  // green when true, red when not
};

// The devices' lines of a frame's overlay (drawn under the robots' lines), one per device of the twin as its I/O image
// has them (sim::World::devices()): a machine "mill: busy A (2.4 s left)", "mill: done A (to unload)", "mill: loaded
// A", "mill: idle"; a conveyor "input: running", "input: stopped", or "input: held (accumulating)" when its run
// command is on but a part at the stop holds it, with ", stop eye on" / ", drop eye on" while a photo-eye sees a part.
// Machines first, in the cell's order, then conveyors.
std::vector<std::string> device_lines(const sim::DeviceStates& devices);

// Draws the overlay on `image` (CV_8UC3): the lines on a darkened band at the top left, the verdict on a band across
// the bottom. Used by VideoRecorder; public so that its tests can compare.
void draw_overlay(cv::Mat& image, const Overlay& overlay);

class VideoRecorder {
 public:
  // Opens the file (VideoWriter::open's errors, before anything runs) and starts the recording thread. `model` must
  // outlive the recorder.
  VideoRecorder(const mjModel* model, VideoOptions options);
  // Stops the thread; the file is finished as far as it got (finish() was not called: no verdict).
  ~VideoRecorder();
  VideoRecorder(const VideoRecorder&) = delete;
  VideoRecorder& operator=(const VideoRecorder&) = delete;

  const VideoOptions& options() const { return options_; }
  // The simulation time between two frames.
  runtime::SimDuration frame_period() const;

  // A frame of `data`'s state now (joint positions, mocap bodies) at simulation time t, with one line of text per
  // robot (and, after them, any other lines: the devices', device_lines()). Called by the thread that steps `data` (the simulation thread), with nothing stepping it meanwhile. Waits
  // while the recording thread is a few frames behind (lock-step: the run waits for the video; never drops a frame).
  // Does nothing after an error or finish().
  void record(const mjData* data, runtime::SimDuration t, std::vector<std::string> robot_lines);

  // After the run: the final state of `data` at time t, with the robots' last lines and the verdict, held for
  // options().hold; then closes the file. Throws InputError naming the file if anything failed while recording.
  void finish(const mjData* data, runtime::SimDuration t, const std::string& verdict, bool ok);

  // Frames encoded so far (all of them after finish()).
  std::int64_t frames() const;

 private:
  struct Frame {
    runtime::SimDuration time{0};
    std::vector<mjtNum> qpos, mocap_pos, mocap_quat, userdata;  // userdata: colours the run changed (scene.hpp)
    Overlay overlay;
    int repeat = 1;     // the hold at the end: the same picture this many times
    bool last = false;  // the thread ends after it
  };
  Frame capture(const mjData* data, runtime::SimDuration t) const;
  void push(Frame frame);
  void loop();

  const mjModel* model_;
  VideoOptions options_;
  VideoWriter writer_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Frame> queue_;  // under mutex_
  bool stop_ = false;        // under mutex_: no more frames (finish() or an error)
  std::exception_ptr error_;  // under mutex_
  std::vector<std::string> last_lines_;  // robot lines of the last record(), simulation thread / finish()
  std::int64_t encoded_ = 0;             // under mutex_
  std::thread thread_;
};

}  // namespace cellwright::twin
