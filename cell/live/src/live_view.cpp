#include "live_view.hpp"

#include <fmt/format.h>
#include <mujoco/mujoco.h>

#include <chrono>
#include <deque>

#include "cellwright/runtime/log_event.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace cellwright::cell::view {

namespace {

using nlohmann::json;

double seconds(runtime::SimDuration t) { return std::chrono::duration<double>(t).count(); }

json vec3(const double* p) { return json::array({p[0], p[1], p[2]}); }

// Where a collision of bodies `a` and `b` is: a contact between them now, else half-way between the bodies.
json collision_pos(const mjModel* m, const mjData* d, const std::string& a, const std::string& b) {
  const int ba = mj_name2id(m, mjOBJ_BODY, a.c_str()), bb = mj_name2id(m, mjOBJ_BODY, b.c_str());
  for (int i = 0; i < d->ncon; ++i) {
    const int g1 = m->geom_bodyid[d->contact[i].geom1], g2 = m->geom_bodyid[d->contact[i].geom2];
    if ((g1 == ba && g2 == bb) || (g1 == bb && g2 == ba)) return vec3(d->contact[i].pos);
  }
  if (ba < 0 && bb < 0) return json::array({0.0, 0.0, 0.0});
  if (ba < 0 || bb < 0) return vec3(d->xpos + 3 * (ba < 0 ? bb : ba));
  const double* pa = d->xpos + 3 * ba;
  const double* pb = d->xpos + 3 * bb;
  return json::array({(pa[0] + pb[0]) / 2, (pa[1] + pb[1]) / 2, (pa[2] + pb[2]) / 2});
}

// The tool of cell robot `robot`, or of the robot bound to program label `robot`; null if neither.
json tool_pos(ScenarioRun& run, const std::string& robot) {
  const twin::Scene& scene = run.world().scene();
  const twin::RobotIds* ids = scene.find_robot(robot);
  if (!ids) {
    for (const Binding& b : run.scenario().robots) {
      if (b.label == robot) ids = scene.find_robot(b.name);
    }
  }
  if (!ids || ids->tcp_site < 0) return nullptr;
  return vec3(run.world().data()->site_xpos + 3 * ids->tcp_site);
}

json workpiece_pos(ScenarioRun& run, const std::string& workpiece) {
  const twin::WorkpieceIds* w = run.world().scene().find_workpiece(workpiece);
  if (!w || w->body < 0) return nullptr;
  return vec3(run.world().data()->xpos + 3 * w->body);
}

}  // namespace

const char* shape_of(int type) {
  switch (type) {
    case mjGEOM_BOX: return "box";
    case mjGEOM_CYLINDER: return "cylinder";
    case mjGEOM_SPHERE: return "sphere";
    case mjGEOM_CAPSULE: return "capsule";
    case mjGEOM_PLANE: return "plane";
    default: return nullptr;  // meshes (the robots' and imported ones) and the rest are not sent
  }
}

// The bodies of the robots' subtrees (drawn from the URDFs on the page).
std::vector<bool> robot_bodies(const twin::Scene& scene) {
  const mjModel* m = scene.model();
  std::vector<bool> robot(static_cast<std::size_t>(m->nbody), false);
  for (const twin::RobotIds& r : scene.robots()) {
    if (r.base_body < 0) continue;
    const int root = m->body_rootid[r.base_body];
    for (int b = 0; b < m->nbody; ++b) {
      if (m->body_rootid[b] == root && b != 0) robot[static_cast<std::size_t>(b)] = true;
    }
  }
  return robot;
}

// The bodies the cell message lists, in id order: those of the sent geoms.
std::vector<int> sent_bodies(const twin::Scene& scene) {
  const mjModel* m = scene.model();
  const std::vector<bool> robot = robot_bodies(scene);
  std::vector<bool> used(static_cast<std::size_t>(m->nbody), false);
  for (int g = 0; g < m->ngeom; ++g) {
    const int b = m->geom_bodyid[g];
    if (!robot[static_cast<std::size_t>(b)] && shape_of(m->geom_type[g]) && m->geom_rgba[4 * g + 3] > 0) {
      used[static_cast<std::size_t>(b)] = true;
    }
  }
  std::vector<int> out;
  for (int b = 0; b < m->nbody; ++b) {
    if (used[static_cast<std::size_t>(b)]) out.push_back(b);
  }
  return out;
}

bool moves(const mjModel* m, int body) {
  // Welded to a body with a joint (any ancestor's, not only the root's or its own), or under a mocap body.
  return m->body_weldid[body] != 0 || m->body_mocapid[m->body_rootid[body]] >= 0;
}

std::string body_name(const mjModel* m, int b) {
  const char* n = mj_id2name(m, mjOBJ_BODY, b);
  return n ? n : fmt::format("body {}", b);
}

json cameras(ScenarioRun& run) {
  const twin::Scene& scene = run.world().scene();
  const mjModel* m = scene.model();
  const mjData* d = run.world().data();
  json out = json::array();
  for (const models::CameraSpec& c : run.scenario().cell.cameras) {
    const int id = scene.camera_id(c.name);
    if (id < 0) continue;
    mjtNum q[4];
    mju_mat2Quat(q, d->cam_xmat + 9 * id);
    out.push_back({{"name", c.name},
                   {"pos", vec3(d->cam_xpos + 3 * id)},
                   {"quat", {q[0], q[1], q[2], q[3]}},
                   {"fovy", m->cam_fovy[id]},
                   {"resolution", {c.width, c.height}}});
  }
  return out;
}

json mark(ScenarioRun& run, const std::string& line) {
  const mjModel* m = run.world().scene().model();
  const mjData* d = run.world().data();
  runtime::LogEvent e;
  try {
    e = runtime::decode(line, "event log", 0);
  } catch (const std::exception&) {
    return nullptr;  // the loop hands over lines the log wrote: they decode
  }
  json pos;
  const char* kind = "fault";
  if (const auto* c = std::get_if<runtime::events::Collision>(&e)) {
    kind = "collision";
    pos = collision_pos(m, d, c->a, c->b);
  } else if (const auto* fi = std::get_if<runtime::events::FaultInjected>(&e)) {
    pos = tool_pos(run, fi->robot);
    if (pos.is_null()) pos = workpiece_pos(run, fi->workpiece);
  } else if (const auto* fd = std::get_if<runtime::events::FaultDetected>(&e)) {
    pos = tool_pos(run, fd->robot);
  }
  if (pos.is_null()) pos = json::array({0.0, 0.0, 0.0});
  return {{"kind", kind}, {"text", line}, {"pos", pos}};
}

json gantt(ScenarioRun& run) {
  const runtime::EventLog& log = run.runtime().log();
  if (!log.keeps_lines()) return nullptr;
  std::deque<json> out;
  for (const std::string& line : log.lines()) {
    if (line.find("\"type\":\"command_") == std::string::npos) continue;
    const runtime::LogEvent e = runtime::decode(line, "event log", 0);
    if (const auto* s = std::get_if<runtime::events::CommandStart>(&e)) {
      out.push_back({{"robot", s->robot}, {"command", s->command}, {"start", seconds(s->t)}, {"end", nullptr},
                     {"ok", true}});
      if (out.size() > 400) out.pop_front();
    } else if (const auto* c = std::get_if<runtime::events::CommandEnd>(&e)) {
      for (auto it = out.rbegin(); it != out.rend(); ++it) {
        if ((*it)["robot"] == c->robot && (*it)["end"].is_null()) {
          (*it)["end"] = seconds(c->t);
          (*it)["ok"] = c->ok;
          break;
        }
      }
    }
  }
  return json(std::vector<json>(out.begin(), out.end()));
}

}  // namespace cellwright::cell::view
