#include "cellwright/twin/runtime/image_processing.hpp"

#include <algorithm>
#include <utility>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::runtime {

ImageProcessing::ImageProcessing(const vision::Detector& detector, SharedEnvironment& env, MessageQueue<Frame>& frames,
                                 EventLog& log, VisionOptions options, std::function<void(const VisionFrame&)> on_frame)
    : detector_(detector),
      env_(env),
      frames_(frames),
      log_(log),
      options_(std::move(options)),
      on_frame_(std::move(on_frame)) {
  CW_CHECK(options_.period.count() > 0, "the vision period must be positive, got {} ns", options_.period.count());
  // The image-processing thread is the parallelism: OpenCV's own worker pool (TBB) is turned off, process-wide, so
  // that a frame costs the same whatever else runs on the shared cores, and no threads the runtime does not know of
  // (and ThreadSanitizer cannot follow) touch its frames.
  cv::setNumThreads(0);
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
  const std::vector<vision::Prediction> predictions = env_.read([](const EnvironmentModel& m) {
    std::vector<vision::Prediction> p;
    for (const WorkpieceState& w : m.workpieces) {
      if (w.present && w.held_by.empty()) p.push_back({w.name, w.pose.translation()});
    }
    return p;
  });
  vision::DetectionResult result;
  if (frame.problem.empty()) {
    result = vision::detect(detector_, frame.image, predictions);
  } else {
    result.frame_problem = frame.problem;
    for (const WorkpieceSpec& w : detector_.workpieces()) result.not_seen.push_back(w.name);
  }

  std::vector<EventLog::Seen> seen;
  std::vector<std::string> not_seen = result.not_seen;
  env_.write([&](EnvironmentModel& m) {
    // correct() stamps the estimate model.time - age: the frame's own time, whatever the model's clock says now.
    const SimDuration age = m.time - frame.time;
    for (const vision::Detection& d : result.detections) {
      // Only a confirmed estimate is worth keeping: a part not yet confirmed takes what the camera sees (else a part
      // first seen with a tool near it would never be confirmed while the tool waits there).
      const WorkpieceState* known = m.find_workpiece(d.workpiece);
      const bool confirmed = known != nullptr && known->present && known->motion_known;
      const bool under_a_tool =
          confirmed && std::any_of(m.robots.begin(), m.robots.end(), [&](const RobotState& r) {
            if (!r.tcp) return false;
            const Eigen::Vector3d t = r.tcp->translation();
            return t.z() > d.position.z() && (t - d.position).head<2>().norm() < options_.occlusion_radius;
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
        const Eigen::Vector3d moved = d.position - last->second.position;
        const double dt = std::chrono::duration<double>(frame.time - last->second.time).count();
        velocity = moved.norm() < options_.rest_deadband ? Eigen::Vector3d::Zero() : Eigen::Vector3d(moved / dt);
      }
      last_seen_[d.workpiece] = {d.position, frame.time};
      if (age.count() >= 0 && correct(m, d.workpiece, d.pose(), d.confidence, age, velocity)) {
        seen.push_back({d.workpiece, d.position, d.yaw, d.confidence});
      }
    }
  });
  log_.vision(now, frame.time, seen, not_seen, result.rejected.size(), result.frame_problem);
  ++processed_;
  if (on_frame_) on_frame_(VisionFrame{frame.time, frame.image, std::move(result)});
}

}  // namespace cellwright::twin::runtime
