#include "cellwright/runtime/robot_control.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/safety.hpp"
#include "cellwright/runtime/segment_target.hpp"

namespace cellwright::runtime {

const char* to_string(RobotPhase phase) {
  switch (phase) {
    case RobotPhase::kBringUp:
      return "bring_up";
    case RobotPhase::kReady:
      return "ready";
    case RobotPhase::kResolving:
      return "resolving";
    case RobotPhase::kExecuting:
      return "executing";
    case RobotPhase::kFailed:
      return "failed";
  }
  return "?";
}

namespace {

std::vector<double> to_std(const Eigen::VectorXd& v) {
  return {v.data(), v.data() + v.size()};
}

Eigen::VectorXd to_eigen(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// Whether a move to `next` right after one to `previous` is a straight approach, grasp or lift: between the point
// above something and the point at it, or between the hand-over approach and grasp, of the same object.
bool straight_from(const std::optional<task::Target>& previous, const task::Target& next) {
  if (!previous || previous->object != next.object) return false;
  using K = task::TargetKind;
  const auto pair = [&](K a, K b) {
    return (previous->kind == a && next.kind == b) || (previous->kind == b && next.kind == a);
  };
  return pair(K::kAbove, K::kAt) || pair(K::kHandApproach, K::kHandGrasp);
}

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

void add_once(std::vector<std::string>& names, const std::string& name) {
  if (!contains(names, name)) names.push_back(name);
}

// The symptom a driver's failure shows as (docs/faults.md section 2).
Symptom symptom_of(drivers::ErrorCode error) {
  switch (error) {
    case drivers::ErrorCode::timeout:
      return Symptom::driver_timeout;
    case drivers::ErrorCode::connection_lost:
      return Symptom::link_lost;
    case drivers::ErrorCode::unreachable:
      return Symptom::position_refused;
    case drivers::ErrorCode::unknown:
      return Symptom::unknown_error;
    default:
      return Symptom::driver_fault;
  }
}

}  // namespace

RobotControl::RobotControl(std::size_t index, std::string label, std::string cell_name, drivers::RobotDriver& driver,
                           models::KinematicChain chain, double grip_force, NameMap names,
                           SharedEnvironment& environment, MessageQueue<MotionCommand>& inbox,
                           MessageQueue<RobotStatus>& status_out, EventLog& log, MotionOptions options,
                           bool await_fresh_truth, Coordination* coordination)
    : index_(index),
      label_(std::move(label)),
      cell_(std::move(cell_name)),
      driver_(driver),
      chain_(std::move(chain)),
      grip_force_(grip_force),
      names_(std::move(names)),
      env_(environment),
      inbox_(inbox),
      status_out_(status_out),
      log_(log),
      options_(std::move(options)),
      await_fresh_truth_(await_fresh_truth),
      coordination_(coordination) {
  CW_CHECK(options_.speed > 0.0 && options_.speed <= 1.0, "motion speed {} outside (0, 1]", options_.speed);
  CW_CHECK(options_.position_tolerance > 0.0, "position tolerance {} must be positive", options_.position_tolerance);
  CW_CHECK(options_.read_line_share >= 0.0 && options_.read_line_share <= 1.0, "read line share {} outside [0, 1]",
           options_.read_line_share);
}

void RobotControl::connect() {
  if (driver_.state() != drivers::DriverState::disconnected) return;
  const drivers::ErrorCode e = driver_.connect();  // throws InputError when the configuration cannot work
  CW_CHECK(e == drivers::ErrorCode::none, "robot {}: connect() refused: {}", cell_, drivers::to_string(e));
}

std::string RobotControl::bound(const std::string& label) const {
  if (auto it = instances_.find(label); it != instances_.end()) return it->second;
  if (auto it = names_.objects.find(label); it != names_.objects.end()) return it->second;
  if (auto it = names_.robots.find(label); it != names_.robots.end()) return it->second;
  return label;
}

bool RobotControl::bind_class(SimDuration now, const task::Primitive& p) {
  const bool to_part = p.kind == task::PrimitiveKind::kMove &&
                       (p.target.kind == task::TargetKind::kAbove || p.target.kind == task::TargetKind::kAt);
  const std::string& label = to_part ? p.target.object : p.workpiece;
  if (!to_part && p.kind != task::PrimitiveKind::kClose) return true;
  const auto cls = names_.classes.find(label);
  if (cls == names_.classes.end() || instances_.count(label) != 0) return true;
  std::string part;
  if (to_part) {
    // Parts further than this from the class's location have not arrived there yet.
    constexpr double kReach = 0.25;
    part = env_.write([&](EnvironmentModel& m) {
      const CellLocation* at = m.find_location(cls->second);
      CW_CHECK(at != nullptr, "class {} arrives at {}, which the cell model does not have", label, cls->second);
      WorkpieceState* best = nullptr;
      double best_d = kReach;
      for (WorkpieceState& w : m.workpieces) {
        if (!w.present || w.lost || !w.held_by.empty() || !w.claimed_by.empty()) continue;
        const Eigen::Vector3d bottom = w.pose.translation() - Eigen::Vector3d(0, 0, w.size().z() / 2);
        const Eigen::Vector3d d = bottom - at->pose.translation();
        if (std::abs(d.z()) > 0.1) continue;
        if (const double h = d.head<2>().norm(); h < best_d) {
          best_d = h;
          best = &w;
        }
      }
      if (best == nullptr) return std::string();
      best->claimed_by = cell_;
      return best->name;
    });
  } else if (!hand_peer_.empty()) {
    // A Get: the part the giver holds; if it holds none (it lost it, and skips its hand-over), the part it took for
    // it, so that the taker skips too.
    part = env_.write([&](EnvironmentModel& m) {
      const RobotState* giver = m.find_robot(hand_peer_);
      if (giver == nullptr) return std::string();
      WorkpieceState* w = nullptr;
      if (giver->hold) {
        w = m.find_workpiece(giver->hold->workpiece);
      } else {
        for (WorkpieceState& c : m.workpieces) {
          if (c.claimed_by == hand_peer_) w = &c;
        }
      }
      if (w == nullptr) return std::string();
      w->claimed_by = cell_;
      return w->name;
    });
  }
  if (part.empty()) return false;
  instances_[label] = part;
  misplace_checked_.erase(std::remove(misplace_checked_.begin(), misplace_checked_.end(), part),
                          misplace_checked_.end());  // a new part, though maybe the same body as before
  log_.sensor(now, label_, current_->command.index, "bound", part);  // the class's part is `part` from now on
  return true;
}

void RobotControl::unbind_part(const std::string& part) {
  if (part.empty()) return;
  bool was_bound = false;
  for (auto it = instances_.begin(); it != instances_.end();) {
    if (it->second == part) {
      it = instances_.erase(it);
      was_bound = true;
    } else {
      ++it;
    }
  }
  if (!was_bound) return;
  env_.write([&](EnvironmentModel& m) {
    if (WorkpieceState* w = m.find_workpiece(part); w != nullptr && w->claimed_by == cell_) w->claimed_by.clear();
  });
}

void RobotControl::report(SimDuration now, CommandOutcome outcome, std::string reason) {
  RobotStatus s;
  s.robot = index_;
  s.index = current_ ? current_->command.index : RobotStatus::kNoCommand;
  s.outcome = outcome;
  s.reason = std::move(reason);
  s.time = now;
  // The status queue holds one entry per robot at least, and a robot reports one status per command; closed means
  // the run is over and nobody listens any more.
  const QueueStatus pushed = status_out_.try_push(std::move(s));
  CW_CHECK(pushed == QueueStatus::ok || pushed == QueueStatus::closed, "robot {}: status queue refused: {}", label_,
           to_string(pushed));
}

void RobotControl::bring_up(SimDuration now) {
  const auto failed = [&](std::string why) {
    phase_ = RobotPhase::kFailed;
    report(now, CommandOutcome::kFailed, fmt::format("driver of {} could not be brought up: {}", cell_, why));
  };
  for (;;) {
    switch (driver_.state()) {
      case drivers::DriverState::active:
        phase_ = RobotPhase::kReady;
        return;
      case drivers::DriverState::connected:
      case drivers::DriverState::stopped:
        if (home_id_ == 0) {
          const drivers::Submitted s = driver_.home();
          if (!s.accepted()) return failed(fmt::format("home refused: {}: {}", drivers::to_string(s.error), s.message));
          home_id_ = s.id;
        }
        [[fallthrough]];
      case drivers::DriverState::homed: {
        if (home_id_ != 0) {
          const drivers::CommandStatus st = driver_.poll(home_id_);
          if (st.phase == drivers::CommandPhase::failed) {
            return failed(fmt::format("homing failed: {}: {}", drivers::to_string(st.error), st.message));
          }
          if (st.phase != drivers::CommandPhase::done) return;  // homing: next turn
        }
        if (driver_.state() != drivers::DriverState::homed) return;
        const drivers::ErrorCode e = driver_.activate();
        if (e != drivers::ErrorCode::none) return failed(fmt::format("activate refused: {}", drivers::to_string(e)));
        continue;
      }
      case drivers::DriverState::disconnected:
      case drivers::DriverState::fault:
        return failed(fmt::format("the driver is {}", drivers::to_string(driver_.state())));
    }
  }
}

void RobotControl::log_start(SimDuration now) {
  if (!current_ || current_->start_logged) return;
  const task::Primitive& p = current_->command.primitive;
  log_.command_start(now, label_, current_->command.index, task::to_string(p), p.task, p.motion, current_->detail);
  current_->start_logged = true;
}

void RobotControl::fail(SimDuration now, std::string reason) {
  if (recovery_) end_recovery(now, false, reason);
  log_start(now);
  log_.command_end(now, label_, current_->command.index, task::to_string(current_->command.primitive), false, reason);
  report(now, CommandOutcome::kFailed, std::move(reason));
  current_.reset();
  phase_ = RobotPhase::kFailed;
}

std::optional<RobotControl::Goal> RobotControl::choose_goal(const MotionTarget& target,
                                                            const std::vector<double>& joints,
                                                            const Eigen::Isometry3d& base, std::string* why) const {
  const drivers::Capabilities& caps = driver_.capabilities();
  Goal goal;
  if (!target.joints.empty()) {
    goal.joints = target.joints;
    goal.pose_in_base = chain_.forward(to_eigen(goal.joints));
    return goal;
  }
  CW_CHECK(joints.size() == chain_.dof(), "robot {}: {} joints in the model, {} in the kinematics", cell_,
           joints.size(), chain_.dof());
  const Eigen::VectorXd seed = to_eigen(joints);
  std::optional<models::IkResult> best;
  int best_rank = 0;
  std::string reason;
  for (std::size_t i = 0; i < target.poses.size(); ++i) {
    const int rank = i < target.rank.size() ? target.rank[i] : 0;
    if (best && rank > best_rank) continue;  // a better-ranked pose is already reachable
    const Eigen::Isometry3d in_base = base.inverse() * target.poses[i];
    if (!caps.full_orientation && drivers::out_of_arm_plane(in_base) > options_.arm_plane_tolerance) {
      // A 5-axis arm's yaw follows its position: its controller could not be told this orientation.
      if (reason.empty()) {
        reason = fmt::format(
            "the tool's approach axis is {:.1f} deg out of the arm's vertical plane, and {} cannot "
            "turn it there (5 axes)",
            drivers::out_of_arm_plane(in_base) * 180 / M_PI, cell_);
      }
      continue;
    }
    models::IkResult ik = chain_.inverse(in_base, seed, options_.ik);
    if (ik.status != models::IkStatus::kOk) {
      if (reason.empty()) reason = ik.reason;
      continue;
    }
    if (!best || rank < best_rank || (ik.q - seed).norm() < (best->q - seed).norm()) {
      best = std::move(ik);
      best_rank = rank;
      goal.pose_in_base = in_base;
    }
  }
  if (!best) {
    if (why != nullptr) *why = reason;
    return std::nullopt;
  }
  goal.joints = to_std(best->q);
  return goal;
}

bool RobotControl::submit_current(SimDuration now) {
  const task::Primitive& p = active();
  const drivers::Capabilities& caps = driver_.capabilities();
  drivers::Command cmd;
  if (!bind_class(now, p)) {
    const std::string& cls = p.kind == task::PrimitiveKind::kMove ? p.target.object : p.workpiece;
    phase_ = RobotPhase::kResolving;
    current_->waiting_for = fmt::format("no part of {} has arrived at {} yet", cls, names_.classes.at(cls));
    log_start(now);
    if (!current_->wait_logged) {
      log_.sensor(now, label_, current_->command.index, "waiting_for_part", cls);
      current_->wait_logged = true;
    }
    watch_wait(now, current_->waiting_for);
    return false;
  }
  if (!current_->step && !recovery_ && about_lost_part()) {  // the class's part just bound is one declared lost
    skip_current(now, "its workpiece is lost");
    return false;
  }
  if (p.segment && !current_->step) {
    std::optional<drivers::Command> c = segment_command(now);
    if (!c) return false;
    cmd = std::move(*c);
  } else if (p.kind == task::PrimitiveKind::kMove) {
    task::Target target = p.target;
    target.object = bound(target.object);
    if (target.kind == task::TargetKind::kHandApproach || target.kind == task::TargetKind::kHandGrasp) {
      hand_peer_ = target.object;
    }
    struct Seen {
      MotionTarget target;
      std::vector<double> joints;
      Eigen::Isometry3d base;
    };
    const Seen seen = env_.read([&](const EnvironmentModel& m) {
      const RobotState* r = m.find_robot(cell_);
      return Seen{resolve_target(m, cell_, target, options_.targets), r ? r->joints : std::vector<double>{},
                  r ? r->base() : Eigen::Isometry3d::Identity()};
    });
    if (seen.target.resolution == MotionTarget::Resolution::kWait) {
      phase_ = RobotPhase::kResolving;
      current_->waiting_for = seen.target.reason;
      log_start(now);
      if (!current_->wait_logged) {
        log_.sensor(
            now, label_, current_->command.index, "waiting_for_part",
            target.kind == task::TargetKind::kAbove || target.kind == task::TargetKind::kAt ? target.object : "");
        current_->wait_logged = true;
      }
      // A part that is not in the cell for part_wait has not arrived (one riding a belt is on its way).
      const bool part_target = target.kind == task::TargetKind::kAbove || target.kind == task::TargetKind::kAt;
      const bool absent = part_target && env_.read([&](const EnvironmentModel& m) {
        const WorkpieceState* w = m.find_workpiece(target.object);
        return w != nullptr && !w->present;
      });
      if (!absent) {
        current_->waiting_since.reset();
      } else if (!current_->waiting_since) {
        current_->waiting_since = now;
      } else if (options_.recovery.enabled && now - *current_->waiting_since >= options_.recovery.part_wait) {
        symptom(now, Symptom::part_not_arrived,
                fmt::format("{} has not been in the cell for {} s: {}", target.object,
                            format_sim_time(now - *current_->waiting_since), seen.target.reason),
                target.object);
        return false;
      }
      watch_wait(now, seen.target.reason);
      return false;
    }
    current_->waiting_since.reset();
    if (seen.target.resolution == MotionTarget::Resolution::kFail) {
      fail(now, seen.target.reason);
      return false;
    }
    // Not on a recovery step: a pick_again goes to the part where it is seen anyway, and a symptom here would replace
    // the recovery under way (its remaining steps lost).
    if (options_.recovery.enabled && !current_->step) {
      const std::uint64_t before = symptoms_;
      check_misplaced(now, target);
      if (!current_ || (symptoms_ != before && recovery_)) return false;  // the check started a recovery
    }
    std::string why;
    const std::optional<Goal> goal = choose_goal(seen.target, seen.joints, seen.base, &why);
    if (!goal) {
      const std::string reason = fmt::format("{} is unreachable for {}: {}", seen.target.description, cell_, why);
      const bool is_part = env_.read([&](const EnvironmentModel& m) { return m.find_workpiece(target.object) != nullptr; });
      if (options_.recovery.enabled) {
        symptom(now, Symptom::target_unreachable, reason, is_part ? target.object : std::string());
      } else {
        fail(now, reason);
      }
      return false;
    }
    // The driver solves its own IK for a pose and may pick another configuration: such a move is checked on the tool.
    const bool pose_command = caps.cartesian_control && (caps.prefers_pose || !caps.joint_control);
    if (!pose_command && !caps.joint_control) {
      fail(now, fmt::format("the driver of {} takes neither joint nor pose motions", cell_));
      return false;
    }
    cmd = move_command(*goal, pose_command, caps.linear_motion && straight_from(last_target_, target), target);
  } else {
    cmd = grip_command(p.kind);
  }
  const drivers::Submitted s = driver_.submit(cmd);
  current_->detail = drivers::describe(cmd);
  if (s.error == drivers::ErrorCode::busy) return false;  // its queue is full (a position read, say): next turn
  if (!s.accepted()) {
    // Refused by a driver that went to fault on a position read after this turn's collect_position looked (the
    // driver fails the read and enters fault at once): the read's failure is the cause, and collect_position reports
    // it.
    if (driver_.state() == drivers::DriverState::fault && collect_position(now)) return false;
    std::string reason =
        fmt::format("the driver refused '{}': {}: {}", current_->detail, drivers::to_string(s.error), s.message);
    if (driver_.state() == drivers::DriverState::fault && !last_failure_.empty()) {
      reason += fmt::format(" ({})", last_failure_);  // why it is in fault, if a read-back said
    }
    if (options_.recovery.enabled && driver_.state() == drivers::DriverState::fault) {
      symptom(now, Symptom::driver_fault, reason, std::string());
    } else {
      fail(now, reason);
    }
    return false;
  }
  if (p.segment && !current_->step) {
    const bool master = p.segment->master == label_;
    coordination_->taken(p.segment->block, segments_submitted_[p.segment->block]++, master);
    if (p.segment->index == p.segment->count) {  // the block's last segment
      carry_.erase(p.segment->block);
      coordination_->forget_carry(p.segment->block);
    }
  }
  current_->id = s.id;
  current_->submitted_at = now;
  current_->reads_at_submit = reads_asked_;
  current_->stalled_since.reset();
  if (!current_->baseline_taken && !current_->step) {
    current_->baseline_taken = true;
    env_.read([&](const EnvironmentModel& m) {
      if (const RobotState* r = m.find_robot(cell_)) {
        current_->joints_at_start = r->joints;
        current_->force_at_start = r->wrist_force;
      }
    });
  }
  phase_ = RobotPhase::kExecuting;
  log_start(now);
  if (current_->wait_logged && !current_->ready_logged) {  // the part it waited for is there: the wait ends now
    const bool to_part = p.kind != task::PrimitiveKind::kMove || p.target.kind == task::TargetKind::kAbove ||
                         p.target.kind == task::TargetKind::kAt;
    log_.sensor(now, label_, current_->command.index, "part_ready",
                to_part ? bound(p.kind == task::PrimitiveKind::kMove ? p.target.object : p.workpiece) : "");
    current_->ready_logged = true;
  }
  return true;
}

drivers::Command RobotControl::move_command(const Goal& goal, bool pose_command, bool linear,
                                            const task::Target& target) {
  current_->goal = goal.joints;
  current_->goal_pose = goal.pose_in_base;
  current_->pose_command = pose_command;
  current_->target = target;
  if (!pose_command) return drivers::MoveJoints{goal.joints, options_.speed};
  return drivers::MovePose{goal.pose_in_base, linear ? drivers::Path::linear : drivers::Path::joint, options_.speed};
}

drivers::Command RobotControl::grip_command(task::PrimitiveKind kind) const {
  const drivers::Capabilities& caps = driver_.capabilities();
  drivers::Grip grip;
  grip.action = kind == task::PrimitiveKind::kClose ? drivers::Grip::Action::close : drivers::Grip::Action::open;
  if (caps.gripper_force && grip_force_ > 0.0) grip.force = std::min(grip_force_, caps.gripper_max_force);
  return grip;
}

std::optional<drivers::Command> RobotControl::segment_command(SimDuration now) {
  const task::Primitive& p = current_->command.primitive;
  const task::Segment& seg = *p.segment;
  const bool master = seg.master == label_;
  if (coordination_ == nullptr) {
    fail(now, fmt::format("coordinated block {}: this run has no coordination between its robots", seg.block));
    return std::nullopt;
  }
  const std::uint64_t n = segments_submitted_[seg.block];
  if (Carry& carry = carry_[seg.block]; carry.master.empty()) {  // the block's robots, once per carry
    carry.master = seg.master;
    carry.follower = seg.follower;
    carry.master_cell = names_.robots.at(seg.master);
    carry.follower_cell = names_.robots.at(seg.follower);
  }
  const drivers::Capabilities& caps = driver_.capabilities();
  if (!current_->prepared) {
    drivers::Command cmd;
    std::optional<Eigen::Isometry3d> target_world;
    if (p.kind == task::PrimitiveKind::kMove) {
      std::optional<Eigen::Isometry3d> master_target;
      if (!master) {
        const std::optional<SegmentPost> mp = coordination_->master_post(seg.block, n);
        if (!mp) {
          phase_ = RobotPhase::kResolving;
          current_->waiting_for = fmt::format("{}'s target for segment {} of {}", seg.master, seg.index, seg.block);
          return std::nullopt;
        }
        master_target = mp->target;
      }
      task::Target target = p.target;
      target.object = bound(target.object);
      bool linear = false;
      const MotionTarget resolved = segment_target(target, seg, master_target, &linear);
      if (resolved.resolution == MotionTarget::Resolution::kWait) {
        phase_ = RobotPhase::kResolving;
        current_->waiting_for = resolved.reason;
        return std::nullopt;
      }
      if (resolved.resolution == MotionTarget::Resolution::kFail) {
        fail(now, fmt::format("coordinated block {}, segment {}: {}", seg.block, seg.index, resolved.reason));
        return std::nullopt;
      }
      const auto [joints, base] = env_.read([&](const EnvironmentModel& m) {
        const RobotState* r = m.find_robot(cell_);
        return std::pair{r->joints, r->base()};
      });
      std::string why;
      const std::optional<Goal> goal = choose_goal(resolved, joints, base, &why);
      if (!goal) {
        fail(now, fmt::format("coordinated block {}, segment {}: {} is unreachable for {}: {}", seg.block, seg.index,
                              resolved.description, cell_, why));
        return std::nullopt;
      }
      const bool pose_command =
          caps.cartesian_control && ((linear && caps.linear_motion) || caps.prefers_pose || !caps.joint_control);
      cmd = move_command(*goal, pose_command, linear && caps.linear_motion, target);
      target_world = base * goal->pose_in_base;
    } else {
      cmd = grip_command(p.kind);
    }
    const std::optional<double> least = driver_.least_duration(cmd);
    if (!least) {
      const drivers::Refusal refusal = drivers::check_command(cmd, caps);
      fail(now, fmt::format("coordinated block {}, segment {}: the driver of {} cannot tell how long '{}' takes{}{}",
                            seg.block, seg.index, cell_, drivers::describe(cmd),
                            caps.timed_motion ? "" : " (its moves cannot be timed, which moving together needs)",
                            refusal ? ": " + refusal.message : std::string()));
      return std::nullopt;
    }
    current_->prepared = cmd;
    coordination_->post(seg.block, n, master, SegmentPost{master ? target_world : std::nullopt, *least, now});
  }
  const std::optional<double> agreed = coordination_->agreed(seg.block, n, now);
  if (!agreed) {
    phase_ = RobotPhase::kResolving;
    current_->waiting_for = fmt::format("{} to be ready for segment {} of {}", master ? seg.follower : seg.master,
                                        seg.index, seg.block);
    return std::nullopt;
  }
  drivers::Command cmd = *current_->prepared;
  if (auto* m = std::get_if<drivers::MoveJoints>(&cmd)) m->duration = *agreed;
  if (auto* m = std::get_if<drivers::MovePose>(&cmd)) m->duration = *agreed;
  return cmd;
}

MotionTarget RobotControl::segment_target(const task::Target& target, const task::Segment& seg,
                                          const std::optional<Eigen::Isometry3d>& master_target, bool* linear) {
  Carry& carry = carry_[seg.block];
  const bool measured = carry.targets.grasp.has_value();
  const MotionTarget out = env_.read([&](const EnvironmentModel& m) {
    SegmentMove move;
    move.robot = cell_;
    move.master = names_.robots.at(seg.master);
    move.is_master = seg.master == label_;
    if (const RobotState* self = m.find_robot(cell_)) move.tool = tool_in_world(*self);
    if (const RobotState* lead = m.find_robot(move.master)) move.master_tool = lead->tcp;
    move.master_target = master_target;
    return resolve_segment_target(m, target, seg, move, carry.targets, options_.targets, linear);
  });
  if (!measured && carry.targets.grasp) coordination_->set_grasp(seg.block, *carry.targets.grasp);  // the safety watch
  return out;
}

void RobotControl::complete(SimDuration now) {
  const task::Primitive& p = active();
  const std::size_t index = current_->command.index;
  if (!current_->done_seen) {
    current_->done_seen = now;
    current_->reads_at_done = reads_asked_;
  }
  if (p.kind != task::PrimitiveKind::kMove && await_fresh_truth_ &&
      env_.read([](const EnvironmentModel& m) { return m.time; }) <= *current_->done_seen) {
    return;  // the grip sensors of the step that completed the command are not in the model yet: check next turn
  }
  if (p.kind == task::PrimitiveKind::kMove) {
    if (!check_position(now)) return;  // waiting for the read-back, or failed
    if (current_->target) last_target_ = current_->target;
    if (options_.recovery.enabled && check_shift(now)) return;  // the part is gone from the hand: recovering
  } else if (p.kind == task::PrimitiveKind::kClose) {
    const std::string expected = p.workpiece.empty() ? std::string() : bound(p.workpiece);
    const std::optional<GripReading> between =
        env_.read([&](const EnvironmentModel& m) { return m.find_robot(cell_)->grip; });
    std::string held;
    if (!between) {
      log_.sensor(now, label_, index, "grip_not_sensed", expected);
      held = expected;
    } else if (!between->on_part) {
      log_.sensor(now, label_, index, "closed_on_nothing", "");
      if (!expected.empty()) {
        const std::string why = fmt::format("the gripper closed on nothing (expected {})", expected);
        if (options_.recovery.enabled) return symptom(now, Symptom::closed_on_nothing, why, expected);
        return fail(now, why);
      }
    } else if (!expected.empty() && !between->holds(expected)) {
      log_.sensor(now, label_, index, "closed_on_wrong_part", between->part);
      const std::string why = fmt::format("the gripper closed on {}, expected {}", between->part, expected);
      if (options_.recovery.enabled) return symptom(now, Symptom::closed_on_wrong_part, why, expected);
      return fail(now, why);
    } else {
      // A sensor that cannot name the part (a jaw switch) says only "on something": the part expected.
      held = between->part.empty() ? expected : between->part;
      log_.sensor(now, label_, index, "gripped", held);
    }
    if (!held.empty()) {
      env_.write([&](EnvironmentModel& m) {
        RobotState* r = m.find_robot(cell_);
        WorkpieceState* w = m.find_workpiece(held);
        if (r == nullptr || w == nullptr) return;
        const Eigen::Isometry3d tcp = tool_in_world(*r);
        Hold hold;
        hold.workpiece = held;
        // Tool axis pointing mostly down: a grasp from above; otherwise from the side.
        hold.approach = tcp.linear().col(2).z() < -0.7 ? models::Approach::kDown : models::Approach::kSide;
        hold.tcp_above_bottom = tcp.translation().z() - (w->pose.translation().z() - w->size().z() / 2);
        hold.in_hand = tcp.inverse() * w->pose;
        r->hold = hold;
        r->dropped_hold.reset();
        r->released_tcp.reset();
        w->held_by = cell_;
      });
      grip_missing_ = 0;
      shift_reported_ = false;
    }
  } else if (p.kind == task::PrimitiveKind::kOpen) {
    const std::string released = env_.write([&](EnvironmentModel& m) {
      RobotState* r = m.find_robot(cell_);
      if (r == nullptr || !r->hold) return std::string();
      r->released_tcp = tool_in_world(*r);
      std::string name = r->hold->workpiece;
      if (WorkpieceState* w = m.find_workpiece(name); w != nullptr && w->held_by == cell_) w->held_by.clear();
      r->hold.reset();
      return name;
    });
    log_.sensor(now, label_, index, "released", released);
    unbind_part(released);
  }
  if (current_->step) {
    // A recovery step is done: the next one, or the command again (or skipped).
    current_->step.reset();
    reset_submission();
    phase_ = RobotPhase::kReady;
    return;
  }
  if (recovery_) end_recovery(now, true, "");
  log_.command_end(now, label_, index, task::to_string(p), true, "");
  report(now, CommandOutcome::kDone, "");
  current_.reset();
  protective_stops_ = 0;
  phase_ = RobotPhase::kReady;
}

bool RobotControl::check_position(SimDuration now) {
  const std::size_t index = current_->command.index;
  const drivers::Capabilities& caps = driver_.capabilities();
  if (!caps.reads_joints && !caps.reads_pose) {
    log_.sensor(now, label_, index, "position_not_sensed", "");
    return true;
  }
  if (!reading_ || reading_number_ <= current_->reads_at_done) {
    // Only a read asked for once the driver said done shows where the arm stopped.
    if (position_request_ == 0) request_position(now);
    if (options_.recovery.enabled && !halted_ && current_->done_seen &&
        now - *current_->done_seen >= options_.recovery.command_timeout) {
      driver_.stop();
      position_request_ = 0;
      symptom(now, Symptom::driver_timeout,
              fmt::format("no position read-back {} s after '{}' was done", format_sim_time(now - *current_->done_seen),
                          current_->detail),
              std::string());
    }
    return false;
  }
  const drivers::PositionReading& r = *reading_;
  const auto missed = [&](std::string why) {
    log_.sensor(now, label_, index, "position_missed", "");
    const std::string reason = fmt::format("position not reached: {}", why);
    if (options_.recovery.enabled) {
      symptom(now, Symptom::position_missed, reason, std::string());
    } else {
      fail(now, reason);
    }
    return false;
  };
  if (!current_->pose_command && r.joints.size() == current_->goal.size()) {
    std::size_t worst = 0;
    double err = 0;
    for (std::size_t j = 0; j < r.joints.size(); ++j) {
      const double e = std::abs(r.joints[j] - current_->goal[j]);
      if (e > err) {
        err = e;
        worst = j;
      }
    }
    if (err > options_.position_tolerance) {
      return missed(fmt::format("joint {} is {:.4f} rad from its goal (tolerance {:.4f})", worst + 1, err,
                                options_.position_tolerance));
    }
  } else {
    // A pose-commanded robot may reach the pose in another configuration: its tool tells, not its joints.
    std::optional<Eigen::Isometry3d> tool = r.tool_pose;
    if (!tool && r.joints.size() == chain_.dof()) tool = chain_.forward(to_eigen(r.joints));
    if (!tool || !current_->goal_pose) {
      log_.sensor(now, label_, index, "position_not_sensed", "");
      return true;
    }
    const double err = (tool->translation() - current_->goal_pose->translation()).norm();
    if (err > options_.pose_tolerance) {
      return missed(fmt::format("the tool is {:.4f} m from its goal (tolerance {:.4f})", err, options_.pose_tolerance));
    }
    if (r.joints.empty() && current_->goal.size() == chain_.dof()) {
      // No joint read-back: the joints the goal was solved with are the best estimate (they seed the next IK).
      env_.write([&](EnvironmentModel& m) {
        if (RobotState* robot = m.find_robot(cell_)) robot->joints = current_->goal;
      });
    }
  }
  log_.sensor(now, label_, index, "position_reached", "");
  return true;
}

bool RobotControl::request_position(SimDuration now) {
  if (position_request_ != 0) return true;
  const drivers::DriverState st = driver_.state();
  if (st != drivers::DriverState::homed && st != drivers::DriverState::active && st != drivers::DriverState::stopped) {
    return false;
  }
  const drivers::Submitted s = driver_.request_position();
  if (!s.accepted()) return false;  // busy: its queue is full; next turn
  position_request_ = s.id;
  last_request_ = now;
  ++reads_asked_;
  return true;
}

bool RobotControl::collect_position(SimDuration now) {
  if (position_request_ == 0) return false;
  const drivers::CommandStatus st = driver_.poll(position_request_);
  if (st.phase == drivers::CommandPhase::pending || st.phase == drivers::CommandPhase::running) return false;
  position_request_ = 0;
  if (st.phase == drivers::CommandPhase::done) {
    adopt_reading();
    return false;
  }
  last_failure_ = fmt::format("the position read-back failed: {}: {}", drivers::to_string(st.error), st.message);
  // Cancelled: stopped on purpose or behind another failure, which is reported where it happened. A recovery under
  // way reads and resets the driver itself.
  if (st.error == drivers::ErrorCode::cancelled || st.error == drivers::ErrorCode::unknown_command || halted_ ||
      recovery_ || phase_ == RobotPhase::kBringUp) {
    return false;
  }
  // A command in flight reports a failure of its own; idle, a move done and waiting for its read-back, or a command
  // cancelled behind the read (the read's fault is the cause), nothing else would say why.
  if (current_ && current_->id != 0) {
    const drivers::CommandStatus c = driver_.poll(current_->id);
    const bool cancelled = c.phase == drivers::CommandPhase::failed && c.error == drivers::ErrorCode::cancelled;
    if (c.phase != drivers::CommandPhase::done && !cancelled) return false;
  }
  if (options_.recovery.enabled) {
    symptom(now, symptom_of(st.error), last_failure_, std::string());
  } else if (current_) {
    fail(now, last_failure_);
  } else {
    phase_ = RobotPhase::kFailed;
    report(now, CommandOutcome::kFailed, last_failure_);
  }
  return true;
}

void RobotControl::adopt_reading() {
  std::optional<drivers::PositionReading> r = driver_.last_position();
  if (!r || (reading_ && r->request <= reading_->request)) return;
  reading_ = std::move(r);
  reading_number_ = reads_asked_;
  env_.write([&](EnvironmentModel& m) {
    RobotState* robot = m.find_robot(cell_);
    if (robot == nullptr) return;
    if (reading_->joints.size() == chain_.dof()) {
      robot->joints = reading_->joints;
      robot->tcp = robot->base() * chain_.forward(to_eigen(robot->joints));
    } else if (reading_->tool_pose) {
      robot->tcp = robot->base() * *reading_->tool_pose;
    }
  });
}

void RobotControl::poll_current(SimDuration now) {
  const drivers::CommandStatus st = driver_.poll(current_->id);
  switch (st.phase) {
    case drivers::CommandPhase::pending:
    case drivers::CommandPhase::running:
      if (st.phase == drivers::CommandPhase::running) current_->seen_running = true;
      if (options_.recovery.enabled && !halted_ && now - current_->submitted_at >= options_.recovery.command_timeout) {
        driver_.stop();  // what it was doing is abandoned
        return symptom(now, Symptom::driver_timeout,
                       fmt::format("'{}' has not ended {} s after it was sent", current_->detail,
                                   format_sim_time(now - current_->submitted_at)),
                       std::string());
      }
      return;
    case drivers::CommandPhase::failed: {
      // Cancelled behind a position read that failed after this turn's collect_position looked (the driver fails
      // both at once): the read's failure is the cause, and collect_position reports it.
      if (st.error == drivers::ErrorCode::cancelled && collect_position(now)) return;
      const std::string reason = fmt::format("the driver failed '{}': {}: {}", current_->detail,
                                             drivers::to_string(st.error), st.message);
      if (!options_.recovery.enabled || halted_) return fail(now, reason);
      if (protective_ || (recovery_ && recovery_->settle)) {
        reset_submission();  // stopped on purpose: done again once released
        return;
      }
      return symptom(now, symptom_of(st.error), reason, std::string());
    }
    case drivers::CommandPhase::done:
      return complete(now);
  }
}

void RobotControl::start_next(SimDuration now) {
  MotionCommand cmd;
  if (inbox_.try_pop(cmd) != QueueStatus::ok) return;
  CW_CHECK(cmd.robot == index_, "robot {} got a command for robot {}", index_, cmd.robot);
  current_ = Current{};  // not emplace(): clang 14 finds these nested structs not default-constructible
  current_->command = std::move(cmd);
  (void)now;
}

void RobotControl::step(SimDuration now) {
  if (phase_ == RobotPhase::kFailed) return;
  if (options_.safety.enabled && phase_ != RobotPhase::kBringUp) {
    watch_carry(now);
    if (phase_ == RobotPhase::kFailed) return;
  }
  collect_position(now);
  if (phase_ == RobotPhase::kFailed) return;
  track_held_part();
  if (options_.recovery.enabled && phase_ != RobotPhase::kBringUp) {
    watch_safety(now);
    if (phase_ != RobotPhase::kFailed) watch_grip(now);
    if (phase_ == RobotPhase::kFailed) return;
  }
  run_commands(now);
  // The periodic read goes last, so that a read asked for after a completion seen in this turn is the one that
  // checks it.
  if (phase_ != RobotPhase::kFailed && periodic_read_due(now)) request_position(now);
}

bool RobotControl::periodic_read_due(SimDuration now) const {
  const drivers::Capabilities& caps = driver_.capabilities();
  SimDuration period = options_.position_period;
  if (options_.read_line_share > 0.0 && caps.read_time > SimDuration::zero() && !caps.reads_while_moving) {
    if (current_ && current_->id != 0) return false;  // it would wait behind the command, then delay the check's read
    period = std::max(period, std::chrono::duration_cast<SimDuration>(caps.read_time / options_.read_line_share));
  }
  return !last_request_ || now - *last_request_ >= period;
}

void RobotControl::run_commands(SimDuration now) {
  if (phase_ == RobotPhase::kBringUp) {
    bring_up(now);
    if (phase_ != RobotPhase::kReady) return;
  }
  for (;;) {
    if (!current_) {
      if (recovery_ && recovery_->rehome) {
        // A fault sensed while idle (a failed read-back): the driver is brought back before the next command.
        advance_recovery(now);
        if (phase_ == RobotPhase::kFailed || (recovery_ && recovery_->rehome)) return;
      }
      start_next(now);
      if (!current_) return;
    }
    if (current_->id == 0 && !current_->step && !recovery_ && about_lost_part()) {
      skip_current(now, "its workpiece is lost");
      continue;
    }
    if (recovery_ && !advance_recovery(now)) return;
    if (!current_) continue;  // skipped
    if (phase_ == RobotPhase::kFailed) return;
    if (protective_) return;  // the safety layer holds the robot
    if (current_->id == 0 && driver_.state() == drivers::DriverState::stopped) {
      if (driver_.activate() != drivers::ErrorCode::none) return;
    }
    if (current_->id == 0 && !submit_current(now)) return;  // waiting for its target, recovering, or failed
    poll_current(now);
    if (phase_ == RobotPhase::kFailed) return;
    if (current_ && (current_->id != 0 || recovery_)) return;  // still running, or recovering: next turn
  }
}

// ---- Faults ----

const task::Primitive& RobotControl::active() const {
  return current_->step ? *current_->step : current_->command.primitive;
}

void RobotControl::reset_submission() {
  current_->id = 0;
  current_->goal.clear();
  current_->goal_pose.reset();
  current_->done_seen.reset();
  current_->reads_at_done = 0;
  current_->pose_command = false;
  current_->target.reset();
  current_->waiting_since.reset();
  current_->seen_running = false;
  current_->stalled_since.reset();
}

void RobotControl::symptom(SimDuration now, Symptom s, std::string detail, std::string workpiece) {
  if (!options_.recovery.enabled) return fail(now, std::move(detail));
  const int primitive = current_ ? static_cast<int>(current_->command.index) : -1;
  if (current_ && s != Symptom::no_progress && current_->attempts + 1 >= options_.recovery.progress_limit) {
    // Interrupted again and again: the robot makes no progress with this command.
    detail = fmt::format("'{}' interrupted {} times and not done; this time {}: {}",
                         task::to_string(current_->command.primitive), current_->attempts + 1, to_string(s), detail);
    s = Symptom::no_progress;
  }
  ++symptoms_;
  log_.fault_detected(now, label_, primitive, to_string(s), detail);
  bool blocked = false, waiting = false;
  if (current_) {
    blocked = motion_blocked();
    waiting = current_->id == 0 && current_->stalled_since.has_value();
    log_start(now);
    ++current_->attempts;
    current_->step.reset();
    reset_submission();
  }
  const SimDuration detected = recovery_ ? recovery_->detected : now;
  recovery_ = Recovery{};
  recovery_->motion_blocked = blocked;
  recovery_->waiting = waiting;
  recovery_->diagnosis.symptom = s;
  recovery_->detected = detected;
  recovery_->workpiece = std::move(workpiece);
  recovery_->detail = std::move(detail);
  if (s == Symptom::grip_lost) {
    // Stop carrying and let the part come to rest before asking where it is.
    driver_.stop();
    env_.write([&](EnvironmentModel& m) {
      RobotState* r = m.find_robot(cell_);
      if (r != nullptr) r->dropped_hold = std::exchange(r->hold, std::nullopt);
      WorkpieceState* w = m.find_workpiece(recovery_->workpiece);
      if (w != nullptr && w->held_by == cell_) w->held_by.clear();
    });
    recovery_->settle = true;
    return;
  }
  diagnose_and_act(now);
}

bool RobotControl::answer(Question q) const {
  const std::string& part = recovery_->workpiece;
  switch (q) {
    case Question::part_seen:
      return env_.read([&](const EnvironmentModel& m) {
        const WorkpieceState* w = m.find_workpiece(part);
        return w != nullptr && w->present && !w->lost;
      });
    case Question::part_at_rest:
      return env_.read([&](const EnvironmentModel& m) {
        const WorkpieceState* w = m.find_workpiece(part);
        return w != nullptr && w->motion_known && w->velocity.norm() <= options_.targets.part_at_rest_speed;
      });
    case Question::part_upright:
      return env_.read([&](const EnvironmentModel& m) {
        const WorkpieceState* w = m.find_workpiece(part);
        return w != nullptr && stands_upright(*w);
      });
    case Question::part_reachable: {
      // A grasp from above fits only a part standing up.
      if (part.empty() || !answer(Question::part_upright)) return false;
      task::Target above{task::TargetKind::kAbove, part};
      task::Target at{task::TargetKind::kAt, part};
      return reachable(above) && reachable(at);
    }
    case Question::part_in_hand:
      return env_.read([&](const EnvironmentModel& m) {
        const RobotState* r = m.find_robot(cell_);
        return r != nullptr && r->grip && r->grip->holds(part);
      });
    case Question::driver_in_fault:
      return driver_.state() == drivers::DriverState::fault;
    case Question::retries_left:
      return !current_ || current_->attempts <= options_.recovery.max_attempts;
    case Question::obstacle_near:
      return env_.read([&](const EnvironmentModel& m) {
        const RobotState* r = m.find_robot(cell_);
        if (r == nullptr || !r->tcp) return !m.obstacles.empty();
        for (const ObstacleState& o : m.obstacles) {
          if (distance_to_box(r->tcp->translation(), o.centre, o.size) < 0.5) return true;
        }
        return false;
      });
    case Question::signal_fired:
      return false;  // task control's question
    case Question::motion_blocked:
      return recovery_->motion_blocked;
    case Question::waiting_for_part:
      return recovery_->waiting;
    case Question::part_lost:
      return !part.empty() && !contains(excused_, part) &&
             env_.read([&](const EnvironmentModel& m) {
               const WorkpieceState* w = m.find_workpiece(part);
               return w != nullptr && w->lost;
             });
  }
  return false;
}

bool RobotControl::reachable(const task::Target& target) const {
  struct Seen {
    MotionTarget target;
    std::vector<double> joints;
    Eigen::Isometry3d base;
  };
  TargetOptions targets = options_.targets;
  const Seen seen = env_.read([&](const EnvironmentModel& m) {
    const RobotState* r = m.find_robot(cell_);
    // Asked as if the hand were empty: the part is to be picked.
    EnvironmentModel copy = m;
    if (RobotState* rc = copy.find_robot(cell_)) {
      rc->hold.reset();
      rc->released_tcp.reset();
    }
    if (WorkpieceState* w = copy.find_workpiece(target.object)) {
      w->held_by.clear();
      w->velocity.setZero();
    }
    return Seen{resolve_target(copy, cell_, target, targets), r ? r->joints : std::vector<double>{},
                r ? r->base() : Eigen::Isometry3d::Identity()};
  });
  if (seen.target.resolution != MotionTarget::Resolution::kOk) return false;
  return choose_goal(seen.target, seen.joints, seen.base, nullptr).has_value();
}

void RobotControl::diagnose_and_act(SimDuration now) {
  Recovery& r = *recovery_;
  const DecisionTree& tree = options_.recovery.tree ? *options_.recovery.tree : DecisionTree::standard();
  const Diagnosis d = tree.diagnose(r.diagnosis.symptom, [&](Question q) { return answer(q); });
  r.diagnosis = d;
  log_.diagnosis(now, label_, to_string(d.symptom), d.cause, to_string(d.action), d.path);
  const std::string& part = r.workpiece;
  using K = task::PrimitiveKind;
  const auto primitive = [&](K kind, task::TargetKind target = task::TargetKind::kAbove) {
    task::Primitive p;
    p.kind = kind;
    if (kind == K::kMove) p.target = task::Target{target, part};
    if (kind == K::kClose) p.workpiece = part;
    if (current_) {
      p.where = current_->command.primitive.where;
      p.task = current_->command.primitive.task;
    }
    p.motion = "recovery";
    return p;
  };
  switch (d.action) {
    case Action::retry:
      return;  // the command is submitted again (reset_submission was done)
    case Action::reset_rehome: {
      r.rehome = true;
      // Homing takes the arm away from where it stopped: it comes back the way the program brought it there (a
      // straight approach is made from its approach pose again) before the command is done again.
      std::optional<task::Target> back;
      if (current_ && current_->command.primitive.kind == K::kMove) {
        back = current_->command.primitive.target;
      } else {
        back = last_target_;
      }
      const bool grip = current_ && current_->command.primitive.kind != K::kMove;
      if (back) {
        task::Target t = *back;
        const auto step_to = [&](task::TargetKind kind) {
          task::Primitive p = primitive(K::kMove);
          p.target = task::Target{kind, t.object};
          r.steps.push_back(p);
        };
        if (t.kind == task::TargetKind::kAt) step_to(task::TargetKind::kAbove);
        if (t.kind == task::TargetKind::kHandGrasp) step_to(task::TargetKind::kHandApproach);
        if (grip) step_to(t.kind);  // a grip is made where the arm was
      }
      return;
    }
    case Action::wait_clear:
      r.wait_clear = true;
      return;
    case Action::pick_again: {
      r.steps.push_back(primitive(K::kOpen));
      r.steps.push_back(primitive(K::kMove, task::TargetKind::kAbove));
      r.steps.push_back(primitive(K::kMove, task::TargetKind::kAt));
      const bool closing = current_ && current_->command.primitive.kind == K::kClose;
      if (!closing) {
        // Carrying it was interrupted: grasp it again and lift it, then go on with the move.
        r.steps.push_back(primitive(K::kClose));
        r.steps.push_back(primitive(K::kMove, task::TargetKind::kAbove));
      }
      return;
    }
    case Action::adopt_hold: {
      env_.write([&](EnvironmentModel& m) {
        RobotState* rs = m.find_robot(cell_);
        const WorkpieceState* w = m.find_workpiece(part);
        if (rs == nullptr || w == nullptr || !rs->hold || !rs->tcp) return;
        rs->hold->in_hand = rs->tcp->inverse() * w->pose;
        rs->hold->tcp_above_bottom = rs->tcp->translation().z() - (w->pose.translation().z() - w->size().z() / 2);
      });
      const SimDuration took = now - r.detected;
      recovery_.reset();
      log_.recovery_end(now, label_, d.cause, to_string(d.action), true, "the hold follows the part", took);
      return;
    }
    case Action::go_on:
    case Action::resignal: {
      const SimDuration took = now - r.detected;
      const std::string cause = d.cause;
      const std::string action(to_string(d.action));
      recovery_.reset();
      log_.recovery_end(now, label_, cause, action, true, "", took);
      return;
    }
    case Action::set_aside:
      set_aside(now, part, d.cause);
      r.skip = true;
      if (current_) {
        r.steps.clear();
      }
      return;
    case Action::stop_cell:
      return stop_cell(now, fmt::format("{}: {}", d.cause, r.detail));
  }
}

bool RobotControl::advance_recovery(SimDuration now) {
  Recovery& r = *recovery_;
  if (r.settle) {
    const bool rest = env_.read([&](const EnvironmentModel& m) {
      const WorkpieceState* w = m.find_workpiece(r.workpiece);
      return w == nullptr || !w->present || (w->motion_known && w->velocity.norm() <= options_.targets.part_at_rest_speed);
    });
    if (!rest && now - r.detected < std::chrono::seconds(3)) return false;
    r.settle = false;
    diagnose_and_act(now);
    return false;
  }
  if (r.wait_clear) {
    if (protective_) return false;
    r.wait_clear = false;
  }
  if (r.rehome) {
    if (!rehome(now)) return false;
    r.rehome = false;
  }
  if (!current_) return false;  // the recovery waits for the next command
  if (!current_->step && current_->id == 0) {
    if (!r.steps.empty()) {
      current_->step = r.steps.front();
      r.steps.pop_front();
    } else if (r.skip) {
      skip_current(now, fmt::format("its workpiece is lost ({})", r.diagnosis.cause));
      return false;
    }
  }
  return true;
}

bool RobotControl::rehome(SimDuration now) {
  Recovery& r = *recovery_;
  // Starts the steps over from the reset or the read-back; false when the attempts are spent (the cell is stopped).
  const auto start_over = [&](const std::string& why) {
    r.home_id = 0;
    r.read_id = 0;
    r.read_asked.reset();
    r.position_read = false;
    if (!why.empty()) r.last_failure = why;
    if (++r.tries <= options_.recovery.max_attempts) return true;
    stop_cell(now, fmt::format("{}: {}; {} could not be recovered: reset, read-back, homing and activation tried {} "
                               "times; the last failure: {}",
                               r.diagnosis.cause, r.detail, cell_, r.tries - 1, r.last_failure));
    return false;
  };
  // A step's command failed: a failure that put the driver in fault is started over from the reset (next turn).
  const auto step_failed = [&](const std::string& why) {
    r.last_failure = why;
    if (driver_.state() != drivers::DriverState::fault) start_over(why);
    return false;
  };
  if (r.tries == 0 && !start_over("")) return false;
  switch (driver_.state()) {
    case drivers::DriverState::active:
      return true;
    case drivers::DriverState::fault: {
      // A fault again after this recovery's reset (a read-back or the homing failed on the way): start over, saying
      // what failed (the step in flight, else a position read, else only that the driver is in fault).
      if (r.reset_done) {
        std::string why;
        for (const drivers::CommandId id : {r.home_id, r.read_id}) {
          if (id == 0 || !why.empty()) continue;
          if (const drivers::CommandStatus st = driver_.poll(id); st.phase == drivers::CommandPhase::failed) {
            why = fmt::format("{}: {}", drivers::to_string(st.error), st.message);
          }
        }
        if (why.empty()) why = last_failure_;
        if (why.empty()) why = fmt::format("the driver of {} went into fault again", cell_);
        if (!start_over(why)) return false;
      }
      last_failure_.clear();
      r.reset_done = true;
      r.home_id = 0;  // whatever was in flight is gone with the fault: home again
      const drivers::ErrorCode e = driver_.reset();
      // A lost link leaves the driver disconnected with connection_lost (robot_driver.hpp): connect again next.
      const bool link_down =
          e == drivers::ErrorCode::connection_lost && driver_.state() == drivers::DriverState::disconnected;
      if (e != drivers::ErrorCode::none && !link_down) {
        stop_cell(now, fmt::format("the driver of {} could not be reset: {}", cell_, drivers::to_string(e)));
      }
      return false;
    }
    case drivers::DriverState::disconnected: {
      drivers::ErrorCode e = drivers::ErrorCode::none;
      std::string why;
      try {
        e = driver_.connect();
      } catch (const std::exception& ex) {
        why = ex.what();
        e = drivers::ErrorCode::connection_lost;
      }
      if (e != drivers::ErrorCode::none) {
        start_over(fmt::format("the driver of {} could not connect again: {} {}", cell_, drivers::to_string(e), why));
      }
      return false;
    }
    case drivers::DriverState::connected:
    case drivers::DriverState::stopped:
    case drivers::DriverState::homed:
      break;
  }
  // Where the arm stopped, before anything moves it: the model (and a twin's copy of the arm) learns it.
  const drivers::Capabilities& caps = driver_.capabilities();
  if (!r.position_read && (caps.reads_joints || caps.reads_pose)) {
    if (r.read_id == 0) {
      const drivers::Submitted s = driver_.request_position();
      if (s.error == drivers::ErrorCode::busy) return false;  // its queue is full: next turn
      if (!s.accepted()) {
        return step_failed(fmt::format("where {} stopped could not be asked: {}: {}", cell_,
                                       drivers::to_string(s.error), s.message));
      }
      r.read_id = s.id;
      r.read_asked = now;
      ++reads_asked_;
    }
    const drivers::CommandStatus st = driver_.poll(r.read_id);
    if (st.phase == drivers::CommandPhase::failed) {
      r.read_id = 0;
      return step_failed(fmt::format("the read-back of where {} stopped failed: {}: {}", cell_,
                                     drivers::to_string(st.error), st.message));
    }
    if (st.phase != drivers::CommandPhase::done) {
      if (now - *r.read_asked < options_.recovery.command_timeout) return false;
      driver_.stop();  // the read is abandoned
      r.read_id = 0;
      return step_failed(fmt::format("no read-back of where {} stopped {} s after it was asked", cell_,
                                     format_sim_time(now - *r.read_asked)));
    }
    r.read_id = 0;
    r.position_read = true;
    adopt_reading();
    if (current_) {
      const Eigen::Vector3d at = env_.read([&](const EnvironmentModel& m) -> Eigen::Vector3d {
        const RobotState* robot = m.find_robot(cell_);
        if (robot == nullptr) return Eigen::Vector3d::Zero();
        return tool_in_world(*robot).translation();
      });
      log_.sensor(now, label_, current_->command.index, "stopped_at",
                  fmt::format("({:.3f}, {:.3f}, {:.3f})", at.x(), at.y(), at.z()));
    }
  }
  if (driver_.state() != drivers::DriverState::homed || r.home_id != 0) {
    if (r.home_id == 0) {
      // A loaded arm is not sent home: its way home, with the part, may cross another robot's space, and nothing the
      // controller has can check that way (docs/faults.md, reset_rehome).
      struct Loaded {
        std::string part, others;
        Eigen::Vector3d at = Eigen::Vector3d::Zero();
      };
      const Loaded loaded = env_.read([&](const EnvironmentModel& m) {
        Loaded l;
        const RobotState* robot = m.find_robot(cell_);
        if (robot == nullptr || !robot->hold) return l;
        for (const RobotState& o : m.robots) {
          if (o.name != cell_) l.others += (l.others.empty() ? "" : ", ") + o.name;
        }
        if (!l.others.empty()) l.part = robot->hold->workpiece;
        l.at = tool_in_world(*robot).translation();
        return l;
      });
      if (!loaded.part.empty()) {
        stop_cell(now, fmt::format("{}: {}; {} holds {} where it stopped, at ({:.3f}, {:.3f}, {:.3f}): re-homing would "
                                   "carry it along a way no check has cleared of {}; take the part out and home the "
                                   "arm by hand",
                                   r.diagnosis.cause, r.detail, cell_, loaded.part, loaded.at.x(), loaded.at.y(),
                                   loaded.at.z(), loaded.others));
        return false;
      }
      const drivers::Submitted s = driver_.home();
      if (s.error == drivers::ErrorCode::busy) return false;
      if (!s.accepted()) {
        return step_failed(
            fmt::format("{} could not be homed again: {}: {}", cell_, drivers::to_string(s.error), s.message));
      }
      r.home_id = s.id;
    }
    const drivers::CommandStatus st = driver_.poll(r.home_id);
    if (st.phase == drivers::CommandPhase::failed) {
      r.home_id = 0;
      return step_failed(
          fmt::format("{} could not be homed again: {}: {}", cell_, drivers::to_string(st.error), st.message));
    }
    if (st.phase != drivers::CommandPhase::done) return false;
    r.home_id = 0;
    if (driver_.state() == drivers::DriverState::fault) return false;  // a fault on the way: reset next turn
    if (driver_.state() != drivers::DriverState::homed) {
      start_over(fmt::format("the homing of {} ended with the driver {}, not homed", cell_,
                             drivers::to_string(driver_.state())));
      return false;
    }
  }
  if (const drivers::ErrorCode e = driver_.activate(); e != drivers::ErrorCode::none) {
    return step_failed(fmt::format("{} could not be activated again: {}", cell_, drivers::to_string(e)));
  }
  return true;
}

void RobotControl::end_recovery(SimDuration now, bool ok, const std::string& detail) {
  if (!recovery_) return;
  const Recovery r = std::move(*recovery_);
  recovery_.reset();
  log_.recovery_end(now, label_, r.diagnosis.cause, to_string(r.diagnosis.action), ok, detail, now - r.detected);
}

void RobotControl::set_aside(SimDuration now, const std::string& workpiece, const std::string& reason) {
  if (workpiece.empty()) return;
  struct Lost {
    bool now = false;  // declared lost here (not already lost)
    std::optional<Eigen::Vector3d> last_seen;
  };
  const Lost lost = env_.write([&](EnvironmentModel& m) {
    WorkpieceState* w = m.find_workpiece(workpiece);
    if (w == nullptr || w->lost) return Lost{};
    w->lost = true;
    w->lost_reason = reason;
    if (w->held_by == cell_) w->held_by.clear();
    RobotState* r = m.find_robot(cell_);
    if (r != nullptr && r->hold && r->hold->workpiece == workpiece) r->hold.reset();
    if (r != nullptr && r->dropped_hold && r->dropped_hold->workpiece == workpiece) r->dropped_hold.reset();
    return Lost{true, w->present ? std::optional<Eigen::Vector3d>(w->pose.translation()) : std::nullopt};
  });
  if (lost.now) log_.workpiece_lost(now, workpiece, reason, lost.last_seen);
  carrying_lost_ = workpiece;
  add_once(excused_, workpiece);
}

bool RobotControl::motion_blocked() const {
  // The controller took the command and has answered a position request asked after it was sent.
  if (current_->id == 0 || !current_->seen_running || reading_number_ <= current_->reads_at_submit) return false;
  struct Seen {
    std::vector<double> joints;
    std::optional<Eigen::Vector3d> force;
  };
  const Seen seen = env_.read([&](const EnvironmentModel& m) {
    const RobotState* r = m.find_robot(cell_);
    return r == nullptr ? Seen{} : Seen{r->joints, r->wrist_force};
  });
  const auto farthest = [](const std::vector<double>& a, const std::vector<double>& b) {
    double d = 0;
    for (std::size_t j = 0; j < a.size(); ++j) d = std::max(d, std::abs(a[j] - b[j]));
    return d;
  };
  const bool move = active().kind == task::PrimitiveKind::kMove;
  const std::vector<double>& from = current_->joints_at_start;
  if (move && !current_->goal.empty() && seen.joints.size() == current_->goal.size() &&
      from.size() == seen.joints.size() && farthest(seen.joints, from) > options_.position_tolerance &&
      farthest(seen.joints, current_->goal) > options_.position_tolerance) {
    return true;  // it moved, and stands short of its goal
  }
  return seen.force && current_->force_at_start &&
         (*seen.force - *current_->force_at_start).norm() > options_.recovery.contact_force;
}

void RobotControl::watch_wait(SimDuration now, const std::string& why) {
  if (!options_.recovery.enabled || !current_) return;
  if (!current_->stalled_since) {
    current_->stalled_since = now;
    return;
  }
  if (now - *current_->stalled_since < options_.recovery.progress_timeout) return;
  // The part it waits for may be one set aside upstream (a class whose part never comes): the first part declared
  // lost that this robot has skipped no work for is the one the tree asks about (part_lost).
  const std::string lost = env_.read([&](const EnvironmentModel& m) {
    for (const WorkpieceState& w : m.workpieces) {
      if (w.lost && !contains(excused_, w.name)) return w.name;
    }
    return std::string();
  });
  symptom(now, Symptom::no_progress,
          fmt::format("'{}' has waited {} s for its part: {}", task::to_string(active()),
                      format_sim_time(now - *current_->stalled_since), why),
          lost);
}

bool RobotControl::about_lost_part() const {
  const task::Primitive& p = current_->command.primitive;
  std::string part;
  if (p.kind == task::PrimitiveKind::kMove) {
    part = bound(p.target.object);
  } else {
    part = p.workpiece.empty() ? std::string() : bound(p.workpiece);
  }
  if (!carrying_lost_.empty()) return true;
  if (part.empty()) return false;
  return env_.read([&](const EnvironmentModel& m) {
    const WorkpieceState* w = m.find_workpiece(part);
    return w != nullptr && w->lost;
  });
}

void RobotControl::skip_current(SimDuration now, const std::string& reason) {
  const task::Primitive& p = current_->command.primitive;
  const std::size_t index = current_->command.index;
  {
    // This robot has now skipped work for the lost part (Question::part_lost asks about the others).
    std::string part = carrying_lost_;
    if (part.empty()) part = bound(p.kind == task::PrimitiveKind::kMove ? p.target.object : p.workpiece);
    if (!part.empty()) add_once(excused_, part);
  }
  if (p.kind == task::PrimitiveKind::kClose && !p.workpiece.empty() && carrying_lost_.empty()) {
    carrying_lost_ = bound(p.workpiece);  // it would carry it: skip until it releases it
  } else if (p.kind == task::PrimitiveKind::kOpen) {
    carrying_lost_.clear();
    if (!p.workpiece.empty()) unbind_part(bound(p.workpiece));
  }
  if (recovery_) {
    const Recovery r = std::move(*recovery_);
    recovery_.reset();
    log_.recovery_end(now, label_, r.diagnosis.cause, to_string(r.diagnosis.action), true,
                      fmt::format("set aside: {}", r.workpiece), now - r.detected);
  }
  log_.skipped(now, label_, index, task::to_string(p), reason);
  log_start(now);
  log_.command_end(now, label_, index, task::to_string(p), true, "");
  report(now, CommandOutcome::kDone, "");
  current_.reset();
  phase_ = RobotPhase::kReady;
}

void RobotControl::stop_cell(SimDuration now, const std::string& reason) {
  driver_.stop();
  if (recovery_) {
    const Recovery r = std::move(*recovery_);
    recovery_.reset();
    log_.recovery_end(now, label_, r.diagnosis.cause, to_string(r.diagnosis.action), false, reason,
                      now - r.detected);
  }
  RobotStatus s;
  s.robot = index_;
  s.index = current_ ? current_->command.index : RobotStatus::kNoCommand;
  s.outcome = CommandOutcome::kFailed;
  s.reason = reason;
  s.time = now;
  s.stop_cell = true;
  if (current_) {
    log_start(now);
    log_.command_end(now, label_, current_->command.index, task::to_string(current_->command.primitive), false,
                     reason);
  }
  const QueueStatus pushed = status_out_.try_push(std::move(s));
  CW_CHECK(pushed == QueueStatus::ok || pushed == QueueStatus::closed, "robot {}: status queue refused: {}", label_,
           to_string(pushed));
  current_.reset();
  phase_ = RobotPhase::kFailed;
}

void RobotControl::watch_grip(SimDuration now) {
  if (!current_ || current_->step || current_->id == 0 || recovery_) return;
  if (active().kind != task::PrimitiveKind::kMove) return;  // a grip changes what is between the fingers
  if (active().segment && options_.safety.enabled) return;    // a coordinated carry: watch_carry watches both ends
  struct Seen {
    std::optional<Hold> hold;
    std::optional<GripReading> between;
  };
  const Seen seen = env_.read([&](const EnvironmentModel& m) {
    const RobotState* r = m.find_robot(cell_);
    return r == nullptr ? Seen{} : Seen{r->hold, r->grip};
  });
  if (!seen.hold || !seen.between) {
    grip_missing_ = 0;
    return;
  }
  if (!seen.between->holds(seen.hold->workpiece)) {
    if (++grip_missing_ >= options_.recovery.grip_lost_periods) {
      grip_missing_ = 0;
      symptom(now, Symptom::grip_lost,
              fmt::format("the grip sensor lost {} while carrying it ({})", seen.hold->workpiece,
                          seen.between->on_part ? seen.between->part : std::string("nothing between the fingers")),
              seen.hold->workpiece);
    }
    return;
  }
  grip_missing_ = 0;
}

bool RobotControl::check_shift(SimDuration now) {
  const std::optional<std::string> lost = env_.read([&](const EnvironmentModel& m) -> std::optional<std::string> {
    const RobotState* r = m.find_robot(cell_);
    if (r == nullptr || !r->hold || !r->grip || r->grip->holds(r->hold->workpiece)) return std::nullopt;
    return r->hold->workpiece;
  });
  if (lost) {
    // Standing still after a move, the grip sensor misses the part it holds (lost while re-homing, say).
    symptom(now, Symptom::grip_lost, fmt::format("the grip sensor no longer has {} after the move", *lost), *lost);
    return true;
  }
  if (shift_reported_ || options_.track_held_parts) return false;
  struct Seen {
    std::optional<Hold> hold;
    std::optional<Eigen::Isometry3d> tcp, part;
    bool fresh = false;
  };
  const Seen seen = env_.read([&](const EnvironmentModel& m) {
    Seen s;
    const RobotState* r = m.find_robot(cell_);
    if (r == nullptr || !r->hold) return s;
    s.hold = r->hold;
    s.tcp = r->tcp;
    const WorkpieceState* w = m.find_workpiece(r->hold->workpiece);
    if (w != nullptr) {
      s.part = w->pose;
      s.fresh = w->stamp >= m.time;  // measured this period (truth), not carried along by the model
    }
    return s;
  });
  if (!seen.hold || !seen.tcp || !seen.part || !seen.fresh) return false;
  const Eigen::Vector3d expected = (*seen.tcp * seen.hold->in_hand).translation();
  const double off = (seen.part->translation() - expected).norm();
  if (off <= options_.recovery.shift_tolerance) return false;
  shift_reported_ = true;
  return note(now, Symptom::part_shifted,
       fmt::format("{} is {:.4f} m from where the hold puts it (tolerance {:.4f})", seen.hold->workpiece, off,
                   options_.recovery.shift_tolerance),
       seen.hold->workpiece);
}

bool RobotControl::note(SimDuration now, Symptom s, const std::string& detail, const std::string& workpiece) {
  const DecisionTree& tree = options_.recovery.tree ? *options_.recovery.tree : DecisionTree::standard();
  std::optional<Recovery> saved = std::move(recovery_);
  recovery_ = Recovery{};
  recovery_->diagnosis.symptom = s;
  recovery_->detected = now;
  recovery_->workpiece = workpiece;
  recovery_->detail = detail;
  const Diagnosis d = tree.diagnose(s, [&](Question q) { return answer(q); });
  if (d.action != Action::adopt_hold && d.action != Action::go_on) {
    // The tree wants the command interrupted: taken up like any symptom.
    recovery_ = std::move(saved);
    symptom(now, s, detail, workpiece);
    return true;
  }
  ++symptoms_;
  log_.fault_detected(now, label_, current_ ? static_cast<int>(current_->command.index) : -1, to_string(s), detail);
  diagnose_and_act(now);  // acts at once and ends this recovery
  recovery_ = std::move(saved);
  return false;
}

void RobotControl::watch_safety(SimDuration now) {
  if (!options_.safety.enabled) return;
  // A new object in the cell: noted by the robot whose tool is nearest to it.
  struct New {
    std::string name;
    double distance = 0;
    bool nearest = false;  // this robot's tool is the nearest: it notes the obstacle
  };
  const std::vector<New> appeared = env_.read([&](const EnvironmentModel& m) {
    std::vector<New> out;
    const RobotState* self = m.find_robot(cell_);
    if (self == nullptr || !self->tcp) return out;
    for (const ObstacleState& o : m.obstacles) {
      if (std::find(obstacles_seen_.begin(), obstacles_seen_.end(), o.name) != obstacles_seen_.end()) continue;
      const double mine = distance_to_box(self->tcp->translation(), o.centre, o.size);
      bool nearest = true;
      for (const RobotState& r : m.robots) {
        if (r.name != cell_ && r.tcp && distance_to_box(r.tcp->translation(), o.centre, o.size) < mine) nearest = false;
      }
      out.push_back({o.name, mine, nearest});
    }
    return out;
  });
  for (const New& n : appeared) {
    obstacles_seen_.push_back(n.name);
    if (n.nearest) {
      note(now, Symptom::obstacle_seen,
           fmt::format("the safety sensor sees {}, {:.3f} m from the tool of {}", n.name, n.distance, cell_),
           std::string());
    }
  }
  const bool moving = current_ && current_->id != 0 && active().kind == task::PrimitiveKind::kMove;
  if (!moving && !protective_) return;
  const std::vector<double> goal = moving ? current_->goal : std::vector<double>{};
  const SafetyVerdict v = env_.read([&](const EnvironmentModel& m) {
    const RobotState* r = m.find_robot(cell_);
    if (r == nullptr) return SafetyVerdict{};
    // While stopped, the way it was going to take is watched until it is clear.
    const std::vector<double>& to = protective_ ? protective_goal_ : goal;
    return check_safety(m, cell_, chain_, r->joints, to, options_.safety);
  });
  if (v.stop && !protective_ && coordination_ != nullptr) {
    for (const auto& [block, carry] : carry_) {
      if (carry.master.empty()) continue;
      // A robot of a coordinated block stopped for its own reason stops its partner too (watch_carry).
      const std::string why = fmt::format("{} ({}) stopped by the safety layer: {}", label_, cell_, v.reason);
      coordination_->stop(block, why);
      return stop_carry(now, block, why, "protective_stop", v.obstacle ? "obstacle" : "safety_stop", true);
    }
  }
  if (v.stop && !protective_) {
    protective_ = true;
    protective_goal_ = goal;
    protective_since_ = now;
    clear_since_.reset();
    protective_reason_ = v.reason;
    driver_.stop();
    log_.protective_stop(now, label_, v.reason);
    ++protective_stops_;
    if (current_) {
      symptom(now, Symptom::protective_stop, v.reason, std::string());
    }
    return;
  }
  if (!protective_) return;
  if (v.stop) {
    clear_since_.reset();
    if (now - protective_since_ >= options_.recovery.clear_wait) {
      protective_ = false;
      stop_cell(now, fmt::format("the way of {} stayed blocked for {} s: {}", cell_,
                                 format_sim_time(now - protective_since_), v.reason));
    }
    return;
  }
  if (!clear_since_) clear_since_ = now;
  if (now - *clear_since_ < options_.safety.clear_time) return;
  protective_ = false;
  log_.protective_release(now, label_);
  if (driver_.state() == drivers::DriverState::stopped) (void)driver_.activate();
}

void RobotControl::watch_carry(SimDuration now) {
  if (coordination_ == nullptr) return;
  for (auto& [block, carry] : carry_) {
    if (carry.master.empty()) continue;
    if (const std::optional<std::string> why = coordination_->stopped(block)) {
      return stop_carry(now, block, *why, "", "", false);
    }
    if (!coordination_->claim_watch(block, now)) continue;
    struct Seen {
      std::string workpiece;  // "" unless both hold the same workpiece
      CarryHand hands[2];
      std::optional<GripReading> grips[2];
    };
    const Seen seen = env_.read([&](const EnvironmentModel& m) {
      Seen s;
      const RobotState* r[2] = {m.find_robot(carry.master_cell), m.find_robot(carry.follower_cell)};
      if (r[0] == nullptr || r[1] == nullptr || !r[0]->hold || !r[1]->hold ||
          r[0]->hold->workpiece != r[1]->hold->workpiece) {
        return s;
      }
      s.workpiece = r[0]->hold->workpiece;
      for (int i = 0; i < 2; ++i) {
        s.hands[i].tcp = r[i]->tcp;
        s.hands[i].force = r[i]->wrist_force;
        s.grips[i] = r[i]->grip;
      }
      return s;
    });
    if (seen.workpiece.empty()) {  // not carrying (yet, or any more)
      carry.grip_missing[0] = carry.grip_missing[1] = 0;
      carry.seen_at.reset();
      continue;
    }
    CarryHand hands[2] = {seen.hands[0], seen.hands[1]};
    hands[0].label = carry.master;
    hands[0].cell = carry.master_cell;
    hands[1].label = carry.follower;
    hands[1].cell = carry.follower_cell;
    // While this robot opens or closes (and so does its partner: the segment is common), what is between the fingers
    // changes on purpose.
    const bool gripping = current_ && active().kind != task::PrimitiveKind::kMove;
    for (int i = 0; i < 2; ++i) {
      const bool missing = !gripping && seen.grips[i] && !seen.grips[i]->holds(seen.workpiece);
      carry.grip_missing[i] = missing ? carry.grip_missing[i] + 1 : 0;
      hands[i].grip_lost = carry.grip_missing[i] >= options_.recovery.grip_lost_periods;
      if (!hands[i].tcp) continue;
      const Eigen::Vector3d p = hands[i].tcp->translation();
      if (carry.seen_at && now > *carry.seen_at) {
        hands[i].velocity = (p - carry.seen[i]) / std::chrono::duration<double>(now - *carry.seen_at).count();
      }
      carry.seen[i] = p;
    }
    carry.seen_at = now;
    const CarryVerdict v = check_carry(hands[0], hands[1], coordination_->grasp(block), seen.workpiece,
                                       options_.safety);
    if (!v.stop) continue;
    coordination_->stop(block, v.reason);
    return stop_carry(now, block, v.reason, v.symptom, v.cause, true, v.arm);
  }
}

void RobotControl::stop_carry(SimDuration now, const std::string& block, const std::string& reason,
                              const std::string& symptom, const std::string& cause, bool detected,
                              const std::string& arm) {
  driver_.stop();
  log_.protective_stop(now, label_, reason);
  if (detected) {
    ++symptoms_;
    // The fault is the arm's it is on (its partner's, when this robot watched the carry in this period); its
    // command is then not this robot's to name.
    const bool mine = arm.empty() || arm == label_;
    const std::string& robot = mine ? label_ : arm;
    log_.fault_detected(now, robot, mine && current_ ? static_cast<int>(current_->command.index) : -1, symptom,
                        reason);
    log_.diagnosis(now, robot, symptom, cause, "stop_cell", "coordinated_carry=yes");
  }
  stop_cell(now, fmt::format("coordinated block {}: both arms stopped: {}", block, reason));
}

void RobotControl::check_misplaced(SimDuration now, const task::Target& target) {
  if (target.kind != task::TargetKind::kAbove && target.kind != task::TargetKind::kAt) return;
  if (std::find(misplace_checked_.begin(), misplace_checked_.end(), target.object) != misplace_checked_.end()) return;
  struct Seen {
    bool part = false;
    double offset = 0, yaw = 0;
    std::string location;
  };
  const Seen seen = env_.read([&](const EnvironmentModel& m) {
    Seen s;
    const WorkpieceState* w = m.find_workpiece(target.object);
    if (w == nullptr || !w->held_by.empty() || !w->present || w->lost) return s;
    const Eigen::Vector3d bottom = w->pose.translation() - Eigen::Vector3d(0, 0, w->size().z() / 2);
    const CellLocation* at = nullptr;
    double nearest = options_.targets.at_location_tolerance;
    for (const CellLocation& l : m.geometry->locations) {
      const double d = (bottom - l.pose.translation()).norm();
      if (d <= nearest) {
        nearest = d;
        at = &l;
      }
    }
    if (at == nullptr) return s;
    s.part = true;
    s.location = at->name;
    Eigen::Vector3d off = bottom - at->pose.translation();
    off.z() = 0;
    // On a belt, the stop and the part before it decide where along the belt a part comes to rest: only how far it
    // is off to the side tells.
    for (const CellConveyor& c : m.geometry->conveyors) {
      const Eigen::Vector3d local = c.pose.inverse() * bottom;
      if (std::abs(local.x()) <= c.length / 2 && std::abs(local.y()) <= c.width / 2) {
        const Eigen::Vector3d along = c.pose.linear().col(0);
        off -= along * along.dot(off);
        break;
      }
    }
    s.offset = off.norm();
    if (w->shape() == models::Shape::kBox) {
      const Eigen::Vector3d xp = w->pose.linear().col(0);
      const Eigen::Vector3d xl = at->pose.linear().col(0);
      double a = std::atan2(xp.y(), xp.x()) - std::atan2(xl.y(), xl.x());
      const double quarter = M_PI / 2;
      a = std::fmod(std::fmod(a, quarter) + quarter, quarter);
      s.yaw = std::min(a, quarter - a);
    }
    return s;
  });
  if (!seen.part) return;
  misplace_checked_.push_back(target.object);
  if (seen.offset > options_.recovery.misplace_offset || seen.yaw > options_.recovery.misplace_yaw) {
    symptom(now, Symptom::part_misplaced,
            fmt::format("{} rests {:.3f} m and {:.1f} deg off its place at {} (tolerance {:.3f} m, {:.1f} deg)",
                        target.object, seen.offset, seen.yaw * 180 / M_PI, seen.location,
                        options_.recovery.misplace_offset, options_.recovery.misplace_yaw * 180 / M_PI),
            target.object);
  }
}

Eigen::Isometry3d RobotControl::tool_in_world(const RobotState& r) const {
  if (r.tcp) return *r.tcp;
  return r.base() * chain_.forward(to_eigen(r.joints));
}

void RobotControl::track_held_part() {
  if (!options_.track_held_parts) return;
  env_.write([&](EnvironmentModel& m) {
    RobotState* r = m.find_robot(cell_);
    if (r == nullptr || !r->tcp || !r->hold) return;
    WorkpieceState* w = m.find_workpiece(r->hold->workpiece);
    if (w == nullptr) return;
    w->pose = *r->tcp * r->hold->in_hand;
    w->velocity.setZero();
    w->motion_known = true;
    w->stamp = m.time;
  });
}

void RobotControl::halt() {
  halted_ = true;
  driver_.stop();
}

RobotControlView RobotControl::view() const {
  RobotControlView v;
  v.robot = label_;
  v.cell = cell_;
  v.phase = phase_;
  if (current_) {
    v.primitive = current_->command.index;
    v.command = task::to_string(current_->command.primitive);
    v.detail = current_->id == 0 && !current_->waiting_for.empty() ? current_->waiting_for : current_->detail;
  }
  v.driver = driver_.state();
  return v;
}

}  // namespace cellwright::runtime
