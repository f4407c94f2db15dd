// `twin calibrate CELL --camera NAME=SOURCE --target TARGET.yaml [-o FILE]`: the pose of a real camera in the cell,
// from a calibration target of known pose in its first frame (vision/calibration.hpp), written to FILE (beside the
// cell, NAME.calibration.yaml, unless -o says otherwise) in one piece, and the line that makes the camera's entry
// read it printed. Exit 0 when written, 2 on bad input (the cell, the camera text, the target file, a target not
// found): nothing is written then.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/vision/calibration.hpp"
#include "cellwright/vision/camera_source.hpp"
#include "commands.hpp"

namespace cellwright::tools {

void add_calibrate(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "calibrate",
      "Find a real camera's pose in the cell from a calibration target of known pose (a checkerboard) in its first "
      "frame, and write it to a calibration file for the camera's entry. Exit 0 when written, 2 on bad input.");
  struct Args {
    std::string cell;
    std::string camera;
    std::string target;
    std::string output;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("cell", args->cell, "cell description (.yaml)")->required();
  cmd->add_option("--camera", args->camera,
                  "the camera and where its frames come from: NAME=v4l2:/dev/videoN or NAME=file:VIDEO_OR_GLOB[,fps=N] "
                  "(the first frame is used)")
      ->required();
  cmd->add_option("--target", args->target,
                  "the calibration target: its checkerboard and its pose in the cell (docs/vision.md)")
      ->required();
  cmd->add_option("-o,--output", args->output, "the calibration file to write (default: NAME.calibration.yaml beside "
                                               "the cell description)");
  cmd->callback([run, args] {
    *run = [args] {
      const models::CellDescription cell = models::load_cell(args->cell);
      vision::CameraText text = vision::parse_camera_text(args->camera, {"--camera", 0, 0});
      if (text.images() && !text.fps) text.fps = 1;  // only the first frame is looked at: its rate does not matter
      const models::CameraSpec* camera = cell.find_camera(text.camera);
      if (camera == nullptr) {
        throw InputError({"--camera", 0, 0},
                         fmt::format("'{}': the cell {} has no camera '{}'", text.text, args->cell, text.camera));
      }
      const vision::CalibrationTarget target = vision::read_target(args->target);
      const std::filesystem::path out =
          args->output.empty() ? cell.source.parent_path() / (camera->name + ".calibration.yaml")
                               : std::filesystem::path(args->output);
      const vision::CameraSource source(text, *camera);
      const vision::CameraPoseFit fit =
          vision::locate_camera(source.first_frame(), vision::CameraModel(*camera), target, {text.path, 0, 0});
      const Eigen::Vector3d moved = fit.pose.translation() - camera->pose.transform().translation();
      const double turned =
          Eigen::AngleAxisd(fit.pose.linear().transpose() * camera->pose.rotation()).angle() * 180.0 / M_PI;
      write_file_atomically(
          out, models::format_camera_calibration(
                   camera->name, fit.pose,
                   fmt::format("The pose of camera '{}' of {} in the cell, found by `twin calibrate` from the target "
                               "{} in the first frame of {}:\n{} corners, reprojection error {:.3f} px.",
                               camera->name, cell.source.filename().string(), args->target, text.text, fit.points,
                               fit.rms_px)));
      const Eigen::Vector3d p = fit.pose.translation();
      std::printf("camera '%s' at (%.4f, %.4f, %.4f) m; %zu corners, reprojection error %.3f px\n",
                  camera->name.c_str(), p.x(), p.y(), p.z(), fit.points, fit.rms_px);
      std::printf("from the cell description's pose: moved %.1f mm, turned %.2f degrees\n", moved.norm() * 1000,
                  turned);
      std::printf("written to %s\n", out.string().c_str());
      std::error_code ec;
      const std::filesystem::path rel = std::filesystem::relative(std::filesystem::absolute(out),
                                                                  cell.source.parent_path(), ec);
      // Relative to the cell's directory when it is in it (as the other files a cell names), else absolute.
      const bool inside = !ec && !rel.empty() && *rel.begin() != "..";
      const std::string named = inside ? rel.string() : std::filesystem::absolute(out).lexically_normal().string();
      if (camera->calibration == std::filesystem::absolute(out).lexically_normal()) {
        std::printf("camera '%s' of %s reads it already (calibration: %s)\n", camera->name.c_str(), args->cell.c_str(),
                    named.c_str());
      } else {
        std::printf("add to camera '%s' in %s:\n    calibration: %s\n", camera->name.c_str(), args->cell.c_str(),
                    named.c_str());
      }
      return 0;
    };
  });
}

}  // namespace cellwright::tools
