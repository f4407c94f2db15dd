// The run report and the Gantt chart, from a synthetic event log of the paper's exchange program.
#include "cellwright/cell/report.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/cell/gantt.hpp"

namespace cellwright::cell {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// Writes event lines in the runtime's format (runtime/event_log.hpp).
class LogWriter {
 public:
  void start() {
    add(0, "run_start",
        R"("program":"exchange.task","cell":"yasuda-cell","mode":"lockstep","period":0.0100,)"
        R"("robots":[{"robot":"r1","cell":"puma"},{"robot":"r2","cell":"melfa"}])");
  }
  void fire(double t, const std::string& robot, int k) {
    add(t, "fire",
        fmt::format(R"("transition":"{}.t{}","robot":"{}","primitive":{},"line":0,"task":"","motion":"")", robot, k,
                    robot, k));
  }
  void command(double t0, double t1, const std::string& robot, int k, const std::string& text,
               const std::string& task) {
    add(t0, "command_start",
        fmt::format(R"("robot":"{}","primitive":{},"command":"{}","task":"{}","motion":"",)"
                    R"("detail":"")",
                    robot, k, text, task));
    pending_.push_back(
        {t1, fmt::format(R"("robot":"{}","primitive":{},"command":"{}","ok":true,"reason":"")", robot, k, text)});
  }
  void collision(double t, const std::string& a, const std::string& b) {
    add(t, "collision", fmt::format(R"("a":"{}","b":"{}","depth":0.001000)", a, b));
  }
  // Any event: `rest` is its keys after "t" and "type", without braces.
  void event(double t, const std::string& type, const std::string& rest) { add(t, type, rest); }
  void end(double t, const std::string& outcome, const std::string& reason, int firings) {
    add(t, "run_end", fmt::format(R"("outcome":"{}","reason":"{}","firings":{})", outcome, reason, firings));
  }
  // The lines sorted by time (stable: equal times keep the order they were added in), as JSONL.
  std::string text() {
    flush(1e9);
    std::stable_sort(lines_.begin(), lines_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::string out;
    for (const auto& [t, l] : lines_) out += l + "\n";
    return out;
  }

 private:
  void add(double t, const std::string& type, const std::string& rest) {
    flush(t);
    lines_.push_back({t, fmt::format(R"({{"t":{:.4f},"type":"{}",{}}})", t, type, rest)});
  }
  void flush(double upto) {
    for (auto it = pending_.begin(); it != pending_.end();) {
      if (it->first <= upto) {
        lines_.push_back({it->first, fmt::format(R"({{"t":{:.4f},"type":"command_end",{}}})", it->first, it->second)});
        it = pending_.erase(it);
      } else {
        ++it;
      }
    }
  }
  std::vector<std::pair<double, std::string>> lines_;
  std::vector<std::pair<double, std::string>> pending_;
};

// The exchange program (scenes/exchange.task, listing in docs/task-language.md), with every move/open/close taking
// 1 s at the times below, so every figure of the report is known.
//   r1: 0 open 0-1, 1 move 1-2, 2 move 2-3, 3 close 3-4, 4 move 4-5 (Pick A: 0..5), 5 signal, 6 wait (5..5),
//       7 move handover 5-6, 8 signal ready, 9 wait gripped 6..9, 10 open A 9-10, 11 signal released, 12 signal,
//       13 wait step2 10..11, done at 11.
//   r2: 0 signal, 1 wait step1 0..5, 2 open 5-6, 3 move 6-7, 4 wait ready 7..7, 5 move 7-8, 6 close 8-9,
//       7 signal gripped, 8 wait released 9..10, 9 move 10-11, 10 signal, 11 wait (11..11), 12 move 11-12,
//       13 move 12-13, 14 open A 13-14 (blocked 14-14.5), 15 move 14.5-15.5, done at 15.5.
// With `journey`, also the robot control's sensor events: r1 waits for A from 1 to 1.6 before its move above(A)
// (waiting_for_part, part_ready), grips it at 4, lets it go to r2 at 10; r2 lets it go on the output at 14.
std::string exchange_log(bool finished = true, bool journey = false) {
  LogWriter w;
  w.start();
  auto sensor = [&](double t, const std::string& r, int k, const std::string& condition, const std::string& part) {
    if (journey) {
      w.event(t, "sensor",
              fmt::format(R"("robot":"{}","primitive":{},"condition":"{}","workpiece":"{}")", r, k, condition, part));
    }
  };
  auto step = [&](const std::string& r, int k, double t0, double t1, const std::string& text, const std::string& task) {
    w.fire(t0, r, k);
    w.command(t0, t1, r, k, text, task);
  };
  step("r1", 0, 0, 1, "open", "Pick A");
  step("r1", 1, 1, 2, "move above(A)", "Pick A");
  sensor(1, "r1", 1, "waiting_for_part", "A");
  sensor(1.6, "r1", 1, "part_ready", "A");
  step("r1", 2, 2, 3, "move at(A)", "Pick A");
  step("r1", 3, 3, 4, "close A", "Pick A");
  sensor(4, "r1", 3, "gripped", "A");
  step("r1", 4, 4, 5, "move above(A)", "Pick A");
  w.fire(5, "r1", 5);
  w.fire(5, "r1", 6);
  step("r1", 7, 5, 6, "move handover(r2)", "Put r2");
  w.fire(6, "r1", 8);
  w.fire(6, "r1", 9);
  step("r1", 10, 9, 10, "open A", "Put r2");
  sensor(10, "r1", 10, "released", "A");
  w.fire(10, "r1", 11);
  w.fire(10, "r1", 12);
  w.fire(10, "r1", 13);
  w.fire(11, "r1", 14);

  w.fire(0, "r2", 0);
  w.fire(0, "r2", 1);
  step("r2", 2, 5, 6, "open", "Get r1");
  step("r2", 3, 6, 7, "move hand_approach(r1)", "Get r1");
  w.fire(7, "r2", 4);
  step("r2", 5, 7, 8, "move hand_grasp(r1)", "Get r1");
  step("r2", 6, 8, 9, "close A", "Get r1");
  w.fire(9, "r2", 7);
  w.fire(9, "r2", 8);
  step("r2", 9, 10, 11, "move hand_approach(r1)", "Get r1");
  w.fire(11, "r2", 10);
  w.fire(11, "r2", 11);
  step("r2", 12, 11, 12, "move above(B)", "Place B");
  step("r2", 13, 12, 13, "move at(B)", "Place B");
  step("r2", 14, 13, 14, "open A", "Place B");
  sensor(14, "r2", 14, "released", "A");
  w.collision(12.5, "melfa/link4", "conveyor/output");
  if (!finished) {
    w.end(14.2, "timeout", "sim time limit of 14.2 s reached", 30);
    return w.text();
  }
  step("r2", 15, 14.5, 15.5, "move above(B)", "Place B");
  w.fire(15.5, "r2", 16);
  w.end(16.5, "finished", "", 32);
  return w.text();
}

Scenario exchange_scenario() {
  return load_scenario(kScenes + "/exchange.yaml");
}

// A final pose for A resting on the output conveyor's belt, `along` metres downstream of the drop point.
FinalPose on_output(const Scenario& s, double along) {
  const models::ConveyorSpec& c = *s.cell.find_conveyor("output");
  const models::WorkpieceSpec& a = *s.cell.find_workpiece("A");
  FinalPose f;
  f.name = "A";
  f.pose.translation() = c.belt_point(c.enter + along) + Eigen::Vector3d(0, 0, a.size.z() / 2);
  return f;
}

TEST(Timeline, BarsFollowTheFiringsAndCommands) {
  const Scenario s = exchange_scenario();
  const Timeline tl = build_timeline(runtime::decode_log(exchange_log(), "e"), s.program);
  EXPECT_DOUBLE_EQ(tl.end, 16.5);
  ASSERT_EQ(tl.robots.size(), 2u);
  const RobotTimeline& r1 = tl.robots[0];
  EXPECT_EQ(r1.robot, "r1");
  EXPECT_EQ(r1.cell, "puma");
  EXPECT_EQ(r1.commands, 7u);
  // 7 one-second commands; waiting for "gripped" 6..9 and for the step barrier 10..11.
  EXPECT_DOUBLE_EQ(r1.busy, 7.0);
  EXPECT_DOUBLE_EQ(r1.waiting, 4.0);
  EXPECT_DOUBLE_EQ(r1.blocked, 0.0);
  EXPECT_DOUBLE_EQ(r1.idle, 16.5 - 11.0);
  const RobotTimeline& r2 = tl.robots[1];
  EXPECT_EQ(r2.commands, 9u);
  EXPECT_DOUBLE_EQ(r2.busy, 9.0);
  EXPECT_DOUBLE_EQ(r2.waiting, 5.0 + 1.0);  // step 1 barrier 0..5, "released" 9..10
  EXPECT_DOUBLE_EQ(r2.blocked, 0.5);        // open A ended at 14, the depart started at 14.5
  EXPECT_DOUBLE_EQ(r2.idle, 1.0);           // done at 15.5, run ended at 16.5
  // The bars of r1 in order, with their kinds.
  std::vector<std::string> kinds;
  for (const Bar& b : r1.bars) kinds.push_back(fmt::format("{} {}-{}", to_string(b.activity), b.start, b.end));
  EXPECT_THAT(kinds, ElementsAre("grip 0-1", "move 1-2", "move 2-3", "grip 3-4", "move 4-5", "move 5-6", "wait 6-9",
                                 "grip 9-10", "wait 10-11"));
  for (const RobotTimeline& rt : tl.robots) {
    for (std::size_t i = 1; i < rt.bars.size(); ++i) EXPECT_LE(rt.bars[i - 1].end, rt.bars[i].start);
  }
}

// A move that waited for its part is waiting (part_wait) up to part_ready and a move after it; the journey's marks
// come from the sensor events of the Pick, the Put and the Place.
TEST(Timeline, AWaitForThePartIsWaitingNotAMoveAndTheJourneyIsMarked) {
  const Scenario s = exchange_scenario();
  const Timeline tl = build_timeline(runtime::decode_log(exchange_log(true, true), "e"), s.program);
  const RobotTimeline& r1 = tl.robots[0];
  std::vector<std::string> kinds;
  for (const Bar& b : r1.bars) kinds.push_back(fmt::format("{} {}-{}", to_string(b.activity), b.start, b.end));
  EXPECT_THAT(kinds, ElementsAre("grip 0-1", "part_wait 1-1.6", "move 1.6-2", "move 2-3", "grip 3-4", "move 4-5",
                                 "move 5-6", "wait 6-9", "grip 9-10", "wait 10-11"));
  EXPECT_DOUBLE_EQ(r1.busy, 6.4);
  EXPECT_DOUBLE_EQ(r1.waiting, 4.6);
  EXPECT_DOUBLE_EQ(r1.waiting_for_part, 0.6);
  EXPECT_DOUBLE_EQ(r1.idle, 16.5 - 11.0);
  std::vector<std::string> marks;
  for (const RobotTimeline& rt : tl.robots) {
    for (const JourneyMark& m : rt.marks) marks.push_back(fmt::format("{} {} {} {}", rt.robot, m.t, to_string(m.step), m.workpiece));
  }
  EXPECT_THAT(marks, ElementsAre("r1 4 picked A", "r1 10 handed over A", "r2 14 placed A"));
  // Without part_ready (the command ended before its part came), the whole command is the wait.
  std::string log = exchange_log(true, true);
  log.erase(log.find(R"({"t":1.6000,"type":"sensor")"), log.find('\n', log.find(R"({"t":1.6000,"type":"sensor")")) -
                                                                log.find(R"({"t":1.6000,"type":"sensor")") + 1);
  const Timeline no_ready = build_timeline(runtime::decode_log(log, "e"), s.program);
  EXPECT_EQ(fmt::format("{} {}-{}", to_string(no_ready.robots[0].bars[1].activity), no_ready.robots[0].bars[1].start,
                        no_ready.robots[0].bars[1].end),
            "part_wait 1-2");
  EXPECT_EQ(to_string(no_ready.robots[0].bars[2].activity), std::string("move"));
  EXPECT_DOUBLE_EQ(no_ready.robots[0].bars[2].start, 2.0);
}

TEST(Timeline, EventsOfAnotherProgramAreRefused) {
  const Scenario s = exchange_scenario();
  std::string log = exchange_log();
  log +=
      R"({"t":17.0000,"type":"command_start","robot":"r2","primitive":40,"command":"open","task":"","motion":"","detail":""})"
      "\n";
  try {
    build_timeline(runtime::decode_log(log, "e.jsonl"), s.program, "e.jsonl");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("primitive 40"));
    EXPECT_GT(e.where().line, 1);
  }
  EXPECT_THROW(build_timeline(runtime::decode_log("{\"t\":0,\"type\":\"fire\"}\n", "e"), s.program), InputError);
}

TEST(Report, FinishedRunWithThePartOnTheOutputBeltIsOk) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(exchange_log(), "e"), {on_output(s, 0.1)}, 14.25);
  EXPECT_TRUE(r.ok()) << (r.failures.empty() ? "" : r.failures.front());
  EXPECT_EQ(r.outcome, "finished");
  EXPECT_EQ(r.firings, 32u);
  ASSERT_TRUE(r.finished_at);
  EXPECT_DOUBLE_EQ(*r.finished_at, 15.5);  // the last firing
  EXPECT_DOUBLE_EQ(*r.estimated_cycle_time, 14.25);
  const WorkpieceReport& a = r.workpieces[0];
  EXPECT_EQ(a.name, "A");
  EXPECT_EQ(a.label, "A");
  EXPECT_EQ(a.final_location, "output");
  EXPECT_EQ(a.expected, "output");
  EXPECT_EQ(a.ok, true);
  // Picked from t = 0 (the Pick's first command), placed when the Place's depart ended at 15.5.
  ASSERT_TRUE(a.pick_start && a.place_end && a.cycle_time);
  EXPECT_DOUBLE_EQ(*a.pick_start, 0.0);
  EXPECT_DOUBLE_EQ(*a.place_end, 15.5);
  EXPECT_DOUBLE_EQ(*a.cycle_time, 15.5);
  EXPECT_EQ(r.parts_completed, 1u);
  ASSERT_TRUE(r.throughput);
  EXPECT_DOUBLE_EQ(*r.throughput, 60.0 / 15.5);
  // The other workpieces are reported without an expectation.
  EXPECT_FALSE(r.workpieces[1].ok);
  ASSERT_EQ(r.collisions.size(), 1u);
  EXPECT_EQ(r.collisions[0].a, "melfa/link4");

  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["result"], "ok");
  EXPECT_EQ(j["cycle_time"]["measured"], 15.5);
  EXPECT_EQ(j["cycle_time"]["estimated"], 14.25);
  EXPECT_EQ(j["workpieces"][0]["final_location"], "output");
  EXPECT_EQ(j["robots"][1]["blocked"], 0.5);
  EXPECT_EQ(j["collisions"][0]["b"], "conveyor/output");
  EXPECT_THAT(format_summary(r), HasSubstr("estimated cycle time 14.25 s, measured 15.50 s"));
  // A time not known is "n/a", with no unit after it (a real run has no estimate; a stalled one never finished).
  Report unknown = r;
  unknown.estimated_cycle_time.reset();
  unknown.finished_at.reset();
  EXPECT_THAT(format_summary(unknown), HasSubstr("estimated cycle time n/a, measured n/a\n"));
}

TEST(Report, PartAtTheDropPointIsAtBothTheLocationAndTheBelt) {
  const Scenario s = exchange_scenario();
  const FinalPose f = on_output(s, 0.0);
  EXPECT_THAT(places_of(s.cell, *s.cell.find_workpiece("A"), f, 0.03), ElementsAre("output_drop", "output"));
}

TEST(Report, WrongPlaceFailsNamingWhereThePartIs) {
  const Scenario s = exchange_scenario();
  FinalPose f;
  f.name = "A";
  const models::LocationSpec& fixture = *s.cell.find_location("machine_fixture");
  f.pose.translation() = fixture.pose.xyz + Eigen::Vector3d(0, 0, 0.03);
  const Report r = make_report(s, runtime::decode_log(exchange_log(), "e"), {f}, std::nullopt);
  EXPECT_FALSE(r.ok());
  ASSERT_EQ(r.failures.size(), 1u);
  EXPECT_THAT(r.failures[0], HasSubstr("workpiece A must end at output"));
  EXPECT_THAT(r.failures[0], HasSubstr("at machine_fixture, mill"));
  EXPECT_EQ(to_json(s, r)["result"], "failed");
  EXPECT_TRUE(to_json(s, r)["cycle_time"]["estimated"].is_null());
}

TEST(Report, PartLyingOnItsSideIsNowhere) {
  const Scenario s = exchange_scenario();
  FinalPose f = on_output(s, 0.1);
  f.pose.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_TRUE(places_of(s.cell, *s.cell.find_workpiece("A"), f, 0.01).empty());
}

TEST(Report, UnfinishedRunFailsEvenWithThePartInPlace) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(exchange_log(false), "e"), {on_output(s, 0.0)}, 14.0);
  EXPECT_FALSE(r.ok());
  EXPECT_THAT(r.failures[0], HasSubstr("did not finish: timeout: sim time limit"));
  EXPECT_FALSE(r.finished_at);
  EXPECT_FALSE(r.workpieces[0].cycle_time);  // its Place never ended
  EXPECT_EQ(r.parts_completed, 0u);
  EXPECT_FALSE(r.throughput);
}

TEST(Report, LogWithoutRunEndIsUnfinished) {
  const Scenario s = exchange_scenario();
  std::string log = exchange_log();
  log = log.substr(0, log.rfind("{\"t\":16.5000"));
  const Report r = make_report(s, runtime::decode_log(log, "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_EQ(r.outcome, "unfinished");
  EXPECT_FALSE(r.ok());
}

// --- The account and the faults (docs/faults.md section 5) -------------------------------------------------------

// The exchange log up to A's drop at t = 5.5 s (r1 carrying it to the hand-over), then the controller's detection,
// diagnosis, and either a pick_again that recovers (ok) or a set_aside that declares A lost; the run ends as `outcome`.
std::string drop_log(const std::string& how, const std::string& outcome = "finished") {
  LogWriter w;
  w.start();
  w.fire(0, "r1", 0);
  w.command(0, 1, "r1", 0, "open", "Pick A");
  w.event(5.5, "fault_injected", R"("kind":"drop","robot":"puma","workpiece":"","detail":"carry 1 after 0.5 s")");
  if (how != "none") {
    w.event(5.53, "fault_detected",
            R"("robot":"r1","primitive":7,"symptom":"grip_lost","detail":"A left the fingers")");
  }
  if (how == "recover") {
    w.event(5.53, "diagnosis",
            R"("robot":"r1","symptom":"grip_lost","cause":"dropped","action":"pick_again","path":"part_seen=yes")");
    w.event(8.25, "recovery_end",
            R"("robot":"r1","cause":"dropped","action":"pick_again","ok":true,"detail":"","duration":2.7200)");
  } else if (how == "lose") {
    w.event(5.53, "diagnosis",
            R"("robot":"r1","symptom":"grip_lost","cause":"dropped_out_of_reach","action":"set_aside","path":"")");
    w.event(5.6, "workpiece_lost", R"("workpiece":"A","reason":"dropped out of reach","x":0.5,"y":-0.25,"z":0.03)");
    w.event(5.6, "recovery_end",
            R"("robot":"r1","cause":"dropped_out_of_reach","action":"set_aside","ok":true,"detail":"",)"
            R"("duration":0.0700)");
  } else if (how == "stop") {
    w.event(5.53, "diagnosis",
            R"("robot":"r1","symptom":"grip_lost","cause":"unknown","action":"stop_cell","path":"")");
    w.event(5.54, "cell_stopped", R"("reason":"grip_lost on r1: nothing else applied")");
    w.event(5.54, "recovery_end",
            R"("robot":"r1","cause":"unknown","action":"stop_cell","ok":true,"detail":"","duration":0.0100)");
  }
  w.end(outcome == "stopped" ? 5.6 : 20, outcome, outcome == "stopped" ? "grip_lost on r1" : "", 12);
  return w.text();
}

FinalPose on_floor(const std::string& name) {
  FinalPose f;
  f.name = name;
  f.pose.translation() = Eigen::Vector3d(0.5, -0.25, 0.03);
  return f;
}

const WorkpieceReport& part(const Report& r, const std::string& name) {
  for (const WorkpieceReport& w : r.workpieces) {
    if (w.name == name) return w;
  }
  throw std::runtime_error("no workpiece " + name);
}

TEST(ReportAccount, EachStatusFromTheFinalPosesAndTheEvents) {
  Scenario s = exchange_scenario();
  // A in place; B held by the MELFA; C never fed (a fed part that did not arrive); D where it started (no
  // expectation: elsewhere, where it is).
  s.feed = Feed{"input", {"C"}, 0, 0, 1, {}};
  FinalPose b;
  b.name = "B";
  b.held_by = "melfa";
  b.pose.translation() = Eigen::Vector3d(0.3, 0.2, 0.5);
  FinalPose c;
  c.name = "C";
  c.present = false;
  FinalPose d;
  d.name = "D";
  const models::LocationSpec& fixture = *s.cell.find_location("machine_fixture");
  d.pose.translation() = fixture.pose.xyz + Eigen::Vector3d(0, 0, s.cell.find_workpiece("D")->size.z() / 2);
  const Report r = make_report(s, runtime::decode_log(exchange_log(), "e"), {on_output(s, 0.1), b, c, d}, 14.0);
  EXPECT_TRUE(r.ok()) << (r.failures.empty() ? "" : r.failures.front());
  EXPECT_EQ(part(r, "A").status, PartStatus::kInPlace);
  EXPECT_EQ(part(r, "A").where, "output");
  EXPECT_EQ(part(r, "B").status, PartStatus::kHeld);
  EXPECT_EQ(part(r, "B").where, "melfa");
  EXPECT_EQ(part(r, "C").status, PartStatus::kNotArrived);
  EXPECT_EQ(part(r, "C").where, "not in the cell");
  EXPECT_EQ(part(r, "D").status, PartStatus::kElsewhere);
  EXPECT_EQ(part(r, "D").where, "machine_fixture");
  EXPECT_EQ(r.unaccounted(), 0u);
  EXPECT_EQ(std::string(to_string(PartStatus::kScrapped)), "scrapped");

  const nlohmann::json j = to_json(s, r);
  ASSERT_EQ(j["account"].size(), 4u);
  EXPECT_EQ(j["account"][0]["status"], "in_place");
  EXPECT_EQ(j["account"][1]["status"], "held");
  EXPECT_EQ(j["account"][2]["status"], "not_arrived");
  EXPECT_EQ(j["account"][3]["status"], "elsewhere");
  EXPECT_TRUE(j["account"][0]["lost"].is_null());
  EXPECT_EQ(j["unaccounted"], 0);
  EXPECT_EQ(j["faults"].size(), 0u);
  EXPECT_EQ(j["false_alarms"], 0);
  // The summary lists the parts not in place, but not an unexpected part resting where it started.
  const std::string text = format_summary(r);
  EXPECT_THAT(text, HasSubstr("part B: held (melfa)"));
  EXPECT_THAT(text, HasSubstr("part C: not_arrived"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("part D")));
}

TEST(ReportAccount, PartNotWhereItShouldBeAndNotDeclaredLostIsUnaccounted) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(drop_log("none"), "e"), {on_floor("A")}, std::nullopt);
  EXPECT_FALSE(r.ok());
  const WorkpieceReport& a = part(r, "A");
  EXPECT_EQ(a.status, PartStatus::kElsewhere);
  EXPECT_EQ(a.where, "floor");
  EXPECT_TRUE(a.unaccounted);
  EXPECT_EQ(r.unaccounted(), 1u);
  EXPECT_EQ(to_json(s, r)["unaccounted"], 1);
  EXPECT_EQ(to_json(s, r)["account"][0]["unaccounted"], true);
  EXPECT_THAT(format_summary(r), HasSubstr("part A: elsewhere (floor): UNACCOUNTED"));
  // The fault was injected and never detected.
  ASSERT_EQ(r.faults.size(), 1u);
  EXPECT_FALSE(r.faults[0].detected);
  EXPECT_FALSE(r.faults[0].recovered);
  EXPECT_THAT(format_summary(r), HasSubstr("drop at t = 5.50 s on puma: not detected"));
}

TEST(ReportAccount, PartDeclaredLostIsAFailureButAccountedFor) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(drop_log("lose"), "e"), {on_floor("A")}, std::nullopt);
  const WorkpieceReport& a = part(r, "A");
  EXPECT_EQ(a.status, PartStatus::kLost);
  ASSERT_TRUE(a.lost);
  EXPECT_DOUBLE_EQ(a.lost->t, 5.6);
  EXPECT_EQ(a.lost->reason, "dropped out of reach");
  ASSERT_TRUE(a.lost->last_seen);
  EXPECT_DOUBLE_EQ(a.lost->last_seen->y(), -0.25);
  EXPECT_FALSE(a.unaccounted);
  EXPECT_FALSE(r.ok());
  ASSERT_EQ(r.failures.size(), 1u);  // one line for A, not one for the expectation and one for the loss
  EXPECT_THAT(r.failures[0], HasSubstr("workpiece A (expected at output) was declared lost at t = 5.60 s"));
  EXPECT_THAT(r.failures[0], HasSubstr("last seen at (0.500, -0.250, 0.030)"));
  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["account"][0]["status"], "lost");
  EXPECT_EQ(j["account"][0]["lost"]["reason"], "dropped out of reach");
  EXPECT_EQ(j["account"][0]["lost"]["last_seen"][1], -0.25);
  // The fault: detected, diagnosed, and its recovery (set_aside) ended well.
  ASSERT_EQ(r.faults.size(), 1u);
  EXPECT_TRUE(r.faults[0].detected);
  EXPECT_EQ(r.faults[0].action, "set_aside");
  EXPECT_TRUE(r.faults[0].recovered);
}

TEST(ReportAccount, PartExpectedLostAndLostIsOk) {
  Scenario s = exchange_scenario();
  s.expect[0].place = std::string(kLostPlace);
  const Report lost = make_report(s, runtime::decode_log(drop_log("lose"), "e"), {on_floor("A")}, std::nullopt);
  EXPECT_TRUE(lost.ok()) << (lost.failures.empty() ? "" : lost.failures.front());
  EXPECT_EQ(part(lost, "A").status, PartStatus::kLost);
  EXPECT_EQ(part(lost, "A").ok, true);
  EXPECT_FALSE(part(lost, "A").unaccounted);
  // Expected lost but delivered: the expectation fails, and the part is not unaccounted (the scenario expected it
  // gone, and it is in sight).
  const Report delivered = make_report(s, runtime::decode_log(exchange_log(), "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_FALSE(delivered.ok());
  EXPECT_THAT(delivered.failures[0], HasSubstr("workpiece A is expected to be lost"));
  EXPECT_THAT(delivered.failures[0], HasSubstr("at output"));
  EXPECT_FALSE(part(delivered, "A").unaccounted);
}

TEST(ReportAccount, LostPartThatNeverArrivedIsNotArrivedAndAccounted) {
  Scenario s = exchange_scenario();
  s.feed = Feed{"input", {"A"}, 0, 0, 1, {}};
  LogWriter w;
  w.start();
  w.event(0, "fault_injected", R"("kind":"missing","robot":"","workpiece":"A","detail":"")");
  w.event(30, "fault_detected", R"("robot":"r1","primitive":1,"symptom":"part_not_arrived","detail":"")");
  w.event(30, "diagnosis", R"("robot":"r1","symptom":"part_not_arrived","cause":"missing","action":"set_aside","path":"")");
  w.event(30, "workpiece_lost", R"("workpiece":"A","reason":"never arrived","x":null,"y":null,"z":null)");
  w.event(30, "recovery_end", R"("robot":"r1","cause":"missing","action":"set_aside","ok":true,"detail":"","duration":0.0)");
  w.end(31, "finished", "", 20);
  FinalPose a;
  a.name = "A";
  a.present = false;
  const Report r = make_report(s, runtime::decode_log(w.text(), "e"), {a}, std::nullopt);
  const WorkpieceReport& pa = part(r, "A");
  EXPECT_EQ(pa.status, PartStatus::kNotArrived);
  ASSERT_TRUE(pa.lost);
  EXPECT_FALSE(pa.lost->last_seen);
  EXPECT_FALSE(pa.unaccounted);
  EXPECT_FALSE(r.ok());  // lost all the same: the scenario expected it on the output
  EXPECT_THAT(r.failures[0], HasSubstr("last seen nowhere"));
  EXPECT_TRUE(to_json(s, r)["account"][0]["lost"]["last_seen"].is_null());
  ASSERT_EQ(r.faults.size(), 1u);
  EXPECT_EQ(r.faults[0].workpiece, "A");
  EXPECT_EQ(r.faults[0].symptom, "part_not_arrived");  // a fault of no robot matches any robot's detection
  EXPECT_DOUBLE_EQ(*r.faults[0].recovery_time, 30.0);
}

TEST(ReportFaults, InjectionMatchedToDetectionDiagnosisAndRecovery) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(drop_log("recover"), "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_TRUE(r.ok()) << (r.failures.empty() ? "" : r.failures.front());
  ASSERT_EQ(r.faults.size(), 1u);
  const FaultReport& f = r.faults[0];
  EXPECT_EQ(f.kind, "drop");
  EXPECT_DOUBLE_EQ(f.t, 5.5);
  EXPECT_EQ(f.robot, "puma");
  EXPECT_TRUE(f.detected);
  EXPECT_DOUBLE_EQ(*f.detected_at, 5.53);
  EXPECT_EQ(f.detected_by, "r1");
  EXPECT_EQ(f.symptom, "grip_lost");
  EXPECT_EQ(f.cause, "dropped");
  EXPECT_EQ(f.action, "pick_again");
  EXPECT_TRUE(f.recovered);
  EXPECT_NEAR(*f.recovery_time, 2.75, 1e-9);
  EXPECT_FALSE(f.stopped_safely);
  EXPECT_TRUE(r.false_alarms.empty());
  const nlohmann::json j = to_json(s, r);
  ASSERT_EQ(j["faults"].size(), 1u);
  EXPECT_EQ(j["faults"][0]["kind"], "drop");
  EXPECT_EQ(j["faults"][0]["detected"], true);
  EXPECT_EQ(j["faults"][0]["detected_at"], 5.53);
  EXPECT_EQ(j["faults"][0]["symptom"], "grip_lost");
  EXPECT_EQ(j["faults"][0]["recovery_time"], 2.75);
  EXPECT_EQ(j["faults"][0]["stopped_safely"], false);
  EXPECT_THAT(format_summary(r),
              HasSubstr("drop at t = 5.50 s on puma: detected at t = 5.53 s (grip_lost by r1), cause dropped, "
                        "action pick_again, recovered in 2.75 s"));
}

TEST(ReportFaults, StoppedRunIsAKnownOutcomeAndTheFaultWasStoppedSafely) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, runtime::decode_log(drop_log("stop", "stopped"), "e"), {on_floor("A")}, std::nullopt);
  EXPECT_EQ(r.outcome, "stopped");
  EXPECT_FALSE(r.ok());
  EXPECT_THAT(r.failures[0], HasSubstr("the cell was stopped: grip_lost on r1"));
  ASSERT_TRUE(r.stopped_at);
  EXPECT_DOUBLE_EQ(*r.stopped_at, 5.54);
  ASSERT_EQ(r.faults.size(), 1u);
  EXPECT_TRUE(r.faults[0].detected);
  EXPECT_EQ(r.faults[0].action, "stop_cell");
  EXPECT_TRUE(r.faults[0].stopped_safely);
  EXPECT_FALSE(r.faults[0].recovered);  // the cell was stopped before the recovery's end
  // On the floor, never declared lost: in a cell stopped safely it is accounted where it was found.
  EXPECT_FALSE(part(r, "A").unaccounted);
  EXPECT_EQ(part(r, "A").status, PartStatus::kElsewhere);
  EXPECT_EQ(to_json(s, r)["stopped_at"], 5.54);
  EXPECT_THAT(format_summary(r), HasSubstr("cell stopped safely"));
}

TEST(ReportFaults, DetectionsBeforeAnyInjectionAreUnexplainedFaults) {
  const Scenario s = exchange_scenario();
  LogWriter w;
  w.start();
  w.event(1.0, "fault_detected", R"("robot":"r2","primitive":3,"symptom":"driver_timeout","detail":"no answer")");
  w.event(2.0, "fault_injected", R"("kind":"timeout","robot":"melfa","workpiece":"","detail":"move 2")");
  // A detection on the other robot does not match the MELFA's fault; the next one of r2 does.
  w.event(2.5, "fault_detected", R"("robot":"r1","primitive":3,"symptom":"wait_timeout","detail":"")");
  w.event(3.0, "fault_detected", R"("robot":"r2","primitive":4,"symptom":"driver_timeout","detail":"")");
  w.event(3.0, "diagnosis", R"("robot":"r1","symptom":"wait_timeout","cause":"x","action":"resignal","path":"")");
  w.event(3.0, "diagnosis", R"("robot":"r2","symptom":"driver_timeout","cause":"no_answer","action":"reset_rehome","path":"")");
  w.event(4.0, "recovery_end", R"("robot":"r2","cause":"no_answer","action":"reset_rehome","ok":false,"detail":"x","duration":1.0)");
  // A second injection of the same kind, never detected (the earlier detections are taken).
  w.event(5.0, "fault_injected", R"("kind":"timeout","robot":"melfa","workpiece":"","detail":"grip 1")");
  w.end(10, "failed", "r2: driver_timeout", 10);
  const Report r = make_report(s, runtime::decode_log(w.text(), "e"), {on_output(s, 0.1)}, std::nullopt);
  // A driver's timeout is real whatever the twin shows: not a false alarm.
  EXPECT_TRUE(r.false_alarms.empty());
  ASSERT_EQ(r.unexplained.size(), 1u);
  EXPECT_DOUBLE_EQ(r.unexplained[0].t, 1.0);
  EXPECT_EQ(r.unexplained[0].robot, "r2");
  EXPECT_EQ(r.unexplained[0].primitive, 3);
  EXPECT_EQ(r.unexplained[0].symptom, "driver_timeout");
  ASSERT_EQ(r.faults.size(), 2u);
  EXPECT_TRUE(r.faults[0].detected);
  EXPECT_DOUBLE_EQ(*r.faults[0].detected_at, 3.0);
  EXPECT_EQ(r.faults[0].cause, "no_answer");
  EXPECT_FALSE(r.faults[0].recovered);  // its recovery failed
  EXPECT_FALSE(r.faults[0].recovery_time);
  EXPECT_FALSE(r.faults[1].detected);
  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["false_alarms"], 0);
  EXPECT_EQ(j["unexplained_faults"][0]["symptom"], "driver_timeout");
  EXPECT_THAT(format_summary(r), HasSubstr("unexplained fault at t = 1.00 s: driver_timeout by r2 (no answer)"));
}

// A driver's fault is logged by the simulation thread a round after robot control saw the command fail.
TEST(ReportFaults, ADetectionOfTheSameRobotARoundBeforeItsDriverFaultIsItsDetection) {
  const Scenario s = exchange_scenario();
  LogWriter w;
  w.start();  // period 0.01 s
  w.event(3.0, "fault_detected", R"("robot":"r2","primitive":3,"symptom":"driver_fault","detail":"")");  // too early
  w.event(22.05, "fault_detected", R"("robot":"r1","primitive":7,"symptom":"link_lost","detail":"")");
  w.event(22.05, "diagnosis", R"("robot":"r1","symptom":"link_lost","cause":"link_dropped","action":"reset_rehome","path":"")");
  w.event(22.06, "fault_injected", R"("kind":"link_lost","robot":"puma","workpiece":"","detail":"command 2190")");
  w.event(24.0, "recovery_end", R"("robot":"r1","cause":"link_dropped","action":"reset_rehome","ok":true,"detail":"","duration":1.95)");
  // Another robot's detection just before an injection is not taken.
  w.event(30.0, "fault_detected", R"("robot":"r1","primitive":9,"symptom":"wait_timeout","detail":"")");
  w.event(30.01, "fault_injected", R"("kind":"timeout","robot":"melfa","workpiece":"","detail":"")");
  w.end(40, "finished", "", 32);
  const Report r = make_report(s, runtime::decode_log(w.text(), "e"), {on_output(s, 0.1)}, std::nullopt);
  ASSERT_EQ(r.faults.size(), 2u);
  EXPECT_TRUE(r.faults[0].detected);
  EXPECT_DOUBLE_EQ(*r.faults[0].detected_at, 22.05);
  EXPECT_EQ(r.faults[0].cause, "link_dropped");
  EXPECT_TRUE(r.faults[0].recovered);
  EXPECT_NEAR(*r.faults[0].recovery_time, 24.0 - 22.06, 1e-9);
  EXPECT_FALSE(r.faults[1].detected);
  // The detection at 3 s came before every injection and nothing took it (unexplained); the one at 30 s is not
  // counted (a fault had been injected before it).
  EXPECT_TRUE(r.false_alarms.empty());
  ASSERT_EQ(r.unexplained.size(), 1u);
  EXPECT_DOUBLE_EQ(r.unexplained[0].t, 3.0);
}

// --- Where parts are, what completed, what went wrong unexplained (issue 24) -----------------------------------------

// The controller declared A lost, but physically the PUMA still holds it (it was never released): the account says
// where it is, "held", and keeps the declaration beside it; likewise a part declared lost that is in fact where it is
// expected is in place.
TEST(ReportAccount, APartDeclaredLostIsAccountedWhereItPhysicallyIs) {
  const Scenario s = exchange_scenario();
  FinalPose held = on_floor("A");
  held.held_by = "puma";
  held.pose.translation() = Eigen::Vector3d(0.4, -0.3, 0.4);
  const Report r = make_report(s, runtime::decode_log(drop_log("lose"), "e"), {held}, std::nullopt);
  const WorkpieceReport& a = part(r, "A");
  EXPECT_EQ(a.status, PartStatus::kHeld);
  EXPECT_EQ(a.where, "puma");
  ASSERT_TRUE(a.lost);  // the declaration stays visible
  EXPECT_EQ(a.lost->reason, "dropped out of reach");
  EXPECT_FALSE(r.ok());
  EXPECT_THAT(r.failures[0], HasSubstr("was declared lost at t = 5.60 s"));
  EXPECT_THAT(r.failures[0], HasSubstr("but it is held by puma"));
  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["account"][0]["status"], "held");
  EXPECT_EQ(j["account"][0]["where"], "puma");
  EXPECT_EQ(j["account"][0]["lost"]["reason"], "dropped out of reach");
  EXPECT_THAT(format_summary(r), HasSubstr("part A: held (puma); declared lost at t = 5.60 s (dropped out of reach)"));

  const Report placed = make_report(s, runtime::decode_log(drop_log("lose"), "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_EQ(part(placed, "A").status, PartStatus::kInPlace);
  EXPECT_EQ(part(placed, "A").where, "output");
  EXPECT_TRUE(part(placed, "A").lost);
  EXPECT_EQ(to_json(s, placed)["account"][0]["status"], "in_place");
}

// A part that never existed (a `missing` fault) was "picked" and "placed" by commands that did nothing: it is not
// completed, and there is no throughput of it.
TEST(ReportParts, APartThatNeverArrivedIsNotCompleted) {
  const Scenario s = exchange_scenario();
  FinalPose a;
  a.name = "A";
  a.present = false;
  const Report r = make_report(s, runtime::decode_log(exchange_log(), "e"), {a}, 14.0);
  EXPECT_EQ(r.parts_completed, 0u);
  EXPECT_FALSE(r.throughput);
  EXPECT_FALSE(part(r, "A").completed);
  EXPECT_FALSE(part(r, "A").cycle_time);
  EXPECT_EQ(to_json(s, r)["parts_completed"], 0);
  EXPECT_TRUE(to_json(s, r)["throughput_parts_per_min"].is_null());
  EXPECT_THAT(format_summary(r), ::testing::Not(HasSubstr("parts completed")));
  // On the output belt it is completed.
  const Report done = make_report(s, runtime::decode_log(exchange_log(), "e"), {on_output(s, 0.1)}, 14.0);
  EXPECT_EQ(done.parts_completed, 1u);
  EXPECT_TRUE(part(done, "A").completed);
  EXPECT_EQ(to_json(s, done)["workpieces"][0]["completed"], true);
}

// A relay: the PUMA picks A and places it on the mill's fixture, the MELFA picks it from there and places it on the
// output. The part is placed once (where it belongs), its cycle runs from the PUMA's pick to the end of the MELFA's
// Place; when the run stops before the final Place, nothing is completed.
class RelayReport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("cw-report-relay-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "relay.task") << "robot r1 r2\nworkpiece A\nlocation M OUT\n\nsteps\n  r1      | r2\n"
                                          "  Pick A  |\n  Place M |\n          | Pick A\n          | Place OUT\nend\n";
    s_ = parse_scenario("cell: " + kScenes + "/cell.yaml\nprogram: relay.task\nrobots: {r1: puma, r2: melfa}\n"
                        "bind: {M: machine_fixture, OUT: output_drop}\nexpect: {A: output}\ntolerance: 0.03\n",
                        dir_ / "relay.yaml");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // Each robot's primitives one after the other, 1 s per command, r1's first; a close of a Pick grips A, an open of
  // a Place releases it. Up to `until` s of commands.
  std::string log(double until) const {
    LogWriter w;
    w.start();
    double t = 0;
    for (std::size_t i = 0; i < s_.program.robots.size(); ++i) {
      const std::string& robot = s_.program.robots[i];
      const auto& prims = s_.program.programs[i].primitives;
      for (std::size_t k = 0; k < prims.size() && t < until; ++k) {
        const task::Primitive& p = prims[k];
        w.fire(t, robot, static_cast<int>(k));
        if (p.kind != task::PrimitiveKind::kMove && p.kind != task::PrimitiveKind::kOpen &&
            p.kind != task::PrimitiveKind::kClose) {
          continue;
        }
        w.command(t, t + 1, robot, static_cast<int>(k), task::to_string(p), p.task);
        const char* condition = p.kind == task::PrimitiveKind::kClose && p.task.starts_with("Pick ") ? "gripped"
                                : p.kind == task::PrimitiveKind::kOpen && p.task.starts_with("Place ")
                                    ? "released"
                                    : nullptr;
        if (condition != nullptr && !p.workpiece.empty()) {
          w.event(t + 1, "sensor",
                  fmt::format(R"("robot":"{}","primitive":{},"condition":"{}","workpiece":"A")", robot, k, condition));
        }
        t += 1;
      }
    }
    w.end(t + 1, t < until ? "finished" : "stopped", "", 20);
    return w.text();
  }

  std::filesystem::path dir_;
  Scenario s_;
};

TEST_F(RelayReport, ThePartIsPlacedOnceAndItsCycleEndsWithTheFinalPlace) {
  const std::string text = log(1e9);
  const Report r = make_report(s_, runtime::decode_log(text, "e"), {on_output(s_, 0.1)}, std::nullopt);
  // The end of the MELFA's Place: the last command of the log.
  double last_end = 0;
  for (const runtime::LoggedEvent& e : runtime::decode_log(text, "e")) {
    if (const auto* end = std::get_if<runtime::events::CommandEnd>(&e.event)) {
      last_end = std::chrono::duration<double>(end->t).count();
    }
  }
  const WorkpieceReport& a = part(r, "A");
  ASSERT_TRUE(a.completed);
  EXPECT_DOUBLE_EQ(*a.pick_start, 0.0);
  EXPECT_DOUBLE_EQ(*a.place_end, last_end);
  EXPECT_DOUBLE_EQ(*a.cycle_time, last_end);
  EXPECT_EQ(r.parts_completed, 1u);
  // Two Places released A; only the MELFA's, on the output, is its placement.
  ASSERT_EQ(r.placed_at.size(), 1u);
  EXPECT_GT(r.placed_at[0], last_end - 3);
  EXPECT_EQ(to_json(s_, r)["flow"]["placed"], 1);
}

TEST_F(RelayReport, AStopBeforeTheFinalPlaceCompletesNothing) {
  // Stopped in the MELFA's Pick: A rests on the mill's fixture, where the PUMA's Place put it.
  const std::string text = log(7.5);
  FinalPose a;
  a.name = "A";
  const models::LocationSpec& fixture = *s_.cell.find_location("machine_fixture");
  a.pose.translation() = fixture.pose.xyz + Eigen::Vector3d(0, 0, 0.03);
  const Report r = make_report(s_, runtime::decode_log(text, "e"), {a}, std::nullopt);
  EXPECT_EQ(r.parts_completed, 0u);
  EXPECT_FALSE(r.throughput);
  EXPECT_FALSE(part(r, "A").cycle_time);
  EXPECT_THAT(format_summary(r), ::testing::Not(HasSubstr("parts completed")));
}

// What the controller detected and no injection explains: an unexplained fault, with its diagnosis, in report.json
// and the summary. A driver's fault is always real; on a real (or emulated) driver there is no twin truth to call a
// detection a false alarm.
TEST(ReportFaults, DetectionsNoInjectionExplainsAreUnexplainedFaultsWithTheirDiagnosis) {
  const Scenario s = exchange_scenario();
  LogWriter w;
  w.start();
  w.event(2.0, "fault_detected", R"("robot":"r2","primitive":3,"symptom":"driver_fault","detail":"EOF on the link")");
  w.event(2.0, "diagnosis",
          R"("robot":"r2","symptom":"driver_fault","cause":"controller_fault","action":"reset_rehome","path":"")");
  w.event(2.01, "physical", R"("held":[{"robot":"puma","workpiece":""},{"robot":"melfa","workpiece":""}],"obstacles":0)");
  w.event(4.0, "recovery_end",
          R"("robot":"r2","cause":"controller_fault","action":"reset_rehome","ok":false,"detail":"","duration":2.0)");
  w.end(5, "failed", "r2: driver_fault", 10);
  const Report r = make_report(s, runtime::decode_log(w.text(), "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_TRUE(r.false_alarms.empty());
  ASSERT_EQ(r.unexplained.size(), 1u);
  const Detection& d = r.unexplained[0];
  EXPECT_DOUBLE_EQ(d.t, 2.0);
  EXPECT_EQ(d.robot, "r2");
  EXPECT_EQ(d.symptom, "driver_fault");
  EXPECT_EQ(d.cause, "controller_fault");
  EXPECT_EQ(d.action, "reset_rehome");
  EXPECT_FALSE(d.recovered);
  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["false_alarms"], 0);
  ASSERT_EQ(j["unexplained_faults"].size(), 1u);
  EXPECT_EQ(j["unexplained_faults"][0]["symptom"], "driver_fault");
  EXPECT_EQ(j["unexplained_faults"][0]["robot"], "r2");
  EXPECT_EQ(j["unexplained_faults"][0]["cause"], "controller_fault");
  EXPECT_EQ(j["unexplained_faults"][0]["action"], "reset_rehome");
  EXPECT_EQ(j["unexplained_faults"][0]["recovered"], false);
  const std::string text = format_summary(r);
  EXPECT_THAT(text, HasSubstr("unexplained faults: 1, false alarms: 0"));
  EXPECT_THAT(text, HasSubstr("unexplained fault at t = 2.00 s: driver_fault by r2 (EOF on the link), cause "
                              "controller_fault, action reset_rehome, not recovered"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("false alarm at")));
}

// A grip_lost while the twin has the part between the robot's fingers: nothing physically wrong, a false alarm. The
// same detection with the fingers empty is a real fault, unexplained; and on a real driver (no twin truth of it) it
// is unexplained whatever the twin's copy holds.
TEST(ReportFaults, AFalseAlarmIsADetectionTheTwinsTruthRefutes) {
  const Scenario s = exchange_scenario();
  auto log = [](const std::string& held) {
    LogWriter w;
    w.start();
    w.event(3.0, "fault_detected", R"("robot":"r1","primitive":7,"symptom":"grip_lost","detail":"A left the fingers")");
    w.event(3.0, "diagnosis", R"("robot":"r1","symptom":"grip_lost","cause":"dropped","action":"pick_again","path":"")");
    w.event(3.01, "physical",
            fmt::format(R"("held":[{{"robot":"puma","workpiece":"{}"}},{{"robot":"melfa","workpiece":""}}],"obstacles":0)",
                        held));
    w.event(5.0, "recovery_end", R"("robot":"r1","cause":"dropped","action":"pick_again","ok":true,"detail":"","duration":2.0)");
    w.end(20, "finished", "", 32);
    return runtime::decode_log(w.text(), "e");
  };
  const Report still_held = make_report(s, log("A"), {on_output(s, 0.1)}, std::nullopt);
  ASSERT_EQ(still_held.false_alarms.size(), 1u);
  EXPECT_TRUE(still_held.unexplained.empty());
  EXPECT_THAT(still_held.false_alarms[0].truth, HasSubstr("A between the fingers of puma"));
  EXPECT_EQ(still_held.false_alarms[0].cause, "dropped");
  EXPECT_TRUE(still_held.false_alarms[0].recovered);
  EXPECT_EQ(to_json(s, still_held)["false_alarms"], 1);
  EXPECT_THAT(format_summary(still_held), HasSubstr("false alarm at t = 3.00 s: grip_lost by r1: the twin has A"));

  const Report dropped = make_report(s, log(""), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_TRUE(dropped.false_alarms.empty());
  ASSERT_EQ(dropped.unexplained.size(), 1u);
  EXPECT_TRUE(dropped.unexplained[0].recovered);

  RunSetup real = setup_of(s);
  ASSERT_EQ(real.drivers.size(), 2u);
  EXPECT_EQ(real.drivers[0].robot, "puma");
  real.drivers[0].kind = "val2";
  real.drivers[0].port = "/dev/ttyUSB0";
  const Report on_real = make_report(s, log("A"), {on_output(s, 0.1)}, std::nullopt, "e", real);
  EXPECT_TRUE(on_real.false_alarms.empty());
  EXPECT_EQ(on_real.unexplained.size(), 1u);
  RunSetup no_twin = setup_of(s);
  no_twin.twin_truth = false;
  EXPECT_EQ(make_report(s, log("A"), {on_output(s, 0.1)}, std::nullopt, "e", no_twin).unexplained.size(), 1u);
}

// What the run used is what the report says: the perception, each robot's driver and the faults asked for, from the
// run's setup (the command line's overrides included), not from the scenario file.
TEST(ReportSetup, TheRunsPerceptionDriversAndFaultsAreInTheReport) {
  const Scenario s = exchange_scenario();
  RunSetup setup = setup_of(s);
  EXPECT_EQ(setup.perception, "truth");
  setup.perception = "cad";
  setup.drivers[1].kind = "movemaster";
  setup.drivers[1].port = "/tmp/melfa";
  setup.drivers[1].emulated = true;
  setup.faults = {"missing:workpiece=A"};
  const Report r = make_report(s, runtime::decode_log(exchange_log(), "e"), {on_output(s, 0.1)}, 14.0, "e", setup);
  const nlohmann::json j = to_json(s, r);
  EXPECT_EQ(j["perception"], "cad");
  ASSERT_EQ(j["drivers"].size(), 2u);
  EXPECT_EQ(j["drivers"][0], (nlohmann::json{{"robot", "puma"}, {"kind", "sim"}, {"port", ""}, {"emulated", false}}));
  EXPECT_EQ(j["drivers"][1]["kind"], "movemaster");
  EXPECT_EQ(j["drivers"][1]["port"], "/tmp/melfa");
  EXPECT_EQ(j["drivers"][1]["emulated"], true);
  EXPECT_EQ(j["requested_faults"], nlohmann::json::array({"missing:workpiece=A"}));
  EXPECT_THAT(format_summary(r), HasSubstr("perception cad; drivers: puma simulated, melfa emulated movemaster on "
                                           "/tmp/melfa; faults asked for: missing:workpiece=A"));
}

// A long run's report is built from its file one line at a time (the log is never held whole): the same report as
// from the parsed log, faults and all.
TEST(ReportFromStream, IsTheReportOfTheParsedLog) {
  const Scenario s = exchange_scenario();
  for (const std::string& log : {exchange_log(), exchange_log(false), drop_log("recover"), drop_log("stop", "stopped")}) {
    std::istringstream in(log);
    const Report streamed = make_report(s, in, {on_output(s, 0.1)}, 14.0);
    const Report parsed = make_report(s, runtime::decode_log(log, "events.jsonl"), {on_output(s, 0.1)}, 14.0);
    EXPECT_EQ(to_json(s, streamed).dump(1), to_json(s, parsed).dump(1));
    EXPECT_EQ(format_summary(streamed), format_summary(parsed));
    ASSERT_EQ(streamed.timeline.robots.size(), parsed.timeline.robots.size());
    for (std::size_t i = 0; i < parsed.timeline.robots.size(); ++i) {
      ASSERT_EQ(streamed.timeline.robots[i].bars.size(), parsed.timeline.robots[i].bars.size());
      for (std::size_t k = 0; k < parsed.timeline.robots[i].bars.size(); ++k) {
        EXPECT_EQ(streamed.timeline.robots[i].bars[k].label, parsed.timeline.robots[i].bars[k].label);
        EXPECT_EQ(streamed.timeline.robots[i].bars[k].end, parsed.timeline.robots[i].bars[k].end);
      }
    }
  }
}

TEST(ReportFromStream, ABadLineOrAFiringBeforeRunStartIsRefusedWithItsLineNumber) {
  const Scenario s = exchange_scenario();
  std::string log = exchange_log();
  log.insert(log.find('\n', log.find('\n') + 1) + 1, "{\"t\":1,\"type\":\n");  // line 3
  std::istringstream bad(log);
  try {
    (void)make_report(s, bad, {}, std::nullopt, "run/events.jsonl");
    FAIL() << "a broken line was accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("run/events.jsonl:3"));
  }
  std::istringstream early(
      R"({"t":0,"type":"fire","transition":"r1.t0","robot":"r1","primitive":0,"line":1,"task":"","motion":""})"
      "\n" +
      exchange_log());
  try {
    (void)make_report(s, early, {}, std::nullopt, "e.jsonl");
    FAIL() << "a firing before run_start was accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("e.jsonl:1"));
    EXPECT_THAT(e.what(), HasSubstr("before run_start"));
  }
}

// A log whose event lacks a field, or has one of the wrong type, is refused with the file, the line and the key:
// never read as a default ("" for a missing detail, no position for a mistyped one, no primitive for a sensor event).
TEST(ReportFromStream, AFieldMissingOrOfTheWrongTypeIsRefusedWithItsLineAndKey) {
  const Scenario s = exchange_scenario();
  const std::string drop = drop_log("lose");
  const std::string journey = exchange_log(true, true);
  struct Broken {
    const std::string& intact;  // a log that reads
    std::string from, to;       // the change of one of its lines
    std::string what;           // what the error must say
  };
  const std::vector<Broken> cases = {
      {drop, R"(,"detail":"carry 1 after 0.5 s")", "", R"(fault_injected event has no "detail")"},
      {drop, R"("x":0.5,)", "", R"(workpiece_lost event has no "x")"},
      {drop, R"("y":-0.25)", R"("y":null)", "must be all numbers or all null"},
      {journey, R"("robot":"r1","primitive":3,"condition":"gripped")", R"("robot":"r1","condition":"gripped")",
       R"(sensor event has no "primitive")"},
      {journey, R"("ok":true)", R"("ok":"yes")", R"(command_end event: "ok" is a string ("yes"), not true or false)"},
      {journey, R"({"robot":"r2","cell":"melfa"})", R"({"robot":"r2"})", R"(run_start event has no "robots[1].cell")"},
      {journey, R"("type":"collision")", R"("type":"collission")", R"(unknown event type "collission")"},
  };
  for (const Broken& c : cases) {
    const std::size_t at = c.intact.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    const std::string log = std::string(c.intact).replace(at, c.from.size(), c.to);
    const auto line = 1 + std::count(c.intact.begin(), c.intact.begin() + static_cast<std::ptrdiff_t>(at), '\n');
    std::istringstream in(log);
    try {
      (void)make_report(s, in, {on_output(s, 0.1)}, std::nullopt, "run/events.jsonl");
      ADD_FAILURE() << "accepted a log where " << c.what;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(fmt::format("run/events.jsonl:{}: error: ", line))) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(c.what));
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not an InputError: " << e.what();
    }
  }
}

TEST(Gantt, TickStepsAreOneTwoOrFiveTimesAPowerOfTen) {
  EXPECT_DOUBLE_EQ(tick_step(16.5, 20), 1.0);
  EXPECT_DOUBLE_EQ(tick_step(40, 20), 2.0);
  EXPECT_DOUBLE_EQ(tick_step(90, 20), 5.0);
  EXPECT_DOUBLE_EQ(tick_step(1, 20), 0.05);
  EXPECT_DOUBLE_EQ(tick_step(300, 20), 20.0);
}

TEST(Gantt, DrawsOneRowPerRobotWithBarsInTheirColours) {
  const Scenario s = exchange_scenario();
  const Timeline tl = build_timeline(runtime::decode_log(exchange_log(), "e"), s.program);
  GanttOptions o;
  o.title = "exchange";
  const cv::Mat img = draw_gantt(tl, o);
  ASSERT_EQ(img.type(), CV_8UC3);
  EXPECT_EQ(img.cols, o.width);
  EXPECT_GT(img.rows, 2 * o.row_height);
  // Sample r1's row at t = 7.5 s (waiting for "gripped": grey) and at t = 1.5 s (a move: blue), and r2's row at
  // t = 14.25 s (blocked: red-purple), a few pixels inside the bars' top edge (above any label). The chart maps
  // [0, 17] s (16.5 rounded up to a tick) onto x.
  const int left = 170, right = 40, title = 50;
  auto x_of = [&](double t) { return left + static_cast<int>(std::lround((o.width - left - right) * t / 17.0)); };
  auto colour_at = [&](int row, double t) {
    const cv::Vec3b c = img.at<cv::Vec3b>(title + row * o.row_height + 22 + 4, x_of(t));
    return fmt::format("{},{},{}", c[0], c[1], c[2]);
  };
  EXPECT_EQ(colour_at(0, 7.5), "200,200,200");
  EXPECT_EQ(colour_at(0, 1.5), "178,114,0");
  EXPECT_EQ(colour_at(1, 14.25), "120,60,204");
  EXPECT_EQ(colour_at(0, 13.5), "255,255,255");  // r1 is done: background
}

// A blocked span of a millisecond in a 17 s chart (under a pixel) is still drawn, and the legend shows every
// activity's colour and the journey marks; the part wait is drawn in its colour.
TEST(Gantt, ShortBlockedSpansStayVisibleAndTheLegendShowsEveryColour) {
  Timeline tl;
  tl.end = 16.5;
  RobotTimeline rt;
  rt.robot = "r1";
  rt.cell = "puma";
  rt.bars.push_back({0, 5, Activity::kPartWait, 1, "move above(A)", "Pick A"});
  rt.bars.push_back({5, 8, Activity::kMove, 1, "move above(A)", "Pick A"});
  rt.bars.push_back({8, 8.001, Activity::kBlocked, 1, "before move at(A)", "Pick A"});
  rt.bars.push_back({8.001, 12, Activity::kMove, 2, "move at(A)", "Pick A"});
  rt.marks.push_back({13, JourneyStep::kPicked, "A"});
  tl.robots.push_back(rt);
  GanttOptions o;
  const cv::Mat img = draw_gantt(tl, o);
  const int left = 170, right = 40, title = 15;
  auto x_of = [&](double t) { return left + static_cast<int>(std::lround((o.width - left - right) * t / 17.0)); };
  auto count = [&](const cv::Mat& part, Activity a) {
    const cv::Scalar c = activity_colour(a);
    cv::Mat mask;
    cv::inRange(part, c, c, mask);
    return cv::countNonZero(mask);
  };
  const cv::Mat row = img(cv::Rect(0, title, o.width, o.row_height));
  const cv::Mat around_blocked = row(cv::Rect(x_of(8) - 2, 0, 10, o.row_height));
  EXPECT_GE(count(around_blocked, Activity::kBlocked), 4 * (o.row_height - 30));  // >= 4 px wide
  EXPECT_GT(count(row, Activity::kPartWait), 0);
  EXPECT_EQ(count(row, Activity::kGrip), 0);
  const cv::Mat legend = img(cv::Rect(0, title + o.row_height + 60, o.width, img.rows - title - o.row_height - 60));
  for (Activity a : {Activity::kMove, Activity::kGrip, Activity::kWait, Activity::kPartWait, Activity::kBlocked}) {
    EXPECT_GT(count(legend, a), 300) << to_string(a);
  }
  // The picked mark: its green above the bar at t = 13 s.
  const cv::Mat mark = row(cv::Rect(x_of(13) - 6, 0, 12, 22));
  cv::Mat green;
  cv::inRange(mark, cv::Scalar(115, 158, 0), cv::Scalar(115, 158, 0), green);
  EXPECT_GT(cv::countNonZero(green), 10);
}

// --- The devices: their rows, figures and pages, from hand-written device events ---------------------------------------

void device(LogWriter& w, double t, const std::string& name, const std::string& kind, const std::string& state,
            const std::string& part = "") {
  w.event(t, "device",
          fmt::format(R"("device":"{}","kind":"{}","state":"{}","workpiece":"{}")", name, kind, state, part));
}

// A 10 s run of the exchange cell with a mill cycle: the mill idle from the start, busy with A from 2 s to 6 s, done
// (A waiting to be taken out) until 7 s, then idle; the input conveyor running for the first half of the run and its
// photo-eye on from 4 s to 5 s. `outcome` and the end: as given.
std::string device_log(const std::string& outcome = "finished", bool finish_cycle = true) {
  LogWriter w;
  w.start();
  device(w, 0, "mill", "machine", "idle");
  device(w, 0, "input", "conveyor", "running");
  device(w, 0, "input_eye", "sensor", "off");
  device(w, 2, "mill", "machine", "busy", "A");
  device(w, 4, "input_eye", "sensor", "on");
  device(w, 5, "input_eye", "sensor", "off");
  device(w, 5, "input", "conveyor", "stopped");
  if (finish_cycle) {
    device(w, 6, "mill", "machine", "done", "A");
    device(w, 7, "mill", "machine", "idle");
  }
  w.end(10, outcome, outcome == "finished" ? "" : "the cell was stopped", 0);
  return w.text();
}

Report device_report(const std::string& log) {
  const Scenario s = exchange_scenario();
  return make_report(s, runtime::decode_log(log, "e"), {on_output(s, 0.1)}, std::nullopt);
}

TEST(DeviceReport, AMillCycleIsBusyDoneAndIdleTimeWithItsPartProcessed) {
  const Report r = device_report(device_log());
  ASSERT_EQ(r.timeline.devices.size(), 3u);
  const DeviceTimeline& mill = r.timeline.devices[0];
  EXPECT_EQ(mill.device, "mill");
  EXPECT_EQ(mill.kind, "machine");
  EXPECT_DOUBLE_EQ(mill.busy, 4.0);
  EXPECT_DOUBLE_EQ(mill.done, 1.0);
  EXPECT_DOUBLE_EQ(mill.idle, 5.0);  // the run (10 s) minus busy and done
  EXPECT_DOUBLE_EQ(mill.utilisation, 0.4);
  EXPECT_EQ(mill.cycles_started, 1u);
  EXPECT_EQ(mill.cycles_finished, 1u);
  EXPECT_THAT(mill.processed, ElementsAre("A"));
  EXPECT_EQ(mill.state, "idle");
  std::vector<std::string> bars;
  for (const DeviceBar& b : mill.bars) bars.push_back(fmt::format("{} {}-{} {}", to_string(b.activity), b.start, b.end, b.workpiece));
  EXPECT_THAT(bars, ElementsAre("busy 2-6 A", "done 6-7 A"));

  const Scenario s = exchange_scenario();
  const nlohmann::json j = to_json(s, r);
  ASSERT_EQ(j["devices"].size(), 3u);
  EXPECT_EQ(j["devices"][0]["device"], "mill");
  EXPECT_EQ(j["devices"][0]["busy"], 4.0);
  EXPECT_EQ(j["devices"][0]["done_waiting"], 1.0);
  EXPECT_EQ(j["devices"][0]["idle"], 5.0);
  EXPECT_EQ(j["devices"][0]["utilisation"], 0.4);
  EXPECT_EQ(j["devices"][0]["cycles_finished"], 1);
  EXPECT_EQ(j["devices"][0]["processed"], nlohmann::json::array({"A"}));
  EXPECT_THAT(format_summary(r), HasSubstr("mill (machine): busy 4.00 s (40 %), done waiting 1.00 s, idle 5.00 s; "
                                           "cycles 1 started, 1 finished; processed A\n"));
}

// "A report is true when the run goes badly": a run that stops during the cycle shows the mill busy to the end and
// its part not processed.
TEST(DeviceReport, ARunThatStopsWithTheMillBusyShowsItBusyToTheEndAndThePartNotProcessed) {
  const Report r = device_report(device_log("stopped", false));
  const DeviceTimeline& mill = r.timeline.devices[0];
  EXPECT_DOUBLE_EQ(mill.busy, 8.0);  // 2 s to the end at 10 s
  EXPECT_DOUBLE_EQ(mill.done, 0.0);
  EXPECT_DOUBLE_EQ(mill.idle, 2.0);
  EXPECT_EQ(mill.cycles_started, 1u);
  EXPECT_EQ(mill.cycles_finished, 0u);
  EXPECT_TRUE(mill.processed.empty());
  EXPECT_EQ(mill.state, "busy");
  EXPECT_EQ(mill.workpiece, "A");
  ASSERT_EQ(mill.bars.size(), 1u);
  EXPECT_DOUBLE_EQ(mill.bars[0].end, 10.0);
  const nlohmann::json j = to_json(exchange_scenario(), r);
  EXPECT_EQ(j["devices"][0]["state"], "busy");
  EXPECT_EQ(j["devices"][0]["processed"], nlohmann::json::array());
  EXPECT_THAT(format_summary(r), HasSubstr("processed none; busy at the end with A (not processed)"));
  // A machine that went done without having been busy processed nothing either.
  LogWriter w;
  w.start();
  device(w, 0, "mill", "machine", "idle");
  device(w, 1, "mill", "machine", "done", "A");
  w.end(2, "finished", "", 0);
  EXPECT_TRUE(device_report(w.text()).timeline.devices[0].processed.empty());
}

TEST(DeviceReport, AConveyorStoppedHalfTheRunAndAPhotoEyeOnForASecond) {
  const Report r = device_report(device_log());
  const DeviceTimeline& input = r.timeline.devices[1];
  EXPECT_EQ(input.kind, "conveyor");
  EXPECT_DOUBLE_EQ(input.running, 5.0);
  EXPECT_DOUBLE_EQ(input.stopped, 5.0);
  EXPECT_EQ(input.starts, 1u);
  EXPECT_EQ(input.state, "stopped");
  const DeviceTimeline& eye = r.timeline.devices[2];
  EXPECT_EQ(eye.kind, "sensor");
  EXPECT_DOUBLE_EQ(eye.on, 1.0);
  EXPECT_DOUBLE_EQ(eye.off, 9.0);
  EXPECT_EQ(eye.starts, 1u);
  const nlohmann::json j = to_json(exchange_scenario(), r);
  EXPECT_EQ(j["devices"][1]["running"], 5.0);
  EXPECT_EQ(j["devices"][1]["stopped"], 5.0);
  EXPECT_EQ(j["devices"][2]["on"], 1.0);
  const std::string summary = format_summary(r);
  EXPECT_THAT(summary, HasSubstr("input (conveyor): running 5.00 s (50 %), stopped 5.00 s"));
  EXPECT_THAT(summary, HasSubstr("input_eye (sensor): on 1.00 s (10 %), off 9.00 s"));
}

// A log from before the devices (none of their events) gives the report it gave: no "devices" key, the same summary
// lines; and the device events of a log change nothing else of its report.
TEST(DeviceReport, ALogWithoutDeviceEventsGivesTheReportItGave) {
  const Scenario s = exchange_scenario();
  const std::string plain = exchange_log();
  const Report before = make_report(s, runtime::decode_log(plain, "e"), {on_output(s, 0.1)}, 14.25);
  EXPECT_TRUE(before.timeline.devices.empty());
  const nlohmann::json j = to_json(s, before);
  EXPECT_FALSE(j.contains("devices"));
  EXPECT_THAT(format_summary(before), ::testing::Not(HasSubstr("(machine)")));
  std::string with_devices = plain;
  const std::size_t after_start = with_devices.find('\n') + 1;
  with_devices.insert(after_start,
                      R"({"t":0.0000,"type":"device","device":"mill","kind":"machine","state":"idle","workpiece":""})"
                      "\n"
                      R"({"t":0.0000,"type":"device","device":"input","kind":"conveyor","state":"running","workpiece":""})"
                      "\n");
  const Report with = make_report(s, runtime::decode_log(with_devices, "e"), {on_output(s, 0.1)}, 14.25);
  ASSERT_EQ(with.timeline.devices.size(), 2u);
  nlohmann::json jw = to_json(s, with);
  jw.erase("devices");
  EXPECT_EQ(jw.dump(1), j.dump(1));
  // The chart of a log without devices has the robots' rows only (the same height as before).
  const cv::Mat chart = draw_gantt(before.timeline);
  EXPECT_EQ(chart.rows, 15 + 2 * GanttOptions{}.row_height + 60 + 84);
  EXPECT_GT(draw_gantt(with.timeline).rows, chart.rows + 2 * GanttOptions{}.row_height);
}

TEST(DeviceReport, ADeviceEventOfAnUnknownKindOrStateIsRefusedWithItsLine) {
  const Scenario s = exchange_scenario();
  struct Case {
    std::string lines, what;
  };
  for (const Case& c : std::vector<Case>{
           {R"({"t":1.0000,"type":"device","device":"mill","kind":"press","state":"busy","workpiece":""})",
            "kind \"press\""},
           {R"({"t":1.0000,"type":"device","device":"mill","kind":"machine","state":"running","workpiece":""})",
            "state \"running\"; a machine is idle, busy, done"},
           {R"({"t":1.0000,"type":"device","device":"mill","kind":"machine","state":"busy","workpiece":""})"
            "\n"
            R"({"t":2.0000,"type":"device","device":"mill","kind":"sensor","state":"on","workpiece":""})",
            "device mill is a machine (its first event), not a sensor"}}) {
    std::string log = exchange_log();
    log.insert(log.find('\n') + 1, c.lines + "\n");
    try {
      make_report(s, runtime::decode_log(log, "e.jsonl"), {on_output(s, 0.1)}, std::nullopt, "e.jsonl");
      ADD_FAILURE() << c.what;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(c.what));
      EXPECT_THAT(e.what(), HasSubstr("e.jsonl"));
      EXPECT_GE(e.where().line, 2);
    }
  }
}

// The chart has a row per device after the robots' rows: the mill busy (vermillion) and done (green) told apart, the
// conveyor running (sky blue), the photo-eye on (dark grey); and a legend line for them.
TEST(Gantt, DrawsARowPerDeviceAfterTheRobots) {
  const Report r = device_report(device_log());
  GanttOptions o;
  const cv::Mat img = draw_gantt(r.timeline, o);
  const int left = 170, right = 40, title = 15;
  // The axis maps [0, 10] s onto x.
  auto x_of = [&](double t) { return left + static_cast<int>(std::lround((o.width - left - right) * t / 10.0)); };
  auto colour_at = [&](int row, double t) {
    const cv::Vec3b c = img.at<cv::Vec3b>(title + row * o.row_height + o.row_height - 12, x_of(t));
    return cv::Scalar(c[0], c[1], c[2]);
  };
  // Rows 0 and 1 are the robots; the mill is row 2, the conveyor 3, the eye 4.
  EXPECT_EQ(colour_at(2, 4.0), device_colour(DeviceActivity::kBusy));
  EXPECT_EQ(colour_at(2, 6.5), device_colour(DeviceActivity::kDone));
  EXPECT_NE(colour_at(2, 8.5), device_colour(DeviceActivity::kBusy));  // idle: no bar
  EXPECT_EQ(colour_at(3, 2.5), device_colour(DeviceActivity::kRunning));
  EXPECT_NE(colour_at(3, 7.5), device_colour(DeviceActivity::kRunning));  // stopped
  EXPECT_EQ(colour_at(4, 4.5), device_colour(DeviceActivity::kOn));
  EXPECT_NE(colour_at(4, 2.5), device_colour(DeviceActivity::kOn));
  const cv::Mat legend = img(cv::Rect(0, title + 5 * o.row_height + 60, o.width, img.rows - title - 5 * o.row_height - 60));
  for (DeviceActivity a : {DeviceActivity::kBusy, DeviceActivity::kDone, DeviceActivity::kRunning, DeviceActivity::kOn}) {
    cv::Mat mask;
    cv::inRange(legend, device_colour(a), device_colour(a), mask);
    EXPECT_GT(cv::countNonZero(mask), 300) << to_string(a);
  }
}

}  // namespace
}  // namespace cellwright::cell
