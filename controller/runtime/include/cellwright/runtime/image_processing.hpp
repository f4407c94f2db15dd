// ImageProcessing: the paper's image-processing thread (Fig. 2; issue 5). Every vision period the simulation thread,
// which owns the physics and the rendering context, captures a camera frame and hands it over through a message
// queue; this thread finds the workpieces in it (a PartDetector: the cell's is twin/vision), corrects the environment
// model with what it saw (correct(), under the model's lock), logs a "vision" event and wakes whoever waits for the
// model to change.
//
// What the model learns from a frame:
//  - each confidently seen part that no robot holds: its pose (centre, yaw), the confidence, the frame's age, and its
//    velocity from the frame before: the displacement over the time between them, or zero when it moved less than
//    VisionOptions::rest_deadband (the detector's noise); unknown when the part was not seen in the frame before
//    (then the model does not let a robot grasp it yet: a part first seen may be riding a belt);
//  - a part not seen (hidden by an arm, out of view, held): nothing; the model keeps its last estimate, whose stamp
//    tells its age;
//  - a confirmed part (present, motion known) seen with a robot's tool above it, within
//    VisionOptions::occlusion_radius horizontally: nothing either
//    (logged as not seen): an arm over a part hides some of it, and a partly hidden part can still fit its shape well
//    enough to pass the detector, a few millimetres off, which would read as motion.
// A frame that could not be made (Frame::problem) or used (wrong size) is logged with its problem and changes nothing.
//
// Threads: constructed by the Runtime on the main thread; step() and process() on the image-processing thread only.
// The detector is shared read-only; the model is written under its lock; the on_frame callback runs on this thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/part_detector.hpp"
#include "cellwright/runtime/recovery.hpp"

namespace cellwright::runtime {

// A camera frame as the simulation thread captured it.
struct Frame {
  SimDuration time{0};  // simulation time it shows
  Image image;          // empty when the capture failed
  std::string problem;  // why the capture failed, "" if it did not
};

// A processed frame, for whoever wants to see it (e.g. `twin run --save-frames`).
struct VisionFrame {
  SimDuration time{0};
  Image image;
  Sightings result;
  std::vector<Prediction> predictions;  // where the environment model had each free part before this frame's correction
};

struct VisionOptions {
  std::string camera;                                   // the cell camera to look through
  SimDuration period = std::chrono::milliseconds(400);  // simulation time between frames (the paper's 400 ms)
  double rest_deadband = 0.003;   // m: a part that moved less than this between two frames is at rest
  double occlusion_radius = 0.3;  // m: a tool above a part and this close (horizontally) may hide it (its arm)
};

class ImageProcessing {
 public:
  // `detector` and the rest must outlive this object. `on_frame` may be empty.
  // `recovery` gives the decision tree for a frame that did not come (frame_lost, docs/faults.md).
  ImageProcessing(const PartDetector& detector, SharedEnvironment& env, MessageQueue<Frame>& frames, EventLog& log,
                  VisionOptions options, std::function<void(const VisionFrame&)> on_frame = {},
                  RecoveryOptions recovery = {});

  // Processes every frame waiting in the queue, without blocking, at simulation time `now`. Returns how many.
  std::size_t step(SimDuration now);

  // Processes one frame at simulation time `now` (>= frame.time).
  void process(const Frame& frame, SimDuration now);

  std::uint64_t frames_processed() const { return processed_; }
  const VisionOptions& options() const { return options_; }

 private:
  struct LastSeen {
    Eigen::Vector3d position;
    SimDuration time;
  };
  const PartDetector& detector_;
  SharedEnvironment& env_;
  MessageQueue<Frame>& frames_;
  EventLog& log_;
  VisionOptions options_;
  std::function<void(const VisionFrame&)> on_frame_;
  std::map<std::string, LastSeen> last_seen_;
  std::uint64_t processed_ = 0;
  RecoveryOptions recovery_;
  std::optional<SimDuration> frame_lost_since_;  // frames have not come since then
  Diagnosis frame_lost_diagnosis_;
};

}  // namespace cellwright::runtime
