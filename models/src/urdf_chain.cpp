// Building a KinematicChain from a URDF robot read by the one URDF loader (urdf.hpp), which the scene uses too.
#include <cmath>
#include <limits>

#include "cellwright/common/error.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/urdf.hpp"

namespace cellwright::models {
namespace {

Eigen::Isometry3d to_isometry(const urdf::Pose& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  Eigen::Quaterniond r(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z);
  t.linear() = r.normalized().toRotationMatrix();
  return t;
}

const char* joint_type_name(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE:
      return "revolute";
    case urdf::Joint::CONTINUOUS:
      return "continuous";
    case urdf::Joint::PRISMATIC:
      return "prismatic";
    case urdf::Joint::FLOATING:
      return "floating";
    case urdf::Joint::PLANAR:
      return "planar";
    case urdf::Joint::FIXED:
      return "fixed";
    default:
      return "unknown";
  }
}

}  // namespace

KinematicChain KinematicChain::from_urdf_file(const std::filesystem::path& urdf, const std::string& base,
                                              const std::string& tip) {
  return from_urdf(load_urdf_file(urdf), base, tip);
}

KinematicChain KinematicChain::from_urdf_string(const std::string& xml, const std::string& file_label,
                                                const std::string& base, const std::string& tip) {
  return from_urdf(parse_urdf(xml, file_label), base, tip);
}

KinematicChain KinematicChain::from_urdf(const UrdfModel& loaded, const std::string& base, const std::string& tip) {
  const std::string& file_label = loaded.file();
  const urdf::ModelInterface* model = &loaded.robot();
  if (!model->getLink(base)) {
    throw InputError({file_label},
                     fmt::format("robot '{}' has no link named '{}' (the chain's base)", model->getName(), base));
  }
  if (!model->getLink(tip)) {
    throw InputError({file_label},
                     fmt::format("robot '{}' has no link named '{}' (the chain's tip)", model->getName(), tip));
  }

  // Walk up from the tip to the base, then turn the path around.
  std::vector<urdf::JointConstSharedPtr> path;
  for (urdf::LinkConstSharedPtr link = model->getLink(tip); link->name != base;) {
    if (!link->parent_joint) {
      throw InputError(loaded.link_at(tip),
                       fmt::format("link '{}' is not a descendant of link '{}': no chain from base to tip", tip, base));
    }
    path.push_back(link->parent_joint);
    link = model->getLink(link->parent_joint->parent_link_name);
    CW_CHECK(link != nullptr, "urdfdom returned joint '{}' without its parent link", path.back()->name);
  }

  KinematicChain chain;
  chain.base_ = base;
  chain.tip_ = tip;
  Eigen::Isometry3d pending = Eigen::Isometry3d::Identity();  // fixed transforms since the last movable joint
  double reach = 0;
  for (auto it = path.rbegin(); it != path.rend(); ++it) {
    const urdf::Joint& j = **it;
    const SourceLocation where = loaded.joint_at(j.name);
    const Eigen::Isometry3d origin = to_isometry(j.parent_to_joint_origin_transform);
    if (!origin.matrix().allFinite())
      throw InputError(where, fmt::format("joint '{}' has a non-finite origin", j.name));
    if (j.type == urdf::Joint::FIXED) {
      pending = pending * origin;
      continue;
    }
    if (j.type != urdf::Joint::REVOLUTE && j.type != urdf::Joint::CONTINUOUS && j.type != urdf::Joint::PRISMATIC) {
      throw InputError(where, fmt::format("joint '{}' is {}; a kinematic chain takes only fixed, revolute, continuous "
                                          "and prismatic joints",
                                          j.name, joint_type_name(j.type)));
    }
    if (j.mimic) {
      throw InputError(where, fmt::format("joint '{}' mimics '{}'; mimic joints are not supported in a kinematic chain",
                                          j.name, j.mimic->joint_name));
    }
    const Eigen::Vector3d axis(j.axis.x, j.axis.y, j.axis.z);
    if (!axis.allFinite() || axis.norm() < 1e-9) {
      throw InputError(where, fmt::format("joint '{}' has a zero or non-finite axis ({} {} {})", j.name, axis.x(),
                                          axis.y(), axis.z()));
    }
    JointLimit limit{-std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
    if (j.type != urdf::Joint::CONTINUOUS) {
      if (!j.limits) throw InputError(where, fmt::format("joint '{}' has no <limit>", j.name));
      limit.lower = j.limits->lower;
      limit.upper = j.limits->upper;
      if (!std::isfinite(limit.lower) || !std::isfinite(limit.upper) || limit.lower > limit.upper) {
        throw InputError(where, fmt::format("joint '{}' has limits lower = {} > upper = {} (or not finite)", j.name,
                                            limit.lower, limit.upper));
      }
    }
    if (j.limits) limit.velocity = j.limits->velocity;
    const Eigen::Isometry3d joint_origin = pending * origin;
    if (chain.joints_.empty()) {
      chain.first_joint_origin_ = joint_origin.translation();
    } else {
      reach += joint_origin.translation().norm();
    }
    if (j.type == urdf::Joint::PRISMATIC) reach += std::max(std::abs(limit.lower), std::abs(limit.upper));
    chain.joints_.push_back({joint_origin, axis.normalized(), j.type == urdf::Joint::PRISMATIC});
    chain.names_.push_back(j.name);
    chain.limits_.push_back(limit);
    pending = Eigen::Isometry3d::Identity();
  }
  if (chain.joints_.empty()) {
    throw InputError(loaded.link_at(tip),
                     fmt::format("no revolute, continuous or prismatic joint between links '{}' and '{}'", base, tip));
  }
  chain.tip_offset_ = pending;
  chain.max_reach_ = reach + pending.translation().norm();
  chain.find_spherical_wrist();
  return chain;
}

KinematicChain KinematicChain::mounted(const Eigen::Isometry3d& tool, const std::string& tip) const {
  KinematicChain out = *this;
  out.tip_ = tip;
  out.max_reach_ = max_reach_ - tip_offset_.translation().norm();
  out.tip_offset_ = tip_offset_ * tool;
  out.max_reach_ += out.tip_offset_.translation().norm();
  out.find_spherical_wrist();
  return out;
}

}  // namespace cellwright::models
