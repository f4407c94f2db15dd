// The files a run leaves in its output directory (`-o DIR`): the event log, report.json, the Gantt chart, the final
// picture and the report page. Everything here is MuJoCo-free: the rig hands over the final picture as an image.
//
// Thread safety: re-entrant functions; any thread may call them.
#pragma once

#include <opencv2/core.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// The file names write_outputs writes into its directory.
inline constexpr const char* kEventsFile = "events.jsonl";
inline constexpr const char* kReportFile = "report.json";
inline constexpr const char* kGanttFile = "gantt.png";
inline constexpr const char* kFinalFile = "final.png";
inline constexpr const char* kPageFile = "index.html";

// Whose a directory is. An output directory is Cellwright's when it does not exist yet, is empty, or holds this
// marker file, which make_output_directory writes into it before anything else (its text says what wrote it: the
// command line). A directory of the user's own, non-empty and unmarked, is never written over unasked:
// check_output_directory refuses it when a file the command writes is there already.
inline constexpr const char* kMarkerFile = ".cellwright-output";

// Every name a run (`twin run`, `twin step` with -o DIR) may write directly into its directory: the files above and
// the streamed log (streamed_events_file).
std::vector<std::string> run_output_files();

// Checks, before anything runs or is written, that the command may write `files` (names directly inside `dir`; a
// subdirectory such as a campaign's "runs" counts as one) into `dir`: check_writable_dir's checks, then, when `dir`
// exists, is not empty and holds no kMarkerFile, that none of `files` is in it, unless `force` (--force). Throws
// InputError({dir}) "is not an output directory of Cellwright's (it has no .cellwright-output) and holds N file(s)
// this command would overwrite: index.html, report.json; give another -o/--output, or --force to overwrite them".
// Creates nothing.
void check_output_directory(const std::filesystem::path& dir, const std::vector<std::string>& files, bool force);

// Creates `dir` and its parents if needed and, when it has none, writes kMarkerFile into it first (what wrote it:
// this process's command line). Throws InputError naming it when it cannot be made.
void make_output_directory(const std::filesystem::path& dir);

// Where a run with outputs in `dir` streams its event log while it runs (RunOptions::events_file): events.jsonl.part,
// which ScenarioRun::write_outputs renames to events.jsonl at the end; a run that dies leaves it, with every line
// logged so far.
inline std::filesystem::path streamed_events_file(const std::filesystem::path& dir) {
  return dir / (std::string(kEventsFile) + ".part");
}

// Writes events.jsonl (the log's text as given), report.json, gantt.png (draw_gantt of the report's timeline), if
// `final_image` is not empty final.png, and index.html (report_page.hpp: the report page, with both pictures in it)
// into `dir`, creating it if needed; each file atomically (temporary file, then rename). Throws InputError naming the
// path when a file or the directory cannot be written.
void write_outputs(const std::filesystem::path& dir, const Scenario& scenario, const Report& report,
                   const std::string& events, const cv::Mat& final_image);
// The same but for events.jsonl, which the caller has already put in `dir` (a streamed log moved there). `video`:
// the run's video, relative to `dir`, for the page to play (ReportPageMedia::video).
void write_report_outputs(const std::filesystem::path& dir, const Scenario& scenario, const Report& report,
                          const cv::Mat& final_image,
                          const std::optional<std::filesystem::path>& video = std::nullopt);

}  // namespace cellwright::cell
