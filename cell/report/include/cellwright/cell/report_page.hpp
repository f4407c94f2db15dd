// The report page: `index.html`, the one file of `twin run -o DIR` a person opens in a browser. It tells what
// report.json and the summary of `twin run` tell (report.hpp), laid out for reading:
//  - the scenario (its file, program, cell, seed, perception) and the verdict, large and coloured (green ok, red
//    failed), with the runtime's outcome and reason and every failure;
//  - the cycle time estimated before the run against the one measured, and their difference in per cent; throughput
//    and, for a flow of parts, placed / fed / delivered and the steady state;
//  - the parts: expected place against where each one is, its state in the account (in place, elsewhere, held, lost,
//    not arrived; unaccounted), how far it is from an expected location, when it was picked and placed and its
//    cycle time;
//  - per robot: commands, busy / waiting / blocked / idle seconds with a bar of the four shares;
//  - the collisions, the injected faults and what became of each (detected, diagnosed, recovered, stopped safely),
//    and the false alarms;
//  - the Gantt chart and the final snapshot, their PNG bytes embedded as data: URIs (base64 by yaml-cpp's
//    EncodeBase64), so that the page is one self-contained file; and the video of the run when one was recorded,
//    as a <video> element pointing to its file beside the page (a video is too large to embed).
//
// The page is HTML5 with inline CSS only (no script, nothing loaded from elsewhere), readable on screen and printed
// (colours kept in print, sections not split across pages where avoidable). Every string that comes from the user's
// files (scenario, cell, program, workpiece, robot and location names, fault details, failure messages) is escaped.
//
// Thread safety: a pure function; any thread may call it.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// What the page shows besides the scenario and its report.
struct ReportPageMedia {
  std::string gantt_png;  // the Gantt chart's PNG bytes (gantt.png); empty: the page says there is no chart
  std::string final_png;  // the final snapshot's PNG bytes (final.png); empty: the page says there is none
  // The run's video, relative to the page's directory (e.g. "run.mp4"); nullopt when none was recorded. The page
  // plays it with the browser's controls and links to it; it does not check that the file exists.
  std::optional<std::filesystem::path> video;
};

// The page (docs/scenarios.md, "Outputs") as UTF-8 text. The same scenario, report and media give the same bytes.
std::string render_report_page(const Scenario& scenario, const Report& report, const ReportPageMedia& media);

// Text made safe to put in HTML text or in a double-quoted attribute value: & < > " become entities, control
// characters character references (xml::Writer::escape_attribute, the project's one escaping).
std::string escape_html(std::string_view text);

}  // namespace cellwright::cell
