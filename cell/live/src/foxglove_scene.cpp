#include "cellwright/cell/live/foxglove_scene.hpp"

#include <mujoco/mujoco.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "cellwright/common/error.hpp"
#include "cellwright/serve/foxglove_schemas.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "live_view.hpp"

namespace cellwright::cell {

namespace {

using nlohmann::json;

// The live view's frame (live.hpp), as a JSON schema: the fields Foxglove's panels may read.
constexpr const char* kFrameSchema = R"schema({
  "title": "cellwright.Frame",
  "description": "The live view's frame of a twin serve run (docs/live-view.md)",
  "type": "object",
  "properties": {
    "type": {"type": "string"},
    "t": {"type": "number", "description": "simulation time, s"},
    "firings": {"type": "integer"},
    "state": {"type": "string", "description": "paused, playing or ended"},
    "outcome": {"type": "string"},
    "reason": {"type": "string"},
    "marking": {"type": "string", "description": "the Petri net's marking"},
    "fired": {"type": "array", "items": {"type": "string"}},
    "robots": {"type": "array", "items": {"type": "object", "properties": {
      "name": {"type": "string"}, "label": {"type": "string"},
      "joints": {"type": "array", "items": {"type": "number"}, "description": "rad"},
      "fingers": {"type": "number", "description": "m open"},
      "activity": {"type": "string"}, "command": {"type": "string"},
      "phase": {"type": "string"}, "detail": {"type": "string"}}}},
    "bodies": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
    "faults": {"type": "array", "items": {"type": "string"}},
    "marks": {"type": "array", "items": {"type": "object", "properties": {
      "kind": {"type": "string"}, "text": {"type": "string"},
      "pos": {"type": "array", "items": {"type": "number"}}}}},
    "gantt": {"type": "array", "items": {"type": "object", "properties": {
      "robot": {"type": "string"}, "command": {"type": "string"}, "start": {"type": "number"},
      "end": {"type": ["number", "null"]}, "ok": {"type": "boolean"}}}},
    "replay": {"type": "boolean"},
    "replay_index": {"type": "integer"}
  }
})schema";

json stamp(std::uint64_t ns) { return {{"sec", ns / 1'000'000'000}, {"nsec", ns % 1'000'000'000}}; }

json vec(double x, double y, double z) { return {{"x", x}, {"y", y}, {"z", z}}; }

json pose(const double* p, const double* q /* w x y z */) {
  return {{"position", vec(p[0], p[1], p[2])}, {"orientation", {{"x", q[1]}, {"y", q[2]}, {"z", q[3]}, {"w", q[0]}}}};
}

json color(const float* c) { return {{"r", c[0]}, {"g", c[1]}, {"b", c[2]}, {"a", c[3]}}; }

json entity(const std::string& id, std::uint64_t ns) {
  return {{"timestamp", stamp(ns)},     {"frame_id", "world"},       {"id", id},
          {"lifetime", {{"sec", 0}, {"nsec", 0}}}, {"frame_locked", false}, {"metadata", json::array()},
          {"arrows", json::array()},    {"cubes", json::array()},    {"spheres", json::array()},
          {"cylinders", json::array()}, {"lines", json::array()},    {"triangles", json::array()},
          {"texts", json::array()},     {"models", json::array()}};
}

// Adds geom g, where it is in the world now, to entity e.
void add_geom(json& e, const mjModel* m, const mjData* d, int g) {
  const int type = m->geom_type[g];
  const mjtNum* sz = m->geom_size + 3 * g;
  const mjtNum* p = d->geom_xpos + 3 * g;
  mjtNum q[4];
  mju_mat2Quat(q, d->geom_xmat + 9 * g);
  const int mat = m->geom_matid[g];  // drawn in its material's colour when it has one, as MuJoCo does
  const json c = color(mat >= 0 ? m->mat_rgba + 4 * mat : m->geom_rgba + 4 * g);
  switch (type) {
    case mjGEOM_BOX:
      e["cubes"].push_back({{"pose", pose(p, q)}, {"size", vec(2 * sz[0], 2 * sz[1], 2 * sz[2])}, {"color", c}});
      break;
    case mjGEOM_PLANE: {
      const double x = sz[0] > 0 ? 2 * sz[0] : 10, y = sz[1] > 0 ? 2 * sz[1] : 10;
      e["cubes"].push_back({{"pose", pose(p, q)}, {"size", vec(x, y, 0.001)}, {"color", c}});
      break;
    }
    case mjGEOM_SPHERE:
      e["spheres"].push_back({{"pose", pose(p, q)}, {"size", vec(2 * sz[0], 2 * sz[0], 2 * sz[0])}, {"color", c}});
      break;
    case mjGEOM_CYLINDER:
    case mjGEOM_CAPSULE: {
      // MuJoCo's and Foxglove's cylinders both stand along their z.
      e["cylinders"].push_back({{"pose", pose(p, q)},
                                {"size", vec(2 * sz[0], 2 * sz[0], 2 * sz[1])},
                                {"bottom_scale", 1},
                                {"top_scale", 1},
                                {"color", c}});
      if (type == mjGEOM_CAPSULE) {
        const mjtNum* r = d->geom_xmat + 9 * g;  // its z axis is the third column
        for (double s : {-1.0, 1.0}) {
          const double end[3] = {p[0] + s * sz[1] * r[2], p[1] + s * sz[1] * r[5], p[2] + s * sz[1] * r[8]};
          e["spheres"].push_back(
              {{"pose", pose(end, q)}, {"size", vec(2 * sz[0], 2 * sz[0], 2 * sz[0])}, {"color", c}});
        }
      }
      break;
    }
    default: break;  // not drawn (view::shape_of)
  }
}

json marks_entity(const FaultMarks& marks, std::uint64_t ns) {
  json e = entity("marks", ns);
  const double identity[4] = {1, 0, 0, 0};
  for (const FaultMarks::Mark& mk : marks.marks()) {
    if (!mk.pos) continue;  // placed within a control period
    const bool collision = mk.kind == "collision";
    const float rgba[4] = {1.0F, collision ? 0.55F : 0.1F, 0.1F, 0.85F};
    e["spheres"].push_back({{"pose", pose(mk.pos->data(), identity)}, {"size", vec(0.06, 0.06, 0.06)},
                            {"color", color(rgba)}});
    const double above[3] = {(*mk.pos)[0], (*mk.pos)[1], (*mk.pos)[2] + 0.06};
    e["texts"].push_back({{"pose", pose(above, identity)},
                          {"billboard", true},
                          {"font_size", 12},
                          {"scale_invariant", true},
                          {"color", color(rgba)},
                          {"text", mk.line}});
  }
  return e;
}

}  // namespace

std::vector<serve::Channel> foxglove_channels() {
  serve::Channel scene;
  scene.id = kSceneChannel;
  scene.topic = "/cellwright/scene";
  scene.schema_name = "foxglove.SceneUpdate";
  scene.schema = std::string(serve::foxglove_schema(scene.schema_name));
  CW_CHECK(!scene.schema.empty(), "this build carries no schema {} (serve/page/bundle.cmake)", scene.schema_name);
  serve::Channel frame;
  frame.id = kFrameChannel;
  frame.topic = "/cellwright/frame";
  frame.schema_name = "cellwright.Frame";
  frame.schema = json::parse(kFrameSchema).dump();
  return {scene, frame};
}

std::string foxglove_scene_json(ScenarioRun& run, bool whole, const FaultMarks& marks, std::uint64_t time_ns) {
  const twin::Scene& scene = run.world().scene();
  const mjModel* m = scene.model();
  const mjData* d = run.world().data();
  const std::vector<bool> robot = view::robot_bodies(scene);
  // Each drawn geom's body, in id order, and what it holds.
  std::vector<json> by_body(static_cast<std::size_t>(m->nbody));
  for (int g = 0; g < m->ngeom; ++g) {
    const int b = m->geom_bodyid[g];
    if (!view::shape_of(m->geom_type[g]) || m->geom_rgba[4 * g + 3] <= 0) continue;
    if (!whole && !robot[static_cast<std::size_t>(b)] && !view::moves(m, b)) continue;
    json& e = by_body[static_cast<std::size_t>(b)];
    if (e.is_null()) e = entity("body/" + view::body_name(m, b), time_ns);
    add_geom(e, m, d, g);
  }
  json entities = json::array();
  for (json& e : by_body) {
    if (!e.is_null()) entities.push_back(std::move(e));
  }
  entities.push_back(marks_entity(marks, time_ns));
  json deletions = json::array();
  if (whole) deletions.push_back({{"timestamp", stamp(time_ns)}, {"type", 1}, {"id", ""}});
  return json{{"deletions", deletions}, {"entities", entities}}.dump();
}

std::uint64_t foxglove_now_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}

}  // namespace cellwright::cell
