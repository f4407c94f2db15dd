// Smooth joint trajectories for the simulated robots, and the motion durations they imply.
//
// Every simulated motion follows a quintic time scaling s(t) = 10 u^3 - 15 u^4 + 6 u^5 (u = t / T): position,
// velocity and acceleration are continuous and start and end at rest, so the servos are never asked to jump (facts.md:
// a step change of a stiff servo's target throws the part out of the fingers). Its peak speed is 15/8 of the mean
// speed and its peak acceleration 10/sqrt(3) times distance / T^2.
//
// A path is a polyline in joint space: two points for a joint-interpolated move, many for a straight line of the
// tool (waypoints solved by inverse kinematics, a few millimetres apart). The time scaling runs along the polyline's
// normalised arc parameter; the duration makes the fastest joint reach, at the profile's peak, its speed limit.
//
// The functions here are pure and may be called from any thread: the SimDriver uses them on the simulation thread,
// the cycle-time estimate uses them before a run starts.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace cellwright::twin::sim {

// Peak speed of the quintic scaling relative to the mean speed (distance / duration).
inline constexpr double kQuinticPeakSpeed = 15.0 / 8.0;

// The quintic scaling: s(u) in [0, 1] for u in [0, 1] (clamped outside), and its first derivative ds/du.
double quintic(double u);
double quintic_rate(double u);

// Duration of a motion along `path` (at least two points, all of the same size): the shortest T such that no joint
// exceeds max_speed[j] * speed at the profile's peak, and at least min_time. max_speed has one entry per joint, all
// > 0; speed in (0, 1]. Throws InternalError on inconsistent sizes or non-positive limits (callers validate input).
double path_duration(const std::vector<Eigen::VectorXd>& path, const Eigen::VectorXd& max_speed, double speed,
                     double min_time);

// A joint-space polyline traversed in time `duration` with the quintic scaling along its arc parameter. The arc
// parameter is the normalised sum of the segments' largest joint steps, so a two-point path is exactly a quintic
// joint move and a fine polyline follows its waypoints at a speed that varies smoothly.
class JointPath {
 public:
  // path: at least two points of equal size; duration > 0. Throws InternalError otherwise.
  JointPath(std::vector<Eigen::VectorXd> path, double duration);

  double duration() const { return duration_; }
  const Eigen::VectorXd& start() const { return points_.front(); }
  const Eigen::VectorXd& end() const { return points_.back(); }

  // Position and velocity at time t seconds since the start (held at the ends outside [0, duration]).
  Eigen::VectorXd position(double t) const;
  Eigen::VectorXd velocity(double t) const;

 private:
  // The segment index and the fraction along it for arc parameter a in [0, 1].
  void locate(double a, std::size_t& segment, double& fraction) const;

  std::vector<Eigen::VectorXd> points_;
  std::vector<double> arc_;  // cumulative arc parameter at each point, arc_.front() = 0, arc_.back() = 1
  double duration_;
};

}  // namespace cellwright::twin::sim
