// report.json read back as a typed Report (report_json.hpp): the round trip to_json(from_json(to_json(r))) ==
// to_json(r) for real runs (the exchange, the exchange with a drop, the pipeline) and synthetic reports with every
// optional part set, and every field of report.json required: missing, of another type, or contradicting another
// field, it is an InputError naming the file and the field.
#include "cellwright/cell/report_json.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/faults.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cell/report_files.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";
const std::string kFile = "runs/0003/report.json";

// The message of the InputError `f` throws ("" if it throws none).
std::string input_error(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return std::string();
}

// report.json's text read back as a Report and written again: the same text.
void expect_round_trip(const Scenario& s, const Report& r) {
  const std::string text = to_json(s, r).dump(1);
  const Report back = from_json(json::parse(text), kFile);
  EXPECT_EQ(to_json(s, back).dump(1), text);
  // The typed values a campaign and a suite read.
  EXPECT_EQ(back.ok(), r.ok());
  EXPECT_EQ(back.outcome, r.outcome);
  EXPECT_EQ(back.faults.size(), r.faults.size());
  EXPECT_EQ(back.unaccounted(), r.unaccounted());
  EXPECT_EQ(back.placed_at.size(), r.placed_at.size());
}

// A report with every optional part set: parts in place, lost (seen and never seen), held, unaccounted; faults
// detected and recovered, stopped safely, not detected; false alarms; collisions; the flow's steady state.
Report full_report() {
  Report r;
  r.outcome = "stopped";
  r.reason = "no remedy left for 'grip_lost'";
  r.end_time = 31.23456;
  r.timeline.end = r.end_time;
  r.finished_at = 29.5;
  r.estimated_cycle_time = 14.25;
  r.firings = 42;
  r.throughput = 3.5;
  r.parts_completed = 2;
  r.placed_at = {10.1, 20.2, 30.3};
  r.parts_fed = 4;
  r.parts_delivered = 1;
  r.steady_throughput = 2.97;
  r.steady_cycle = 10.1;
  r.stopped_at = 31.0;
  WorkpieceReport a;
  a.name = "A";
  a.label = "part";
  a.final_location = "output";
  a.at = {"output", "output_drop"};
  a.position = {0.1234, -0.5, 0.75};
  a.expected = "output";
  a.tolerance = 0.03;
  a.ok = true;
  a.pick_start = 1.25;
  a.place_end = 12.5;
  a.cycle_time = 11.25;
  a.status = PartStatus::kInPlace;
  a.where = "output";
  WorkpieceReport b;
  b.name = "B";
  b.final_location = "floor";
  b.at = {"floor"};
  b.expected = "lost";
  b.ok = true;
  b.status = PartStatus::kLost;
  b.where = "floor";
  b.lost = LostPart{5.5, "dropped", Eigen::Vector3d(0.5, 0.25, 0.0)};
  WorkpieceReport c;
  c.name = "C";
  c.final_location = "held by puma";
  c.at = {"held by puma"};
  c.status = PartStatus::kHeld;
  c.where = "puma";
  c.lost = LostPart{7.0, "never seen", std::nullopt};
  WorkpieceReport d;
  d.name = "D";
  d.final_location = "elsewhere";
  d.expected = "output";
  d.ok = false;
  d.status = PartStatus::kElsewhere;
  d.where = "elsewhere";
  d.unaccounted = true;
  r.workpieces = {a, b, c, d};
  RobotTimeline t;
  t.robot = "r1";
  t.cell = "puma";
  t.commands = 12;
  t.busy = 10.5;
  t.waiting = 3.25;
  t.waiting_for_part = 1.5;
  t.blocked = 0.75;
  t.idle = 16.7;
  r.timeline.robots = {t};
  r.collisions.push_back({4.5, "puma/link6", "B", 0.0042});
  FaultReport f;
  f.kind = "drop";
  f.t = 5.0;
  f.robot = "puma";
  f.workpiece = "B";
  f.detail = "after 0.3 s";
  f.detected = true;
  f.detected_at = 5.25;
  f.detected_by = "r1";
  f.symptom = "grip_lost";
  f.cause = "dropped";
  f.action = "set_aside";
  f.recovered = true;
  f.recovery_time = 2.5;
  f.stopped_safely = true;
  FaultReport quiet;
  quiet.kind = "obstacle";
  quiet.t = 8.0;
  r.faults = {f, quiet};
  r.false_alarms.push_back(
      Detection{0.5, "r2", 3, "grip_lost", "the grip sensor reads open", "dropped", "regrasp", true,
                "the twin holds workpiece 'B' between its fingers"});
  r.unexplained.push_back(Detection{1.5, "r1", 4, "controller_not_answering", "no reply in 8 s", "controller_timeout",
                                    "reset", false, ""});
  r.setup.perception = "vision";
  r.setup.drivers = {{"puma", "sim", "", false}, {"melfa", "movemaster", "/dev/pts/7", true}};
  r.setup.faults = {"drop:robot=puma,carry=1,every=0,after=0.3"};
  r.failures = {"workpiece D must end at output, is elsewhere", "the cell was stopped"};
  return r;
}

TEST(ReportJson, SyntheticReportsComeBackAsWritten) {
  Scenario s;
  s.source = "/x/relay.yaml";
  s.program_file = "/x/relay.task";
  s.cell_file = "/x/cell.yaml";
  s.seed = 77;
  expect_round_trip(s, Report{});
  expect_round_trip(s, full_report());
  const Report back = from_json(to_json(s, full_report()), kFile);
  EXPECT_EQ(back.workpieces[1].status, PartStatus::kLost);
  ASSERT_TRUE(back.workpieces[1].lost && back.workpieces[1].lost->last_seen);
  EXPECT_EQ(*back.workpieces[1].lost->last_seen, Eigen::Vector3d(0.5, 0.25, 0.0));
  EXPECT_FALSE(back.workpieces[2].lost->last_seen);
  EXPECT_EQ(back.workpieces[0].label, "part");
  EXPECT_EQ(back.workpieces[2].label, "");
  EXPECT_EQ(back.timeline.end, back.end_time);
  EXPECT_EQ(back.placed_at, (std::vector<double>{10.1, 20.2, 30.3}));
  EXPECT_EQ(back.false_alarms[0].primitive, 3);
}

// A run of real robots without the twin says its parts' places are the controller's model's, in report.json
// ("parts_from") and back; a report of the twin's truth has no such key (a simulated run's report.json is unchanged),
// and any other value is refused.
TEST(ReportJson, PartsFromTheControllersModelAreSaidSoAndComeBack) {
  Scenario s;
  Report r = full_report();
  EXPECT_FALSE(to_json(s, r).contains("parts_from"));
  EXPECT_FALSE(from_json(to_json(s, r), kFile).setup.parts_from_model);
  r.setup.parts_from_model = true;
  const json j = to_json(s, r);
  EXPECT_EQ(j["parts_from"], "controller_model");
  EXPECT_TRUE(from_json(j, kFile).setup.parts_from_model);
  expect_round_trip(s, r);
  EXPECT_THAT(format_summary(r), HasSubstr("parts: where the controller's model (no twin"));
  EXPECT_THAT(format_summary(r), HasSubstr("(controller's model)"));
  json bad = j;
  bad["parts_from"] = "twin";
  EXPECT_THAT(input_error([&] { from_json(bad, kFile); }), HasSubstr("\"parts_from\" must be \"controller_model\""));
}

// The devices' figures (a log with device events) come back as written, each of their fields required by its kind;
// a report without devices has no "devices" key (a run without them is unchanged).
TEST(ReportJson, DevicesComeBackAsWrittenAndTheirFieldsAreRequired) {
  Scenario s;
  Report r = full_report();
  EXPECT_FALSE(to_json(s, r).contains("devices"));
  DeviceTimeline mill = test_reports::machine_figures("mill", 12.5, 1.25, 17.48456, true, "busy");
  mill.workpiece = "B";
  mill.cycles_started = 2;
  const DeviceTimeline belt = test_reports::switch_figures("input", "conveyor", 15.5, 15.73456, 3, "stopped");
  const DeviceTimeline eye = test_reports::switch_figures("input_eye", "sensor", 2.0, 29.23456, 2, "off");
  r.timeline.devices = {mill, belt, eye};
  expect_round_trip(s, r);
  const Report back = from_json(to_json(s, r), kFile);
  ASSERT_EQ(back.timeline.devices.size(), 3u);
  EXPECT_EQ(back.timeline.devices[0].processed, std::vector<std::string>{"A"});
  EXPECT_EQ(back.timeline.devices[0].state, "busy");
  EXPECT_EQ(back.timeline.devices[1].starts, 3u);
  EXPECT_EQ(back.timeline.devices[2].on, 2.0);
  const json full = to_json(s, r);
  for (const char* field : {"busy", "done_waiting", "idle", "utilisation", "cycles_started", "cycles_finished",
                            "processed", "workpiece", "state", "device", "kind"}) {
    json j = full;
    j["devices"][0].erase(field);
    EXPECT_THAT(input_error([&] { from_json(j, kFile); }),
                HasSubstr(fmt::format("\"devices[0].{}\" is missing", field)));
  }
  for (const char* field : {"running", "stopped", "starts"}) {
    json j = full;
    j["devices"][1].erase(field);
    EXPECT_THAT(input_error([&] { from_json(j, kFile); }),
                HasSubstr(fmt::format("\"devices[1].{}\" is missing", field)));
  }
  for (const char* field : {"on", "off", "times_on"}) {
    json j = full;
    j["devices"][2].erase(field);
    EXPECT_THAT(input_error([&] { from_json(j, kFile); }),
                HasSubstr(fmt::format("\"devices[2].{}\" is missing", field)));
  }
  json bad = full;
  bad["devices"][1]["kind"] = "robot";
  EXPECT_THAT(input_error([&] { from_json(bad, kFile); }),
              HasSubstr("\"devices[1].kind\" must be one of machine, conveyor, sensor"));
}

// Runs a scenario as `twin run` does (lock-step, in this process), checks its report's round trip and returns it.
Report run_and_round_trip(const Scenario& s) {
  const Preflight pre = preflight(s, &twin_port());
  EXPECT_TRUE(pre.ok()) << pre.problems.front();
  ScenarioRun run(s, pre);
  run.runtime().run();
  const Report r = run.report();
  expect_round_trip(s, r);
  return r;
}

TEST(ReportJson, ReportsOfRealRunsComeBackAsWritten) {
  EXPECT_TRUE(run_and_round_trip(load_scenario(kScenes + "/exchange.yaml")).ok());
  Scenario faulted = load_scenario(kScenes + "/exchange.yaml");
  // Dropped 1 s into the PUMA's carry, over the floor (at 0.3 s it fell back onto the input belt, which since it
  // accumulates holds it at the stop to be picked again: a run that recovers, not one that loses a part).
  faulted.faults.push_back(parse_fault_text("drop:robot=puma,after=1.0", faulted.cell));
  faulted.faults.push_back(parse_fault_text("timeout:robot=melfa,n=2", faulted.cell));
  const Report f = run_and_round_trip(faulted);
  ASSERT_EQ(f.faults.size(), 2u);
  EXPECT_TRUE(f.faults[0].detected);
  EXPECT_EQ(f.workpieces[0].status, PartStatus::kLost);
  EXPECT_EQ(run_and_round_trip(load_scenario(kScenes + "/pipeline.yaml")).placed_at.size(), 3u);
}

// Every field to_json writes, at any depth ("faults[1].detected"), with its JSON pointer.
void each_field(const json& j, const std::string& path, const json::json_pointer& ptr,
                const std::function<void(const std::string&, const json::json_pointer&)>& f) {
  if (j.is_object()) {
    for (const auto& [key, value] : j.items()) {
      const std::string p = path.empty() ? key : path + "." + key;
      f(p, ptr / key);
      each_field(value, p, ptr / key, f);
    }
  } else if (j.is_array()) {
    for (std::size_t i = 0; i < j.size(); ++i) each_field(j[i], fmt::format("{}[{}]", path, i), ptr / i, f);
  }
}

TEST(ReportJson, EveryMissingFieldIsNamedWithTheFile) {
  const json full = to_json(Scenario{}, full_report());
  int fields = 0;
  each_field(full, "", json::json_pointer(), [&](const std::string& path, const json::json_pointer& ptr) {
    json j = full;
    j[ptr.parent_pointer()].erase(ptr.back());
    const std::string e = input_error([&] { from_json(j, kFile); });
    EXPECT_THAT(e, HasSubstr(kFile + ": error: \"" + path + "\" is missing")) << path;
    ++fields;
  });
  EXPECT_GT(fields, 80);
}

TEST(ReportJson, EveryFieldOfAnotherTypeIsNamed) {
  const json full = to_json(Scenario{}, full_report());
  each_field(full, "", json::json_pointer(), [&](const std::string& path, const json::json_pointer& ptr) {
    // A list holding `true` is no field's type: a string, number, count, flag, list of strings or numbers, object.
    json j = full;
    j[ptr] = json::array({true});
    const std::string e = input_error([&] { from_json(j, kFile); });
    EXPECT_THAT(e, HasSubstr(kFile + ": error: \"" + path)) << path << ": " << e;  // itself, or its first element
  });
  const json minimal = to_json(Scenario{}, Report{});
  struct Case {
    std::string field, message;
    json value;
  };
  for (const Case& c : {Case{"firings", "must be a whole number >= 0, not -3", -3},
                        Case{"firings", "must be a whole number >= 0, not 2.5", 2.5},
                        Case{"end_time", "must be a number, not \"12\"", "12"},
                        Case{"outcome", "must be a string, not null", nullptr}}) {
    json j = minimal;
    j[c.field] = c.value;
    EXPECT_THAT(input_error([&] { from_json(j, kFile); }), HasSubstr("\"" + c.field + "\" " + c.message));
  }
  json status = full;
  status["account"][0]["status"] = "misplaced";
  EXPECT_THAT(input_error([&] { from_json(status, kFile); }),
              HasSubstr("\"account[0].status\" must be one of in_place, elsewhere, held, lost, not_arrived, scrapped, "
                        "not \"misplaced\""));
  EXPECT_THAT(input_error([&] { from_json(json::array(), kFile); }), HasSubstr("\"the report\" must be a JSON object"));
}

TEST(ReportJson, FieldsThatContradictEachOtherAreRefused) {
  const json full = to_json(Scenario{}, full_report());
  struct Case {
    std::function<void(json&)> change;
    std::string message;
  };
  for (const Case& c : {
           Case{[](json& j) { j["result"] = "ok"; }, "\"result\" must be \"failed\" with 2 failures, not \"ok\""},
           Case{[](json& j) { j["unaccounted"] = 0; }, "\"unaccounted\" must be 1, the account's unaccounted parts"},
           Case{[](json& j) { j["false_alarms"] = 0; }, "\"false_alarms\" must be 1, the length of"},
           Case{[](json& j) { j["flow"]["placed"] = 2; }, "\"flow.placed\" must be 3, the length of flow.placed_at"},
           Case{[](json& j) { j["account"][1]["workpiece"] = "A"; }, "\"account[1].workpiece\" must be \"B\""},
           Case{[](json& j) { j["account"][0]["expected"] = nullptr; }, "\"account[0].expected\" must be the"},
           Case{[](json& j) { j["account"].erase(3); }, "\"account\" must have 4 entries, one per workpiece"},
           Case{[](json& j) { j["faults"][0]["detected_at"] = nullptr; },
                "\"faults[0].detected_at\" is null for a detected fault"},
           Case{[](json& j) { j["faults"][0]["recovery_time"] = nullptr; },
                "\"faults[0].recovery_time\" is null for a recovered fault"},
           Case{[](json& j) { j["workpieces"][0]["ok"] = nullptr; },
                "\"workpieces[0].ok\" is null for a workpiece with an expectation"},
           Case{[](json& j) { j["flow"]["steady_cycle_s"] = nullptr; }, "\"flow.steady_cycle_s\" and"},
           Case{[](json& j) { j["position"] = 1; }, ""},  // a field it does not know: ignored
       }) {
    json j = full;
    c.change(j);
    const std::string e = input_error([&] { from_json(j, kFile); });
    if (c.message.empty()) {
      EXPECT_EQ(e, "");
    } else {
      EXPECT_THAT(e, HasSubstr(kFile + ": error: " + c.message));
    }
  }
}

TEST(ReportJson, AFileIsReadNamedWhenItIsNotJson) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("cw-report-json-{}", ::getpid());
  fs::create_directories(dir);
  std::ofstream(dir / "report.json") << to_json(Scenario{}, full_report()).dump(1);
  EXPECT_EQ(read_report(dir / "report.json").faults.size(), 2u);
  std::ofstream(dir / "bad.json") << "{\"result\": \"ok\",\n";
  EXPECT_THAT(input_error([&] { read_report(dir / "bad.json"); }),
              HasSubstr((dir / "bad.json").string() + ": error: not JSON: "));
  EXPECT_THAT(input_error([&] { read_report(dir / "bad.json"); }), HasSubstr("line 2"));
  EXPECT_THAT(input_error([&] { read_report(dir / "none.json"); }), HasSubstr("none.json"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cellwright::cell
