// The quintic joint trajectories: they start and end at rest at the right points, respect the speed limits they
// were timed for, and follow polylines through their waypoints.
#include "cellwright/twin/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {
namespace {

Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) out[i++] = x;
  return out;
}

TEST(Quintic, StartsAndEndsAtRest) {
  EXPECT_DOUBLE_EQ(quintic(0.0), 0.0);
  EXPECT_DOUBLE_EQ(quintic(1.0), 1.0);
  EXPECT_DOUBLE_EQ(quintic(0.5), 0.5);
  EXPECT_DOUBLE_EQ(quintic(-1.0), 0.0);
  EXPECT_DOUBLE_EQ(quintic(2.0), 1.0);
  EXPECT_DOUBLE_EQ(quintic_rate(0.0), 0.0);
  EXPECT_DOUBLE_EQ(quintic_rate(1.0), 0.0);
  EXPECT_DOUBLE_EQ(quintic_rate(0.5), kQuinticPeakSpeed);
  EXPECT_DOUBLE_EQ(quintic_accel(0.5), 0.0);
  // The derivatives agree with finite differences of the scaling.
  for (double u = 0.05; u < 1.0; u += 0.1) {
    const double h = 1e-6;
    EXPECT_NEAR(quintic_rate(u), (quintic(u + h) - quintic(u - h)) / (2 * h), 1e-6) << u;
    EXPECT_NEAR(quintic_accel(u), (quintic_rate(u + h) - quintic_rate(u - h)) / (2 * h), 1e-5) << u;
  }
}

TEST(JointPath, TwoPointMoveIsTimedByTheSlowestJoint) {
  const JointPath path({vec({0, 0}), vec({1.0, -0.5})});
  // Joint 1 needs 1 rad at 2 rad/s peak, joint 2 0.5 rad at 0.25 rad/s: joint 2 decides.
  const double t = path.min_duration(vec({2.0, 0.25}), 1.0, 0.1);
  EXPECT_DOUBLE_EQ(t, kQuinticPeakSpeed * 0.5 / 0.25);
  // Half speed takes twice as long; the minimum time applies to short moves.
  EXPECT_DOUBLE_EQ(path.min_duration(vec({2.0, 0.25}), 0.5, 0.1), 2 * t);
  EXPECT_DOUBLE_EQ(path.min_duration(vec({100.0, 100.0}), 1.0, 0.3), 0.3);
  EXPECT_DOUBLE_EQ(move_duration(vec({0, 0}), vec({1.0, -0.5}), vec({2.0, 0.25}), 1.0, 0.1), t);

  // Sampled finely, no joint exceeds its limit and the peak reaches it.
  double peak = 0;
  for (double s = 0; s <= t; s += t / 1000) {
    const JointSample x = path.sample(s, t);
    EXPECT_LE(std::abs(x.velocity[1]), 0.25 * (1 + 1e-9));
    peak = std::max(peak, std::abs(x.velocity[1]));
  }
  EXPECT_NEAR(peak, 0.25, 1e-4);
  const JointSample start = path.sample(0, t), end = path.sample(t, t), after = path.sample(2 * t, t);
  EXPECT_TRUE(start.position.isApprox(vec({0, 0})));
  EXPECT_TRUE(end.position.isApprox(vec({1.0, -0.5})));
  EXPECT_TRUE(after.position.isApprox(vec({1.0, -0.5})));
  EXPECT_EQ(start.velocity.norm(), 0.0);
  EXPECT_EQ(end.velocity.norm(), 0.0);
}

TEST(JointPath, VelocityIsTheDerivativeOfPosition) {
  const JointPath path({vec({0, 1}), vec({0.3, 1.2}), vec({0.5, 1.0})});
  const double T = 2.0, h = 1e-6;
  for (double t = 0.1; t < T; t += 0.13) {
    const Eigen::VectorXd numeric = (path.sample(t + h, T).position - path.sample(t - h, T).position) / (2 * h);
    EXPECT_LT((numeric - path.sample(t, T).velocity).norm(), 1e-5) << t;
  }
}

TEST(JointPath, PolylinePassesThroughItsWaypoints) {
  // Arc given as a uniform parameter (a straight line of the tool in equal steps).
  const JointPath path({vec({0}), vec({0.1}), vec({0.4}), vec({0.5})}, {0.0, 1.0 / 3, 2.0 / 3, 1.0});
  const double T = 1.0;
  // The scaling reaches a = 1/3 at the time u where quintic(u) = 1/3: bisect for it.
  double lo = 0, hi = 1;
  for (int i = 0; i < 60; ++i) ((quintic((lo + hi) / 2) < 1.0 / 3) ? lo : hi) = (lo + hi) / 2;
  EXPECT_NEAR(path.sample(lo * T, T).position[0], 0.1, 1e-9);
  // Timing uses the steepest segment: 0.3 rad over a third of the arc.
  EXPECT_NEAR(path.min_duration(vec({1.0}), 1.0, 0.0), kQuinticPeakSpeed * 0.9, 1e-12);
}

TEST(JointPath, StandingStillIsAValidPath) {
  const JointPath path({vec({0.2, 0.2}), vec({0.2, 0.2})});
  EXPECT_DOUBLE_EQ(path.min_duration(vec({1, 1}), 1.0, 0.25), 0.25);
  EXPECT_TRUE(path.sample(0.1, 0.25).position.isApprox(vec({0.2, 0.2})));
}

TEST(JointPath, RejectsInconsistentInput) {
  EXPECT_THROW(JointPath({vec({0})}), InternalError);
  EXPECT_THROW(JointPath({vec({0}), vec({0, 1})}), InternalError);
  EXPECT_THROW(JointPath({vec({0}), vec({1})}, {0.0, 0.5}), InternalError);
  EXPECT_THROW(JointPath({vec({0}), vec({1}), vec({2})}, {0.0, 0.0, 1.0}), InternalError);
  EXPECT_THROW(JointPath({vec({0}), vec({NAN})}), InternalError);
  const JointPath ok({vec({0}), vec({1})});
  EXPECT_THROW(static_cast<void>(ok.min_duration(vec({0.0}), 1.0, 0.0)), InternalError);
  EXPECT_THROW(static_cast<void>(ok.min_duration(vec({1.0}), 1.5, 0.0)), InternalError);
  EXPECT_THROW(static_cast<void>(ok.sample(0.0, 0.0)), InternalError);
}

}  // namespace
}  // namespace cellwright::twin::sim
