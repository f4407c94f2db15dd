#include "cellwright/runtime/grip_sensor.hpp"

#include <limits>

namespace cellwright::runtime {

std::string part_between_fingers(bool left_touch, bool right_touch, const Eigen::Vector3d& tcp,
                                 const std::vector<PartBox>& parts, double margin) {
  if (!left_touch || !right_touch) return {};
  std::string held;
  double best = std::numeric_limits<double>::infinity();
  for (const PartBox& p : parts) {
    const Eigen::Vector3d local = p.pose.inverse() * tcp;
    const double d = (tcp - p.pose.translation()).norm();
    if ((local.cwiseAbs() - p.size / 2).maxCoeff() <= margin && d < best) {
      best = d;
      held = p.name;
    }
  }
  return held;
}

}  // namespace cellwright::runtime
