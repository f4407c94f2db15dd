// Carries out parsed VAL II instructions (instruction.hpp) with an EmulatedArm: the one executor for the monitor's
// lines and, later, for stored programs' steps. It keeps the monitor's state: the speed and the O, A, T a location
// was last given in (what WHERE writes its angles near).
//
// Threads: one thread (the emulator's) uses an Executor.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <string>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"
#include "val2/instruction.hpp"

namespace cellwright::emulate::val2 {

// What carrying out an instruction gave.
struct Outcome {
  std::vector<std::string> lines;  // to print before the prompt; error lines start with '*'
  bool interrupted = false;        // the arm was interrupted (the emulator is stopping): print nothing
  std::string failure;             // the arm's message, when an error line came from the arm
};

// The monitor's conventions (val2_emulator.hpp, Val2EmulatorOptions).
struct Conventions {
  bool val_orientation = false;                             // O, A, T as VAL publishes them, else the page's
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();  // the monitor's world in the arm's base frame
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();   // the monitor's tool point in the arm's TCP frame
};

class Executor {
 public:
  // `speed`: the monitor speed, percent, before any SPEED. The arm's chain has six joints (the caller checks).
  Executor(EmulatedArm& arm, double speed, Conventions conventions = {});

  // Carries out `instruction` (blocking while the arm moves or waits) and says what to print.
  Outcome execute(const Instruction& instruction);

 private:
  Outcome move_to(const Eigen::VectorXd& q, bool linear);
  Outcome move_to_location(const Location& location, bool linear);
  Outcome where() const;

  EmulatedArm& arm_;
  double speed_;  // percent
  Conventions conventions_;
  std::array<double, 3> oat_{0, 0, 0};  // degrees: the last O, A, T given in a TRANS
};

// The tool rotation of O, A, T (degrees): Rz(O)·Ry(A)·Rz(T)·Rx(180°).
Eigen::Matrix3d oat_rotation(double o, double a, double t);
// The O, A, T (degrees, each in (−180, 180]) of rotation `r` nearest to `near` (see val2_emulator.hpp).
std::array<double, 3> oat_angles(const Eigen::Matrix3d& r, const std::array<double, 3>& near);
// The same in VAL's published convention (val2_emulator.hpp, "Orientation"): the tool's approach axis is
// Rz(O)·(0, −cos A, −sin A), its finger line at T = 0 is Rz(O)·(1, 0, 0), and T turns the finger line about the
// approach axis.
Eigen::Matrix3d val_oat_rotation(double o, double a, double t);
std::array<double, 3> val_oat_angles(const Eigen::Matrix3d& r, const std::array<double, 3>& near);

}  // namespace cellwright::emulate::val2
