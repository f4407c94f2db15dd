// The events' one codec: every type writes the bytes the log has always had and reads back to the same bytes; a line
// that lacks a field, has one of the wrong type, an unknown type or is not JSON is refused with its file, line and key.
#include "cellwright/runtime/log_event.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::nanoseconds;
using ::testing::HasSubstr;
namespace ev = events;

// Random field values, seeded: strings with what JSON must escape (quotes, backslashes, control characters, non-ASCII,
// invalid UTF-8), integers at their limits, times and lengths of any sign.
class Random {
 public:
  explicit Random(unsigned seed) : rng_(seed) {}

  std::string text() {
    static const std::vector<std::string> pieces = {
        "",         "r1",          "puma",         "A",           "move at(A)",
        "\"q\"",    "back\\slash", "line\nbreak",  "tab\t",       std::string("nul\0x", 5),
        "\x01\x1f", "caf\xc3\xa9", "\xe2\x9c\x93", "bad\xff\xfe", "part_seen=yes"};
    std::string s;
    for (int n = pick(0, 3); n > 0; --n)
      s += pieces[static_cast<std::size_t>(pick(0, static_cast<int>(pieces.size()) - 1))];
    return s;
  }
  SimDuration time() {
    switch (pick(0, 3)) {
      case 0:
        return nanoseconds(0);
      case 1:
        return nanoseconds(static_cast<std::int64_t>(pick(0, 1'000'000)) * 100'000);  // on the log's grid
      case 2:
        return nanoseconds(std::uniform_int_distribution<std::int64_t>(-1'000'000'000, 100'000'000'000'000)(rng_));
      default:
        return nanoseconds(pick(-60'000, 60'000));  // around zero: "-0.0000" must not appear
    }
  }
  double length(double scale) {
    if (pick(0, 5) == 0) return pick(0, 1) == 0 ? 0.0 : -0.0;
    if (pick(0, 5) == 0) return std::uniform_real_distribution<double>(-1e-6, 1e-6)(rng_);
    return std::uniform_real_distribution<double>(-scale, scale)(rng_);
  }
  int integer() { return pick(0, 3) == 0 ? std::numeric_limits<int>::min() : pick(-1, 1000); }
  std::size_t count() {
    return pick(0, 3) == 0 ? std::numeric_limits<std::size_t>::max() : static_cast<std::size_t>(pick(0, 1000));
  }
  bool flag() { return pick(0, 1) == 1; }
  int pick(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  Eigen::Vector3d point() { return {length(2), length(2), length(2)}; }

 private:
  std::mt19937 rng_;
};

// A random event of the variant's alternative `index`.
LogEvent random_event(std::size_t index, Random& r) {
  const SimDuration t = r.time();
  switch (index) {
    case 0: {
      ev::RunStart e{t, r.text(), r.text(), r.text(), r.time(), {}};
      for (int n = r.pick(0, 3); n > 0; --n) e.robots.push_back({r.text(), r.text()});
      return e;
    }
    case 1:
      return ev::Fire{t, r.text(), r.text(), r.integer(), r.integer(), r.text(), r.text()};
    case 2:
      return ev::CommandStart{t, r.text(), r.count(), r.text(), r.text(), r.text(), r.text()};
    case 3:
      return ev::CommandEnd{t, r.text(), r.count(), r.text(), r.flag(), r.text()};
    case 4:
      return ev::Sensor{t, r.text(), r.count(), r.text(), r.text()};
    case 5:
      return ev::Collision{t, r.text(), r.text(), r.length(0.05)};
    case 6:
      return ev::WorkpieceArrived{t, r.text(), r.text()};
    case 7:
      return ev::WorkpieceLeft{t, r.text(), r.text()};
    case 8: {
      ev::Vision e{t, r.time(), {}, {}, r.count(), r.text()};
      for (int n = r.pick(0, 3); n > 0; --n) {
        e.seen.push_back(
            {r.text(), r.point(), r.flag() ? std::optional<double>(r.length(4)) : std::nullopt, r.length(1)});
      }
      for (int n = r.pick(0, 2); n > 0; --n) e.not_seen.push_back(r.text());
      return e;
    }
    case 9:
      return ev::FaultInjected{t, r.text(), r.text(), r.text(), r.text()};
    case 10:
      return ev::FaultDetected{t, r.text(), r.integer(), r.text(), r.text()};
    case 11:
      return ev::Diagnosis{t, r.text(), r.text(), r.text(), r.text(), r.text()};
    case 12:
      return ev::RecoveryEnd{t, r.text(), r.text(), r.text(), r.flag(), r.text(), r.time()};
    case 13:
      return ev::ProtectiveStop{t, r.text(), r.text()};
    case 14:
      return ev::ProtectiveRelease{t, r.text()};
    case 15:
      return ev::WorkpieceLost{t, r.text(), r.text(),
                               r.flag() ? std::optional<Eigen::Vector3d>(r.point()) : std::nullopt};
    case 16:
      return ev::Skipped{t, r.text(), r.count(), r.text(), r.text()};
    case 17:
      return ev::CellStopped{t, r.text()};
    case 18: {
      ev::Physical e{t, {}, r.count()};
      for (int n = r.pick(0, 3); n > 0; --n) e.held.push_back({r.text(), r.text()});
      return e;
    }
    case 19:  // squeeze either way; error, turn and tilt (mm, degrees) of any size
      return ev::Carry{t, r.text(), r.text(), r.text(), r.length(50.0), r.length(20.0),
                       r.length(5.0), r.length(90.0)};
    case 20:
      return ev::RunEnd{t, r.text(), r.text(), r.flag() ? std::numeric_limits<std::uint64_t>::max() : 12u};
    case 21:
      return ev::Device{t, r.text(), r.text(), r.text(), r.text()};
    default:
      ADD_FAILURE() << "no random event for alternative " << index;
      return ev::CellStopped{};
  }
}

TEST(LogEventCodec, EveryTypeReadsBackToTheSameBytes) {
  Random r(20261127);
  // A number that prints as zero has no minus sign: no value ":-0.0...0" ending at a ',', '}' or ']'. (By hand, not
  // with <regex>: GCC 12's -Wmaybe-uninitialized fires inside libstdc++'s regex in the sanitizer builds.)
  const auto has_negative_zero = [](const std::string& line) {
    for (std::size_t at = line.find(":-0."); at != std::string::npos; at = line.find(":-0.", at + 1)) {
      std::size_t k = at + 4;
      while (k < line.size() && line[k] == '0') ++k;
      if (k > at + 4 && k < line.size() && (line[k] == ',' || line[k] == '}' || line[k] == ']')) return true;
    }
    return false;
  };
  for (std::size_t index = 0; index < std::variant_size_v<LogEvent>; ++index) {
    for (int i = 0; i < 300; ++i) {
      const LogEvent e = random_event(index, r);
      ASSERT_EQ(e.index(), index);
      const std::string line = encode(e);
      ASSERT_TRUE(nlohmann::json::accept(line)) << line;
      EXPECT_EQ(line.find('\n'), std::string::npos) << line;
      EXPECT_FALSE(has_negative_zero(line)) << line;
      const LogEvent back = decode(line, "events.jsonl", 1);
      ASSERT_EQ(back.index(), index) << line;
      EXPECT_EQ(encode(back), line);
      EXPECT_EQ(decode(encode(back), "events.jsonl", 1), back) << line;  // what was read is what is read again
      EXPECT_EQ(type_of(back), type_of(e));
    }
  }
}

// The bytes of each type are the log's, key by key (lines written by the log before the typed events, kept here).
TEST(LogEventCodec, WritesTheLinesTheLogHasAlwaysHad) {
  const nanoseconds t(21'934'567'890);
  const std::vector<std::pair<LogEvent, std::string>> cases = {
      {ev::Vision{t,
                  nanoseconds(21'900'000'000),
                  {{"A", {0.5, -0.25, 0.03}, 0.5, 0.98765}, {"B", {-0.00001, 0.1, 0.2}, std::nullopt, 1}},
                  {"C", "D"},
                  2,
                  ""},
       R"({"t":21.9346,"type":"vision","frame":21.9000,"seen":[{"workpiece":"A","x":0.5000,"y":-0.2500,"z":0.0300,"yaw":28.65,"confidence":0.988},{"workpiece":"B","x":0.0000,"y":0.1000,"z":0.2000,"yaw":null,"confidence":1.000}],"not_seen":["C","D"],"rejected":2,"problem":""})"},
      {ev::FaultInjected{t, "drop", "puma", "A", "carry 1 after 0.5 s"},
       R"({"t":21.9346,"type":"fault_injected","kind":"drop","robot":"puma","workpiece":"A","detail":"carry 1 after 0.5 s"})"},
      {ev::FaultDetected{t, "r1", -1, "grip_lost", "A left"},
       R"({"t":21.9346,"type":"fault_detected","robot":"r1","primitive":-1,"symptom":"grip_lost","detail":"A left"})"},
      {ev::Diagnosis{t, "r1", "grip_lost", "dropped", "pick_again", "part_seen=yes"},
       R"({"t":21.9346,"type":"diagnosis","robot":"r1","symptom":"grip_lost","cause":"dropped","action":"pick_again","path":"part_seen=yes"})"},
      {ev::RecoveryEnd{t, "r1", "dropped", "pick_again", true, "", nanoseconds(3'380'000'000)},
       R"({"t":21.9346,"type":"recovery_end","robot":"r1","cause":"dropped","action":"pick_again","ok":true,"detail":"","duration":3.3800})"},
      {ev::ProtectiveStop{t, "r2", "obstacle"},
       R"({"t":21.9346,"type":"protective_stop","robot":"r2","reason":"obstacle"})"},
      {ev::ProtectiveRelease{t, "r2"}, R"({"t":21.9346,"type":"protective_release","robot":"r2"})"},
      {ev::WorkpieceLost{t, "A", "cannot_grasp", Eigen::Vector3d(0.03, -0.55, 0.53)},
       R"({"t":21.9346,"type":"workpiece_lost","workpiece":"A","reason":"cannot_grasp","x":0.0300,"y":-0.5500,"z":0.5300})"},
      {ev::WorkpieceLost{t, "A", "missing", std::nullopt},
       R"({"t":21.9346,"type":"workpiece_lost","workpiece":"A","reason":"missing","x":null,"y":null,"z":null})"},
      {ev::Skipped{t, "r1", 10, "open A", "A is lost"},
       R"({"t":21.9346,"type":"skipped","robot":"r1","primitive":10,"command":"open A","reason":"A is lost"})"},
      {ev::CellStopped{t, "nothing else applied"},
       R"({"t":21.9346,"type":"cell_stopped","reason":"nothing else applied"})"},
      {ev::Physical{t, {{"puma", "A"}, {"melfa", ""}}, 1},
       R"({"t":21.9346,"type":"physical","held":[{"robot":"puma","workpiece":"A"},{"robot":"melfa","workpiece":""}],"obstacles":1})"},
      {ev::WorkpieceLeft{t, "A", "output"},
       R"({"t":21.9346,"type":"workpiece_left","workpiece":"A","where":"output"})"},
      {ev::Device{t, "mill", "machine", "busy", "A"},
       R"({"t":21.9346,"type":"device","device":"mill","kind":"machine","state":"busy","workpiece":"A"})"},
  };
  for (const auto& [event, line] : cases) {
    EXPECT_EQ(encode(event), line);
    EXPECT_EQ(encode(decode(line, "e", 1)), line);
  }
}

// What the error says for each kind of broken line: the file, the line, and the key or the problem.
TEST(LogEventCodec, ABrokenLineIsRefusedWithItsFileLineAndKey) {
  const std::string fire = R"("transition":"r1.t3","robot":"r1","primitive":3,"line":8,"task":"","motion":"")";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"t":1.0,"type":)", "not a JSON value (each line of an event log is one JSON object)"},
      {R"([1,2])", "an event must be a JSON object, not a list"},
      {R"({"t":1.0})", R"(the event has no "type")"},
      {R"({"t":1.0,"type":3})", R"(the event's "type" is an integer, not a string)"},
      {R"({"t":1.0,"type":"teleport"})", R"(unknown event type "teleport")"},
      {R"({"type":"fire",)" + fire + "}", R"(fire event has no "t")"},
      {R"({"t":"1.0","type":"fire",)" + fire + "}", R"(fire event: "t" is a string ("1.0"), not a number)"},
      {R"({"t":1.0,"type":"fire","robot":"r1","primitive":3,"line":8,"task":"","motion":""})",
       R"(fire event has no "transition")"},
      {R"({"t":1.0,"type":"fire","transition":7,"robot":"r1","primitive":3,"line":8,"task":"","motion":""})",
       R"(fire event: "transition" is an integer (7), not a string)"},
      {R"({"t":1.0,"type":"fire","transition":"r1.t3","robot":"r1","primitive":3.5,"line":8,"task":"","motion":""})",
       R"(fire event: "primitive" is a number (3.5), not an integer)"},
      {R"({"t":1.0,"type":"fire","transition":"r1.t3","robot":"r1","primitive":3,"line":4294967296,"task":"","motion":""})",
       R"(fire event: "line" is an integer (4294967296), not an integer in range)"},
      {R"({"t":1.0,"type":"command_end","robot":"r1","primitive":-1,"command":"open","ok":true,"reason":""})",
       R"(command_end event: "primitive" is an integer (-1), not a count (an integer >= 0))"},
      {R"({"t":1.0,"type":"command_end","robot":"r1","primitive":1,"command":"open","ok":1,"reason":""})",
       R"(command_end event: "ok" is an integer (1), not true or false)"},
      {R"({"t":1.0,"type":"run_start","program":"p","cell":"c","mode":"lockstep","period":0.01,"robots":{}})",
       R"(run_start event: "robots" is an object ({}), not a list of objects)"},
      {R"({"t":1.0,"type":"run_start","program":"p","cell":"c","mode":"lockstep","period":0.01,"robots":["r1"]})",
       R"(run_start event: "robots[0]" is a string ("r1"), not an object)"},
      {R"({"t":1.0,"type":"physical","held":[{"robot":"puma","workpiece":""},{"workpiece":"A"}],"obstacles":0})",
       R"(physical event has no "held[1].robot")"},
      {R"({"t":1.0,"type":"vision","frame":1.0,"seen":[{"workpiece":"A","x":0,"y":0,"z":0,"yaw":"east","confidence":1}],"not_seen":[],"rejected":0,"problem":""})",
       R"(vision event: "seen[0].yaw" is a string ("east"), not a number)"},
      {R"({"t":1.0,"type":"vision","frame":1.0,"seen":[],"not_seen":[3],"rejected":0,"problem":""})",
       R"(vision event: "not_seen[0]" is an integer (3), not a string)"},
      {R"({"t":1.0,"type":"workpiece_lost","workpiece":"A","reason":"","x":0.1,"y":null,"z":0.2})",
       R"(workpiece_lost event: "x", "y" and "z" must be all numbers or all null (nowhere), not 0.1, null, 0.2)"},
      {R"({"t":1.0,"type":"run_end","outcome":"finished","reason":"","firings":-3})",
       R"(run_end event: "firings" is an integer (-3), not a count (an integer >= 0))"},
  };
  for (const auto& [line, what] : cases) {
    try {
      (void)decode(line, "run/events.jsonl", 12);
      ADD_FAILURE() << "accepted " << line;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, "run/events.jsonl");
      EXPECT_EQ(e.where().line, 12);
      EXPECT_EQ(e.problem(), what) << line;
    }
  }
}

TEST(LogEventCodec, AWholeLogIsReadWithItsLineNumbersAndBlankLinesSkipped) {
  EventLog log;
  log.workpiece_arrived(nanoseconds(0), "A", "input");
  log.protective_release(nanoseconds(1'000'000'000), "r1");
  const std::string text = log.lines()[0] + "\r\n\n  \n" + log.lines()[1] + "\n";
  const std::vector<LoggedEvent> events = decode_log(text, "e.jsonl");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].line, 1);
  EXPECT_EQ(events[1].line, 4);
  EXPECT_EQ(std::get<ev::WorkpieceArrived>(events[0].event).where, "input");
  EXPECT_EQ(std::get<ev::ProtectiveRelease>(events[1].event).t, nanoseconds(1'000'000'000));
  // The stream reader sees the same, and a broken line names its number.
  std::istringstream in(text + "{\"t\":2,\"type\":\"cell_stopped\"}\n");
  std::vector<int> lines;
  try {
    read_log(in, "e.jsonl", [&](const LoggedEvent& e) { lines.push_back(e.line); });
    ADD_FAILURE() << "a cell_stopped without its reason was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, 5);
    EXPECT_THAT(e.what(), HasSubstr(R"(e.jsonl:5: error: cell_stopped event has no "reason")"));
  }
  EXPECT_EQ(lines, (std::vector<int>{1, 4}));
}

// A typed observer of the log gets each event as it is logged, in the log's order: the same events its lines hold.
TEST(LogEventCodec, ALogsObserversGetEachEventItLogs) {
  EventLog log;
  std::vector<LogEvent> seen;
  log.add_observer([&](const LogEvent& e) { seen.push_back(e); });
  log.fault_detected(nanoseconds(5), "r1", 3, "grip_lost", "A left");
  log.log(ev::CellStopped{nanoseconds(7), "nothing else applied"});
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(std::get<ev::FaultDetected>(seen[0]).symptom, "grip_lost");
  EXPECT_EQ(encode(seen[1]), log.lines()[1]);
  EXPECT_EQ(log.detections(), 1u);
}

// A run's event observer gets every event of the run, typed, in the log's order.
TEST(LogEventCodec, ARunObserverGetsEveryEventOfTheRunTyped) {
  cellwright::testing::ScriptedCell cell;
  std::vector<std::string> lines;
  cell.config.event_observers.push_back([&lines](const LogEvent& e) { lines.push_back(encode(e)); });
  Runtime rt(cell.config);
  ASSERT_EQ(rt.run().outcome, Outcome::kFinished);
  EXPECT_GT(lines.size(), 20u);
  EXPECT_EQ(lines, rt.log().lines());
}

}  // namespace
}  // namespace cellwright::runtime
