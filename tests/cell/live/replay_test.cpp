// The check and the counterexample replay (cell/live/replay.hpp): the deadlocking program's check names the deadlock
// and its firings; served, it is greeted with that check and replayed: task control fires the counterexample's
// transitions in its order and the run ends at the dead marking; "replay" starts it again.
#include "cellwright/cell/live/replay.hpp"

#include <gtest/gtest.h>

#include "cellwright/task/to_net.hpp"
#include "live_loop.hpp"
#include "scene_copy.hpp"

namespace cellwright::cell {
namespace {

using live_testing::is_frame;
using live_testing::json;
using live_testing::LiveLoop;
using live_testing::WsViewer;

TEST(CheckProgram, TheDeadlockAndItsFiringsAreNamed) {
  live_testing::SceneCopy copy;
  const Scenario s = load_scenario(copy.deadlock());
  const petri::Net net = task::to_net(s.program);
  const CheckOutcome c = check_program(net);
  EXPECT_FALSE(c.ok);
  EXPECT_EQ(c.property, "deadlock");
  ASSERT_FALSE(c.counterexample.empty());
  EXPECT_NE(c.last_marking.find("waiting for"), std::string::npos) << c.last_marking;
  const json j = json::parse(check_json(net, c));
  EXPECT_EQ(j["type"], "check");
  EXPECT_EQ(j["ok"], false);
  EXPECT_EQ(j["property"], "deadlock");
  EXPECT_EQ(j["summary"].get<std::string>().rfind("FAIL", 0), 0u) << j["summary"];
  ASSERT_EQ(j["counterexample"].size(), c.counterexample.size());
  for (const json& step : j["counterexample"]) {
    EXPECT_TRUE(step["robot"] == "r1" || step["robot"] == "r2") << step.dump();
    EXPECT_GT(step["line"].get<int>(), 0) << step.dump();
    EXPECT_NE(step["transition"].get<std::string>().rfind("1. ", 0), 0u) << "one step, not a numbered list";
  }
  EXPECT_EQ(j["dead_marking"], c.last_marking);
  // The preflight refuses it for its check only: it can be served as a replay; the exchange cannot (it passes).
  const Preflight refused = preflight(s, &twin_port());
  ASSERT_FALSE(refused.ok());
  const std::optional<Preflight> replay = counterexample_preflight(s, refused);
  ASSERT_TRUE(replay.has_value());
  EXPECT_TRUE(replay->plan.has_value());
  const Scenario exchange = load_scenario(copy.exchange());
  EXPECT_FALSE(counterexample_preflight(exchange, preflight(exchange, &twin_port())).has_value());
  EXPECT_TRUE(check_program(task::to_net(exchange.program)).ok);
}

TEST_F(LiveLoop, AProgramThatFailsTheCheckIsServedAsItsCounterexamplesReplay) {
  live_testing::SceneCopy copy;
  start({}, 256 * 1024, copy.deadlock().string());
  const CheckOutcome check = check_program(preflight_->net);
  WsViewer v(port());
  ASSERT_TRUE(v.wait_for("cell").is_object());
  const json greeting = v.wait_for("check");
  ASSERT_TRUE(greeting.is_object()) << "the check is sent on connect";
  EXPECT_EQ(greeting["ok"], false);
  EXPECT_EQ(greeting["property"], "deadlock");
  const json first = v.wait_for("frame");
  EXPECT_EQ(first["replay"], true);
  EXPECT_EQ(first["replay_index"], 0);

  v.send(command("play"));
  const json end = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; });
  ASSERT_TRUE(end.is_object()) << "the replay did not end";
  EXPECT_EQ(end["outcome"], "failed");
  EXPECT_NE(end["reason"].get<std::string>().find("deadlock"), std::string::npos) << end["reason"];
  EXPECT_EQ(end["replay_index"].get<std::size_t>(), check.counterexample.size());
  EXPECT_EQ(end["firings"].get<std::size_t>(), check.counterexample.size());
  EXPECT_EQ(end["marking"], check.last_marking) << "the run ends at the counterexample's dead marking";
  // The transitions fired, in the counterexample's order, over the frames seen (each step's once: the frame of the
  // step where the firings grew).
  std::vector<std::string> fired;
  std::uint64_t firings = 0;
  for (std::size_t k = 0; k < v.count("frame"); ++k) {
    const json f = v.wait_for("frame", k);
    if (f["firings"].get<std::uint64_t>() <= firings) continue;
    firings = f["firings"].get<std::uint64_t>();
    for (const json& t : f["fired"]) fired.push_back(t.get<std::string>());
  }
  std::vector<std::string> want;
  for (const petri::TransitionId t : check.counterexample) {
    const petri::Transition& tr = preflight_->net.transitions()[t];
    want.push_back(tr.id + ": " + petri::describe_path(preflight_->net, {t}));
  }
  EXPECT_EQ(fired, want);

  // replay: the run again, from its start.
  const std::size_t cells = v.count("cell");
  auto paused = [](const json& m) { return is_frame(m) && m["state"] == "paused"; };
  const std::size_t paused_before = v.count(paused);
  v.send(command("replay"));
  ASSERT_TRUE(v.wait_for("cell", cells).is_object());
  const json again = v.wait_for(paused, paused_before);
  ASSERT_TRUE(again.is_object());
  EXPECT_EQ(again["replay_index"], 0);
  v.send(R"({"type":"check"})");
  EXPECT_EQ(v.wait_for("check", 1)["property"], "deadlock");
}

// A program whose net is unbounded (r1 signals on every pass of its loop, r2 waits once): the check's witness is the
// firings after which the semaphore's place has grown; served, lock-step and in real time, the replay fires exactly
// those and stops there (its last marking is not dead: nothing else may fire), saying so.
class UnboundedReplay : public LiveLoop {
 protected:
  void expect_replay(bool realtime) {
    live_testing::SceneCopy copy;
    live_testing::write_text(copy.dir() / "unbounded.task",
                             "robot r1 r2\nsemaphore s\n\nsequence r1\n  repeat 3\n    signal s\n  end\nend\n\n"
                             "sequence r2\n  wait s\nend\n");
    const std::filesystem::path scenario = copy.dir() / "unbounded.yaml";
    live_testing::write_text(scenario, "cell: cell.yaml\nprogram: unbounded.task\nrobots: {r1: puma, r2: melfa}\n");
    RunOptions ro;
    ro.realtime = realtime;
    ro.speed = 4;
    start({}, 256 * 1024, scenario.string(), ro);
    const CheckOutcome check = check_program(preflight_->net);
    ASSERT_EQ(check.property, "boundedness");
    ASSERT_FALSE(check.counterexample.empty());
    WsViewer v(port());
    const json greeting = v.wait_for("check");
    ASSERT_TRUE(greeting.is_object());
    EXPECT_EQ(greeting["property"], "boundedness");
    ASSERT_EQ(greeting["counterexample"].size(), check.counterexample.size());
    v.send(command("play"));
    const json end = v.wait_for([](const json& m) { return is_frame(m) && m["state"] == "ended"; });
    ASSERT_TRUE(end.is_object()) << "the replay did not end";
    EXPECT_EQ(end["outcome"], "stopped");
    EXPECT_EQ(end["reason"], "the counterexample ends here: " + check.last_marking);
    EXPECT_EQ(end["firings"].get<std::size_t>(), check.counterexample.size());
    EXPECT_EQ(end["replay_index"].get<std::size_t>(), check.counterexample.size());
    EXPECT_EQ(end["marking"], check.last_marking);
  }
};

TEST_F(UnboundedReplay, LockStepFiresTheWitnessAndStopsWhereThePlaceHasGrown) {
  expect_replay(false);
}

TEST_F(UnboundedReplay, RealTimeToo) {
  expect_replay(true);
}

}  // namespace
}  // namespace cellwright::cell
