// A run's event log streamed to a file as the runtime writes it (RunConfig::log_stream with keep_log false), so that
// a long run's memory does not grow with its log and a run that dies leaves every line logged so far: used by every
// rig, simulated (cell/sim's ScenarioRun) or of real robots only (`twin run` in a build without the twin). After the
// run the report is made from the file read back, and the file is moved into the output directory as events.jsonl.
//
// Order of use (main thread): StreamedLog log(streamed_events_file(dir)); config.log_stream = &log.stream(); build
// and run the Runtime; log.report(...) and log.move_into(dir, runtime.log()) while the runtime's threads are not
// running; or, when the run is refused after the log was opened, log.remove().
// Threads: one thread, the caller's; the runtime writes into stream() from its threads while it runs.
#pragma once

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/runtime/event_log.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

class StreamedLog {
 public:
  // Creates `file`'s directory and its parents if needed (make_output_directory: with the marker file when the
  // directory is new to Cellwright), then `file`, emptied. Throws InputError naming the file when it cannot be written.
  explicit StreamedLog(std::filesystem::path file);
  StreamedLog(const StreamedLog&) = delete;
  StreamedLog& operator=(const StreamedLog&) = delete;

  // Where the runtime writes the log (RunConfig::log_stream).
  std::ostream& stream() { return out_; }
  // The log's file (it moves when move_into moves it).
  const std::filesystem::path& file() const { return file_; }

  // For a run refused after the log was opened: closes and removes the file, then the marker and the directories the
  // constructor made (each directory only if empty), so that nothing is left behind.
  void remove();

  // Every line `log` logged so far in the file. Throws InputError naming the file when it cannot be written (a full
  // disk).
  void flush(const runtime::EventLog& log) const;

  // The report of the run from the file (flushed first): make_report on the log read back one line at a time.
  // Throws InputError as flush() and make_report, or when the file cannot be read back.
  Report report(const runtime::EventLog& log, const Scenario& scenario, const std::vector<FinalPose>& finals,
                std::optional<double> estimated_cycle_time, RunSetup setup) const;

  // The file (flushed first) moved into `dir` as events.jsonl (copied when `dir` is on another file system); nothing
  // when it is that file already. `dir` must exist.
  void move_into(const std::filesystem::path& dir, const runtime::EventLog& log);

 private:
  std::filesystem::path file_;
  std::ofstream out_;
  std::vector<std::filesystem::path> made_;  // the directories the constructor made, innermost first
  std::filesystem::path made_marker_;        // the marker it made, or empty
};

}  // namespace cellwright::cell
