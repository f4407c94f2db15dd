// A regression suite: `twin test [DIR|SCENARIO...]` (docs/scenarios.md, "Regression suites"). Every scenario among
// the paths given runs as a `twin run SCENARIO -o OUT/NAME --quiet` child process (children.hpp), a few at a time,
// and is judged by its exit status and report.json (its `expect:` outcomes); the verdicts come out as one line per
// scenario for a person and as JUnit XML for a CI server (Jenkins, GitLab).
//
// The parts, each usable alone (the tests use them so):
//  1. classify_yaml(): what a YAML file is, by its content: a scenario (a mapping with the fields `cell` and
//     `program`), a cell description (lists of robots, workpieces, conveyors, ...), a decision tree (every key a
//     symptom of docs/faults.md), or something else.
//  2. discover(): the scenarios among the paths given, and what was skipped and why. A folder contributes its
//     *.yaml and *.yml files that are scenarios (the others are skipped, saying what they are); its subfolders are
//     not entered (they are skipped, saying so) unless named themselves. A file named explicitly must be a scenario.
//     A YAML file that cannot be read or parsed (in a folder, or named) is a case of its own that is an ERROR
//     without a run, its message the parse error (file:line:column); the other scenarios still run.
//  3. plan_suite(): each scenario's name, output directory and time limit, checked before anything runs.
//  4. run_suite(): the children, at most `jobs` at a time, and a verdict for each; a passing scenario's outputs are
//     removed unless kept, a failing one's stay.
//  5. record_videos(): with `twin test --video`, each failed scenario run again with a video, which joins its kept
//     outputs (video.mp4, and the report page index.html that shows it).
//  6. format_result(), format_totals(), format_junit(): the lines and the XML.
//
// Verdicts: pass (exit 0, report.json says "ok"); fail (the run ended and an expectation does not hold: exit 1 or a
// report that is not "ok"); error (`twin run` refused the scenario: exit 2 before it wrote a report, e.g. a typo in
// the file; or the suite could not parse the file as YAML: not run); crash (a signal, or an exit without a readable
// report.json: one that lacks a field is named so, children.hpp); hang (still running at the time limit: killed).
// Only pass counts as passed.
//
// Errors: bad input to the suite itself (a path that does not exist, a folder that cannot be read, a file named
// explicitly that is not a scenario, a folder without any scenario or YAML file that does not parse, an output
// directory that cannot be written or would overwrite something that is not an earlier run's outputs) throws
// InputError naming the file, before any child starts. A YAML file that does not parse is not such an error: one
// broken file must not cost the verdicts of the others, so it is an ERROR case (above).
//
// Thread safety: plain values and functions; run_suite() is for one thread (it waits for its children itself), and
// its callbacks are called on that thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/children.hpp"

namespace cellwright::cell {

// --- Discovery -------------------------------------------------------------------------------------------------------

enum class YamlKind { kScenario, kCell, kDecisionTree, kOther };

struct YamlClass {
  YamlKind kind = YamlKind::kOther;
  // What it is, for a person: "a scenario", "a cell description (docs/cell-description.md)", "a decision tree
  // (docs/faults.md)", "a mapping without the fields `cell` and `program`", "a list", ...
  std::string what;
  double wall_time = 0;  // a scenario's `limits: {wall_time}` (s), 0 when it sets none
};

// What the YAML file is, by its content. Throws InputError naming the file when it cannot be read or is not YAML
// (with the line and column of the syntax error).
YamlClass classify_yaml(const std::filesystem::path& file);

struct Skipped {
  std::filesystem::path path;
  std::string why;  // "a cell description (docs/cell-description.md), not a scenario", "a subfolder (not entered
                    // unless named)"
};

struct FoundScenario {
  std::filesystem::path path;  // as given, or the folder as given joined with the file name
  double wall_time = 0;        // YamlClass::wall_time
  // Set when the file could not be read or parsed as YAML (classify_yaml's InputError, "FILE:LINE:COLUMN: error:
  // not valid YAML: ..."): it is not run, its case is an ERROR with this message.
  std::string error;
};

struct Discovery {
  std::vector<FoundScenario> scenarios;  // folders' files in name order, in the order the paths were given; a file
                                         // found twice (named twice, or named and in a folder named) only once
  std::vector<Skipped> skipped;          // in the same order
};

// The scenarios among `paths` (files and folders), with the YAML files that cannot be read or parsed among them (set
// `error`, in their place in name order). Throws InputError (naming the path) when a path does not exist or a folder
// cannot be read, a file named explicitly parses but is not a scenario (saying what it is), or no scenario (nor
// YAML file that does not parse) is found at all.
Discovery discover(const std::vector<std::filesystem::path>& paths);

// --- Planning --------------------------------------------------------------------------------------------------------

struct SuiteCase {
  std::filesystem::path scenario;  // as discovered (for the person); children get it made absolute
  std::string name;                // the file name without extension, "-2", "-3" ... added when taken already
  std::filesystem::path dir;       // OUT/NAME: the run's outputs, stdout.txt and stderr.txt
  double timeout = 0;              // s of wall time before the child is killed
  std::string error;               // FoundScenario::error: not run, an ERROR with this message; else empty
};

// The default time limit of a scenario: its own wall-time limit plus a minute (so that `twin run` judges a slow run
// itself), 600 s when it sets none.
double default_timeout(double scenario_wall_time);

// One case per scenario of `found`, in its order, outputs under `out`; `timeout` (s, > 0) for every scenario, or
// default_timeout() of each. Throws InputError when `timeout` is not > 0 (naming --timeout), `out` cannot be
// written (check_writable_dir), or an OUT/NAME of a case that runs exists and is not the outputs of an earlier run (a
// directory with the marker file of outputs.hpp or stdout.txt, or an empty one): the suite would replace it, and
// that is a folder (or file) of the user's; `force` (--force) lifts that. A case with an error writes nothing.
// Creates nothing: run_suite's children make and mark OUT/NAME (children.hpp), the caller OUT.
std::vector<SuiteCase> plan_suite(const Discovery& found, const std::filesystem::path& out,
                                  std::optional<double> timeout, bool force = false);

// Checks that `file` (the --junit file) can be written: not a directory, its folder writable or creatable
// (check_writable_dir), the file itself writable when it exists. Throws InputError naming it; creates nothing.
void check_writable_file(const std::filesystem::path& file);

// A new, empty directory of our own for the outputs when no -o is given: $TMPDIR (else /tmp)/cellwright-test-XXXXXX.
// Throws InputError when it cannot be made.
std::filesystem::path make_temporary_output_dir();

// --- Running ---------------------------------------------------------------------------------------------------------

enum class Verdict { kPass, kFail, kError, kCrash, kHang };
const char* to_string(Verdict v);  // "pass", "fail", "error", "crash", "hang"

struct SuiteOptions {
  std::filesystem::path executable;   // the `twin` executable (the CLI passes /proc/self/exe)
  unsigned jobs = 0;                  // scenarios at a time; 0: std::thread::hardware_concurrency()
  std::optional<std::uint64_t> seed;  // passed to every run as --seed
  bool keep = false;                  // keep a passing scenario's outputs too
};

struct CaseResult {
  SuiteCase test;
  Verdict verdict = Verdict::kCrash;
  ChildEnd end;
  std::optional<double> sim_time;     // s, report.json's end_time
  std::optional<std::size_t> placed;  // parts placed, report.json's flow.placed
  // Why it did not pass, one line: the report's first failure (the first expectation that does not hold), the
  // refusal (the child's first line on stderr), the crash or the hang. Empty when it passed.
  std::string message;
  std::vector<std::string> failures;  // every failure of the report (fail), else {message} unless passed
  std::string output;                 // the child's stdout (`twin run`'s summary of the report)
  std::string errors;                 // the child's stderr
  bool kept = true;                   // its outputs are still in test.dir (false for a case with an error: none)
  std::filesystem::path video;        // test.dir/video.mp4 once record_videos() made it, else empty
  std::string video_note;             // why there is no video, or what to know of it; empty when all went well
  bool passed() const { return verdict == Verdict::kPass; }
};

// The verdict of a child that ended so, its report read (sim time, parts placed, failures) and the message. `output`
// and `errors` are read from the child's directory.
CaseResult judge(const SuiteCase& test, const ChildEnd& end);

struct SuiteProgress {
  std::size_t done = 0, total = 0, running = 0, failed = 0;
};
// "[#####.....] 3/6 scenarios, 2 running, 1 failed" with a bar of `width` cells.
std::string format_progress(const SuiteProgress& progress, int width = 30);

struct SuiteCallbacks {
  std::function<void(const SuiteProgress&)> progress;  // a scenario started or ended
  std::function<void(const CaseResult&)> ended;        // a scenario ended (before the progress call)
};

// Runs every case as `EXE run SCENARIO -o DIR --quiet [--seed S]` (SCENARIO absolute), at most `jobs` at a time, each
// killed at its time limit, judges each (judge()) and removes a passing one's directory unless options.keep. A case
// with an error is not run: its result (ERROR, its message the error, no outputs) is reported first. Results in the
// order of `cases`. Throws InputError as run_children.
std::vector<CaseResult> run_suite(const std::vector<SuiteCase>& cases, const SuiteOptions& options,
                                  const SuiteCallbacks& callbacks = {});

// --- Videos of the failed scenarios --------------------------------------------------------------------------------

struct VideoSettings {
  int fps = 20;                  // --video-fps
  std::string size = "800x600";  // --video-size
  double slowdown = 25;          // a video costs about 20 times a run's wall time: the re-run's time limit follows
};

struct VideoCallbacks {
  std::function<void(std::size_t done, std::size_t total)> progress;  // a re-run started or ended
  std::function<void(const CaseResult&)> ended;                       // a re-run ended (its video or note set)
};

// The time limit of a failed scenario's re-run with a video: `slowdown` times the first run's wall time, at least
// 60 s, and at most `slowdown` times the scenario's own limit.
double video_timeout(const CaseResult& result, double slowdown);

// Runs every FAILed scenario of `results` whose outputs were kept again, as `EXE run SCENARIO -o DIR/.video --quiet
// --video DIR/.video/video.mp4 --video-fps F --video-size WxH [--seed S]` children (at most options.jobs at a time,
// each killed at video_timeout()), then moves the video into DIR and removes DIR/.video. Lock-step runs are
// deterministic, so the re-run is the run that failed: when the two event logs are the same, the re-run's report page
// (index.html, which shows the video) replaces the first run's. When they differ (a scenario run in real time) the
// first run's page stays with its report and pictures, the re-run's page goes beside it as video.html, and
// `video_note` says the video shows another run. A re-run that does not end with a report, or makes no video, leaves
// `video` empty and says why in `video_note` (its stderr's first line; the whole of it kept as
// DIR/video-stderr.txt); the first run's outputs are untouched. Only FAILs are re-run: an ERROR would be refused
// again, a CRASH or HANG would crash or hang again, a PASS has nothing to look at. Throws InputError as run_children
// (a directory that cannot be made, a child that cannot be started), after killing the re-runs and removing every
// DIR/.video; the videos already moved stay.
void record_videos(std::vector<CaseResult>& results, const SuiteOptions& options, const VideoSettings& video,
                   const VideoCallbacks& callbacks = {});

// --- Reporting -------------------------------------------------------------------------------------------------------

// One line (no newline): verdict, name padded to `name_width`, sim time, wall time, parts placed, and for a scenario
// that did not pass its message:
//   "PASS   exchange   sim   14.32 s  wall    5.1 s  placed 1"
//   "FAIL   vision     sim   20.00 s  wall    4.0 s  placed 0  workpiece A: ..."
//   "HANG   slow       sim       -    wall  600.0 s  placed -  still running after 600 s: killed"
std::string format_result(const CaseResult& result, std::size_t name_width);

// "5 passed, 1 failed" and, when some did not pass for another reason than an expectation, " (1 crashed, 1 hung,
// 1 refused)".
std::string format_totals(const std::vector<CaseResult>& results);

// JUnit XML as Jenkins and GitLab read it: <testsuites> with one <testsuite name="twin test"> (tests, failures,
// errors, skipped="0", time: `wall_time` s), one <testcase name="NAME" classname="FOLDER" file="SCENARIO"
// time="WALL"> per result; a fail holds <failure message="FIRST FAILURE" type="fail"> with every failure, one a line,
// and where the outputs are; an error, crash or hang <error message="..." type="error|crash|hang">. Every test case
// has the child's stdout (the report's text) in <system-out> and its stderr, when any, in <system-err>; a failure's
// text names its video when there is one, and what to know of it (video_note). Text is made fit for any XML 1.0
// reader: control characters other than tab, newline and carriage return, and bytes that are not UTF-8, become
// U+FFFD; the XML writer (common/xml.hpp) escapes the rest.
std::string format_junit(const std::vector<CaseResult>& results, double wall_time);

}  // namespace cellwright::cell
