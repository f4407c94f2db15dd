// The files a run leaves in its output directory (outputs.hpp).
#include "cellwright/cell/outputs.hpp"

#include <fmt/format.h>

#include <string>
#include <system_error>
#include <vector>

#include "cellwright/cell/gantt.hpp"
#include "cellwright/cell/report_page.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/vision/png.hpp"

namespace cellwright::cell {

void make_output_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the output directory: {}", ec.message()));
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
