// A run's event log streamed to a file (streamed_log.hpp).
#include "cellwright/cell/streamed_log.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "cellwright/cell/outputs.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"

namespace cellwright::cell {

StreamedLog::StreamedLog(std::filesystem::path file) : file_(std::move(file)) {
  std::error_code ec;
  for (std::filesystem::path d = file_.parent_path(); !d.empty() && !std::filesystem::exists(d, ec);
       d = d.parent_path()) {
    made_.push_back(d);
    if (d == d.parent_path()) break;
  }
  // The marker, when this log is what makes the directory Cellwright's: removed too by remove().
  if (file_.has_parent_path() && !std::filesystem::exists(file_.parent_path() / kMarkerFile, ec)) {
    made_marker_ = file_.parent_path() / kMarkerFile;
  }
  if (file_.has_parent_path()) make_output_directory(file_.parent_path());
  out_.open(file_, std::ios::binary | std::ios::trunc);
  if (!out_) throw InputError({file_.string()}, fmt::format("cannot write the event log: {}", std::strerror(errno)));
}

void StreamedLog::remove() {
  out_.close();
  std::error_code ec;
  std::filesystem::remove(file_, ec);
  if (!made_marker_.empty()) std::filesystem::remove(made_marker_, ec);
  for (const std::filesystem::path& d : made_) std::filesystem::remove(d, ec);  // each only if empty
}

void StreamedLog::flush(const runtime::EventLog& log) const {
  try {
    log.flush();
  } catch (const std::runtime_error& e) {
    throw InputError({file_.string()}, e.what());
  }
}

Report StreamedLog::report(const runtime::EventLog& log, const Scenario& scenario, const std::vector<FinalPose>& finals,
                           std::optional<double> estimated_cycle_time, RunSetup setup) const {
  flush(log);
  std::ifstream in(file_, std::ios::binary);
  if (!in) throw InputError({file_.string()}, "cannot read the event log back");
  return make_report(scenario, in, finals, estimated_cycle_time, file_.string(), std::move(setup));
}

void StreamedLog::move_into(const std::filesystem::path& dir, const runtime::EventLog& log) {
  flush(log);
  std::error_code ec;
  const std::filesystem::path target = dir / kEventsFile;
  if (!std::filesystem::equivalent(file_, target, ec)) {
    move_file(file_, target);
    file_ = target;
  }
}

}  // namespace cellwright::cell
