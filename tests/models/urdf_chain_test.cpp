// Building chains from URDF text: what is accepted, and the errors a user sees for bad files.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "cellwright/models/kinematics.hpp"
#include "common/garbage_in.hpp"
#include "models/input_error.hpp"

namespace cellwright::models {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;

// A two-joint arm, line numbers matter: joint "j1" is on line 4 and joint "j2" on line 9.
constexpr const char* kArm = R"(<?xml version="1.0"?>
<robot name="toy">
  <link name="base_link"/>
  <joint name="j1" type="revolute">
    <parent link="base_link"/> <child link="l1"/>
    <origin xyz="0 0 0.5"/> <axis xyz="0 0 1"/> <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="l1"/>
  <joint name="j2" type="JTYPE">
    <parent link="l1"/> <child link="l2"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/> <axis xyz="AXIS"/> <limit lower="LOWER" upper="0.2" effort="1" velocity="1"/>
  </joint>
  <link name="l2"/>
  <joint name="tip_joint" type="fixed">
    <parent link="l2"/> <child link="tcp"/> <origin xyz="0.1 0 0"/>
  </joint>
  <link name="tcp"/>
</robot>
)";

std::string arm(std::string type = "prismatic", std::string axis = "1 0 0", std::string lower = "-0.1") {
  std::string s = kArm;
  s.replace(s.find("JTYPE"), 5, type);
  s.replace(s.find("AXIS"), 4, axis);
  s.replace(s.find("LOWER"), 5, lower);
  return s;
}

TEST(UrdfChain, BuildsAChainOfRevoluteAndPrismaticJointsFoldingFixedOnes) {
  const KinematicChain c = KinematicChain::from_urdf_string(arm(), "toy.urdf");
  ASSERT_EQ(c.dof(), 2u);
  EXPECT_THAT(c.joint_names(), ::testing::ElementsAre("j1", "j2"));
  EXPECT_EQ(c.limits()[1].lower, -0.1);
  EXPECT_EQ(c.limits()[1].upper, 0.2);
  // j1 turns a quarter turn, j2 slides 0.1 along the (turned) x axis: tip at (0, 0.3 + 0.1 + 0.1, 0.5).
  Eigen::VectorXd q(2);
  q << std::numbers::pi / 2, 0.1;
  EXPECT_LT((c.forward(q).translation() - Eigen::Vector3d(0, 0.5, 0.5)).norm(), 1e-12);
  EXPECT_LT((c.first_joint_origin() - Eigen::Vector3d(0, 0, 0.5)).norm(), 1e-12);
  EXPECT_NEAR(c.max_reach(), 0.3 + 0.2 + 0.1, 1e-12);  // link, prismatic travel, tip offset
  // The prismatic column of the Jacobian is its axis, with no angular part.
  const auto jac = c.jacobian(q);
  EXPECT_LT((jac.col(1) - (Eigen::Matrix<double, 6, 1>() << 0, 1, 0, 0, 0, 0).finished()).norm(), 1e-12);
}

TEST(UrdfChain, ContinuousJointsHaveNoLimits) {
  const KinematicChain c = KinematicChain::from_urdf_string(arm("continuous", "0 0 1"), "toy.urdf");
  EXPECT_TRUE(std::isinf(c.limits()[1].lower));
  EXPECT_TRUE(std::isinf(c.limits()[1].upper));
  Eigen::VectorXd q(2);
  q << 0.3, 25.0;
  EXPECT_TRUE(c.within_limits(q));
}

TEST(UrdfChain, AGripperFingerIsAOneJointChain) {
  const auto puma = std::filesystem::path(models_dir()) / "urdf" / "puma560.urdf";
  const KinematicChain finger = KinematicChain::from_urdf_file(puma, "gripper_base", "finger_left");
  ASSERT_EQ(finger.dof(), 1u);
  EXPECT_EQ(finger.joint_names()[0], "finger_left_joint");
  Eigen::VectorXd q(1);
  q << 0.025;
  EXPECT_LT((finger.forward(q).translation() - Eigen::Vector3d(0, 0.025, 0.04)).norm(), 1e-12);
}

TEST(UrdfChain, MissingFileNamesTheFile) {
  const InputError e = input_error([] { KinematicChain::from_urdf_file("/nonexistent/robot.urdf"); });
  EXPECT_EQ(e.where().file, "/nonexistent/robot.urdf");
  EXPECT_THAT(e.what(), AllOf(HasSubstr("/nonexistent/robot.urdf"), HasSubstr("no such file")));
}

TEST(UrdfChain, MalformedXmlNamesFileAndLine) {
  std::string bad = arm();
  bad.replace(bad.find("</joint>"), 8, "</joint");  // line 7
  const InputError e = input_error([&] { KinematicChain::from_urdf_string(bad, "bad.urdf"); });
  EXPECT_EQ(e.where().file, "bad.urdf");
  EXPECT_EQ(e.where().line, 7);
  EXPECT_THAT(e.what(), AllOf(HasSubstr("bad.urdf:7"), HasSubstr("malformed XML")));
}

TEST(UrdfChain, WrongRootElementIsRejected) {
  const InputError e =
      input_error([] { KinematicChain::from_urdf_string("<?xml version=\"1.0\"?>\n<mujoco/>\n", "scene.xml"); });
  EXPECT_EQ(e.where().line, 2);
  EXPECT_THAT(e.problem(), HasSubstr("<mujoco>"));
}

TEST(UrdfChain, JointToAnUndefinedLinkIsReportedAtThatJoint) {
  std::string bad = arm();
  bad.replace(bad.find("<child link=\"l2\"/>"), 18, "<child link=\"l9\"/>");
  const InputError e = input_error([&] { KinematicChain::from_urdf_string(bad, "toy.urdf"); });
  EXPECT_EQ(e.where().line, 9);
  EXPECT_THAT(e.problem(), AllOf(HasSubstr("invalid URDF"), HasSubstr("l9")));
}

TEST(UrdfChain, NonNumericValuesAreReported) {
  const InputError e = input_error([&] { KinematicChain::from_urdf_string(arm("prismatic", "1 x 0"), "toy.urdf"); });
  EXPECT_EQ(e.where().file, "toy.urdf");
  EXPECT_THAT(e.problem(), HasSubstr("invalid URDF"));
}

TEST(UrdfChain, MissingTipOrBaseLinkIsNamed) {
  const InputError tip = input_error([] { KinematicChain::from_urdf_string(arm(), "toy.urdf", "base_link", "tool0"); });
  EXPECT_THAT(tip.what(), AllOf(HasSubstr("toy.urdf"), HasSubstr("'tool0'"), HasSubstr("tip")));
  const InputError base = input_error([] { KinematicChain::from_urdf_string(arm(), "toy.urdf", "world", "tcp"); });
  EXPECT_THAT(base.what(), AllOf(HasSubstr("'world'"), HasSubstr("base")));
}

TEST(UrdfChain, TipThatIsNotBelowTheBaseIsRejected) {
  const InputError e = input_error([] { KinematicChain::from_urdf_string(arm(), "toy.urdf", "tcp", "base_link"); });
  EXPECT_THAT(e.problem(), HasSubstr("not a descendant"));
}

TEST(UrdfChain, UnsupportedJointTypeIsReportedAtItsLine) {
  const InputError e = input_error([] { KinematicChain::from_urdf_string(arm("floating"), "toy.urdf"); });
  EXPECT_EQ(e.where().line, 9);
  EXPECT_THAT(e.problem(), AllOf(HasSubstr("'j2'"), HasSubstr("floating")));
}

TEST(UrdfChain, InvertedLimitsAreReportedAtTheJoint) {
  const InputError e = input_error([] { KinematicChain::from_urdf_string(arm("revolute", "0 0 1", "0.5"), "t.urdf"); });
  EXPECT_EQ(e.where().line, 9);
  EXPECT_THAT(e.problem(), AllOf(HasSubstr("'j2'"), HasSubstr("lower = 0.5 > upper = 0.2")));
}

TEST(UrdfChain, ZeroAxisIsRejected) {
  const InputError e = input_error([] { KinematicChain::from_urdf_string(arm("revolute", "0 0 0"), "toy.urdf"); });
  EXPECT_THAT(e.what(), AllOf(HasSubstr("toy.urdf"), HasSubstr("j2")));
}

TEST(UrdfChain, ChainWithoutMovableJointsIsRejected) {
  const InputError e = input_error([] { KinematicChain::from_urdf_string(arm(), "toy.urdf", "l2", "tcp"); });
  EXPECT_THAT(e.problem(), HasSubstr("no revolute, continuous or prismatic joint"));
}

TEST(UrdfChain, MimicJointsAreRejected) {
  std::string s = arm();
  s.replace(s.find("<limit lower=\"-0.1\""), 0, "<mimic joint=\"j1\"/> ");
  const InputError e = input_error([&] { KinematicChain::from_urdf_string(s, "toy.urdf"); });
  EXPECT_EQ(e.where().line, 9);
  EXPECT_THAT(e.problem(), HasSubstr("mimic"));
}

// Seeded garbage in: the shipped URDFs with random edits (XML's punctuation, digits) become a chain whose forward
// kinematics is finite, or are refused with an InputError naming the file; nothing else escapes.
TEST(UrdfGarbageIn, MutatedUrdfsGiveAChainOrAnInputError) {
  const std::filesystem::path dir = std::filesystem::path(CW_SOURCE_DIR) / "models" / "urdf";
  const auto counts = cellwright::testing::feed_garbage(
      {cellwright::testing::slurp_text(dir / "puma560.urdf"), cellwright::testing::slurp_text(dir / "melfa_rve2.urdf")},
      1500, 20261124, "<>/=\"' \n-.0123456789eEabxyz", "mutant.urdf", [](const std::string& text) {
        const KinematicChain chain = KinematicChain::from_urdf_string(text, "mutant.urdf");
        Eigen::VectorXd q(static_cast<Eigen::Index>(chain.dof()));
        for (std::size_t i = 0; i < chain.dof(); ++i) {
          const JointLimit& l = chain.limits()[i];
          q[static_cast<Eigen::Index>(i)] = std::isfinite(l.lower) ? l.lower : 0.0;
        }
        EXPECT_TRUE(chain.forward(q).matrix().allFinite()) << text;
      });
  EXPECT_GT(counts.accepted, 100);
  EXPECT_GT(counts.refused, 300);
}

}  // namespace
}  // namespace cellwright::models
