// The exchange as a cell of real robots can run it with no twin (tests of RealRun over pseudo-terminals): A already at
// the input conveyor's stop bar, since a run without the twin has no part sensor and its controller cannot know when a
// part riding a belt arrives (tests/tools/real_only_check.sh does the same).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <cmath>
#include <vector>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::cell::test_real {

// Writes the exchange's files, the cell changed so, into `dir` and loads the scenario from there.
inline Scenario exchange_at_the_stop(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  const fs::path scenes = fs::path(CW_SOURCE_DIR) / "scenes";
  std::string cell = read_file(scenes / "cell.yaml");
  const std::string on_belt = "colour: [0.85, 0.1, 0.1], on: input}";
  const std::size_t a = cell.find(on_belt);
  EXPECT_NE(a, std::string::npos);
  cell.replace(a, on_belt.size(), "colour: [0.85, 0.1, 0.1], pose: {xyz: [0.03, -0.55, 0.53], yaw: 0}}");
  for (std::size_t at = cell.find("../models/"); at != std::string::npos; at = cell.find("../models/", at + 1)) {
    cell.replace(at, 2, fs::path(CW_SOURCE_DIR).string());
  }
  write_file_atomically(dir / "cell.yaml", cell);
  fs::copy_file(scenes / "exchange.yaml", dir / "exchange.yaml");
  fs::copy_file(scenes / "exchange.task", dir / "exchange.task");
  return load_scenario(dir / "exchange.yaml");
}

// The cell's homes of the exchange's arms (degrees, scenes/cell.yaml), where the controllers' READY / nest take them:
// the bring-up's cross-check refuses a controller whose home is not the cell's.
inline const std::vector<double> kPumaHome = {0, 84, -192, 0, -72, 90};
inline const std::vector<double> kMelfaHome = {-90, 30, 60, 0, 60, 0};

// An emulated arm of the URDF under models/ (e.g. "/urdf/puma560.urdf"), homing to `home` (degrees), at a quarter of
// real time (the runs go at --speed 4).
inline emulate::KinematicArm arm_at_home(const char* urdf, std::vector<double> home) {
  emulate::KinematicArmOptions o;
  o.time_scale = 0.25;
  for (double& h : home) h *= M_PI / 180.0;
  o.home = std::move(home);
  return emulate::KinematicArm(models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + urdf), o);
}

}  // namespace cellwright::cell::test_real
