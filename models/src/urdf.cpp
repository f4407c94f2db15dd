// The one URDF loader (urdf.hpp): urdfdom interprets the robot, tinyxml2 supplies the line numbers urdfdom does not
// report.
#include "cellwright/models/urdf.hpp"

#include <console_bridge/console.h>
#include <tinyxml2.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <map>
#include <mutex>
#include <vector>

#include "cellwright/common/files.hpp"

namespace cellwright::models {
namespace {

// Collects urdfdom's log messages while a parse runs, so they can go into the InputError instead of stderr.
class CapturingHandler : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* /*filename*/, int /*line*/) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_WARN) messages.push_back(text);
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) errors.push_back(text);
  }
  std::vector<std::string> messages;
  std::vector<std::string> errors;  // urdfdom may log an error and still return a robot (a number it cannot read)
};

// urdfdom logs through console_bridge's process-wide handler, so parses take turns.
std::mutex& parse_mutex() {
  static std::mutex m;
  return m;
}

// The line of each <mesh> element below `e` by its filename attribute (the first of each).
void index_meshes(const tinyxml2::XMLElement* e, std::map<std::string, int>& meshes) {
  for (const tinyxml2::XMLElement* c = e->FirstChildElement(); c != nullptr; c = c->NextSiblingElement()) {
    if (std::string(c->Name()) == "mesh" && c->Attribute("filename") != nullptr) {
      meshes.emplace(c->Attribute("filename"), c->GetLineNum());
    }
    index_meshes(c, meshes);
  }
}

// The line of each <link> and <joint> element by its name attribute, and of each link's <inertial>, <visual> and
// <collision> elements in order (of the first <link> of a name: urdfdom refuses a second one).
void index_lines(const tinyxml2::XMLElement* robot, std::map<std::string, int>& links,
                 std::map<std::string, int>& joints,
                 std::map<std::string, std::map<std::string, std::vector<int>>>& parts) {
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    const char* name = e->Attribute("name");
    if (name == nullptr) continue;
    if (std::string(e->Name()) == "link" && links.emplace(name, e->GetLineNum()).second) {
      for (const tinyxml2::XMLElement* p = e->FirstChildElement(); p != nullptr; p = p->NextSiblingElement()) {
        parts[name][p->Name()].push_back(p->GetLineNum());
      }
    }
    if (std::string(e->Name()) == "joint") joints.emplace(name, e->GetLineNum());
  }
}

// Best guess at the line an urdfdom message is about: the first link or joint it names.
int line_of_message(const std::string& message, const std::map<std::string, int>& links,
                    const std::map<std::string, int>& joints) {
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
  consider(joints);
  consider(links);
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

int line_in(const std::map<std::string, int>& lines, const std::string& name) {
  auto it = lines.find(name);
  return it == lines.end() ? 0 : it->second;
}

// urdfdom accepts a joint whose parent is its child, a link that is the child of two joints (the last one wins) and
// a loop of joints; a walk along the links would then never end. And its links hold their children by shared_ptr: on
// a loop they hold each other and are never freed, even when urdfdom itself then refuses the file for want of a root
// (found by tests/fuzz/urdf_fuzz under LeakSanitizer, twice: after urdfdom accepted a loop, and after it refused one).
// So the joints' parents and children are read from the XML (as urdfdom reads them: each <joint name> directly under
// <robot>, its first <parent link> and <child link>) and a file that is not a tree is refused at the joint that breaks
// it before urdfdom sees it. Joints without those are left to urdfdom, which refuses them before it links anything.
void check_tree(const tinyxml2::XMLElement* robot, const std::string& file) {
  struct Joint {
    std::string parent, child;
    int line = 0;
  };
  std::map<std::string, Joint> joints;  // by name, the order urdfdom keeps them in
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    const tinyxml2::XMLElement* parent = e->FirstChildElement("parent");
    const tinyxml2::XMLElement* child = e->FirstChildElement("child");
    const char* name = e->Attribute("name");
    const char* parent_link = parent != nullptr ? parent->Attribute("link") : nullptr;
    const char* child_link = child != nullptr ? child->Attribute("link") : nullptr;
    if (name == nullptr || parent_link == nullptr || child_link == nullptr) continue;
    joints.emplace(name, Joint{parent_link, child_link, e->GetLineNum()});
  }
  std::map<std::string, const std::string*> parent_joint;  // child link -> the name of its joint
  for (const auto& [name, joint] : joints) {
    if (joint.child == joint.parent) {
      throw InputError({file, joint.line},
                       fmt::format("joint '{}' has link '{}' as both its parent and its child", name, joint.child));
    }
    const auto [it, first] = parent_joint.emplace(joint.child, &name);
    if (!first) {
      throw InputError({file, joint.line},
                       fmt::format("link '{}' is the child of joints '{}' and '{}'; a URDF is a tree, each link has "
                                   "one parent",
                                   joint.child, *it->second, name));
    }
  }
  // One parent each: a link whose parents do not end at the root within as many steps as there are links is on a loop.
  for (const auto& start : parent_joint) {
    const std::string* name = start.second;
    for (std::size_t steps = 0; name != nullptr; ++steps) {
      const Joint& joint = joints.at(*name);
      if (steps > parent_joint.size()) {
        throw InputError({file, joint.line},
                         fmt::format("joint '{}' closes a loop of joints through link '{}'; a URDF is a tree", *name,
                                     joint.child));
      }
      const auto up = parent_joint.find(joint.parent);
      name = up == parent_joint.end() ? nullptr : up->second;
    }
  }
}

// A link's <inertial> must describe a body that can exist: a mass that is finite and not negative (urdfdom reads
// "-40" as it is, and MuJoCo would take it), and an inertia tensor whose entries are finite and whose principal
// moments are not negative and satisfy the triangle inequality (each at most the sum of the other two), as every
// rigid body's do. The moments are compared with a tolerance of 1e-6 of their sum, for the rounding of CAD exports.
void check_inertials(const urdf::ModelInterface& robot, const std::map<std::string, int>& links,
                     const std::string& file) {
  for (const auto& [name, link] : robot.links_) {
    if (!link || !link->inertial) continue;
    const urdf::Inertial& in = *link->inertial;
    const SourceLocation at{file, line_in(links, name)};
    if (!std::isfinite(in.mass) || in.mass < 0) {
      throw InputError(at, fmt::format("link '{}': mass {} kg is not physical: a mass must be finite and not negative",
                                       name, in.mass));
    }
    const double entries[] = {in.ixx, in.ixy, in.ixz, in.iyy, in.iyz, in.izz};
    const auto tensor = [&] {
      return fmt::format("ixx {} ixy {} ixz {} iyy {} iyz {} izz {}", in.ixx, in.ixy, in.ixz, in.iyy, in.iyz, in.izz);
    };
    for (const double e : entries) {
      if (!std::isfinite(e)) {
        throw InputError(at, fmt::format("link '{}': the inertia ({}) is not finite", name, tensor()));
      }
    }
    Eigen::Matrix3d inertia;
    inertia << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
    const Eigen::Vector3d m = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(inertia, Eigen::EigenvaluesOnly)
                                  .eigenvalues();  // ascending
    const double tolerance = 1e-6 * std::abs(m.sum()) + 1e-12;
    if (m[0] < -tolerance) {
      throw InputError(at, fmt::format("link '{}': the inertia ({}) is not physical: its principal moments {:.6g}, "
                                       "{:.6g}, {:.6g} must not be negative",
                                       name, tensor(), m[0], m[1], m[2]));
    }
    if (m[2] > m[0] + m[1] + tolerance) {
      throw InputError(at, fmt::format("link '{}': the inertia ({}) is not physical: its principal moments {:.6g}, "
                                       "{:.6g}, {:.6g} break the triangle inequality ({:.6g} is more than the sum of "
                                       "the other two)",
                                       name, tensor(), m[0], m[1], m[2], m[2]));
    }
  }
}

}  // namespace

SourceLocation UrdfModel::link_at(const std::string& name) const {
  return {file_, line_in(link_lines_, name)};
}

SourceLocation UrdfModel::joint_at(const std::string& name) const {
  return {file_, line_in(joint_lines_, name)};
}

SourceLocation UrdfModel::mesh_at(const std::string& filename) const {
  return {file_, line_in(mesh_lines_, filename)};
}

SourceLocation UrdfModel::link_part_at(const std::string& link, const std::string& tag, std::size_t index) const {
  if (const auto l = link_part_lines_.find(link); l != link_part_lines_.end()) {
    if (const auto t = l->second.find(tag); t != l->second.end() && index < t->second.size()) {
      return {file_, t->second[index]};
    }
  }
  return link_at(link);
}

UrdfModel load_urdf_file(const std::filesystem::path& file) {
  std::string text;
  try {
    text = read_file(file);
  } catch (const InputError& e) {
    throw InputError({file.string()}, fmt::format("cannot read the URDF file: {}", e.problem()));
  }
  // A run reads each robot's URDF many times (its chain for task control, robot control, the plan and the sweep; its
  // scene): a file whose text was parsed before under the same name is not parsed again. Keyed by the text itself,
  // so an edited file is parsed afresh; errors are not kept (they are thrown again on the next load).
  static std::mutex cache_mutex;
  static std::map<std::pair<std::string, std::string>, UrdfModel> cache;
  constexpr std::size_t kCacheSize = 16;
  std::pair<std::string, std::string> key{file.string(), std::move(text)};
  {
    const std::lock_guard lock(cache_mutex);
    if (const auto it = cache.find(key); it != cache.end()) return it->second;
  }
  UrdfModel parsed = parse_urdf(key.second, key.first);
  const std::lock_guard lock(cache_mutex);
  if (cache.size() >= kCacheSize) cache.clear();
  cache.emplace(std::move(key), parsed);
  return parsed;
}

UrdfModel parse_urdf(const std::string& xml, const std::string& file_label) {
  UrdfModel out;
  out.file_ = file_label;
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
  index_lines(root, out.link_lines_, out.joint_lines_, out.link_part_lines_);
  index_meshes(root, out.mesh_lines_);
  check_tree(root, file_label);

  urdf::ModelInterfaceSharedPtr model;
  std::vector<std::string> messages, errors;
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
    errors = std::move(handler.errors);
  }
  // urdfdom drops an <inertial> whose numbers it cannot read ("mass [nan] is not a float"), logs an error and returns
  // the robot without it: a robot that is not the file's, so it is refused as one it could not read.
  if (model && !errors.empty()) {
    model.reset();
    messages = errors;
  }
  if (!model) {
    std::string problem = messages.empty() ? std::string("urdfdom rejected the file") : messages.back();
    int line = 0;
    for (std::size_t i = 0; i < messages.size(); ++i) {
      if ((line = line_of_message(messages[i], out.link_lines_, out.joint_lines_)) != 0) {
        // The message that names the element, after the one that says what is wrong in it, if that came first
        // ("Inertial: mass [nan] is not a float", then "Could not parse inertial element for Link [l1]").
        problem = i > 0 ? fmt::format("{}: {}", messages[i], messages[i - 1]) : messages[i];
        break;
      }
    }
    throw InputError({file_label, line}, fmt::format("invalid URDF: {}", problem));
  }
  check_inertials(*model, out.link_lines_, file_label);
  out.robot_ = std::move(model);
  return out;
}

}  // namespace cellwright::models
