// MirroredDriver: a real robot's driver (Movemaster EX, VAL II over RS-232), with the robot's copy in the twin
// following it. The runtime drives the real robot through it exactly as through the real driver (every RobotDriver
// call is the real driver's: its capabilities, states, ids, statuses and readings); on the side, the twin's copy of
// the arm (a SimDriver of the World) is made to follow what the real robot reports, so that the twin's snapshots,
// collision checks, grip sensing and event log still show the robot (docs/real-robots.md, "The live switch").
//
// HOW THE COPY FOLLOWS. Every motion and grip the real driver accepts is given to the copy too, at the same time, so
// that the two move together (a MovePose is solved by the copy's own inverse kinematics); the real command is reported
// running (poll()) until the copy has finished it as well, so that what the runtime reads of the twin next (the grip
// sensor after a close, a part's pose after a move with it in hand) shows the copy where the real robot is. Then the
// copy is corrected from the real robot's read-backs: when the newest reading (joints, or a tool pose solved to
// joints seeded with the copy's) differs from where the copy stands by more than the tolerances, the copy moves
// there (MoveJoints, at the speed of the last command).
//
// The copy's failures (a pose it cannot solve, a move that fails in the twin, a fault) never hold back or fail the
// real robot: the real command is released, the miss is counted (counts()), and the next reading corrects the copy.
//
// LIFECYCLE: connect(), home(), activate(), stop(), reset(), disconnect() go to the real driver and then to the copy
// (the copy is activated as soon as it is homed). The real driver's answer is the answer. A stopped copy stays where
// it stands (as the real robot does) and is activated again; only home() sends it home; after disconnect() it stays
// down until connect().
//
// THREADS: the owner (one robot-control thread) calls everything, and so is the copy's owner too. The copy is
// stepped by the simulation thread as every SimDriver. counts() may be called from any thread.
#pragma once

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::twin::sim {

class MirroredDriver final : public drivers::RobotDriver {
 public:
  struct Counts {
    int mirrored = 0;     // real commands given to the copy
    int corrections = 0;  // copy moves to a read-back that differed from where the copy stood
    int misses = 0;       // what the copy could not do (a refused or failed command, a pose without IK solution)
  };
  // How far the copy may stand from the real robot's read-back before it is corrected.
  static constexpr double kJointTolerance = 0.01;  // rad
  static constexpr double kToolTolerance = 0.002;  // m
  // The most commands a copy that is not up yet keeps to do once it is.
  static constexpr std::size_t kMaxBehind = 16;

  // `real` is owned; `copy` is the World's SimDriver of the same robot; `chain` its kinematics (for pose readings).
  MirroredDriver(std::string robot, std::unique_ptr<drivers::RobotDriver> real, drivers::RobotDriver& copy,
                 models::KinematicChain chain);
  ~MirroredDriver() override;

  const std::string& robot() const { return robot_; }
  drivers::RobotDriver& real() { return *real_; }
  Counts counts() const;

  // ---- RobotDriver: the real driver's, with the copy following ----
  const drivers::Capabilities& capabilities() const override { return real_->capabilities(); }
  drivers::DriverState state() const override;
  drivers::ErrorCode connect() override;
  void disconnect() override;
  drivers::Submitted home() override;
  drivers::ErrorCode activate() override;
  void stop() override;
  drivers::ErrorCode reset() override;
  drivers::Submitted submit(const drivers::Command& command) override;
  drivers::Submitted request_position() override;
  drivers::CommandStatus poll(drivers::CommandId id) const override;
  std::optional<drivers::PositionReading> last_position() const override;
  void set_notifier(std::function<void()> notify) override;
  void set_clock(Clock clock) override;
  // The real gripper's sensor (the copy's grip is the twin's, read by the rig from the World when the real driver
  // cannot tell).
  std::optional<drivers::GripSense> grip_sense() const override { return real_->grip_sense(); }

 private:
  struct Action {
    std::optional<drivers::Command> command;  // a real command to mirror, or
    std::vector<double> joints;               // a correction: move here
    drivers::CommandId real = 0;              // the real command it mirrors (0 for a correction)
  };
  // Moves the copy along: called in every call (the owner's thread). Const because poll() is.
  void follow() const;
  void bring_up_copy() const;
  void release_all() const;
  // The correction the newest reading asks for, if any (the copy's position read, the real one compared).
  std::optional<std::vector<double>> correction() const;

  const std::string robot_;
  std::unique_ptr<drivers::RobotDriver> real_;
  drivers::RobotDriver& copy_;
  const models::KinematicChain chain_;
  // All below: the owner's thread only (mutable: poll() and last_position() are const and follow too).
  mutable std::deque<Action> pending_;
  mutable drivers::CommandId copy_running_ = 0;       // the copy's command in flight
  mutable drivers::CommandId copy_running_real_ = 0;  // the real command it mirrors
  mutable drivers::CommandId copy_home_ = 0;
  mutable drivers::CommandId copy_read_ = 0;         // the copy's position request in flight
  mutable std::vector<double> copy_joints_;          // where the copy stood at its last reading
  mutable drivers::CommandId last_reading_ = 0;      // the newest real reading taken into account
  mutable drivers::CommandId last_mirrored_ = 0;     // the newest real command given to the copy
  mutable bool correction_due_ = false;              // a real reading not yet compared with the copy
  mutable double speed_ = 1.0;                       // of the last real motion
  mutable std::map<drivers::CommandId, bool> held_;  // real commands whose copy has not finished them
  mutable std::atomic<int> mirrored_{0}, corrections_{0}, misses_{0};
};

}  // namespace cellwright::twin::sim
