// DriverArm: an EmulatedArm (emulated_arm.hpp) that moves a robot through any joint-level RobotDriver; in the twin,
// the SimDriver of a MuJoCo arm, so that an emulated controller drives the twin's arm (virtual commissioning,
// `twin emulate --scenario ...`). The emulator's thread becomes the driver's owner thread (robot_driver.hpp): it is
// the only caller of the driver's methods.
//
// start() brings the driver up (connect, home, activate) and must be called, on the emulator's thread or before it
// runs, before anything else. move() submits MoveJoints (MovePose with Path::linear for a linear move when the driver
// moves in straight lines) and waits, on the driver's notifier, until it is done or failed; grip() submits a Grip;
// set_output() a SetOutput; wait_input() a WaitInput; joints() asks for a position and waits for the answer.
// gripper_opening() is the commanded opening (the interface reads no finger width back): the full width after an
// open, 0 after a close. input() reads the cell's wiring through the function given at construction.
//
// Threads: the emulator's thread calls everything but interrupt(), which any thread may call.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/emulate/emulated_arm.hpp"

namespace cellwright::emulate {

struct DriverArmOptions {
  std::vector<double> home;             // the controller's home (NT, READY), chain order, radians
  double gripper_width = 0.05;          // m, what gripper_opening() reports when open
  std::function<bool(int)> read_input;  // the cell's wiring: input n's level (none: every input off)
  std::chrono::nanoseconds reply_timeout = std::chrono::seconds(5);  // the longest wait for a position reading
};

class DriverArm final : public EmulatedArm {
 public:
  // `driver` must do joint-level control and read joints. Throws InputError when it cannot (naming what it lacks) or
  // the home has the wrong length.
  DriverArm(drivers::RobotDriver& driver, models::KinematicChain chain, DriverArmOptions options);
  ~DriverArm() override;

  // Connects, homes and activates the driver, waiting for each. An ArmResult that is not ok says what failed.
  ArmResult start();

  const models::KinematicChain& chain() const override { return chain_; }
  std::vector<double> joints() const override;
  std::vector<double> home() const override { return options_.home; }
  std::vector<double> max_joint_speed() const override { return driver_.capabilities().max_joint_speed; }
  ArmResult move(const std::vector<double>& target, double speed, bool linear) override;
  ArmResult grip(bool close) override;
  double gripper_opening() const override { return opening_; }
  void set_output(int channel, bool on) override;
  bool input(int channel) const override;
  ArmResult wait_input(int channel, bool on, std::chrono::nanoseconds timeout) override;
  void interrupt() override;

 private:
  // Submits `command` (or home() when empty) and waits for its end; maps the driver's failure to an ArmResult.
  ArmResult run(const std::optional<drivers::Command>& command);
  // Waits until command `id` is done or failed, or interrupt(). Returns its last status.
  drivers::CommandStatus wait(drivers::CommandId id) const;

  drivers::RobotDriver& driver_;
  const models::KinematicChain chain_;
  const DriverArmOptions options_;
  double opening_;
  mutable std::vector<double> last_joints_;
  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  std::uint64_t events_ = 0;
  bool interrupted_ = false;
};

}  // namespace cellwright::emulate
