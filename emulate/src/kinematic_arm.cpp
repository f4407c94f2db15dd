// KinematicArm (kinematic_arm.hpp).
#include "cellwright/emulate/kinematic_arm.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::emulate {

namespace {

const SourceLocation kOptions{"<emulator options>", 0, 0};

}  // namespace

KinematicArm::KinematicArm(models::KinematicChain chain, KinematicArmOptions options)
    : chain_(std::move(chain)), options_(std::move(options)) {
  const std::size_t n = chain_.dof();
  const auto& limits = chain_.limits();
  if (options_.home.empty()) {
    options_.home.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) options_.home[i] = std::clamp(0.0, limits[i].lower, limits[i].upper);
  }
  if (options_.home.size() != n) {
    throw InputError(kOptions, fmt::format("the home position has {} joints; the arm has {}", options_.home.size(), n));
  }
  Eigen::VectorXd home(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) home[static_cast<Eigen::Index>(i)] = options_.home[i];
  if (!chain_.within_limits(home)) throw InputError(kOptions, "the home position is outside the joint limits");
  if (options_.max_joint_speed.empty()) {
    for (const models::JointLimit& l : limits) options_.max_joint_speed.push_back(l.velocity > 0 ? l.velocity : 1.0);
  }
  if (options_.max_joint_speed.size() != n) {
    throw InputError(kOptions, fmt::format("{} joint speeds for {} joints", options_.max_joint_speed.size(), n));
  }
  for (const double v : options_.max_joint_speed) {
    if (!(v > 0 && std::isfinite(v))) throw InputError(kOptions, fmt::format("joint speed {} is not positive", v));
  }
  if (!(options_.time_scale > 0 && std::isfinite(options_.time_scale))) {
    throw InputError(kOptions, fmt::format("time scale {} is not positive", options_.time_scale));
  }
  if (options_.io_channels < 0) throw InputError(kOptions, "a negative number of I/O channels");
  start_ = goal_ = options_.home;
  opening_ = options_.gripper_width;
  outputs_.assign(static_cast<std::size_t>(options_.io_channels), false);
  inputs_ = outputs_;
}

std::chrono::nanoseconds KinematicArm::motion_time(const std::vector<double>& from, const std::vector<double>& to,
                                                   double speed) const {
  double t = 0.0;
  for (std::size_t i = 0; i < from.size() && i < to.size(); ++i) {
    t = std::max(t, std::abs(to[i] - from[i]) / (speed * options_.max_joint_speed[i]));
  }
  return std::chrono::nanoseconds(static_cast<std::int64_t>(t * 1e9));
}

std::vector<double> KinematicArm::joints() const {
  std::lock_guard lock(mutex_);
  const Clock::time_point now = Clock::now();
  if (now >= t1_ || t1_ <= t0_) return goal_;
  const double f = std::chrono::duration<double>(now - t0_) / std::chrono::duration<double>(t1_ - t0_);
  std::vector<double> q(goal_.size());
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = start_[i] + f * (goal_[i] - start_[i]);
  return q;
}

bool KinematicArm::wait_until(std::unique_lock<std::mutex>& lock, Clock::time_point until) {
  cv_.wait_until(lock, until, [&] { return interrupted_ || Clock::now() >= until; });
  return !interrupted_;
}

ArmResult KinematicArm::move(const std::vector<double>& target, double speed, bool /*linear*/) {
  if (ArmResult bad = check_target(chain_, target); !bad.ok()) return bad;
  speed = std::clamp(speed, 1e-3, 1.0);
  const std::vector<double> from = joints();
  std::unique_lock lock(mutex_);
  if (interrupted_) return {ArmStatus::interrupted, "interrupted"};
  start_ = from;
  goal_ = target;
  t0_ = Clock::now();
  t1_ = t0_ + std::chrono::duration_cast<Clock::duration>(motion_time(from, target, speed) * options_.time_scale);
  if (!wait_until(lock, t1_)) {
    // Stopped where it was.
    const double f =
        std::clamp(std::chrono::duration<double>(Clock::now() - t0_) /
                       std::max(std::chrono::duration<double>(t1_ - t0_), std::chrono::duration<double>(1e-9)),
                   0.0, 1.0);
    for (std::size_t i = 0; i < goal_.size(); ++i) goal_[i] = start_[i] + f * (goal_[i] - start_[i]);
    t1_ = t0_;
    return {ArmStatus::interrupted, "interrupted"};
  }
  return {};
}

ArmResult KinematicArm::grip(bool close) {
  std::unique_lock lock(mutex_);
  const double to = close ? 0.0 : options_.gripper_width;
  const double travel = options_.gripper_width > 0 ? std::abs(to - opening_) / options_.gripper_width : 0.0;
  const auto until =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(options_.gripper_time * travel * options_.time_scale);
  if (!wait_until(lock, until)) return {ArmStatus::interrupted, "interrupted"};
  opening_ = to;
  return {};
}

double KinematicArm::gripper_opening() const {
  std::lock_guard lock(mutex_);
  return opening_;
}

void KinematicArm::set_output(int channel, bool on) {
  std::lock_guard lock(mutex_);
  if (channel_ok(channel)) outputs_[static_cast<std::size_t>(channel - 1)] = on;
}

bool KinematicArm::input(int channel) const {
  std::lock_guard lock(mutex_);
  return channel_ok(channel) && inputs_[static_cast<std::size_t>(channel - 1)];
}

void KinematicArm::set_input(int channel, bool on) {
  {
    std::lock_guard lock(mutex_);
    if (!channel_ok(channel)) return;
    inputs_[static_cast<std::size_t>(channel - 1)] = on;
  }
  cv_.notify_all();
}

std::vector<bool> KinematicArm::outputs() const {
  std::lock_guard lock(mutex_);
  return outputs_;
}

ArmResult KinematicArm::wait_input(int channel, bool on, std::chrono::nanoseconds timeout) {
  std::unique_lock lock(mutex_);
  if (!channel_ok(channel))
    return {ArmStatus::failed, fmt::format("input {} outside 1..{}", channel, options_.io_channels)};
  const auto ready = [&] { return interrupted_ || inputs_[static_cast<std::size_t>(channel - 1)] == on; };
  if (timeout.count() > 0) {
    if (!cv_.wait_for(lock, timeout, ready)) return {ArmStatus::timeout, fmt::format("input {} timed out", channel)};
  } else {
    cv_.wait(lock, ready);
  }
  if (interrupted_) return {ArmStatus::interrupted, "interrupted"};
  return {};
}

void KinematicArm::interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  cv_.notify_all();
}

}  // namespace cellwright::emulate
