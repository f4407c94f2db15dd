#include "cellwright/twin/sim/carry_meter.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace cellwright::twin::sim {

namespace {

double degrees(double radians) {
  return radians * 180.0 / std::numbers::pi;
}

}  // namespace

std::vector<runtime::events::Carry> CarryMeter::measure(runtime::SimDuration t, const std::vector<CarryHand>& hands,
                                                        const std::vector<CarryPart>& parts) {
  std::vector<runtime::events::Carry> out;
  std::map<std::string, Hold> still;
  for (const CarryPart& part : parts) {
    std::vector<const CarryHand*> on;
    for (const CarryHand& h : hands) {
      if (h.held == part.name) on.push_back(&h);
    }
    if (on.size() < 2) continue;
    const CarryHand& a = *on[0];
    const CarryHand& b = *on[1];
    const Eigen::Isometry3d relative = a.tcp.inverse() * b.tcp;
    Hold hold;
    const auto it = holds_.find(part.name);
    if (it != holds_.end() && it->second.a == a.robot && it->second.b == b.robot) {
      hold = it->second;
    } else {
      hold = {a.robot, b.robot, relative};  // the hold begins: its grasp transform
    }
    still[part.name] = hold;
    runtime::events::Carry c;
    c.t = t;
    c.workpiece = part.name;
    c.a = a.robot;
    c.b = b.robot;
    const Eigen::Vector3d between = b.tcp.translation() - a.tcp.translation();
    if (between.norm() > 1e-9) c.squeeze = (a.wrist_force - b.wrist_force).dot(between.normalized()) / 2.0;
    const Eigen::Isometry3d off = hold.grasp.inverse() * relative;
    c.error = off.translation().norm() * 1000.0;
    c.turn = degrees(Eigen::AngleAxisd(off.linear()).angle());
    Eigen::Index k = 0;
    part.size.maxCoeff(&k);
    const double up = std::clamp(std::abs(part.pose.linear().col(k).z()), 0.0, 1.0);
    c.tilt = degrees(std::asin(up));
    out.push_back(std::move(c));
  }
  holds_ = std::move(still);
  return out;
}

}  // namespace cellwright::twin::sim
