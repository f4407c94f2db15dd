// A fault campaign (`twin campaign`, docs/faults.md section 6): N seeded variants of a scenario, each with one fault
// (or now and then two) drawn from the kinds that apply to it, run as `twin run` child processes a few at a time, and
// their report.json files read back as typed Reports (report_json.hpp) and added up per fault kind: injected,
// detected, recovered, stopped safely, parts unaccounted, mean time to recover, and the runs that crashed, hung or
// stalled.
//
// A stall (stalled()) is a run that did not end by itself: it reached its simulation-time or wall-time limit with
// its program unfinished (report.json's outcome "timeout"), e.g. a robot idle, waiting for a part set aside
// upstream, or going round in circles. Nothing but the limit ends such a run, so "idle with work left" and "at the
// time limit" are the same runs. A stall is a failure: counted per fault kind and in all, charted, and a fault in a
// stalled run is never "recovered", even when its recovery ended well before the stall (the cell did not get its
// work done: the fault counts as detected, its run as a stall, and its recovery time is left out of the mean). A run
// the controller stopped itself (no progress escalated to a safe stop) ended "stopped": stopped safely, not a stall.
//
// The parts, each usable alone (the tests use them so):
//  1. campaign_targets(): what of a scenario faults can be put on — robots that carry and how often, commands each
//     robot certainly sends, workpieces, signals, vision, the estimated cycle time.
//  2. applicable_kinds() / check_kinds(): which fault kinds apply to those targets.
//  3. draw_variant(): run i's faults as `twin run --fault` texts and its seed, from std::mt19937_64 seeded with (seed,
//     i) alone, so run i is the same whatever the number of runs and jobs.
//  4. run_campaign(): the child processes (children.hpp: `EXE run SCENARIO --fault ... --seed S --quiet
//     -o DIR/runs/NNNN`, stdout and stderr to files in the run's directory), at most `jobs` at a time, a child past
//     its wall-time limit killed (a hang), a child that died by a signal or wrote no readable report.json (one that
//     lacks a field is unreadable: children.hpp) a crash.
//  5. aggregate() and the writers: campaign.csv, runs.csv, campaign.md, campaign.png.
//
// Thread safety: plain values and functions; run_campaign() is for one thread (it waits for its children itself),
// and its progress callback is called on that thread.
#pragma once

#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/common/files.hpp"
#include "cellwright/cell/children.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/twin_port.hpp"

namespace cellwright::cell {

// Every fault kind of docs/faults.md section 1, in its order.
const std::vector<std::string>& fault_kinds();

// What of a scenario a fault can be put on.
struct CampaignTargets {
  struct Robot {
    std::string cell;   // cell robot name (what `--fault ...:robot=` takes)
    std::string label;  // program label
    int carries = 0;    // close commands that grip a workpiece
    int moves = 0;      // move commands of its program (each sent at least once in a run)
    int grips = 0;      // open and close commands
    bool sim = true;    // on the simulation driver
  };
  std::vector<Robot> robots;            // program robots, in program order
  std::vector<std::string> workpieces;  // cell workpieces the program uses, in program order
  int signals = 0;                      // signal commands of all programs (each fired once in a run)
  bool vision = false;                  // perception: vision
  double cycle_time = 0;                // s, estimated; 0 when unknown
};

// From the scenario's compiled program and bindings; `cycle_time` as given (the estimate, see run.hpp).
CampaignTargets campaign_targets(const Scenario& scenario, double cycle_time);

// Why `kind` does not apply to `targets` ("no robot carries a part"), or "" when it does. An unknown kind: "unknown
// fault kind".
std::string why_not_applicable(const std::string& kind, const CampaignTargets& targets);

// The kinds of fault_kinds() that apply, in that order.
std::vector<std::string> applicable_kinds(const CampaignTargets& targets);

// The kinds a campaign draws from: `requested` (empty: every applicable kind) checked and without repeats, in the
// order given. Throws InputError naming `where` when a kind is unknown (listing the known ones), does not apply
// (saying why), or when no kind applies at all.
std::vector<std::string> check_kinds(const std::vector<std::string>& requested, const CampaignTargets& targets,
                                     const SourceLocation& where);

// The largest n a `command: move|grip` fault may use on a robot: the commands of that kind its program sends at least
// once, at most 4 (so that the command comes early, before other faults can cut the run short). 0: none.
int command_bound(const CampaignTargets::Robot& robot, const std::string& command);

// One fault of a variant.
struct DrawnFault {
  std::string kind;
  std::string spec;  // the `twin run --fault` text: "drop:robot=puma,carry=1,after=0.35"
};

// One run of a campaign.
struct Variant {
  std::size_t index = 0;    // 0-based
  std::uint64_t seed = 1;   // the run's `--seed`
  std::vector<DrawnFault> faults;  // one, sometimes two (1 in 8 runs), each of `kinds`
};

// Run `index`'s faults and seed, drawn with std::mt19937_64 seeded from (seed, index) only. `kinds` must be
// non-empty and applicable (check_kinds). Where and when:
//   drop, slip: a robot that carries, carry 1..its carries, after 0.1..0.6 s;
//   misplace: a workpiece, offset 0.02..0.05 m along x and y, yaw 5..40 degrees (the injection draws the sides);
//   unreachable, missing: a workpiece;
//   obstacle: a robot, time 5..85 % of the estimated cycle (1..10 s when unknown);
//   timeout, garbage, hardware, position, link_lost: a robot on the simulation driver, command move or grip, n 1..
//   command_bound;
//   lost_signal: n 1..min(signals, 4);
//   frame_lost: time as obstacle, count 1..3; detection_noise: time as obstacle, duration 1..4 s.
Variant draw_variant(const CampaignTargets& targets, const std::vector<std::string>& kinds, std::uint64_t seed,
                     std::size_t index);

// --- Running ---------------------------------------------------------------------------------------------------------

struct CampaignOptions {
  // Defaults of the command line.
  static constexpr double kDefaultTimeout = 600;  // s
  std::filesystem::path scenario;    // passed to the children as given (make it absolute)
  std::filesystem::path out;         // DIR
  std::filesystem::path executable;  // the `twin` executable (the CLI passes /proc/self/exe)
  std::size_t runs = 20;
  std::uint64_t seed = 1;
  unsigned jobs = 0;     // 0: std::thread::hardware_concurrency()
  double timeout = kDefaultTimeout;  // s of wall time per run
  std::vector<std::string> kinds;  // checked (check_kinds)
  CampaignTargets targets;
};

// Everything `twin campaign` checks before it writes anything, and the options to run it with: loads the scenario
// (InputError as load_scenario), refuses one with real drivers (a campaign runs the twin only) or one preflight
// refuses (the problems in the message; collisions swept by `twin`), estimates its cycle time (`twin`'s estimate), works out
// the targets and checks the kinds (check_kinds), `runs` >= 1, `timeout` > 0, and that `out` can be written
// (check_writable_dir). `jobs` 0 becomes the number of cores. InputError names the option at fault.
CampaignOptions plan_campaign(const std::filesystem::path& scenario, const std::vector<std::string>& kinds,
                              long long runs, std::uint64_t seed, unsigned jobs, double timeout,
                              const std::filesystem::path& out, const std::filesystem::path& executable,
                              const TwinPort& twin);

struct RunRecord {
  Variant variant;
  std::filesystem::path dir;  // DIR/runs/NNNN
  RunStatus status = RunStatus::kDone;
  int exit_code = -1;     // when it exited
  int signal = 0;         // when a signal ended it
  double wall_time = 0;   // s
  std::string problem;    // a crash's or hang's description ("killed by signal 11", "exit 2: <stderr's last line>")
  std::optional<Report> report;  // its report.json read back, when it wrote one that reads (status done)
};

// Whether a run's report is a stall (see the top of this file): its outcome is "timeout" (a time limit), or
// "unfinished" (a log without run_end: the run did not end by itself either).
bool stalled(const Report& report);

// Progress while a campaign runs: how many runs have ended, and of them crashes, hangs and stalls, and how many run
// now.
struct CampaignProgress {
  std::size_t done = 0, total = 0, running = 0, crashes = 0, hangs = 0, stalls = 0;
};

// The progress bar: "[#####.....] 12/40 runs, 2 running, 0 crashes, 0 hangs, 3 stalls" with a bar of `width` cells.
std::string format_progress(const CampaignProgress& progress, int width = 30);

// Runs every variant (draw_variant for 0..runs-1) as a child process of options.executable:
//   EXE run SCENARIO --fault F... --seed S --quiet -o DIR/runs/NNNN
// with stdin /dev/null and stdout/stderr to DIR/runs/NNNN/stdout.txt and stderr.txt (NNNN the index, 4 digits at
// least), at most `jobs` at a time; a child still running `timeout` s after it started is killed (SIGKILL) and is a
// hang. The records come back in index order. `on_progress` (may be empty) is called when a run starts or ends.
// options.out is made Cellwright's first (make_output_directory: its marker file), then each run's directory (emptied
// and marked before its child starts). Throws InputError if a run directory cannot be made or a child cannot be
// started.
std::vector<RunRecord> run_campaign(const CampaignOptions& options,
                                    const std::function<void(const CampaignProgress&)>& on_progress = {});

// --- Adding up -------------------------------------------------------------------------------------------------------

struct KindSummary {
  std::string kind;
  std::size_t runs = 0;            // runs that drew this kind
  std::size_t injected = 0;        // faults of the kind the reports say were injected
  std::size_t detected = 0;        // ... detected
  std::size_t recovered = 0;       // ... recovered, in runs that did not stall
  std::size_t stopped_safely = 0;  // ... after which the cell was stopped
  std::size_t lost = 0;            // parts the controller declared lost in the runs that drew the kind
  std::size_t unaccounted = 0;     // parts unaccounted in the runs that drew the kind
  std::size_t false_alarms = 0;    // false alarms in the runs that drew the kind
  std::size_t unexplained = 0;     // detections no injection explains (Report::unexplained): a real fault the
                                   // run did not ask for, in the runs that drew the kind
  std::size_t crashes = 0, hangs = 0;  // of the runs that drew the kind
  std::size_t stalls = 0;              // runs that drew the kind and stalled (stalled())
  std::size_t ok_runs = 0;         // runs whose report says "ok"
  std::optional<double> mean_recovery_time;  // s, over the recovered faults of the kind (none of a stalled run)
};

struct CampaignSummary {
  std::string scenario;  // file name
  std::uint64_t seed = 1;
  std::vector<KindSummary> kinds;  // the campaign's kinds, in their order
  KindSummary total;               // kind "all": every run once (a two-fault run counts once in `runs`)
};

// Adds up the records' reports. A report's faults are counted under their own kind (a kind the campaign did not ask
// for, e.g. injected by the scenario itself, gets a row of its own after the others); a run's lost and unaccounted
// parts, false alarms, unexplained faults, crash, hang or stall under every kind it drew. A fault of a stalled run is not recovered.
CampaignSummary aggregate(const std::vector<RunRecord>& runs, const std::vector<std::string>& kinds,
                          const std::string& scenario, std::uint64_t seed);

// campaign.csv: a header line, one line per kind, then "all". Columns: kind, runs, injected, detected, recovered,
// stopped_safely, lost, unaccounted, false_alarms, crashes, hangs, stalls, ok_runs, mean_recovery_time_s (empty when
// none).
std::string format_csv(const CampaignSummary& summary);
// runs.csv: one line per run: index, seed, status, exit_code, outcome, result, unaccounted, faults (the --fault
// texts joined by " + "), problem.
std::string format_runs_csv(const std::vector<RunRecord>& runs);
// campaign.md: a title line, the table (kind, runs, injected, detected, recovered, stopped safely, lost parts,
// unaccounted parts, false alarms, crashes, hangs, stalls, mean time to recover), the runs that crashed or hung, and
// the runs that stalled (their outcome's reason, and the faults whose recovery had ended well before the stall).
std::string format_markdown(const CampaignSummary& summary, const std::vector<RunRecord>& runs);
// campaign.png: per kind a group of bars (injected, detected, recovered, stopped safely, stalled runs, lost,
// unaccounted) with a count axis, the mean time to recover under each group, and a legend; the title line counts the
// crashes, hangs, stalls and false alarms; in the style of the Gantt chart (gantt.hpp).
cv::Mat draw_campaign(const CampaignSummary& summary, int width = 1200, int height = 600);

// Checks that `dir` can be created or written, creating nothing (common/files.hpp; every command's -o uses it).
using cellwright::check_writable_dir;

// Every name a campaign writes directly into its directory: campaign.csv, runs.csv, campaign.md, campaign.png and
// runs (the runs' directories), for check_output_directory (outputs.hpp).
std::vector<std::string> campaign_output_files();

// Writes campaign.csv, runs.csv, campaign.md and campaign.png into `dir` (each atomically). Throws InputError when a
// file cannot be written.
void write_campaign(const std::filesystem::path& dir, const CampaignSummary& summary,
                    const std::vector<RunRecord>& runs);

}  // namespace cellwright::cell
