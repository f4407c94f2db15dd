#include "cellwright/drivers/robot_driver.hpp"

#include <limits>

#include <algorithm>

#include <fmt/format.h>

#include <cmath>
#include <type_traits>

namespace cellwright::drivers {

namespace {

Refusal refuse(ErrorCode error, std::string message) {
  return {error, std::move(message)};
}

Refusal check_speed(double speed) {
  if (!std::isfinite(speed) || speed <= 0.0 || speed > 1.0) {
    return refuse(ErrorCode::invalid_command, fmt::format("speed {} is not a fraction in (0, 1]", speed));
  }
  return {};
}

Refusal check_duration(const std::optional<double>& duration, const Capabilities& caps) {
  if (!duration) return {};
  if (!caps.timed_motion) return refuse(ErrorCode::unsupported, "this robot's moves cannot be given a duration");
  if (!std::isfinite(*duration) || *duration <= 0.0) {
    return refuse(ErrorCode::invalid_command, fmt::format("duration {} s is not a positive time", *duration));
  }
  return {};
}

Refusal check(const MoveJoints& c, const Capabilities& caps) {
  if (!caps.joint_control) return refuse(ErrorCode::unsupported, "this robot takes no joint-level moves");
  if (c.positions.size() != caps.joints) {
    return refuse(ErrorCode::invalid_command,
                  fmt::format("{} joint positions given, the robot has {} joints", c.positions.size(), caps.joints));
  }
  for (std::size_t i = 0; i < c.positions.size(); ++i) {
    if (!std::isfinite(c.positions[i])) {
      return refuse(ErrorCode::invalid_command, fmt::format("joint {} position is {}", i + 1, c.positions[i]));
    }
  }
  if (Refusal bad = check_duration(c.duration, caps)) return bad;
  return check_speed(c.speed);
}

Refusal check(const MovePose& c, const Capabilities& caps) {
  if (!caps.cartesian_control) return refuse(ErrorCode::unsupported, "this robot takes no Cartesian moves");
  if (c.path == Path::linear && !caps.linear_motion) {
    return refuse(ErrorCode::unsupported, "this robot has no straight-line moves");
  }
  if (!c.pose.matrix().allFinite()) return refuse(ErrorCode::invalid_command, "the target pose is not finite");
  const Eigen::Matrix3d r = c.pose.linear();
  const double off = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-6 || r.determinant() < 0.0) {
    return refuse(ErrorCode::invalid_command,
                  fmt::format("the target orientation is not a rotation (|R^T R - I| = {:.3g}, det R = {:.6f})", off,
                              r.determinant()));
  }
  if (Refusal bad = check_duration(c.duration, caps)) return bad;
  return check_speed(c.speed);
}

Refusal check(const Grip& c, const Capabilities& caps) {
  if (!caps.gripper) return refuse(ErrorCode::unsupported, "this robot has no gripper");
  if (c.width) {
    if (!caps.gripper_width) return refuse(ErrorCode::unsupported, "this gripper cannot be set to a width");
    if (!std::isfinite(*c.width) || *c.width < 0.0 || *c.width > caps.gripper_max_width) {
      return refuse(ErrorCode::invalid_command,
                    fmt::format("gripper width {} m is outside [0, {}] m", *c.width, caps.gripper_max_width));
    }
  }
  if (c.force) {
    if (!caps.gripper_force) return refuse(ErrorCode::unsupported, "this gripper cannot limit its force");
    if (!std::isfinite(*c.force) || *c.force <= 0.0 || *c.force > caps.gripper_max_force) {
      return refuse(ErrorCode::invalid_command,
                    fmt::format("gripper force {} N is outside (0, {}] N", *c.force, caps.gripper_max_force));
    }
  }
  return {};
}

Refusal check_channel(std::string_view kind, int channel, std::size_t count) {
  if (channel < 1 || static_cast<std::size_t>(channel) > count) {
    return refuse(ErrorCode::invalid_command,
                  count == 0 ? fmt::format("digital {} {}: this robot has none", kind, channel)
                             : fmt::format("digital {} {} is outside 1..{}", kind, channel, count));
  }
  return {};
}

Refusal check(const SetOutput& c, const Capabilities& caps) {
  return check_channel("output", c.channel, caps.digital_outputs);
}

Refusal check(const WaitInput& c, const Capabilities& caps) {
  if (c.timeout.count() < 0) {
    return refuse(ErrorCode::invalid_command, fmt::format("wait timeout {} ns is negative", c.timeout.count()));
  }
  return check_channel("input", c.channel, caps.digital_inputs);
}

// Six decimals; a value that rounds to zero prints as "0.000000", never "-0.000000".
std::string fixed(double v) {
  std::string s = fmt::format("{:.6f}", v);
  if (s == "-0.000000") s.erase(0, 1);
  return s;
}

std::string fixed_list(const double* v, std::size_t n) {
  std::string s = "[";
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) s += ", ";
    s += fixed(v[i]);
  }
  return s + "]";
}

// " duration 1.250000" for a timed move, nothing otherwise (so untimed moves read as they always did).
std::string duration_suffix(const std::optional<double>& duration) {
  return duration ? fmt::format(" duration {}", fixed(*duration)) : std::string();
}

std::string describe_one(const MoveJoints& c) {
  return fmt::format("move_joints {} speed {}{}", fixed_list(c.positions.data(), c.positions.size()), fixed(c.speed),
                     duration_suffix(c.duration));
}

std::string describe_one(const MovePose& c) {
  // q and -q are the same rotation: print the one whose first component that shows (|c| >= 5e-7) is positive.
  const Eigen::Quaterniond q(c.pose.linear());
  double wxyz[] = {q.w(), q.x(), q.y(), q.z()};
  for (const double v : wxyz) {
    if (std::abs(v) < 5e-7) continue;
    if (v < 0.0) {
      for (double& u : wxyz) u = -u;
    }
    break;
  }
  const Eigen::Vector3d p = c.pose.translation();
  return fmt::format("move_pose {} xyz {} quat_wxyz {} speed {}{}", c.path == Path::linear ? "linear" : "joint",
                     fixed_list(p.data(), 3), fixed_list(wxyz, 4), fixed(c.speed), duration_suffix(c.duration));
}

std::string describe_one(const Grip& c) {
  std::string s = c.action == Grip::Action::open ? "grip open" : "grip close";
  if (c.width) s += " width " + fixed(*c.width);
  if (c.force) s += " force " + fixed(*c.force);
  return s;
}

std::string describe_one(const SetOutput& c) {
  return fmt::format("set_output {} {}", c.channel, c.on ? "on" : "off");
}

std::string describe_one(const WaitInput& c) {
  std::string s = fmt::format("wait_input {} {}", c.channel, c.on ? "on" : "off");
  if (c.timeout.count() > 0) s += fmt::format(" timeout {} ns", c.timeout.count());
  return s;
}

}  // namespace

Refusal check_command(const Command& command, const Capabilities& capabilities) {
  return std::visit([&](const auto& c) { return check(c, capabilities); }, command);
}

std::string describe(const Command& command) {
  return std::visit([](const auto& c) { return describe_one(c); }, command);
}

double out_of_arm_plane(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d p = pose.translation();
  const double radial = std::hypot(p.x(), p.y());
  if (radial < 1e-6) return std::numeric_limits<double>::infinity();
  // The plane's normal is horizontal and tangential; the approach axis's angle to the plane is asin of its component
  // along that normal.
  const Eigen::Vector3d normal(-p.y() / radial, p.x() / radial, 0.0);
  const double along = pose.linear().col(2).dot(normal);
  return std::abs(std::asin(std::clamp(along, -1.0, 1.0)));
}

std::string_view to_string(DriverState state) {
  switch (state) {
    case DriverState::disconnected:
      return "disconnected";
    case DriverState::connected:
      return "connected";
    case DriverState::homed:
      return "homed";
    case DriverState::active:
      return "active";
    case DriverState::stopped:
      return "stopped";
    case DriverState::fault:
      return "fault";
  }
  return "?";
}

std::string_view to_string(ErrorCode error) {
  switch (error) {
    case ErrorCode::none:
      return "none";
    case ErrorCode::wrong_state:
      return "wrong_state";
    case ErrorCode::invalid_command:
      return "invalid_command";
    case ErrorCode::unsupported:
      return "unsupported";
    case ErrorCode::busy:
      return "busy";
    case ErrorCode::unreachable:
      return "unreachable";
    case ErrorCode::timeout:
      return "timeout";
    case ErrorCode::cancelled:
      return "cancelled";
    case ErrorCode::hardware:
      return "hardware";
    case ErrorCode::protocol:
      return "protocol";
    case ErrorCode::connection_lost:
      return "connection_lost";
    case ErrorCode::unknown:
      return "unknown";
    case ErrorCode::unknown_command:
      return "unknown_command";
  }
  return "?";
}

std::string_view to_string(CommandPhase phase) {
  switch (phase) {
    case CommandPhase::pending:
      return "pending";
    case CommandPhase::running:
      return "running";
    case CommandPhase::done:
      return "done";
    case CommandPhase::failed:
      return "failed";
  }
  return "?";
}

}  // namespace cellwright::drivers
