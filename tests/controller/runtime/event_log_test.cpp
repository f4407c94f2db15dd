// The event log's bytes: fixed key order and number formatting, so that logs compare with a plain diff.
#include "cellwright/runtime/event_log.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <nlohmann/json.hpp>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::nanoseconds;

TEST(RuntimeEventLog, SimTimeHasFourDecimalsRoundedOnTheNanosecondCount) {
  EXPECT_EQ(format_sim_time(nanoseconds(0)), "0.0000");
  EXPECT_EQ(format_sim_time(nanoseconds(1'234'567'890)), "1.2346");
  EXPECT_EQ(format_sim_time(nanoseconds(1'234'549'999)), "1.2345");
  EXPECT_EQ(format_sim_time(nanoseconds(50'000)), "0.0001");  // half rounds away from zero
  EXPECT_EQ(format_sim_time(nanoseconds(49'999)), "0.0000");
  EXPECT_EQ(format_sim_time(nanoseconds(119'999'950'000)), "120.0000");
  EXPECT_EQ(format_sim_time(nanoseconds(-1'500'000)), "-0.0015");
  EXPECT_EQ(format_sim_time(nanoseconds(-10)), "0.0000");  // no "-0.0000"
}

TEST(RuntimeEventLog, EachEventHasItsFixedKeysInOrder) {
  EventLog log;
  const nanoseconds t(2'500'000'000);
  log.run_start(nanoseconds(0), "scenes/exchange.task", "yasuda-cell", "lockstep", nanoseconds(10'000'000),
                {{"r1", "puma"}, {"r2", "melfa"}});
  log.fire(t, "r1.t3", "r1", 3, 8, "Pick A", "grasp A");
  log.command_start(t, "r1", 3, "close A", "Pick A", "grasp A", "grip close force 5.000000");
  log.command_end(t, "r1", 3, "close A", false, "closed on nothing");
  log.sensor(t, "r1", 3, "gripped", "A");
  log.collision(t, "puma/link3", "machine/mill", 0.00123456789);
  log.workpiece_arrived(t, "A", "input");
  log.run_end(t, "failed", "robot r1: \"quoted\"\n", 12);
  const std::vector<std::string> expected = {
      R"({"t":0.0000,"type":"run_start","program":"scenes/exchange.task","cell":"yasuda-cell","mode":"lockstep","period":0.0100,"robots":[{"robot":"r1","cell":"puma"},{"robot":"r2","cell":"melfa"}]})",
      R"({"t":2.5000,"type":"fire","transition":"r1.t3","robot":"r1","primitive":3,"line":8,"task":"Pick A","motion":"grasp A"})",
      R"({"t":2.5000,"type":"command_start","robot":"r1","primitive":3,"command":"close A","task":"Pick A","motion":"grasp A","detail":"grip close force 5.000000"})",
      R"({"t":2.5000,"type":"command_end","robot":"r1","primitive":3,"command":"close A","ok":false,"reason":"closed on nothing"})",
      R"({"t":2.5000,"type":"sensor","robot":"r1","primitive":3,"condition":"gripped","workpiece":"A"})",
      R"({"t":2.5000,"type":"collision","a":"puma/link3","b":"machine/mill","depth":0.001235})",
      R"({"t":2.5000,"type":"workpiece_arrived","workpiece":"A","where":"input"})",
      R"({"t":2.5000,"type":"run_end","outcome":"failed","reason":"robot r1: \"quoted\"\n","firings":12})",
  };
  EXPECT_EQ(log.lines(), expected);
  for (const auto& line : log.lines()) EXPECT_TRUE(nlohmann::json::accept(line)) << line;
}

TEST(RuntimeEventLog, WritesEachLineToTheSinkAndKeepsTheText) {
  std::ostringstream out;
  EventLog log(&out);
  log.workpiece_arrived(nanoseconds(0), "A", "input");
  log.collision(nanoseconds(0), "a", "b", -0.0);
  EXPECT_EQ(out.str(), log.text());
  EXPECT_EQ(log.size(), 2u);
  EXPECT_NE(log.text().find("\"depth\":0.000000}"), std::string::npos);  // negative zero folded
}

// A streamed log holds a count, not its lines: what a thousand-part shift needs to keep its memory flat.
TEST(RuntimeEventLog, AStreamedLogKeepsNoLinesAndSaysSoWhenAskedForThem) {
  std::ostringstream out;
  EventLog log(&out, EventLog::Keep::kNothing);
  EXPECT_FALSE(log.keeps_lines());
  for (int i = 0; i < 3; ++i) log.workpiece_arrived(nanoseconds(i), "A", "input");
  log.flush();
  EXPECT_EQ(log.size(), 3u);
  const std::string text = out.str();
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3);
  EXPECT_THROW((void)log.text(), InternalError);
  EXPECT_THROW((void)log.lines(), InternalError);
  EXPECT_THROW(EventLog(nullptr, EventLog::Keep::kNothing), InternalError);  // its lines would go nowhere
}

TEST(RuntimeEventLog, FlushSaysWhenTheSinkHasFailed) {
  std::ostringstream out;
  EventLog log(&out, EventLog::Keep::kNothing);
  log.workpiece_arrived(nanoseconds(0), "A", "input");
  EXPECT_NO_THROW(log.flush());
  out.setstate(std::ios::badbit);  // as a full disk leaves a file stream
  log.workpiece_arrived(nanoseconds(1), "A", "input");
  EXPECT_THROW(log.flush(), std::runtime_error);
}

TEST(RuntimeEventLog, LinesFromManyThreadsNeverInterleave) {
  EventLog log;
  std::vector<std::thread> threads;
  for (int k = 0; k < 4; ++k) {
    threads.emplace_back([&log, k] {
      for (int i = 0; i < 200; ++i) log.workpiece_arrived(nanoseconds(i), "part" + std::to_string(k), "input");
    });
  }
  for (auto& t : threads) t.join();
  ASSERT_EQ(log.size(), 800u);
  for (const auto& line : log.lines()) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["type"], "workpiece_arrived");
  }
}

}  // namespace
}  // namespace cellwright::runtime
