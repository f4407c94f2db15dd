// The two robot URDF files as every reader gets them (the URDF loader): naming convention, physically valid
// inertias, and the shared gripper.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/urdf.hpp"

namespace cellwright::models {
namespace {

// The file as every reader gets it, from the one URDF loader; null (and a failure) if it cannot be loaded. The models
// are immutable, so one load serves every test.
const urdf::ModelInterface* load(const std::string& name) {
  static std::map<std::string, UrdfModel> loaded;
  if (auto it = loaded.find(name); it != loaded.end()) return &it->second.robot();
  try {
    return &loaded.emplace(name, load_urdf_file(std::filesystem::path(models_dir()) / "urdf" / name))
                .first->second.robot();
  } catch (const InputError& e) {
    ADD_FAILURE() << e.what();
    return nullptr;
  }
}

class UrdfFile : public ::testing::TestWithParam<std::string> {
 protected:
  const urdf::ModelInterface* model = load(GetParam());
};

TEST_P(UrdfFile, FollowsTheCellNamingConvention) {
  ASSERT_TRUE(model);
  for (const char* link : {"base_link", "link1", "link2", "link3", "link4", "link5", "link6", "flange", "gripper_base",
                           "finger_left", "finger_right", "tcp"}) {
    EXPECT_TRUE(model->getLink(link)) << link;
  }
  EXPECT_EQ(model->getRoot()->name, "base_link");
  for (int i = 1; i <= 6; ++i) {
    const auto j = model->getJoint("joint" + std::to_string(i));
    ASSERT_TRUE(j) << i;
    EXPECT_EQ(j->type, urdf::Joint::REVOLUTE);
    EXPECT_EQ(j->child_link_name, "link" + std::to_string(i));
    EXPECT_GT(j->limits->effort, 0);
    EXPECT_GT(j->limits->velocity, 0);
  }
  for (const char* name : {"finger_left_joint", "finger_right_joint"}) {
    const auto j = model->getJoint(name);
    ASSERT_TRUE(j) << name;
    EXPECT_EQ(j->type, urdf::Joint::PRISMATIC);
    EXPECT_EQ(j->parent_link_name, "gripper_base");
    EXPECT_EQ(j->limits->lower, 0);     // closed: the pads touch
    EXPECT_EQ(j->limits->upper, 0.04);  // open: 80 mm between the pads
  }
  // Both fingers open outwards, symmetrically.
  EXPECT_EQ(model->getJoint("finger_left_joint")->axis.y, 1);
  EXPECT_EQ(model->getJoint("finger_right_joint")->axis.y, -1);
}

TEST_P(UrdfFile, EveryBodyHasAPhysicallyValidInertia) {
  ASSERT_TRUE(model);
  for (const auto& [name, link] : model->links_) {
    if (name == "flange" || name == "tcp") continue;  // frames only
    ASSERT_TRUE(link->inertial) << name;
    const urdf::Inertial& in = *link->inertial;
    EXPECT_GT(in.mass, 0) << name;
    Eigen::Matrix3d inertia;
    inertia << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
    const Eigen::Vector3d m = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(inertia).eigenvalues();
    EXPECT_GT(m.minCoeff(), 0) << name;
    // MuJoCo rejects a body whose principal moments break the triangle inequality.
    EXPECT_GE(m[0] + m[1], m[2] * (1 - 1e-9)) << name;
  }
}

TEST_P(UrdfFile, GripperWeighsHalfAKilogram) {
  ASSERT_TRUE(model);
  double mass = 0;
  for (const char* name : {"gripper_base", "finger_left", "finger_right"}) mass += model->getLink(name)->inertial->mass;
  EXPECT_NEAR(mass, 0.5, 1e-9);
}

// The tcp sits on the centre plane between the pads, at the pads' middle, z along the approach direction.
TEST_P(UrdfFile, TcpIsTheGraspPointBetweenThePads) {
  ASSERT_TRUE(model);
  const auto left = model->getLink("finger_left");
  const urdf::Collision* pad = nullptr;
  for (const auto& c : left->collision_array) {
    if (c->name == "finger_left_pad") pad = c.get();
  }
  ASSERT_NE(pad, nullptr) << "finger_left has no collision element named finger_left_pad";
  const double pad_centre_z =
      model->getJoint("finger_left_joint")->parent_to_joint_origin_transform.position.z + pad->origin.position.z;
  const auto& tcp = model->getJoint("tcp_joint")->parent_to_joint_origin_transform;
  EXPECT_EQ(model->getJoint("tcp_joint")->parent_link_name, "gripper_base");
  EXPECT_NEAR(tcp.position.z, pad_centre_z, 1e-12);
  EXPECT_EQ(tcp.position.x, 0);
  EXPECT_EQ(tcp.position.y, 0);
  double r, p, y;
  tcp.rotation.getRPY(r, p, y);
  EXPECT_EQ(r * r + p * p + y * y, 0);
  // The pad's inner face is at the joint position: at 0 the fingers touch, a 45 mm part is held at 22.5 mm.
  const auto* box = dynamic_cast<const urdf::Box*>(pad->geometry.get());
  ASSERT_NE(box, nullptr);
  EXPECT_NEAR(pad->origin.position.y - box->dim.y / 2, 0, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(BothArms, UrdfFile, ::testing::Values("puma560.urdf", "melfa_rve2.urdf"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                           return p.param.substr(0, p.param.find('.'));
                         });

// "The same gripper" in both files: every gripper link and joint is identical.
TEST(UrdfFiles, BothArmsCarryTheSameGripper) {
  const auto puma = load("puma560.urdf"), melfa = load("melfa_rve2.urdf");
  ASSERT_TRUE(puma && melfa);
  auto same_pose = [](const urdf::Pose& a, const urdf::Pose& b) {
    return a.position.x == b.position.x && a.position.y == b.position.y && a.position.z == b.position.z &&
           a.rotation.x == b.rotation.x && a.rotation.y == b.rotation.y && a.rotation.z == b.rotation.z &&
           a.rotation.w == b.rotation.w;
  };
  for (const char* name : {"gripper_base", "finger_left", "finger_right"}) {
    const auto a = puma->getLink(name), b = melfa->getLink(name);
    EXPECT_EQ(a->inertial->mass, b->inertial->mass) << name;
    EXPECT_TRUE(same_pose(a->inertial->origin, b->inertial->origin)) << name;
    EXPECT_EQ(a->inertial->ixx, b->inertial->ixx) << name;
    ASSERT_EQ(a->collision_array.size(), b->collision_array.size()) << name;
    for (std::size_t i = 0; i < a->collision_array.size(); ++i) {
      EXPECT_EQ(a->collision_array[i]->name, b->collision_array[i]->name);
      EXPECT_TRUE(same_pose(a->collision_array[i]->origin, b->collision_array[i]->origin)) << name;
    }
  }
  for (const char* name : {"finger_left_joint", "finger_right_joint", "tcp_joint"}) {
    EXPECT_TRUE(same_pose(puma->getJoint(name)->parent_to_joint_origin_transform,
                          melfa->getJoint(name)->parent_to_joint_origin_transform))
        << name;
  }
}

}  // namespace
}  // namespace cellwright::models
