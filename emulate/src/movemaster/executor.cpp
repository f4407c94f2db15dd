// The Movemaster EX controller's commands (executor.hpp).
#include "movemaster/executor.hpp"

#include <fmt/format.h>

#include <cmath>

#include "movemaster/pose.hpp"

namespace cellwright::emulate::movemaster {

namespace {

// WH's numbers: one decimal, always signed, as the controller prints them; a value that rounds to zero is +0.0.
std::string wh_number(double v) {
  double rounded = std::round(v * 10) / 10;
  if (rounded == 0) rounded = 0;  // no "-0.0"
  return fmt::format("{:+.1f}", rounded);
}

}  // namespace

Executor::Executor(EmulatedArm& arm, double nominal_tool_length_mm, int speed_level, Conventions conventions)
    : arm_(arm),
      nominal_tool_length_mm_(nominal_tool_length_mm),
      speed_level_(speed_level),
      tool_length_mm_(nominal_tool_length_mm) {
  conventions_ = std::move(conventions);
}

Pose5 Executor::page_angles(const Pose5& pose) const {
  Pose5 out = pose;
  if (conventions_.pitch_down_positive) out.p = -pose.p;
  if (conventions_.roll_left_handed) out.r = -pose.r;
  return out;
}

void Executor::raise(int code) {
  if (error_ != kHardwareError) error_ = code;
}

Executed Executor::execute(const Command& c) {
  Executed out;
  if (error_ == kHardwareError && c.op != Op::ER && c.op != Op::RS && c.op != Op::WH) {
    out.ignored = true;
    return out;
  }
  switch (c.op) {
    case Op::NT:
      return move(arm_.home(), false);
    case Op::MP: {
      const std::optional<std::vector<double>> q = solve(c.pose, out.error);
      if (!q) {
        raise(kPositionError);
        return out;
      }
      return move(*q, false);
    }
    case Op::PD:
      positions_[c.position] = c.pose;
      return out;
    case Op::MS:
    case Op::MO: {
      if (!positions_[c.position]) {
        raise(kPositionError);
        out.error = fmt::format("position {} is not defined", c.position);
        return out;
      }
      const std::optional<std::vector<double>> q = solve(*positions_[c.position], out.error);
      if (!q) {
        raise(kPositionError);
        return out;
      }
      // The letter is the hand's state during the straight move: set it first, if it differs.
      if (c.open && gripper_closed_ != !*c.open) {
        Executed g = grip(!*c.open);
        if (!g.error.empty() || g.interrupted) return g;
      }
      return move(*q, c.op == Op::MS);
    }
    case Op::GO:
      return grip(false);
    case Op::GC:
      return grip(true);
    case Op::GP:
      grip_force_ = c.grip;  // kept; the emulated hand closes fully whatever the force
      return out;
    case Op::SP:
      speed_level_ = c.level;
      if (c.high) high_acceleration_ = *c.high;  // kept; the arm's motions have no acceleration setting
      return out;
    case Op::TL:
      tool_length_mm_ = c.tool_length;
      return out;
    case Op::WH:
      out.reply = where();
      return out;
    case Op::ER:
      out.reply = std::to_string(error_);
      return out;
    case Op::RS:
      error_ = kNoError;
      return out;
    case Op::OB:
      arm_.set_output(std::abs(c.bit), c.bit > 0);
      return out;
    case Op::TB:
    case Op::GT:
    case Op::ED:
    case Op::RN:
    case Op::NW:
      return out;  // the program's (movemaster/program.hpp)
  }
  return out;
}

std::optional<std::vector<double>> Executor::solve(const Pose5& pose, std::string& why) const {
  const std::optional<Eigen::Isometry3d> tool = tool_frame(page_angles(pose));
  if (!tool) {
    why = fmt::format("the tool point ({:.1f}, {:.1f}) mm is on the base's z axis: it has no azimuth", pose.x, pose.y);
    return std::nullopt;
  }
  Eigen::Isometry3d in_world = *tool;
  in_world.translation() -= tool_offset() * tool->linear().col(2);
  // From the controller's world and tool point to the arm's base frame and chain tip.
  const Eigen::Isometry3d tip = conventions_.world * in_world * conventions_.tool.inverse();
  const std::vector<double> now = arm_.joints();
  const Eigen::VectorXd seed = Eigen::Map<const Eigen::VectorXd>(now.data(), static_cast<Eigen::Index>(now.size()));
  const models::IkResult ik = arm_.chain().inverse(tip, seed);
  if (ik.status != models::IkStatus::kOk) {
    why = fmt::format("unreachable: {}", ik.reason);
    return std::nullopt;
  }
  return std::vector<double>(ik.q.data(), ik.q.data() + ik.q.size());
}

Executed Executor::move(const std::vector<double>& target, bool linear) {
  Executed out;
  const ArmResult r = arm_.move(target, (speed_level_ + 1) / 10.0, linear);
  switch (r.status) {
    case ArmStatus::ok:
      break;
    case ArmStatus::unreachable:
      raise(kPositionError);
      out.error = r.message;
      break;
    case ArmStatus::failed:
    case ArmStatus::timeout:
      raise(kHardwareError);
      out.error = r.message;
      break;
    case ArmStatus::interrupted:
      out.interrupted = true;
      break;
  }
  return out;
}

Executed Executor::grip(bool close) {
  Executed out;
  const ArmResult r = arm_.grip(close);
  if (r.status == ArmStatus::interrupted) {
    out.interrupted = true;
  } else if (!r.ok()) {
    raise(kHardwareError);
    out.error = fmt::format("the gripper failed: {}", r.message);
  } else {
    gripper_closed_ = close;
  }
  return out;
}

std::string Executor::where() const {
  const std::vector<double> now = arm_.joints();
  const Eigen::Isometry3d tip =
      arm_.chain().forward(Eigen::Map<const Eigen::VectorXd>(now.data(), static_cast<Eigen::Index>(now.size())));
  Eigen::Isometry3d tool = conventions_.world.inverse() * tip * conventions_.tool;
  tool.translation() += tool_offset() * tool.linear().col(2);
  const Pose5 p = page_angles(pose_of(tool));
  return fmt::format("{},{},{},{},{}", wh_number(p.x), wh_number(p.y), wh_number(p.z), wh_number(p.p), wh_number(p.r));
}

}  // namespace cellwright::emulate::movemaster
