// Where a part leaves the cell on an exit conveyor in a shift (a feed of more parts than bodies, scenario Feed::count):
// the rule by which the WorldPlant takes delivered parts out and feeds their bodies again (world_plant.hpp,
// recycle_at), and by which the cycle-time estimate times a body's ride out (cell/plan/estimate.hpp).
//
// A point is over the belt's line when it lies within half the belt's width + 5 cm of its centre line across it
// (horizontally), above the belt's base (the floor), and between the belt's upstream end and 0.5 m past its downstream
// end (a part falling off the end). A part has left the cell when its centre is over the belt's line at least
// out_at() along the belt from its upstream end: the belt's `leave` point, or, with a stop bar, 5 cm before it (parts
// collect against the bar, their centres half a part upstream of it).
//
// The belt's frame is worked out once, when the BeltExit is made. Pure; any thread.
#pragma once

#include <Eigen/Geometry>

#include <optional>

#include "cellwright/models/cell.hpp"

namespace cellwright::twin::sim {

class BeltExit {
 public:
  // The conveyor must outlive the BeltExit.
  explicit BeltExit(const models::ConveyorSpec& conveyor);

  const models::ConveyorSpec& conveyor() const { return *conveyor_; }
  // m along the belt from its upstream end where a part's centre has left the cell.
  double out_at() const;
  // The distance along the belt from its upstream end of a point (world) over the belt's line; nullopt when the point
  // is not over it.
  std::optional<double> along(const Eigen::Vector3d& point) const;
  // Whether a part whose centre is at `point` (world) has left the cell.
  bool left(const Eigen::Vector3d& point) const;

 private:
  const models::ConveyorSpec* conveyor_;
  Eigen::Vector3d start_;  // the belt's top at its upstream end, on its centre line (world)
  Eigen::Vector3d dir_;    // unit direction of travel (world)
};

}  // namespace cellwright::twin::sim
