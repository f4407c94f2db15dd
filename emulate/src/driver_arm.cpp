// DriverArm (driver_arm.hpp).
#include "cellwright/emulate/driver_arm.hpp"

#include <fmt/format.h>

#include "cellwright/common/error.hpp"

namespace cellwright::emulate {

namespace {

ArmStatus status_of(drivers::ErrorCode e) {
  switch (e) {
    case drivers::ErrorCode::unreachable:
      return ArmStatus::unreachable;
    case drivers::ErrorCode::timeout:
      return ArmStatus::timeout;
    default:
      return ArmStatus::failed;
  }
}

}  // namespace

DriverArm::DriverArm(drivers::RobotDriver& driver, models::KinematicChain chain, DriverArmOptions options)
    : driver_(driver), chain_(std::move(chain)), options_(std::move(options)), opening_(options_.gripper_width) {
  const SourceLocation where{"<emulated arm>", 0, 0};
  const drivers::Capabilities& caps = driver_.capabilities();
  if (!caps.joint_control || !caps.reads_joints) {
    throw InputError(where, "an emulated controller needs a driver with joint control that reads joints");
  }
  if (caps.joints != chain_.dof() || options_.home.size() != chain_.dof()) {
    throw InputError(where, fmt::format("the driver has {} joints, the kinematics {}, the home {}", caps.joints,
                                        chain_.dof(), options_.home.size()));
  }
  last_joints_ = options_.home;
  driver_.set_notifier([this] {
    {
      std::lock_guard lock(mutex_);
      ++events_;
    }
    cv_.notify_all();
  });
}

DriverArm::~DriverArm() {
  driver_.set_notifier({});
}

drivers::CommandStatus DriverArm::wait(drivers::CommandId id) const {
  for (;;) {
    std::uint64_t seen = 0;
    {
      std::lock_guard lock(mutex_);
      seen = events_;
      if (interrupted_) return {id, drivers::CommandPhase::failed, drivers::ErrorCode::cancelled, "interrupted"};
    }
    const drivers::CommandStatus st = driver_.poll(id);
    if (st.phase == drivers::CommandPhase::done || st.phase == drivers::CommandPhase::failed) return st;
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return interrupted_ || events_ != seen; });
  }
}

ArmResult DriverArm::run(const std::optional<drivers::Command>& command) {
  const drivers::Submitted s = command ? driver_.submit(*command) : driver_.home();
  if (!s.accepted()) {
    return {ArmStatus::failed, fmt::format("the driver refused: {}: {}", drivers::to_string(s.error), s.message)};
  }
  const drivers::CommandStatus st = wait(s.id);
  if (st.phase == drivers::CommandPhase::done) return {};
  if (st.error == drivers::ErrorCode::cancelled && st.message == "interrupted") {
    driver_.stop();
    return {ArmStatus::interrupted, "interrupted"};
  }
  return {status_of(st.error), fmt::format("{}: {}", drivers::to_string(st.error), st.message)};
}

ArmResult DriverArm::start() {
  if (driver_.state() == drivers::DriverState::disconnected) {
    const drivers::ErrorCode e = driver_.connect();
    if (e != drivers::ErrorCode::none) return {ArmStatus::failed, fmt::format("connect: {}", drivers::to_string(e))};
  }
  if (driver_.state() == drivers::DriverState::connected || driver_.state() == drivers::DriverState::stopped) {
    if (ArmResult r = run(std::nullopt); !r.ok()) return r;
  }
  if (driver_.state() == drivers::DriverState::homed) {
    const drivers::ErrorCode e = driver_.activate();
    if (e != drivers::ErrorCode::none) return {ArmStatus::failed, fmt::format("activate: {}", drivers::to_string(e))};
  }
  if (driver_.state() != drivers::DriverState::active) {
    return {ArmStatus::failed, fmt::format("the driver is {}, not active", drivers::to_string(driver_.state()))};
  }
  return {};
}

std::vector<double> DriverArm::joints() const {
  const drivers::Submitted s = driver_.request_position();
  if (s.accepted()) {
    const drivers::CommandStatus st = wait(s.id);
    if (st.phase == drivers::CommandPhase::done) {
      const std::optional<drivers::PositionReading> r = driver_.last_position();
      if (r && r->request == s.id && r->joints.size() == chain_.dof()) last_joints_ = r->joints;
    }
  }
  return last_joints_;
}

ArmResult DriverArm::move(const std::vector<double>& target, double speed, bool linear) {
  if (ArmResult bad = check_target(chain_, target); !bad.ok()) return bad;
  speed = std::clamp(speed, 1e-3, 1.0);
  if (linear && driver_.capabilities().linear_motion)
    return run(drivers::MovePose{
        chain_.forward(Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()))),
        drivers::Path::linear, speed});
  return run(drivers::MoveJoints{target, speed});
}

ArmResult DriverArm::grip(bool close) {
  drivers::Grip g;
  g.action = close ? drivers::Grip::Action::close : drivers::Grip::Action::open;
  ArmResult r = run(g);
  if (r.ok()) opening_ = close ? 0.0 : options_.gripper_width;
  return r;
}

void DriverArm::set_output(int channel, bool on) {
  run(drivers::SetOutput{channel, on});
}

bool DriverArm::input(int channel) const {
  return options_.read_input && options_.read_input(channel);
}

ArmResult DriverArm::wait_input(int channel, bool on, std::chrono::nanoseconds timeout) {
  return run(drivers::WaitInput{channel, on, timeout});
}

void DriverArm::interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  cv_.notify_all();
}

}  // namespace cellwright::emulate
