// Child processes for the commands that run scenarios as `twin run` children: `twin campaign` (campaign.hpp) and
// `twin test` (suite.hpp). Each child is an executable started with posix_spawn, stdin /dev/null, its stdout and
// stderr in files of a directory of its own; at most `jobs` run at a time; a child still running past its wall-time
// limit is killed (SIGKILL) and is a hang. How a child ended is told apart from what it left in its directory:
//   done:  it exited and wrote a report.json that reads back as a Report (report_json.hpp: every field there, with
//          its type), whatever its exit status;
//   crash: a signal ended it, or it exited without a readable report.json (`twin run` refusing its input exits 2
//          before it writes anything: that is a "crash" here; the caller may tell it apart by the exit code). A
//          report.json that is not JSON, or lacks a field, is not readable: the problem names the file and the field,
//          and the run is never counted as done on what it would have said.
//   hang:  it outlived its limit and was killed.
//
// Thread safety: run_children() is for one thread; it waits for its children itself (polling every 20 ms) and calls
// its callbacks on that thread.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/report.hpp"

namespace cellwright::cell {

enum class RunStatus {
  kDone,   // exited and wrote report.json
  kCrash,  // died by a signal, or exited without a report.json
  kHang,   // outlived the timeout and was killed
};
const char* to_string(RunStatus s);  // "done", "crash", "hang"

// The files a child's standard output and error go to, in its directory.
inline constexpr const char* kChildStdout = "stdout.txt";
inline constexpr const char* kChildStderr = "stderr.txt";

// One child to run.
struct ChildSpec {
  std::vector<std::string> args;  // its arguments after argv[0] (which is the executable's path)
  std::filesystem::path dir;      // removed if it exists, then made, before the start; stdout.txt, stderr.txt
  double timeout = 600;           // s of wall time from its start after which it is killed (> 0)
};

// How a child ended.
struct ChildEnd {
  RunStatus status = RunStatus::kDone;
  int exit_code = -1;    // when it exited
  int signal = 0;        // when a signal ended it
  double wall_time = 0;  // s from its start to when its end was seen
  // A crash's or hang's description: "killed by signal 11 (Segmentation fault)", "exit 2 without report.json:
  // <first line of stderr>", "exit 0 with an unreadable report.json: DIR/report.json: error: "faults[0].detected" is
  // missing", "still running after 600 s: killed". Empty when done.
  std::string problem;
  // The first line of its stderr that says something (an InputError's message), at most 200 characters; "" if none.
  std::string first_error;
  std::optional<Report> report;  // DIR/report.json read back (read_report) when done
};

struct ChildCallbacks {
  std::function<void(std::size_t index)> started;                     // child `index` was started
  std::function<void(std::size_t index, const ChildEnd& end)> ended;  // child `index` ended (told apart)
};

// Runs `children` (in order, at most max(jobs, 1) at a time) as `executable ARGS...`, each with stdin /dev/null and
// stdout/stderr to DIR/stdout.txt and DIR/stderr.txt, and returns how each ended, in the order given. The callbacks
// (either may be empty) are called as children start and end. Throws InputError if a directory cannot be made or a
// child cannot be started; the children already running are killed and reaped first.
std::vector<ChildEnd> run_children(const std::filesystem::path& executable, const std::vector<ChildSpec>& children,
                                   std::size_t jobs, const ChildCallbacks& callbacks = {});

}  // namespace cellwright::cell
