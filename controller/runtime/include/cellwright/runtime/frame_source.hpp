// FrameSource: where the image-processing thread's frames come from when they do not come from the plant (issue 26):
// a real camera, or a recording of one. The runtime knows only this interface, so it needs no image library; the
// cell's cameras (vision/camera_source.hpp, on OpenCV's VideoCapture) implement it, and tests supply doubles.
//
// Without a source (RunConfig::camera unset) the simulation thread renders the plant's camera (Plant::capture), as
// before. With one, it asks the source instead, every vision period, at the same moment in the period: the source
// gives the picture that belongs to simulation time `t` (a recording: its frame of that time, so that a lock-step run
// is repeatable; a live camera: its newest picture), or nothing, with the reason. Nothing is the frame-lost symptom
// (docs/faults.md): image processing senses it and diagnoses it as it does a lost frame of the twin's camera.
// A source never blocks for long: a camera that stops delivering (a file at its end, a device gone) answers nothing.
//
// Threads: capture() and release_thread_resources() are called by the simulation thread only, one call at a time.
#pragma once

#include <optional>
#include <string>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/plant.hpp"

namespace cellwright::runtime {

class FrameSource {
 public:
  virtual ~FrameSource() = default;

  // The picture for simulation time `t` (never earlier than the previous call's), 8-bit BGR at the size the detector
  // expects; nullopt when there is none, with the reason in *why (when why is not null). Never throws for what the
  // camera does.
  virtual std::optional<Image> capture(SimDuration t, std::string* why) = 0;

  // Called by the simulation thread as it stops (see Plant::release_thread_resources).
  virtual void release_thread_resources() {}
};

}  // namespace cellwright::runtime
