// KinematicArm: the standalone emulator's arm (`twin emulate movemaster|val2 --link PATH`): the project's kinematics
// and a clock, nothing else (no dynamics, no contacts). See emulated_arm.hpp for the contract.
//
// A move is a straight line in joint space that takes max over joints |Δq_i| / (speed · max_joint_speed_i), times
// options.time_scale (tests run fast with a small scale), on the steady clock; joints() while it runs interpolates.
// A linear move takes the same path (this arm does not model the tool's path). The gripper takes gripper_time to
// travel. Digital outputs are kept; inputs are set from outside (set_input, e.g. by a test or a wired partner).
//
// Threads: one emulator thread calls the EmulatedArm methods; joints(), outputs(), set_input() and interrupt() may be
// called from any thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"

namespace cellwright::emulate {

struct KinematicArmOptions {
  std::vector<double> home;             // radians, chain order; empty: every joint at 0 clamped into its limits
  std::vector<double> max_joint_speed;  // rad/s; empty: the URDF's velocity limits (1 rad/s where it gives none)
  double time_scale = 1.0;              // > 0: a motion takes this times its computed duration
  double gripper_width = 0.05;          // m, fully open
  std::chrono::nanoseconds gripper_time = std::chrono::milliseconds(300);
  int io_channels = 32;  // outputs and inputs 1..n
};

class KinematicArm final : public EmulatedArm {
 public:
  // Starts at home, gripper open. Throws InputError (naming the option) when the home has the wrong length or breaks
  // the limits, a speed is not positive, or time_scale is not positive.
  KinematicArm(models::KinematicChain chain, KinematicArmOptions options);

  const models::KinematicChain& chain() const override { return chain_; }
  std::vector<double> joints() const override;
  std::vector<double> home() const override { return options_.home; }
  std::vector<double> max_joint_speed() const override { return options_.max_joint_speed; }
  ArmResult move(const std::vector<double>& target, double speed, bool linear) override;
  ArmResult grip(bool close) override;
  double gripper_opening() const override;
  void set_output(int channel, bool on) override;
  bool input(int channel) const override;
  ArmResult wait_input(int channel, bool on, std::chrono::nanoseconds timeout) override;
  void interrupt() override;

  // ---- Outside the contract (any thread) ----
  void set_input(int channel, bool on);
  std::vector<bool> outputs() const;  // index 0 is channel 1
  // The duration move() would take from `from` to `to` at `speed`, unscaled.
  std::chrono::nanoseconds motion_time(const std::vector<double>& from, const std::vector<double>& to,
                                       double speed) const;

 private:
  using Clock = std::chrono::steady_clock;
  // Waits until `until` or interrupt(); false when interrupted. Lock held.
  bool wait_until(std::unique_lock<std::mutex>& lock, Clock::time_point until);
  bool channel_ok(int channel) const { return channel >= 1 && channel <= options_.io_channels; }

  const models::KinematicChain chain_;
  KinematicArmOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool interrupted_ = false;
  // The motion in progress (or the last one): joints go from start_ to goal_ between t0_ and t1_.
  std::vector<double> start_, goal_;
  Clock::time_point t0_{}, t1_{};
  double opening_ = 0.0;
  std::vector<bool> outputs_, inputs_;
};

}  // namespace cellwright::emulate
