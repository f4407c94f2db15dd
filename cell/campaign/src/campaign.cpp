// A fault campaign: variants, child processes, the account (campaign.hpp).
#include "cellwright/cell/campaign.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/vision/png.hpp"
#include "cellwright/cell/gantt.hpp"
#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/preflight.hpp"

namespace cellwright::cell {

// The names a campaign writes into its directory (campaign_output_files).
namespace {
constexpr const char* kCampaignCsv = "campaign.csv";
constexpr const char* kRunsCsv = "runs.csv";
constexpr const char* kCampaignMd = "campaign.md";
constexpr const char* kCampaignPng = "campaign.png";
constexpr const char* kRunsDir = "runs";
}  // namespace

const std::vector<std::string>& fault_kinds() {
  static const std::vector<std::string> kinds = {
      "drop",     "slip",     "misplace", "unreachable", "missing",     "obstacle",   "timeout",
      "garbage",  "hardware", "position", "link_lost",   "lost_signal", "frame_lost", "detection_noise"};
  return kinds;
}

namespace {

bool is_driver_kind(const std::string& kind) {
  return kind == "timeout" || kind == "garbage" || kind == "hardware" || kind == "position" || kind == "link_lost";
}

}  // namespace

CampaignTargets campaign_targets(const Scenario& s, double cycle_time) {
  CampaignTargets t;
  t.cycle_time = cycle_time;
  t.vision = s.perception == runtime::Perception::kVision;
  for (std::size_t r = 0; r < s.program.robots.size(); ++r) {
    CampaignTargets::Robot robot;
    robot.label = s.program.robots[r];
    robot.cell = s.robot_of(robot.label);
    for (const task::Primitive& p : s.program.programs[r].primitives) {
      switch (p.kind) {
        case task::PrimitiveKind::kMove:
          ++robot.moves;
          break;
        case task::PrimitiveKind::kClose:
          ++robot.grips;
          if (!p.workpiece.empty()) ++robot.carries;
          break;
        case task::PrimitiveKind::kOpen:
          ++robot.grips;
          break;
        case task::PrimitiveKind::kSignal:
          ++t.signals;
          break;
        case task::PrimitiveKind::kWait:
        case task::PrimitiveKind::kLoop:
        case task::PrimitiveKind::kDevice:
          break;
      }
    }
    for (const DriverChoice& d : s.drivers) {
      if (d.robot == robot.cell) robot.sim = !d.real();
    }
    t.robots.push_back(std::move(robot));
  }
  for (const Binding& b : s.workpieces) t.workpieces.push_back(b.name);
  return t;
}

std::string why_not_applicable(const std::string& kind, const CampaignTargets& t) {
  const auto any_robot = [&](auto pred) { return std::any_of(t.robots.begin(), t.robots.end(), pred); };
  if (kind == "drop" || kind == "slip") {
    return any_robot([](const auto& r) { return r.carries > 0; }) ? "" : "no robot of the program carries a part";
  }
  if (kind == "misplace" || kind == "unreachable" || kind == "missing") {
    return t.workpieces.empty() ? "the program uses no workpiece" : "";
  }
  if (kind == "obstacle") return t.robots.empty() ? "the program has no robot" : "";
  if (is_driver_kind(kind)) {
    return any_robot([](const auto& r) { return r.sim && r.moves + r.grips > 0; })
               ? ""
               : "no robot of the program is on the simulation driver";
  }
  if (kind == "lost_signal") return t.signals > 0 ? "" : "the program fires no signal";
  if (kind == "frame_lost" || kind == "detection_noise") {
    return t.vision ? "" : "the scenario's perception is not vision (no camera frames)";
  }
  return "unknown fault kind";
}

std::vector<std::string> applicable_kinds(const CampaignTargets& t) {
  std::vector<std::string> out;
  for (const std::string& k : fault_kinds()) {
    if (why_not_applicable(k, t).empty()) out.push_back(k);
  }
  return out;
}

std::vector<std::string> check_kinds(const std::vector<std::string>& requested, const CampaignTargets& t,
                                     const SourceLocation& where) {
  if (requested.empty()) {
    std::vector<std::string> all = applicable_kinds(t);
    if (all.empty()) throw InputError(where, "no fault kind applies to this scenario");
    return all;
  }
  std::vector<std::string> out;
  for (const std::string& k : requested) {
    const auto& known = fault_kinds();
    if (std::find(known.begin(), known.end(), k) == known.end()) {
      throw InputError(where, fmt::format("unknown fault kind '{}'; the kinds are: {}", k, fmt::join(known, ", ")));
    }
    const std::string why = why_not_applicable(k, t);
    if (!why.empty()) {
      throw InputError(where, fmt::format("fault kind '{}' does not apply to this scenario: {}", k, why));
    }
    if (std::find(out.begin(), out.end(), k) == out.end()) out.push_back(k);
  }
  return out;
}

int command_bound(const CampaignTargets::Robot& robot, const std::string& command) {
  const int count = command == "move" ? robot.moves : command == "grip" ? robot.grips : 0;
  return std::min(count, 4);
}

namespace {

// Draws from the campaign's generator without the standard distributions (whose results differ between standard
// libraries): the same (seed, index) gives the same variant everywhere.
class Draw {
 public:
  Draw(std::uint64_t seed, std::size_t index) {
    const auto i = static_cast<std::uint64_t>(index);
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                      static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(i >> 32), 0x63616d70u};
    rng_.seed(seq);
  }
  std::uint64_t raw() { return rng_(); }
  // In [0, n); n > 0.
  std::size_t below(std::size_t n) { return static_cast<std::size_t>(rng_() % n); }
  // In [lo, hi], integers.
  int between(int lo, int hi) { return lo + static_cast<int>(below(static_cast<std::size_t>(hi - lo + 1))); }
  // In [lo, hi).
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(rng_() >> 11) * 0x1.0p-53;
  }
  template <typename T>
  const T& pick(const std::vector<T>& v) {
    return v[below(v.size())];
  }

 private:
  std::mt19937_64 rng_;
};

// A number as the --fault text writes it: at most `decimals` decimals, no trailing zeros.
std::string num(double x, int decimals) {
  std::string s = fmt::format("{:.{}f}", x, decimals);
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") return std::string("0");
  return s;
}

// A moment within the estimated cycle.
double moment(Draw& d, const CampaignTargets& t) {
  return t.cycle_time > 0 ? d.uniform(0.05, 0.85) * t.cycle_time : d.uniform(1, 10);
}

DrawnFault draw_fault(Draw& d, const CampaignTargets& t, const std::string& kind) {
  DrawnFault f;
  f.kind = kind;
  if (kind == "drop" || kind == "slip") {
    std::vector<const CampaignTargets::Robot*> carriers;
    for (const auto& r : t.robots) {
      if (r.carries > 0) carriers.push_back(&r);
    }
    CW_CHECK(!carriers.empty(), "fault kind {} without a robot that carries", kind);
    const auto* r = d.pick(carriers);
    f.spec = fmt::format("{}:robot={},carry={},after={}", kind, r->cell, d.between(1, r->carries),
                         num(d.uniform(0.1, 0.6), 2));
  } else if (kind == "misplace") {
    const std::string& w = d.pick(t.workpieces);
    // Amounts only: the injection draws the sides from the run's seed. Off to the side by more than the controller
    // takes for a part in its place (2 cm) and than the nominal grasp tolerates; turned by up to 20 degrees (a belt's
    // stop straightens a turned part again; docs/faults.md).
    const double x = d.uniform(0.0, 0.02), y = d.uniform(0.025, 0.04);
    const double yaw = d.uniform(0, 20);
    f.spec = fmt::format("misplace:workpiece={},offset={}/{},yaw={}", w, num(x, 3), num(y, 3), num(yaw, 1));
  } else if (kind == "unreachable" || kind == "missing") {
    f.spec = fmt::format("{}:workpiece={}", kind, d.pick(t.workpieces));
  } else if (kind == "obstacle") {
    const auto& r = d.pick(t.robots);
    f.spec = fmt::format("obstacle:robot={},time={}", r.cell, num(moment(d, t), 2));
  } else if (is_driver_kind(kind)) {
    // A (robot, command) pair its program certainly sends.
    std::vector<std::pair<const CampaignTargets::Robot*, std::string>> choices;
    for (const auto& r : t.robots) {
      if (!r.sim) continue;
      for (const char* c : {"move", "grip"}) {
        if (command_bound(r, c) > 0) choices.emplace_back(&r, c);
      }
    }
    CW_CHECK(!choices.empty(), "fault kind {} without a robot on the simulation driver", kind);
    const auto& [r, command] = d.pick(choices);
    f.spec = fmt::format("{}:robot={},command={},n={}", kind, r->cell, command, d.between(1, command_bound(*r, command)));
  } else if (kind == "lost_signal") {
    CW_CHECK(t.signals > 0, "lost_signal without signals");
    f.spec = fmt::format("lost_signal:n={}", d.between(1, std::min(t.signals, 4)));
  } else if (kind == "frame_lost") {
    f.spec = fmt::format("frame_lost:time={},count={}", num(moment(d, t), 2), d.between(1, 3));
  } else if (kind == "detection_noise") {
    f.spec = fmt::format("detection_noise:time={},duration={}", num(moment(d, t), 2), num(d.uniform(1, 4), 1));
  } else {
    CW_CHECK(false, "draw_fault: unknown kind {}", kind);
  }
  return f;
}

}  // namespace

Variant draw_variant(const CampaignTargets& t, const std::vector<std::string>& kinds, std::uint64_t seed,
                     std::size_t index) {
  CW_CHECK(!kinds.empty(), "draw_variant without kinds");
  Draw d(seed, index);
  Variant v;
  v.index = index;
  v.seed = 1 + d.raw() % 1000000000ULL;
  v.faults.push_back(draw_fault(d, t, d.pick(kinds)));
  if (d.below(8) == 0) {
    DrawnFault second = draw_fault(d, t, d.pick(kinds));
    if (second.spec != v.faults.front().spec) v.faults.push_back(std::move(second));
  }
  return v;
}

// --- Planning --------------------------------------------------------------------------------------------------------

CampaignOptions plan_campaign(const std::filesystem::path& scenario, const std::vector<std::string>& kinds,
                              long long runs, std::uint64_t seed, unsigned jobs, double timeout,
                              const std::filesystem::path& out, const std::filesystem::path& executable,
                              const TwinPort& twin) {
  if (runs < 1) throw InputError({"--runs", 0, 0}, fmt::format("a campaign needs at least one run, not {}", runs));
  if (!(timeout > 0)) throw InputError({"--timeout", 0, 0}, fmt::format("must be > 0 s, not {}", timeout));
  const Scenario s = load_scenario(scenario);
  for (const DriverChoice& d : s.drivers) {
    const bool used = std::any_of(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.name == d.robot; });
    if (used && d.real()) {
      throw InputError(d.where, fmt::format("robot '{}' is on the real {} driver: a campaign runs the twin only",
                                            d.robot, to_string(d.kind)));
    }
  }
  const Preflight pre = preflight(s, &twin);
  if (!pre.ok()) {
    std::string why;
    for (const std::string& p : pre.problems) why += "\n  " + p;
    throw InputError({s.source.string(), 0, 0}, fmt::format("the scenario is refused, nothing was run:{}", why));
  }
  const double cycle_time = twin.estimate(s, pre).cycle_time;  // the preflight's plan on the cell it compiled: no run
  CampaignOptions o;
  o.targets = campaign_targets(s, cycle_time);
  o.kinds = check_kinds(kinds, o.targets, {"--faults", 0, 0});
  check_writable_dir(out);
  o.scenario = s.source;
  o.out = out;
  o.executable = executable;
  o.runs = static_cast<std::size_t>(runs);
  o.seed = seed;
  o.jobs = jobs > 0 ? jobs : std::max(1u, std::thread::hardware_concurrency());
  o.timeout = timeout;
  return o;
}

// --- Running ---------------------------------------------------------------------------------------------------------

std::string format_progress(const CampaignProgress& p, int width) {
  const int filled =
      p.total == 0 ? 0 : static_cast<int>(static_cast<double>(width) * static_cast<double>(p.done) /
                                          static_cast<double>(p.total));
  return fmt::format("[{}{}] {}/{} runs, {} running, {} crash{}, {} hang{}, {} stall{}", std::string(filled, '#'),
                     std::string(static_cast<std::size_t>(width - filled), '.'), p.done, p.total, p.running, p.crashes,
                     p.crashes == 1 ? "" : "es", p.hangs, p.hangs == 1 ? "" : "s", p.stalls, p.stalls == 1 ? "" : "s");
}

bool stalled(const Report& report) {
  return report.outcome == "timeout" || report.outcome == "unfinished";
}

std::vector<RunRecord> run_campaign(const CampaignOptions& o,
                                    const std::function<void(const CampaignProgress&)>& on_progress) {
  make_output_directory(o.out);  // marked as Cellwright's before anything is written into it
  std::vector<RunRecord> records(o.runs);
  std::vector<ChildSpec> children(o.runs);
  for (std::size_t i = 0; i < o.runs; ++i) {
    RunRecord& rec = records[i];
    rec.variant = draw_variant(o.targets, o.kinds, o.seed, i);
    rec.dir = o.out / kRunsDir / fmt::format("{:04}", i);
    ChildSpec& c = children[i];
    c.args = {"run", o.scenario.string()};
    for (const DrawnFault& f : rec.variant.faults) {
      c.args.push_back("--fault");
      c.args.push_back(f.spec);
    }
    // No final.png: nobody opens a campaign run's picture (`--video` re-runs a failed one with all of its outputs).
    for (const std::string& a : {std::string("--seed"), std::to_string(rec.variant.seed), std::string("--quiet"),
                                 std::string("--final-png"), std::string("never"), std::string("-o"),
                                 rec.dir.string()}) {
      c.args.push_back(a);
    }
    c.dir = rec.dir;
    c.timeout = o.timeout;
  }
  CampaignProgress progress;
  progress.total = o.runs;
  auto report = [&] {
    if (on_progress) on_progress(progress);
  };
  ChildCallbacks callbacks;
  callbacks.started = [&](std::size_t) {
    ++progress.running;
    report();
  };
  callbacks.ended = [&](std::size_t i, const ChildEnd& end) {
    RunRecord& rec = records[i];
    rec.status = end.status;
    rec.exit_code = end.exit_code;
    rec.signal = end.signal;
    rec.wall_time = end.wall_time;
    rec.problem = end.problem;
    rec.report = end.report;
    ++progress.done;
    --progress.running;
    if (rec.status == RunStatus::kCrash) ++progress.crashes;
    if (rec.status == RunStatus::kHang) ++progress.hangs;
    if (rec.report && stalled(*rec.report)) ++progress.stalls;
    report();
  };
  report();
  run_children(o.executable, children, o.jobs, callbacks);
  return records;
}

// --- Adding up -------------------------------------------------------------------------------------------------------

CampaignSummary aggregate(const std::vector<RunRecord>& runs, const std::vector<std::string>& kinds,
                          const std::string& scenario, std::uint64_t seed) {
  CampaignSummary s;
  s.scenario = scenario;
  s.seed = seed;
  s.total.kind = std::string("all");
  std::map<std::string, std::size_t> row;
  std::map<std::string, std::vector<double>> times;
  auto row_of = [&](const std::string& kind) -> KindSummary& {
    auto it = row.find(kind);
    if (it == row.end()) {
      it = row.emplace(kind, s.kinds.size()).first;
      KindSummary k;
      k.kind = kind;
      s.kinds.push_back(k);
    }
    return s.kinds[it->second];
  };
  for (const std::string& k : kinds) row_of(k);
  std::vector<double> all_times;
  for (const RunRecord& rec : runs) {
    std::set<std::string> drawn;
    for (const DrawnFault& f : rec.variant.faults) drawn.insert(f.kind);
    std::size_t lost = 0, unaccounted = 0, false_alarms = 0, unexplained = 0;
    bool ok = false, stall = false;
    if (rec.report) {
      const Report& r = *rec.report;
      unaccounted = r.unaccounted();
      false_alarms = r.false_alarms.size();
      unexplained = r.unexplained.size();
      for (const WorkpieceReport& w : r.workpieces) lost += w.lost ? 1 : 0;
      ok = r.ok();
      stall = stalled(r);
      for (const FaultReport& f : r.faults) {
        KindSummary& k = row_of(f.kind);
        ++k.injected;
        ++s.total.injected;
        if (f.detected) ++k.detected, ++s.total.detected;
        if (f.stopped_safely) ++k.stopped_safely, ++s.total.stopped_safely;
        if (f.recovered && !stall) {  // a recovery the run stalled after did not get the work done
          CW_CHECK(f.recovery_time.has_value(), "a recovered {} fault without its recovery time", f.kind);
          ++k.recovered;
          ++s.total.recovered;
          times[k.kind].push_back(*f.recovery_time);
          all_times.push_back(*f.recovery_time);
        }
      }
    }
    auto count_run = [&](KindSummary& k) {
      ++k.runs;
      k.lost += lost;
      k.unaccounted += unaccounted;
      k.false_alarms += false_alarms;
      k.unexplained += unexplained;
      if (rec.status == RunStatus::kCrash) ++k.crashes;
      if (rec.status == RunStatus::kHang) ++k.hangs;
      if (stall) ++k.stalls;
      if (ok) ++k.ok_runs;
    };
    for (const std::string& kind : drawn) count_run(row_of(kind));
    count_run(s.total);
  }
  auto mean = [](const std::vector<double>& v) -> std::optional<double> {
    if (v.empty()) return std::nullopt;
    double sum = 0;
    for (double x : v) sum += x;
    return sum / static_cast<double>(v.size());
  };
  for (KindSummary& k : s.kinds) k.mean_recovery_time = mean(times[k.kind]);
  s.total.mean_recovery_time = mean(all_times);
  return s;
}

namespace {

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string csv_line(const KindSummary& k) {
  return fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", csv_field(k.kind), k.runs, k.injected,
                     k.detected, k.recovered, k.stopped_safely, k.lost, k.unaccounted, k.false_alarms, k.unexplained,
                     k.crashes, k.hangs, k.stalls,
                     k.ok_runs, k.mean_recovery_time ? fmt::format("{:.4f}", *k.mean_recovery_time) : std::string());
}

std::string md_line(const KindSummary& k, bool bold) {
  const std::string name = bold ? "**" + k.kind + "**" : k.kind;
  return fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", name, k.runs,
                     k.injected, k.detected, k.recovered, k.stopped_safely, k.lost, k.unaccounted, k.false_alarms,
                     k.unexplained, k.crashes,
                     k.hangs, k.stalls,
                     k.mean_recovery_time ? fmt::format("{:.2f}", *k.mean_recovery_time) : std::string("-"));
}

std::string faults_text(const Variant& v) {
  std::string s;
  for (const DrawnFault& f : v.faults) s += (s.empty() ? "" : " + ") + f.spec;
  return s;
}

}  // namespace

std::string format_csv(const CampaignSummary& s) {
  std::string out =
      "kind,runs,injected,detected,recovered,stopped_safely,lost,unaccounted,false_alarms,unexplained,crashes,hangs,"
      "stalls,"
      "ok_runs,mean_recovery_time_s\n";
  for (const KindSummary& k : s.kinds) out += csv_line(k);
  out += csv_line(s.total);
  return out;
}

std::string format_runs_csv(const std::vector<RunRecord>& runs) {
  std::string out = "index,seed,status,exit_code,outcome,result,unaccounted,faults,problem\n";
  for (const RunRecord& r : runs) {
    std::string outcome, result, unaccounted;
    if (r.report) {
      outcome = r.report->outcome;
      result = r.report->ok() ? "ok" : "failed";
      unaccounted = std::to_string(r.report->unaccounted());
    }
    out += fmt::format("{},{},{},{},{},{},{},{},{}\n", r.variant.index, r.variant.seed, to_string(r.status),
                       r.signal != 0 ? std::string() : std::to_string(r.exit_code), csv_field(outcome),
                       csv_field(result), unaccounted, csv_field(faults_text(r.variant)), csv_field(r.problem));
  }
  return out;
}

std::string format_markdown(const CampaignSummary& s, const std::vector<RunRecord>& runs) {
  std::string out = fmt::format("# Fault campaign: {}, {} runs, seed {}\n\n", s.scenario, s.total.runs, s.seed);
  out += fmt::format(
      "{} of {} runs ok; {} faults injected, {} detected, {} recovered, {} stopped safely; {} run{} stalled; {} "
      "unexplained fault{}, {} false alarm{}.\n\n",
      s.total.ok_runs, s.total.runs, s.total.injected, s.total.detected, s.total.recovered, s.total.stopped_safely,
      s.total.stalls, s.total.stalls == 1 ? "" : "s", s.total.unexplained, s.total.unexplained == 1 ? "" : "s",
      s.total.false_alarms, s.total.false_alarms == 1 ? "" : "s");
  out +=
      "| fault | runs | injected | detected | recovered | stopped safely | lost parts | unaccounted parts | "
      "false alarms | unexplained faults | crashes | hangs | stalls | mean time to recover (s) |\n";
  out += "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const KindSummary& k : s.kinds) out += md_line(k, false);
  out += md_line(s.total, true);
  std::string bad;
  for (const RunRecord& r : runs) {
    if (r.status == RunStatus::kDone) continue;
    bad += fmt::format("- run {:04} (seed {}, {}): {}: {}\n", r.variant.index, r.variant.seed, faults_text(r.variant),
                       to_string(r.status), r.problem);
  }
  if (!bad.empty()) out += "\nRuns that crashed or hung:\n\n" + bad;
  std::string stalls;
  for (const RunRecord& r : runs) {
    if (!r.report || !stalled(*r.report)) continue;
    std::string before;  // the faults whose recovery ended well before the stall
    for (const FaultReport& f : r.report->faults) {
      if (!f.recovered || !f.recovery_time) continue;
      before += fmt::format("{}{} at {:.2f} s", before.empty() ? "" : ", ", f.kind, f.t + *f.recovery_time);
    }
    stalls += fmt::format("- run {:04} (seed {}, {}): {} at {:.2f} s{}{}\n", r.variant.index, r.variant.seed,
                          faults_text(r.variant), r.report->outcome, r.report->end_time,
                          r.report->reason.empty() ? std::string() : ": " + r.report->reason,
                          before.empty() ? std::string() : "; recovered before the stall, not counted: " + before);
  }
  if (!stalls.empty()) out += "\nRuns that stalled:\n\n" + stalls;
  out +=
      "\nA run's faults count under their kind; its lost and unaccounted parts, false alarms, unexplained faults, crash, "
      "hang or stall "
      "under every kind it drew (a run drew one kind, now and then two). Recovered: the recovery ended well (setting a "
      "lost part aside included) and the run did not stall; lost parts: declared lost by the controller; unaccounted: "
      "neither where expected nor declared lost. Stall: the run reached its time limit with its program unfinished "
      "(idle, or going round in circles): a failure, and a fault of a stalled run is not recovered even when its "
      "recovery ended well before the stall. Mean time to recover: from the injection to the recovery's end, over the "
      "recovered faults. False alarm: a detection the twin's truth refutes (nothing was physically wrong); "
      "unexplained fault: a detection no injected fault explains, with something physically wrong (a real fault the "
      "campaign did not ask for).\n";
  return out;
}

namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void put_text(cv::Mat& img, const std::string& text, cv::Point at, double scale, const cv::Scalar& c, int thick = 1) {
  cv::putText(img, text, at, kFont, scale, c, thick, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, double scale, int thick = 1) {
  int base = 0;
  return cv::getTextSize(text, kFont, scale, thick, &base);
}

struct Metric {
  const char* name;
  cv::Scalar colour;  // BGR, colour-blind safe (Okabe-Ito)
  std::size_t KindSummary::*value;
};

const std::vector<Metric>& metrics() {
  static const std::vector<Metric> m = {
      {"injected", {160, 160, 160}, &KindSummary::injected},
      {"detected", {178, 114, 0}, &KindSummary::detected},
      {"recovered", {115, 158, 0}, &KindSummary::recovered},
      {"stopped safely", {0, 159, 230}, &KindSummary::stopped_safely},
      {"stalled runs", {0, 0, 0}, &KindSummary::stalls},
      {"lost parts", {167, 121, 204}, &KindSummary::lost},
      {"unaccounted parts", {0, 94, 213}, &KindSummary::unaccounted},
  };
  return m;
}

}  // namespace

cv::Mat draw_campaign(const CampaignSummary& s, int width, int height) {
  CW_CHECK(width >= 400 && height >= 300, "campaign chart of {} x {} px", width, height);
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 80, right = 30, top = 75, bottom = 130;
  const int x0 = left, x1 = width - right, y0 = top, y1 = height - bottom;
  put_text(img,
           fmt::format("{}: {} runs, seed {}; crashes {}, hangs {}, stalls {}, false alarms {}, unexplained {}",
                       s.scenario, s.total.runs, s.seed, s.total.crashes, s.total.hangs, s.total.stalls,
                       s.total.false_alarms, s.total.unexplained),
           {x0, 36}, 0.65, {0, 0, 0}, 2);

  std::size_t most = 1;
  for (const KindSummary& k : s.kinds) {
    for (const Metric& m : metrics()) most = std::max(most, k.*m.value);
  }
  const double step = std::max(1.0, std::ceil(tick_step(static_cast<double>(most), 10)));
  const double axis_top = std::ceil(static_cast<double>(most) / step - 1e-9) * step;
  auto y_of = [&](double v) { return y1 - static_cast<int>(std::lround((y1 - y0) * v / axis_top)); };

  // Grid and count axis.
  for (double v = 0; v <= axis_top + step / 2; v += step) {
    cv::line(img, {x0, y_of(v)}, {x1, y_of(v)}, {232, 232, 232}, 1);
    const std::string label = fmt::format("{:.0f}", v);
    const cv::Size sz = text_size(label, 0.5);
    put_text(img, label, {x0 - 10 - sz.width, y_of(v) + sz.height / 2}, 0.5, {0, 0, 0});
  }
  cv::line(img, {x0, y0}, {x0, y1}, {0, 0, 0}, 1);
  cv::line(img, {x0, y1}, {x1, y1}, {0, 0, 0}, 2);
  {
    const std::string label = "count";
    put_text(img, label, {8, y0 - 12}, 0.5, {0, 0, 0});
  }

  // A group of bars per kind, its name and mean time to recover below.
  const int groups = std::max<int>(1, static_cast<int>(s.kinds.size()));
  const double group_w = static_cast<double>(x1 - x0) / groups;
  const int n_metrics = static_cast<int>(metrics().size());
  const int bar_w = std::clamp(static_cast<int>(group_w * 0.8 / n_metrics), 2, 60);
  for (int g = 0; g < static_cast<int>(s.kinds.size()); ++g) {
    const KindSummary& k = s.kinds[static_cast<std::size_t>(g)];
    const int gx = x0 + static_cast<int>(std::lround(group_w * (g + 0.5))) - n_metrics * bar_w / 2;
    if (g % 2 == 1) {
      cv::Mat band = img(cv::Rect(x0 + static_cast<int>(group_w * g), y0, static_cast<int>(group_w), y1 - y0));
      band -= cv::Scalar(8, 8, 8);
    }
    for (int m = 0; m < n_metrics; ++m) {
      const Metric& metric = metrics()[static_cast<std::size_t>(m)];
      const double v = static_cast<double>(k.*metric.value);
      const int bx0 = gx + m * bar_w, bx1 = bx0 + bar_w - 1;
      if (v > 0) {
        cv::rectangle(img, {bx0, y_of(v)}, {bx1, y1}, metric.colour, cv::FILLED);
        const std::string label = fmt::format("{:.0f}", v);
        const cv::Size sz = text_size(label, 0.4);
        if (sz.width <= bar_w + 6) put_text(img, label, {(bx0 + bx1 - sz.width) / 2, y_of(v) - 4}, 0.4, {0, 0, 0});
      }
    }
    const int cx = x0 + static_cast<int>(std::lround(group_w * (g + 0.5)));
    const double scale = group_w >= 110 ? 0.5 : 0.4;
    auto centred = [&](const std::string& text, int y, const cv::Scalar& c) {
      const cv::Size sz = text_size(text, scale);
      put_text(img, text, {cx - sz.width / 2, y}, scale, c);
    };
    centred(k.kind, y1 + 20, {0, 0, 0});
    centred(k.mean_recovery_time ? fmt::format("{:.2f} s", *k.mean_recovery_time) : std::string("-"), y1 + 40,
            {90, 90, 90});
    if (k.crashes + k.hangs > 0) centred(fmt::format("{}c {}h", k.crashes, k.hangs), y1 + 60, {0, 0, 200});
  }
  put_text(img, "mean time to recover below each kind; crashes (c) and hangs (h) in red", {x0, y1 + 84}, 0.45,
           {90, 90, 90});

  // Legend, on one line: the gap between its entries shrinks (from 40 px) to fit the chart's width.
  int names = 0;
  for (const Metric& m : metrics()) names += 36 + text_size(m.name, 0.55).width;
  const int gap = std::clamp((x1 - x0 - names) / std::max(1, n_metrics - 1), 12, 40);
  int lx = x0;
  const int ly = height - 36;
  for (const Metric& m : metrics()) {
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, m.colour, cv::FILLED);
    cv::rectangle(img, {lx, ly}, {lx + 28, ly + 20}, {60, 60, 60}, 1);
    put_text(img, m.name, {lx + 36, ly + 16}, 0.55, {0, 0, 0});
    lx += 36 + text_size(m.name, 0.55).width + gap;
  }
  return img;
}

std::vector<std::string> campaign_output_files() {
  return {kCampaignCsv, kRunsCsv, kCampaignMd, kCampaignPng, kRunsDir};
}

void write_campaign(const std::filesystem::path& dir, const CampaignSummary& summary,
                    const std::vector<RunRecord>& runs) {
  make_output_directory(dir);
  write_file_atomically(dir / kCampaignCsv, format_csv(summary));
  write_file_atomically(dir / kRunsCsv, format_runs_csv(runs));
  write_file_atomically(dir / kCampaignMd, format_markdown(summary, runs));
  const int width = std::max(1200, 140 * static_cast<int>(summary.kinds.size()) + 120);
  vision::write_png(draw_campaign(summary, width, 600), dir / kCampaignPng);
}

}  // namespace cellwright::cell
