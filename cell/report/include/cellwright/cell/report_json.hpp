// report.json read back into the typed Report (report.hpp): the inverse of to_json, so that what reads a run's
// results (`twin campaign`, `twin test`) works on typed values, never on string lookups with silent defaults.
// docs/scenarios.md describes report.json field by field.
//
// Strict: every field to_json writes must be there with its type, or the file is refused with an InputError naming
// the file and the field ("faults[2].detected"). A count is a whole number >= 0; a time a number, or null where
// to_json writes null for "none"; a part's status one of PartStatus's names. Fields that must agree must agree:
// `result` "ok" exactly when `failures` is empty; `unaccounted` the number of the account's unaccounted parts;
// `false_alarms` the number of `false_alarm_detections`; `flow.placed` the length of `flow.placed_at`; the account's
// entry i of workpieces[i] with the same `expected`; a detected fault has `detected_at`, a recovered one
// `recovery_time`; a workpiece with an expectation has `ok`; the steady throughput and cycle are both given or both
// null. Fields it does not know are ignored (a report.json may carry more than this reader needs). "devices" may be
// absent (a run without device events: none); when present, each entry has the fields of its kind.
//
// What to_json does not write stays as a default Report has it: the timelines' bars and journey marks (the devices'
// bars too), and
// WorkpieceReport::arrived; Timeline::end is `end_time`. So for every report r of scenario s:
//   to_json(s, from_json(to_json(s, r), file)) == to_json(s, r).
//
// Adding a field: write it in to_json (report.cpp), read it here with the Fields reader of report_json.cpp (one line
// per field), and add it to docs/scenarios.md's table; the round-trip test (report_json_test.cpp) checks the pair.
//
// Thread safety: pure functions; any thread may call them.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

#include "cellwright/cell/report.hpp"

namespace cellwright::cell {

// The Report a report.json holds (as to_json wrote it). `file` names it in errors. Throws InputError (file, the
// field and the problem) as above; also when `j` is not an object.
Report from_json(const nlohmann::json& j, const std::string& file);

// Reads `file` and from_json's it. Throws InputError naming the file when it cannot be read, is not JSON (the
// parser's line and column), or as from_json.
Report read_report(const std::filesystem::path& file);

}  // namespace cellwright::cell
