// Building a KinematicChain from URDF text: urdfdom interprets the robot (the same reader the scene uses), tinyxml2
// supplies the line numbers urdfdom does not report.
#include <console_bridge/console.h>
#include <tinyxml2.h>
#include <urdf_parser/urdf_parser.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>

#include "cellwright/common/error.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::models {
namespace {

// Collects urdfdom's log messages while a parse runs, so they can go into the InputError instead of stderr.
class CapturingHandler : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* /*filename*/, int /*line*/) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_WARN) messages.push_back(text);
  }
  std::vector<std::string> messages;
};

// urdfdom logs through console_bridge's process-wide handler, so parses take turns.
std::mutex& parse_mutex() {
  static std::mutex m;
  return m;
}

// Line of the <link> or <joint> element with this name attribute, 0 if there is none.
struct ElementLines {
  std::map<std::string, int> links, joints;

  int link(const std::string& name) const {
    auto it = links.find(name);
    return it == links.end() ? 0 : it->second;
  }
  int joint(const std::string& name) const {
    auto it = joints.find(name);
    return it == joints.end() ? 0 : it->second;
  }
};

ElementLines index_lines(const tinyxml2::XMLElement* robot) {
  ElementLines lines;
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    const char* name = e->Attribute("name");
    if (name == nullptr) continue;
    if (std::string(e->Name()) == "link") lines.links.emplace(name, e->GetLineNum());
    if (std::string(e->Name()) == "joint") lines.joints.emplace(name, e->GetLineNum());
  }
  return lines;
}

// Best guess at the line an urdfdom message is about: the first link or joint it names.
int line_of_message(const std::string& message, const ElementLines& lines) {
  int best_pos = -1, best_line = 0;
  auto consider = [&](const std::map<std::string, int>& names) {
    for (const auto& [name, line] : names) {
      for (const std::string& quoted : {"[" + name + "]", "'" + name + "'", "\"" + name + "\""}) {
        auto pos = message.find(quoted);
        if (pos != std::string::npos && (best_pos < 0 || static_cast<int>(pos) < best_pos)) {
          best_pos = static_cast<int>(pos);
          best_line = line;
        }
      }
    }
  };
  consider(lines.joints);
  consider(lines.links);
  return best_line;
}

// tinyxml2's error in words, with the element it was reading when it knows it.
std::string describe_xml_error(const tinyxml2::XMLDocument& doc) {
  std::string what;
  switch (doc.ErrorID()) {
    case tinyxml2::XML_ERROR_EMPTY_DOCUMENT:
      return "the file is empty";
    case tinyxml2::XML_ERROR_PARSING_ELEMENT:
      what = "an element cannot be parsed (unclosed or broken tag?)";
      break;
    case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE:
      what = "an attribute cannot be parsed (missing quote or '='?)";
      break;
    case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT:
      what = "a closing tag does not match the open element";
      break;
    case tinyxml2::XML_ERROR_PARSING_COMMENT:
      what = "a comment is not closed";
      break;
    default:
      what = doc.ErrorName();
  }
  // ErrorStr() ends in "...: XMLElement name=<name>" when the element is known.
  const std::string full = doc.ErrorStr() != nullptr ? doc.ErrorStr() : "";
  const std::string key = "XMLElement name=";
  if (auto pos = full.find(key); pos != std::string::npos)
    what += fmt::format(" in <{}>", full.substr(pos + key.size()));
  return what;
}

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
  std::ifstream in(urdf, std::ios::binary);
  if (!in) throw InputError({urdf.string()}, "cannot open the URDF file (missing or unreadable)");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError({urdf.string()}, "cannot read the URDF file");
  return from_urdf_string(text.str(), urdf.string(), base, tip);
}

KinematicChain KinematicChain::from_urdf_string(const std::string& xml, const std::string& file_label,
                                                const std::string& base, const std::string& tip) {
  // Well-formedness first: tinyxml2 knows the line of a syntax error, urdfdom does not.
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) {
    throw InputError({file_label, doc.ErrorLineNum()}, fmt::format("malformed XML: {}", describe_xml_error(doc)));
  }
  const tinyxml2::XMLElement* root = doc.RootElement();
  if (root == nullptr || std::string(root->Name()) != "robot") {
    throw InputError({file_label, root != nullptr ? root->GetLineNum() : 0},
                     fmt::format("the root element is <{}>, a URDF needs <robot>", root ? root->Name() : ""));
  }
  const ElementLines lines = index_lines(root);

  urdf::ModelInterfaceSharedPtr model;
  std::vector<std::string> messages;
  {
    std::lock_guard lock(parse_mutex());
    CapturingHandler handler;
    console_bridge::useOutputHandler(&handler);
    try {
      model = urdf::parseURDF(xml);
    } catch (const std::exception& e) {
      handler.messages.push_back(e.what());
      model.reset();
    }
    console_bridge::restorePreviousOutputHandler();
    messages = std::move(handler.messages);
  }
  if (!model) {
    std::string problem = messages.empty() ? std::string("urdfdom rejected the file") : messages.back();
    int line = 0;
    for (const std::string& m : messages) {
      if ((line = line_of_message(m, lines)) != 0) {
        problem = m;
        break;
      }
    }
    throw InputError({file_label, line}, fmt::format("invalid URDF: {}", problem));
  }

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
      throw InputError({file_label, lines.link(tip)},
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
    const SourceLocation where{file_label, lines.joint(j.name)};
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
      limit = {j.limits->lower, j.limits->upper};
      if (!std::isfinite(limit.lower) || !std::isfinite(limit.upper) || limit.lower > limit.upper) {
        throw InputError(where, fmt::format("joint '{}' has limits lower = {} > upper = {} (or not finite)", j.name,
                                            limit.lower, limit.upper));
      }
    }
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
    throw InputError({file_label, lines.link(tip)},
                     fmt::format("no revolute, continuous or prismatic joint between links '{}' and '{}'", base, tip));
  }
  chain.tip_offset_ = pending;
  chain.max_reach_ = reach + pending.translation().norm();
  chain.find_spherical_wrist();
  return chain;
}

}  // namespace cellwright::models
