// `twin snapshot <cell.yaml> [--camera NAME] [--width W --height H] [--after SECONDS] [--detections] -o out.png
// [--mjcf out.xml]`: build the cell's MuJoCo scene and render one picture of it offscreen (no display needed),
// optionally after simulating it for a while, and/or save the generated MJCF. With --detections (a cell camera
// only), find the workpieces in the picture (vision/detector.hpp), draw them on it and print one line per workpiece.
// Exit 0 on success, 2 on bad input. Robots that overlap at the start (twin::start_overlaps) are bad input that is
// drawn all the same: the error is printed, the picture and the MJCF written, and the exit status is 2.
#if CW_SIM
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/vision/png.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/vision/detector.hpp"
#include "cellwright/vision/draw.hpp"
#include "commands.hpp"

namespace cellwright::tools {

void add_snapshot(CLI::App& app, Command* run) {
  struct Options {
    std::string cell;
    std::string camera{twin::kOverviewCamera};
    int width = 0, height = 0;  // 0: the camera's resolution (640 x 480 for the overview)
    double after = 0;
    std::string out;
    std::string mjcf;
    bool detections = false;
  };
  auto opts = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand(
      "snapshot", "Render a picture of a cell (offscreen, no display) to a PNG file. Exit 0 on success; 2 on bad input (robots "
      "that overlap at the start: 2, the picture written all the same to show it).");
  sub->add_option("cell", opts->cell, "cell description (.yaml)")->required();
  sub->add_option(
      "--camera", opts->camera,
      fmt::format("a camera of the cell, or '{}' for a view of the whole cell (default)", twin::kOverviewCamera));
  sub->add_option("--width", opts->width, "image width in pixels (default: the camera's)")->check(CLI::Range(1, 4096));
  sub->add_option("--height", opts->height, "image height in pixels (default: the camera's)")
      ->check(CLI::Range(1, 4096));
  sub->add_option("--after", opts->after, "simulate the cell this many seconds first (default 0)")
      ->check(CLI::Range(0.0, 3600.0));
  sub->add_option("-o,--output", opts->out, "PNG file to write (replaced atomically)");
  sub->add_option("--mjcf", opts->mjcf, "also write the generated MuJoCo model (MJCF) to this file");
  sub->add_flag("--detections", opts->detections,
                "find the workpieces in the camera's picture, draw them on it and print them (a cell camera only)");
  sub->callback([run, opts] {
    *run = [opts] {
      if (opts->out.empty() && opts->mjcf.empty()) {
        std::fprintf(stderr, "twin snapshot: error: nothing to write: give -o out.png and/or --mjcf out.xml\n");
        return 2;
      }
      if (opts->detections && opts->camera == twin::kOverviewCamera) {
        std::fprintf(stderr, "twin snapshot: error: --detections needs --camera NAME, a camera of the cell\n");
        return 2;
      }
      const models::CellDescription cell = models::load_cell(opts->cell);
      twin::Scene scene = twin::build_scene(cell);
      // Robots that overlap at the start: the cell cannot run (twin run refuses it with the same error), but the
      // picture is what shows the overlap, so it is still drawn, and the exit status says that the cell is wrong.
      const std::vector<twin::StartOverlap> overlaps = twin::start_overlaps(scene);
      const int status = overlaps.empty() ? 0 : 2;
      if (!overlaps.empty()) std::fprintf(stderr, "%s\n", twin::start_overlap_error(overlaps).what());
      if (!opts->mjcf.empty()) twin::write_mjcf(scene.mjcf(), opts->mjcf);
      if (opts->out.empty()) return status;
      int width = 640, height = 480;
      if (const models::CameraSpec* cam = cell.find_camera(opts->camera)) {
        width = cam->width;
        height = cam->height;
      }
      if (opts->width > 0) width = opts->width;
      if (opts->height > 0) height = opts->height;
      scene.step(static_cast<int>(opts->after / scene.model()->opt.timestep + 0.5));
      cv::Mat image = twin::render_view(scene, opts->camera, width, height);
      if (opts->detections) {
        const vision::Detector detector(cell, vision::CameraModel(*cell.find_camera(opts->camera), width, height));
        const vision::DetectionResult found = vision::detect(detector, image);
        vision::draw_detections(image, found);
        for (const auto& d : found.detections) std::printf("%s\n", vision::describe(d).c_str());
        for (const auto& r : found.rejected) {
          std::printf("rejected a blob%s at (%d, %d): %s\n",
                      r.workpiece.empty() ? "" : (" like " + r.workpiece).c_str(), r.box.x, r.box.y, r.reason.c_str());
        }
        for (const auto& name : found.not_seen) std::printf("%s not seen\n", name.c_str());
      }
      vision::write_png(image, opts->out);
      if (status != 0) {
        std::fprintf(stderr, "twin snapshot: %s written all the same, to show the overlap (exit 2: the cell cannot run)\n",
                     opts->out.c_str());
      }
      return status;
    };
  });
}

}  // namespace cellwright::tools

#else  // a twin for real robots only: the command needs the simulator

#include "simulator.hpp"

namespace cellwright::tools {

void add_snapshot(CLI::App& app, Command* run) {
  add_unavailable(app, run, "snapshot", "Draw the cell (or a camera's view) to a PNG file");
}

}  // namespace cellwright::tools

#endif  // CW_SIM
