// The MuJoCo scene of a cell (scene.hpp). MuJoCo 2.2.2 has no model-editing API (mjSpec, attach) and compiles one
// URDF at a time, so the whole cell is written here as one MJCF text: robots from their URDFs (read with the one URDF
// loader, models/urdf.hpp), conveyors, machines, workpieces, cameras and lights; then compiled from memory through
// MuJoCo's virtual file system.
#include "cellwright/twin/scene.hpp"

#include <tinyxml2.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

#include <fmt/ranges.h>

#include "cellwright/common/xml.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/models/urdf.hpp"
#include "cellwright/twin/mesh_import.hpp"

namespace cellwright::twin {

namespace {

// --- Servo tuning ------------------------------------------------------------------------------------------------
// Position servos are PD controllers (MuJoCo 2.2.2 has no gravity compensation), so a joint sags under gravity by
// torque / kp. kp is chosen per joint from an upper bound of the gravity torque on it, so that the sag stays under
// kSagBound everywhere in the workspace with kPayload in the hand. Armature (the reflected inertia of the geared
// motor, which real arms have) keeps each servo's natural frequency under kOmegaStep / timestep so that the
// explicit position feedback stays stable whatever the link inertia; damping makes the servo about critically damped.
constexpr double kGravity = 9.81;
constexpr double kSagBound = 0.004;       // rad
constexpr double kPayload = 1.0;          // kg, at the tool centre point
constexpr double kKpMin = 100.0;          // N m / rad
constexpr double kOmegaStep = 0.3;        // rad per timestep at the servo's natural frequency
constexpr double kFingerSqueeze = 0.002;  // m of squeeze at which a finger reaches its grip force
constexpr double kFingerOmegaFactor = 2.0;  // the fingers' natural frequency bound, times the arm servos'

// --- Buffers ------------------------------------------------------------------------------------------------------
constexpr int kNjmax = 500;    // constraint rows (see the <size> element below)
constexpr int kNconmax = 200;  // contacts

// --- Conveyor belts -------------------------------------------------------------------------------------------
// The belt is a body sliding along the conveyor, driven by a velocity servo; its friction carries the parts. It is
// kBeltWrap longer than the conveyor and moves back by kBeltWrap after running that far (Scene::wrap_belts): its flat
// top is the same before and after, so parts resting on it do not notice.
constexpr double kBeltThickness = 0.01;
constexpr double kBeltWrap = 0.05;
// Collision bits: geoms collide when (contype & other's conaffinity) or the reverse is non-zero. Everything has the
// default bit 1; the moving belts have only bit 2, workpieces both. So parts ride on the belts, while robots meet the
// conveyor's static frame instead: the belt's collision box reaches kBeltWrap beyond the conveyor's upstream end,
// where a gripper putting a part down at the belt's start would otherwise hit something invisible.
constexpr const char* kBeltBits = "2";
constexpr const char* kPartBits = "3";
constexpr double kFrameGap = 0.002;  // m between the frame's top and the belt's top
constexpr double kGuideThickness = 0.01;  // m, of a conveyor's side guides
constexpr double kBeltMass = 2.0;
// The belt's speed servo, force = kv (ctrl - v), is split into joint damping kv (which the Euler integrator treats
// implicitly: as an actuator's velocity gain it would be explicit, and kv h / mass = 5 at a 5 ms step oscillates) and a
// motor force kv ctrl: the same law, stable at any step.
constexpr double kBeltKv = 2000.0;  // N / (m/s): 1 N of drag slows the belt by 0.5 mm/s
// Parts on the belt: an accumulating conveyor's low-friction belt. A part pushed against the stop by the belt's
// friction F = mu m g at its bottom, the stop pushing back up to its 40 mm top, tips when mu x 40 mm exceeds half
// the part's 40 mm width: with mu = 1 the parts rocked at the stop (about 0.4 mm up and down at a 2 ms step, 1 mm at
// 5 ms). 0.3 keeps them standing; it still takes a fed part to belt speed within 20 ms.
const char* const kBeltFriction = "0.3 0.005 0.0001";
constexpr double kPedestalSide = models::kPedestalSide;

const char* const kPadFriction = "1 0.005 0.0001";  // sliding, torsional, rolling (facts.md: grasps hold with these)
// Gripper pads and parts: contacts twice as stiff as MuJoCo's default and nearly hard once touching, so that a part
// sits in the fingers within half a millimetre of where they close on it.
const char* const kGripSolref = "0.01 1";
const char* const kGripSolimp = "0.95 0.99 0.001";

// --- Numbers in MJCF ----------------------------------------------------------------------------------------------

std::string num(double v) {
  if (std::abs(v) < 1e-12) v = 0;  // no "-0" or 1e-17 noise in the file
  return fmt::format("{}", v);     // the shortest text that reads back as the same double
}
std::string nums(std::initializer_list<double> v) {
  std::string s;
  for (double x : v) s += (s.empty() ? "" : " ") + num(x);
  return s;
}
std::string vec(const Eigen::Vector3d& v) {
  return nums({v.x(), v.y(), v.z()});
}
std::string quat(const Eigen::Quaterniond& q) {
  return nums({q.w(), q.x(), q.y(), q.z()});
}
std::string quat(const Eigen::Matrix3d& r) {
  return quat(Eigen::Quaterniond(r).normalized());
}
std::string rgba(const Eigen::Vector4d& c) {
  return nums({c[0], c[1], c[2], c[3]});
}

using Attrs = xml::Attributes;

// --- URDF ------------------------------------------------------------------------------------------------------

Eigen::Vector3d to_eigen(const urdf::Vector3& v) {
  return {v.x, v.y, v.z};
}
Eigen::Quaterniond to_eigen(const urdf::Rotation& r) {
  return Eigen::Quaterniond(r.w, r.x, r.y, r.z).normalized();
}
Eigen::Isometry3d to_eigen(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = to_eigen(p.rotation).toRotationMatrix();
  t.translation() = to_eigen(p.position);
  return t;
}

bool movable(const urdf::Joint& j) {
  return j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::CONTINUOUS || j.type == urdf::Joint::PRISMATIC;
}

// A link of a robot as the scene writes it: from the robot's URDF or from the gripper mounted on its flange.
struct RobotLink {
  const urdf::Link* link = nullptr;
  const models::UrdfModel* model = nullptr;  // the file it comes from, for errors
};

struct RobotModel {
  const models::RobotSpec* spec = nullptr;
  std::optional<models::MountedRobot> mounted;  // read by the one URDF loader
  const urdf::ModelInterface* urdf = nullptr;   // the robot's URDF (mounted->arm)
  const urdf::ModelInterface* hand = nullptr;   // the model holding the fingers and the tool link
  std::vector<std::string> arm_joints;          // movable joints from the base link to the tool link
  std::set<std::string> finger_links;
  std::string left_finger_link;
  std::string tool_link;  // the link that carries the "<robot>/tcp" site

  // The file a joint of the robot as mounted comes from: the robot's URDF or the gripper's.
  const models::UrdfModel& joint_model(const urdf::Joint& j) const {
    return urdf->getJoint(j.name).get() == &j ? mounted->arm : mounted->hand();
  }
  // The file a link of the robot as mounted comes from.
  const models::UrdfModel& link_model(const std::string& name) const {
    const RobotLink l = link(name);
    return l.model != nullptr ? *l.model : mounted->arm;
  }
  // The link named `name` of the robot as mounted.
  RobotLink link(const std::string& name) const {
    if (auto l = urdf->getLink(name)) return {l.get(), &mounted->arm};
    if (mounted->gripper) {
      if (auto l = hand->getLink(name)) return {l.get(), &*mounted->gripper};
    }
    return {};
  }
  // The links fixed or jointed to `parent`, with their joints (nullptr: the gripper's root, fixed to the flange).
  std::vector<std::pair<const urdf::Joint*, RobotLink>> children(const urdf::Link& parent) const {
    std::vector<std::pair<const urdf::Joint*, RobotLink>> out;
    for (const auto& j : parent.child_joints) {
      const RobotLink child = link(j->child_link_name);
      CW_CHECK(child.link != nullptr, "URDF joint {} without child link", j->name);
      out.emplace_back(j.get(), child);
    }
    if (mounted->gripper && parent.name == spec->flange_link && urdf->getLink(parent.name).get() == &parent) {
      out.emplace_back(nullptr, RobotLink{hand->getRoot().get(), &*mounted->gripper});
    }
    return out;
  }
};

RobotModel read_robot_model(const models::RobotSpec& spec) {
  RobotModel r;
  r.spec = &spec;
  const std::string file = spec.urdf.string();
  auto fail = [&](const std::string& problem) -> InputError {
    return InputError({file, 0, 0}, fmt::format("robot '{}': {}", spec.name, problem));
  };
  try {
    r.mounted = models::load_robot(spec);
  } catch (const InputError& e) {
    throw InputError(e.where(), fmt::format("robot '{}': not a usable URDF file: {}", spec.name, e.problem()));
  }
  r.urdf = &r.mounted->arm.robot();
  r.hand = &r.mounted->hand().robot();
  r.tool_link = r.mounted->gripper ? "tcp" : spec.tool_link;
  const models::UrdfModel& hand = r.mounted->hand();
  for (const char* joint : {"finger_left_joint", "finger_right_joint"}) {
    auto j = r.hand->getJoint(joint);
    if (!j || j->type != urdf::Joint::PRISMATIC || !j->limits) {
      throw InputError(hand.joint_at(joint),
                       fmt::format("robot '{}': the URDF needs a prismatic joint '{}' with limits (the gripper's "
                                   "fingers), or the cell's 'gripper: cellwright' to mount the project's gripper",
                                   spec.name, joint));
    }
    r.finger_links.insert(j->child_link_name);
  }
  r.left_finger_link = r.hand->getJoint("finger_left_joint")->child_link_name;
  auto left = r.hand->getJoint("finger_left_joint")->limits;
  auto right = r.hand->getJoint("finger_right_joint")->limits;
  if (left->lower != right->lower || left->upper != right->upper || !(left->upper > left->lower)) {
    throw fail("finger_left_joint and finger_right_joint must have the same travel (lower < upper)");
  }
  r.arm_joints = models::robot_chain(spec, *r.mounted).joint_names();
  if (r.arm_joints.size() != spec.home.size()) {
    throw InputError(spec.where, fmt::format("robot '{}': 'home' has {} angles but {} has {} joints from {} to {}",
                                             spec.name, spec.home.size(), file, r.arm_joints.size(), spec.base_link,
                                             r.tool_link));
  }
  for (const models::UrdfModel* model : {static_cast<const models::UrdfModel*>(&r.mounted->arm), &hand}) {
    for (const auto& [name, joint] : model->robot().joints_) {
      if (joint->mimic) {
        throw InputError(model->joint_at(name),
                         fmt::format("robot '{}': joint '{}' is a mimic joint; the scene drives every joint",
                                     spec.name, name));
      }
      if (joint->type == urdf::Joint::FLOATING || joint->type == urdf::Joint::PLANAR) {
        throw InputError(model->joint_at(name),
                         fmt::format("robot '{}': joint '{}' is floating or planar; only fixed, revolute, continuous "
                                     "and prismatic joints are supported",
                                     spec.name, name));
      }
    }
  }
  return r;
}

// Upper bounds, over all configurations, of the gravity load on a joint and of the inertia it moves: every link
// below the joint is taken at the largest distance from the joint's axis the chain allows (the sum of the joint
// offsets on the way, plus its centre of gravity's offset).
struct LoadBound {
  double torque = 0;   // N m (revolute) or N (prismatic)
  double inertia = 0;  // kg m^2 (revolute) or kg (prismatic)
};

// The mass of a link that has none in its URDF, as MuJoCo computed it from the link's collision geometry (see
// Builder::massless): body name -> mass, centre of mass in the body frame, half the trace of the inertia there.
struct LinkMass {
  double mass = 0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  double half_trace = 0;
};
using LinkMasses = std::map<std::string, LinkMass>;

void accumulate_load(const RobotModel& robot, const LinkMasses& estimated, const urdf::Link& link, double reach,
                     bool prismatic, LoadBound& b) {
  auto add = [&](double mass, const Eigen::Vector3d& com, double half_trace) {
    const double r = reach + com.norm();
    b.torque += mass * kGravity * (prismatic ? 1.0 : r);
    b.inertia += prismatic ? mass : mass * r * r + half_trace;
  };
  if (link.inertial) {
    const auto& in = *link.inertial;
    add(in.mass, to_eigen(in.origin.position), 0.5 * (in.ixx + in.iyy + in.izz));
  } else if (auto it = estimated.find(robot.spec->name + "/" + link.name); it != estimated.end()) {
    add(it->second.mass, it->second.com, it->second.half_trace);
  }
  if (link.name == robot.tool_link) {
    b.torque += kPayload * kGravity * (prismatic ? 1.0 : reach);
    b.inertia += prismatic ? kPayload : kPayload * reach * reach;
  }
  for (const auto& [j, child] : robot.children(link)) {
    const double offset = j != nullptr ? to_eigen(j->parent_to_joint_origin_transform.position).norm() : 0.0;
    accumulate_load(robot, estimated, *child.link, reach + offset, prismatic, b);
  }
}

// --- The cell's MJCF -------------------------------------------------------------------------------------------

// Where an element of the generated MJCF comes from in the user's files: an element of a robot's URDF (or of the
// gripper mounted on it), or the robot's entry in the cell file, so that what MuJoCo says about the element names
// those (compile_mjcf) rather than a line of a file the user never wrote.
struct Origin {
  SourceLocation at;  // the URDF's file and the line of the element; or the robot's entry in the cell file
  std::string what;   // "link 'link3' (its <inertial>)", "joint 'joint2'", "mesh 'meshes/base.stl'"
  const models::RobotSpec* robot = nullptr;
};
using Origins = std::map<std::size_t, Origin>;  // by the element's number in document order (xml::Writer::elements)

// MJCF text and where its robots' elements come from.
struct Mjcf {
  std::string text;
  Origins origins;
};

struct Builder {
  Builder(const models::CellDescription& c, const SceneOptions& o) : cell(c), options(o) {}

  const models::CellDescription& cell;
  const SceneOptions& options;
  xml::Writer x{2};          // the project's one XML writer (common/xml.hpp), two spaces per level
  std::vector<double> qpos;  // initial qpos in MuJoCo's order (joints in document order)
  std::vector<double> ctrl;  // initial actuator targets, in the order actuators are written
  // An element written after the worldbody (actuators, sensors, mesh assets), with its origin if it has one.
  struct Deferred {
    std::string tag;
    Attrs attrs;
    std::optional<Origin> origin;
  };
  std::vector<Deferred> actuators;  // <actuator> children, written after the worldbody
  std::vector<Deferred> sensors;
  Origins origins;  // of the elements written so far
  std::vector<std::pair<std::string, std::string>> excludes;
  // Bodies fixed to the world (no joint on the way to it): the world itself, robot bases, conveyor frames, machines.
  // MuJoCo never lets two of them touch, but its broadphase pairs them whenever their boxes overlap and then tests
  // every pair of their geoms; excluded, the pair costs one lookup (a quarter of a step's geom tests in the cell).
  std::vector<std::string> fixed_bodies{"world"};
  std::vector<std::pair<std::string, std::string>> couplings;  // joints that move together (joint1 = joint2)
  // Robot meshes: <mesh> assets {name, file MuJoCo reads, scale}, written after the worldbody; by source and scale.
  std::vector<std::array<std::string, 3>> meshes;
  std::vector<Origin> mesh_origins;  // of each of `meshes`, the first <mesh> element that names it
  std::map<std::pair<std::string, std::string>, std::string> mesh_names;
  // Bodies of links without <inertial> whose collision geometry gives them mass (MuJoCo's default density), and the
  // masses MuJoCo computed for them in a first compile (scene_mjcf), used to tune the servos.
  std::set<std::string> massless;
  LinkMasses estimated;

  void actuator(const std::string& tag, const Attrs& attrs, double initial, std::optional<Origin> origin = {}) {
    actuators.push_back({tag, attrs, std::move(origin)});
    ctrl.push_back(initial);
  }
  void sensor(const std::string& tag, const Attrs& attrs, std::optional<Origin> origin = {}) {
    sensors.push_back({tag, attrs, std::move(origin)});
  }
  // The next element written comes from `origin`.
  void from(Origin origin) { origins[x.elements()] = std::move(origin); }
  void write(const Deferred& d) {
    if (d.origin) from(*d.origin);
    x.leaf(d.tag, d.attrs);
  }

  // --- Robots ---

  void geom_attrs(Attrs& a, const urdf::Geometry& g, const urdf::Pose& origin, const RobotModel& r,
                  const std::string& link) {
    const Eigen::Isometry3d t = to_eigen(origin);
    a.emplace_back("pos", vec(t.translation()));
    a.emplace_back("quat", quat(t.linear()));
    switch (g.type) {
      case urdf::Geometry::BOX: {
        const auto& b = static_cast<const urdf::Box&>(g);
        a.emplace_back("type", "box");
        a.emplace_back("size", nums({b.dim.x / 2, b.dim.y / 2, b.dim.z / 2}));
        break;
      }
      case urdf::Geometry::CYLINDER: {
        const auto& c = static_cast<const urdf::Cylinder&>(g);
        a.emplace_back("type", "cylinder");
        a.emplace_back("size", nums({c.radius, c.length / 2}));
        break;
      }
      case urdf::Geometry::SPHERE: {
        const auto& s = static_cast<const urdf::Sphere&>(g);
        a.emplace_back("type", "sphere");
        a.emplace_back("size", num(s.radius));
        break;
      }
      case urdf::Geometry::MESH: {
        const auto& m = static_cast<const urdf::Mesh&>(g);
        const models::UrdfModel& model = r.link(link).model != nullptr ? *r.link(link).model : r.mounted->arm;
        const SourceLocation where = model.mesh_at(m.filename);
        const std::filesystem::path source =
            models::resolve_mesh(m.filename, *r.spec, std::filesystem::path(model.file()), where);
        const Eigen::Vector3d scale = to_eigen(m.scale);
        if (!scale.allFinite() || scale.minCoeff() <= 0) {
          throw InputError(where, fmt::format("robot '{}': mesh '{}' has scale {} {} {}; each must be above 0",
                                              r.spec->name, m.filename, scale.x(), scale.y(), scale.z()));
        }
        const auto key = std::make_pair(source.string(), vec(scale));
        auto it = mesh_names.find(key);
        if (it == mesh_names.end()) {
          const std::string name = fmt::format("{}/mesh{}", r.spec->name, meshes.size() + 1);
          meshes.push_back({name, twin::mujoco_mesh(source, where).string(), vec(scale)});
          mesh_origins.push_back({where, fmt::format("mesh '{}'", m.filename), r.spec});
          it = mesh_names.emplace(key, name).first;
        }
        a.emplace_back("type", "mesh");
        a.emplace_back("mesh", it->second);
        break;
      }
      default:
        throw InputError(r.link(link).model != nullptr ? r.link(link).model->link_at(link) : SourceLocation{r.spec->urdf.string()},
                         fmt::format("robot '{}': link '{}' has a geometry of unknown type", r.spec->name, link));
    }
  }

  // Half extents and centre of a geometry's bounding box in its link frame (for the touch sensor zones).
  static std::pair<Eigen::Vector3d, Eigen::Vector3d> bounds(const urdf::Geometry& g) {
    switch (g.type) {
      case urdf::Geometry::BOX: {
        const auto& b = static_cast<const urdf::Box&>(g);
        return {Eigen::Vector3d::Zero(), Eigen::Vector3d(b.dim.x, b.dim.y, b.dim.z) / 2};
      }
      case urdf::Geometry::CYLINDER: {
        const auto& c = static_cast<const urdf::Cylinder&>(g);
        return {Eigen::Vector3d::Zero(), Eigen::Vector3d(c.radius, c.radius, c.length / 2)};
      }
      case urdf::Geometry::SPHERE: {
        const auto& s = static_cast<const urdf::Sphere&>(g);
        return {Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(s.radius)};
      }
      default:
        return {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    }
  }

  // `moving`: the link is below a movable joint of the robot.
  void robot_link(const RobotModel& r, const urdf::Link& link, bool moving, std::vector<std::string>& collision_bodies) {
    const std::string& robot = r.spec->name;
    const std::string body = robot + "/" + link.name;
    const models::UrdfModel& file = r.link_model(link.name);
    const auto part = [&](const char* tag, std::size_t i) {
      return Origin{file.link_part_at(link.name, tag, i), fmt::format("link '{}' (its <{}>)", link.name, tag), r.spec};
    };
    if (link.inertial) {
      const auto& in = *link.inertial;
      const Eigen::Isometry3d t = to_eigen(in.origin);
      // MJCF takes a full inertia tensor only in the body's axes: turn the URDF's (given in the inertial frame).
      Eigen::Matrix3d inertia;
      inertia << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      inertia = t.linear() * inertia * t.linear().transpose();
      from(part("inertial", 0));
      x.leaf("inertial", {{"pos", vec(t.translation())},
                          {"mass", num(in.mass)},
                          {"fullinertia", nums({inertia(0, 0), inertia(1, 1), inertia(2, 2), inertia(0, 1),
                                                inertia(0, 2), inertia(1, 2)})}});
    }
    // A link without <inertial> that has geometry (vendors' URDFs often give no masses) gets its mass the way MuJoCo
    // gives a body without <inertial> one: from its collision geometry at MuJoCo's default density, 1000 kg/m^3
    // (MuJoCo refuses a body whose geoms have no mass). The servos of a moving one are tuned with it (scene_mjcf).
    const bool from_geometry = !link.inertial && !link.collision_array.empty();
    if (from_geometry && moving) massless.insert(body);
    if (!r.spec->draw_collision) {
      for (std::size_t i = 0; i < link.visual_array.size(); ++i) {
        const auto& v = link.visual_array[i];
        if (!v || !v->geometry) continue;
        Attrs a{{"class", "visual"}};
        geom_attrs(a, *v->geometry, v->origin, r, link.name);
        if (v->material) {
          const auto& c = v->material->color;
          a.emplace_back("rgba", nums({c.r, c.g, c.b, c.a}));
        }
        from(part("visual", i));
        x.leaf("geom", a);
      }
    }
    const bool finger = r.finger_links.count(link.name) != 0;
    bool has_pad = false;
    for (const auto& c : link.collision_array) {
      if (c && c->name.find("pad") != std::string::npos) has_pad = true;
    }
    bool collides = false;
    for (std::size_t i = 0; i < link.collision_array.size(); ++i) {
      const auto& c = link.collision_array[i];
      if (!c || !c->geometry) continue;
      if (r.spec->draw_collision) {
        // meshes: collision: the collision geometry drawn in the URDF's visual colour (grey if none).
        Attrs a{{"class", "visual"}};
        geom_attrs(a, *c->geometry, c->origin, r, link.name);
        const urdf::Visual* v = link.visual_array.empty() ? nullptr : link.visual_array.front().get();
        if (v != nullptr && v->material) {
          a.emplace_back("rgba", nums({v->material->color.r, v->material->color.g, v->material->color.b, 1}));
        } else {
          a.emplace_back("rgba", "0.7 0.7 0.7 1");
        }
        from(part("collision", i));
        x.leaf("geom", a);
      }
      // Finger pads grip: four contact dimensions (torsional friction too) so that a held part does not pivot.
      const bool pad = finger && (!has_pad || c->name.find("pad") != std::string::npos);
      Attrs a{{"class", pad ? "pad" : "collision"}};
      if (!c->name.empty()) a.emplace_back("name", body + "/" + c->name);
      geom_attrs(a, *c->geometry, c->origin, r, link.name);
      if (from_geometry) a.emplace_back("density", "1000");
      from(part("collision", i));
      x.leaf("geom", a);
      collides = true;
      if (pad) {
        // The touch sensor zone: the pad enlarged by 3 mm, so that contacts on its face fall inside.
        const auto [centre, half] = bounds(*c->geometry);
        const Eigen::Isometry3d t = to_eigen(c->origin);
        const std::string side = link.name == r.left_finger_link ? "left" : "right";
        from(part("collision", i));
        x.leaf("site", {{"name", fmt::format("{}/finger_{}_touch", robot, side)},
                        {"type", "box"},
                        {"group", "4"},
                        {"pos", vec(t * centre)},
                        {"quat", quat(t.linear())},
                        {"size", vec(half + Eigen::Vector3d::Constant(0.003))},
                        {"rgba", "0.2 0.9 0.2 0.3"}});
      }
    }
    if (collides) collision_bodies.push_back(body);
    if (link.name == r.spec->flange_link && r.link(link.name).link == &link) {
      x.leaf("site", {{"name", robot + "/wrist_ft"}, {"size", "0.01"}, {"group", "4"}, {"rgba", "0.9 0.2 0.2 0.5"}});
    }
    if (link.name == r.tool_link && r.hand->getLink(link.name).get() == &link) {
      x.leaf("site", {{"name", robot + "/tcp"}, {"size", "0.005"}, {"group", "4"}, {"rgba", "0.2 0.2 0.9 0.5"}});
    }
    for (const auto& [j, child] : r.children(link)) {
      const Eigen::Isometry3d t = j != nullptr ? to_eigen(j->parent_to_joint_origin_transform) : Eigen::Isometry3d::Identity();
      from({child.model->link_at(child.link->name), fmt::format("link '{}'", child.link->name), r.spec});
      x.open("body", {{"name", robot + "/" + child.link->name}, {"pos", vec(t.translation())}, {"quat", quat(t.linear())}});
      if (j != nullptr && movable(*j)) robot_joint(r, *j, *child.link);
      robot_link(r, *child.link, moving || (j != nullptr && movable(*j)), collision_bodies);
      x.close();
    }
  }

  void robot_joint(const RobotModel& r, const urdf::Joint& j, const urdf::Link& child) {
    const std::string& robot = r.spec->name;
    const std::string name = robot + "/" + j.name;
    const Origin origin{r.joint_model(j).joint_at(j.name), fmt::format("joint '{}'", j.name), r.spec};
    const bool prismatic = j.type == urdf::Joint::PRISMATIC;
    const bool limited = j.type != urdf::Joint::CONTINUOUS && j.limits;
    LoadBound load;
    accumulate_load(r, estimated, child, 0, prismatic, load);

    const auto arm = std::find(r.arm_joints.begin(), r.arm_joints.end(), j.name);
    const bool is_arm = arm != r.arm_joints.end();
    const bool is_finger = j.name == "finger_left_joint" || j.name == "finger_right_joint";
    const double omega_max = kOmegaStep / cell.timestep;
    double kp = 0, force_limit = 0, initial = 0;
    if (is_finger) {
      // Fingers push with at most the grip force; they reach it after kFingerSqueeze of squeeze on a part.
      force_limit = r.spec->grip_force;
      kp = force_limit / kFingerSqueeze;
      initial = j.limits->upper;  // open
    } else {
      kp = std::max(kKpMin, load.torque / kSagBound);
      force_limit = j.limits && j.limits->effort > 0 ? j.limits->effort : 0;
      initial = is_arm ? r.spec->home[static_cast<std::size_t>(arm - r.arm_joints.begin())] : 0;
    }
    // The fingers' damping is joint damping, which Euler integrates implicitly: their spring alone must stay stable
    // (symplectic Euler: omega h < 2), so they may be twice as fast as the arm servos; at a 5 ms step with the arms'
    // bound they would take 30 ms to close the last millimetre on a part.
    const double omega = is_finger ? kFingerOmegaFactor * omega_max : omega_max;
    const double armature = std::max(kp / (omega * omega), prismatic ? 0.01 : 0.01);
    const double urdf_damping = j.dynamics ? j.dynamics->damping : 0.0;
    const double damping = std::max(urdf_damping, 2.0 * std::sqrt(kp * (armature + 0.5 * load.inertia)));
    // An arm servo's damping acts in the servo (force = kp (ctrl - q) - kd qdot, within the joint's effort), not as
    // friction of the joint: as joint damping, the effort limit would cap the joint speed at effort / kd (0.14 rad/s
    // for the PUMA's first joint). A controller adds kd times the wanted speed to its target (sim_driver.hpp), so the
    // servo only spends effort on the tracking error. The fingers keep joint damping: their force limit is the grip.
    const bool servo_damped = !is_finger;
    Attrs ja{{"name", name},
             {"type", prismatic ? "slide" : "hinge"},
             {"axis", vec(to_eigen(j.axis))},
             {"armature", num(armature)},
             {"damping", num(servo_damped ? urdf_damping : damping)}};
    if (limited) {
      ja.emplace_back("limited", "true");
      ja.emplace_back("range", nums({j.limits->lower, j.limits->upper}));
    }
    from(origin);
    x.leaf("joint", ja);
    qpos.push_back(initial);

    Attrs aa{{"name", name}, {"joint", name}};
    if (servo_damped) {
      aa.insert(
          aa.end(),
          {{"gaintype", "fixed"}, {"gainprm", num(kp)}, {"biastype", "affine"}, {"biasprm", nums({0, -kp, -damping})}});
    } else {
      aa.emplace_back("kp", num(kp));
    }
    if (limited) {
      aa.emplace_back("ctrllimited", "true");
      aa.emplace_back("ctrlrange", nums({j.limits->lower, j.limits->upper}));
    }
    if (force_limit > 0) {
      aa.emplace_back("forcelimited", "true");
      aa.emplace_back("forcerange", nums({-force_limit, force_limit}));
    }
    actuator(servo_damped ? "general" : "position", aa, initial, origin);
    if (is_finger) {
      const std::string side = j.name == "finger_left_joint" ? "left" : "right";
      sensor("jointpos", {{"name", fmt::format("{}/finger_{}_pos", robot, side)}, {"joint", name}}, origin);
    } else {
      sensor("jointpos", {{"name", name + "_pos"}, {"joint", name}}, origin);
    }
  }

  // A geom of the cell's fixed scenery (the floor, a pedestal, a stand, a plate), in a body of its own named
  // "scenery/<geom>" rather than on the world body: MuJoCo's broadphase tests every geom of the world body against
  // every geom of every other body on every step, but pairs a body of its own only with what comes near it (the floor,
  // a plane, is still tested against everything). The body sits at the origin; the geom keeps its pose.
  void scenery(const Attrs& geom) {
    const auto name = std::find_if(geom.begin(), geom.end(), [](const auto& a) { return a.first == "name"; });
    CW_CHECK(name != geom.end(), "a scenery geom needs a name");
    const std::string body = std::string(kSceneryPrefix) + name->second;
    fixed_bodies.push_back(body);
    x.open("body", {{"name", body}});
    x.leaf("geom", geom);
    x.close();
  }

  void robot(const RobotModel& r) {
    const models::RobotSpec& spec = *r.spec;
    x.comment(fmt::format("robot '{}' from {}{}", spec.name, spec.urdf.string(),
                          r.mounted->gripper ? fmt::format(", gripper {} on {}", r.mounted->gripper->file(),
                                                           spec.flange_link)
                                             : std::string()));
    if (spec.base.xyz.z() > 1e-3) {
      // A robot mounted above the floor stands on a pedestal.
      from({spec.where, "its pedestal (the cell's base height)", &spec});
      scenery({{"name", spec.name + "/pedestal"},
                      {"type", "box"},
                      {"pos", vec(Eigen::Vector3d(spec.base.xyz.x(), spec.base.xyz.y(), spec.base.xyz.z() / 2))},
                      {"quat", quat(Eigen::Matrix3d(Eigen::AngleAxisd(spec.base.rpy.z(), Eigen::Vector3d::UnitZ())))},
                      {"size", nums({kPedestalSide / 2, kPedestalSide / 2, spec.base.xyz.z() / 2})},
                      {"material", "pedestal"}});
    }
    // The base link stands at the robot's base; links above it (a `world` root) are left out (load_robot checked
    // that they are fixed to it).
    from({r.mounted->arm.link_at(spec.base_link), fmt::format("link '{}'", spec.base_link), &spec});
    fixed_bodies.push_back(spec.name + "/" + spec.base_link);
    x.open("body", {{"name", spec.name + "/" + spec.base_link},
                    {"pos", vec(spec.base.xyz)},
                    {"quat", quat(spec.base.rotation())}});
    std::vector<std::string> bodies;
    robot_link(r, *r.urdf->getLink(spec.base_link), false, bodies);
    x.close();
    // Self-collision inside one arm is not simulated (its URDF geometry overlaps at the joints); arms still collide
    // with each other, with the cell and with parts.
    for (std::size_t a = 0; a < bodies.size(); ++a) {
      for (std::size_t b = a + 1; b < bodies.size(); ++b) excludes.emplace_back(bodies[a], bodies[b]);
    }
    // The fingers of a parallel gripper move together (rack and pinion): without the coupling, two force-limited
    // servos squeezing a part leave it free to drift along the closing direction.
    couplings.emplace_back(spec.name + "/finger_left_joint", spec.name + "/finger_right_joint");
    sensor("force", {{"name", spec.name + "/wrist_force"}, {"site", spec.name + "/wrist_ft"}});
    sensor("torque", {{"name", spec.name + "/wrist_torque"}, {"site", spec.name + "/wrist_ft"}});
    for (const char* side : {"left", "right"}) {
      sensor("touch", {{"name", fmt::format("{}/finger_{}_touch", spec.name, side)},
                       {"site", fmt::format("{}/finger_{}_touch", spec.name, side)}});
    }
  }

  // --- Conveyors, machines, workpieces ---

  void conveyor(const models::ConveyorSpec& c) {
    const std::string name = "conveyor/" + c.name;
    const double l = c.length, w = c.width, h = c.height, t = kBeltThickness;
    x.comment(fmt::format("conveyor '{}': belt top {} m above the floor, {} m/s", c.name, num(h), num(c.speed)));
    fixed_bodies.push_back(name);
    x.open("body", {{"name", name}, {"pos", vec(c.pose.xyz)}, {"quat", quat(c.pose.rotation())}});
    // The frame reaches up to kFrameGap under the belt top: it is what robots touch there (the belt below collides
    // with workpieces only, see kBeltBits), with the conveyor's true extent.
    x.leaf("geom", {{"name", name + "/frame"},
                    {"type", "box"},
                    {"pos", nums({0, 0, (h - kFrameGap) / 2})},
                    {"size", nums({l / 2, w / 2, (h - kFrameGap) / 2})},
                    {"material", "conveyor_frame"}});
    x.leaf("geom", {{"class", "visual"},
                    {"type", "box"},
                    {"pos", nums({0, 0, h - t / 2})},
                    {"size", nums({l / 2, w / 2, t / 2})},
                    {"material", "belt"}});
    for (double end : {-l / 2, l / 2}) {
      x.leaf("geom",
             {{"class", "visual"},
              {"type", "cylinder"},
              {"pos", nums({end, 0, h - t / 2 - 0.01})},
              {"quat", quat(Eigen::Matrix3d(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX())))},
              {"size", nums({t / 2 + 0.01, w / 2 + 0.01})},
              {"material", "conveyor_frame"}});
    }
    if (c.stop) {
      x.leaf("geom", {{"name", name + "/stop"},
                      {"type", "box"},
                      {"pos", nums({c.leave - l / 2 + 0.005, 0, h + 0.02})},
                      {"size", nums({0.005, w / 2, 0.02})},
                      {"material", "stop"},
                      // A smooth stop: with grippy friction there, the belt pulling a part's bottom while the stop
                      // holds its face wedges it down onto the belt with many times its weight.
                      {"priority", "1"},
                      {"friction", "0.1 0.005 0.0001"}});
    }
    if (c.guides > 0) {
      // Side guides: rails along both edges of the belt, from its top up to `guides`, the conveyor's whole length.
      for (const auto& [side, sign] : {std::pair{"left", 1.0}, std::pair{"right", -1.0}}) {
        x.leaf("geom", {{"name", fmt::format("{}/guide_{}", name, side)},
                        {"type", "box"},
                        {"pos", nums({0, sign * (w / 2 + kGuideThickness / 2), h + c.guides / 2})},
                        {"size", nums({l / 2, kGuideThickness / 2, c.guides / 2})},
                        {"material", "stop"},
                        {"priority", "1"},
                        {"friction", "0.1 0.005 0.0001"}});  // smooth, like the stop bar
      }
    }
    // The belt: kBeltWrap longer than the conveyor, reaching kBeltWrap upstream at q = 0, so that for q in
    // [0, kBeltWrap) its top covers the whole conveyor. Collision only: the visible belt is the static plate above.
    x.open("body", {{"name", name + "/belt"}, {"pos", nums({0, 0, h - t / 2})}});
    x.leaf("joint", {{"name", name + "/belt"}, {"type", "slide"}, {"axis", "1 0 0"}, {"damping", num(kBeltKv)}});
    qpos.push_back(0);
    x.leaf("inertial", {{"pos", "0 0 0"}, {"mass", num(kBeltMass)}, {"diaginertia", "0.1 0.1 0.1"}});
    x.leaf("geom", {{"name", name + "/belt"},
                    {"type", "box"},
                    {"group", "3"},
                    {"rgba", "0.1 0.1 0.1 0.3"},
                    {"pos", nums({-kBeltWrap / 2, 0, 0})},
                    {"size", nums({(l + kBeltWrap) / 2, w / 2, t / 2})},
                    {"contype", kBeltBits},
                    {"conaffinity", kBeltBits},
                    {"priority", "1"},  // its friction, not the part's, acts between them
                    {"friction", kBeltFriction}});
    x.close();
    x.close();
    excludes.emplace_back(name, name + "/belt");
    actuator("general",
             {{"name", name + "/belt"},
              {"joint", name + "/belt"},
              {"gaintype", "fixed"},
              {"gainprm", num(kBeltKv)},  // with the joint's damping kBeltKv: a velocity servo, ctrl in m/s
              {"ctrllimited", "true"},
              {"ctrlrange", "-2 2"}},
             c.speed);
  }

  void machine(const models::MachineSpec& m) {
    const std::string name = "machine/" + m.name;
    x.comment(fmt::format("machine '{}': process time {} s", m.name, num(m.process_time)));
    fixed_bodies.push_back(name);
    x.open("body", {{"name", name}, {"pos", vec(m.pose.xyz)}, {"quat", quat(m.pose.rotation())}});
    x.leaf("geom", {{"name", name + "/body"},
                    {"type", "box"},
                    {"pos", nums({0, 0, m.size.z() / 2})},
                    {"size", vec(m.size / 2)},
                    {"material", "machine"}});
    x.leaf("geom", {{"name", name + "/fixture"},
                    {"type", "box"},
                    {"pos", nums({0, 0, m.size.z() + m.fixture_size.z() / 2})},
                    {"size", vec(m.fixture_size / 2)},
                    {"material", "fixture"}});
    // A status lamp on a corner, for the eye only. White: the overhead camera finds parts by their colour, and a
    // green lamp looks like a green part to it (docs/vision.md).
    x.leaf("geom", {{"class", "visual"},
                    {"type", "cylinder"},
                    {"pos", nums({m.size.x() / 2 - 0.03, m.size.y() / 2 - 0.03, m.size.z() + 0.04})},
                    {"size", "0.015 0.04"},
                    {"rgba", "0.92 0.92 0.88 1"}});
    x.close();
  }

  void workpiece(const models::WorkpieceSpec& w) {
    const std::string name = "workpiece/" + w.name;
    const Eigen::Quaterniond q(w.pose.rotation());
    x.open("body", {{"name", name}, {"pos", vec(w.pose.xyz)}, {"quat", quat(q)}});
    x.leaf("joint", {{"name", name}, {"type", "free"}});
    qpos.insert(qpos.end(), {w.pose.xyz.x(), w.pose.xyz.y(), w.pose.xyz.z(), q.w(), q.x(), q.y(), q.z()});
    Attrs a{{"name", name}, {"class", "part"}, {"mass", num(w.mass)}, {"rgba", rgba(w.rgba)}};
    if (w.shape == models::Shape::kBox) {
      a.emplace_back("type", "box");
      a.emplace_back("size", vec(w.size / 2));
    } else {
      a.emplace_back("type", "cylinder");
      a.emplace_back("size", nums({w.size.x() / 2, w.size.z() / 2}));
    }
    x.leaf("geom", a);
    x.close();
  }

  // --- Whole cell ---

  Eigen::AlignedBox3d extent() const {
    Eigen::AlignedBox3d box(Eigen::Vector3d(-0.5, -0.5, 0), Eigen::Vector3d(0.5, 0.5, 0.5));
    for (const auto& r : cell.robots) box.extend(r.base.xyz);
    for (const auto& c : cell.conveyors) {
      box.extend(c.belt_point(0));
      box.extend(c.belt_point(c.length));
    }
    for (const auto& m : cell.machines) box.extend(m.fixture_top().xyz);
    for (const auto& w : cell.workpieces) box.extend(w.pose.xyz);
    for (const auto& l : cell.locations) box.extend(l.pose.xyz);
    return box;
  }

  std::string build(const std::vector<RobotModel>& robots) {
    x.open("mujoco", {{"model", cell.name}});
    x.leaf("compiler", {{"angle", "radian"}, {"autolimits", "false"}, {"inertiafromgeom", "auto"}});
    // docs/simulation.md, "Physics settings", has the measurements behind each choice. Elliptic friction cones and a
    // high impratio make friction grasps hold (facts.md; pyramidal cones lost a part in the pipeline). Euler, not the
    // implicit integrator: MuJoCo 2.2's implicit integration spends a third of a step on the velocity derivative of
    // every force; Euler integrates joint damping (fingers, belts) implicitly and the arm servos' damping explicitly,
    // which is stable because their natural frequency stays under kOmegaStep / timestep. No noslip pass (was 3, then
    // 1): a held part slips 2.6 mm over pick_place_test's 30 cm carry against 2.3 mm with one pass, and the pass cost a
    // fifth of a step (its projection of the constraints, mj_projectConstraint, and its own solve). Sparse constraint
    // Jacobians: a dense row spans all 44 degrees of freedom of the paper's cell, where a contact moves only the two
    // chains it touches; the same numbers to about 1e-6, 5-18 % less CPU a run.
    x.leaf("option",
           {{"timestep", num(cell.timestep)},
            {"integrator", "Euler"},
            {"cone", "elliptic"},
            {"impratio", "10"},
            {"noslip_iterations", "0"},
            {"jacobian", "sparse"}});
    // MuJoCo 2.2 sizes mjData by these: njmax rows of constraint (its njmax x njmax matrix made 4000 rows cost 200
    // MB), nconmax contacts. The shipped scenarios need at most about 135 rows and 35 contacts; a run that needs more
    // fails with a clear error (World: the buffer-full warning faults every robot).
    x.leaf("size", {{"njmax", std::to_string(kNjmax)},
                    {"nconmax", std::to_string(kNconmax)},
                    // A colour per workpiece that the run may change (scene.hpp, kColourSlot).
                    {"nuserdata", std::to_string(kColourSlot * static_cast<int>(cell.workpieces.size()))}});
    int offwidth = 640, offheight = 480;
    for (const auto& c : cell.cameras) {
      offwidth = std::max(offwidth, c.width);
      offheight = std::max(offheight, c.height);
    }
    x.open("visual");
    x.leaf("global", {{"offwidth", std::to_string(offwidth)}, {"offheight", std::to_string(offheight)}});
    x.leaf("quality", {{"shadowsize", "1024"}, {"offsamples", "0"}});
    x.leaf("headlight", {{"ambient", "0.35 0.35 0.35"}, {"diffuse", "0.45 0.45 0.45"}, {"specular", "0.1 0.1 0.1"}});
    x.close();

    x.open("asset");
    x.leaf("texture", {{"name", "sky"},
                       {"type", "skybox"},
                       {"builtin", "gradient"},
                       {"rgb1", "0.75 0.82 0.9"},
                       {"rgb2", "0.3 0.35 0.4"},
                       {"width", "256"},
                       {"height", "256"}});
    x.leaf("texture", {{"name", "floor"},
                       {"type", "2d"},
                       {"builtin", "checker"},
                       {"rgb1", "0.62 0.62 0.6"},
                       {"rgb2", "0.55 0.55 0.53"},
                       {"width", "256"},
                       {"height", "256"}});
    x.leaf("material", {{"name", "floor"}, {"texture", "floor"}, {"texrepeat", "8 8"}, {"reflectance", "0"}});
    x.leaf("material", {{"name", "conveyor_frame"}, {"rgba", "0.35 0.45 0.55 1"}});
    x.leaf("material", {{"name", "belt"}, {"rgba", "0.12 0.12 0.12 1"}});
    // The stop bars are light grey, not safety yellow: a yellow bar is a yellow part to the camera (docs/vision.md).
    x.leaf("material", {{"name", "stop"}, {"rgba", "0.8 0.8 0.82 1"}});
    x.leaf("material", {{"name", "machine"}, {"rgba", "0.3 0.5 0.35 1"}});
    x.leaf("material", {{"name", "fixture"}, {"rgba", "0.7 0.7 0.72 1"}});
    x.leaf("material", {{"name", "pedestal"}, {"rgba", "0.3 0.3 0.32 1"}});
    x.close();

    x.open("default");
    x.open("default", {{"class", "visual"}});
    x.leaf("geom", {{"contype", "0"}, {"conaffinity", "0"}, {"group", "1"}, {"density", "0"}});
    x.close();
    x.open("default", {{"class", "collision"}});
    x.leaf("geom", {{"group", "3"}, {"density", "0"}, {"rgba", "0.5 0.5 0.9 0.4"}});
    x.close();
    x.open("default", {{"class", "pad"}});
    x.leaf(
        "geom",
        {{"group", "3"}, {"density", "0"}, {"condim", "4"}, {"friction", kPadFriction}, {"rgba", "0.9 0.5 0.2 0.5"}});
    x.close();
    x.open("default", {{"class", "part"}});
    x.leaf("geom", {{"contype", kPartBits},
                    {"conaffinity", kPartBits},
                    {"condim", "4"},
                    {"friction", kPadFriction},
                    {"solref", kGripSolref},
                    {"solimp", kGripSolimp}});
    x.close();
    x.close();

    x.open("worldbody");
    const Eigen::AlignedBox3d box = extent();
    const Eigen::Vector3d centre = box.center();
    const Eigen::Vector3d half = box.sizes() / 2 + Eigen::Vector3d::Constant(1.5);
    scenery({{"name", "floor"},
                    {"type", "plane"},
                    {"pos", nums({centre.x(), centre.y(), 0})},
                    {"size", nums({half.x(), half.y(), 0.1})},
                    {"material", "floor"}});
    if (cell.lights.empty()) {
      x.leaf("light", {{"name", "default"},
                       {"pos", nums({centre.x(), centre.y(), 3})},
                       {"dir", "0 0 -1"},
                       {"directional", "false"},
                       {"castshadow", "true"},
                       {"diffuse", "0.6 0.6 0.6"}});
    }
    for (const auto& l : cell.lights) {
      x.leaf("light", {{"name", l.name},
                       {"pos", vec(l.position)},
                       {"dir", vec(l.direction)},
                       {"directional", l.directional ? "true" : "false"},
                       {"castshadow", l.cast_shadow ? "true" : "false"},
                       {"diffuse", vec(l.diffuse)}});
    }
    for (const auto& c : cell.cameras) {
      x.leaf("camera", {{"name", c.name},
                        {"pos", vec(c.pose.xyz)},
                        {"quat", quat(c.pose.rotation())},
                        {"fovy", num(c.fovy * 180.0 / std::numbers::pi)}});
    }
    for (const auto& l : cell.locations) {
      x.leaf("site", {{"name", "location/" + l.name},
                      {"pos", vec(l.pose.xyz)},
                      {"quat", quat(l.pose.rotation())},
                      {"size", "0.01"},
                      {"group", "5"},
                      {"rgba", "0.9 0.9 0.1 0.6"}});
    }
    for (const auto& l : cell.locations) {
      if (!l.stand) continue;
      // A stand a scenario built under its location: static, like a machine (its top is where the part rests).
      scenery({{"name", "stand/" + l.name},
                      {"type", "box"},
                      {"pos", nums({l.pose.xyz.x(), l.pose.xyz.y(), l.pose.xyz.z() / 2})},
                      {"quat", quat(l.pose.rotation())},
                      {"size", nums({l.stand->x() / 2, l.stand->y() / 2, l.pose.xyz.z() / 2})},
                      {"material", "machine"}});
    }
    if (cell.handover) {
      x.leaf("site", {{"name", "handover/" + cell.handover->name},
                      {"pos", vec(cell.handover->pose.xyz)},
                      {"quat", quat(cell.handover->pose.rotation())},
                      {"size", "0.01"},
                      {"group", "5"},
                      {"rgba", "0.9 0.1 0.9 0.6"}});
    }
    for (const auto& r : robots) robot(r);
    for (const auto& c : cell.conveyors) conveyor(c);
    for (const auto& m : cell.machines) machine(m);
    for (const auto& w : cell.workpieces) workpiece(w);
    for (std::size_t i = 0; i < options.obstacles.size(); ++i) {
      const double side = options.obstacles[i];
      x.open("body", {{"name", fmt::format("obstacle/{}", i + 1)}, {"mocap", "true"}, {"pos", "0 0 -1"}});
      x.leaf("geom", {{"name", fmt::format("obstacle/{}", i + 1)},
                      {"type", "box"},
                      {"size", nums({side / 2, side / 2, side / 2})},
                      {"rgba", "0.2 0.2 0.22 1"}});
      x.close();
    }
    for (std::size_t i = 0; i < options.plates.size(); ++i) {
      const Plate& p = options.plates[i];
      scenery({{"name", fmt::format("plate/{}", i + 1)},
                      {"type", "box"},
                      {"pos", vec(p.pose.translation())},
                      {"quat", quat(Eigen::Matrix3d(p.pose.linear()))},
                      {"size", vec(p.size / 2)},
                      {"contype", "0"},
                      {"conaffinity", "0"},
                      {"rgba", nums({p.rgba[0], p.rgba[1], p.rgba[2], p.rgba[3]})}});
    }
    x.close();

    if (!meshes.empty()) {
      // The robots' meshes (a second <asset> section: the meshes are known once the robots are written).
      x.open("asset");
      for (std::size_t i = 0; i < meshes.size(); ++i) {
        const auto& [name, file, scale] = meshes[i];
        from(mesh_origins[i]);
        x.leaf("mesh", {{"name", name}, {"file", file}, {"scale", scale}});
      }
      x.close();
    }
    for (std::size_t a = 0; a < fixed_bodies.size(); ++a) {
      for (std::size_t b = a + 1; b < fixed_bodies.size(); ++b) excludes.emplace_back(fixed_bodies[a], fixed_bodies[b]);
    }
    x.open("contact");
    for (const auto& [a, b] : excludes) x.leaf("exclude", {{"body1", a}, {"body2", b}});
    x.close();
    x.open("equality");
    for (const auto& [a, b] : couplings) x.leaf("joint", {{"joint1", a}, {"joint2", b}, {"polycoef", "0 1 0 0 0"}});
    x.close();
    // Actuators and sensors were collected while the bodies were written.
    x.open("actuator");
    for (const Deferred& a : actuators) write(a);
    x.close();
    x.open("sensor");
    for (const Deferred& s : sensors) write(s);
    x.close();
    // The initial state, so that the saved MJCF opens in MuJoCo's viewer as the cell starts.
    x.open("keyframe");
    x.leaf("key", {{"name", "initial"}, {"qpos", join(qpos)}, {"ctrl", join(ctrl)}});
    x.close();
    x.close();
    return x.str();
  }
  static std::string join(const std::vector<double>& v) {
    std::string s;
    for (double d : v) s += (s.empty() ? "" : " ") + num(d);
    return s;
  }
};

std::vector<RobotModel> read_robot_models(const models::CellDescription& cell) {
  std::vector<RobotModel> out;
  for (const auto& r : cell.robots) out.push_back(read_robot_model(r));
  return out;
}

int id_of(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  CW_CHECK(id >= 0, "the scene has no {} named '{}'", static_cast<int>(type), name);
  return id;
}

// Frees a VFS allocated on the heap (it holds 2000 file names of 1000 bytes: too big for the stack).
struct VfsDeleter {
  void operator()(mjVFS* v) const {
    mj_deleteVFS(v);
    delete v;
  }
};

// The number (in document order, from 0) of the element of `xml` that starts on `line` and of its ancestors, innermost
// first; empty if no element starts there.
std::vector<std::size_t> elements_at_line(const std::string& xml, int line) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) return {};
  std::size_t count = 0;
  std::vector<std::size_t> path;  // the numbers of the elements open at the walk's position, outermost first
  std::vector<std::size_t> found;
  const std::function<bool(const tinyxml2::XMLElement*)> walk = [&](const tinyxml2::XMLElement* e) {
    path.push_back(count++);
    if (e->GetLineNum() == line) {
      found.assign(path.rbegin(), path.rend());
      return true;
    }
    for (const tinyxml2::XMLElement* c = e->FirstChildElement(); c != nullptr; c = c->NextSiblingElement()) {
      if (walk(c)) return true;
    }
    path.pop_back();
    return false;
  };
  if (doc.RootElement() != nullptr) walk(doc.RootElement());
  return found;
}

// MuJoCo's message as the user's error: its first line without MuJoCo's "Error: " or "XML Error: " (the lines after
// it, "Object name = ..., line = ..." or "Element '...', line ...", place it in the generated MJCF, which the origin
// replaces), and the generated MJCF's line it names (0 if none).
std::pair<std::string, int> split_mujoco_message(const std::string& message) {
  std::string first;
  std::istringstream lines(message);
  for (std::string l; std::getline(lines, l);) {
    if (l.empty() || l.rfind("Object name", 0) == 0 || l.rfind("Element ", 0) == 0) continue;
    if (first.empty()) first = l;
  }
  for (const char* prefix : {"XML Error: ", "Error: ", "Warning: "}) {
    if (first.rfind(prefix, 0) == 0) first = first.substr(std::string(prefix).size());
  }
  // The generated MJCF's names of what it means ("in object '' (id = 9)", ": puma/mesh1"): the origin names it.
  // (Parsed by hand, not with <regex>: GCC 12's -Wmaybe-uninitialized fires inside libstdc++'s regex in the sanitizer
  // builds.)
  const auto is_digit = [](char c) { return c >= '0' && c <= '9'; };
  const auto digits_from = [&](const std::string& text, std::size_t at) {  // the end of a run of digits at `at`
    while (at < text.size() && is_digit(text[at])) ++at;
    return at;
  };
  for (std::size_t at = first.find(" in object '"); at != std::string::npos;
       at = first.find(" in object '", at + 1)) {
    const std::size_t quote = first.find('\'', at + 12);
    if (quote == std::string::npos || first.compare(quote + 1, 7, " (id = ") != 0) continue;
    const std::size_t end = digits_from(first, quote + 8);
    if (end == quote + 8 || end >= first.size() || first[end] != ')') continue;
    first.erase(at, end + 1 - at);
    break;
  }
  if (const std::size_t colon = first.rfind(": "); colon != std::string::npos) {
    const std::string tail = first.substr(colon + 2);  // "<name>/mesh<digits>" to the end
    const std::size_t slash = tail.find('/');
    if (slash != std::string::npos && slash > 0 && tail.find_first_of(" :") == std::string::npos &&
        tail.compare(slash + 1, 4, "mesh") == 0 && tail.size() > slash + 5 &&
        digits_from(tail, slash + 5) == tail.size()) {
      first.erase(colon);
    }
  }
  int line = 0;
  for (std::size_t at = message.find("line"); at != std::string::npos; at = message.find("line", at + 1)) {
    std::size_t k = at + 4;
    if (message.compare(k, 2, " =") == 0) k += 2;
    if (k >= message.size() || message[k] != ' ') continue;
    const std::size_t end = digits_from(message, k + 1);
    if (end == k + 1) continue;
    line = std::stoi(message.substr(k + 1, end - k - 1));
    break;
  }
  return {first, line};
}

// What MuJoCo said about the scene as an InputError: at the URDF element (and the cell's robot entry) the generated
// element it names comes from; else at the cell file, the generated MJCF's line given as a hint only.
InputError mujoco_error(const std::string& message, bool warning, const Mjcf& mjcf,
                        const models::CellDescription& cell) {
  const auto [problem, line] = split_mujoco_message(message);
  const char* verb = warning ? "warns about" : "rejects";
  if (line > 0) {
    for (const std::size_t element : elements_at_line(mjcf.text, line)) {
      const auto it = mjcf.origins.find(element);
      if (it == mjcf.origins.end()) continue;
      const Origin& o = it->second;
      return InputError(o.at, fmt::format("robot '{}' ({}): {}: MuJoCo {} it: {}", o.robot->name, o.robot->where.str(),
                                          o.what, verb, problem));
    }
  }
  return InputError({cell.source.string(), 0, 0},
                    fmt::format("MuJoCo {} the scene built from this cell: {}{}", verb, problem,
                                line > 0 ? fmt::format(" (line {} of the generated MJCF, which twin snapshot --mjcf "
                                                       "FILE writes)",
                                                       line)
                                         : std::string()));
}

// Compiles MJCF text with MuJoCo from memory. Throws InputError (mujoco_error) with MuJoCo's error or warning.
mjModel* compile_mjcf(const Mjcf& built, const models::CellDescription& cell) {
  const std::string& mjcf = built.text;
  std::unique_ptr<mjVFS, VfsDeleter> vfs(new mjVFS);
  mj_defaultVFS(vfs.get());
  const char* kFile = "cell.xml";
  CW_CHECK(mj_makeEmptyFileVFS(vfs.get(), kFile, static_cast<int>(mjcf.size())) == 0, "VFS refused {}", kFile);
  const int index = mj_findFileVFS(vfs.get(), kFile);
  CW_CHECK(index >= 0, "VFS lost {}", kFile);
  std::copy(mjcf.begin(), mjcf.end(), static_cast<char*>(vfs->filedata[index]));
  std::array<char, 1024> error{};
  mjModel* model = mj_loadXML(kFile, vfs.get(), error.data(), static_cast<int>(error.size()));
  if (model == nullptr) throw mujoco_error(error.data(), false, built, cell);
  if (error[0] != '\0') {
    mj_deleteModel(model);
    // A compiler warning (e.g. an inertia fixed up): the model is not what the files describe.
    throw mujoco_error(error.data(), true, built, cell);
  }
  return model;
}

// The scene's MJCF and its origins: written once or, with links that have no mass, twice (scene_mjcf).
Mjcf build_mjcf(const models::CellDescription& cell, const SceneOptions& options) {
  const std::vector<RobotModel> robots = read_robot_models(cell);
  Builder b{cell, options};
  Mjcf mjcf{b.build(robots), std::move(b.origins)};
  if (b.massless.empty()) return mjcf;
  // Links without <inertial> got their mass from their geometry; MuJoCo computed it. Tune the servos with those
  // masses: compile once, read them, and write the scene again.
  LinkMasses estimated;
  {
    std::unique_ptr<mjModel, void (*)(mjModel*)> model(compile_mjcf(mjcf, cell), mj_deleteModel);
    const mjModel* m = model.get();
    for (const std::string& body : b.massless) {
      const int id = id_of(m, mjOBJ_BODY, body);
      estimated[body] = {m->body_mass[id],
                         Eigen::Vector3d(m->body_ipos[3 * id], m->body_ipos[3 * id + 1], m->body_ipos[3 * id + 2]),
                         0.5 * (m->body_inertia[3 * id] + m->body_inertia[3 * id + 1] + m->body_inertia[3 * id + 2])};
    }
  }
  Builder tuned{cell, options};
  tuned.estimated = std::move(estimated);
  std::string text = tuned.build(robots);
  return {std::move(text), std::move(tuned.origins)};
}

}  // namespace

bool is_scenery_body(const mjModel* m, int body) {
  if (body == 0) return true;
  const char* name = mj_id2name(m, mjOBJ_BODY, body);
  return name != nullptr && std::string_view(name).starts_with(kSceneryPrefix);
}

std::string scene_mjcf(const models::CellDescription& cell, const SceneOptions& options) {
  return build_mjcf(cell, options).text;
}

Scene::Scene(Scene&&) noexcept = default;
Scene& Scene::operator=(Scene&&) noexcept = default;
Scene::~Scene() = default;

Scene build_scene(const models::CellDescription& cell, const SceneOptions& options) {
  Scene s;
  s.cell_ = cell;
  Mjcf built = build_mjcf(cell, options);
  s.model_ = std::shared_ptr<const mjModel>(compile_mjcf(built, cell), mj_deleteModel);
  s.mjcf_ = std::move(built.text);
  s.data_.reset(mj_makeData(s.model_.get()));
  CW_CHECK(s.data_ != nullptr, "mj_makeData failed");
  const mjModel* m = s.model_.get();

  for (const auto& r : cell.robots) {
    RobotIds ids;
    ids.name = r.name;
    ids.home = r.home;
    ids.base_body = id_of(m, mjOBJ_BODY, r.name + "/" + r.base_link);
    ids.flange_body = id_of(m, mjOBJ_BODY, r.name + "/" + r.flange_link);
    ids.tcp_site = id_of(m, mjOBJ_SITE, r.name + "/tcp");
    ids.wrist_site = id_of(m, mjOBJ_SITE, r.name + "/wrist_ft");
    ids.wrist_force_sensor = id_of(m, mjOBJ_SENSOR, r.name + "/wrist_force");
    ids.wrist_torque_sensor = id_of(m, mjOBJ_SENSOR, r.name + "/wrist_torque");
    // Arm joints: those of the robot's chain from its base link to its tool, base to tip.
    const models::KinematicChain chain = models::robot_chain(r);
    for (const std::string& local : chain.joint_names()) {
      const std::string jn = r.name + "/" + local;
      const int j = id_of(m, mjOBJ_JOINT, jn);
      ids.joints.push_back(jn);
      ids.joint.push_back(j);
      ids.qpos_adr.push_back(m->jnt_qposadr[j]);
      ids.dof_adr.push_back(m->jnt_dofadr[j]);
      ids.actuator.push_back(id_of(m, mjOBJ_ACTUATOR, jn));
      ids.joint_pos_sensor.push_back(id_of(m, mjOBJ_SENSOR, jn + "_pos"));
    }
    CW_CHECK(ids.joints.size() == r.home.size(), "robot {}: {} arm joints in the scene, {} home angles", r.name,
             ids.joints.size(), r.home.size());
    for (int side = 0; side < 2; ++side) {
      const std::string finger = side == 0 ? "left" : "right";
      const std::string jn = fmt::format("{}/finger_{}_joint", r.name, finger);
      const int j = id_of(m, mjOBJ_JOINT, jn);
      ids.finger_joint[side] = j;
      ids.finger_qpos_adr[side] = m->jnt_qposadr[j];
      ids.finger_dof_adr[side] = m->jnt_dofadr[j];
      ids.finger_actuator[side] = id_of(m, mjOBJ_ACTUATOR, jn);
      ids.finger_pos_sensor[side] = id_of(m, mjOBJ_SENSOR, fmt::format("{}/finger_{}_pos", r.name, finger));
      ids.finger_touch_sensor[side] = id_of(m, mjOBJ_SENSOR, fmt::format("{}/finger_{}_touch", r.name, finger));
      ids.finger_range = {m->jnt_range[2 * j], m->jnt_range[2 * j + 1]};
    }
    s.robots_.push_back(std::move(ids));
  }
  for (const auto& c : cell.conveyors) {
    ConveyorIds ids;
    ids.name = c.name;
    ids.body = id_of(m, mjOBJ_BODY, "conveyor/" + c.name);
    ids.belt_body = id_of(m, mjOBJ_BODY, "conveyor/" + c.name + "/belt");
    ids.belt_joint = id_of(m, mjOBJ_JOINT, "conveyor/" + c.name + "/belt");
    ids.belt_qpos_adr = m->jnt_qposadr[ids.belt_joint];
    ids.belt_dof_adr = m->jnt_dofadr[ids.belt_joint];
    ids.belt_actuator = id_of(m, mjOBJ_ACTUATOR, "conveyor/" + c.name + "/belt");
    ids.speed = c.speed;
    ids.wrap = kBeltWrap;
    s.conveyors_.push_back(ids);
  }
  for (const auto& mc : cell.machines) {
    s.machines_.push_back(MachineIds{mc.name, id_of(m, mjOBJ_BODY, "machine/" + mc.name),
                                     id_of(m, mjOBJ_GEOM, "machine/" + mc.name + "/fixture")});
  }
  for (const auto& w : cell.workpieces) {
    WorkpieceIds ids;
    ids.name = w.name;
    ids.body = id_of(m, mjOBJ_BODY, "workpiece/" + w.name);
    ids.joint = id_of(m, mjOBJ_JOINT, "workpiece/" + w.name);
    ids.qpos_adr = m->jnt_qposadr[ids.joint];
    ids.dof_adr = m->jnt_dofadr[ids.joint];
    ids.geom = id_of(m, mjOBJ_GEOM, "workpiece/" + w.name);
    s.workpieces_.push_back(ids);
  }
  for (std::size_t i = 0; i < options.obstacles.size(); ++i) {
    ObstacleIds ids;
    ids.name = fmt::format("obstacle/{}", i + 1);
    ids.body = id_of(m, mjOBJ_BODY, ids.name);
    ids.mocap = m->body_mocapid[ids.body];
    ids.geom = id_of(m, mjOBJ_GEOM, ids.name);
    ids.size = options.obstacles[i];
    s.obstacles_.push_back(ids);
  }
  s.reset();
  return s;
}

Scene Scene::share() const {
  Scene s;
  s.cell_ = cell_;
  s.mjcf_ = mjcf_;
  s.model_ = model_;
  s.data_.reset(mj_makeData(model_.get()));
  CW_CHECK(s.data_ != nullptr, "mj_makeData failed");
  s.robots_ = robots_;
  s.conveyors_ = conveyors_;
  s.machines_ = machines_;
  s.workpieces_ = workpieces_;
  s.obstacles_ = obstacles_;
  s.reset();
  return s;
}

namespace {
template <typename T>
const T* find_by_name(const std::vector<T>& v, std::string_view name) {
  for (const auto& e : v) {
    if (e.name == name) return &e;
  }
  return nullptr;
}
}  // namespace

const RobotIds* Scene::find_robot(std::string_view name) const {
  return find_by_name(robots_, name);
}
const ConveyorIds* Scene::find_conveyor(std::string_view name) const {
  return find_by_name(conveyors_, name);
}
const WorkpieceIds* Scene::find_workpiece(std::string_view name) const {
  return find_by_name(workpieces_, name);
}

int Scene::camera_id(std::string_view name) const {
  return mj_name2id(model_.get(), mjOBJ_CAMERA, std::string(name).c_str());
}

void Scene::reset() {
  const int key = mj_name2id(model_.get(), mjOBJ_KEY, "initial");
  CW_CHECK(key >= 0, "the scene has no 'initial' keyframe");
  mj_resetDataKeyframe(model_.get(), data_.get(), key);
  mj_forward(model_.get(), data_.get());
}

void Scene::step(int n) {
  for (int i = 0; i < n; ++i) {
    mj_step(model_.get(), data_.get());
    wrap_belts(data_.get());
  }
}

void write_mjcf(const std::string& mjcf, const std::filesystem::path& path) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const std::filesystem::path tmp =
      dir / fmt::format(".{}.{}.tmp", path.filename().string(), static_cast<long>(::getpid()));
  std::error_code ec;
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << mjcf;
    out.close();
    if (!out) {
      std::filesystem::remove(tmp, ec);
      throw InputError({path.string(), 0, 0}, "cannot write the MJCF file (does its directory exist?)");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    const std::string message = ec.message();
    std::filesystem::remove(tmp, ec);
    throw InputError({path.string(), 0, 0}, fmt::format("cannot write the MJCF file: {}", message));
  }
}

void place_free_body(const mjModel* m, mjData* d, int body, const double pose[7]) {
  CW_CHECK(body > 0 && body < m->nbody && m->body_parentid[body] == 0 && m->body_jntnum[body] == 1 &&
               m->jnt_type[m->body_jntadr[body]] == mjJNT_FREE && m->body_mocapid[body] < 0,
           "body {} is not a free body of the world", body);
  mjtNum* q = d->qpos + m->jnt_qposadr[m->body_jntadr[body]];
  mju_copy(q, pose, 7);
  mju_normalize4(q + 3);  // as mj_kinematics normalises the quaternions of qpos first
  mjtNum quat[4];
  mju_copy4(quat, q + 3);
  mju_normalize4(quat);  // and then the body's own
  mju_copy4(d->xquat + 4 * body, quat);
  mju_copy3(d->xpos + 3 * body, q);
  mju_quat2Mat(d->xmat + 9 * body, quat);
  mj_local2Global(d, d->xipos + 3 * body, d->ximat + 9 * body, m->body_ipos + 3 * body, m->body_iquat + 4 * body, body,
                  m->body_sameframe[body]);
  for (int g = m->body_geomadr[body]; g < m->body_geomadr[body] + m->body_geomnum[body]; ++g) {
    mj_local2Global(d, d->geom_xpos + 3 * g, d->geom_xmat + 9 * g, m->geom_pos + 3 * g, m->geom_quat + 4 * g, body,
                    m->geom_sameframe[g]);
  }
  for (int i = 0; i < m->nsite; ++i) {
    if (m->site_bodyid[i] != body) continue;
    mj_local2Global(d, d->site_xpos + 3 * i, d->site_xmat + 9 * i, m->site_pos + 3 * i, m->site_quat + 4 * i, body,
                    m->site_sameframe[i]);
  }
}

GeomRole geom_role(const Scene& scene, int geom) {
  const mjModel* m = scene.model();
  GeomRole out;
  if (m->geom_contype[geom] == 0 && m->geom_conaffinity[geom] == 0) return out;
  const char* g = mj_id2name(m, mjOBJ_GEOM, geom);
  const std::string gname = g != nullptr ? g : "";
  const int b = m->geom_bodyid[geom];
  const char* bn = mj_id2name(m, mjOBJ_BODY, b);
  const std::string body = bn != nullptr ? bn : "";
  const auto starts = [](const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; };
  out.kind = GeomRole::Kind::fixed;
  if (is_scenery_body(m, b)) {
    out.name = gname == "floor"            ? "the floor"
               : starts(gname, "stand/") ? fmt::format("the stand of location '{}'", gname.substr(6))
                                         : fmt::format("'{}'", gname);
    for (std::size_t r = 0; r < scene.robots().size(); ++r) {
      if (gname == scene.robots()[r].name + "/pedestal") {
        out.mount_of = static_cast<int>(r);
        out.name = fmt::format("robot '{}''s pedestal", scene.robots()[r].name);
      }
    }
  } else if (starts(body, "conveyor/")) {
    const std::string name = body.substr(9);
    if (name.find('/') != std::string::npos) {
      out.kind = GeomRole::Kind::belt;
      return out;
    }
    out.name = fmt::format("conveyor '{}' ({})", name,
                           gname == body + "/stop"               ? "stop bar"
                           : gname == body + "/frame"            ? "frame"
                           : gname.starts_with(body + "/guide_") ? "side guide"
                                                                 : gname);
  } else if (starts(body, "machine/")) {
    out.name = fmt::format("machine '{}'{}", body.substr(8), gname == body + "/fixture" ? " (fixture)" : "");
  } else if (starts(body, "obstacle/")) {
    out.kind = GeomRole::Kind::obstacle;
  } else if (starts(body, "workpiece/")) {
    out.kind = GeomRole::Kind::workpiece;
    for (std::size_t w = 0; w < scene.workpieces().size(); ++w) {
      if (scene.workpieces()[w].body == b) out.index = static_cast<int>(w);
    }
    CW_CHECK(out.index >= 0, "workpiece body {} not among the scene's workpieces", body);
    out.name = fmt::format("workpiece '{}'", body.substr(10));
  } else {
    out.name = fmt::format("'{}'", body);
    for (std::size_t r = 0; r < scene.robots().size(); ++r) {
      const std::string prefix = scene.robots()[r].name + "/";
      if (starts(body, prefix)) {
        out.kind = GeomRole::Kind::robot;
        out.index = static_cast<int>(r);
        out.name = fmt::format("link '{}'", body.substr(prefix.size()));
      }
    }
  }
  return out;
}

std::string StartOverlap::text() const {
  return fmt::format("robot '{}''s {} and {} overlap by {:.0f} mm", robot, body,
                     other_robot.empty() ? other : fmt::format("robot '{}''s {}", other_robot, other), depth * 1000);
}

std::vector<StartOverlap> start_overlaps(const Scene& scene, double depth) {
  const mjData* d = scene.data();
  // By robot, then the other robot (or the fixed object): the deepest contact.
  std::map<std::pair<int, std::string>, StartOverlap> found;
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if (con.dist >= -depth) continue;
    // A robot's body against another robot's or the fixed cell (parts, belts and obstacles are not judged here).
    GeomRole a = geom_role(scene, con.geom1), b = geom_role(scene, con.geom2);
    using Kind = GeomRole::Kind;
    const auto judged = [](const GeomRole& r) { return r.kind == Kind::robot || r.kind == Kind::fixed; };
    if (!judged(a) || !judged(b)) continue;
    if (a.kind != Kind::robot || (b.kind == Kind::robot && b.index < a.index)) std::swap(a, b);
    if (a.kind != Kind::robot || (b.kind == Kind::robot && a.index == b.index) || a.index == b.mount_of) continue;
    const auto& robots = scene.robots();
    const bool two_robots = b.kind == Kind::robot;
    const std::string other_robot = two_robots ? robots[static_cast<std::size_t>(b.index)].name : std::string();
    const auto key = std::make_pair(a.index, two_robots ? "robot " + other_robot : b.name);
    StartOverlap& o = found[key];
    if (-con.dist <= o.depth) continue;
    const std::string& robot = robots[static_cast<std::size_t>(a.index)].name;
    o = {robot, a.name, other_robot, b.name, -con.dist, scene.cell().find_robot(robot)->where,
         other_robot.empty() ? SourceLocation{} : scene.cell().find_robot(other_robot)->where};
  }
  std::vector<StartOverlap> out;
  for (auto& [key, o] : found) out.push_back(std::move(o));
  return out;
}

InputError start_overlap_error(const std::vector<StartOverlap>& overlaps) {
  CW_CHECK(!overlaps.empty(), "no overlap to report");
  std::vector<std::string> what, entries;
  for (const StartOverlap& o : overlaps) {
    what.push_back(o.text());
    for (const SourceLocation& at : {o.where, o.other_where}) {
      if (!at.file.empty() && std::find(entries.begin(), entries.end(), at.str()) == entries.end()) {
        entries.push_back(at.str());
      }
    }
  }
  return InputError(overlaps.front().where,
                    fmt::format("at the start, with every robot at home: {}; move a robot's base or change its home "
                                "(the robots' entries: {})",
                                fmt::join(what, "; "), fmt::join(entries, ", ")));
}

void Scene::wrap_belts(mjData* d) const {
  for (const auto& c : conveyors_) {
    mjtNum& q = d->qpos[c.belt_qpos_adr];
    if (q >= c.wrap) q -= c.wrap;
    if (q < 0) q += c.wrap;
  }
}

}  // namespace cellwright::twin
