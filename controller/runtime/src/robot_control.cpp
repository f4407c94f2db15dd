#include "cellwright/runtime/robot_control.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "cellwright/common/error.hpp"

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

}  // namespace

RobotControl::RobotControl(std::size_t index, std::string label, std::string cell_name, drivers::RobotDriver& driver,
                           models::KinematicChain chain, double grip_force, NameMap names,
                           SharedEnvironment& environment, MessageQueue<MotionCommand>& inbox,
                           MessageQueue<RobotStatus>& status_out, EventLog& log, MotionOptions options,
                           bool await_fresh_truth)
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
      await_fresh_truth_(await_fresh_truth) {
  CW_CHECK(options_.speed > 0.0 && options_.speed <= 1.0, "motion speed {} outside (0, 1]", options_.speed);
  CW_CHECK(options_.position_tolerance > 0.0, "position tolerance {} must be positive", options_.position_tolerance);
}

void RobotControl::connect() {
  if (driver_.state() != drivers::DriverState::disconnected) return;
  const drivers::ErrorCode e = driver_.connect();  // throws InputError when the configuration cannot work
  CW_CHECK(e == drivers::ErrorCode::none, "robot {}: connect() refused: {}", cell_, drivers::to_string(e));
}

std::string RobotControl::bound(const std::string& label) const {
  if (auto it = names_.objects.find(label); it != names_.objects.end()) return it->second;
  if (auto it = names_.robots.find(label); it != names_.robots.end()) return it->second;
  return label;
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
  log_start(now);
  log_.command_end(now, label_, current_->command.index, task::to_string(current_->command.primitive), false, reason);
  report(now, CommandOutcome::kFailed, std::move(reason));
  current_.reset();
  phase_ = RobotPhase::kFailed;
}

bool RobotControl::submit_current(SimDuration now) {
  const task::Primitive& p = current_->command.primitive;
  const drivers::Capabilities& caps = driver_.capabilities();
  drivers::Command cmd;
  if (p.kind == task::PrimitiveKind::kMove) {
    task::Target target = p.target;
    target.object = bound(target.object);
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
      return false;
    }
    if (seen.target.resolution == MotionTarget::Resolution::kFail) {
      fail(now, seen.target.reason);
      return false;
    }
    std::vector<double> goal = seen.target.joints;
    Eigen::Isometry3d pose_in_base = Eigen::Isometry3d::Identity();
    if (goal.empty()) {
      CW_CHECK(seen.joints.size() == chain_.dof(), "robot {}: {} joints in the model, {} in the kinematics", cell_,
               seen.joints.size(), chain_.dof());
      const Eigen::VectorXd seed = to_eigen(seen.joints);
      std::optional<models::IkResult> best;
      int best_rank = 0;
      std::string why;
      for (std::size_t i = 0; i < seen.target.poses.size(); ++i) {
        const int rank = i < seen.target.rank.size() ? seen.target.rank[i] : 0;
        if (best && rank > best_rank) continue;  // a better-ranked pose is already reachable
        const Eigen::Isometry3d in_base = seen.base.inverse() * seen.target.poses[i];
        if (!caps.full_orientation && drivers::out_of_arm_plane(in_base) > options_.arm_plane_tolerance) {
          // A 5-axis arm's yaw follows its position: its controller could not be told this orientation.
          if (why.empty()) {
            why = fmt::format(
                "the tool's approach axis is {:.1f} deg out of the arm's vertical plane, and {} cannot "
                "turn it there (5 axes)",
                drivers::out_of_arm_plane(in_base) * 180 / M_PI, cell_);
          }
          continue;
        }
        models::IkResult ik = chain_.inverse(in_base, seed, options_.ik);
        if (ik.status != models::IkStatus::kOk) {
          if (why.empty()) why = ik.reason;
          continue;
        }
        if (!best || rank < best_rank || (ik.q - seed).norm() < (best->q - seed).norm()) {
          best = std::move(ik);
          best_rank = rank;
          pose_in_base = in_base;
        }
      }
      if (!best) {
        fail(now, fmt::format("{} is unreachable for {}: {}", seen.target.description, cell_, why));
        return false;
      }
      goal = to_std(best->q);
    } else {
      pose_in_base = chain_.forward(to_eigen(goal));
    }
    // The driver solves its own IK for a pose and may pick another configuration: such a move is checked on the tool.
    const bool pose_command = caps.cartesian_control && (caps.prefers_pose || !caps.joint_control);
    if (!pose_command && !caps.joint_control) {
      fail(now, fmt::format("the driver of {} takes neither joint nor pose motions", cell_));
      return false;
    }
    if (pose_command) {
      const drivers::Path path =
          caps.linear_motion && straight_from(last_target_, target) ? drivers::Path::linear : drivers::Path::joint;
      cmd = drivers::MovePose{pose_in_base, path, options_.speed};
    } else {
      cmd = drivers::MoveJoints{goal, options_.speed};
    }
    current_->goal = std::move(goal);
    current_->goal_pose = pose_in_base;
    current_->pose_command = pose_command;
    current_->target = target;
  } else {
    drivers::Grip grip;
    grip.action = p.kind == task::PrimitiveKind::kClose ? drivers::Grip::Action::close : drivers::Grip::Action::open;
    if (caps.gripper_force && grip_force_ > 0.0) grip.force = std::min(grip_force_, caps.gripper_max_force);
    cmd = grip;
  }
  const drivers::Submitted s = driver_.submit(cmd);
  current_->detail = drivers::describe(cmd);
  if (s.error == drivers::ErrorCode::busy) return false;  // its queue is full (a position read, say): next turn
  if (!s.accepted()) {
    fail(now, fmt::format("the driver refused '{}': {}: {}", current_->detail, drivers::to_string(s.error), s.message));
    return false;
  }
  current_->id = s.id;
  phase_ = RobotPhase::kExecuting;
  log_start(now);
  return true;
}

void RobotControl::complete(SimDuration now) {
  const task::Primitive& p = current_->command.primitive;
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
  } else if (p.kind == task::PrimitiveKind::kClose) {
    const std::string expected = p.workpiece.empty() ? std::string() : bound(p.workpiece);
    const std::optional<std::string> between =
        env_.read([&](const EnvironmentModel& m) { return m.find_robot(cell_)->between_fingers; });
    std::string held;
    if (!between) {
      log_.sensor(now, label_, index, "grip_not_sensed", expected);
      held = expected;
    } else if (between->empty()) {
      log_.sensor(now, label_, index, "closed_on_nothing", "");
      if (!expected.empty()) return fail(now, fmt::format("the gripper closed on nothing (expected {})", expected));
    } else if (!expected.empty() && *between != expected) {
      log_.sensor(now, label_, index, "closed_on_wrong_part", *between);
      return fail(now, fmt::format("the gripper closed on {}, expected {}", *between, expected));
    } else {
      log_.sensor(now, label_, index, "gripped", *between);
      held = *between;
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
        r->released_tcp.reset();
        w->held_by = cell_;
      });
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
  }
  log_.command_end(now, label_, index, task::to_string(p), true, "");
  report(now, CommandOutcome::kDone, "");
  current_.reset();
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
    return false;
  }
  const drivers::PositionReading& r = *reading_;
  const auto missed = [&](std::string why) {
    log_.sensor(now, label_, index, "position_missed", "");
    fail(now, fmt::format("position not reached: {}", why));
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

void RobotControl::collect_position() {
  if (position_request_ != 0) {
    const drivers::CommandStatus st = driver_.poll(position_request_);
    if (st.phase == drivers::CommandPhase::pending || st.phase == drivers::CommandPhase::running) return;
    position_request_ = 0;
    if (st.phase == drivers::CommandPhase::done) {
      std::optional<drivers::PositionReading> r = driver_.last_position();
      if (r && (!reading_ || r->request > reading_->request)) {
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
    }
  }
}

void RobotControl::poll_current(SimDuration now) {
  const drivers::CommandStatus st = driver_.poll(current_->id);
  switch (st.phase) {
    case drivers::CommandPhase::pending:
    case drivers::CommandPhase::running:
      return;
    case drivers::CommandPhase::failed:
      return fail(now, fmt::format("the driver failed '{}': {}: {}", current_->detail, drivers::to_string(st.error),
                                   st.message));
    case drivers::CommandPhase::done:
      return complete(now);
  }
}

void RobotControl::start_next(SimDuration now) {
  MotionCommand cmd;
  if (inbox_.try_pop(cmd) != QueueStatus::ok) return;
  CW_CHECK(cmd.robot == index_, "robot {} got a command for robot {}", index_, cmd.robot);
  current_.emplace();
  current_->command = std::move(cmd);
  (void)now;
}

void RobotControl::step(SimDuration now) {
  if (phase_ == RobotPhase::kFailed) return;
  collect_position();
  track_held_part();
  run_commands(now);
  // The periodic read goes last, so that a read asked for after a completion seen in this turn is the one that
  // checks it.
  if (phase_ != RobotPhase::kFailed && (!last_request_ || now - *last_request_ >= options_.position_period)) {
    request_position(now);
  }
}

void RobotControl::run_commands(SimDuration now) {
  if (phase_ == RobotPhase::kBringUp) {
    bring_up(now);
    if (phase_ != RobotPhase::kReady) return;
  }
  for (;;) {
    if (!current_) {
      start_next(now);
      if (!current_) return;
    }
    if (current_->id == 0 && !submit_current(now)) return;  // waiting for its target, or failed
    poll_current(now);
    if (current_ || phase_ == RobotPhase::kFailed) return;  // still running, or failed
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
