// A cell's robot as the cell mounts it (robot_model.hpp): its URDF, the gripper on its flange, its chain.
#include "cellwright/models/robot_model.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <system_error>
#include <vector>

namespace cellwright::models {
namespace {

// Whether link `descendant` lies at or below link `ancestor`.
bool at_or_below(const urdf::ModelInterface& robot, const std::string& descendant, const std::string& ancestor) {
  for (auto link = robot.getLink(descendant); link; link = link->getParent()) {
    if (link->name == ancestor) return true;
  }
  return false;
}

// The pose of `link` in the frame of its ancestor `ancestor`, through fixed joints only; false if a joint on the way
// moves.
bool fixed_pose(const urdf::ModelInterface& robot, const std::string& link, const std::string& ancestor,
                Eigen::Isometry3d& pose) {
  pose = Eigen::Isometry3d::Identity();
  for (auto l = robot.getLink(link); l && l->name != ancestor; l = l->getParent()) {
    const urdf::Joint& j = *l->parent_joint;
    if (j.type != urdf::Joint::FIXED) return false;
    const urdf::Pose& p = j.parent_to_joint_origin_transform;
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
    t.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().matrix();
    pose = t * pose;
  }
  return true;
}

}  // namespace

std::filesystem::path gripper_urdf() {
  return std::filesystem::path(models_dir()) / "urdf" / "gripper.urdf";
}

MountedRobot load_robot(const RobotSpec& spec) {
  MountedRobot out{load_urdf_file(spec.urdf), std::nullopt};
  const urdf::ModelInterface& arm = out.arm.robot();
  const std::string file = spec.urdf.string();
  auto need_link = [&](const std::string& link, const char* role) {
    if (!arm.getLink(link)) {
      throw InputError({file}, fmt::format("robot '{}': the URDF has no link '{}' (its {}; the URDF's links: {})",
                                           spec.name, link, role, [&] {
                                             std::vector<std::string> names;
                                             for (const auto& [name, l] : arm.links_) names.push_back(name);
                                             return fmt::format("{}", fmt::join(names, ", "));
                                           }()));
    }
  };
  need_link(spec.base_link, "base_link");
  need_link(spec.flange_link, "flange_link");
  if (!at_or_below(arm, spec.flange_link, spec.base_link)) {
    throw InputError(out.arm.link_at(spec.flange_link),
                     fmt::format("robot '{}': link '{}' (the flange) is not below link '{}' (the base)", spec.name,
                                 spec.flange_link, spec.base_link));
  }
  // Links above the base (a `world` root) are left out of the cell: they must not move the base.
  Eigen::Isometry3d unused;
  if (!fixed_pose(arm, spec.base_link, arm.getRoot()->name, unused)) {
    throw InputError(out.arm.link_at(spec.base_link),
                     fmt::format("robot '{}': a movable joint lies between the URDF's root link '{}' and its base "
                                 "link '{}'; the base must be fixed",
                                 spec.name, arm.getRoot()->name, spec.base_link));
  }
  if (spec.gripper == GripperKind::kCellwright) {
    out.gripper = load_urdf_file(gripper_urdf());
    const urdf::ModelInterface& g = out.gripper->robot();
    for (const auto& [name, link] : g.links_) {
      if (arm.getLink(name)) {
        throw InputError(out.arm.link_at(name),
                         fmt::format("robot '{}': a gripper is mounted on '{}', so the URDF must not have a link named "
                                     "'{}' (the gripper's)",
                                     spec.name, spec.flange_link, name));
      }
    }
    for (const auto& [name, joint] : g.joints_) {
      if (arm.getJoint(name)) {
        throw InputError(out.arm.joint_at(name),
                         fmt::format("robot '{}': a gripper is mounted on '{}', so the URDF must not have a joint "
                                     "named '{}' (the gripper's)",
                                     spec.name, spec.flange_link, name));
      }
    }
  } else {
    need_link(spec.tool_link, "tool_link");
    if (!at_or_below(arm, spec.tool_link, spec.flange_link)) {
      throw InputError(out.arm.link_at(spec.tool_link),
                       fmt::format("robot '{}': link '{}' (the tool) is not below link '{}' (the flange)", spec.name,
                                   spec.tool_link, spec.flange_link));
    }
  }
  return out;
}

KinematicChain robot_chain(const RobotSpec& spec) {
  return robot_chain(spec, load_robot(spec));
}

KinematicChain robot_chain(const RobotSpec& spec, const MountedRobot& robot) {
  if (!robot.gripper) return KinematicChain::from_urdf(robot.arm, spec.base_link, spec.tool_link);
  const urdf::ModelInterface& g = robot.gripper->robot();
  Eigen::Isometry3d tool;
  const bool fixed = fixed_pose(g, "tcp", g.getRoot()->name, tool);
  CW_CHECK(fixed, "the gripper model {} has a movable joint between its root and tcp", robot.gripper->file());
  return KinematicChain::from_urdf(robot.arm, spec.base_link, spec.flange_link).mounted(tool, "tcp");
}

std::filesystem::path resolve_mesh(const std::string& uri, const RobotSpec& spec, const std::filesystem::path& urdf,
                                   const SourceLocation& where) {
  std::error_code ec;
  auto exists = [&](const std::filesystem::path& p) { return std::filesystem::is_regular_file(p, ec); };
  std::filesystem::path path;
  const std::string package = "package://", file = "file://";
  if (uri.rfind(package, 0) == 0) {
    const std::string rest = uri.substr(package.size());
    const auto slash = rest.find('/');
    const std::string name = rest.substr(0, slash);
    const std::string inside = slash == std::string::npos ? std::string() : rest.substr(slash + 1);
    for (const auto& dir : spec.package_path) {
      if (!name.empty() && std::filesystem::is_directory(dir / name, ec)) {
        path = (dir / name / inside).lexically_normal();
        break;
      }
    }
    if (path.empty()) {
      std::vector<std::string> dirs;
      for (const auto& d : spec.package_path) dirs.push_back(d.string());
      throw InputError(where, fmt::format("robot '{}': mesh '{}': unknown package '{}' (package_path: {}; set the "
                                          "robot's package_path to the directory that holds it)",
                                          spec.name, uri, name, dirs.empty() ? "none" : fmt::format("{}", fmt::join(dirs, ", "))));
    }
  } else if (uri.rfind(file, 0) == 0) {
    path = uri.substr(file.size());
  } else if (uri.find("://") != std::string::npos) {
    throw InputError(where, fmt::format("robot '{}': mesh '{}': unsupported URI scheme (package:// and file:// and "
                                        "paths are)",
                                        spec.name, uri));
  } else {
    path = std::filesystem::path(uri).is_absolute() ? std::filesystem::path(uri) : urdf.parent_path() / uri;
  }
  if (!exists(path)) {
    throw InputError(where, fmt::format("robot '{}': mesh '{}': no file {}", spec.name, uri, path.string()));
  }
  return path;
}

}  // namespace cellwright::models
