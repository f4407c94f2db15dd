// A camera entry's `calibration:` file (issue 26, written by `twin calibrate`): read back to the pose it was written
// with, and refused, naming the file, when it is missing or another camera's.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <unistd.h>

#include "cellwright/common/files.hpp"
#include "cellwright/models/cell.hpp"

namespace cellwright::models {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

const fs::path kCell = fs::path(CW_SOURCE_DIR) / "scenes/cell.yaml";

CellDescription with_calibration(const fs::path& file) {
  std::string text = read_file(kCell);
  const std::string entry = "  - name: overhead\n";
  text.insert(text.find(entry) + entry.size(), "    calibration: " + file.string() + "\n");
  return parse_cell(text, kCell);
}

TEST(CameraCalibration, TheEntrysFileGivesThePoseItWasWrittenWith) {
  const fs::path file = fs::temp_directory_path() / ("cw-calibration-" + std::to_string(::getpid()) + ".yaml");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.352, -0.004, 2.597);
  pose.linear() = Eigen::AngleAxisd(3.1, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                  Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()).toRotationMatrix();
  write_file_atomically(file, format_camera_calibration("overhead", pose, "written by a test\n\nof two lines"));
  const CellDescription cell = with_calibration(file);
  const CameraSpec& cam = *cell.find_camera("overhead");
  EXPECT_LT((cam.pose.transform().translation() - pose.translation()).norm(), 1e-6);
  EXPECT_LT(Eigen::AngleAxisd(cam.pose.rotation().transpose() * pose.linear()).angle(), 1e-6);
  EXPECT_EQ(cam.nominal.xyz, Eigen::Vector3d(0.35, 0, 2.6));
  EXPECT_EQ(cam.calibration, file);

  write_file_atomically(file, format_camera_calibration("front", pose, ""));
  try {
    (void)with_calibration(file);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(file.string() + ":1:"));
    EXPECT_THAT(e.what(), HasSubstr("this calibration is of camera 'front'"));
  }
  fs::remove(file);
  try {
    (void)with_calibration(file);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("calibration file '" + file.string() + "' no such file"));
  }
}

}  // namespace
}  // namespace cellwright::models
