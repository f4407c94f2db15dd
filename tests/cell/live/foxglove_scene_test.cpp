// The live view as Foxglove's channels (cell/live/foxglove_scene.hpp): the scene of a run of the exchange scenario as
// foxglove.SceneUpdate messages (the base, then what moves, and the marks), and a Foxglove client of a served run
// that gets the base when it subscribes and a frame and a scene at each step a page asks for. (tests/foxglove runs
// Foxglove's own client and validates the messages against Foxglove's schema.)
#include "cellwright/cell/live/foxglove_scene.hpp"

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "cellwright/runtime/log_event.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "live_loop.hpp"
#include "support/foxglove_data.hpp"

namespace cellwright::cell {
namespace {

using nlohmann::json;

class FoxgloveScene : public live_testing::ExchangeRun {
 protected:
  json scene(bool whole, const FaultMarks& marks = {}) {
    return json::parse(foxglove_scene_json(*run_, whole, marks, 1'700'000'000'123'456'789ULL));
  }
  const mjModel* model() { return run_->world().scene().model(); }
  const mjData* data() { return run_->world().data(); }
  std::string body_id(int b) { return std::string("body/") + mj_id2name(model(), mjOBJ_BODY, b); }
  static const json* find(const json& s, const std::string& id) {
    for (const json& e : s["entities"]) {
      if (e["id"] == id) return &e;
    }
    return nullptr;
  }
  static std::size_t primitives(const json& e) { return e["cubes"].size() + e["cylinders"].size() + e["spheres"].size(); }
};

TEST_F(FoxgloveScene, TheBaseClearsThePanelAndDrawsEveryBodyWhereItIs) {
  const json s = scene(true);
  ASSERT_EQ(s["deletions"].size(), 1u);
  EXPECT_EQ(s["deletions"][0]["type"], 1);  // ALL
  // Every visible box, cylinder, sphere, capsule (a cylinder and two spheres) and plane of the model, in its body's
  // entity, stamped, in the frame "world".
  const mjModel* m = model();
  std::map<std::string, std::size_t> expected;
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_rgba[4 * g + 3] <= 0) continue;
    const int t = m->geom_type[g];
    const std::size_t n = t == mjGEOM_CAPSULE ? 3 : (t == mjGEOM_BOX || t == mjGEOM_CYLINDER || t == mjGEOM_SPHERE ||
                                                     t == mjGEOM_PLANE)
                                                        ? 1
                                                        : 0;
    if (n) expected[body_id(m->geom_bodyid[g])] += n;
  }
  ASSERT_GT(expected.size(), 5u);
  for (const auto& [id, n] : expected) {
    const json* e = find(s, id);
    ASSERT_NE(e, nullptr) << id;
    EXPECT_EQ(primitives(*e), n) << id;
    EXPECT_EQ((*e)["frame_id"], "world");
    EXPECT_EQ((*e)["timestamp"]["sec"], 1'700'000'000);
    EXPECT_EQ((*e)["timestamp"]["nsec"], 123'456'789);
  }
  EXPECT_EQ(s["entities"].size(), expected.size() + 1);  // and the marks
  // Each primitive where MuJoCo has its geom (position, orientation up to the quaternion's sign) at full size (MuJoCo
  // keeps half sizes; a cylinder's are its radius and half-height), in its entity in geom order; a capsule's end
  // spheres at its two ends.
  std::map<std::string, std::map<std::string, std::size_t>> next;  // entity -> array -> index
  std::size_t checked = 0;
  for (int g = 0; g < m->ngeom; ++g) {
    const int t = m->geom_type[g];
    if (m->geom_rgba[4 * g + 3] <= 0 || (t != mjGEOM_BOX && t != mjGEOM_CYLINDER && t != mjGEOM_SPHERE &&
                                         t != mjGEOM_CAPSULE && t != mjGEOM_PLANE)) {
      continue;
    }
    const std::string id = body_id(m->geom_bodyid[g]);
    const char* array = t == mjGEOM_BOX || t == mjGEOM_PLANE ? "cubes" : t == mjGEOM_SPHERE ? "spheres" : "cylinders";
    const json& prim = find(s, id)->at(array).at(next[id][array]++);
    const double* p = data()->geom_xpos + 3 * g;
    const double* sz = m->geom_size + 3 * g;
    mjtNum q[4];
    mju_mat2Quat(q, data()->geom_xmat + 9 * g);
    const json& o = prim["pose"]["orientation"];
    const double sign = q[0] * o["w"].get<double>() < 0 ? -1 : 1;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(prim["pose"]["position"][std::string(1, "xyz"[i])].get<double>(), p[i], 1e-9);
    EXPECT_NEAR(sign * o["w"].get<double>(), q[0], 1e-9) << id;
    EXPECT_NEAR(sign * o["x"].get<double>(), q[1], 1e-9) << id;
    EXPECT_NEAR(sign * o["y"].get<double>(), q[2], 1e-9) << id;
    EXPECT_NEAR(sign * o["z"].get<double>(), q[3], 1e-9) << id;
    const json& size = prim["size"];
    if (t == mjGEOM_BOX) {
      EXPECT_NEAR(size["x"].get<double>(), 2 * sz[0], 1e-9) << id;
      EXPECT_NEAR(size["y"].get<double>(), 2 * sz[1], 1e-9) << id;
      EXPECT_NEAR(size["z"].get<double>(), 2 * sz[2], 1e-9) << id;
    } else if (t == mjGEOM_SPHERE) {
      EXPECT_NEAR(size["x"].get<double>(), 2 * sz[0], 1e-9) << id;
    } else if (t == mjGEOM_CYLINDER || t == mjGEOM_CAPSULE) {
      EXPECT_NEAR(size["x"].get<double>(), 2 * sz[0], 1e-9) << id;
      EXPECT_NEAR(size["y"].get<double>(), 2 * sz[0], 1e-9) << id;
      EXPECT_NEAR(size["z"].get<double>(), 2 * sz[1], 1e-9) << id;
    }
    if (t == mjGEOM_CAPSULE) {
      const double* r = data()->geom_xmat + 9 * g;
      for (double end : {-1.0, 1.0}) {
        const json& cap = find(s, id)->at("spheres").at(next[id]["spheres"]++);
        EXPECT_NEAR(cap["pose"]["position"]["z"].get<double>(), p[2] + end * sz[1] * r[8], 1e-9) << id;
        EXPECT_NEAR(cap["size"]["x"].get<double>(), 2 * sz[0], 1e-9) << id;
      }
    }
    ++checked;
  }
  EXPECT_GT(checked, 20u);
}

TEST_F(FoxgloveScene, LaterMessagesHoldWhatMovesAndTheMarks) {
  const json whole = scene(true);
  const json some = scene(false);
  EXPECT_TRUE(some["deletions"].empty());
  EXPECT_LT(some["entities"].size(), whole["entities"].size());
  const twin::Scene& sc = run_->world().scene();
  // The body nearest the PUMA's tool that has something drawn (its wrist or gripper).
  int tool_body = model()->site_bodyid[sc.find_robot("puma")->tcp_site];
  while (tool_body > 0 && !find(whole, body_id(tool_body))) tool_body = model()->body_parentid[tool_body];
  ASSERT_GT(tool_body, 0);
  const json* before = find(some, body_id(tool_body));
  ASSERT_NE(before, nullptr) << "the puma's tool body is not among the moving ones";
  for (const auto& wp : {"A", "B"}) EXPECT_NE(find(some, body_id(sc.find_workpiece(wp)->body)), nullptr) << wp;
  // The fixed cell (bodies without joints under the world: stands, belts' frames, the machine) is only in the base.
  std::vector<std::string> fixed;
  for (const json& e : whole["entities"]) {
    const std::string id = e["id"];
    if (id.rfind("body/", 0) != 0) continue;
    const int b = mj_name2id(model(), mjOBJ_BODY, id.substr(5).c_str());
    ASSERT_GE(b, 0) << id;
    const int root = model()->body_rootid[b];
    const bool is_fixed = model()->body_weldid[b] == 0 && model()->body_mocapid[root] < 0 &&
                          root != model()->body_rootid[sc.find_robot("puma")->base_body] &&
                          root != model()->body_rootid[sc.find_robot("melfa")->base_body];
    if (is_fixed) fixed.push_back(id);
    EXPECT_EQ(find(some, id) == nullptr, is_fixed) << id;
  }
  EXPECT_FALSE(fixed.empty());
  // The robot moves on: so does its entity. A fault is marked where it was placed, with its line.
  FaultMarks marks;
  const std::string line =
      runtime::encode(runtime::events::FaultDetected{runtime::SimDuration{0}, "r1", 2, "slip", "let go"});
  marks.add(line);
  marks.place_new(*run_);
  const auto pos = [&](const json& s) {
    const json& c = find(s, body_id(tool_body))->at("cubes").empty() ? find(s, body_id(tool_body))->at("cylinders")
                                                                       : find(s, body_id(tool_body))->at("cubes");
    return Eigen::Vector3d(c[0]["pose"]["position"]["x"], c[0]["pose"]["position"]["y"], c[0]["pose"]["position"]["z"]);
  };
  const Eigen::Vector3d p0 = pos(some);
  json later;
  for (int i = 0; i < 400; ++i) {
    run_->runtime().step();
    later = scene(false, marks);
    if ((pos(later) - p0).norm() > 0.05) break;
  }
  EXPECT_GT((pos(later) - p0).norm(), 0.05) << "the puma's tool never moved in the scene";
  const json* mk = find(later, "marks");
  ASSERT_NE(mk, nullptr);
  ASSERT_EQ((*mk)["spheres"].size(), 1u);
  ASSERT_EQ((*mk)["texts"].size(), 1u);
  EXPECT_EQ((*mk)["texts"][0]["text"], line);
  const std::array<double, 3> placed = *marks.marks()[0].pos;
  EXPECT_NEAR((*mk)["spheres"][0]["pose"]["position"]["x"].get<double>(), placed[0], 1e-9);
  EXPECT_NEAR((*mk)["spheres"][0]["pose"]["position"]["z"].get<double>(), placed[2], 1e-9);
}

TEST(FoxgloveChannels, TheSceneIsFoxglovesSceneUpdateAndTheFrameHasASchema) {
  const std::vector<serve::Channel> c = foxglove_channels();
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].id, kSceneChannel);
  EXPECT_EQ(c[0].topic, "/cellwright/scene");
  EXPECT_EQ(c[0].schema_name, "foxglove.SceneUpdate");
  EXPECT_EQ(json::parse(c[0].schema)["title"], "foxglove.SceneUpdate");
  EXPECT_EQ(c[1].id, kFrameChannel);
  EXPECT_EQ(c[1].topic, "/cellwright/frame");
  EXPECT_EQ(json::parse(c[1].schema)["title"], "cellwright.Frame");
}

}  // namespace
}  // namespace cellwright::cell

namespace cellwright::cell::live_testing {
namespace {

struct Data {
  std::uint32_t subscription = 0;
  json payload;
};

// A Message Data's subscription and JSON payload, if `b` is one.
std::optional<Data> decode(const std::string& b) {
  const std::optional<cellwright::testing::MessageData> d = cellwright::testing::decode_message_data(b);
  if (!d) return std::nullopt;
  return Data{d->subscription, json::parse(d->payload, nullptr, false)};
}

// A Foxglove client of a served run: the base when it subscribes, then a frame and a scene at each step a page asks
// for; the page and the client are told apart.
TEST_F(LiveLoop, AFoxgloveClientSeesTheRunThatAPageSteps) {
  start();
  WsViewer fox(port(), "/", serve::kFoxgloveSubprotocol);
  // (A client may connect before the loop has advertised: the channels come in an advertise of their own then.)
  const json ad = fox.wait_for([](const json& m) { return m.value("op", "") == "advertise" && !m["channels"].empty(); });
  ASSERT_EQ(ad["channels"].size(), 2u);
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":10,"channelId":1},{"id":20,"channelId":2}]})");
  auto on = [](std::uint32_t sub) {
    return [sub](const std::string& b) { return decode(b) && decode(b)->subscription == sub; };
  };
  const std::optional<Data> base = decode(fox.wait_binary(on(10)));
  ASSERT_TRUE(base);
  EXPECT_EQ(base->payload["deletions"][0]["type"], 1);
  // The page steps once; the client sees the frame of that step, and the scene (what moves).
  WsViewer page(port());
  ASSERT_FALSE(page.wait_for("cell").is_null());
  page.send(command("step"));
  const json stepped = page.wait_for([](const json& m) { return is_frame(m) && m["firings"].get<int>() >= 1; });
  ASSERT_FALSE(stepped.is_null());
  const std::optional<Data> frame = decode(fox.wait_binary(
      [&](const std::string& b) { return on(20)(b) && decode(b)->payload.value("firings", 0) >= 1; }));
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->payload["type"], "frame");
  EXPECT_EQ(frame->payload["firings"], stepped["firings"]);
  const std::optional<Data> moving = decode(fox.wait_binary(on(10), 1));
  ASSERT_TRUE(moving);
  EXPECT_TRUE(moving->payload["deletions"].empty());
  // The client is not one of the page's viewers, and got none of their messages.
  EXPECT_EQ(server().viewers(), 1u);
  EXPECT_EQ(fox.count("cell") + fox.count("frame"), 0u);
}

}  // namespace
}  // namespace cellwright::cell::live_testing
