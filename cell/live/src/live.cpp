#include "cellwright/cell/live/live.hpp"

#include <fmt/format.h>
#include <mujoco/mujoco.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "live_view.hpp"

namespace cellwright::cell {

namespace {

using nlohmann::json;

std::filesystem::path common_dir(const std::filesystem::path& a, const std::filesystem::path& b) {
  std::filesystem::path out;
  auto i = a.begin(), j = b.begin();
  for (; i != a.end() && j != b.end() && *i == *j; ++i, ++j) out /= *i;
  return out;
}

std::string url_under(const std::filesystem::path& models, const std::filesystem::path& file) {
  return "/models/" + std::filesystem::relative(file, models).generic_string();
}

json pose7(const double* pos, const double* quat) {
  return json::array({pos[0], pos[1], pos[2], quat[0], quat[1], quat[2], quat[3]});
}

const char* role_name(twin::GeomRole::Kind k) {
  switch (k) {
    case twin::GeomRole::Kind::none: return "visual";
    case twin::GeomRole::Kind::fixed: return "fixed";
    case twin::GeomRole::Kind::belt: return "belt";
    case twin::GeomRole::Kind::robot: return "robot";
    case twin::GeomRole::Kind::workpiece: return "workpiece";
    case twin::GeomRole::Kind::obstacle: return "obstacle";
  }
  return "?";
}

// The last part of a MuJoCo joint name: "puma/joint1" -> "joint1" (the URDF's own name).
std::string urdf_joint(const std::string& mj_name) {
  const auto slash = mj_name.rfind('/');
  return slash == std::string::npos ? mj_name : mj_name.substr(slash + 1);
}

}  // namespace

std::filesystem::path models_root(const Scenario& scenario) {
  std::optional<std::filesystem::path> root;
  auto take = [&](const std::filesystem::path& dir) {
    const std::filesystem::path d = dir.lexically_normal();
    root = root ? common_dir(*root, d) : d;
  };
  for (const models::RobotSpec& r : scenario.cell.robots) {
    take(r.urdf.parent_path());
    for (const std::filesystem::path& p : r.package_path) take(p);
  }
  if (!root) return {};  // no robots: nothing to serve
  if (*root == root->root_path()) {
    throw InputError({scenario.cell.source.string(), 0, 0},
                     "the robots' URDFs and mesh packages have no directory in common but the file system's root, "
                     "which the live view will not serve: keep them under one directory");
  }
  return *root;
}

std::string live_cell_json(ScenarioRun& run, const std::filesystem::path& models) {
  const Scenario& s = run.scenario();
  const twin::Scene& scene = run.world().scene();
  const mjModel* m = scene.model();
  const mjData* d = run.world().data();
  json robots = json::array();
  for (const Binding& b : s.robots) {
    const models::RobotSpec* spec = s.cell.find_robot(b.name);
    const twin::RobotIds* ids = scene.find_robot(b.name);
    if (!spec || !ids) continue;
    json packages = json::object();
    for (const std::filesystem::path& dir : spec->package_path) {
      std::error_code ec;
      for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (e.is_directory() && !packages.contains(name)) packages[name] = url_under(models, e.path());
      }
    }
    json joints = json::array();
    for (const std::string& j : ids->joints) joints.push_back(urdf_joint(j));
    const int base = ids->base_body;
    robots.push_back({{"name", b.name},
                      {"label", b.label},
                      {"urdf", url_under(models, spec->urdf)},
                      {"packages", packages},
                      {"base_link", spec->base_link},
                      {"base", base >= 0 ? pose7(d->xpos + 3 * base, d->xquat + 4 * base) : json()},
                      {"joints", joints}});
  }
  const std::vector<int> bodies = view::sent_bodies(scene);
  std::vector<bool> listed(static_cast<std::size_t>(m->nbody), false);
  json jb = json::array();
  for (int b : bodies) {
    listed[static_cast<std::size_t>(b)] = true;
    jb.push_back({{"id", b}, {"name", view::body_name(m, b)}, {"pose", pose7(d->xpos + 3 * b, d->xquat + 4 * b)},
                  {"moves", view::moves(m, b)}});
  }
  json geoms = json::array();
  for (int g = 0; g < m->ngeom; ++g) {
    const int b = m->geom_bodyid[g];
    const char* shape = view::shape_of(m->geom_type[g]);
    if (!listed[static_cast<std::size_t>(b)] || !shape || m->geom_rgba[4 * g + 3] <= 0) continue;
    const mjtNum* sz = m->geom_size + 3 * g;
    // MuJoCo draws a geom with a material in the material's colour (conveyors, machines): so does the page.
    const int mat = m->geom_matid[g];
    const float* c = mat >= 0 ? m->mat_rgba + 4 * mat : m->geom_rgba + 4 * g;
    const mjtNum* p = m->geom_pos + 3 * g;
    const mjtNum* q = m->geom_quat + 4 * g;
    geoms.push_back({{"body", b},
                     {"shape", shape},
                     {"size", {sz[0], sz[1], sz[2]}},
                     {"pos", {p[0], p[1], p[2]}},
                     {"quat", {q[0], q[1], q[2], q[3]}},
                     {"rgba", {c[0], c[1], c[2], c[3]}},
                     {"role", role_name(twin::geom_role(scene, g).kind)}});
  }
  return json{{"type", "cell"},
              {"name", s.cell.name},
              {"scenario", s.source.filename().string()},
              {"mode", run.realtime() ? "real time" : "lock-step"},
              {"program", s.program_file.filename().string()},
              {"robots", robots},
              {"bodies", jb},
              {"geoms", geoms},
              {"cameras", view::cameras(run)}}
      .dump();
}

void FaultMarks::add(std::string line) {
  std::lock_guard lock(mutex_);
  if (marks_.size() < 200) marks_.push_back({std::move(line), "", std::nullopt});
}

void FaultMarks::place_new(ScenarioRun& run) {
  std::vector<std::string> lines;
  std::size_t first = 0;
  {
    std::lock_guard lock(mutex_);
    while (first < marks_.size() && marks_[first].pos) ++first;
    for (std::size_t i = first; i < marks_.size(); ++i) lines.push_back(marks_[i].line);
  }
  if (lines.empty()) return;
  std::vector<json> placed;
  for (const std::string& line : lines) placed.push_back(view::mark(run, line));
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < placed.size(); ++i) {
    Mark& mk = marks_[first + i];  // only add() changes marks_ meanwhile, and it appends
    if (placed[i].is_null()) {
      mk.kind = "fault";
      mk.pos = std::array<double, 3>{0, 0, 0};
    } else {
      mk.kind = placed[i]["kind"].get<std::string>();
      mk.pos = placed[i]["pos"].get<std::array<double, 3>>();
    }
  }
}

std::vector<FaultMarks::Mark> FaultMarks::marks() const {
  std::lock_guard lock(mutex_);
  return marks_;
}

std::string live_frame_json(ScenarioRun& run, const LiveFrameState& state, const FaultMarks& fault_marks) {
  const Scenario& s = run.scenario();
  const twin::Scene& scene = run.world().scene();
  const mjModel* m = scene.model();
  const mjData* d = run.world().data();
  const petri::Net& net = run.runtime().config().net;
  const runtime::StepState* st = state.step;
  json robots = json::array();
  for (std::size_t i = 0; i < s.robots.size(); ++i) {
    const twin::RobotIds* ids = scene.find_robot(s.robots[i].name);
    if (!ids) continue;
    json joints = json::array();
    for (int adr : ids->qpos_adr) joints.push_back(d->qpos[adr]);
    double fingers = 0;
    for (int adr : ids->finger_qpos_adr) fingers += adr >= 0 ? d->qpos[adr] : 0;
    json r = {{"name", s.robots[i].name}, {"label", s.robots[i].label}, {"joints", joints}, {"fingers", fingers}};
    if (st && i < st->task.robots.size()) {
      const runtime::RobotView& v = st->task.robots[i];
      r["activity"] = v.done ? "done" : runtime::to_string(v.activity);
      r["command"] = v.command;
    }
    if (st && i < st->robots.size()) {
      r["phase"] = runtime::to_string(st->robots[i].phase);
      r["detail"] = st->robots[i].detail;
    }
    robots.push_back(std::move(r));
  }
  json bodies = json::array();
  for (int b : view::sent_bodies(scene)) {
    if (!view::moves(m, b)) continue;
    json row = pose7(d->xpos + 3 * b, d->xquat + 4 * b);
    row.insert(row.begin(), b);
    bodies.push_back(std::move(row));
  }
  json fired = json::array();
  if (st) {
    for (const std::string& id : st->task.last_fired) {
      if (auto t = net.find_transition(id)) fired.push_back(fmt::format("{}: {}", id, petri::describe_path(net, {*t})));
    }
  }
  json faults = json::array(), marks = json::array();
  for (const FaultMarks::Mark& mk : fault_marks.marks()) {
    faults.push_back(mk.line);
    if (mk.pos) {
      marks.push_back({{"kind", mk.kind}, {"text", mk.line}, {"pos", *mk.pos}});
    } else if (json now = view::mark(run, mk.line); !now.is_null()) {
      marks.push_back(std::move(now));  // not placed yet (logged since the last period): where things are now
    }
  }
  json f = {{"type", "frame"},
            {"t", st ? std::chrono::duration<double>(st->time).count() : 0.0},
            {"firings", st ? st->task.firings : 0},
            {"state", state.state},
            {"marking", petri::describe_marking(net, st ? st->task.marking : net.initial_marking())},
            {"fired", fired},
            {"robots", robots},
            {"bodies", bodies},
            {"faults", faults},
            {"marks", marks}};
  if (json g = view::gantt(run); !g.is_null()) f["gantt"] = std::move(g);
  if (st && st->result) {
    f["outcome"] = runtime::to_string(st->result->outcome);
    f["reason"] = st->result->reason;
  }
  return f.dump();
}

}  // namespace cellwright::cell
