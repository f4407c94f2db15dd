// The files a run leaves in its output directory (outputs.hpp).
#include "cellwright/cell/outputs.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <string>
#include <system_error>
#include <vector>

#include "cellwright/cell/gantt.hpp"
#include "cellwright/cell/report_page.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/vision/png.hpp"

namespace cellwright::cell {

namespace {

// This process's command line, its arguments separated by spaces ("twin run scenes/exchange.yaml -o out/x").
std::string command_line() {
  std::string text;
  try {
    text = read_file("/proc/self/cmdline");
  } catch (const InputError&) {
    return "twin";
  }
  while (!text.empty() && text.back() == '\0') text.pop_back();
  for (char& c : text) {
    if (c == '\0') c = ' ';
  }
  return text;
}

}  // namespace

std::vector<std::string> run_output_files() {
  return {kEventsFile, streamed_events_file("").string(), kReportFile, kGanttFile, kFinalFile, kPageFile};
}

void check_output_directory(const std::filesystem::path& dir, const std::vector<std::string>& files, bool force) {
  namespace fs = std::filesystem;
  check_writable_dir(dir);
  std::error_code ec;
  if (force || !fs::exists(dir, ec) || fs::is_empty(dir, ec) || fs::exists(dir / kMarkerFile, ec)) return;
  std::vector<std::string> taken;
  for (const std::string& f : files) {
    if (fs::exists(fs::symlink_status(dir / f, ec))) taken.push_back(f);
  }
  if (taken.empty()) return;
  throw InputError({dir.string(), 0, 0},
                   fmt::format("is not an output directory of Cellwright's (it has no {}) and holds {} file{} this "
                               "command would overwrite: {}; give another -o/--output, or --force to overwrite them",
                               kMarkerFile, taken.size(), taken.size() == 1 ? "" : "s", fmt::join(taken, ", ")));
}

void make_output_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the output directory: {}", ec.message()));
  if (std::filesystem::exists(dir / kMarkerFile, ec)) return;
  write_file_atomically(dir / kMarkerFile,
                        fmt::format("Cellwright's outputs, written by: {}\nA later run with this directory as its "
                                    "-o/--output replaces them.\n",
                                    command_line()));
}

void write_outputs(const std::filesystem::path& dir, const Scenario& scenario, const Report& report,
                   const std::string& events, const cv::Mat& final_image) {
  make_output_directory(dir);
  write_file_atomically(dir / kEventsFile, events);
  write_report_outputs(dir, scenario, report, final_image);
}

void write_report_outputs(const std::filesystem::path& dir, const Scenario& scenario, const Report& report,
                          const cv::Mat& final_image, const std::optional<std::filesystem::path>& video) {
  make_output_directory(dir);
  write_file_atomically(dir / kReportFile, to_json(scenario, report).dump(2) + "\n");
  GanttOptions gantt;
  gantt.title = fmt::format("{}: {} ({}), {:.2f} s", scenario.source.filename().string(),
                            scenario.program_file.filename().string(), report.outcome, report.end_time);
  // The page embeds the very bytes of the pictures written beside it, encoded once.
  const auto png_bytes = [](const cv::Mat& image) {
    const std::vector<unsigned char> png = vision::encode_png(image);
    return std::string(png.begin(), png.end());
  };
  ReportPageMedia media;
  media.gantt_png = png_bytes(draw_gantt(report.timeline, gantt));
  write_file_atomically(dir / kGanttFile, media.gantt_png);
  if (!final_image.empty()) {
    media.final_png = png_bytes(final_image);
    write_file_atomically(dir / kFinalFile, media.final_png);
  }
  media.video = video;
  write_file_atomically(dir / kPageFile, render_report_page(scenario, report, media));
}

}  // namespace cellwright::cell
