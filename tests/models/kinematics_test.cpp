// Forward and inverse kinematics of the cell's two arms, checked against the Robotics Toolbox's DH model, the
// published MELFA lengths and round trips FK(IK(T)) = T.
#include "cellwright/models/kinematics.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <thread>

namespace cellwright::models {
namespace {

using ::testing::HasSubstr;
constexpr double kPi = std::numbers::pi;

std::filesystem::path urdf_path(const std::string& name) {
  return std::filesystem::path(models_dir()) / "urdf" / name;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The Robotics Toolbox's definition of a standard DH link transform: Rz(theta) Tz(d) Tx(a) Rx(alpha).
Eigen::Isometry3d dh(double theta, double d, double a, double alpha) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.rotate(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()));
  t.translate(Eigen::Vector3d(a, 0, d));  // Tz(d) Tx(a): both translations commute
  t.rotate(Eigen::AngleAxisd(alpha, Eigen::Vector3d::UnitX()));
  return t;
}

// PUMA 560, Python toolbox convention (d1 = 0.67183 m: the pedestal is included), written out from facts.md.
Eigen::Isometry3d puma_dh_fkine(const Eigen::VectorXd& q) {
  const double d[6] = {0.67183, 0, 0.15005, 0.4318, 0, 0};
  const double a[6] = {0, 0.4318, 0.0203, 0, 0, 0};
  const double alpha[6] = {kPi / 2, 0, -kPi / 2, kPi / 2, -kPi / 2, 0};
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 6; ++i) t = t * dh(q[i], d[i], a[i], alpha[i]);
  return t;
}

Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) q[i++] = x;
  return q;
}

Eigen::VectorXd random_q(const KinematicChain& c, std::mt19937_64& rng) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(c.dof()));
  for (std::size_t i = 0; i < c.dof(); ++i) {
    std::uniform_real_distribution<double> u(c.limits()[i].lower, c.limits()[i].upper);
    q[static_cast<Eigen::Index>(i)] = u(rng);
  }
  return q;
}

double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(Eigen::Matrix3d(a.transpose() * b)).angle();
}

class PumaTest : public ::testing::Test {
 protected:
  KinematicChain flange = KinematicChain::from_urdf_file(urdf_path("puma560.urdf"), "base_link", "flange");
  KinematicChain tcp = KinematicChain::from_urdf_file(urdf_path("puma560.urdf"));
};

TEST_F(PumaTest, ChainHasTheSixArmJointsWithTheToolboxLimits) {
  EXPECT_EQ(tcp.dof(), 6u);
  EXPECT_THAT(tcp.joint_names(), ::testing::ElementsAre("joint1", "joint2", "joint3", "joint4", "joint5", "joint6"));
  // Wang and Chen 1991, as in the toolbox (degrees).
  const double lower[6] = {-160, -45, -225, -110, -100, -266};
  const double upper[6] = {160, 225, 45, 170, 100, 266};
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(tcp.limits()[static_cast<std::size_t>(i)].lower * 180 / kPi, lower[i], 1e-4) << "joint " << i + 1;
    EXPECT_NEAR(tcp.limits()[static_cast<std::size_t>(i)].upper * 180 / kPi, upper[i], 1e-4) << "joint " << i + 1;
  }
}

TEST_F(PumaTest, ForwardKinematicsMatchesTheToolboxDhModelAtNamedPoses) {
  const std::vector<std::pair<std::string, Eigen::VectorXd>> poses = {{"qz", vec({0, 0, 0, 0, 0, 0})},
                                                                      {"qr", vec({0, kPi / 2, -kPi / 2, 0, 0, 0})},
                                                                      {"qs", vec({0, 0, -kPi / 2, 0, 0, 0})},
                                                                      {"qn", vec({0, kPi / 4, kPi, 0, kPi / 4, 0})}};
  for (const auto& [name, q] : poses) {
    const Eigen::Isometry3d ours = flange.forward(q), toolbox = puma_dh_fkine(q);
    EXPECT_LT((ours.translation() - toolbox.translation()).norm(), 1e-4) << name;
    EXPECT_LT(rotation_angle(ours.linear(), toolbox.linear()), 1e-6) << name;
  }
}

TEST_F(PumaTest, ForwardKinematicsMatchesTheDhModelAtRandomPoses) {
  std::mt19937_64 rng(7);
  for (int k = 0; k < 500; ++k) {
    const Eigen::VectorXd q = random_q(flange, rng);
    const Eigen::Isometry3d ours = flange.forward(q), toolbox = puma_dh_fkine(q);
    ASSERT_LT((ours.translation() - toolbox.translation()).norm(), 1e-9) << q.transpose();
    ASSERT_LT(rotation_angle(ours.linear(), toolbox.linear()), 1e-9) << q.transpose();
  }
}

// Values worked out by hand from the DH table, independent of any code. qz: the arm is an "L" (upper arm along +x,
// forearm up), x = a2 + a3, y = -d3, z = d1 + d4. qr: the arm stands straight up; q2 + q3 = 0 turns the a3 offset
// back to +x, so x = a3, y = -d3, z = d1 + a2 + d4. In both the flange axes are parallel to the base's. (The
// MATLAB model, d1 = 0, gives the same x and y and z lower by 0.67183.)
TEST_F(PumaTest, ForwardKinematicsAtQzAndQrEqualsHandComputedToolboxPoses) {
  const Eigen::Isometry3d qz = flange.forward(vec({0, 0, 0, 0, 0, 0}));
  EXPECT_LT((qz.translation() - Eigen::Vector3d(0.4521, -0.15005, 1.10363)).norm(), 1e-4) << qz.translation();
  EXPECT_LT(rotation_angle(qz.linear(), Eigen::Matrix3d::Identity()), 1e-9);

  const Eigen::Isometry3d qr = flange.forward(vec({0, kPi / 2, -kPi / 2, 0, 0, 0}));
  EXPECT_LT((qr.translation() - Eigen::Vector3d(0.0203, -0.15005, 1.53543)).norm(), 1e-4) << qr.translation();
  EXPECT_LT(rotation_angle(qr.linear(), Eigen::Matrix3d::Identity()), 1e-9);
}

TEST_F(PumaTest, TcpIsOnTheFlangeAxis146MillimetresOut) {
  std::mt19937_64 rng(11);
  for (int k = 0; k < 50; ++k) {
    const Eigen::VectorXd q = random_q(tcp, rng);
    const Eigen::Isometry3d f = flange.forward(q), t = tcp.forward(q);
    EXPECT_LT((t.translation() - (f.translation() + 0.146 * f.linear().col(2))).norm(), 1e-12);
    EXPECT_LT(rotation_angle(f.linear(), t.linear()), 1e-12);
  }
}

class MelfaTest : public ::testing::Test {
 protected:
  KinematicChain tcp = KinematicChain::from_urdf_file(urdf_path("melfa_rve2.urdf"));
  // The wrist centre is link5's origin (joint5's axis meets joints 4 and 6 there).
  KinematicChain wrist = KinematicChain::from_urdf_file(urdf_path("melfa_rve2.urdf"), "base_link", "link5");
};

TEST_F(MelfaTest, HasSixJointsWithTheRv2ajLimitsOnTheFirstThree) {
  ASSERT_EQ(tcp.dof(), 6u);
  const double lower[3] = {-150, -60, -110}, upper[3] = {150, 120, 120};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(tcp.limits()[static_cast<std::size_t>(i)].lower * 180 / kPi, lower[i], 1e-4);
    EXPECT_NEAR(tcp.limits()[static_cast<std::size_t>(i)].upper * 180 / kPi, upper[i], 1e-4);
  }
}

// RV-2AJ: shoulder 300 mm high, upper arm 250, forearm 160, wrist 72 mm to the flange; gripper tcp 90 mm further.
TEST_F(MelfaTest, LengthsAreTheRv2ajOnes) {
  const Eigen::Isometry3d up = tcp.forward(Eigen::VectorXd::Zero(6));
  EXPECT_LT((up.translation() - Eigen::Vector3d(0, 0, 0.3 + 0.25 + 0.16 + 0.072 + 0.09)).norm(), 1e-12);

  // Arm stretched forward: the wrist centre is at the published maximum reach, 410 mm from the shoulder.
  const Eigen::Vector3d forward = wrist.forward(vec({0, kPi / 2, 0, 0, 0})).translation();
  EXPECT_LT((forward - Eigen::Vector3d(0.41, 0, 0.3)).norm(), 1e-12) << forward.transpose();

  // Elbow folded to its 120 degree limit: the published minimum reach, 220 mm (219.3 mm with these lengths).
  const Eigen::Vector3d folded = wrist.forward(vec({0, 0, 2 * kPi / 3, 0, 0})).translation();
  EXPECT_NEAR((folded - Eigen::Vector3d(0, 0, 0.3)).norm(), 0.22, 1e-3);

  // Positive joint 1 turns the arm towards +y.
  const Eigen::Vector3d turned = wrist.forward(vec({kPi / 2, kPi / 2, 0, 0, 0})).translation();
  EXPECT_LT((turned - Eigen::Vector3d(0, 0.41, 0.3)).norm(), 1e-12) << turned.transpose();
}

TEST_F(MelfaTest, WristIsSphericalTheWristJointsDoNotMoveTheWristCentre) {
  std::mt19937_64 rng(3);
  for (int k = 0; k < 100; ++k) {
    Eigen::VectorXd q = random_q(tcp, rng), moved = q;
    moved.tail<3>() = random_q(tcp, rng).tail<3>();
    const Eigen::Vector3d a = wrist.forward(q.head<5>()).translation(),
                          b = wrist.forward(moved.head<5>()).translation();
    EXPECT_LT((a - b).norm(), 1e-12);
    // The flange stays 72 mm + 90 mm (tcp) from the wrist centre.
    EXPECT_NEAR((tcp.forward(moved).translation() - b).norm(), 0.162, 1e-12);
  }
}

// Both arms: properties every chain must have.
class ArmTest : public ::testing::TestWithParam<std::string> {
 protected:
  KinematicChain chain = KinematicChain::from_urdf_file(urdf_path(GetParam()));
};

TEST_P(ArmTest, JacobianMatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  for (int k = 0; k < 100; ++k) {
    const Eigen::VectorXd q = random_q(chain, rng);
    const auto jac = chain.jacobian(q);
    const Eigen::Isometry3d t0 = chain.forward(q);
    constexpr double h = 1e-6;
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      Eigen::VectorXd qh = q;
      qh[i] += h;
      const Eigen::Isometry3d t1 = chain.forward(qh);
      const Eigen::Vector3d v = (t1.translation() - t0.translation()) / h;
      const Eigen::AngleAxisd dr(Eigen::Matrix3d(t1.linear() * t0.linear().transpose()));
      const Eigen::Vector3d w = dr.angle() * dr.axis() / h;
      EXPECT_LT((jac.col(i).head<3>() - v).norm(), 1e-5) << "column " << i;
      EXPECT_LT((jac.col(i).tail<3>() - w).norm(), 1e-5) << "column " << i;
    }
  }
}

// frames() is the safety layer's one walk for every joint frame and the tip: the same bits as the walks it replaces.
TEST_P(ArmTest, FramesAreEachJointFrameAndTheTipBitForBit) {
  std::mt19937_64 rng(17);
  for (int n = 0; n < 50; ++n) {
    const Eigen::VectorXd q = random_q(chain, rng);
    const std::vector<Eigen::Isometry3d> frames = chain.frames(q);
    ASSERT_EQ(frames.size(), chain.dof() + 1);
    for (std::size_t k = 1; k <= chain.dof(); ++k) {
      EXPECT_TRUE(frames[k - 1].matrix() == chain.joint_frame(q, k).matrix()) << "joint " << k;
    }
    EXPECT_TRUE(frames.back().matrix() == chain.forward(q).matrix());
  }
  EXPECT_THROW(chain.frames(Eigen::VectorXd::Zero(2)), InternalError);
}

TEST_P(ArmTest, MaxReachBoundsTheTipDistanceFromJointOne) {
  std::mt19937_64 rng(13);
  double farthest = 0;
  for (int k = 0; k < 20000; ++k) {
    const double d = (chain.forward(random_q(chain, rng)).translation() - chain.first_joint_origin()).norm();
    ASSERT_LE(d, chain.max_reach());
    farthest = std::max(farthest, d);
  }
  // An upper bound, but not a useless one.
  EXPECT_GT(farthest, 0.75 * chain.max_reach());
}

TEST_P(ArmTest, InverseOfRandomReachablePosesFromDistantSeeds) {
  std::mt19937_64 rng(2024);
  constexpr int kPoses = 2000;
  int solved = 0;
  for (int k = 0; k < kPoses; ++k) {
    const Eigen::VectorXd q_true = random_q(chain, rng), seed = random_q(chain, rng);
    const Eigen::Isometry3d target = chain.forward(q_true);
    const IkResult r = chain.inverse(target, seed);
    if (r.status != IkStatus::kOk) continue;
    ++solved;
    // What the solver says and what is true must agree.
    ASSERT_TRUE(chain.within_limits(r.q)) << r.q.transpose();
    const Eigen::Isometry3d reached = chain.forward(r.q);
    ASSERT_LE((reached.translation() - target.translation()).norm(), 1e-5);
    ASSERT_LE(rotation_angle(reached.linear(), target.linear()), 1e-4);
    ASSERT_NEAR(r.position_error, (reached.translation() - target.translation()).norm(), 1e-12);
  }
  const double rate = static_cast<double>(solved) / kPoses;
  RecordProperty("success_rate", std::to_string(rate));
  std::printf("[ info     ] %s: %d of %d random reachable poses solved (%.2f%%)\n", GetParam().c_str(), solved, kPoses,
              100 * rate);
  EXPECT_GE(rate, 0.99);
}

TEST_P(ArmTest, InverseFromANearbySeedReturnsTheNearbySolution) {
  std::mt19937_64 rng(99);
  std::normal_distribution<double> jitter(0, 0.05);
  int checked = 0;
  for (int k = 0; k < 300; ++k) {
    const Eigen::VectorXd q_true = random_q(chain, rng);
    Eigen::VectorXd seed = q_true;
    for (Eigen::Index i = 0; i < seed.size(); ++i) seed[i] += jitter(rng);
    if (!chain.within_limits(seed)) continue;
    // Stay away from the wrist singularity, where nearby joint vectors are not unique.
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(chain.jacobian(q_true));
    if (svd.singularValues().minCoeff() < 0.02) continue;
    const IkResult r = chain.inverse(chain.forward(q_true), seed);
    ASSERT_EQ(r.status, IkStatus::kOk) << r.reason;
    EXPECT_LT((r.q - q_true).norm(), 1e-3) << "true " << q_true.transpose() << "\nfound " << r.q.transpose();
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST_P(ArmTest, InverseIsDeterministicAndThreadSafe) {
  std::mt19937_64 rng(17);
  std::vector<Eigen::Isometry3d> targets;
  std::vector<Eigen::VectorXd> seeds;
  for (int k = 0; k < 40; ++k) {
    targets.push_back(chain.forward(random_q(chain, rng)));
    seeds.push_back(random_q(chain, rng));
  }
  std::vector<IkResult> serial;
  for (int k = 0; k < 40; ++k) serial.push_back(chain.inverse(targets[k], seeds[k]));
  std::vector<IkResult> a(40), b(40);
  std::thread ta([&] {
    for (int k = 0; k < 40; ++k) a[k] = chain.inverse(targets[k], seeds[k]);
  });
  std::thread tb([&] {
    for (int k = 39; k >= 0; --k) b[k] = chain.inverse(targets[k], seeds[k]);
  });
  ta.join();
  tb.join();
  for (int k = 0; k < 40; ++k) {
    EXPECT_EQ(serial[k].status, a[k].status);
    EXPECT_EQ(serial[k].q, a[k].q);  // bit for bit
    EXPECT_EQ(serial[k].q, b[k].q);
  }
}

TEST_P(ArmTest, TooFarIsUnreachableWithTheDistanceInTheReason) {
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() = chain.first_joint_origin() + Eigen::Vector3d(1.2, 0.9, 0.2);
  const IkResult r = chain.inverse(target, Eigen::VectorXd::Zero(6));
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  EXPECT_THAT(r.reason, HasSubstr("out of reach: 1.513 m"));
}

TEST_P(ArmTest, NonFiniteOrNonRotationTargetsAreUnreachable) {
  Eigen::Isometry3d target = chain.forward(Eigen::VectorXd::Zero(6));
  target.translation().x() = std::nan("");
  EXPECT_EQ(chain.inverse(target, Eigen::VectorXd::Zero(6)).status, IkStatus::kUnreachable);
  Eigen::Isometry3d scaled = chain.forward(Eigen::VectorXd::Zero(6));
  scaled.linear() *= 2;
  const IkResult r = chain.inverse(scaled, Eigen::VectorXd::Zero(6));
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  EXPECT_THAT(r.reason, HasSubstr("not a rotation"));
}

TEST_P(ArmTest, WrongSizedJointVectorsAreOurBug) {
  EXPECT_THROW(chain.forward(Eigen::VectorXd::Zero(5)), InternalError);
  EXPECT_THROW(chain.jacobian(Eigen::VectorXd::Zero(7)), InternalError);
  EXPECT_THROW(chain.inverse(Eigen::Isometry3d::Identity(), Eigen::VectorXd::Zero(2)), InternalError);
}

INSTANTIATE_TEST_SUITE_P(BothArms, ArmTest, ::testing::Values("puma560.urdf", "melfa_rve2.urdf"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                           return p.param.substr(0, p.param.find('.'));
                         });

// A tool pointing down.
Eigen::Isometry3d pose_down(double x, double y, double z) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(x, y, z);
  return t;
}

// Arm straight up: the wrist centre is on joint 1's axis and joints 4 and 6 are aligned, so joint 1 and joints 4 + 6
// are free (a continuum of answers). The solver must still answer, and stay at the seed's values of the free joints.
TEST_F(MelfaTest, SingularPosesAreSolvedNearTheSeed) {
  const Eigen::Isometry3d up = tcp.forward(Eigen::VectorXd::Zero(6));
  const IkResult at_zero = tcp.inverse(up, Eigen::VectorXd::Zero(6));
  ASSERT_EQ(at_zero.status, IkStatus::kOk) << at_zero.reason;
  EXPECT_LT(at_zero.q.norm(), 1e-6) << at_zero.q.transpose();

  // Any q1 + q4 + q6 = 0 with the rest 0 is an answer; this seed is 0.05 rad or less from (1, 0, 0, 0.4, 0, -1.4).
  const Eigen::VectorXd seed = vec({1.0, 0.05, -0.05, 0.4, 0.02, -1.4});
  const IkResult r = tcp.inverse(up, seed);
  ASSERT_EQ(r.status, IkStatus::kOk) << r.reason;
  EXPECT_LT((tcp.forward(r.q).translation() - up.translation()).norm(), 1e-5);
  EXPECT_LT((r.q - vec({1.0, 0, 0, 0.4, 0, -1.4})).norm(), 0.01) << r.q.transpose();
}

TEST_F(MelfaTest, BelowTheFloorIsOutOfReach) {
  const IkResult r = tcp.inverse(pose_down(0.1, 0, -0.3), Eigen::VectorXd::Zero(6));
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  EXPECT_THAT(r.reason, HasSubstr("out of reach"));
}

// Straight behind the arm, low: the arm has no side offset, so the wrist must lie in the plane of joint 1's angle,
// which would have to be 180 degrees (limit 150); leaning back over the top cannot reach that low (joint 2 >= -60).
TEST_F(MelfaTest, BehindTheJointLimitsIsUnreachableButSolvableWithoutThem) {
  const Eigen::Isometry3d behind = pose_down(-0.35, 0, 0.05);
  ASSERT_LT((behind.translation() - tcp.first_joint_origin()).norm(), tcp.max_reach());
  const IkResult r = tcp.inverse(behind, Eigen::VectorXd::Zero(6));
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  EXPECT_THAT(r.reason, HasSubstr("outside the joint limits"));
  EXPECT_THAT(r.reason, HasSubstr("none within them"));
  EXPECT_GT(r.position_error, 1e-3);
  EXPECT_TRUE(tcp.within_limits(r.q));

  // The same arm with joint 1 free to turn all the way round reaches it: the limit is the reason.
  std::string text = read_text(urdf_path("melfa_rve2.urdf"));
  const std::string limit = R"(<limit lower="-2.617994" upper="2.617994" effort="30")";
  ASSERT_NE(text.find(limit), std::string::npos);
  text.replace(text.find(limit), limit.size(), R"(<limit lower="-3.2" upper="3.2" effort="30")");
  const KinematicChain free_base = KinematicChain::from_urdf_string(text, "melfa_free_j1.urdf");
  const IkResult free = free_base.inverse(behind, Eigen::VectorXd::Zero(6));
  EXPECT_EQ(free.status, IkStatus::kOk) << free.reason;
  EXPECT_GT(std::abs(free.q[0]), 2.617994);
}

// The PUMA's wrist can flip: (q4 + pi, -q5, q6 + pi) gives the same pose. Both are answers; the seed decides.
TEST_F(PumaTest, InverseReturnsTheSolutionBranchNearestTheSeed) {
  std::mt19937_64 rng(21);
  int checked = 0;
  while (checked < 50) {
    Eigen::VectorXd q = random_q(tcp, rng);
    if (std::abs(q[4]) < 0.2) continue;  // away from the wrist singularity
    Eigen::VectorXd flipped = q;
    flipped[3] += q[3] < 0 ? kPi : -kPi;
    flipped[4] = -q[4];
    flipped[5] += q[5] < 0 ? kPi : -kPi;
    if (!tcp.within_limits(flipped)) continue;
    const Eigen::Isometry3d target = tcp.forward(q);
    ASSERT_LT((tcp.forward(flipped).translation() - target.translation()).norm(), 1e-12);
    for (const Eigen::VectorXd& wanted : {q, flipped}) {
      Eigen::VectorXd seed = wanted;
      seed.tail<3>().array() += 0.2;
      const IkResult r = tcp.inverse(target, seed);
      ASSERT_EQ(r.status, IkStatus::kOk) << r.reason;
      EXPECT_LT((r.q - wanted).norm(), 1e-4) << "wanted " << wanted.transpose() << "\ngot    " << r.q.transpose();
    }
    ++checked;
  }
}

// A chain without a spherical wrist (the MELFA up to link5: five joints) is solved by the iterative search alone.
TEST_F(MelfaTest, ChainsWithoutASphericalWristAreSolvedIteratively) {
  std::mt19937_64 rng(31);
  constexpr int kPoses = 300;
  int solved = 0;
  for (int k = 0; k < kPoses; ++k) {
    const Eigen::VectorXd q_true = random_q(wrist, rng), seed = random_q(wrist, rng);
    const Eigen::Isometry3d target = wrist.forward(q_true);
    const IkResult r = wrist.inverse(target, seed);
    if (r.status != IkStatus::kOk) continue;
    ++solved;
    ASSERT_TRUE(wrist.within_limits(r.q));
    ASSERT_LE((wrist.forward(r.q).translation() - target.translation()).norm(), 1e-5);
  }
  std::printf("[ info     ] MELFA base..link5 (5 joints): %d of %d solved\n", solved, kPoses);
  EXPECT_GE(solved, kPoses * 9 / 10);
}

// The forearm is offset 150 mm sideways from the shoulder (d3), so the wrist centre can never be on joint 1's axis;
// and a target 0.2 m in front of and below the shoulder, pointing down, needs the elbow folded past its limit.
TEST_F(PumaTest, UnreachablePosesWithinReachSayWhy) {
  const IkResult on_axis = tcp.inverse(pose_down(0, 0, 0.6), Eigen::VectorXd::Zero(6));
  EXPECT_EQ(on_axis.status, IkStatus::kUnreachable);
  EXPECT_THAT(on_axis.reason, HasSubstr("wrist centre (0.000, -0.000, 0.746) m cannot be reached"));
  const IkResult folded = tcp.inverse(pose_down(0.2, 0, 0.67183 - 0.2), Eigen::VectorXd::Zero(6));
  EXPECT_EQ(folded.status, IkStatus::kUnreachable);
  EXPECT_THAT(folded.reason, HasSubstr("outside the joint limits"));
}

TEST_F(PumaTest, ReachesAPickPoseOnATableInFrontAndKeepsJointSixNearTheSeed) {
  // A pick 0.5 m in front of the pedestal, 0.75 m above the floor, gripper pointing down.
  Eigen::VectorXd seed = vec({0, kPi / 4, kPi, 0, kPi / 4, 0});  // qn (q3 = 180 deg is outside the limits: clamped)
  const IkResult r = tcp.inverse(pose_down(0.5, -0.15, 0.75), seed);
  ASSERT_EQ(r.status, IkStatus::kOk) << r.reason;
  // Joint 6 has more than one turn of travel; the answer takes the turn nearest the seed.
  EXPECT_LE(std::abs(r.q[5]), kPi + 1e-9);
}

}  // namespace
}  // namespace cellwright::models
