// The Runtime end to end without MuJoCo: the paper's Table 1 program on scripted arms and a kinematic plant, in
// lock-step (byte-identical logs) and real-time mode, with failures, bad input and stepping.
#include "cellwright/runtime/runtime.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <algorithm>
#include <chrono>
#include <sstream>
#include <thread>
#include <vector>

#include "cellwright/drivers/faulty_driver.hpp"
#include "cellwright/models/robot_model.hpp"
#include "controller/runtime/scripted_cell.hpp"
#include "controller/runtime/self_running_driver.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::ScriptedCell;
using cellwright::testing::ScriptedTiming;
using cellwright::testing::SelfRunningDriver;
using ::testing::HasSubstr;

std::vector<nlohmann::json> parse(const EventLog& log) {
  std::vector<nlohmann::json> out;
  for (const auto& l : log.lines()) out.push_back(nlohmann::json::parse(l));
  return out;
}

std::vector<nlohmann::json> parse_text(const std::string& jsonl) {
  std::vector<nlohmann::json> out;
  std::istringstream in(jsonl);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  }
  return out;
}

// Index of the first event with these key values, or -1.
long find(const std::vector<nlohmann::json>& events, const nlohmann::json& match) {
  for (std::size_t i = 0; i < events.size(); ++i) {
    bool all = true;
    for (const auto& [k, v] : match.items()) all = all && events[i].contains(k) && events[i][k] == v;
    if (all) return static_cast<long>(i);
  }
  return -1;
}

// Per robot label, the primitives in the order their commands started.
std::map<std::string, std::vector<int>> starts(const std::vector<nlohmann::json>& events) {
  std::map<std::string, std::vector<int>> out;
  for (const auto& e : events) {
    if (e["type"] == "command_start") out[e["robot"]].push_back(e["primitive"]);
  }
  return out;
}

TEST(RuntimeRun, ExchangeProgramRunsToCompletionAndMovesThePart) {
  ScriptedCell cell;
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason << "\n" << rt.log().text();
  EXPECT_TRUE(cell.config.net.is_final(r.final_marking));
  ASSERT_TRUE(r.finished_at.has_value());
  EXPECT_LE(*r.finished_at, r.end_time);
  // Part A was carried from the input conveyor to the output drop location and rests there, held by nobody.
  const models::LocationSpec& drop = *cell.config.cell.find_location("output_drop");
  const Eigen::Vector3d a = cell.plant->workpiece_pose("A").translation();
  const double half = cell.config.cell.find_workpiece("A")->size.z() / 2;
  EXPECT_LT((a.head<2>() - drop.pose.xyz.head<2>()).norm(), 0.005) << a.transpose();
  EXPECT_NEAR(a.z() - half, drop.pose.xyz.z(), 0.005) << rt.log().text();
  EXPECT_EQ(r.environment.find_workpiece("A")->held_by, "");
  EXPECT_FALSE(r.environment.find_robot("melfa")->hold.has_value());
  // The log tells the same story: it starts and ends, the grips were sensed on A.
  const auto events = parse(rt.log());
  EXPECT_EQ(events.front()["type"], "run_start");
  EXPECT_EQ(events.back()["type"], "run_end");
  EXPECT_EQ(events.back()["outcome"], "finished");
  EXPECT_NE(find(events, {{"type", "sensor"}, {"robot", "r1"}, {"condition", "gripped"}, {"workpiece", "A"}}), -1);
  EXPECT_NE(find(events, {{"type", "sensor"}, {"robot", "r2"}, {"condition", "gripped"}, {"workpiece", "A"}}), -1);
  EXPECT_EQ(r.firings, cell.config.net.num_transitions());  // every transition of the two chains fired once
}

// The exchange program's order, as the net makes it: the hand-over handshake, and each robot's commands in program
// order, each started after its firing and ended ok.
void expect_exchange_order(const std::vector<nlohmann::json>& events) {
  // r2 moves its fingers around the part (primitive 5, hand_grasp) only after r1 signalled ready (r1.t8 fired).
  const long ready = find(events, {{"type", "fire"}, {"transition", "r1.t8"}});
  const long grasp = find(events, {{"type", "command_start"}, {"robot", "r2"}, {"primitive", 5}});
  ASSERT_NE(ready, -1);
  ASSERT_NE(grasp, -1);
  EXPECT_LT(ready, grasp);
  // r1 opens (10) only after r2 reported its close (6) done; r2 departs (9) only after r1's open ended.
  EXPECT_LT(find(events, {{"type", "command_end"}, {"robot", "r2"}, {"primitive", 6}, {"ok", true}}),
            find(events, {{"type", "command_start"}, {"robot", "r1"}, {"primitive", 10}}));
  EXPECT_LT(find(events, {{"type", "command_end"}, {"robot", "r1"}, {"primitive", 10}, {"ok", true}}),
            find(events, {{"type", "command_start"}, {"robot", "r2"}, {"primitive", 9}}));
  // Each command starts after the firing that began it, and ends ok once.
  for (const auto& [robot, prims] : starts(events)) {
    for (int k : prims) {
      const std::string t = robot + ".t" + std::to_string(k);
      EXPECT_LT(find(events, {{"type", "fire"}, {"transition", t}}),
                find(events, {{"type", "command_start"}, {"robot", robot}, {"primitive", k}}));
      EXPECT_NE(find(events, {{"type", "command_end"}, {"robot", robot}, {"primitive", k}, {"ok", true}}), -1);
    }
  }
  EXPECT_THAT(starts(events)["r1"], ::testing::ElementsAre(0, 1, 2, 3, 4, 7, 10));
  EXPECT_THAT(starts(events)["r2"], ::testing::ElementsAre(2, 3, 5, 6, 9, 12, 13, 14, 15));
}

TEST(RuntimeRun, CommandStartsRespectTheNet) {
  ScriptedCell cell;
  Runtime rt(cell.config);
  ASSERT_EQ(rt.run().outcome, Outcome::kFinished);
  expect_exchange_order(parse(rt.log()));
}

// A cell with no simulation at all: both arms are controllers that run by themselves on the runtime's clock and say
// where they are only when asked. Nothing steps a plant and nothing senses the grips (a close is taken as done); the
// parts are known from the cell description and move with the hands that hold them.
TEST(RuntimeWithoutSimulation, TheExchangeRunsOnSelfRunningControllersInTheNetsOrder) {
  const auto run = [] {
    ScriptedCell cell;
    std::map<std::string, std::unique_ptr<SelfRunningDriver>> own;
    for (auto& [name, d] : cell.drivers) {
      own[name] = std::make_unique<SelfRunningDriver>(*d, std::chrono::milliseconds(1));
      cell.config.drivers[name] = own[name].get();
    }
    cell.config.plant = nullptr;
    cell.config.sensors = {};
    cell.config.perception = Perception::kCad;
    Runtime rt(cell.config);
    const RunResult r = rt.run();
    EXPECT_EQ(r.outcome, Outcome::kFinished) << r.reason << "\n" << rt.log().text();
    for (const auto& [name, d] : cell.drivers) {
      // Asked where it is many times (every period while it worked), and run on the runtime's clock to the end.
      EXPECT_GT(d->calls().request_position, 50u) << name;
      EXPECT_EQ(std::chrono::milliseconds(own[name]->ticks()), r.end_time) << name;
    }
    // Part A ends where the MELFA put it down, as the model knows it.
    const models::LocationSpec& drop = *cell.config.cell.find_location("output_drop");
    const Eigen::Vector3d a = r.environment.find_workpiece("A")->pose.translation();
    EXPECT_LT((a.head<2>() - drop.pose.xyz.head<2>()).norm(), 0.005) << a.transpose();
    return rt.log().text();
  };
  const std::string log = run();
  const auto events = parse_text(log);
  expect_exchange_order(events);
  EXPECT_NE(find(events, {{"type", "sensor"}, {"robot", "r1"}, {"condition", "grip_not_sensed"}, {"workpiece", "A"}}),
            -1);
  EXPECT_EQ(find(events, {{"type", "workpiece_arrived"}}), -1);
  EXPECT_EQ(run(), log);  // lock-step without a simulation is deterministic too
}

TEST(RuntimeRun, TheWallTimeLimitEndsARunThatTakesTooLong) {
  ScriptedCell cell;
  cell.config.limits.wall_time = std::chrono::nanoseconds(1);  // over at the first period
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  EXPECT_EQ(r.outcome, Outcome::kTimeout);
  EXPECT_THAT(r.reason, HasSubstr("wall time limit of 1e-09 s was reached at simulation time"));
  const auto events = parse(rt.log());
  EXPECT_EQ(events.back()["outcome"], "timeout");
  EXPECT_THAT(events.back()["reason"].get<std::string>(), HasSubstr("wall time limit"));

  ScriptedCell roomy;  // a limit the run stays well within changes nothing
  roomy.config.limits.wall_time = std::chrono::hours(1);
  EXPECT_EQ(Runtime(roomy.config).run().outcome, Outcome::kFinished);
}

// A recorder that is slow (a video encoder catching up) does not use up the wall-time limit: the run ends as it does
// without it, with the same log. The recorder takes 1 s in all; the limit is half of that, far more than the run
// itself needs.
TEST(RuntimeRun, TimeSpentRecordingDoesNotCountTowardsTheWallTimeLimit) {
  // The limit is scaled to this machine (a sanitized build on a loaded machine runs the cell many times slower): five
  // times the wall time of the run unrecorded, while the recording alone takes four times the limit. Counted, the
  // recording would end the run at the limit; not counted, the run finishes well inside it.
  ScriptedCell plain;
  Runtime without(plain.config);
  const auto started = std::chrono::steady_clock::now();
  const RunResult expected = without.run();
  const auto unrecorded = std::chrono::steady_clock::now() - started;
  ASSERT_EQ(expected.outcome, Outcome::kFinished);
  const auto limit = std::max(std::chrono::duration_cast<std::chrono::milliseconds>(5 * unrecorded),
                              std::chrono::milliseconds(200));

  ScriptedCell cell;
  cell.config.limits.wall_time = limit;
  int frames = 0;
  cell.config.observers.push_back({expected.end_time / 20, true, [&frames, limit](const Observation&) {
                                     ++frames;
                                     // the slow consumer, not a wait for another thread
                                     std::this_thread::sleep_for(limit / 5);
                                   }});
  Runtime with(cell.config);
  const RunResult r = with.run();
  EXPECT_EQ(r.outcome, Outcome::kFinished) << r.reason;
  EXPECT_GE(frames, 20);
  EXPECT_EQ(with.log().text(), without.log().text());
}

TEST(RuntimeRun, PerRobotTimeAddsUpToTheRunTime) {
  ScriptedCell cell;
  cell.config.limits.settle = std::chrono::milliseconds(200);
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished);
  EXPECT_EQ(r.end_time, *r.finished_at + std::chrono::milliseconds(200));
  ASSERT_EQ(r.robots.size(), 2u);
  for (const RobotTime& t : r.robots) {
    EXPECT_EQ(t.time.total(), r.end_time) << t.robot;
    EXPECT_GT(t.time.busy.count(), 0) << t.robot;
    EXPECT_GE(t.time.idle, std::chrono::milliseconds(200)) << t.robot;  // at least the settle time
  }
  EXPECT_EQ(r.robots[0].cell, "puma");
  EXPECT_EQ(r.robots[1].cell, "melfa");
  // r2 waits while r1 picks; r1 waits while r2 grips.
  EXPECT_GT(r.robots[1].time.waiting, r.robots[0].time.busy / 4);
  EXPECT_GT(r.robots[0].time.waiting.count(), 0);
}

TEST(RuntimeRun, AFailedCommandStopsTheRunWithTheReason) {
  ScriptedCell cell;
  // Puma's moves: above(A), then at(A): the second fails.
  drivers::FaultPlan plan;
  plan.rules.push_back(
      {drivers::CommandKind::move_joints, 2, {drivers::ErrorCode::unreachable, false, "joint 2 at its limit"}});
  drivers::FaultyDriver faulty(cell.driver("puma"), plan);
  cell.config.drivers["puma"] = &faulty;
  cell.config.motion.recovery.enabled = false;  // the first failure ends the run (runtime_recovery_test: recovery)
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFailed);
  EXPECT_THAT(r.reason, HasSubstr("robot r1, primitive 2 'move at(A)'"));
  EXPECT_THAT(r.reason, HasSubstr("joint 2 at its limit"));
  const auto events = parse(rt.log());
  EXPECT_NE(find(events, {{"type", "command_end"}, {"robot", "r1"}, {"primitive", 2}, {"ok", false}}), -1);
  EXPECT_EQ(events.back()["outcome"], "failed");
  EXPECT_EQ(find(events, {{"type", "command_start"}, {"robot", "r1"}, {"primitive", 3}}), -1);
  EXPECT_FALSE(cell.config.net.is_final(r.final_marking));
  EXPECT_LT(r.end_time, std::chrono::seconds(5));  // stopped at once, not at the time limit
}

TEST(RuntimeRun, AGripOnNothingFailsTheClose) {
  ScriptedCell cell;
  std::map<std::string, drivers::ScriptedDriver*> raw;
  for (auto& [name, d] : cell.drivers) raw[name] = d.get();
  // Part A lies 5 cm beside where the cell description has it, and only the presence sensors tell the controller
  // (perception cad): the fingers close beside it, and the grip sensor feels nothing between them.
  models::CellDescription moved = cell.config.cell;
  for (auto& w : moved.workpieces) {
    if (w.name == "A") w.pose.xyz.y() += 0.05;
  }
  ScriptedPlant plant(moved, raw);
  cell.config.plant = &plant;
  cell.config.sensors = plant.sensors();
  cell.config.perception = Perception::kCad;
  cell.config.motion.recovery.enabled = false;
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFailed);
  EXPECT_THAT(r.reason, HasSubstr("'close A'"));
  EXPECT_THAT(r.reason, HasSubstr("closed on nothing (expected A)"));
  EXPECT_NE(find(parse(rt.log()), {{"type", "sensor"}, {"robot", "r1"}, {"condition", "closed_on_nothing"}}), -1);
}

TEST(RuntimeRun, WithRecoveryAGripOnNothingIsTriedAgainThenThePartIsSetAsideAndTheProgramGoesOn) {
  ScriptedCell cell;
  std::map<std::string, drivers::ScriptedDriver*> raw;
  for (auto& [name, d] : cell.drivers) raw[name] = d.get();
  // As above: the controller (perception cad) believes A is 5 cm from where it is, so every grasp closes beside it.
  models::CellDescription moved = cell.config.cell;
  for (auto& w : moved.workpieces) {
    if (w.name == "A") w.pose.xyz.y() += 0.05;
  }
  ScriptedPlant plant(moved, raw);
  cell.config.plant = &plant;
  cell.config.sensors = plant.sensors();
  cell.config.perception = Perception::kCad;
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason << "\n" << rt.log().text();
  const auto events = parse(rt.log());
  // Sensed, diagnosed as a part not where expected, picked again where the model has it: max_attempts times.
  const long first = find(events, {{"type", "fault_detected"}, {"robot", "r1"}, {"symptom", "closed_on_nothing"}});
  ASSERT_NE(first, -1);
  // The simulation thread logged the plant's physical state with it, in the next period: what a report judges a
  // detection by (a false alarm or a real fault).
  const long physical = find(events, {{"type", "physical"}});
  ASSERT_GT(physical, first);
  EXPECT_LE(events[static_cast<std::size_t>(physical)]["t"].get<double>() -
                events[static_cast<std::size_t>(first)]["t"].get<double>(),
            0.0101);
  EXPECT_TRUE(events[static_cast<std::size_t>(physical)]["held"].is_array());
  int picks = 0, asides = 0;
  for (const auto& e : events) {
    if (e["type"] == "diagnosis" && e["action"] == "pick_again") ++picks;
    if (e["type"] == "diagnosis" && e["action"] == "set_aside") ++asides;
  }
  EXPECT_EQ(picks, RecoveryOptions{}.max_attempts);
  EXPECT_EQ(asides, 1);
  // Then A is lost, where it was last believed to be, and everything about it is skipped by both robots.
  EXPECT_NE(find(events, {{"type", "workpiece_lost"}, {"workpiece", "A"}}), -1);
  EXPECT_NE(find(events, {{"type", "skipped"}, {"robot", "r2"}}), -1);
  EXPECT_NE(find(events, {{"type", "recovery_end"}, {"robot", "r1"}, {"action", "set_aside"}, {"ok", true}}), -1);
  EXPECT_TRUE(r.environment.find_workpiece("A")->lost);
  EXPECT_TRUE(cell.config.net.is_final(r.final_marking));
}

TEST(RuntimeRun, AStopAskedForFromAnotherThreadStopsTheCellAndKeepsTheLog) {
  ScriptedCell cell;
  Runtime* self = nullptr;
  // Called by the simulation thread: as a signal-handling thread would, it asks for the stop while the run goes on.
  cell.config.observers.push_back({std::chrono::milliseconds(300), false, [&](const Observation& o) {
                                     if (self != nullptr && o.time >= std::chrono::milliseconds(300)) {
                                       self->request_stop("stopped by the user (SIGINT)");
                                     }
                                   }});
  Runtime rt(cell.config);
  self = &rt;
  const RunResult r = rt.run();
  EXPECT_EQ(r.outcome, Outcome::kStopped);
  EXPECT_EQ(r.reason, "stopped by the user (SIGINT)");
  EXPECT_GE(r.end_time, std::chrono::milliseconds(300));
  EXPECT_LT(r.end_time, std::chrono::milliseconds(400));
  const auto events = parse(rt.log());
  ASSERT_GE(events.size(), 2U);
  EXPECT_EQ(events[events.size() - 2]["type"], "cell_stopped");
  EXPECT_EQ(events.back()["type"], "run_end");
  EXPECT_EQ(events.back()["outcome"], "stopped");
  // Everything logged before the stop is still there: the commands that had started.
  EXPECT_NE(find(events, {{"type", "command_start"}, {"robot", "r1"}}), -1);
}

TEST(RuntimeRun, TheSimTimeLimitEndsARunThatDoesNotFinish) {
  ScriptedCell cell;
  cell.config.limits.sim_time = std::chrono::milliseconds(500);
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  EXPECT_EQ(r.outcome, Outcome::kTimeout);
  EXPECT_EQ(r.end_time, std::chrono::milliseconds(500));
  EXPECT_THAT(r.reason, HasSubstr("0.5000 s"));
}

TEST(RuntimeRun, LockstepLogsAreByteIdenticalOverTwentyRuns) {
  std::string first;
  for (int i = 0; i < 20; ++i) {
    ScriptedCell cell;
    Runtime rt(cell.config);
    ASSERT_EQ(rt.run().outcome, Outcome::kFinished);
    if (i == 0) {
      first = rt.log().text();
      ASSERT_GT(rt.log().size(), 50u);
    } else {
      ASSERT_EQ(rt.log().text(), first) << "run " << i;
    }
  }
}

// The lock-step turns are a deployment choice that must not show in the log: every participant on the simulation
// thread or each on its own, passing over the participants with nothing to do or giving everyone every turn, the run
// is the same byte for byte. Run with a lost signal and the wait watchdog, so that task control must also take its
// turns while a robot waits (the watchdog is a time, not a message).
struct LockstepVariant {
  LockstepThreads threads;
  bool skip_idle;
};

std::pair<std::string, LockstepStats> run_variant(LockstepVariant v, bool lose_a_signal) {
  ScriptedCell cell;
  cell.config.lockstep_threads = v.threads;
  cell.config.lockstep_skip_idle = v.skip_idle;
  if (lose_a_signal) {
    cell.config.signal_filter = [](const SignalSent& s) { return s.count != 1; };  // the first signal is lost
    cell.config.motion.recovery.wait_timeout = std::chrono::milliseconds(500);
  }
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  EXPECT_EQ(r.outcome, Outcome::kFinished) << r.reason;
  return {rt.log().text(), r.lockstep};
}

TEST(RuntimeRun, TheLogIsTheSameOnOneThreadOrManyAndWithIdleParticipantsPassedOver) {
  for (const bool lose : {false, true}) {
    SCOPED_TRACE(lose ? "a signal lost" : "plain");
    const auto [before, today] = run_variant({LockstepThreads::kOwn, false}, lose);  // the scheduling of old
    ASSERT_GT(before.size(), 1000u);
    if (lose) {
      ASSERT_NE(before.find("\"wait_timeout\""), std::string::npos);  // the watchdog did act
    }
    for (const LockstepVariant v : {LockstepVariant{LockstepThreads::kOwn, true},
                                    LockstepVariant{LockstepThreads::kShared, false},
                                    LockstepVariant{LockstepThreads::kShared, true}}) {
      const auto [log, stats] = run_variant(v, lose);
      EXPECT_EQ(log, before) << "threads " << (v.threads == LockstepThreads::kOwn ? "own" : "shared") << ", skip "
                             << v.skip_idle;
      EXPECT_EQ(stats.rounds, today.rounds);
    }
  }
}

TEST(RuntimeRun, IdleParticipantsCostNoTurnAndOneThreadNoHandOff) {
  // The exchange has 4 participants: simulation, task control, two robots.
  const auto [log_own, own] = run_variant({LockstepThreads::kOwn, false}, false);
  EXPECT_GT(own.rounds, 100u);
  EXPECT_EQ(own.skipped, 0u);
  EXPECT_EQ(own.turns, 4 * own.rounds + 1);  // the simulation's last turn ends the run before its yield
  EXPECT_EQ(own.handoffs + 1, own.turns);    // every turn but that last one woke another thread
  const auto [log_skip, skip] = run_variant({LockstepThreads::kOwn, true}, false);
  // Task control takes a turn when a robot has reported, and every period while a robot waits for an event (the
  // watchdog); otherwise it is passed over. The robots take every turn.
  EXPECT_GT(skip.skipped, 0u);
  EXPECT_EQ(skip.turns + skip.skipped, own.turns);
  EXPECT_LT(skip.handoffs, own.handoffs);
  const auto [log_one, one] = run_variant({LockstepThreads::kShared, true}, false);
  EXPECT_EQ(one.handoffs, 0u);  // every turn on the simulation thread
  EXPECT_EQ(one.turns, skip.turns);
  EXPECT_EQ(one.pauses, 0u);  // run(), not step()
}

TEST(RuntimeRun, TheLogShowsWhenTwoRobotsDurationsAreSwapped) {
  // The byte comparison above would catch an order change: swapping the arms' speeds changes when events happen.
  ScriptedCell a("exchange.task", {{"puma", ScriptedTiming{120, 40}}, {"melfa", ScriptedTiming{80, 40}}});
  ScriptedCell b("exchange.task", {{"puma", ScriptedTiming{80, 40}}, {"melfa", ScriptedTiming{120, 40}}});
  Runtime ra(a.config), rb(b.config);
  ASSERT_EQ(ra.run().outcome, Outcome::kFinished);
  ASSERT_EQ(rb.run().outcome, Outcome::kFinished);
  EXPECT_NE(ra.log().text(), rb.log().text());
  // ... while the order of each robot's own commands is the program's in both.
  EXPECT_EQ(starts(parse(ra.log())), starts(parse(rb.log())));
}

TEST(RuntimeRun, SteppingStopsAtEachFiringAndGivesTheSameLogAsARun) {
  ScriptedCell plain;
  Runtime reference(plain.config);
  ASSERT_EQ(reference.run().outcome, Outcome::kFinished);

  ScriptedCell cell;
  Runtime rt(cell.config);
  int steps = 0;
  std::uint64_t firings = 0;
  StepState s;
  do {
    s = rt.step();
    ++steps;
    if (s.ended) break;
    EXPECT_FALSE(s.task.last_fired.empty()) << "step " << steps;
    EXPECT_GT(s.task.firings, firings);
    firings = s.task.firings;
    ASSERT_EQ(s.robots.size(), 2u);
    EXPECT_EQ(s.task.marking.size(), cell.config.net.num_places());
  } while (steps < 200);
  ASSERT_TRUE(s.ended);
  ASSERT_TRUE(s.result.has_value());
  EXPECT_EQ(s.result->outcome, Outcome::kFinished);
  EXPECT_GT(steps, 10);
  EXPECT_EQ(rt.log().text(), reference.log().text());
}

// step(until): a step also ends at the first control period from that time when nothing fired before it, and the
// run stepped so is the run: the same log as a plain run.
TEST(RuntimeRun, SteppingUntilATimeStopsThereOrAtAFiringBefore) {
  ScriptedCell plain;
  Runtime reference(plain.config);
  ASSERT_EQ(reference.run().outcome, Outcome::kFinished);

  ScriptedCell cell;
  Runtime rt(cell.config);
  StepState s = rt.step();
  ASSERT_FALSE(s.ended);
  const SimDuration until = s.time + std::chrono::milliseconds(5);  // within the next control period (10 ms)
  s = rt.step(until);
  ASSERT_FALSE(s.ended);
  EXPECT_GE(s.time, until);
  EXPECT_LT(s.time, until + cell.config.period);
  int steps = 0;
  SimDuration t = s.time;
  while (!s.ended && steps++ < 2000) {
    s = rt.step(t + std::chrono::milliseconds(25));
    if (s.ended) break;
    EXPECT_LE(s.time, t + std::chrono::milliseconds(30)) << "past the time asked without a firing";
    EXPECT_TRUE(s.time >= t + std::chrono::milliseconds(25) || !s.task.last_fired.empty());
    t = s.time;
  }
  ASSERT_TRUE(s.ended);
  EXPECT_EQ(rt.log().text(), reference.log().text());
}

TEST(RuntimeRun, AStepShowsEachRobotsCommandAndState) {
  ScriptedCell cell;
  Runtime rt(cell.config);
  const StepState s = rt.step();
  ASSERT_FALSE(s.ended);
  // The first firings: r1 begins `open`, r2 signals and waits at the step-1 barrier.
  EXPECT_THAT(s.task.last_fired, ::testing::ElementsAre("r1.t0", "r2.t0", "r2.t1"));
  EXPECT_EQ(s.task.robots[0].activity, RobotActivity::kBusy);
  EXPECT_EQ(s.task.robots[0].command, "open");
  EXPECT_EQ(s.task.robots[1].activity, RobotActivity::kWaiting);
  EXPECT_EQ(s.robots[0].cell, "puma");
  EXPECT_EQ(s.robots[1].phase, RobotPhase::kBringUp);  // homing takes 30 ms, the first step ends at 10 ms
  EXPECT_EQ(s.robots[1].driver, drivers::DriverState::connected);
  // Stepping on after run(): the rest runs to the end.
  const RunResult r = rt.run();
  EXPECT_EQ(r.outcome, Outcome::kFinished);
  EXPECT_TRUE(rt.step().ended);
}

TEST(RuntimeRun, RealtimeModeRunsTheSameProgram) {
  ScriptedCell lockstep;
  Runtime reference(lockstep.config);
  ASSERT_EQ(reference.run().outcome, Outcome::kFinished);

  ScriptedCell cell("exchange.task", {}, Mode::kRealtime);
  // Paced to the wall clock, a period is 10 ms / speed of wall time for every thread's turn and wake-up. A sanitized
  // build runs each several times slower: at 20x its robots fell behind the pacer in about 1 run in 7 under ASan
  // (the program then outran its 30 s of simulated time), so it runs at 5x there.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  cell.config.realtime_speed = 5.0;
#else
  cell.config.realtime_speed = 20.0;
#endif
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason << "\n" << rt.log().text();
  EXPECT_EQ(starts(parse(rt.log())), starts(parse(reference.log())));
  const Eigen::Vector3d a = cell.plant->workpiece_pose("A").translation();
  EXPECT_LT((a.head<2>() - cell.config.cell.find_location("output_drop")->pose.xyz.head<2>()).norm(), 0.005);
  for (const RobotTime& t : r.robots) EXPECT_EQ(t.time.total(), r.end_time);
}

// A real-time run's speed in the tests: see RealtimeModeRunsTheSameProgram.
double test_speed() {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  return 5.0;
#else
  return 20.0;
#endif
}

// Holding a real-time run (`twin serve --realtime`): stepped firing by firing it is the same program, and while held
// its clock stands still and nothing moves, however long the hold.
TEST(RuntimeHold, ARealtimeRunSteppedFiringByFiringHoldsItsClockAndRunsTheSameProgram) {
  ScriptedCell lockstep;
  Runtime reference(lockstep.config);
  ASSERT_EQ(reference.run().outcome, Outcome::kFinished);

  ScriptedCell cell("exchange.task", {}, Mode::kRealtime);
  cell.config.realtime_speed = test_speed();
  Runtime rt(cell.config);
  StepState s;
  std::uint64_t firings = 0;
  int steps = 0;
  bool checked_hold = false;
  while (steps++ < 200) {
    s = rt.step();
    if (s.ended) break;
    EXPECT_GT(s.task.firings, firings) << "step " << steps << ": held without a firing";
    EXPECT_EQ(s.task.last_fired.size(), s.task.firings - firings) << "step " << steps;
    firings = s.task.firings;
    ASSERT_EQ(s.robots.size(), 2u);
    if (!checked_hold && s.task.robots[0].activity == RobotActivity::kBusy) {
      // A robot is busy: held, the plant and the clock stay while wall time goes by (a deliberate wait: the hold
      // must outlast many control periods), and nothing is logged later than the held time. (A robot-control thread
      // may still log taking a command task control sent before the hold, stamped with the held time: seen under
      // ASan, where the hold can come before that thread has run.)
      checked_hold = true;
      const SimDuration plant_time = cell.plant->truth().time;
      const std::size_t lines = rt.log().lines().size();
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      const std::optional<StepState> again = rt.wait_held(std::chrono::milliseconds(0));
      ASSERT_TRUE(again.has_value());
      EXPECT_EQ(again->time, s.time);
      EXPECT_EQ(cell.plant->truth().time, plant_time);
      const std::vector<nlohmann::json> events = parse(rt.log());
      const double held_at = std::chrono::duration<double>(s.time).count();
      for (std::size_t i = lines; i < events.size(); ++i) {
        EXPECT_LE(events[i]["t"].get<double>(), held_at + 1e-9) << "logged while held: " << events[i].dump();
      }
    }
  }
  ASSERT_TRUE(s.ended);
  EXPECT_TRUE(checked_hold);
  ASSERT_TRUE(s.result.has_value());
  EXPECT_EQ(s.result->outcome, Outcome::kFinished) << s.result->reason;
  EXPECT_GT(steps, 10);
  EXPECT_EQ(starts(parse(rt.log())), starts(parse(reference.log())));
  EXPECT_TRUE(rt.step().ended);  // and stays ended
}

TEST(RuntimeHold, GoHoldAndGoAgainRunsToTheEnd) {
  ScriptedCell cell("exchange.task", {}, Mode::kRealtime);
  cell.config.realtime_speed = test_speed();
  Runtime rt(cell.config);
  rt.go();
  rt.hold();
  const std::optional<StepState> held = rt.wait_held(std::chrono::steady_clock::duration::max());
  ASSERT_TRUE(held.has_value());
  ASSERT_FALSE(held->ended);
  rt.hold();  // held already: nothing
  rt.go();
  std::optional<StepState> end = rt.wait_held(std::chrono::steady_clock::duration::max());
  ASSERT_TRUE(end.has_value());
  ASSERT_TRUE(end->ended);
  EXPECT_EQ(end->result->outcome, Outcome::kFinished) << end->result->reason;
  EXPECT_GE(end->time, held->time);
  rt.go();  // after the end: nothing
  EXPECT_TRUE(rt.wait_held(std::chrono::milliseconds(0))->ended);
}

TEST(RuntimeHold, ARunLetGoToATimeHoldsThere) {
  ScriptedCell cell("exchange.task", {}, Mode::kRealtime);
  cell.config.realtime_speed = test_speed();
  Runtime rt(cell.config);
  const SimDuration at = std::chrono::milliseconds(500);
  rt.go(HoldAt{false, at});
  const std::optional<StepState> s = rt.wait_held(std::chrono::steady_clock::duration::max());
  ASSERT_TRUE(s.has_value());
  ASSERT_FALSE(s->ended);
  EXPECT_GE(s->time, at);
  EXPECT_LT(s->time, at + cell.config.period);
  // Stopped while held: the stop ends it, as a cell stopped safely.
  rt.request_stop("stopped from the test");
  const std::optional<StepState> end = rt.wait_held(std::chrono::steady_clock::duration::max());
  ASSERT_TRUE(end.has_value() && end->ended);
  EXPECT_EQ(end->result->outcome, Outcome::kStopped);
  EXPECT_EQ(end->result->reason, "stopped from the test");
}

TEST(RuntimeHold, HoldingIsForRealtimeRunsOnly) {
  ScriptedCell cell;
  Runtime rt(cell.config);
  EXPECT_THROW(rt.go(), InternalError);
  EXPECT_THROW(rt.hold(), InternalError);
}

// ---- Bad input is refused before any thread starts ----

void expect_refused(ScriptedCell& cell, const std::string& where, const std::string& what) {
  try {
    Runtime rt(cell.config);
    ADD_FAILURE() << "accepted; expected: " << what;
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(where));
    EXPECT_THAT(e.what(), HasSubstr(what));
  }
  for (auto& [name, d] : cell.drivers) EXPECT_EQ(d->calls().connect, 0) << name;
}

TEST(RuntimeRun, ARobotBoundToNothingInTheCellIsRefused) {
  ScriptedCell cell;
  cell.config.binding.robots["r2"].name = "kuka";
  expect_refused(cell, "scenario.yaml:5:24", "program robot 'r2' is bound to 'kuka', which is not a robot of the cell");
}

TEST(RuntimeRun, AnUnboundRobotIsRefused) {
  ScriptedCell cell;
  cell.config.binding.robots.erase("r2");
  expect_refused(cell, "scenario.yaml:1:1", "program robot 'r2' is not bound to a robot of the cell");
}

TEST(RuntimeRun, TwoRobotsOnOneArmAreRefused) {
  ScriptedCell cell;
  cell.config.binding.robots["r2"].name = "puma";
  expect_refused(cell, "scenario.yaml:5:24", "both bound to cell robot 'puma'");
}

TEST(RuntimeRun, AMissingLocationOrWorkpieceIsRefused) {
  ScriptedCell cell;
  cell.config.binding.objects["B"].name = "output";  // a conveyor, not a location
  expect_refused(cell, "scenario.yaml:6:10", "program location 'B' is bound to 'output', which is not a location");
  ScriptedCell cell2;
  cell2.config.binding.objects["A"] = {"Z", {"scenario.yaml", 7, 3}};
  expect_refused(cell2, "scenario.yaml:7:3", "program workpiece 'A' is bound to 'Z'");
  ScriptedCell cell3;
  cell3.config.binding.objects["Q"] = {"A", {"scenario.yaml", 8, 3}};
  expect_refused(cell3, "scenario.yaml:8:3", "'Q' is not a workpiece or location of the program");
}

TEST(RuntimeRun, AProgramDeviceTheCellDoesNotHaveOrDoesNotWireIsRefusedBeforeAnythingMoves) {
  // A belt the cell does not have, at its declaration's scenario entry; then the cell's belt, on no I/O unit.
  ScriptedCell cell;
  cell.config.program = task::compile(task::parse_program(
      "robot r1 r2\nworkpiece A\nlocation B\nconveyor IN\nsequence r1\n  run IN\n  stop IN\nend\n", "belt.task"));
  expect_refused(cell, "", "program conveyor 'IN' is not a conveyor of the cell (cell conveyors: input, output)");
  cell.config.program = task::compile(task::parse_program(
      "robot r1 r2\nworkpiece A\nlocation B\nconveyor input\nsequence r1\n  run input\n  stop input\nend\n",
      "belt.task"));
  expect_refused(cell, "", "program device 'input' (cell device 'input') is on no I/O unit");
}

TEST(RuntimeRun, AMachineWithSomeOfItsAddressesIsRefusedNamingTheMissingOnes) {
  ScriptedCell cell;
  ASSERT_FALSE(cell.config.cell.machines.empty());
  models::MachineSpec& mill = cell.config.cell.machines[0];
  ASSERT_EQ(mill.name, "mill");
  mill.busy_io.address = -1;
  mill.done_io.address = -1;
  cell.config.program = task::compile(task::parse_program(
      "robot r1 r2\nworkpiece A\nlocation B\nmachine mill\nsequence r1\n  start mill\n  wait mill\nend\n",
      "mill.task"));
  expect_refused(cell, "cell.yaml", "the cell description's `io` of machine 'mill' lacks busy, done, and device "
                                    "control needs start, busy and done");
}

TEST(RuntimeRun, ARobotWithoutADriverIsRefused) {
  ScriptedCell cell;
  cell.config.drivers.erase("melfa");
  expect_refused(cell, "scenario.yaml:5:24", "cell robot 'melfa' (program robot 'r2') has no driver");
}

TEST(RuntimeRun, AHandOverInACellWithoutOneIsRefused) {
  ScriptedCell cell;
  cell.config.cell.handover.reset();
  expect_refused(cell, "exchange.task:9:3", "needs a hand-over");
}

TEST(RuntimeRun, ADriverThatCannotConnectIsRefusedBeforeTheThreadsStart) {
  ScriptedCell cell;
  cell.driver("melfa").refuse_connect("serial port /dev/ttyS9 does not exist");
  Runtime rt(cell.config);
  EXPECT_THROW(
      {
        try {
          rt.run();
        } catch (const InputError& e) {
          EXPECT_THAT(e.what(), HasSubstr("/dev/ttyS9"));
          throw;
        }
      },
      InputError);
  EXPECT_EQ(rt.log().size(), 0u);  // not even run_start: nothing ran
}

// ---- A robot whose robot control is elsewhere (an agent: docs/distributed.md) ----

// The other end of a remote robot's link, in this process: answers each command done, on a thread of its own, as an
// agent would from its process.
class AnsweringLink : public RemoteLink {
 public:
  AnsweringLink(MessageQueue<MotionCommand>& commands, MessageQueue<RobotStatus>& statuses)
      : commands_(commands), statuses_(statuses) {}
  ~AnsweringLink() override { stop(); }
  void start() override {
    ++starts;
    thread_ = std::thread([this] {
      while (!stopping_) {
        MotionCommand c;
        if (commands_.pop_for(c, std::chrono::milliseconds(5)) != QueueStatus::ok) continue;
        statuses_.push(RobotStatus{c.robot, c.index, CommandOutcome::kDone, "", false, c.sent});
      }
    });
  }
  void stop() override {
    stopping_ = true;
    if (thread_.joinable()) thread_.join();
  }
  int starts = 0;

 private:
  MessageQueue<MotionCommand>& commands_;
  MessageQueue<RobotStatus>& statuses_;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

TEST(RuntimeRemote, ARemoteRobotIsDrivenThroughItsLinkWithNoDriverOrRobotControlHere) {
  ScriptedCell cell("exchange.task", {}, Mode::kRealtime);
  cell.config.drivers.erase("melfa");
  cell.config.remote_robots = {"melfa"};
  AnsweringLink* link = nullptr;
  cell.config.attach_remote = [&](std::size_t index, const std::string& name, MessageQueue<MotionCommand>& commands,
                                  MessageQueue<RobotStatus>& statuses) {
    EXPECT_EQ(index, 1u);
    EXPECT_EQ(name, "melfa");
    auto made = std::make_unique<AnsweringLink>(commands, statuses);
    link = made.get();
    return made;
  };
  Runtime rt(cell.config);
  const RunResult r = rt.run();
  ASSERT_EQ(r.outcome, Outcome::kFinished) << r.reason << "\n" << rt.log().text();
  ASSERT_NE(link, nullptr);
  EXPECT_EQ(link->starts, 1);
  const auto events = parse(rt.log());
  const auto commanded = [&](const std::string& robot) {
    return std::count_if(events.begin(), events.end(), [&](const nlohmann::json& e) {
      return e["type"] == "command_start" && e["robot"] == robot;
    });
  };
  EXPECT_GT(commanded("r1"), 0);   // the PUMA's robot control is here
  EXPECT_EQ(commanded("r2"), 0);   // the MELFA's is the link's other end
  EXPECT_EQ(cell.driver("melfa").calls().connect, 0);
}

TEST(RuntimeRemote, ARemoteRobotWhoseLinkTakesNoTurnsInLockStepOrNotOfTheProgramIsRefused) {
  ScriptedCell cell;
  cell.config.remote_robots = {"melfa"};
  cell.config.attach_remote = [](std::size_t, const std::string&, MessageQueue<MotionCommand>& c,
                                 MessageQueue<RobotStatus>& s) -> std::unique_ptr<RemoteLink> {
    return std::make_unique<AnsweringLink>(c, s);
  };
  expect_refused(cell, "scenario.yaml:1:1", "robot 'melfa' is remote and its link carries no lock-step turns");
  ScriptedCell no_driver;
  no_driver.config.remote_robots = {"melfa"};
  no_driver.config.drivers.erase("melfa");
  no_driver.config.attach_remote = cell.config.attach_remote;
  expect_refused(no_driver, "scenario.yaml:1:1", "robot 'melfa' is remote in a lock-step run, which needs its driver");
  ScriptedCell realtime("exchange.task", {}, Mode::kRealtime);
  realtime.config.remote_robots = {"kuka"};
  realtime.config.attach_remote = cell.config.attach_remote;
  expect_refused(realtime, "scenario.yaml:1:1", "remote robot 'kuka' is not a robot of the program");
}

// A link that takes lock-step turns in this process, as an agent takes them in its own (distributed/turn_link.hpp):
// its own RobotControl, built at the first turn on the driver the runtime hands it, stepped once a turn with the
// commands task control queued; it shares the run's model and log.
class TurnTakingLink : public RemoteLink {
 public:
  TurnTakingLink(const RunConfig& config, std::size_t index, MessageQueue<MotionCommand>& commands,
                 MessageQueue<RobotStatus>& statuses)
      : config_(config), index_(index), commands_(commands), statuses_(statuses) {}
  void start() override {}
  void stop() override {}
  void share(SharedEnvironment& environment, EventLog& log) override {
    env_ = &environment;
    log_ = &log;
  }
  bool takes_turns() const override { return true; }
  void take_turn(SimDuration now, drivers::RobotDriver& driver) override {
    MotionCommand c;
    while (commands_.try_pop(c) == QueueStatus::ok) EXPECT_EQ(inbox_.try_push(std::move(c)), QueueStatus::ok);
    if (!control_) {
      const std::string& label = config_.program.robots[index_];
      const std::string& cell = config_.binding.robots.at(label).name;
      const models::RobotSpec& spec = *config_.cell.find_robot(cell);
      MotionOptions motion = config_.motion;
      motion.track_held_parts = config_.perception != Perception::kTruth;
      control_ = std::make_unique<RobotControl>(index_, label, cell, driver, models::robot_chain(spec),
                                                spec.grip_force, resolve_names(config_), *env_, inbox_, statuses_,
                                                *log_, motion, false, nullptr);
      control_->connect();
    }
    control_->step(now);
    ++turns;
  }
  int turns = 0;

 private:
  const RunConfig& config_;
  std::size_t index_;
  MessageQueue<MotionCommand>& commands_;
  MessageQueue<RobotStatus>& statuses_;
  MessageQueue<MotionCommand> inbox_{4};
  SharedEnvironment* env_ = nullptr;
  EventLog* log_ = nullptr;
  std::unique_ptr<RobotControl> control_;
};

TEST(RuntimeRemote, ARemoteRobotsTurnsTakenThroughItsLinkLogByteForByteWhatItsRobotControlHereLogs) {
  ScriptedCell here;
  Runtime local(here.config);
  ASSERT_EQ(local.run().outcome, Outcome::kFinished) << local.log().text();

  ScriptedCell cell;
  cell.config.remote_robots = {"puma", "melfa"};
  std::vector<TurnTakingLink*> links;
  const RunConfig config = cell.config;
  cell.config.attach_remote = [&](std::size_t index, const std::string&, MessageQueue<MotionCommand>& c,
                                  MessageQueue<RobotStatus>& s) -> std::unique_ptr<RemoteLink> {
    auto made = std::make_unique<TurnTakingLink>(config, index, c, s);
    links.push_back(made.get());
    return made;
  };
  for (LockstepThreads threads : {LockstepThreads::kShared, LockstepThreads::kOwn}) {
    SCOPED_TRACE(threads == LockstepThreads::kShared ? "shared" : "own threads");
    ScriptedCell remote;
    remote.config.remote_robots = cell.config.remote_robots;
    remote.config.attach_remote = cell.config.attach_remote;
    remote.config.lockstep_threads = threads;
    links.clear();
    Runtime rt(remote.config);
    ASSERT_EQ(rt.run().outcome, Outcome::kFinished) << rt.log().text();
    ASSERT_EQ(links.size(), 2u);
    EXPECT_GT(links[0]->turns, 100);
    EXPECT_EQ(links[0]->turns, links[1]->turns);  // every robot a turn every period
    EXPECT_EQ(rt.log().text(), local.log().text());
  }
}

}  // namespace
}  // namespace cellwright::runtime
