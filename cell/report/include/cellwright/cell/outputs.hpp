// The files a run leaves in its output directory (`-o DIR`): the event log, report.json, the Gantt chart, the final
// picture and the report page. Everything here is MuJoCo-free: the rig hands over the final picture as an image.
//
// Thread safety: re-entrant functions; any thread may call them.
#pragma once

#include <opencv2/core.hpp>

#include <filesystem>
#include <optional>
#include <string>

#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// Creates `dir` and its parents if needed. Throws InputError naming it when it cannot be made.
void make_output_directory(const std::filesystem::path& dir);

// The file names write_outputs writes into its directory.
inline constexpr const char* kEventsFile = "events.jsonl";
inline constexpr const char* kReportFile = "report.json";
inline constexpr const char* kGanttFile = "gantt.png";
inline constexpr const char* kFinalFile = "final.png";
inline constexpr const char* kPageFile = "index.html";

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
