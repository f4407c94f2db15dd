// Smooth joint trajectories for the simulated robots, and the motion durations they imply.
//
// Every simulated motion follows a quintic time scaling s(t) = 10 u^3 - 15 u^4 + 6 u^5 (u = t / T): position,
// velocity and acceleration are continuous and start and end at rest, so the servos are never asked to jump (facts.md:
// a step change of a stiff servo's target throws the part out of the fingers). Its peak speed is 15/8 of the mean
// speed and its peak acceleration 10/sqrt(3) times distance / T^2.
//
// A path is a polyline in joint space: two points for a joint-interpolated move, many for a straight line of the
// tool (waypoints solved by inverse kinematics, a few millimetres apart). The time scaling runs along the polyline's
// normalised arc parameter; the duration makes the joint that needs it most reach its speed limit at the profile's
// peak.
//
// The functions here are pure and may be called from any thread: the SimDriver uses them on the simulation thread,
// the cycle-time estimate uses them before a run starts.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace cellwright::twin::sim {

// Peak speed of the quintic scaling relative to the mean speed (distance / duration).
inline constexpr double kQuinticPeakSpeed = 15.0 / 8.0;

// The quintic scaling s(u) in [0, 1] for u in [0, 1] (held at the ends outside), and its derivatives ds/du, d2s/du2.
double quintic(double u);
double quintic_rate(double u);
double quintic_accel(double u);

// One point of a trajectory: joint positions, velocities and accelerations.
struct JointSample {
  Eigen::VectorXd position, velocity, acceleration;
};

// A joint-space polyline, to be traversed with the quintic scaling along its arc parameter a in [0, 1].
class JointPath {
 public:
  // `points`: at least two, all of the same non-zero size. `arc`: the cumulative arc parameter at each point,
  // from 0 rising to 1 (e.g. the distance travelled by the tool along a straight line, normalised); empty: the
  // normalised sum of the segments' largest joint steps, so that a two-point path is exactly a quintic joint move.
  // A path that does not move at all gets a uniform arc. Throws InternalError on inconsistent input.
  explicit JointPath(std::vector<Eigen::VectorXd> points, std::vector<double> arc = {});

  const Eigen::VectorXd& start() const { return points_.front(); }
  const Eigen::VectorXd& end() const { return points_.back(); }
  const std::vector<Eigen::VectorXd>& points() const { return points_; }
  std::size_t joints() const { return static_cast<std::size_t>(points_.front().size()); }

  // The shortest duration (seconds) in which no joint j exceeds max_speed[j] * speed at the profile's peak, and at
  // least min_time. max_speed: one value > 0 per joint; speed in (0, 1]; min_time >= 0 (InternalError otherwise).
  double min_duration(const Eigen::VectorXd& max_speed, double speed, double min_time) const;

  // Position, velocity and acceleration at time t (seconds since the start) of a traversal lasting `duration`
  // seconds (> 0); held at the ends outside [0, duration]. Between waypoints the velocity is continuous only as far
  // as the polyline is smooth.
  JointSample sample(double t, double duration) const;

 private:
  std::vector<Eigen::VectorXd> points_;
  std::vector<double> arc_;
};

// The duration of a joint-interpolated move from `from` to `to` (same sizes as max_speed): JointPath({from, to})
// .min_duration(max_speed, speed, min_time). The cycle-time estimate uses it for the motions it predicts.
double move_duration(const Eigen::VectorXd& from, const Eigen::VectorXd& to, const Eigen::VectorXd& max_speed,
                     double speed, double min_time);

}  // namespace cellwright::twin::sim
