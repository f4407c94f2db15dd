// The fault campaign's parts: the targets and kinds a scenario offers, the variants drawn per (seed, run), the child
// processes (a stand-in executable that writes a report, crashes, hangs or writes nothing), and the adding up of
// fabricated report.json files into campaign.csv/.md/.png.
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/campaign.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/faults.hpp"
#include "cell/report_files.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// A scratch directory, removed afterwards.
class Scratch {
 public:
  explicit Scratch(const std::string& tag)
      : dir_(fs::temp_directory_path() / fmt::format("cw-campaign-{}-{}", tag, ::getpid())) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() { fs::remove_all(dir_); }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

std::string slurp(const fs::path& p) {
  std::ostringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

// The --fault text split into its kind and key=value fields.
struct Spec {
  std::string kind;
  std::map<std::string, std::string> fields;
};
Spec parse_spec(const std::string& text) {
  Spec s;
  const auto colon = text.find(':');
  s.kind = text.substr(0, colon);
  if (colon == std::string::npos) return s;
  std::stringstream rest(text.substr(colon + 1));
  std::string item;
  while (std::getline(rest, item, ',')) {
    const auto eq = item.find('=');
    EXPECT_NE(eq, std::string::npos) << text;
    EXPECT_TRUE(s.fields.emplace(item.substr(0, eq), item.substr(eq + 1)).second) << "key given twice: " << text;
  }
  return s;
}

// The exchange's targets without building the world (the cycle time as the estimate would say).
CampaignTargets exchange_targets() {
  return campaign_targets(load_scenario(kScenes + "/exchange.yaml"), 14.0);
}

TEST(CampaignTargets, TheExchangeOffersTwoCarryingSimRobotsOneWorkpieceAndSignals) {
  const CampaignTargets t = exchange_targets();
  ASSERT_EQ(t.robots.size(), 2u);
  EXPECT_EQ(t.robots[0].cell, "puma");
  EXPECT_EQ(t.robots[0].label, "r1");
  EXPECT_EQ(t.robots[0].carries, 1);  // Pick A
  EXPECT_EQ(t.robots[1].carries, 1);  // Get r1
  EXPECT_GE(t.robots[0].moves, 4);
  EXPECT_GE(t.robots[1].grips, 2);
  EXPECT_TRUE(t.robots[0].sim);
  EXPECT_THAT(t.workpieces, ElementsAre("A"));
  EXPECT_GT(t.signals, 0);
  EXPECT_FALSE(t.vision);
  EXPECT_EQ(command_bound(t.robots[0], "move"), 4);
  EXPECT_EQ(command_bound(t.robots[0], "grip"), std::min(t.robots[0].grips, 4));
  EXPECT_EQ(command_bound(t.robots[0], "signal"), 0);
}

TEST(CampaignTargets, TheKindsAreTheFaultSpecsKinds) {
  ASSERT_EQ(fault_kinds().size(), kFaultKinds);
  for (std::size_t i = 0; i < kFaultKinds; ++i) {
    const auto kind = fault_kind(fault_kinds()[i]);
    ASSERT_TRUE(kind) << fault_kinds()[i];
    EXPECT_EQ(static_cast<std::size_t>(*kind), i);
  }
}

TEST(CampaignTargets, KindsApplyByWhatTheScenarioHas) {
  EXPECT_THAT(applicable_kinds(exchange_targets()),
              ElementsAre("drop", "slip", "misplace", "unreachable", "missing", "obstacle", "timeout", "garbage",
                          "hardware", "position", "link_lost", "lost_signal"));
  // One arm, no hand-over: no signal to lose; vision: camera faults too.
  const CampaignTargets single = campaign_targets(load_scenario(kScenes + "/single.yaml"), 8.0);
  EXPECT_EQ(single.signals, 0);
  EXPECT_THAT(why_not_applicable("lost_signal", single), HasSubstr("fires no signal"));
  const CampaignTargets vision = campaign_targets(load_scenario(kScenes + "/vision.yaml"), 8.0);
  EXPECT_TRUE(vision.vision);
  EXPECT_EQ(why_not_applicable("frame_lost", vision), "");
  EXPECT_EQ(why_not_applicable("detection_noise", vision), "");
  // Nothing carries, nothing is on the simulation driver, no workpiece.
  CampaignTargets bare;
  bare.robots.push_back({"puma", "r1", 0, 2, 0, false});
  EXPECT_THAT(why_not_applicable("drop", bare), HasSubstr("carries"));
  EXPECT_THAT(why_not_applicable("timeout", bare), HasSubstr("simulation driver"));
  EXPECT_THAT(why_not_applicable("missing", bare), HasSubstr("no workpiece"));
  EXPECT_EQ(why_not_applicable("obstacle", bare), "");
  EXPECT_EQ(why_not_applicable("teleport", bare), "unknown fault kind");
}

TEST(CampaignTargets, CheckKindsRefusesUnknownAndInapplicableKinds) {
  const CampaignTargets t = exchange_targets();
  EXPECT_EQ(check_kinds({}, t, {"--faults", 0, 0}), applicable_kinds(t));
  EXPECT_THAT(check_kinds({"slip", "drop", "slip"}, t, {"--faults", 0, 0}), ElementsAre("slip", "drop"));
  try {
    check_kinds({"drop", "teleport"}, t, {"--faults", 0, 0});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("unknown fault kind 'teleport'"));
    EXPECT_THAT(e.what(), HasSubstr("detection_noise"));  // the known kinds are listed
    EXPECT_EQ(e.where().file, "--faults");
  }
  try {
    check_kinds({"frame_lost"}, t, {"--faults", 0, 0});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("'frame_lost' does not apply"));
    EXPECT_THAT(e.what(), HasSubstr("not vision"));
  }
  EXPECT_THROW(check_kinds({}, CampaignTargets{}, {"--faults", 0, 0}), InputError);
}

TEST(CampaignVariants, RunIIsTheSameWhateverElseIsDrawn) {
  const CampaignTargets t = exchange_targets();
  const std::vector<std::string> kinds = applicable_kinds(t);
  for (std::size_t i = 0; i < 50; ++i) {
    const Variant a = draw_variant(t, kinds, 7, i);
    const Variant b = draw_variant(t, kinds, 7, i);
    ASSERT_EQ(a.faults.size(), b.faults.size());
    EXPECT_EQ(a.seed, b.seed);
    EXPECT_EQ(a.index, i);
    for (std::size_t k = 0; k < a.faults.size(); ++k) EXPECT_EQ(a.faults[k].spec, b.faults[k].spec);
  }
  // Another campaign seed or another index gives other variants (compared over many, not one by one).
  std::set<std::string> seven, eight;
  std::set<std::uint64_t> seeds;
  for (std::size_t i = 0; i < 40; ++i) {
    seven.insert(draw_variant(t, kinds, 7, i).faults[0].spec);
    eight.insert(draw_variant(t, kinds, 8, i).faults[0].spec);
    seeds.insert(draw_variant(t, kinds, 7, i).seed);
  }
  EXPECT_NE(seven, eight);
  EXPECT_GT(seven.size(), 20u);
  EXPECT_EQ(seeds.size(), 40u);
}

TEST(CampaignVariants, OnlyRequestedKindsWithValidWhereAndWhen) {
  const CampaignTargets t = exchange_targets();
  const models::CellDescription cell = load_scenario(kScenes + "/exchange.yaml").cell;
  const std::vector<std::string> kinds = applicable_kinds(t);
  std::map<std::string, int> seen;
  int doubles = 0;
  for (std::size_t i = 0; i < 400; ++i) {
    const Variant v = draw_variant(t, kinds, 1, i);
    ASSERT_GE(v.faults.size(), 1u);
    ASSERT_LE(v.faults.size(), 2u);
    if (v.faults.size() == 2) ++doubles;
    EXPECT_GE(v.seed, 1u);
    for (const DrawnFault& f : v.faults) {
      // The fault's own parser takes it, as `twin run --fault` will.
      EXPECT_NO_THROW(parse_fault_text(f.spec, cell)) << f.spec;
      const Spec s = parse_spec(f.spec);
      EXPECT_EQ(s.kind, f.kind);
      ++seen[s.kind];
      const auto num = [&](const std::string& key) {
        EXPECT_TRUE(s.fields.count(key)) << f.spec;
        return s.fields.count(key) ? std::stod(s.fields.at(key)) : -1.0;
      };
      if (s.kind == "drop" || s.kind == "slip") {
        EXPECT_TRUE(s.fields.at("robot") == "puma" || s.fields.at("robot") == "melfa") << f.spec;
        EXPECT_EQ(num("carry"), 1.0) << f.spec;  // each arm carries one part
        EXPECT_GE(num("after"), 0.1);
        EXPECT_LE(num("after"), 0.6);
        EXPECT_EQ(s.fields.size(), 3u) << f.spec;
      } else if (s.kind == "misplace") {
        EXPECT_EQ(s.fields.at("workpiece"), "A");
        const std::string offset = s.fields.at("offset");
        const auto slash = offset.find('/');
        ASSERT_NE(slash, std::string::npos) << f.spec;
        // Along the belt up to 2 cm, to the side 2.5 to 4 cm (what a belt's stop does not straighten), turned up to
        // 20 degrees.
        const double along = std::stod(offset.substr(0, slash)), side = std::stod(offset.substr(slash + 1));
        EXPECT_GE(along, 0.0) << f.spec;
        EXPECT_LE(along, 0.02) << f.spec;
        EXPECT_GE(side, 0.025 - 1e-9) << f.spec;
        EXPECT_LE(side, 0.04) << f.spec;
        EXPECT_GE(num("yaw"), 0.0);
        EXPECT_LE(num("yaw"), 20.0);
      } else if (s.kind == "unreachable" || s.kind == "missing") {
        EXPECT_EQ(s.fields.size(), 1u);
        EXPECT_EQ(s.fields.at("workpiece"), "A");
      } else if (s.kind == "obstacle") {
        EXPECT_GE(num("time"), 0.05 * 14.0 - 1e-9);
        EXPECT_LE(num("time"), 0.85 * 14.0);
      } else if (s.kind == "lost_signal") {
        EXPECT_GE(num("n"), 1.0);
        EXPECT_LE(num("n"), std::min(t.signals, 4));
      } else {
        ASSERT_TRUE(s.kind == "timeout" || s.kind == "garbage" || s.kind == "hardware" || s.kind == "position" ||
                    s.kind == "link_lost")
            << f.spec;
        const std::string command = s.fields.at("command");
        EXPECT_TRUE(command == "move" || command == "grip") << f.spec;
        const auto& robot = s.fields.at("robot") == "puma" ? t.robots[0] : t.robots[1];
        EXPECT_GE(num("n"), 1.0);
        EXPECT_LE(num("n"), command_bound(robot, command)) << f.spec;
      }
    }
  }
  // Every applicable kind comes up; about one run in eight has two faults.
  for (const std::string& k : kinds) EXPECT_GT(seen[k], 5) << k;
  EXPECT_EQ(seen.count("frame_lost"), 0u);
  EXPECT_GT(doubles, 20);
  EXPECT_LT(doubles, 90);
  // Asked for drops only, only drops come.
  for (std::size_t i = 0; i < 50; ++i) {
    for (const DrawnFault& f : draw_variant(t, {"drop"}, 3, i).faults) EXPECT_EQ(f.kind, "drop");
  }
}

TEST(CampaignVariants, CameraFaultsComeAtAMomentWithinTheCycle) {
  const Scenario vision = load_scenario(kScenes + "/vision.yaml");
  const CampaignTargets t = campaign_targets(vision, 10.0);
  for (std::size_t i = 0; i < 30; ++i) {
    const std::string spec = draw_variant(t, {"frame_lost", "detection_noise"}, 5, i).faults[0].spec;
    EXPECT_NO_THROW(parse_fault_text(spec, vision.cell)) << spec;
    const Spec s = parse_spec(spec);
    EXPECT_GE(std::stod(s.fields.at("time")), 0.5 - 1e-9);
    EXPECT_LE(std::stod(s.fields.at("time")), 8.5);
    if (s.kind == "frame_lost") {
      EXPECT_GE(std::stoi(s.fields.at("count")), 1);
      EXPECT_LE(std::stoi(s.fields.at("count")), 3);
    } else {
      EXPECT_GE(std::stod(s.fields.at("duration")), 1.0);
    }
  }
}

// --- Adding up -------------------------------------------------------------------------------------------------------

using test_reports::fault_report;
using test_reports::part_report;
using test_reports::run_report;

// A record of a run that drew `specs` (kind:...) and whose report is `report`.
RunRecord record(std::size_t index, const std::vector<std::string>& specs, RunStatus status,
                 std::optional<Report> report) {
  RunRecord r;
  r.variant.index = index;
  r.variant.seed = 100 + index;
  for (const std::string& s : specs) r.variant.faults.push_back({s.substr(0, s.find(':')), s});
  r.status = status;
  r.exit_code = status == RunStatus::kDone ? 0 : -1;
  r.report = std::move(report);
  if (status == RunStatus::kCrash) r.problem = std::string("killed by signal 11 (Segmentation fault)");
  if (status == RunStatus::kHang) r.problem = std::string("still running after 5 s: killed");
  return r;
}

// A finished run's report with these faults, `failures` (none: ok) and parts.
Report report_of(std::vector<FaultReport> faults, std::vector<std::string> failures = {},
                 std::vector<WorkpieceReport> parts = {}) {
  Report r = run_report(std::move(failures));
  r.faults = std::move(faults);
  r.workpieces = std::move(parts);
  return r;
}

std::vector<RunRecord> fabricated_runs() {
  std::vector<RunRecord> runs;
  // Two drops recovered in 2 s and 4 s (the second's part declared lost); a drop that lost the part unaccounted; a
  // timeout stopped safely with a false alarm before it; a run with a drop and a timeout, both recovered; a crash and
  // a hang of timeouts.
  runs.push_back(record(0, {"drop:robot=puma"}, RunStatus::kDone, report_of({fault_report("drop", true, 2.0)})));
  runs.push_back(
      record(1, {"drop:robot=melfa"}, RunStatus::kDone,
             report_of({fault_report("drop", true, 4.0)}, {}, {part_report("A", true), part_report("B", false)})));
  runs.push_back(record(2, {"drop:robot=puma"}, RunStatus::kDone,
                        report_of({fault_report("drop", false, std::nullopt)}, {"workpiece A is elsewhere"},
                                  {part_report("A", false, true)})));
  Report stopped = report_of({fault_report("timeout", true, std::nullopt, true)}, {"the cell was stopped"});
  stopped.outcome = "stopped";
  stopped.false_alarms.push_back(Detection{0.5, "r1", 2, "grip_lost", "", "grip_lost", "regrasp", false, "a part is between its fingers"});
  runs.push_back(record(3, {"timeout:robot=puma"}, RunStatus::kDone, stopped));
  runs.push_back(record(4, {"drop:robot=puma", "timeout:robot=melfa"}, RunStatus::kDone,
                        report_of({fault_report("drop", true, 3.0), fault_report("timeout", true, 1.0)})));
  runs.push_back(record(5, {"timeout:robot=puma"}, RunStatus::kCrash, std::nullopt));
  runs.push_back(record(6, {"timeout:robot=melfa"}, RunStatus::kHang, std::nullopt));
  return runs;
}

TEST(CampaignAggregate, CountsPerKindAndInAll) {
  const CampaignSummary s = aggregate(fabricated_runs(), {"drop", "timeout"}, "exchange.yaml", 1);
  ASSERT_EQ(s.kinds.size(), 2u);
  const KindSummary& drop = s.kinds[0];
  EXPECT_EQ(drop.kind, "drop");
  EXPECT_EQ(drop.runs, 4u);
  EXPECT_EQ(drop.injected, 4u);
  EXPECT_EQ(drop.detected, 3u);
  EXPECT_EQ(drop.recovered, 3u);
  EXPECT_EQ(drop.stopped_safely, 0u);
  EXPECT_EQ(drop.unaccounted, 1u);
  EXPECT_EQ(drop.lost, 1u);
  EXPECT_EQ(drop.ok_runs, 3u);
  ASSERT_TRUE(drop.mean_recovery_time);
  EXPECT_DOUBLE_EQ(*drop.mean_recovery_time, 3.0);
  const KindSummary& timeout = s.kinds[1];
  EXPECT_EQ(timeout.runs, 4u);
  EXPECT_EQ(timeout.injected, 2u);
  EXPECT_EQ(timeout.detected, 2u);
  EXPECT_EQ(timeout.recovered, 1u);
  EXPECT_EQ(timeout.stopped_safely, 1u);
  EXPECT_EQ(timeout.false_alarms, 1u);
  EXPECT_EQ(timeout.crashes, 1u);
  EXPECT_EQ(timeout.hangs, 1u);
  EXPECT_DOUBLE_EQ(*timeout.mean_recovery_time, 1.0);
  EXPECT_EQ(s.total.kind, "all");
  EXPECT_EQ(s.total.runs, 7u);
  EXPECT_EQ(s.total.injected, 6u);
  EXPECT_EQ(s.total.recovered, 4u);
  EXPECT_EQ(s.total.crashes, 1u);
  EXPECT_EQ(s.total.hangs, 1u);
  EXPECT_EQ(s.total.false_alarms, 1u);
  EXPECT_DOUBLE_EQ(*s.total.mean_recovery_time, 2.5);
}

TEST(CampaignAggregate, AFaultOfAKindNotAskedForGetsItsOwnRow) {
  std::vector<RunRecord> runs;
  runs.push_back(record(0, {"drop:robot=puma"}, RunStatus::kDone,
                        report_of({fault_report("drop", true, 1.0), fault_report("obstacle", false, std::nullopt)})));
  const CampaignSummary s = aggregate(runs, {"drop"}, "x.yaml", 1);
  ASSERT_EQ(s.kinds.size(), 2u);
  EXPECT_EQ(s.kinds[1].kind, "obstacle");
  EXPECT_EQ(s.kinds[1].injected, 1u);
  EXPECT_EQ(s.kinds[1].runs, 0u);  // no run drew it
  EXPECT_FALSE(s.kinds[1].mean_recovery_time);
}

// A run that ends at its time limit is a stall: a failure, and a fault of it is not recovered, even when its recovery
// ended well before the run sat idle until the limit (a relay whose part was set aside upstream).
TEST(CampaignAggregate, AStalledRunIsAFailureAndItsFaultIsNotRecovered) {
  const std::string limit = "the simulation time limit of 150 s was reached before the program finished";
  auto stalled_run = [&](std::vector<FaultReport> faults) {
    Report r = report_of(std::move(faults), {"run outcome timeout: " + limit});
    r.outcome = "timeout";
    r.reason = limit;
    r.end_time = 150;
    return r;
  };
  std::vector<RunRecord> runs;
  runs.push_back(record(0, {"drop:robot=r1"}, RunStatus::kDone, report_of({fault_report("drop", true, 2.0)})));
  runs.push_back(record(1, {"drop:robot=r2"}, RunStatus::kDone, stalled_run({fault_report("drop", true, 3.0)})));
  runs.push_back(record(2, {"drop:robot=r1", "timeout:robot=r3"}, RunStatus::kDone,
                        stalled_run({fault_report("drop", false, std::nullopt), fault_report("timeout", true, 1.0)})));
  EXPECT_FALSE(stalled(*runs[0].report));
  EXPECT_TRUE(stalled(*runs[1].report));

  const CampaignSummary s = aggregate(runs, {"drop", "timeout"}, "relay.yaml", 1);
  const KindSummary& drop = s.kinds[0];
  EXPECT_EQ(drop.runs, 3u);
  EXPECT_EQ(drop.injected, 3u);
  EXPECT_EQ(drop.detected, 2u);
  EXPECT_EQ(drop.recovered, 1u);  // run 0's; run 1's recovery was followed by a stall
  EXPECT_EQ(drop.stalls, 2u);
  EXPECT_EQ(drop.ok_runs, 1u);
  ASSERT_TRUE(drop.mean_recovery_time);
  EXPECT_DOUBLE_EQ(*drop.mean_recovery_time, 2.0);  // the stalled run's 3 s left out
  const KindSummary& timeout = s.kinds[1];
  EXPECT_EQ(timeout.detected, 1u);
  EXPECT_EQ(timeout.recovered, 0u);
  EXPECT_EQ(timeout.stalls, 1u);
  EXPECT_FALSE(timeout.mean_recovery_time);
  EXPECT_EQ(s.total.stalls, 2u);
  EXPECT_EQ(s.total.recovered, 1u);

  EXPECT_THAT(format_csv(s), HasSubstr("\ndrop,3,3,2,1,0,0,0,0,0,0,0,2,1,2.0000\n"));
  EXPECT_THAT(format_csv(s), HasSubstr("\nall,3,4,3,1,0,0,0,0,0,0,0,2,1,2.0000\n"));
  const std::string md = format_markdown(s, runs);
  EXPECT_THAT(md, HasSubstr("1 of 3 runs ok; 4 faults injected, 3 detected, 1 recovered, 0 stopped safely; 2 runs "
                            "stalled; 0 unexplained faults, 0 false alarms."));
  EXPECT_THAT(md, HasSubstr("| timeout | 1 | 1 | 1 | 0 | 0 | 0 | 0 | 0 | 0 | 0 | 0 | 1 | - |"));
  EXPECT_THAT(md, HasSubstr("\nRuns that stalled:\n\n- run 0001 (seed 101, drop:robot=r2): timeout at 150.00 s: " +
                            limit + "; recovered before the stall, not counted: drop at 4.00 s\n"));
  EXPECT_THAT(md, HasSubstr("- run 0002 (seed 102, drop:robot=r1 + timeout:robot=r3): timeout at 150.00 s: " + limit +
                            "; recovered before the stall, not counted: timeout at 2.00 s\n"));
  // The chart has a bar of stalled runs (black) in each kind's group.
  const cv::Mat img = draw_campaign(s, 1200, 600);
  int black = 0;
  for (int y = 80; y < 465; ++y) {
    for (int x = 82; x < 1165; ++x) black += img.at<cv::Vec3b>(y, x) == cv::Vec3b(0, 0, 0) ? 1 : 0;
  }
  EXPECT_GT(black, 1000);
}

// A detection no injection explains is a real fault the campaign did not ask for (on real robots, every fault is one):
// counted as an unexplained fault under each kind its run drew, apart from the false alarms, in every output.
TEST(CampaignAggregate, UnexplainedFaultsAreCountedApartFromFalseAlarms) {
  std::vector<RunRecord> runs;
  Report blocked = report_of({fault_report("drop", true, 2.0)});
  blocked.unexplained.push_back(
      Detection{7.5, "r2", 4, "motion_blocked", "short of its goal", "obstruction", "retry", true, ""});
  blocked.unexplained.push_back(
      Detection{9.0, "r2", 6, "no_progress", "stopped 5 times", "livelock", "stop_cell", false, ""});
  runs.push_back(record(0, {"drop:robot=r1"}, RunStatus::kDone, blocked));
  Report alarm = report_of({fault_report("timeout", true, 1.0)});
  alarm.false_alarms.push_back(
      Detection{3.0, "r1", 2, "grip_lost", "", "dropped", "regrasp", true, "A between the fingers of r1"});
  runs.push_back(record(1, {"timeout:robot=r1"}, RunStatus::kDone, alarm));

  const CampaignSummary s = aggregate(runs, {"drop", "timeout"}, "relay.yaml", 1);
  EXPECT_EQ(s.kinds[0].unexplained, 2u);
  EXPECT_EQ(s.kinds[0].false_alarms, 0u);
  EXPECT_EQ(s.kinds[1].unexplained, 0u);
  EXPECT_EQ(s.kinds[1].false_alarms, 1u);
  EXPECT_EQ(s.total.unexplained, 2u);
  EXPECT_EQ(s.total.false_alarms, 1u);
  EXPECT_THAT(format_csv(s), HasSubstr("\ndrop,1,1,1,1,0,0,0,0,2,0,0,0,1,2.0000\n"));
  EXPECT_THAT(format_csv(s), HasSubstr("\nall,2,2,2,2,0,0,0,1,2,0,0,0,2,1.5000\n"));
  const std::string md = format_markdown(s, runs);
  EXPECT_THAT(md, HasSubstr("2 unexplained faults, 1 false alarm."));
  EXPECT_THAT(md, HasSubstr("| drop | 1 | 1 | 1 | 1 | 0 | 0 | 0 | 0 | 2 | 0 | 0 | 0 | 2.00 |"));
}

TEST(CampaignAggregate, CsvMarkdownAndChart) {
  const std::vector<RunRecord> runs = fabricated_runs();
  const CampaignSummary s = aggregate(runs, {"drop", "timeout"}, "exchange.yaml", 1);
  const std::string csv = format_csv(s);
  EXPECT_THAT(csv, HasSubstr("kind,runs,injected,detected,recovered,stopped_safely,lost,unaccounted,false_alarms,"
                             "unexplained,crashes,hangs,stalls,ok_runs,mean_recovery_time_s\n"));
  EXPECT_THAT(csv, HasSubstr("\ndrop,4,4,3,3,0,1,1,0,0,0,0,0,3,3.0000\n"));
  EXPECT_THAT(csv, HasSubstr("\ntimeout,4,2,2,1,1,0,0,1,0,1,1,0,1,1.0000\n"));
  EXPECT_THAT(csv, HasSubstr("\nall,7,6,5,4,1,1,1,1,0,1,1,0,3,2.5000\n"));
  const std::string md = format_markdown(s, runs);
  EXPECT_THAT(md, HasSubstr("# Fault campaign: exchange.yaml, 7 runs, seed 1"));
  EXPECT_THAT(md, HasSubstr("| drop | 4 | 4 | 3 | 3 | 0 | 1 | 1 | 0 | 0 | 0 | 0 | 0 | 3.00 |"));
  EXPECT_THAT(md, HasSubstr("| **all** | 7 | 6 | 5 | 4 | 1 | 1 | 1 | 1 | 0 | 1 | 1 | 0 | 2.50 |"));
  EXPECT_THAT(md, HasSubstr("- run 0005 (seed 105, timeout:robot=puma): crash: killed by signal 11"));
  EXPECT_THAT(md, HasSubstr("- run 0006 (seed 106, timeout:robot=melfa): hang:"));
  const std::string runs_csv = format_runs_csv(runs);
  EXPECT_THAT(runs_csv, HasSubstr("4,104,done,0,finished,ok,0,drop:robot=puma + timeout:robot=melfa,\n"));
  EXPECT_THAT(runs_csv, HasSubstr("2,102,done,0,finished,failed,1,drop:robot=puma,\n"));
  EXPECT_THAT(runs_csv, HasSubstr("5,105,crash,-1,,,,timeout:robot=puma,killed by signal 11"));

  const cv::Mat img = draw_campaign(s, 1200, 600);
  ASSERT_EQ(img.type(), CV_8UC3);
  EXPECT_EQ(img.cols, 1200);
  EXPECT_EQ(img.rows, 600);
  // Something was drawn in each kind's half of the plot (bars are not white).
  const auto coloured = [&](int x_from, int x_to) {
    int n = 0;
    for (int y = 60; y < 470; ++y) {
      for (int x = x_from; x < x_to; ++x) {
        const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
        if (c[0] != c[1] || c[1] != c[2]) ++n;  // a coloured (not grey) pixel: a bar
      }
    }
    return n;
  };
  EXPECT_GT(coloured(80, 620), 500);
  EXPECT_GT(coloured(640, 1170), 500);

  Scratch scratch("write");
  write_campaign(scratch.dir() / "out", s, runs);
  EXPECT_EQ(slurp(scratch.dir() / "out" / "campaign.csv"), csv);
  EXPECT_EQ(slurp(scratch.dir() / "out" / "campaign.md"), md);
  EXPECT_EQ(slurp(scratch.dir() / "out" / "runs.csv"), runs_csv);
  EXPECT_FALSE(cv::imread((scratch.dir() / "out" / "campaign.png").string()).empty());
}

TEST(CampaignProgressBar, ShowsTheShareDone) {
  CampaignProgress p;
  p.total = 10;
  p.done = 5;
  p.running = 2;
  p.crashes = 1;
  EXPECT_EQ(format_progress(p, 10), "[#####.....] 5/10 runs, 2 running, 1 crash, 0 hangs, 0 stalls");
  p.stalls = 3;
  EXPECT_EQ(format_progress(p, 10), "[#####.....] 5/10 runs, 2 running, 1 crash, 0 hangs, 3 stalls");
}

// --- Running -----------------------------------------------------------------------------------------------------

// A stand-in for `twin` in `dir`: a shell script that records its arguments in the run directory (its last
// argument) and then does `body`.
fs::path fake_twin(const fs::path& dir, const std::string& body) {
  const fs::path p = dir / "fake-twin.sh";
  std::ofstream(p) << "#!/bin/sh\nfor a; do out=\"$a\"; done\necho \"$@\" > \"$out/args.txt\"\n" << body << "\n";
  fs::permissions(p, fs::perms::owner_all);
  return p;
}

// A line of the stand-in (fake_twin in `dir`) that writes a whole report.json of a finished run into its directory,
// copied from beside it.
std::string copy_report(const fs::path& dir) {
  test_reports::write_report(dir / "report.full", run_report());
  return "cp \"$(dirname \"$0\")/report.full\" \"$out/report.json\"";
}

CampaignOptions fake_options(const fs::path& dir, const fs::path& exe, std::size_t runs) {
  CampaignOptions o;
  o.scenario = kScenes + "/exchange.yaml";
  o.out = dir / "campaign";
  o.executable = exe;
  o.runs = runs;
  o.seed = 3;
  o.jobs = 2;
  o.timeout = 30;
  o.targets = exchange_targets();
  o.kinds = {"drop", "timeout"};
  return o;
}

TEST(CampaignRun, ChildrenGetTheirFaultsSeedAndDirectory) {
  Scratch scratch("run");
  const fs::path exe =
      fake_twin(scratch.dir(), "echo running\necho 'some warning' >&2\n" + copy_report(scratch.dir()) + "\nexit 0");
  const CampaignOptions o = fake_options(scratch.dir(), exe, 5);
  std::vector<CampaignProgress> progress;
  const std::vector<RunRecord> runs = run_campaign(o, [&](const CampaignProgress& p) { progress.push_back(p); });
  ASSERT_EQ(runs.size(), 5u);
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const RunRecord& r = runs[i];
    EXPECT_EQ(r.variant.index, i);
    EXPECT_EQ(r.status, RunStatus::kDone) << r.problem;
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_EQ(r.dir, o.out / "runs" / fmt::format("{:04}", i));
    ASSERT_TRUE(r.report);
    EXPECT_TRUE(r.report->ok());
    const Variant v = draw_variant(o.targets, o.kinds, o.seed, i);
    std::string expected = "run " + o.scenario.string();
    for (const DrawnFault& f : v.faults) expected += " --fault " + f.spec;
    expected += fmt::format(" --seed {} --quiet --final-png never -o {}\n", v.seed, r.dir.string());
    EXPECT_EQ(slurp(r.dir / "args.txt"), expected);
    EXPECT_EQ(slurp(r.dir / "stdout.txt"), "running\n");
    EXPECT_EQ(slurp(r.dir / "stderr.txt"), "some warning\n");
  }
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back().done, 5u);
  EXPECT_EQ(progress.back().running, 0u);
  for (const CampaignProgress& p : progress) EXPECT_LE(p.running, 2u);
}

TEST(CampaignRun, ACrashAHangAndAMissingReportAreRecorded) {
  Scratch scratch("bad");
  {
    const fs::path exe = fake_twin(scratch.dir(), "kill -SEGV $$");
    const std::vector<RunRecord> runs = run_campaign(fake_options(scratch.dir(), exe, 2));
    for (const RunRecord& r : runs) {
      EXPECT_EQ(r.status, RunStatus::kCrash);
      EXPECT_EQ(r.signal, SIGSEGV);
      EXPECT_THAT(r.problem, HasSubstr("killed by signal 11"));
    }
  }
  {
    const fs::path exe = fake_twin(scratch.dir(), "echo 'bad --fault text' >&2\nexit 2");
    const std::vector<RunRecord> runs = run_campaign(fake_options(scratch.dir(), exe, 1));
    EXPECT_EQ(runs[0].status, RunStatus::kCrash);
    EXPECT_EQ(runs[0].exit_code, 2);
    EXPECT_EQ(runs[0].problem, "exit 2 without report.json: bad --fault text");
  }
  {
    const fs::path exe = fake_twin(scratch.dir(), "exec sleep 20");
    CampaignOptions o = fake_options(scratch.dir(), exe, 2);
    o.timeout = 0.3;
    const auto start = std::chrono::steady_clock::now();
    const std::vector<RunRecord> runs = run_campaign(o);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
    for (const RunRecord& r : runs) {
      EXPECT_EQ(r.status, RunStatus::kHang);
      EXPECT_THAT(r.problem, HasSubstr("killed"));
      EXPECT_FALSE(r.report);
    }
  }
}

TEST(CampaignRun, ACampaignOfOneJobRunsOneAtATimeAndTheSameVariants) {
  Scratch scratch("serial");
  const fs::path exe = fake_twin(scratch.dir(), copy_report(scratch.dir()));
  CampaignOptions o = fake_options(scratch.dir(), exe, 3);
  o.jobs = 1;
  std::size_t most = 0;
  const std::vector<RunRecord> one =
      run_campaign(o, [&](const CampaignProgress& p) { most = std::max(most, p.running); });
  EXPECT_EQ(most, 1u);
  o.runs = 6;
  o.jobs = 3;
  const std::vector<RunRecord> more = run_campaign(o);
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].variant.seed, more[i].variant.seed);
    EXPECT_EQ(one[i].variant.faults.front().spec, more[i].variant.faults.front().spec);
  }
}

// --- Planning ----------------------------------------------------------------------------------------------------

TEST(CampaignPlan, BadInputIsRefusedAndNothingIsWritten) {
  Scratch scratch("plan");
  const fs::path out = scratch.dir() / "out";
  const std::string scenario = kScenes + "/exchange.yaml";
  auto refused = [&](auto&& f, const std::string& what) {
    try {
      f();
      ADD_FAILURE() << "not refused: " << what;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(what));
    }
    EXPECT_FALSE(fs::exists(out));
  };
  refused([&] { plan_campaign(scenario, {}, 0, 1, 0, 600, out, "/bin/true", twin_port()); }, "at least one run");
  refused([&] { plan_campaign(scenario, {}, 2, 1, 0, 0, out, "/bin/true", twin_port()); }, "must be > 0");
  refused([&] { plan_campaign(scenario, {"teleport"}, 2, 1, 0, 600, out, "/bin/true", twin_port()); }, "unknown fault kind");
  refused([&] { plan_campaign(scenario, {"frame_lost"}, 2, 1, 0, 600, out, "/bin/true", twin_port()); }, "does not apply");
  refused([&] { plan_campaign(kScenes + "/nonexistent.yaml", {}, 2, 1, 0, 600, out, "/bin/true", twin_port()); }, "");
  // An output directory that cannot be made: its parent is a file.
  std::ofstream(scratch.dir() / "file") << "x";
  try {
    plan_campaign(scenario, {}, 2, 1, 0, 600, scratch.dir() / "file" / "out", "/bin/true", twin_port());
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("is not a directory"));
  }
  EXPECT_THROW(check_writable_dir(scratch.dir() / "file"), InputError);
  EXPECT_NO_THROW(check_writable_dir(scratch.dir() / "a" / "b"));
  EXPECT_FALSE(fs::exists(scratch.dir() / "a"));
}

TEST(CampaignPlan, TheExchangeIsPlannedWithItsEstimatedCycle) {
  Scratch scratch("plan-ok");
  const CampaignOptions o =
      plan_campaign(kScenes + "/exchange.yaml", {"drop"}, 3, 9, 0, 60, scratch.dir() / "out", "/bin/true", twin_port());
  EXPECT_GT(o.targets.cycle_time, 1.0);
  EXPECT_THAT(o.kinds, ElementsAre("drop"));
  EXPECT_EQ(o.runs, 3u);
  EXPECT_GE(o.jobs, 1u);
  EXPECT_TRUE(o.scenario.is_absolute());
  EXPECT_FALSE(fs::exists(scratch.dir() / "out"));  // planning writes nothing
}

}  // namespace
}  // namespace cellwright::cell
