#include "cellwright/twin/sim/belt_exit.hpp"

namespace cellwright::twin::sim {

namespace {
constexpr double kAcrossMargin = 0.05;  // m beyond the belt's half width that still counts as over it
constexpr double kPastEnd = 0.5;        // m past the downstream end (a part falling off it)
constexpr double kBeforeStop = 0.05;    // m before a stop bar where a part has left the cell
}  // namespace

BeltExit::BeltExit(const models::ConveyorSpec& conveyor)
    : conveyor_(&conveyor),
      start_(conveyor.belt_point(0)),
      dir_((conveyor.belt_point(1) - conveyor.belt_point(0)).normalized()) {}

double BeltExit::out_at() const {
  return conveyor_->leave - (conveyor_->stop ? kBeforeStop : 0.0);
}

std::optional<double> BeltExit::along(const Eigen::Vector3d& point) const {
  const Eigen::Vector3d rel = point - start_;
  const double s = rel.dot(dir_);
  const double across = (rel - s * dir_).head<2>().norm();
  const bool over = across <= conveyor_->width / 2 + kAcrossMargin && rel.z() > -conveyor_->height && s >= 0 &&
                    s <= conveyor_->length + kPastEnd;
  if (!over) return std::nullopt;
  return s;
}

bool BeltExit::left(const Eigen::Vector3d& point) const {
  const std::optional<double> s = along(point);
  return s && *s >= out_at();
}

}  // namespace cellwright::twin::sim
