// A copy of the shipped scenes for tests that write into the cell description (teaching saves locations): a fresh
// temporary directory holding scenes/cell.yaml (its URDF paths made absolute, so that it loads from anywhere; every
// other byte as shipped), the exchange scenario and program, and a scenario of the deadlocking program on that cell.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace cellwright::cell::live_testing {

inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << text;
}

class SceneCopy {
 public:
  SceneCopy() {
    static std::atomic<int> counter{0};
    dir_ = std::filesystem::temp_directory_path() /
           ("cw_teach_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    const std::filesystem::path scenes = std::filesystem::path(CW_SOURCE_DIR) / "scenes";
    std::string cell = read_text(scenes / "cell.yaml");
    const std::string from = "urdf: ../models/", to = "urdf: " + std::string(CW_SOURCE_DIR) + "/models/";
    for (std::size_t at = cell.find(from); at != std::string::npos; at = cell.find(from, at + to.size())) {
      cell.replace(at, from.size(), to);
    }
    write_text(cell_file(), cell);
    for (const char* f : {"exchange.yaml", "exchange.task", "deadlock.task"}) {
      std::filesystem::copy_file(scenes / f, dir_ / f);
    }
    write_text(deadlock(), "cell: cell.yaml\nprogram: deadlock.task\nrobots: {r1: puma, r2: melfa}\n");
  }
  ~SceneCopy() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  SceneCopy(const SceneCopy&) = delete;
  SceneCopy& operator=(const SceneCopy&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path cell_file() const { return dir_ / "cell.yaml"; }
  std::filesystem::path exchange() const { return dir_ / "exchange.yaml"; }
  std::filesystem::path deadlock() const { return dir_ / "deadlock.yaml"; }

 private:
  std::filesystem::path dir_;
};

}  // namespace cellwright::cell::live_testing
