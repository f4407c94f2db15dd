// ReadbackDriver: a test double for robot control's position checks. It wraps a ScriptedDriver (used only through it)
// and changes nothing but what the position read-backs say: a joint or the tool can be reported off by a set amount
// (an arm that stopped short of its goal), or each answer can give where the scripted robot was when the read was
// asked (a controller that latches its position on the request) rather than when it was answered. It records when (in
// the scripted controller's ticks) each read was asked for, with its id, so a test can tell which answer a check used.
//
// Threads: one owner, as every RobotDriver; the test advances the wrapped ScriptedDriver itself.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"

namespace cellwright::testing {

class ReadbackDriver final : public drivers::RobotDriver {
 public:
  struct Request {
    drivers::CommandId id = 0;
    std::uint64_t tick = 0;  // the wrapped driver's now_ticks() when it was asked
  };

  explicit ReadbackDriver(drivers::ScriptedDriver& inner) : inner_(inner) {}

  // From now on every read-back shows joint `joint` (0-based) `offset` rad from where the arm is.
  void misread_joint(std::size_t joint, double offset) { joint_offset_ = {joint, offset}; }
  // From now on every tool-pose read-back shows the tool `offset` (base frame, m) from where it is.
  void misread_tool(const Eigen::Vector3d& offset) { tool_offset_ = offset; }
  // Whether each answer gives the arm as it was when the read was asked.
  void latch_on_request(bool latch) { latch_ = latch; }

  // Every accepted request_position(), in order.
  const std::vector<Request>& requests() const { return requests_; }

  const drivers::Capabilities& capabilities() const override { return inner_.capabilities(); }
  drivers::DriverState state() const override { return inner_.state(); }
  drivers::ErrorCode connect() override { return inner_.connect(); }
  void disconnect() override { inner_.disconnect(); }
  drivers::Submitted home() override { return inner_.home(); }
  drivers::ErrorCode activate() override { return inner_.activate(); }
  void stop() override { inner_.stop(); }
  drivers::ErrorCode reset() override { return inner_.reset(); }
  drivers::Submitted submit(const drivers::Command& command) override { return inner_.submit(command); }
  drivers::Submitted request_position() override {
    drivers::Submitted s = inner_.request_position();
    if (s.accepted()) {
      requests_.push_back({s.id, inner_.now_ticks()});
      latched_[s.id] = {inner_.joints(), inner_.tool_pose()};
    }
    return s;
  }
  drivers::CommandStatus poll(drivers::CommandId id) const override { return inner_.poll(id); }
  std::optional<drivers::PositionReading> last_position() const override {
    std::optional<drivers::PositionReading> r = inner_.last_position();
    if (!r) return r;
    if (latch_) {
      if (auto it = latched_.find(r->request); it != latched_.end()) {
        if (!r->joints.empty()) r->joints = it->second.first;
        if (r->tool_pose) r->tool_pose = it->second.second;
      }
    }
    if (joint_offset_ && joint_offset_->first < r->joints.size())
      r->joints[joint_offset_->first] += joint_offset_->second;
    if (tool_offset_ && r->tool_pose) r->tool_pose->translation() += *tool_offset_;
    return r;
  }
  void set_notifier(std::function<void()> notify) override { inner_.set_notifier(std::move(notify)); }
  void set_clock(Clock clock) override { inner_.set_clock(std::move(clock)); }

 private:
  drivers::ScriptedDriver& inner_;
  std::optional<std::pair<std::size_t, double>> joint_offset_;
  std::optional<Eigen::Vector3d> tool_offset_;
  bool latch_ = false;
  std::vector<Request> requests_;
  std::map<drivers::CommandId, std::pair<std::vector<double>, Eigen::Isometry3d>> latched_;
};

}  // namespace cellwright::testing
