// The exchange as a cell of real robots can run it with no twin (tests of RealRun over pseudo-terminals): A already at
// the input conveyor's stop bar, since a run without the twin has no part sensor and its controller cannot know when a
// part riding a belt arrives (tests/tools/real_only_check.sh does the same).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/common/files.hpp"

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

}  // namespace cellwright::cell::test_real
