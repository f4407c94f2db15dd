// EmulatedArm: the arm behind an emulated robot controller (emulate/). A controller emulator (Movemaster EX,
// VAL II) parses the bytes a host sends, does what the real controller would do with the arm, and answers in the
// controller's language; this interface is the arm it does it with. Two arms implement it:
//  - KinematicArm (kinematic_arm.hpp): the standalone emulator's arm, the project's kinematics and nothing else; a
//    motion takes the time its joint distance needs at the commanded speed, on the wall clock.
//  - DriverArm (driver_arm.hpp): any joint-level RobotDriver, in practice the twin's SimDriver, so that an emulator
//    moves the MuJoCo arm of the twin (virtual commissioning: `twin emulate --scenario ...`).
//
// UNITS are the project's: metres, radians, seconds, in the robot's base frame (the URDF's base_link); the emulators
// convert to and from their controller's units and conventions (docs/real-robots.md).
//
// CALLS BLOCK, as a serial controller works: move() returns when the arm has arrived (or could not), so an emulator
// that reads its next line only then answers `ER` or prints its prompt at the motion's end. Every blocking call ends
// early, with ArmStatus::interrupted, once interrupt() has been called (the emulator is shutting down).
//
// THREADS: one emulator thread calls an arm's methods; interrupt() may be called from any thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"

namespace cellwright::emulate {

enum class ArmStatus : std::uint8_t {
  ok,
  unreachable,  // the target is outside the joint limits (checked before anything moves)
  failed,       // the arm could not finish (the twin's driver failed: a collision, a fault); the message says why
  timeout,      // wait_input(): the input did not reach the level in time
  interrupted,  // interrupt() was called
};

struct ArmResult {
  ArmStatus status = ArmStatus::ok;
  std::string message;  // why, when not ok
  bool ok() const { return status == ArmStatus::ok; }
};

// The check every arm makes of a move's target before anything moves: ok, or unreachable when `target` has the wrong
// number of joints for `chain` or breaks its limits (the message says which).
ArmResult check_target(const models::KinematicChain& chain, const std::vector<double>& target);

class EmulatedArm {
 public:
  virtual ~EmulatedArm() = default;

  // The arm's kinematic chain, base_link to tcp (the tool centre point with the gripper as modelled). Fixed.
  virtual const models::KinematicChain& chain() const = 0;
  // The joints the arm stands at now (in chain order). While a move() runs on another thread, where it is then.
  virtual std::vector<double> joints() const = 0;
  // The joints of the controller's home position (Movemaster `NT`, VAL II `READY`): the cell's home for the robot.
  virtual std::vector<double> home() const = 0;
  // Each joint's top speed (rad/s, m/s for prismatic joints) at speed 1.
  virtual std::vector<double> max_joint_speed() const = 0;

  // Moves to `target` (chain order) with every joint's speed at most `speed` (in (0, 1]) times its top speed; with
  // `linear`, the tool centre point goes in a straight line (as far as the arm can). Returns when there, or
  // unreachable (the target breaks the joint limits; nothing moved), failed, interrupted.
  virtual ArmResult move(const std::vector<double>& target, double speed, bool linear) = 0;
  // Closes or opens the gripper fully; returns when the fingers have stopped (closed on a part, or at their end).
  virtual ArmResult grip(bool close) = 0;
  // The opening between the fingers now, metres.
  virtual double gripper_opening() const = 0;

  // Digital I/O, channels from 1. An output set here is what the cell's wiring carries to the other controllers'
  // inputs (in the twin, one signal table for the cell).
  virtual void set_output(int channel, bool on) = 0;
  virtual bool input(int channel) const = 0;
  // Waits until input `channel` is `on` (or off); timeout zero waits as long as it takes. ok, timeout, interrupted.
  virtual ArmResult wait_input(int channel, bool on, std::chrono::nanoseconds timeout) = 0;

  // Ends the blocking call in progress and every later one with interrupted. Any thread.
  virtual void interrupt() = 0;
};

}  // namespace cellwright::emulate
