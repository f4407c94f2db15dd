// The run's end of a lock-step turn link (distributed/turn_link.hpp) against a peer written here from the wire up
// (raw samples on the turn topics, two DDS participants over UDP loopback): garbage and hellos of another run are
// refused before the first turn; an agent that answers another turn, or garbage, in the middle of a turn is lost for
// good with the reason (the runtime's watch makes that a link_lost fault); a real TurnAgent meets the link and its
// robot control's first step calls the run's driver through it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <deque>
#include <mutex>
#include <condition_variable>
#include <random>
#include <thread>

#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/turn_link.hpp"
#include "cellwright/distributed/turn_wire.hpp"
#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/task/compile.hpp"

namespace cellwright::distributed {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;

int test_domain() {
  return 20 + static_cast<int>((::getpid() + 101) % 200);
}

struct Exchange {
  task::CompiledProgram program = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/exchange.task");
  models::CellDescription cell = models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml");
};

const Exchange& exchange() {
  static const Exchange e;
  return e;
}

// The run's side of robot r1 (the PUMA): its queues, model and log, and its TurnLink.
struct RunSide {
  Participant participant{DdsOptions{.domain = test_domain()}, "turn_link_test_run"};
  runtime::MessageQueue<runtime::MotionCommand> commands{4};
  runtime::MessageQueue<runtime::RobotStatus> statuses{16};
  runtime::SharedEnvironment env{runtime::make_environment_model(exchange().cell)};
  runtime::EventLog log;
  std::string settings =
      turn_settings(exchange().program, "puma", std::chrono::milliseconds(10), runtime::Perception::kTruth);
  TurnLink link{participant, "puma", 0, exchange().program, settings, commands, statuses};
  RunSide() { link.share(env, log); }
};

// A peer speaking the agent's side by hand: what it reads from the turn topic, and a writer for the call topic.
struct HandAgent {
  Participant participant{DdsOptions{.domain = test_domain()}, "turn_link_test_peer"};
  std::mutex mutex;
  std::condition_variable got;
  std::deque<std::vector<char>> turns;
  std::unique_ptr<RawWriter> writer;
  std::unique_ptr<RawReader> reader;
  HandAgent() {
    register_type(participant, kTurnTypeName, max_turn_size());
    register_type(participant, kTurnCallTypeName, max_turn_call_size());
    writer = std::make_unique<RawWriter>(participant, call_topic("puma"), kTurnCallTypeName);
    reader = std::make_unique<RawReader>(participant, turn_topic("puma"), kTurnTypeName,
                                         [this](const std::vector<char>& b) {
                                           {
                                             std::lock_guard lock(mutex);
                                             turns.push_back(b);
                                           }
                                           got.notify_all();
                                         });
    reader->start();
  }
  bool matched() { return writer->wait_for_reader(10s) && reader->wait_for_writer(10s); }
  void hello(const std::string& settings) {
    TurnCall h;
    h.kind = TurnCall::Kind::kDone;
    h.model = runtime::make_environment_model(exchange().cell);
    h.settings = settings;
    ASSERT_TRUE(writer->write(encode_turn_call(h)));
  }
  std::vector<char> next_turn() {
    std::unique_lock lock(mutex);
    EXPECT_TRUE(got.wait_for(lock, 10s, [&] { return !turns.empty(); }));
    if (turns.empty()) return {};
    std::vector<char> b = std::move(turns.front());
    turns.pop_front();
    return b;
  }
};

drivers::ScriptedDriverConfig puma_driver() {
  drivers::ScriptedDriverConfig c;
  c.capabilities.joints = 6;
  c.capabilities.joint_control = true;
  c.capabilities.reads_joints = true;
  c.capabilities.gripper = true;
  c.capabilities.max_joint_speed.assign(6, 1.0);
  c.home_joints = exchange().cell.find_robot("puma")->home;
  return c;
}

TEST(TurnLink, GarbageAndAHelloOfAnotherRunAreRefusedBeforeTheFirstTurn) {
  RunSide run;
  HandAgent peer;
  ASSERT_TRUE(peer.matched());
  std::mt19937 random(7);
  std::vector<char> garbage(64);
  for (char& c : garbage) c = static_cast<char>(random());
  garbage[0] = 0;
  garbage[1] = 1;
  ASSERT_TRUE(peer.writer->write(garbage));
  peer.hello(turn_settings(exchange().program, "puma", std::chrono::milliseconds(10), runtime::Perception::kVision));
  EXPECT_FALSE(run.link.wait_for_agent(1500ms));
  EXPECT_THAT(run.link.refused_hello(), HasSubstr("perception vision"));
  EXPECT_THAT(run.link.refused_hello(), HasSubstr("perception truth"));
  EXPECT_GE(run.link.refusals().count, 1u);
  // The right hello is taken, and nothing is lost yet.
  peer.hello(run.settings);
  EXPECT_TRUE(run.link.wait_for_agent(5s));
  EXPECT_TRUE(run.link.state().present);
}

// The link met by the hand agent, then its first turn answered by `reply` (given the turn's bytes): the link's state
// after the turn.
runtime::LinkState after_a_turn_answered_with(const std::function<std::vector<char>(const TurnMessage&)>& reply) {
  RunSide run;
  HandAgent peer;
  EXPECT_TRUE(peer.matched());
  peer.hello(run.settings);
  EXPECT_TRUE(run.link.wait_for_agent(5s));
  drivers::ScriptedDriver driver(puma_driver());
  runtime::MotionCommand c;
  c.robot = 0;
  c.index = 0;
  c.primitive = exchange().program.programs[0].primitives[0];
  EXPECT_EQ(run.commands.try_push(c), runtime::QueueStatus::ok);
  std::thread turn([&] { run.link.take_turn(std::chrono::milliseconds(10), driver); });
  const std::vector<char> bytes = peer.next_turn();
  const TurnMessage t = decode_turn(bytes, 0, exchange().program, runtime::make_environment_model(exchange().cell));
  EXPECT_EQ(t.kind, TurnMessage::Kind::kTurn);
  EXPECT_EQ(t.turn, 1u);
  EXPECT_EQ(t.commands.size(), 1u);  // what task control queued goes with the turn
  EXPECT_TRUE(peer.writer->write(reply(t)));
  turn.join();
  return run.link.state();
}

TEST(TurnLink, AnAnswerForAnotherTurnLosesTheLinkForGoodNamingBothTurns) {
  const runtime::LinkState s = after_a_turn_answered_with([](const TurnMessage&) {
    TurnCall d;
    d.kind = TurnCall::Kind::kDone;
    d.sequence = 1;
    d.turn = 7;
    d.model = runtime::make_environment_model(exchange().cell);
    return encode_turn_call(d);
  });
  EXPECT_FALSE(s.present);
  EXPECT_EQ(s.losses, 1u);
  EXPECT_EQ(s.in_flight, 0);  // the command sent with the turn: the watch's link_lost is about it
  EXPECT_THAT(s.lost_detail, HasSubstr("answered for turn 7 in turn 1"));
}

TEST(TurnLink, GarbageInTheMiddleOfATurnLosesTheLinkSayingWhy) {
  const runtime::LinkState s = after_a_turn_answered_with([](const TurnMessage&) {
    return std::vector<char>{0, 1, 0, 0, 9, 9, 9};
  });
  EXPECT_FALSE(s.present);
  EXPECT_THAT(s.lost_detail, HasSubstr("does not decode in turn 1"));
}

TEST(TurnLink, AnAgentThatSkipsANumberLosesTheLink) {
  const runtime::LinkState s = after_a_turn_answered_with([](const TurnMessage&) {
    TurnCall d;
    d.kind = TurnCall::Kind::kDone;
    d.sequence = 2;  // 1 never came
    d.turn = 1;
    d.model = runtime::make_environment_model(exchange().cell);
    return encode_turn_call(d);
  });
  EXPECT_FALSE(s.present);
  EXPECT_THAT(s.lost_detail, HasSubstr("turn call"));
}

TEST(TurnLink, ARealAgentMeetsTheLinkAndItsFirstStepCallsTheRunsDriver) {
  RunSide run;
  Participant agent_participant(DdsOptions{.domain = test_domain()}, "turn_link_test_agent");
  TurnAgentConfig config;
  config.program = exchange().program;
  config.cell = exchange().cell;
  config.binding.robots["r1"] = {"puma", {}};
  config.binding.robots["r2"] = {"melfa", {}};
  config.binding.objects["B"] = {"output_drop", {}};  // as scenes/exchange.yaml binds it
  config.robot = "puma";
  TurnAgent agent(agent_participant, config);
  TurnAgentSummary summary;
  std::thread serving([&] { summary = agent.serve(20s); });
  ASSERT_TRUE(run.link.wait_for_agent(10s));
  drivers::ScriptedDriver driver(puma_driver());
  ASSERT_EQ(driver.connect(), drivers::ErrorCode::none);
  for (int k = 1; k <= 5; ++k) {
    run.link.take_turn(std::chrono::milliseconds(10 * k), driver);
    driver.advance(10);
  }
  EXPECT_TRUE(run.link.state().present) << run.link.state().lost_detail;
  run.link.stop();  // the end: the agent leaves
  serving.join();
  EXPECT_TRUE(summary.run_came);
  EXPECT_TRUE(summary.run_ended);
  EXPECT_EQ(summary.turns, 5u);
  EXPECT_EQ(summary.calls, run.link.calls());
  EXPECT_GT(run.link.calls(), 0u);
  // Robot control's bring-up homed the run's driver, through the link.
  EXPECT_NE(driver.state(), drivers::DriverState::connected);
  EXPECT_EQ(summary.refusals.count, 0u);
}

}  // namespace
}  // namespace cellwright::distributed
