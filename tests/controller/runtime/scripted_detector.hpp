// ScriptedDetector: a PartDetector test double for the image-processing thread. Each call of detect() reports what the
// test scripted for that frame, in the order scripted (a frame with nothing scripted shows nothing: every workpiece
// not seen), and the double remembers every image and prediction list it was given, so that a test can check what the
// thread asked of it. It never looks at the pixels: a test tells its frames apart by their contents if it wants to.
//
// Threads: like any PartDetector, detect() on one thread at a time; the test reads what was recorded on that thread
// (or after it stopped).
#pragma once

#include <algorithm>
#include <cstddef>
#include <deque>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/runtime/part_detector.hpp"

namespace cellwright::testing {

class ScriptedDetector final : public runtime::PartDetector {
 public:
  // What one call of detect() was given.
  struct Call {
    runtime::Image image;
    std::vector<runtime::Prediction> predictions;
  };

  // Looks for `workpieces` (cell names, in the cell's order).
  explicit ScriptedDetector(std::vector<std::string> workpieces) : workpieces_(std::move(workpieces)) {}

  // The next frame not yet scripted shows `seen` (reported in the cell's order, whatever the order given) and every
  // other workpiece not seen, with `rejected` blobs not trusted.
  ScriptedDetector& then_sees(std::vector<runtime::Sighting> seen, std::size_t rejected = 0) {
    runtime::Sightings s;
    s.rejected = rejected;
    for (const std::string& w : workpieces_) {
      const auto it =
          std::find_if(seen.begin(), seen.end(), [&](const runtime::Sighting& d) { return d.workpiece == w; });
      if (it == seen.end()) {
        s.not_seen.push_back(w);
      } else {
        s.seen.push_back(*it);
      }
    }
    for (const runtime::Sighting& d : seen) {  // names the cell does not have, last
      if (std::find(workpieces_.begin(), workpieces_.end(), d.workpiece) == workpieces_.end()) s.seen.push_back(d);
    }
    script_.push_back(std::move(s));
    return *this;
  }

  // The next frame not yet scripted cannot be used (as a picture of the wrong size): `problem`, every workpiece not
  // seen.
  ScriptedDetector& then_fails(std::string problem) {
    runtime::Sightings s;
    s.frame_problem = std::move(problem);
    s.not_seen = workpieces_;
    script_.push_back(std::move(s));
    return *this;
  }

  // How many times detect() was called.
  std::size_t calls() const { return given_.size(); }
  // What each call was given, in order.
  const std::vector<Call>& given() const { return given_; }
  // What the last call was given; throws std::logic_error if there was none.
  const Call& last_call() const {
    if (given_.empty()) throw std::logic_error("ScriptedDetector: detect() has not been called");
    return given_.back();
  }
  // Frames scripted and not shown yet.
  std::size_t scripted() const { return script_.size(); }

  std::vector<std::string> workpieces() const override { return workpieces_; }

  // Records the call and reports the next scripted frame. Its `detail` is the call's index (0 for the first), so that
  // a test can tell which result reached whoever draws it.
  runtime::Sightings detect(const runtime::Image& image,
                            const std::vector<runtime::Prediction>& predictions) const override {
    given_.push_back({image, predictions});
    runtime::Sightings s;
    if (script_.empty()) {
      s.not_seen = workpieces_;
    } else {
      s = std::move(script_.front());
      script_.pop_front();
    }
    s.detail = given_.size() - 1;
    return s;
  }

 private:
  std::vector<std::string> workpieces_;
  // detect() is const (the interface's): what it consumes and records is the double's own bookkeeping.
  mutable std::deque<runtime::Sightings> script_;
  mutable std::vector<Call> given_;
};

}  // namespace cellwright::testing
