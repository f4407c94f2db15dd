// The run report and the Gantt chart, from a synthetic event log of the paper's exchange program.
#include "cellwright/twin/scenario/report.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "cellwright/twin/scenario/gantt.hpp"

namespace cellwright::twin::scenario {
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
std::string exchange_log(bool finished = true) {
  LogWriter w;
  w.start();
  auto step = [&](const std::string& r, int k, double t0, double t1, const std::string& text, const std::string& task) {
    w.fire(t0, r, k);
    w.command(t0, t1, r, k, text, task);
  };
  step("r1", 0, 0, 1, "open", "Pick A");
  step("r1", 1, 1, 2, "move above(A)", "Pick A");
  step("r1", 2, 2, 3, "move at(A)", "Pick A");
  step("r1", 3, 3, 4, "close A", "Pick A");
  step("r1", 4, 4, 5, "move above(A)", "Pick A");
  w.fire(5, "r1", 5);
  w.fire(5, "r1", 6);
  step("r1", 7, 5, 6, "move handover(r2)", "Put r2");
  w.fire(6, "r1", 8);
  w.fire(6, "r1", 9);
  step("r1", 10, 9, 10, "open A", "Put r2");
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

TEST(EventLogParse, RejectsBadLinesWithTheirLineNumber) {
  EXPECT_EQ(parse_event_log("{\"t\":0,\"type\":\"a\"}\n\n{\"t\":1,\"type\":\"b\"}\n", "e.jsonl").size(), 2u);
  try {
    parse_event_log("{\"t\":0,\"type\":\"a\"}\n{\"t\":1,\"type\":\n", "e.jsonl");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, 2);
    EXPECT_EQ(e.where().file, "e.jsonl");
  }
  EXPECT_THROW(parse_event_log("{\"type\":\"a\"}\n", "e.jsonl"), InputError);
  EXPECT_THROW(parse_event_log("[1,2]\n", "e.jsonl"), InputError);
}

TEST(Timeline, BarsFollowTheFiringsAndCommands) {
  const Scenario s = exchange_scenario();
  const Timeline tl = build_timeline(parse_event_log(exchange_log(), "e"), s.program);
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

TEST(Timeline, EventsOfAnotherProgramAreRefused) {
  const Scenario s = exchange_scenario();
  std::string log = exchange_log();
  log +=
      R"({"t":17.0000,"type":"command_start","robot":"r2","primitive":40,"command":"open","task":"","motion":"","detail":""})"
      "\n";
  try {
    build_timeline(parse_event_log(log, "e.jsonl"), s.program, "e.jsonl");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("primitive 40"));
    EXPECT_GT(e.where().line, 1);
  }
  EXPECT_THROW(build_timeline(parse_event_log("{\"t\":0,\"type\":\"fire\"}\n", "e"), s.program), InputError);
}

TEST(Report, FinishedRunWithThePartOnTheOutputBeltIsOk) {
  const Scenario s = exchange_scenario();
  const Report r = make_report(s, parse_event_log(exchange_log(), "e"), {on_output(s, 0.1)}, 14.25);
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
  const Report r = make_report(s, parse_event_log(exchange_log(), "e"), {f}, std::nullopt);
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
  const Report r = make_report(s, parse_event_log(exchange_log(false), "e"), {on_output(s, 0.0)}, 14.0);
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
  const Report r = make_report(s, parse_event_log(log, "e"), {on_output(s, 0.1)}, std::nullopt);
  EXPECT_EQ(r.outcome, "unfinished");
  EXPECT_FALSE(r.ok());
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
  const Timeline tl = build_timeline(parse_event_log(exchange_log(), "e"), s.program);
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
    const cv::Vec3b c = img.at<cv::Vec3b>(title + row * o.row_height + o.row_height / 6 + 4, x_of(t));
    return fmt::format("{},{},{}", c[0], c[1], c[2]);
  };
  EXPECT_EQ(colour_at(0, 7.5), "200,200,200");
  EXPECT_EQ(colour_at(0, 1.5), "178,114,0");
  EXPECT_EQ(colour_at(1, 14.25), "120,60,204");
  EXPECT_EQ(colour_at(0, 13.5), "255,255,255");  // r1 is done: background
}

}  // namespace
}  // namespace cellwright::twin::scenario
