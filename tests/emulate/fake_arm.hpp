// FakeArm: an EmulatedArm for the emulators' tests. It has the MELFA's kinematic chain (models/urdf/melfa_rve2.urdf)
// and the cell's MELFA home, records every call, and moves either at once (the default) or only when the test lets it
// (hold_moves), so that a test can see an emulator waiting for a motion. Nothing runs on the wall clock: a move's
// duration is computed (Move::seconds), never slept.
//
// Threads: the emulator's thread calls the EmulatedArm methods; the test's thread calls the rest. All of it is
// guarded by one mutex; waits have deadlines.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <map>
#include <mutex>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::emulate::testing {

// The MELFA's chain, base_link to tcp, read once per test program.
inline const models::KinematicChain& melfa_chain() {
  static const models::KinematicChain chain =
      models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + "/urdf/melfa_rve2.urdf");
  return chain;
}

// The cell's MELFA home (scenes/cell.yaml: -90, 30, 60, 0, 60, 0 degrees): tucked, tool pointing outward and down.
inline std::vector<double> melfa_home() {
  const double d = std::numbers::pi / 180.0;
  return {-90 * d, 30 * d, 60 * d, 0, 60 * d, 0};
}

class FakeArm : public EmulatedArm {
 public:
  // One call of move().
  struct Move {
    std::vector<double> from, target;
    double speed = 0;
    bool linear = false;
    // The time the motion would take: the longest joint distance over that joint's top speed times `speed`.
    std::vector<double> max_speed;
    double seconds() const {
      double t = 0;
      for (std::size_t i = 0; i < target.size(); ++i) {
        t = std::max(t, std::abs(target[i] - from[i]) / (speed * max_speed[i]));
      }
      return t;
    }
  };

  // The MELFA, at home (or at `start`), gripper open.
  FakeArm() : FakeArm(melfa_home()) {}
  explicit FakeArm(std::vector<double> start) : FakeArm(melfa_chain(), melfa_home(), std::move(start)) {}
  // Any arm: `chain` (which must outlive the FakeArm), its `home`, standing at `start`; gripper open. The top speeds
  // are the URDF's velocity limits (1 where it gives none).
  FakeArm(const models::KinematicChain& chain, std::vector<double> home, std::vector<double> start)
      : chain_(chain), home_(std::move(home)), joints_(std::move(start)) {
    for (const models::JointLimit& l : chain_.limits()) max_speed_.push_back(l.velocity > 0 ? l.velocity : 1.0);
  }

  // ---- EmulatedArm ----
  const models::KinematicChain& chain() const override { return chain_; }
  std::vector<double> joints() const override {
    std::lock_guard lock(mutex_);
    return joints_;
  }
  std::vector<double> home() const override { return home_; }
  std::vector<double> max_joint_speed() const override { return max_speed_; }

  // Records the call; unreachable (nothing moves) outside the joint limits; with hold_moves, waits for release_move()
  // or interrupt(); then fails as set by fail_moves(), or arrives at once.
  ArmResult move(const std::vector<double>& target, double speed, bool linear) override {
    std::unique_lock lock(mutex_);
    moves_.push_back(Move{joints_, target, speed, linear, max_speed_});
    changed_.notify_all();
    if (interrupted_) return {ArmStatus::interrupted, "interrupted"};
    const Eigen::VectorXd q =
        Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()));
    if (!chain_.within_limits(q)) return {ArmStatus::unreachable, "outside the joint limits"};
    if (hold_) {
      ++moving_;
      changed_.wait(lock, [&] { return released_ > 0 || interrupted_; });
      --moving_;
      if (interrupted_) return {ArmStatus::interrupted, "interrupted"};
      --released_;
    }
    if (fail_ != ArmStatus::ok) return {fail_, "the fake arm was told to fail"};
    joints_ = target;
    return {};
  }
  ArmResult grip(bool close) override {
    std::lock_guard lock(mutex_);
    grips_.push_back(close);
    changed_.notify_all();
    if (interrupted_) return {ArmStatus::interrupted, "interrupted"};
    closed_ = close;
    return {};
  }
  double gripper_opening() const override {
    std::lock_guard lock(mutex_);
    return closed_ ? 0.0 : 0.08;
  }
  void set_output(int channel, bool on) override {
    std::lock_guard lock(mutex_);
    outputs_[channel] = on;
  }
  bool input(int channel) const override {
    std::lock_guard lock(mutex_);
    const auto it = inputs_.find(channel);
    return it != inputs_.end() && it->second;
  }
  ArmResult wait_input(int channel, bool on, std::chrono::nanoseconds timeout) override {
    std::unique_lock lock(mutex_);
    const auto level = [&] {
      const auto it = inputs_.find(channel);
      return (it != inputs_.end() && it->second) == on;
    };
    const auto done = [&] { return level() || interrupted_; };
    if (timeout.count() == 0) {
      changed_.wait(lock, done);
    } else if (!changed_.wait_for(lock, timeout, done)) {
      return {ArmStatus::timeout, "the input did not come"};
    }
    if (!level()) return {ArmStatus::interrupted, "interrupted"};
    return {};
  }
  void interrupt() override {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
    changed_.notify_all();
  }

  // ---- the test's side ----
  // Every move() call so far, in order (rejected and failed ones included).
  std::vector<Move> moves() const {
    std::lock_guard lock(mutex_);
    return moves_;
  }
  std::size_t move_count() const {
    std::lock_guard lock(mutex_);
    return moves_.size();
  }
  // Every grip() call so far: true for close.
  std::vector<bool> grips() const {
    std::lock_guard lock(mutex_);
    return grips_;
  }
  bool gripper_closed() const {
    std::lock_guard lock(mutex_);
    return closed_;
  }
  bool output(int channel) const {
    std::lock_guard lock(mutex_);
    const auto it = outputs_.find(channel);
    return it != outputs_.end() && it->second;
  }
  void set_input(int channel, bool on) {
    std::lock_guard lock(mutex_);
    inputs_[channel] = on;
    changed_.notify_all();
  }
  bool interrupted() const {
    std::lock_guard lock(mutex_);
    return interrupted_;
  }
  // Puts the arm at `q` at once (no move recorded).
  void place(std::vector<double> q) {
    std::lock_guard lock(mutex_);
    joints_ = std::move(q);
  }

  // With `hold`, each later move() waits (after its checks) until release_move() lets one through.
  void hold_moves(bool hold) {
    std::lock_guard lock(mutex_);
    hold_ = hold;
  }
  // Lets one held move (the current or the next) finish.
  void release_move() {
    std::lock_guard lock(mutex_);
    ++released_;
    changed_.notify_all();
  }
  // Waits until a held move is waiting for release_move(); false at the deadline.
  bool wait_until_moving(std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return moving_ > 0; });
  }
  // Waits until at least `count` moves have been asked for; false at the deadline.
  bool wait_for_moves(std::size_t count, std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return moves_.size() >= count; });
  }
  // Later moves (within limits) end with `status` (ok again by default) and do not move the arm.
  void fail_moves(ArmStatus status = ArmStatus::ok) {
    std::lock_guard lock(mutex_);
    fail_ = status;
  }

 private:
  const models::KinematicChain& chain_;
  const std::vector<double> home_;
  std::vector<double> max_speed_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<double> joints_;
  std::vector<Move> moves_;
  std::vector<bool> grips_;
  bool closed_ = false;
  std::map<int, bool> outputs_, inputs_;
  bool interrupted_ = false;
  bool hold_ = false;
  int moving_ = 0;
  int released_ = 0;
  ArmStatus fail_ = ArmStatus::ok;
};

}  // namespace cellwright::emulate::testing
