#include "cellwright/runtime/image_processing.hpp"

#include <algorithm>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

ImageProcessing::ImageProcessing(const PartDetector& detector, SharedEnvironment& env, MessageQueue<Frame>& frames,
                                 EventLog& log, VisionOptions options, std::function<void(const VisionFrame&)> on_frame,
                                 RecoveryOptions recovery)
    : detector_(detector),
      env_(env),
      frames_(frames),
      log_(log),
      options_(std::move(options)),
      on_frame_(std::move(on_frame)),
      recovery_(std::move(recovery)) {
  CW_CHECK(options_.period.count() > 0, "the vision period must be positive, got {} ns", options_.period.count());
}

std::size_t ImageProcessing::step(SimDuration now) {
  std::size_t n = 0;
  Frame f;
  while (frames_.try_pop(f) == QueueStatus::ok) {
    process(f, now);
    ++n;
  }
  return n;
}

void ImageProcessing::process(const Frame& frame, SimDuration now) {
  CW_CHECK(now >= frame.time, "a frame of {} ns processed at {} ns", frame.time.count(), now.count());
  // Predictions tell same-coloured parts apart: where the model has each free part now.
  const std::vector<Prediction> predictions = env_.read([](const EnvironmentModel& m) {
    std::vector<Prediction> p;
    for (const WorkpieceState& w : m.workpieces) {
      if (w.present && w.held_by.empty()) p.push_back({w.name, w.pose.translation()});
    }
    return p;
  });
  Sightings result;
  if (frame.problem.empty()) {
    result = detector_.detect(frame.image, predictions);
  } else {
    result.frame_problem = frame.problem;
    result.not_seen = detector_.workpieces();
  }

  std::vector<EventLog::Seen> seen;
  std::vector<std::string> not_seen = result.not_seen;
  env_.write([&](EnvironmentModel& m) {
    // correct() stamps the estimate model.time - age: the frame's own time, whatever the model's clock says now.
    const SimDuration age = m.time - frame.time;
    for (const Sighting& d : result.seen) {
      const Eigen::Vector3d position = d.pose.translation();
      // Only a confirmed estimate is worth keeping: a part not yet confirmed takes what the camera sees (else a part
      // first seen with a tool near it would never be confirmed while the tool waits there).
      const WorkpieceState* known = m.find_workpiece(d.workpiece);
      const bool confirmed = known != nullptr && known->present && known->motion_known;
      const bool under_a_tool =
          confirmed && std::any_of(m.robots.begin(), m.robots.end(), [&](const RobotState& r) {
            if (!r.tcp) return false;
            const Eigen::Vector3d t = r.tcp->translation();
            return t.z() > position.z() && (t - position).head<2>().norm() < options_.occlusion_radius;
          });
      if (under_a_tool) {
        not_seen.push_back(d.workpiece);
        continue;
      }
      std::optional<Eigen::Vector3d> velocity;
      const auto last = last_seen_.find(d.workpiece);
      // The frame before this one (a missed frame in between still counts): the displacement since.
      if (last != last_seen_.end() && frame.time - last->second.time <= options_.period * 5 / 2 &&
          frame.time > last->second.time) {
        const Eigen::Vector3d moved = position - last->second.position;
        const double dt = std::chrono::duration<double>(frame.time - last->second.time).count();
        velocity = moved.norm() < options_.rest_deadband ? Eigen::Vector3d::Zero() : Eigen::Vector3d(moved / dt);
      }
      last_seen_[d.workpiece] = {position, frame.time};
      if (age.count() >= 0 && correct(m, d.workpiece, d.pose, d.confidence, age, velocity)) {
        seen.push_back({d.workpiece, position, d.yaw, d.confidence});
      }
    }
  });
  log_.vision(now, frame.time, seen, not_seen, result.rejected, result.frame_problem);
  // A frame that did not come is a symptom (docs/faults.md): the model keeps its last estimates, which age, until a
  // frame comes again; that ends the recovery.
  if (!recovery_.enabled) {
    // No recovery: the vision event's problem is the whole story.
  } else if (!frame.problem.empty() && !frame_lost_since_) {
    frame_lost_since_ = now;
    log_.fault_detected(now, "", -1, to_string(Symptom::frame_lost), frame.problem);
    const DecisionTree& tree = recovery_.tree ? *recovery_.tree : DecisionTree::standard();
    frame_lost_diagnosis_ = tree.diagnose(Symptom::frame_lost, [](Question) { return false; });
    log_.diagnosis(now, "", "frame_lost", frame_lost_diagnosis_.cause, to_string(frame_lost_diagnosis_.action),
                   frame_lost_diagnosis_.path);
  } else if (frame.problem.empty() && frame_lost_since_) {
    log_.recovery_end(now, "", frame_lost_diagnosis_.cause, to_string(frame_lost_diagnosis_.action), true,
                      "a frame came again", now - *frame_lost_since_);
    frame_lost_since_.reset();
  }
  ++processed_;
  if (on_frame_) on_frame_(VisionFrame{frame.time, frame.image, std::move(result), predictions});
}

}  // namespace cellwright::runtime
