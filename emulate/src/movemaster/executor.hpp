// The Movemaster EX controller's state and what each command does to it and to the arm (docs/real-robots.md,
// "Movemaster EX"). One function runs a parsed Command, whether it came from the serial line or, later, from a stored
// program.
//
// The error register: 0 none, 1 hardware error, 2 position or format error; ER answers it and RS clears it.
// (assumed, as the RV-M1's two error modes:) after a hardware error (1) the controller is halted: it executes nothing
// but ER, RS and WH until RS; after a position or format error (2) only the failing command is skipped. A hardware
// error is not overwritten by a later position error; otherwise the latest error stays.
//
// Threads: the emulator's thread only.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"
#include "movemaster/command.hpp"

namespace cellwright::emulate::movemaster {

inline constexpr int kNoError = 0;
inline constexpr int kHardwareError = 1;
inline constexpr int kPositionError = 2;  // also a format error
inline constexpr int kUnlistedError = 9;   // a code the manual does not list (the `unknown` misbehaviour)

struct Executed {
  std::optional<std::string> reply;  // WH's and ER's answer, without its line end
  bool ignored = false;              // not executed: halted by a hardware error
  bool interrupted = false;          // the arm was interrupted (the emulator is stopping)
  std::string error;                 // why the register was set, if it was
};

// The controller's conventions (movemaster_emulator.hpp, MovemasterEmulatorOptions).
struct Conventions {
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();  // the controller's world in the arm's base frame
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();   // its tool point (TL at nominal) in the arm's TCP frame
  bool pitch_down_positive = false;                         // p = +90 points down (else −90, the page's)
  bool roll_left_handed = false;                            // r turns the other way about the approach axis
};

class Executor {
 public:
  // `nominal_tool_length_mm`: the TL length at which the tool point is the chain's tip; `speed_level` the SP level at
  // power-on.
  Executor(EmulatedArm& arm, double nominal_tool_length_mm, int speed_level, Conventions conventions = {});

  Executed execute(const Command& command);
  // Sets the register as a failing command does (kHardwareError or kPositionError).
  void raise(int code);
  int error() const { return error_; }

  // ER and WH: they answer, and a misbehaving line still answers them.
  static bool is_query(Op op) { return op == Op::ER || op == Op::WH; }

 private:
  // Solves the arm's inverse kinematics for a Movemaster pose with the current tool length, seeded from where the arm
  // is. None (and `why`) when the pose has no azimuth or the arm cannot reach it.
  std::optional<std::vector<double>> solve(const Pose5& pose, std::string& why) const;
  // Moves the arm at the current speed; sets the register from the outcome.
  Executed move(const std::vector<double>& target, bool linear);
  Executed grip(bool close);
  std::string where() const;
  // (l − nominal) in metres: how far the tool point is from the chain's tip along the tool's z axis.
  double tool_offset() const { return (tool_length_mm_ - nominal_tool_length_mm_) / 1000; }

  // p and r between the controller's reading and the page's (the same map both ways).
  Pose5 page_angles(const Pose5& pose) const;

  EmulatedArm& arm_;
  const double nominal_tool_length_mm_;
  Conventions conventions_;
  int error_ = kNoError;
  int speed_level_;
  bool high_acceleration_ = true;
  double tool_length_mm_;
  std::array<int, 3> grip_force_{};
  std::optional<bool> gripper_closed_;  // unknown until the first grip
  std::array<std::optional<Pose5>, kLastPosition + 1> positions_;
};

}  // namespace cellwright::emulate::movemaster
