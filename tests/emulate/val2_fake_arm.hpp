// PumaFakeArm: the emulators' FakeArm (fake_arm.hpp) on the PUMA 560's chain (models/urdf/puma560.urdf), for the
// VAL II emulator's tests. FakeArm carries the gripper, the I/O and interrupt(); this class replaces what depends on
// the chain: the joints, home, top speeds and move(), which records each call, refuses targets outside the PUMA's
// limits, can be held until the test releases it, and can be told to fail.
//
// Threads: as FakeArm: the emulator's thread calls the EmulatedArm methods, the test's thread the rest.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <numbers>
#include <string>
#include <vector>

#include "emulate/fake_arm.hpp"

namespace cellwright::emulate::testing {

inline const models::KinematicChain& puma_chain() {
  static const models::KinematicChain chain =
      models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + "/urdf/puma560.urdf");
  return chain;
}

// READY: the arm straight up (shoulder 90°, elbow −90°: the URDF's zero has the upper arm horizontal).
inline std::vector<double> puma_ready() {
  const double d = std::numbers::pi / 180.0;
  return {0, 90 * d, -90 * d, 0, 0, 0};
}

class PumaFakeArm : public FakeArm {
 public:
  // Starts at `start` (in chain order).
  explicit PumaFakeArm(std::vector<double> start = {0.3, 0.8, -2.4, 0.1, -0.7, 0.2}) : joints_(std::move(start)) {
    for (const models::JointLimit& l : puma_chain().limits()) top_speed_.push_back(l.velocity);
  }

  const models::KinematicChain& chain() const override { return puma_chain(); }
  std::vector<double> joints() const override {
    std::lock_guard lock(mutex_);
    return joints_;
  }
  std::vector<double> home() const override { return puma_ready(); }
  std::vector<double> max_joint_speed() const override { return top_speed_; }

  ArmResult move(const std::vector<double>& target, double speed, bool linear) override {
    std::unique_lock lock(mutex_);
    moves_.push_back(Move{joints_, target, speed, linear, top_speed_});
    event_.notify_all();
    const Eigen::VectorXd q =
        Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()));
    if (stopped_) return {ArmStatus::interrupted, "interrupted"};
    if (!puma_chain().within_limits(q)) return {ArmStatus::unreachable, "outside the PUMA's joint limits"};
    ++moving_;
    event_.notify_all();
    event_.wait(lock, [&] { return !held_ || passes_ > 0 || stopped_; });
    --moving_;
    if (stopped_) return {ArmStatus::interrupted, "interrupted"};
    if (held_) --passes_;
    if (failure_ != ArmStatus::ok) return {failure_, "the PUMA fake was told to fail"};
    joints_ = target;
    return {};
  }
  void interrupt() override {
    FakeArm::interrupt();
    std::lock_guard lock(mutex_);
    stopped_ = true;
    event_.notify_all();
  }

  // ---- the test's side (FakeArm's move bookkeeping is not used: these replace it) ----
  std::vector<Move> puma_moves() const {
    std::lock_guard lock(mutex_);
    return moves_;
  }
  void hold(bool on) {
    std::lock_guard lock(mutex_);
    held_ = on;
    event_.notify_all();
  }
  void let_one_through() {
    std::lock_guard lock(mutex_);
    ++passes_;
    event_.notify_all();
  }
  // True once a move() is under way (held or not yet finished); false at the deadline.
  bool in_motion_within(std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    return event_.wait_for(lock, timeout, [&] { return moving_ > 0; });
  }
  void fail_with(ArmStatus status) {
    std::lock_guard lock(mutex_);
    failure_ = status;
  }

 private:
  std::vector<double> top_speed_;
  mutable std::mutex mutex_;
  std::condition_variable event_;
  std::vector<double> joints_;
  std::vector<Move> moves_;
  bool held_ = false;
  int passes_ = 0;
  int moving_ = 0;
  bool stopped_ = false;
  ArmStatus failure_ = ArmStatus::ok;
};

}  // namespace cellwright::emulate::testing
