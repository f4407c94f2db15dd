#include "cellwright/twin/sim/sim_driver.hpp"
#include "cellwright/models/robot_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <type_traits>

#include "cellwright/twin/sim/grip_timing.hpp"
#include "cellwright/twin/sim/move_timing.hpp"

namespace cellwright::twin::sim {

using drivers::CommandId;
using drivers::DriverState;
using drivers::ErrorCode;
using drivers::Submitted;

namespace {

constexpr double kOnPartMargin = 0.001;     // m short of fully closed for a close to count as on a part

double seconds(std::chrono::nanoseconds d) {
  return std::chrono::duration<double>(d).count();
}

std::chrono::nanoseconds nanos(double s) {
  return std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(s * 1e9)));
}

// "<name> <value> <unit>, ..." with the URDF's own joint names.
std::string joint_list(const std::vector<std::string>& names, const Eigen::VectorXd& v, const char* unit) {
  std::string s;
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    s += fmt::format("{}{} {:.4f} {}", i ? ", " : "", names.at(static_cast<std::size_t>(i)), v[i], unit);
  }
  return s;
}

}  // namespace

std::vector<double> sim_joint_speeds(const models::RobotSpec& spec, const models::KinematicChain& chain,
                                     const SimDriverOptions& options) {
  const std::size_t n = chain.dof();
  std::vector<double> speeds = options.max_joint_speed;
  if (speeds.empty()) {
    // The URDF's <limit velocity>, read with the chain by the one URDF loader (models/urdf.hpp).
    for (const models::JointLimit& limit : chain.limits()) speeds.push_back(limit.velocity);
    for (std::size_t j = 0; j < n; ++j) {
      if (!(speeds[j] > 0.0)) {
        throw InputError({spec.urdf.string(), 0, 0},
                         fmt::format("robot '{}': joint '{}' has no velocity limit; the simulated controller needs "
                                     "one (or max_joint_speed in its options)",
                                     spec.name, chain.joint_names()[j]));
      }
    }
  }
  const auto fail = [&](const std::string& problem) {
    return InputError(options.where, fmt::format("simulated robot '{}': {}", spec.name, problem));
  };
  if (speeds.size() != n) {
    throw fail(fmt::format("max_joint_speed has {} values for {} joints", speeds.size(), n));
  }
  for (std::size_t j = 0; j < n; ++j) {
    if (!std::isfinite(speeds[j]) || speeds[j] <= 0.0) {
      throw fail(fmt::format("max_joint_speed of joint {} is {}; it must be > 0", j + 1, speeds[j]));
    }
  }
  return speeds;
}

SimDriver::SimDriver(const Scene& scene, std::size_t robot, SignalTable& signals, SimDriverOptions options)
    : ids_(scene.robots().at(robot)),
      signals_(signals),
      options_(std::move(options)),
      name_(ids_.name),
      chain_(models::robot_chain(scene.cell().robots.at(robot))) {
  const auto& spec = scene.cell().robots.at(robot);
  const std::size_t n = ids_.joints.size();
  auto fail = [&](const std::string& problem) {
    return InputError(options_.where, fmt::format("simulated robot '{}': {}", name_, problem));
  };
  CW_CHECK(chain_.dof() == n, "robot {}: the kinematics has {} joints, the scene {}", name_, chain_.dof(), n);
  for (std::size_t j = 0; j < n; ++j) {
    CW_CHECK(ids_.joints[j] == name_ + "/" + chain_.joint_names()[j], "robot {}: scene joint {} is {}, kinematics {}",
             name_, j, ids_.joints[j], chain_.joint_names()[j]);
  }
  const std::vector<double> speeds = sim_joint_speeds(spec, chain_, options_);
  const auto positive = [&](const char* what, double v) {
    if (!std::isfinite(v) || v <= 0.0) throw fail(fmt::format("{} is {}; it must be > 0", what, v));
  };
  positive("max_tool_speed", options_.max_tool_speed);
  positive("joint_tolerance", options_.joint_tolerance);
  positive("settle_speed", options_.settle_speed);
  positive("settle_timeout", options_.settle_timeout);
  positive("linear_step", options_.linear_step);
  positive("max_waypoint_step", options_.max_waypoint_step);
  positive("finger_speed", options_.finger_speed);
  positive("finger_tolerance", options_.finger_tolerance);
  positive("finger_settle_speed", options_.finger_settle_speed);
  positive("release_clearance", options_.release_clearance);
  positive("brake_time", options_.brake_time);
  if (!std::isfinite(options_.min_move_time) || options_.min_move_time < 0.0) {
    throw fail(fmt::format("min_move_time is {}; it must be >= 0", options_.min_move_time));
  }
  if (!(options_.home_speed > 0.0 && options_.home_speed <= 1.0)) {
    throw fail(fmt::format("home_speed is {}; it must be in (0, 1]", options_.home_speed));
  }
  if (options_.queue_depth == 0) throw fail("queue_depth must be at least 1");

  max_speed_ = Eigen::Map<const Eigen::VectorXd>(speeds.data(), static_cast<Eigen::Index>(n));
  lower_.resize(static_cast<Eigen::Index>(n));
  upper_.resize(static_cast<Eigen::Index>(n));
  for (std::size_t j = 0; j < n; ++j) {
    lower_[static_cast<Eigen::Index>(j)] = chain_.limits()[j].lower;
    upper_[static_cast<Eigen::Index>(j)] = chain_.limits()[j].upper;
  }
  home_ = Eigen::Map<const Eigen::VectorXd>(ids_.home.data(), static_cast<Eigen::Index>(n));
  grip_force_ = spec.grip_force;
  finger_closed_ = ids_.finger_range[0];
  finger_open_ = ids_.finger_range[1];

  drivers::Capabilities caps;
  caps.joints = n;
  caps.joint_control = true;
  caps.cartesian_control = true;
  caps.linear_motion = true;
  caps.full_orientation = n >= 6;
  caps.gripper = true;
  caps.gripper_width = true;
  caps.gripper_force = true;
  caps.gripper_max_width = 2.0 * finger_open_;
  caps.gripper_max_force = grip_force_;
  caps.digital_outputs = signals_.size();
  caps.digital_inputs = signals_.size();
  caps.max_joint_speed = speeds;
  caps.max_tool_speed = options_.max_tool_speed;
  caps.queue_depth = options_.queue_depth;
  caps.reads_joints = true;
  caps.reads_pose = true;
  caps.reads_while_moving = true;  // the simulation's joints can be read at any step
  caps.timed_motion = true;        // its trajectories are its own: a move can be stretched to a duration
  set_capabilities(std::move(caps));

  // Until the first step reads the simulation, plan from the home configuration the scene starts in.
  arm_goal_ = home_;
  arm_position_ = home_;
  arm_velocity_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  finger_from_ = finger_goal_ = finger_open_;
  finger_force_ = grip_force_;
}

// ---- DriverCore hooks (mutex held) ----------------------------------------------------------------------------

void SimDriver::accept_hook(Job& job) {
  auto plan = std::make_unique<SimJob>();
  if (job.kind == JobKind::home) {
    plan_joints(*plan, home_, options_.home_speed);
  } else if (job.kind == JobKind::command) {
    plan_command(*plan, *job.command);
  }
  job.data = std::move(plan);
}

void SimDriver::plan_command(SimJob& job, const drivers::Command& command) const {
  if (const auto* move = std::get_if<drivers::MoveJoints>(&command)) {
    plan_joints(
        job,
        Eigen::Map<const Eigen::VectorXd>(move->positions.data(), static_cast<Eigen::Index>(move->positions.size())),
        move->speed);
    job.min_duration = move->duration;
  } else if (const auto* pose = std::get_if<drivers::MovePose>(&command)) {
    plan_pose(job, *pose);
    job.min_duration = pose->duration;
  }
}

double SimDriver::planned_duration(const SimJob& job, std::vector<Eigen::VectorXd> points) const {
  const double duration =
      least_move_duration(JointPath(std::move(points), job.arc),
                          job.arc.empty() ? std::nullopt : std::optional<double>(job.tool_distance), max_speed_,
                          job.speed, options_.min_move_time, options_.max_tool_speed);
  return std::max(duration, job.min_duration.value_or(0.0));
}

std::optional<double> SimDriver::least_duration(const drivers::Command& command) const {
  if (state() != drivers::DriverState::active || drivers::check_command(command, capabilities())) return std::nullopt;
  const auto l = lock();
  if (const auto* grip = std::get_if<drivers::Grip>(&command)) {
    double goal = grip->action == drivers::Grip::Action::close ? finger_closed_ : finger_open_;
    if (grip->width) goal = std::clamp(*grip->width / 2.0, finger_closed_, finger_open_);
    return finger_ramp_duration(finger_goal_, goal, options_.finger_speed);
  }
  if (!std::holds_alternative<drivers::MoveJoints>(command) && !std::holds_alternative<drivers::MovePose>(command)) {
    return std::nullopt;
  }
  SimJob job;
  plan_command(job, command);
  if (!job.problem.empty() || job.points.empty()) return std::nullopt;
  return planned_duration(job, job.points);
}

void SimDriver::halt_hook() {
  brake_requested_ = true;
}

std::optional<GripOutcome> SimDriver::last_grip() const {
  const auto l = lock();
  return last_grip_;
}

// ---- Queue (mutex held) ----------------------------------------------------------------------------------------

void SimDriver::finish_head(Controller& c, Job& job, ErrorCode error, std::string message) {
  const CommandId id = job.id;
  if (error == ErrorCode::none) {
    c.complete(id);
    return;
  }
  // A failed motion leaves the arm where it is (the targets stop at once, smoothly).
  if (job.as<SimJob>().moves_arm) brake_requested_ = true;
  c.fail(id, error, std::move(message));
}

Eigen::VectorXd SimDriver::queue_end_joints() const {
  const auto& queue = queued();
  for (auto it = queue.rbegin(); it != queue.rend(); ++it) {
    const SimJob& plan = it->as<SimJob>();
    if (!plan.points.empty() && plan.problem.empty()) return plan.points.back();
  }
  return arm_goal_;
}

// ---- Planning (owner thread, mutex held) -----------------------------------------------------------------------

void SimDriver::plan_joints(SimJob& job, const Eigen::VectorXd& goal, double speed) const {
  job.speed = speed;
  for (Eigen::Index j = 0; j < goal.size(); ++j) {
    if (goal[j] < lower_[j] || goal[j] > upper_[j]) {
      job.problem_code = ErrorCode::unreachable;
      job.problem = fmt::format("joint {} target {:.6f} rad is outside its limits [{:.6f}, {:.6f}] rad", j + 1, goal[j],
                                lower_[j], upper_[j]);
      return;
    }
  }
  job.points = {queue_end_joints(), goal};
}

void SimDriver::plan_pose(SimJob& job, const drivers::MovePose& move) const {
  job.speed = move.speed;
  const Eigen::VectorXd seed = queue_end_joints();
  if (move.path == drivers::Path::joint) {
    // The solution closest to the seed can be a different arm configuration (shoulder or elbow flipped) when the
    // target lies far round the base: the arm would then swing through the air. So IK is also seeded with the first
    // joint turned towards the target, and the solution that changes the arm's configuration least wins: the least
    // motion of the joints between the first and the last (turning about the base or the tool axis keeps it).
    models::IkResult ik = chain_.inverse(move.pose, seed, options_.ik);
    const Eigen::Vector3d from = chain_.forward(seed).translation() - chain_.first_joint_origin();
    const Eigen::Vector3d to = move.pose.translation() - chain_.first_joint_origin();
    Eigen::VectorXd turned = seed;
    turned[0] += std::remainder(std::atan2(to.y(), to.x()) - std::atan2(from.y(), from.x()), 2.0 * std::numbers::pi);
    if (chain_.within_limits(turned)) {
      const auto reconfiguration = [&](const Eigen::VectorXd& q) {
        const Eigen::Index inner = std::max<Eigen::Index>(q.size() - 2, 0);
        return (q - seed).segment(1, inner).cwiseAbs().sum();
      };
      const models::IkResult other = chain_.inverse(move.pose, turned, options_.ik);
      if (other.status == models::IkStatus::kOk &&
          (ik.status != models::IkStatus::kOk || reconfiguration(other.q) < reconfiguration(ik.q))) {
        ik = other;
      }
    }
    if (ik.status != models::IkStatus::kOk) {
      job.problem_code = ErrorCode::unreachable;
      job.problem = fmt::format("no joint solution for the pose: {}", ik.reason);
      return;
    }
    job.points = {seed, ik.q};
    return;
  }
  // A straight line of the tool (move_timing.hpp).
  StraightLine line = straight_line(chain_, seed, move.pose, options_.linear_step, options_.max_waypoint_step,
                                    options_.ik);
  if (!line.problem.empty()) {
    job.problem_code = ErrorCode::unreachable;
    job.problem = std::move(line.problem);
    return;
  }
  job.points = std::move(line.points);
  job.arc = std::move(line.arc);
  job.tool_distance = line.tool_distance;
}

// ---- The simulation side ---------------------------------------------------------------------------------------

Eigen::VectorXd SimDriver::joints(const mjData* data) const {
  Eigen::VectorXd q(static_cast<Eigen::Index>(ids_.qpos_adr.size()));
  for (std::size_t j = 0; j < ids_.qpos_adr.size(); ++j) q[static_cast<Eigen::Index>(j)] = data->qpos[ids_.qpos_adr[j]];
  return q;
}

Eigen::VectorXd SimDriver::joint_speeds(const mjData* data) const {
  Eigen::VectorXd v(static_cast<Eigen::Index>(ids_.dof_adr.size()));
  for (std::size_t j = 0; j < ids_.dof_adr.size(); ++j) v[static_cast<Eigen::Index>(j)] = data->qvel[ids_.dof_adr[j]];
  return v;
}

double SimDriver::finger_position(const mjData* data, int side) const {
  return data->qpos[ids_.finger_qpos_adr[static_cast<std::size_t>(side)]];
}

double SimDriver::finger_speed(const mjData* data, int side) const {
  return data->qvel[ids_.finger_dof_adr[static_cast<std::size_t>(side)]];
}

std::array<bool, 2> SimDriver::touch(const mjModel* model, const mjData* data) const {
  std::array<bool, 2> t{};
  for (std::size_t side = 0; side < 2; ++side) {
    t[side] = data->sensordata[model->sensor_adr[ids_.finger_touch_sensor[side]]] > kTouchThreshold;
  }
  return t;
}

double SimDriver::finger_stiffness(const mjModel* model, int side) const {
  return model->actuator_gainprm[ids_.finger_actuator[static_cast<std::size_t>(side)] * mjNGAIN];
}

void SimDriver::hold_here(std::chrono::nanoseconds now, const mjData* data) {
  const Eigen::VectorXd q = joints(data);
  arm_path_.emplace(std::vector<Eigen::VectorXd>{q, q});
  arm_start_ = now;
  arm_duration_ = 1.0;
  braking_ = false;
  arm_goal_ = q;
  arm_position_ = q;
  arm_velocity_.setZero();
  const double f = 0.5 * (finger_position(data, 0) + finger_position(data, 1));
  finger_from_ = finger_goal_ = f;
  finger_start_ = now;
  finger_duration_ = 0;
  finger_closing_ = false;
}

SimDriver::ArmTarget SimDriver::arm_target(std::chrono::nanoseconds now) const {
  ArmTarget t;
  if (braking_) {
    // Constant deceleration from the velocity the targets had: smooth in position and velocity.
    const double tau = std::min(seconds(now - brake_start_), brake_duration_);
    const double T = brake_duration_;
    t.position = brake_q_ + brake_v_ * (tau - tau * tau / (2.0 * T));
    t.velocity = brake_v_ * (1.0 - tau / T);
    t.acceleration = tau < T ? Eigen::VectorXd(-brake_v_ / T) : Eigen::VectorXd::Zero(brake_v_.size());
    return t;
  }
  const JointSample s = arm_path_->sample(seconds(now - arm_start_), arm_duration_);
  t.position = s.position;
  t.velocity = s.velocity;
  t.acceleration = s.acceleration;
  return t;
}

double SimDriver::finger_ramp(std::chrono::nanoseconds now, double* velocity) const {
  if (finger_duration_ <= 0.0) {
    if (velocity) *velocity = 0.0;
    return finger_goal_;
  }
  const double u = seconds(now - finger_start_) / finger_duration_;
  if (velocity) *velocity = (finger_goal_ - finger_from_) * quintic_rate(u) / finger_duration_;
  return finger_from_ + (finger_goal_ - finger_from_) * quintic(u);
}

void SimDriver::move_fingers(std::chrono::nanoseconds now, double goal, double force) {
  finger_from_ = finger_ramp(now, nullptr);
  finger_goal_ = goal;
  finger_force_ = force;
  finger_closing_ = goal < finger_from_;
  finger_start_ = now;
  finger_duration_ = finger_ramp_duration(finger_from_, goal, options_.finger_speed);
}

std::optional<double> SimDriver::holding_at(const mjModel* model, const mjData* data) const {
  if (!finger_closing_) return std::nullopt;
  const std::array<bool, 2> touching = touch(model, data);
  const double left = finger_position(data, 0), right = finger_position(data, 1);
  if (!touching[0] || !touching[1] || left + right <= 2.0 * finger_closed_ + kOnPartMargin) return std::nullopt;
  return 0.5 * (left + right);
}

void SimDriver::start_head(std::chrono::nanoseconds now, Job& head, const mjModel* model, const mjData* data) {
  SimJob& job = head.as<SimJob>();
  job.started = true;
  job.start = now;
  if (!job.problem.empty()) return;  // check_head fails it
  if (!job.points.empty()) {
    job.moves_arm = true;
    // The planned start is where the targets were expected to come to rest; start exactly from where they are.
    job.points.front() = arm_target(now).position;
    const double duration = planned_duration(job, job.points);
    arm_path_.emplace(job.points, job.arc);
    arm_start_ = now;
    arm_duration_ = duration;
    braking_ = false;
    arm_goal_ = arm_path_->end();
    job.duration = duration;
    job.deadline = now + nanos(duration + options_.settle_timeout);
  }
  if (head.kind == JobKind::home) {
    job.moves_fingers = true;
    move_fingers(now, finger_open_, grip_force_);
    return;
  }
  if (head.kind == JobKind::position) return;
  std::visit(
      [&](const auto& c) {
        using C = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<C, drivers::Grip>) {
          job.moves_fingers = true;
          const bool close = c.action == drivers::Grip::Action::close;
          double goal = close ? finger_closed_ : finger_open_;
          if (c.width) goal = std::clamp(*c.width / 2.0, finger_closed_, finger_open_);
          const std::optional<double> held = close || c.width ? std::nullopt : holding_at(model, data);
          if (held) {
            // A release: from where the fingers rest on the part (not from where the closing ramp ran on to), just
            // clear of it.
            finger_duration_ = 0;
            finger_goal_ = *held;
            goal = std::min(*held + options_.release_clearance, finger_open_);
          }
          move_fingers(now, goal, c.force.value_or(grip_force_));
        } else if constexpr (std::is_same_v<C, drivers::WaitInput>) {
          job.deadline = c.timeout.count() > 0 ? now + c.timeout : std::chrono::nanoseconds(0);
        }
      },
      *head.command);
}

bool SimDriver::check_head(Controller& c, std::chrono::nanoseconds now, const mjModel* model, const mjData* data,
                           bool sensors_fresh) {
  Job& head = *c.head();
  SimJob& job = head.as<SimJob>();
  if (!job.problem.empty()) {
    finish_head(c, head, job.problem_code, job.problem);
    return true;
  }
  if (head.kind == JobKind::position) {  // not with reads_while_moving; kept for a queue that holds reads
    c.complete(head.id, reading(c, now, data));
    return true;
  }
  if (head.command) {
    if (const auto* out = std::get_if<drivers::SetOutput>(&*head.command)) {
      signals_.set(out->channel, out->on);
      finish_head(c, head);
      return true;
    }
    if (const auto* wait = std::get_if<drivers::WaitInput>(&*head.command)) {
      if (signals_.get(wait->channel) == wait->on) {
        finish_head(c, head);
        return true;
      }
      if (job.deadline.count() > 0 && now >= job.deadline) {
        finish_head(c, head, ErrorCode::timeout,
                    fmt::format("digital input {} stayed {} for {:.3f} s", wait->channel, wait->on ? "off" : "on",
                                seconds(now - job.start)));
        return true;
      }
      return false;
    }
  }
  bool arm_done = true;
  if (job.moves_arm) {
    const Eigen::VectorXd error = joints(data) - arm_goal_;
    const Eigen::VectorXd speed = joint_speeds(data);
    Eigen::VectorXd off = error;
    if (job.min_duration) {
      // A timed move: what is left of the error once the servo's deflection under its external load (the constraint
      // forces on the joint: a held workpiece, the other arm through it) is taken out.
      for (std::size_t j = 0; j < ids_.actuator.size(); ++j) {
        const double kp = model->actuator_gainprm[ids_.actuator[j] * mjNGAIN];
        off[static_cast<Eigen::Index>(j)] -= data->qfrc_constraint[ids_.dof_adr[j]] / kp;
      }
    }
    arm_done = seconds(now - job.start) >= job.duration && off.cwiseAbs().maxCoeff() <= options_.joint_tolerance &&
               speed.cwiseAbs().maxCoeff() <= options_.settle_speed;
    if (!arm_done && now >= job.deadline) {
      finish_head(c, head, ErrorCode::timeout,
                  fmt::format("the arm did not settle within {:.3f} s of the trajectory's end (tolerance {} rad, {} "
                              "rad/s); joint errors: {}; joint speeds: {}",
                              options_.settle_timeout, options_.joint_tolerance, options_.settle_speed,
                              joint_list(chain_.joint_names(), error, "rad"),
                              joint_list(chain_.joint_names(), speed, "rad/s")));
      return true;
    }
  }
  bool fingers_done = true;
  if (job.moves_fingers && !sensors_fresh) {
    fingers_done = false;  // the touch sensors date from an earlier step: decided at the next one
  } else if (job.moves_fingers) {
    const bool ramp_over = seconds(now - finger_start_) >= finger_duration_;
    const std::array<bool, 2> touching = touch(model, data);
    bool settled = true;
    for (int side = 0; side < 2; ++side) {
      const double q = finger_position(data, side);
      const double kp = finger_stiffness(model, side);
      const bool at_goal = ramp_over && std::abs(q - finger_goal_) <= options_.finger_tolerance;
      // Pressing: closing, the finger touches something, and its target is held at the force limit because the
      // finger is blocked short of the ramp.
      const bool pressing = finger_closing_ && touching[static_cast<std::size_t>(side)] &&
                            finger_ramp(now, nullptr) < q - finger_force_ / kp;
      const bool slow = std::abs(finger_speed(data, side)) <= options_.finger_settle_speed;
      settled = settled && slow && (at_goal || pressing);
    }
    if (settled) {
      if (!job.resting_since) job.resting_since = now;
    } else {
      job.resting_since.reset();
    }
    fingers_done = job.resting_since && seconds(now - *job.resting_since) >= kFingerRestWindow;
    // A finger that cannot reach its goal (blocked while opening) fails like a blocked arm.
    if (!fingers_done && ramp_over && now - finger_start_ >= nanos(finger_duration_ + options_.settle_timeout)) {
      finish_head(c, head, ErrorCode::timeout,
                  fmt::format("the fingers did not reach {:.4f} m (each) within {:.3f} s: left at {:.4f} m, right at "
                              "{:.4f} m",
                              finger_goal_, finger_duration_ + options_.settle_timeout, finger_position(data, 0),
                              finger_position(data, 1)));
      return true;
    }
  }
  if (!(arm_done && fingers_done)) return false;
  if (head.command && std::holds_alternative<drivers::Grip>(*head.command)) record_grip(head, model, data);
  finish_head(c, head);
  return true;
}

drivers::PositionReading SimDriver::reading(const Controller& c, std::chrono::nanoseconds now,
                                            const mjData* data) const {
  drivers::PositionReading r;
  r.stamp = c.stamp(now);
  const Eigen::VectorXd q = joints(data);
  r.joints.assign(q.data(), q.data() + q.size());
  // The tool centre point in the base frame: the URDF's kinematics of the joints read (MuJoCo's tcp site is the
  // same frame, but its pose in mjData dates from before the last step's integration).
  r.tool_pose = chain_.forward(q);
  return r;
}

void SimDriver::record_grip(const Job& job, const mjModel* model, const mjData* data) {
  GripOutcome g;
  g.command = job.id;
  g.action = std::get<drivers::Grip>(*job.command).action;
  const double left = finger_position(data, 0), right = finger_position(data, 1);
  g.opening = left + right;
  g.touch = touch(model, data);
  g.on_part = g.action == drivers::Grip::Action::close && g.touch[0] && g.touch[1] &&
              g.opening > 2.0 * finger_closed_ + kOnPartMargin;
  last_grip_ = g;
}

void SimDriver::write_targets(std::chrono::nanoseconds now, const mjModel* model, mjData* data) {
  const ArmTarget t = arm_target(now);
  arm_position_ = t.position;
  arm_velocity_ = t.velocity;
  // Feed-forward: what the servo must push beyond the target so that the joint follows it (damping, gravity and
  // Coriolis forces, the joint's own inertia), expressed as an offset of the position target.
  for (std::size_t j = 0; j < ids_.actuator.size(); ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    const int dof = ids_.dof_adr[j];
    const int act = ids_.actuator[j];
    const double kp = model->actuator_gainprm[act * mjNGAIN];
    const double inertia = data->qM[model->dof_Madr[dof]];
    // Damping of the joint, plus the servo's own velocity term (bias kv) when it has one.
    const double damping = model->dof_damping[dof] - model->actuator_biasprm[act * mjNBIAS + 2];
    const double force = damping * t.velocity[i] + data->qfrc_bias[dof] + inertia * t.acceleration[i];
    data->ctrl[act] = t.position[i] + force / kp;
  }
  if (now < released_until_) {  // an injected loss of grip force: both fingers driven open
    for (std::size_t side = 0; side < 2; ++side) data->ctrl[ids_.finger_actuator[side]] = finger_open_;
    return;
  }
  double v = 0;
  const double ramp = finger_ramp(now, &v);
  const bool closing = finger_closing_;
  for (int side = 0; side < 2; ++side) {
    const auto s = static_cast<std::size_t>(side);
    const int dof = ids_.finger_dof_adr[s];
    const double kp = finger_stiffness(model, side);
    const double q = finger_position(data, side);
    const int act = ids_.finger_actuator[s];
    double target = ramp + (model->dof_damping[dof] - model->actuator_biasprm[act * mjNBIAS + 2]) * v / kp;
    // The force limit: never further ahead of the finger than force / stiffness.
    const double reach = finger_force_ / kp;
    target = closing ? std::max(target, q - reach) : std::min(target, q + reach);
    data->ctrl[act] = target;
  }
}

bool SimDriver::step(std::chrono::nanoseconds now, const mjModel* model, mjData* data, bool sensors_fresh) {
  Controller c = controller();  // releases the lock and calls the notifier (if something finished) when it ends
  if (!initialised_) {
    hold_here(now, data);
    initialised_ = true;
  }
  if (brake_requested_) {
    brake_requested_ = false;
    const ArmTarget t = arm_target(now);
    brake_q_ = t.position;
    brake_v_ = t.velocity;
    brake_start_ = now;
    // Decelerate at no more than each joint's speed limit per brake_time, within brake_time.
    double T = 0;
    for (Eigen::Index j = 0; j < brake_v_.size(); ++j) {
      T = std::max(T, options_.brake_time * std::abs(brake_v_[j]) / max_speed_[j]);
    }
    brake_duration_ = std::max(T, 1e-3);
    braking_ = true;
    arm_goal_ = brake_q_ + brake_v_ * brake_duration_ / 2.0;
    // The fingers stop where their targets are (still pressing if they were closing on a part).
    const double f = finger_ramp(now, nullptr);
    finger_from_ = finger_goal_ = f;
    finger_duration_ = 0;
  }
  // Position requests are answered at this step whatever the arm does (reads_while_moving).
  while (!c.reads().empty()) c.complete(c.reads().front().id, reading(c, now, data));
  while (Job* head = c.head()) {
    if (!head->as<SimJob>().started) {
      if (!sensors_fresh && reads_touch(*head)) break;  // it starts where the sensors are fresh
      start_head(now, *head, model, data);
    }
    if (!check_head(c, now, model, data, sensors_fresh)) break;
  }
  write_targets(now, model, data);
  const std::deque<Job>& queued = c.queued();
  return std::any_of(queued.begin(), queued.end(), [](const Job& j) { return reads_touch(j); });
}

bool SimDriver::reads_touch(const Job& job) {
  return job.kind == JobKind::home || (job.command && std::holds_alternative<drivers::Grip>(*job.command));
}

void SimDriver::release_grip(std::chrono::nanoseconds until) {
  Controller c = controller();
  released_until_ = until;
}

void SimDriver::fault(const std::string& message, std::chrono::nanoseconds now, const mjData* data) {
  Controller c = controller();
  c.raise_fault(ErrorCode::hardware, message);
  hold_here(now, data);
  initialised_ = true;
}

}  // namespace cellwright::twin::sim
