// MirroredDriver (mirrored_driver.hpp).
#include "cellwright/twin/sim/mirrored_driver.hpp"

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

using drivers::CommandId;
using drivers::CommandPhase;
using drivers::DriverState;
using drivers::ErrorCode;

namespace {

bool finished(CommandPhase p) {
  return p == CommandPhase::done || p == CommandPhase::failed;
}

Eigen::VectorXd to_eigen(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

}  // namespace

MirroredDriver::MirroredDriver(std::string robot, std::unique_ptr<drivers::RobotDriver> real,
                               drivers::RobotDriver& copy, models::KinematicChain chain)
    : robot_(std::move(robot)), real_(std::move(real)), copy_(copy), chain_(std::move(chain)) {
  CW_CHECK(real_ != nullptr, "a mirrored driver needs a real driver");
  CW_CHECK(copy_.capabilities().joints == chain_.dof() && copy_.capabilities().reads_joints,
           "the twin's copy of {} must read its {} joints", robot_, chain_.dof());
}

MirroredDriver::~MirroredDriver() {
  copy_.set_notifier({});
}

MirroredDriver::Counts MirroredDriver::counts() const {
  return {mirrored_.load(), corrections_.load(), misses_.load()};
}

DriverState MirroredDriver::state() const {
  return real_->state();
}

void MirroredDriver::bring_up_copy() const {
  const DriverState s = copy_.state();
  // A homing that failed or was cancelled is over: it must not keep the copy down.
  const bool homing = copy_home_ != 0 && !finished(copy_.poll(copy_home_).phase);
  if (s == DriverState::disconnected) {
    // disconnect() took both down: the copy waits for the real robot's connect().
    if (real_->state() != DriverState::disconnected) copy_.connect();
  } else if (s == DriverState::fault) {
    copy_.reset();
  } else if (s == DriverState::connected && !homing) {
    copy_home_ = copy_.home().id;
  } else if ((s == DriverState::homed || s == DriverState::stopped) && !homing) {
    // A stopped copy resumes where it stands, as the real robot does after stop() (home() homes it itself).
    copy_.activate();
    copy_home_ = 0;
  }
}

void MirroredDriver::release_all() const {
  pending_.clear();
  held_.clear();
  copy_running_ = copy_running_real_ = 0;
  // Halted, homed or reset, the copy may stand elsewhere than it last read: read it again before comparing.
  copy_joints_.clear();
}

ErrorCode MirroredDriver::connect() {
  const ErrorCode e = real_->connect();
  follow();
  return e;
}

void MirroredDriver::disconnect() {
  real_->disconnect();
  copy_.disconnect();
  release_all();
  copy_home_ = copy_read_ = 0;
}

drivers::Submitted MirroredDriver::home() {
  const drivers::Submitted s = real_->home();
  if (s.accepted()) {
    // The copy goes home too (where the real robot's homing takes it: the cell's home), whatever it was doing.
    if (copy_.state() == DriverState::active) copy_.stop();
    release_all();
    // Refused while the copy is not up (disconnected, fault): it is homed as it comes up.
    if (const drivers::Submitted h = copy_.home(); h.accepted()) copy_home_ = h.id;
  }
  follow();
  return s;
}

ErrorCode MirroredDriver::activate() {
  const ErrorCode e = real_->activate();
  follow();
  return e;
}

void MirroredDriver::stop() {
  real_->stop();
  copy_.stop();
  release_all();
}

ErrorCode MirroredDriver::reset() {
  const ErrorCode e = real_->reset();
  follow();
  return e;
}

drivers::Submitted MirroredDriver::submit(const drivers::Command& command) {
  const drivers::Submitted s = real_->submit(command);
  // Motions and grips are mirrored; digital I/O is not (the twin's signals are not the real cell's wires: a copy
  // waiting for a real input would wait for ever).
  const bool mirrored = std::holds_alternative<drivers::MovePose>(command) ||
                        std::holds_alternative<drivers::MoveJoints>(command) ||
                        std::holds_alternative<drivers::Grip>(command);
  if (s.accepted() && mirrored) {
    if (const auto* m = std::get_if<drivers::MovePose>(&command)) speed_ = m->speed;
    if (const auto* m = std::get_if<drivers::MoveJoints>(&command)) speed_ = m->speed;
    pending_.push_back(Action{command, {}, s.id});
    held_[s.id] = true;
    last_mirrored_ = s.id;
  }
  follow();
  return s;
}

drivers::Submitted MirroredDriver::request_position() {
  const drivers::Submitted s = real_->request_position();
  follow();
  return s;
}

drivers::CommandStatus MirroredDriver::poll(CommandId id) const {
  follow();
  drivers::CommandStatus st = real_->poll(id);
  if (st.phase == CommandPhase::done && held_.count(id) != 0) st.phase = CommandPhase::running;
  return st;
}

std::optional<drivers::PositionReading> MirroredDriver::last_position() const {
  follow();
  return real_->last_position();
}

void MirroredDriver::set_notifier(std::function<void()> notify) {
  real_->set_notifier(notify);
  copy_.set_notifier(std::move(notify));
}

void MirroredDriver::set_clock(Clock clock) {
  real_->set_clock(clock);
  copy_.set_clock(std::move(clock));
}

std::optional<std::vector<double>> MirroredDriver::correction() const {
  const std::optional<drivers::PositionReading> r = real_->last_position();
  // Only a reading asked for after the last command given to the copy shows where that command left the real robot
  // (the serial controllers answer in order): an older one would pull the copy back.
  if (!r || r->request <= last_mirrored_ || copy_joints_.size() != chain_.dof()) return std::nullopt;
  if (r->joints.size() == chain_.dof()) {
    double worst = 0;
    for (std::size_t i = 0; i < chain_.dof(); ++i) worst = std::max(worst, std::abs(r->joints[i] - copy_joints_[i]));
    if (worst <= kJointTolerance) return std::nullopt;
    return r->joints;
  }
  if (!r->tool_pose) return std::nullopt;
  const Eigen::Isometry3d copy_tool = chain_.forward(to_eigen(copy_joints_));
  const double off = (copy_tool.translation() - r->tool_pose->translation()).norm();
  const double turn = Eigen::AngleAxisd(copy_tool.linear().transpose() * r->tool_pose->linear()).angle();
  if (off <= kToolTolerance && turn <= kJointTolerance) return std::nullopt;
  const models::IkResult ik = chain_.inverse(*r->tool_pose, to_eigen(copy_joints_));
  if (ik.status != models::IkStatus::kOk) {
    misses_.fetch_add(1);
    return std::nullopt;
  }
  return std::vector<double>(ik.q.data(), ik.q.data() + ik.q.size());
}

void MirroredDriver::follow() const {
  if (copy_.state() == DriverState::fault) {
    // The copy failed in the twin (a numerical reset): it lets go of what it was mirroring, so that the real robot is
    // never held back by it, and comes back through reset and home.
    if (!held_.empty() || !pending_.empty() || copy_running_ != 0) misses_.fetch_add(1);
    release_all();
  }
  if (copy_.state() != DriverState::active) {
    bring_up_copy();
    if (copy_.state() != DriverState::active) {
      // A copy not yet up (still homing, say, when the real robot homed faster) holds nothing back; it does what the
      // real robot was told meanwhile once it is up, so that it catches up (the newest kMaxBehind commands at most:
      // beyond that, the read-backs will correct it).
      held_.clear();
      while (pending_.size() > kMaxBehind) pending_.pop_front();
      return;
    }
  }
  // Where the copy stands, once, before its first command.
  if (copy_joints_.empty() && copy_read_ == 0) {
    const drivers::Submitted r = copy_.request_position();
    copy_read_ = r.accepted() ? r.id : 0;
  }
  // The copy's command in flight.
  if (copy_running_ != 0) {
    const drivers::CommandStatus st = copy_.poll(copy_running_);
    if (finished(st.phase)) {
      if (st.phase == CommandPhase::failed) misses_.fetch_add(1);
      held_.erase(copy_running_real_);
      copy_running_ = copy_running_real_ = 0;
      if (copy_read_ == 0) {
        const drivers::Submitted r = copy_.request_position();
        copy_read_ = r.accepted() ? r.id : 0;
      }
    }
  }
  // The copy's position, to compare with the real robot's.
  if (copy_read_ != 0 && finished(copy_.poll(copy_read_).phase)) {
    const std::optional<drivers::PositionReading> r = copy_.last_position();
    if (r && r->request == copy_read_) copy_joints_ = r->joints;
    copy_read_ = 0;
    correction_due_ = true;
  }
  if (const std::optional<drivers::PositionReading> r = real_->last_position(); r && r->request > last_reading_) {
    last_reading_ = r->request;
    correction_due_ = true;
  }
  // A real command the real driver ended without the copy (failed, cancelled) no longer holds anything.
  for (auto it = held_.begin(); it != held_.end();) {
    if (it->first != copy_running_real_ && real_->poll(it->first).phase == CommandPhase::failed) {
      pending_.erase(
          std::remove_if(pending_.begin(), pending_.end(), [&](const Action& a) { return a.real == it->first; }),
          pending_.end());
      it = held_.erase(it);
    } else {
      ++it;
    }
  }
  // Idle with a reading not compared yet: correct the copy if it stands elsewhere than the real robot.
  if (copy_running_ == 0 && pending_.empty() && copy_read_ == 0 && correction_due_) {
    correction_due_ = false;
    if (std::optional<std::vector<double>> q = correction()) {
      pending_.push_back(Action{std::nullopt, std::move(*q), 0});
    }
  }
  // Start the next action when the copy is free and its position is known.
  while (copy_running_ == 0 && copy_read_ == 0 && !pending_.empty()) {
    Action a = std::move(pending_.front());
    std::optional<drivers::Command> command = a.command;
    if (!command) command = drivers::MoveJoints{a.joints, speed_};
    // A joint-interpolated pose move goes to the copy as the joints nearest to where it stands, as the runtime asks of
    // a simulated arm and as a controller's inverse kinematics chooses: a copy left to choose for itself could take
    // another configuration and another way through the cell than the real arm.
    if (const auto* m = std::get_if<drivers::MovePose>(&*command);
        m != nullptr && m->path == drivers::Path::joint && copy_joints_.size() == chain_.dof()) {
      const models::IkResult ik = chain_.inverse(m->pose, to_eigen(copy_joints_));
      if (ik.status == models::IkStatus::kOk) {
        command = drivers::MoveJoints{std::vector<double>(ik.q.data(), ik.q.data() + ik.q.size()), m->speed};
      }
    }
    const drivers::Submitted s = copy_.submit(*command);
    if (s.error == ErrorCode::busy) break;
    pending_.pop_front();
    if (s.accepted()) {
      copy_running_ = s.id;
      copy_running_real_ = a.real;
      (a.command ? mirrored_ : corrections_).fetch_add(1);
    } else {
      misses_.fetch_add(1);
      held_.erase(a.real);
    }
  }
}

}  // namespace cellwright::twin::sim
