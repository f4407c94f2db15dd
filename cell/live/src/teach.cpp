#include "cellwright/cell/live/teach.hpp"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "cellwright/models/robot_model.hpp"
#include "cellwright/twin/scene.hpp"

namespace cellwright::cell {

namespace {

using nlohmann::json;

double number(const json& j, const char* field) {
  const auto it = j.find(field);
  if (it == j.end() || !it->is_number()) throw LiveRefusal(fmt::format("a teach '{}' needs \"{}\" (a number)",
                                                                       j.value("action", ""), field));
  const double v = it->get<double>();
  if (!std::isfinite(v)) throw LiveRefusal(fmt::format("\"{}\" is not finite", field));
  return v;
}

// The last part of a MuJoCo name: "puma/joint1" -> "joint1".
std::string last_part(const std::string& name) {
  const auto slash = name.rfind('/');
  return slash == std::string::npos ? name : name.substr(slash + 1);
}

json pose7(const Eigen::Isometry3d& t) {
  const Eigen::Quaterniond q(t.linear());
  return json::array({t.translation().x(), t.translation().y(), t.translation().z(), q.w(), q.x(), q.y(), q.z()});
}

}  // namespace

TeachRequest parse_teach(std::string_view text) {
  const json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) throw LiveRefusal("a teach message is a JSON object");
  TeachRequest r;
  const auto robot = j.find("robot");
  if (robot == j.end() || !robot->is_string() || robot->get<std::string>().empty()) {
    throw LiveRefusal("a teach message needs \"robot\" (a robot's name)");
  }
  r.robot = robot->get<std::string>();
  const std::string action = j.value("action", "");
  if (action == "begin") {
    r.action = TeachAction::kBegin;
  } else if (action == "end") {
    r.action = TeachAction::kEnd;
  } else if (action == "joint") {
    r.action = TeachAction::kJoint;
    const auto i = j.find("joint");
    if (i == j.end() || !i->is_number_integer()) throw LiveRefusal("a teach 'joint' needs \"joint\" (a 0-based index)");
    r.joint = i->get<int>();
    r.delta = number(j, "delta");
  } else if (action == "cartesian") {
    r.action = TeachAction::kCartesian;
    r.axis = j.value("axis", "");
    if (r.axis != "x" && r.axis != "y" && r.axis != "z" && r.axis != "yaw") {
      throw LiveRefusal("a teach 'cartesian' needs \"axis\": \"x\", \"y\", \"z\" or \"yaw\"");
    }
    r.delta = number(j, "delta");
  } else if (action == "joints") {
    r.action = TeachAction::kJoints;
    const auto q = j.find("joints");
    if (q == j.end() || !q->is_array()) throw LiveRefusal("a teach 'joints' needs \"joints\" (an array of radians)");
    for (const json& v : *q) {
      if (!v.is_number() || !std::isfinite(v.get<double>())) throw LiveRefusal("\"joints\" holds a non-number");
      r.joints.push_back(v.get<double>());
    }
  } else {
    throw LiveRefusal(fmt::format("unknown teach action '{}' (begin, joint, cartesian, joints or end)", action));
  }
  return r;
}

std::string teach_json(const TeachState& s) {
  if (!s.active) return json{{"type", "teach"}, {"robot", s.robot}, {"active", false}}.dump();
  json contacts = json::array();
  for (const TeachContact& c : s.collisions) {
    contacts.push_back({{"a", c.a}, {"b", c.b}, {"pos", {c.pos.x(), c.pos.y(), c.pos.z()}}, {"depth", c.depth}});
  }
  return json{{"type", "teach"},
              {"robot", s.robot},
              {"active", true},
              {"joints", std::vector<double>(s.joints.data(), s.joints.data() + s.joints.size())},
              {"tool", pose7(s.tool)},
              {"reachable", s.reachable},
              {"at_limit", s.at_limit},
              {"reason", s.reason},
              {"collisions", contacts}}
      .dump();
}

struct Teacher::Robot {
  const models::RobotSpec* spec = nullptr;
  models::KinematicChain chain;
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  int index = -1;                // in the scene's robots
  std::vector<int> qpos_adr;     // per chain joint, the scene's qpos address
};

Teacher::Teacher(const Scenario& scenario) : scenario_(scenario) {
  for (const models::RobotSpec& spec : scenario.cell.robots) {
    auto r = std::unique_ptr<Robot>(new Robot{&spec, models::robot_chain(spec), spec.base.transform(), -1, {}});
    robots_.emplace(spec.name, std::move(r));
  }
}

Teacher::~Teacher() {
  if (scratch_) mj_deleteData(scratch_);
}

std::string Teacher::robot_name(const std::string& name) const {
  if (robots_.count(name) != 0) return name;
  for (const Binding& b : scenario_.robots) {
    if (b.label == name) return b.name;
  }
  return {};
}

const TeachState* Teacher::state(const std::string& robot) const {
  const auto it = states_.find(robot);
  return it == states_.end() ? nullptr : &it->second;
}

std::vector<std::string> Teacher::active() const {
  std::vector<std::string> out;
  for (const auto& [name, s] : states_) out.push_back(name);
  return out;
}

TeachState Teacher::apply(const TeachRequest& req, const twin::sim::World& world) {
  const std::string name = robot_name(req.robot);
  if (name.empty()) throw LiveRefusal(fmt::format("no robot '{}' in the cell", req.robot));
  Robot& r = *robots_.at(name);
  const twin::Scene& scene = world.scene();
  if (r.index < 0) {
    const twin::RobotIds* ids = scene.find_robot(name);
    if (!ids) throw LiveRefusal(fmt::format("robot '{}' is not in the twin's scene", name));
    r.index = static_cast<int>(ids - scene.robots().data());
    for (const std::string& joint : r.chain.joint_names()) {
      int adr = -1;
      for (std::size_t k = 0; k < ids->joints.size(); ++k) {
        if (last_part(ids->joints[k]) == joint) adr = ids->qpos_adr[k];
      }
      if (adr < 0) throw LiveRefusal(fmt::format("robot '{}': joint '{}' is not in the twin's scene", name, joint));
      r.qpos_adr.push_back(adr);
    }
  }
  if (req.action == TeachAction::kBegin) {
    TeachState s;
    s.robot = name;
    s.active = true;
    s.joints.resize(static_cast<Eigen::Index>(r.qpos_adr.size()));
    for (std::size_t k = 0; k < r.qpos_adr.size(); ++k) s.joints[static_cast<Eigen::Index>(k)] = world.data()->qpos[r.qpos_adr[k]];
    refresh(r, s, world);
    return states_[name] = s;
  }
  const auto it = states_.find(name);
  if (it == states_.end()) throw LiveRefusal(fmt::format("robot '{}' is not being taught (send \"begin\" first)", name));
  TeachState s = it->second;
  s.reason.clear();
  s.reachable = true;
  const auto& limits = r.chain.limits();
  const auto n = static_cast<int>(r.chain.dof());
  switch (req.action) {
    case TeachAction::kBegin: break;
    case TeachAction::kEnd:
      states_.erase(it);
      return TeachState{name, false, {}, Eigen::Isometry3d::Identity(), true, {}, "", {}};
    case TeachAction::kJoint: {
      if (req.joint < 0 || req.joint >= n) {
        throw LiveRefusal(fmt::format("robot '{}' has joints 0 to {}, not {}", name, n - 1, req.joint));
      }
      const auto& lim = limits[static_cast<std::size_t>(req.joint)];
      const double want = s.joints[req.joint] + req.delta;
      s.joints[req.joint] = std::clamp(want, lim.lower, lim.upper);
      if (s.joints[req.joint] != want) {
        s.reason = fmt::format("{} stopped at its limit {:.4f} ({} asked)", r.chain.joint_names()[static_cast<std::size_t>(req.joint)],
                               s.joints[req.joint], want);
      }
      break;
    }
    case TeachAction::kJoints: {
      if (static_cast<int>(req.joints.size()) != n) {
        throw LiveRefusal(fmt::format("robot '{}' has {} joints, {} were given", name, n, req.joints.size()));
      }
      for (int k = 0; k < n; ++k) {
        const auto& lim = limits[static_cast<std::size_t>(k)];
        const double v = req.joints[static_cast<std::size_t>(k)];
        if (v < lim.lower || v > lim.upper) {
          throw LiveRefusal(fmt::format("robot '{}': {} = {} is outside its limits [{}, {}]", name,
                                        r.chain.joint_names()[static_cast<std::size_t>(k)], v, lim.lower, lim.upper));
        }
        s.joints[k] = v;
      }
      break;
    }
    case TeachAction::kCartesian: {
      Eigen::Isometry3d target = s.tool;
      if (req.axis == "yaw") {
        target.linear() = Eigen::AngleAxisd(req.delta, Eigen::Vector3d::UnitZ()) * s.tool.linear();
      } else {
        const int axis = req.axis == "x" ? 0 : req.axis == "y" ? 1 : 2;
        target.translation()[axis] += req.delta;
      }
      const models::IkResult ik = r.chain.inverse(r.base.inverse() * target, s.joints);
      if (ik.status != models::IkStatus::kOk) {
        s.reachable = false;
        s.reason = fmt::format("cannot move the tool {} {} {}: {}", req.delta, req.axis == "yaw" ? "rad about" : "m along",
                               req.axis == "yaw" ? "z" : req.axis, ik.reason);
        it->second.reachable = false;
        it->second.reason = s.reason;
        return it->second;  // the pose unchanged
      }
      s.joints = ik.q;
      break;
    }
  }
  refresh(r, s, world);
  return it->second = s;
}

void Teacher::refresh(Robot& r, TeachState& s, const twin::sim::World& world) {
  s.tool = r.base * r.chain.forward(s.joints);
  s.at_limit.clear();
  const auto& limits = r.chain.limits();
  for (Eigen::Index k = 0; k < s.joints.size(); ++k) {
    const auto& lim = limits[static_cast<std::size_t>(k)];
    if (s.joints[k] <= lim.lower || s.joints[k] >= lim.upper) s.at_limit.push_back(static_cast<int>(k));
  }
  // Collisions: the run's state on a scratch mjData, this robot's arm at the teach pose.
  const twin::Scene& scene = world.scene();
  const mjModel* m = scene.model();
  if (scratch_model_ != m) {
    if (scratch_) mj_deleteData(scratch_);
    scratch_ = mj_makeData(m);
    scratch_model_ = m;
  }
  mj_copyData(scratch_, m, world.data());
  for (std::size_t k = 0; k < r.qpos_adr.size(); ++k) scratch_->qpos[r.qpos_adr[k]] = s.joints[static_cast<Eigen::Index>(k)];
  mj_kinematics(m, scratch_);
  mj_comPos(m, scratch_);
  mj_collision(m, scratch_);
  auto describe = [&](int g) {
    const twin::GeomRole role = twin::geom_role(scene, g);
    if (role.kind == twin::GeomRole::Kind::robot && role.index >= 0) {
      return fmt::format("{} {}", scene.robots()[static_cast<std::size_t>(role.index)].name, role.name);
    }
    if (!role.name.empty()) return role.name;
    const char* body = mj_id2name(m, mjOBJ_BODY, m->geom_bodyid[g]);
    return std::string(body ? body : "?");
  };
  s.collisions.clear();
  for (int c = 0; c < scratch_->ncon; ++c) {
    const mjContact& con = scratch_->contact[c];
    if (con.dist > -kTeachContactDepth) continue;
    int mine = con.geom1, other = con.geom2;
    twin::GeomRole a = twin::geom_role(scene, mine), b = twin::geom_role(scene, other);
    auto ours = [&](const twin::GeomRole& g) { return g.kind == twin::GeomRole::Kind::robot && g.index == r.index; };
    if (!ours(a)) {
      std::swap(mine, other);
      std::swap(a, b);
    }
    if (!ours(a) || ours(b)) continue;  // not this robot's, or against itself
    if (b.kind == twin::GeomRole::Kind::workpiece || b.kind == twin::GeomRole::Kind::none) continue;
    s.collisions.push_back({describe(mine), describe(other), Eigen::Vector3d(con.pos[0], con.pos[1], con.pos[2]),
                            -con.dist});
  }
}

}  // namespace cellwright::cell
