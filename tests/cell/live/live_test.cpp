// `twin serve`'s run loop (cell/live/live.hpp) on the exchange scenario, lock-step, watched and driven over loopback
// by test viewers (support/ws_viewer.hpp) as a page would: step one firing, play and pause, restart; a viewer that
// leaves or never reads costs the run nothing; a bad message is refused to the page that sent it.
#define ASIO_STANDALONE
#include "cellwright/cell/live/live.hpp"

#include <gtest/gtest.h>

#include <asio.hpp>
#include <cmath>

#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "support/ws_viewer.hpp"
#include "cellwright/models/robot_model.hpp"
#include "live_loop.hpp"
#include "scene_copy.hpp"

namespace cellwright::cell {
namespace {

using live_testing::is_frame;
using live_testing::json;
using live_testing::LiveLoop;
using live_testing::WsViewer;

TEST_F(LiveLoop, AViewerGetsTheCellAndStepsOneFiringAtATime) {
  start();
  WsViewer v(port());
  const json cell = v.wait_for("cell");
  ASSERT_TRUE(cell.is_object());
  EXPECT_EQ(cell["scenario"], "exchange.yaml");
  EXPECT_EQ(cell["mode"], "lock-step");
  ASSERT_EQ(cell["robots"].size(), scenario_->robots.size());
  EXPECT_EQ(cell["robots"][0]["urdf"].get<std::string>().rfind("/models/", 0), 0u);
  // Paused at first, nothing fired.
  const json first = v.wait_for("frame");
  ASSERT_TRUE(first.is_object());
  EXPECT_EQ(first["state"], "paused");
  EXPECT_EQ(first["firings"], 0);

  std::uint64_t firings = 0;
  double t = 0;
  for (int i = 1; i <= 3; ++i) {
    v.send(command("step"));
    const json f = v.wait_for([&](const json& m) { return is_frame(m) && m["firings"].get<std::uint64_t>() > firings; });
    ASSERT_TRUE(f.is_object()) << "step " << i << " brought no frame with more firings than " << firings;
    EXPECT_EQ(f["state"], "paused");
    EXPECT_FALSE(f["fired"].empty()) << "a step stops where a transition fired";
    EXPECT_GE(f["t"].get<double>(), t);
    firings = f["firings"].get<std::uint64_t>();
    t = f["t"].get<double>();
  }
  // Nothing moves between steps: the run waits for the page.
  EXPECT_FALSE(server().poll_message().has_value());
}

TEST_F(LiveLoop, PlayRunsToTheEndAndPauseStopsBetweenSteps) {
  start();
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("frame").is_object());
  v.send(command("play"));
  // The first step's frame while playing (the frame that answers play itself may come before any step).
  const json playing =
      v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "playing" && m["firings"] > 0; });
  ASSERT_TRUE(playing.is_object()) << "play ran no step";
  v.send(command("pause"));
  // The exchange runs 32 s of simulated time, far longer than a command's round trip over loopback: the pause lands
  // mid-run.
  const json paused = v.wait_for([](const json& m) {
    return is_frame(m) && ((m["state"] == "paused" && m["firings"] > 0) || m["state"] == "ended");
  });
  ASSERT_TRUE(paused.is_object());
  ASSERT_EQ(paused["state"], "paused") << "the run ended before the pause was taken";
  // It stays paused: the next frame is the step's (a run still playing would have sent "playing" frames first).
  const std::size_t frames = v.count("frame");
  v.send(command("step"));
  const json stepped = v.wait_for("frame", frames);
  ASSERT_TRUE(stepped.is_object());
  EXPECT_EQ(stepped["state"], "paused");
  EXPECT_GT(stepped["firings"], paused["firings"]);

  v.send(command("play"));
  const json end = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; });
  ASSERT_TRUE(end.is_object()) << "the run did not end within 5 s of play";
  EXPECT_EQ(end["outcome"], "finished") << end.value("reason", "");
  EXPECT_GT(end["firings"], stepped["firings"]);
  // An ended run stays ended: play does not move it.
  v.send(command("play"));
  const json again = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; }, 1);
  ASSERT_TRUE(again.is_object());
  EXPECT_EQ(again["firings"], end["firings"]);
}

TEST_F(LiveLoop, RestartBuildsTheRunAgainFromTheStart) {
  start();
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("cell").is_object());
  auto at = [](std::uint64_t n) { return [n](const json& m) { return is_frame(m) && m["firings"] == n; }; };
  auto moved = [](const json& m) { return is_frame(m) && m["firings"] > 0; };
  v.send(command("step"));
  const json first = v.wait_for(moved);
  ASSERT_TRUE(first.is_object());
  v.send(command("step"));
  ASSERT_TRUE(v.wait_for(moved, 1).is_object());
  // Every frame before the second step's has come (one connection keeps the order).
  const std::size_t at_start = v.count(at(0)), stepped = v.count(moved);

  v.send(command("restart"));
  ASSERT_TRUE(v.wait_for("cell", 1).is_object()) << "a restart sends the cell again";
  const json again = v.wait_for(at(0), at_start);
  ASSERT_TRUE(again.is_object()) << "no frame of the restarted run at its start";
  EXPECT_EQ(again["t"], 0.0);
  EXPECT_EQ(again["state"], "paused");
  // Its first step is the first run's first step: the same scenario, the same run.
  v.send(command("step"));
  const json f = v.wait_for(moved, stepped);
  ASSERT_TRUE(f.is_object());
  EXPECT_EQ(f["firings"], first["firings"]);
  EXPECT_EQ(f["t"], first["t"]);
  EXPECT_EQ(f["fired"], first["fired"]);
  stop_ = true;
  loop_.join();
  EXPECT_EQ(runs_, 2);
}

TEST_F(LiveLoop, ABadMessageIsRefusedToThePageThatSentItAndTheRunGoesOn) {
  start();
  WsViewer bad(port());
  WsViewer good(port());
  ASSERT_TRUE(good.wait_for("frame").is_object());
  bad.send(R"({"type":"command","command":"jump"})");
  EXPECT_EQ(bad.wait_for("error")["reason"], "unknown command 'jump' (play, pause, step, restart, run_to or replay)");
  bad.send("{{{");
  EXPECT_EQ(bad.wait_for("error", 1)["reason"], "not JSON");
  // Nothing was taken as a command: the page that sent nothing wrong is told nothing and the run is where it was.
  good.send(command("step"));
  const json f = good.wait_for([](const json& m) { return is_frame(m) && m["firings"] > 0; });
  ASSERT_TRUE(f.is_object());
  EXPECT_EQ(good.count("error"), 0u);
  EXPECT_EQ(server().counts().refused, 2u);
}

TEST_F(LiveLoop, RunToATimePausesAtTheFirstPeriodFromThatTime) {
  start();
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("frame").is_object());
  v.send(R"({"type":"command","command":"run_to","time":2.5})");
  const json at = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "paused" && m["t"] > 0.0; });
  ASSERT_TRUE(at.is_object());
  EXPECT_GE(at["t"].get<double>(), 2.5);
  EXPECT_LT(at["t"].get<double>(), 2.5 + 0.0105) << "one control period (10 ms) at most past the time asked";
  // Not after now: refused, the run stays.
  v.send(R"({"type":"command","command":"run_to","time":1})");
  EXPECT_NE(v.wait_for("error")["reason"].get<std::string>().find("not after now"), std::string::npos);
}

TEST_F(LiveLoop, RunToALinePausesWhereATransitionOfThatLineFired) {
  start();
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("frame").is_object());
  // exchange.task line 10: "Place B" (r2), the program's last command.
  v.send(R"({"type":"command","command":"run_to","line":10})");
  const json at = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "paused" && m["firings"] > 0; });
  ASSERT_TRUE(at.is_object());
  bool line10 = false;
  for (const json& f : at["fired"]) line10 = line10 || f.get<std::string>().find("line 10 ") != std::string::npos;
  EXPECT_TRUE(line10) << at["fired"].dump();
  EXPECT_NE(at["state"], "ended");
  // No command on line 3 (a declaration): refused, named.
  v.send(R"({"type":"command","command":"run_to","line":3})");
  EXPECT_EQ(v.wait_for("error")["reason"], "no command of exchange.task is on line 3");
  v.send(R"({"type":"command","command":"run_to"})");
  EXPECT_NE(v.wait_for("error", 1)["reason"].get<std::string>().find("needs"), std::string::npos);
}

// Real time (`twin serve --realtime`): the run goes paced by the wall clock with frames from its simulation thread;
// pause holds it (the twin frozen: no frame moves it on), step lets it go to the next firing, run to a line holds
// where that line fired, teaching is refused while it goes, and it ends on its own.
TEST_F(LiveLoop, RealTimePlaysPausesStepsRunsToALineAndEnds) {
  RunOptions ro;
  ro.realtime = true;
  ro.speed = 8;  // the exchange's 32 s of simulation in about 4 s
  start({}, 256 * 1024, live_testing::kExchange, ro);
  WsViewer v(port());
  EXPECT_EQ(v.wait_for("cell")["mode"], "real time");
  const json first = v.wait_for("frame");
  ASSERT_TRUE(first.is_object());
  EXPECT_EQ(first["state"], "paused");
  EXPECT_EQ(first["t"], 0.0);

  v.send(command("play"));
  const json playing = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "playing" && m["t"] > 0.2; });
  ASSERT_TRUE(playing.is_object()) << "no frame as the run goes";
  const json named =
      v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "playing" && !m["fired"].empty(); });
  ASSERT_TRUE(named.is_object()) << "the frames of a run that goes name its latest firings";
  v.send(R"({"type":"teach","action":"begin","robot":"puma"})");
  EXPECT_NE(v.wait_for("error")["reason"].get<std::string>().find("pause it before teaching"), std::string::npos);
  // A run_to refused (no command on line 3) leaves the run going as it went.
  v.send(R"({"type":"command","command":"run_to","line":3})");
  EXPECT_EQ(v.wait_for("error", 1)["reason"], "no command of exchange.task is on line 3");
  const double after = named["t"].get<double>() + 0.3;
  EXPECT_TRUE(v.wait_for([after](const json& m) { return is_frame(m) && m["state"] == "playing" && m["t"] > after; })
                  .is_object())
      << "the run stopped going after a refused run_to";
  const auto held = [](const json& m) { return is_frame(m) && m["state"] != "playing"; };
  v.send(command("pause"));
  const json paused = v.wait_for(held, 1);  // the first was the frame at the start
  ASSERT_TRUE(paused.is_object());
  ASSERT_EQ(paused["state"], "paused") << "the run ended before the pause was taken";
  EXPECT_GT(paused["t"].get<double>(), after);
  // Held: the next frame is the step's, not one of a run that goes on.
  const std::size_t frames = v.count("frame");
  v.send(command("step"));
  const json stepped = v.wait_for(held, 2);
  ASSERT_TRUE(stepped.is_object());
  EXPECT_EQ(stepped["state"], "paused");
  EXPECT_GT(stepped["firings"], paused["firings"]);
  EXPECT_FALSE(stepped["fired"].empty()) << "a step holds where a transition fired";
  EXPECT_GE(stepped["t"].get<double>(), paused["t"].get<double>());
  EXPECT_GT(v.count("frame"), frames);

  // exchange.task line 10: "Place B" (r2), the program's last command.
  const std::size_t held_before = v.count(held);
  v.send(R"({"type":"command","command":"run_to","line":10})");
  json at;
  for (int i = 0; i < 6 && !at.is_object(); ++i) at = v.wait_for(held, held_before);
  ASSERT_TRUE(at.is_object());
  ASSERT_EQ(at["state"], "paused") << at.value("reason", "");
  bool line10 = false;
  for (const json& f : at["fired"]) line10 = line10 || f.get<std::string>().find("line 10 ") != std::string::npos;
  EXPECT_TRUE(line10) << at["fired"].dump();

  v.send(command("play"));
  json end;
  for (int i = 0; i < 6 && !end.is_object(); ++i) {
    end = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; });
  }
  ASSERT_TRUE(end.is_object()) << "the run did not end";
  EXPECT_EQ(end["outcome"], "finished") << end.value("reason", "");
  EXPECT_GT(end["firings"], at["firings"]);
}

TEST_F(LiveLoop, TeachingJogsACopyThatEveryViewerSeesAndTheRunGoesOnFromWhereItWas) {
  start();
  WsViewer a(port());
  WsViewer b(port());
  ASSERT_TRUE(a.wait_for("frame").is_object());
  ASSERT_TRUE(b.wait_for("frame").is_object());
  a.send(command("step"));
  const json stepped = a.wait_for([](const json& m) { return is_frame(m) && m["firings"] > 0; });
  ASSERT_TRUE(stepped.is_object());
  a.send(R"({"type":"teach","robot":"puma","action":"begin"})");
  const json begun = b.wait_for("teach");
  ASSERT_TRUE(begun.is_object()) << "the other viewer sees the teach pose too";
  EXPECT_EQ(begun["active"], true);
  EXPECT_EQ(begun["joints"], stepped["robots"][0]["joints"]) << "teaching starts from the run's joints";
  a.send(R"({"type":"teach","robot":"puma","action":"joint","joint":0,"delta":0.25})");
  const json jogged = a.wait_for("teach", 1);
  ASSERT_TRUE(jogged.is_object());
  EXPECT_NEAR(jogged["joints"][0].get<double>(), begun["joints"][0].get<double>() + 0.25, 1e-12);
  EXPECT_EQ(jogged["tool"].size(), 7u);
  EXPECT_TRUE(jogged["collisions"].is_array());
  // The run has not moved: a new viewer gets the frame it had; the next step goes on from there as without teaching.
  WsViewer c(port());
  const json seen = c.wait_for("frame");
  EXPECT_EQ(seen["robots"], stepped["robots"]);
  a.send(command("step"));
  const json next = a.wait_for([&](const json& m) { return is_frame(m) && m["firings"] > stepped["firings"]; });
  ASSERT_TRUE(next.is_object());
  ScenarioRun plain(*scenario_, *preflight_);
  plain.runtime().step();
  const runtime::StepState second = plain.runtime().step();
  EXPECT_EQ(next["firings"].get<std::uint64_t>(), second.task.firings);
  EXPECT_EQ(next["t"].get<double>(), std::chrono::duration<double>(second.time).count());
  // Begin refused while playing; end makes the ghost go away for everyone.
  a.send(command("play"));
  a.send(R"({"type":"teach","robot":"melfa","action":"begin"})");
  EXPECT_NE(a.wait_for("error")["reason"].get<std::string>().find("pause"), std::string::npos);
  a.send(command("pause"));
  a.send(R"({"type":"teach","robot":"puma","action":"end"})");
  const json ended = b.wait_for([](const json& m) { return m.value("type", "") == "teach" && m["active"] == false; });
  ASSERT_TRUE(ended.is_object());
  EXPECT_EQ(b.count("error"), 0u);
}

TEST_F(LiveLoop, CheckIsAnsweredToItsSenderAndAPassedProgramHasNoReplay) {
  start();
  WsViewer a(port());
  WsViewer b(port());
  ASSERT_TRUE(a.wait_for("frame").is_object());
  a.send(R"({"type":"check"})");
  const json c = a.wait_for("check");
  ASSERT_TRUE(c.is_object());
  EXPECT_EQ(c["ok"], true);
  EXPECT_EQ(c["property"], "");
  EXPECT_TRUE(c["counterexample"].empty());
  EXPECT_EQ(c["summary"].get<std::string>().rfind("OK", 0), 0u) << c["summary"];
  a.send(command("replay"));
  EXPECT_NE(a.wait_for("error")["reason"].get<std::string>().find("no counterexample"), std::string::npos);
  EXPECT_EQ(b.count("check"), 0u);
  EXPECT_FALSE(a.wait_for("frame").contains("replay"));
}

TEST_F(LiveLoop, ASavedLocationIsInTheCellFileAndInTheRestartedRunsCell) {
  live_testing::SceneCopy copy;
  std::atomic<int> reloads{0};
  std::optional<std::string> reloaded_location;
  ServeOptions options;
  const std::filesystem::path file = copy.exchange();
  options.reload = [&] {
    ++reloads;
    LiveScenario again;
    again.scenario = std::make_unique<Scenario>(load_scenario(file));
    again.preflight = std::make_unique<Preflight>(preflight(*again.scenario, &twin_port()));
    if (const models::LocationSpec* l = again.scenario->cell.find_location("taught_here")) reloaded_location = l->name;
    return again;
  };
  start(options, 256 * 1024, copy.exchange().string());
  WsViewer a(port());
  WsViewer b(port());
  ASSERT_TRUE(a.wait_for("frame").is_object());
  // The PUMA's teach pose set to reach 3 cm beside its input pick, pointing down.
  const models::CellDescription& cell = scenario_->cell;
  const models::LocationSpec& pick = *cell.find_location("input_pick");
  const models::RobotSpec& puma = *cell.find_robot("puma");
  Eigen::Isometry3d target = models::grasp_pose(pick.pose.xyz + Eigen::Vector3d(0.03, 0, pick.grasp_height),
                                                models::Approach::kDown, pick.pose.rpy.z(), puma.base.transform());
  const models::KinematicChain chain = models::robot_chain(puma);
  const models::IkResult ik = chain.inverse(puma.base.transform().inverse() * target, Eigen::VectorXd(puma.home.size()).setZero());
  ASSERT_EQ(ik.status, models::IkStatus::kOk) << ik.reason;
  a.send(R"({"type":"teach","robot":"puma","action":"begin"})");
  a.send(json{{"type", "teach"}, {"robot", "puma"}, {"action", "joints"},
              {"joints", std::vector<double>(ik.q.data(), ik.q.data() + ik.q.size())}}.dump());
  ASSERT_TRUE(a.wait_for("teach", 1).is_object());
  const std::string before = live_testing::read_text(copy.cell_file());
  // Refused: a bad name, a robot not taught; the file untouched, only the sender told.
  a.send(R"({"type":"save_location","robot":"puma","name":"no good"})");
  EXPECT_NE(a.wait_for("error")["reason"].get<std::string>().find("not a location name"), std::string::npos);
  a.send(R"({"type":"save_location","robot":"melfa","name":"x"})");
  EXPECT_NE(a.wait_for("error", 1)["reason"].get<std::string>().find("not being taught"), std::string::npos);
  EXPECT_EQ(live_testing::read_text(copy.cell_file()), before);
  EXPECT_EQ(b.count("error"), 0u);

  a.send(R"({"type":"save_location","robot":"puma","name":"taught_here"})");
  const json saved = b.wait_for("saved");
  ASSERT_TRUE(saved.is_object());
  EXPECT_EQ(saved["file"], "cell.yaml");
  EXPECT_EQ(saved["name"], "taught_here");
  EXPECT_EQ(saved["replaced"], false);
  EXPECT_NE(saved["diff"].get<std::string>().find("+  - {name: taught_here, pose:"), std::string::npos);
  const models::CellDescription after = models::load_cell(copy.cell_file());
  const models::LocationSpec* loc = after.find_location("taught_here");
  ASSERT_NE(loc, nullptr);
  const Eigen::Isometry3d grasp = models::grasp_pose(loc->pose.xyz + Eigen::Vector3d(0, 0, loc->grasp_height),
                                                     models::Approach::kDown, loc->pose.rpy.z(), puma.base.transform());
  EXPECT_LT((grasp.translation() - target.translation()).norm(), 1e-3);
  EXPECT_LT(Eigen::AngleAxisd(grasp.linear().transpose() * target.linear()).angle(), M_PI / 180);
  // The restart loads the scenario again: its cell has the location.
  a.send(command("restart"));
  ASSERT_TRUE(a.wait_for("cell", 1).is_object());
  EXPECT_EQ(reloads, 1);
  EXPECT_EQ(reloaded_location, "taught_here");
  // The ghost went away with the restart.
  EXPECT_TRUE(b.wait_for([](const json& m) { return m.value("type", "") == "teach" && m["active"] == false; }).is_object());
}

TEST_F(LiveLoop, ViewersThatLeaveOrNeverReadCostTheRunNothing) {
  // A frame per step (no pacing to speak of) and a small bound on what may wait for a viewer.
  ServeOptions options;
  options.frame_hz = 1e6;
  start(options, 4 * 1024);
  // A viewer that does the WebSocket handshake and then never reads.
  asio::io_context io;
  asio::ip::tcp::socket stalled(io);
  stalled.open(asio::ip::tcp::v4());
  stalled.set_option(asio::socket_base::receive_buffer_size(4096));
  stalled.connect({asio::ip::make_address("127.0.0.1"), port()});
  asio::write(stalled, asio::buffer(std::string(
                           "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")));
  auto leaving = std::make_unique<WsViewer>(port());
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("frame").is_object());
  ASSERT_TRUE(leaving->wait_for("frame").is_object());
  v.send(command("play"));
  leaving.reset();  // gone mid-run
  const json end = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; });
  ASSERT_TRUE(end.is_object()) << "the run did not end within 5 s with a viewer gone and one not reading";
  EXPECT_EQ(end["outcome"], "finished") << end.value("reason", "");
  // The run is the run a lone viewer sees: the same firings as a plain run of the scenario.
  ScenarioRun plain(*scenario_, *preflight_);
  EXPECT_EQ(end["firings"].get<std::uint64_t>(), plain.runtime().run().firings);
  // Whether frames were dropped for the stalled viewer depends on how much the kernel's socket buffers took (a run
  // of a few hundred frames may fit): serve_tests' FramesToAViewerThatDoesNotReadAreDroppedNotQueued shows the drop.
}

}  // namespace
}  // namespace cellwright::cell

namespace cellwright::cell {
namespace {

using live_testing::kExchange;
using nlohmann::json;

// The view-only parts of the messages (cell/live/src/live_view.hpp), read from one run of the exchange scenario.
class LiveView : public live_testing::ExchangeRun {
 protected:
  json frame(const std::vector<std::string>& faults = {}, const runtime::StepState* step = nullptr) {
    FaultMarks marks;
    for (const std::string& line : faults) marks.add(line);
    return json::parse(live_frame_json(*run_, LiveFrameState{"paused", step}, marks));
  }
};

TEST_F(LiveView, TheCellNamesTheOverheadCameraWithItsPoseFieldOfViewAndResolution) {
  const json cell = json::parse(live_cell_json(*run_, models_root(*scenario_)));
  ASSERT_EQ(cell["cameras"].size(), 1u);
  const json& c = cell["cameras"][0];
  EXPECT_EQ(c["name"], "overhead");
  // scenes/cell.yaml: at (0.35, 0, 2.6) looking at (0.35, 0, 0), 60 degrees, 640 x 480.
  EXPECT_NEAR(c["pos"][0].get<double>(), 0.35, 1e-9);
  EXPECT_NEAR(c["pos"][1].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(c["pos"][2].get<double>(), 2.6, 1e-9);
  EXPECT_NEAR(c["fovy"].get<double>(), 60, 1e-9);
  EXPECT_EQ(c["resolution"], json::array({640, 480}));
  // The camera looks along its -z: that axis, turned by the quaternion, points straight down.
  const double w = c["quat"][0], x = c["quat"][1], y = c["quat"][2], z = c["quat"][3];
  const double look_z = -(1 - 2 * (x * x + y * y));  // the z component of R * (0, 0, -1)
  const double look_x = -(2 * (x * z + w * y)), look_y = -(2 * (y * z - w * x));
  EXPECT_NEAR(look_z, -1, 1e-6);
  EXPECT_NEAR(look_x, 0, 1e-6);
  EXPECT_NEAR(look_y, 0, 1e-6);
}

TEST_F(LiveView, AFaultIsMarkedAtItsRobotsToolAndACollisionBetweenItsBodies) {
  const runtime::SimDuration t = std::chrono::milliseconds(1500);
  const std::string fault = runtime::encode(runtime::events::FaultInjected{t, "drop", "puma", "A", "let go"});
  const std::string hit = runtime::encode(runtime::events::Collision{t, "workpiece/A", "workpiece/B", 0.002});
  const json f = frame({fault, hit});
  ASSERT_EQ(f["marks"].size(), 2u);
  EXPECT_EQ(f["marks"][0]["kind"], "fault");
  EXPECT_EQ(f["marks"][0]["text"], fault);
  const twin::Scene& scene = run_->world().scene();
  const mjData* d = run_->world().data();
  const double* tcp = d->site_xpos + 3 * scene.find_robot("puma")->tcp_site;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(f["marks"][0]["pos"][i].get<double>(), tcp[i], 1e-9) << i;
  // A and B are apart in a row on the input belt: half-way between them.
  EXPECT_EQ(f["marks"][1]["kind"], "collision");
  const double* a = d->xpos + 3 * scene.find_workpiece("A")->body;
  const double* b = d->xpos + 3 * scene.find_workpiece("B")->body;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(f["marks"][1]["pos"][i].get<double>(), (a[i] + b[i]) / 2, 1e-9) << i;
  // No faults, no marks.
  EXPECT_TRUE(frame()["marks"].empty());
}

// A mark stays where its event happened: placed when it was logged (a RunObserver every control period places it in a
// served run), not where the robot is when a page first sees it.
TEST_F(LiveView, AMarkStaysWhereItWasPlacedWhileTheRobotMovesOn) {
  const twin::Scene& scene = run_->world().scene();
  const int tcp = scene.find_robot("puma")->tcp_site;
  const auto tool = [&] { return Eigen::Map<const Eigen::Vector3d>(run_->world().data()->site_xpos + 3 * tcp); };
  FaultMarks marks;
  marks.add(runtime::encode(runtime::events::FaultDetected{runtime::SimDuration{0}, "r1", 2, "slip", "let go"}));
  marks.place_new(*run_);
  const Eigen::Vector3d placed = tool();
  runtime::StepState st;
  for (int i = 0; i < 400 && (tool() - placed).norm() < 0.05; ++i) st = run_->runtime().step();
  ASSERT_GT((tool() - placed).norm(), 0.05) << "the puma never moved";
  const json f = json::parse(live_frame_json(*run_, LiveFrameState{"paused", &st}, marks));
  ASSERT_EQ(f["marks"].size(), 1u);
  EXPECT_EQ(f["marks"][0]["kind"], "fault");
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(f["marks"][0]["pos"][i].get<double>(), placed[i], 1e-9) << i;
}

TEST_F(LiveView, TheGanttGrowsWithTheCommandsAsTheRunSteps) {
  EXPECT_TRUE(frame()["gantt"].empty());
  // Step until a command has ended: it has a start and an end, the one running after it an open end.
  json g;
  runtime::StepState st;
  for (int i = 0; i < 200; ++i) {
    st = run_->runtime().step();
    g = frame({}, &st)["gantt"];
    const bool ended = std::any_of(g.begin(), g.end(), [](const json& s) { return !s["end"].is_null(); });
    if (ended || st.ended) break;
  }
  ASSERT_FALSE(g.empty());
  const double now = std::chrono::duration<double>(st.time).count();
  bool ended = false;
  for (const json& s : g) {
    EXPECT_TRUE(s["robot"] == "r1" || s["robot"] == "r2") << s.dump();
    EXPECT_FALSE(s["command"].get<std::string>().empty());
    EXPECT_LE(s["start"].get<double>(), now + 1e-9);
    if (!s["end"].is_null()) {
      ended = true;
      EXPECT_GE(s["end"].get<double>(), s["start"].get<double>());
      EXPECT_TRUE(s["ok"].get<bool>()) << s.dump();
    }
  }
  EXPECT_TRUE(ended) << g.dump();
}

}  // namespace
}  // namespace cellwright::cell
