// report.json files for the tests of what reads them back (children, campaign, suite): to_json of a typed Report, so
// that a stand-in child writes what `twin run` writes, every field there.
#pragma once

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/cell/report.hpp"

namespace cellwright::cell::test_reports {

// A run that ended `outcome` at `end_time` s with these failures ("ok" when there are none) and `placed` parts placed
// (one a second from 1 s).
inline Report run_report(std::vector<std::string> failures = {}, std::string outcome = "finished", double end_time = 10,
                         std::size_t placed = 0) {
  Report r;
  r.outcome = std::move(outcome);
  r.end_time = end_time;
  r.timeline.end = end_time;
  r.failures = std::move(failures);
  for (std::size_t i = 0; i < placed; ++i) r.placed_at.push_back(1.0 + static_cast<double>(i));
  return r;
}

// An injected fault of `kind` at 1 s; detected 0.5 s later when `detected`, recovered `recovery` s after the
// injection when given.
inline FaultReport fault_report(const std::string& kind, bool detected, std::optional<double> recovery,
                                bool stopped_safely = false) {
  FaultReport f;
  f.kind = kind;
  f.t = 1.0;
  f.robot = "puma";
  f.detected = detected;
  if (detected) f.detected_at = 1.5;
  f.recovered = recovery.has_value();
  f.recovery_time = recovery;
  f.stopped_safely = stopped_safely;
  return f;
}

// A workpiece of the account: `name`, lost at 3 s when `lost`, unaccounted when `unaccounted`.
inline WorkpieceReport part_report(const std::string& name, bool lost, bool unaccounted = false) {
  WorkpieceReport w;
  w.name = name;
  w.final_location = "elsewhere";
  w.status = lost ? PartStatus::kLost : PartStatus::kElsewhere;
  if (lost) w.lost = LostPart{3.0, "dropped", std::nullopt};
  w.unaccounted = unaccounted;
  return w;
}

// report.json's text, as `twin run` writes it (the scenario's names empty).
inline std::string report_text(const Report& r) {
  return to_json(Scenario{}, r).dump(1);
}

// Writes report_text(r) to `file`.
inline void write_report(const std::filesystem::path& file, const Report& r) {
  std::ofstream(file, std::ios::binary) << report_text(r);
}

// A machine's figures as the report has them from its device events: `busy`, `done` and `idle` seconds, one cycle
// started and `finished` (0 or 1), the part processed when finished, and its state at the end.
inline DeviceTimeline machine_figures(const std::string& name, double busy, double done, double idle, bool finished,
                                      const std::string& state) {
  DeviceTimeline d;
  d.device = name;
  d.kind = "machine";
  d.state = state;
  d.busy = busy;
  d.done = done;
  d.idle = idle;
  d.utilisation = busy / (busy + done + idle);
  d.cycles_started = 1;
  d.cycles_finished = finished ? 1 : 0;
  if (finished) d.processed = {"A"};
  return d;
}

// A conveyor's or sensor's figures: `active` s running (on), `inactive` s stopped (off), started (came on) `starts`
// times, `state` at the end.
inline DeviceTimeline switch_figures(const std::string& name, const std::string& kind, double active, double inactive,
                                     std::size_t starts, const std::string& state) {
  DeviceTimeline d;
  d.device = name;
  d.kind = kind;
  d.state = state;
  (kind == "conveyor" ? d.running : d.on) = active;
  (kind == "conveyor" ? d.stopped : d.off) = inactive;
  d.starts = starts;
  return d;
}

}  // namespace cellwright::cell::test_reports
