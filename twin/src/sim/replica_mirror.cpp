// ReplicaMirror (replica_mirror.hpp).
#include "cellwright/twin/sim/replica_mirror.hpp"

#include <algorithm>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

using drivers::CommandPhase;
using drivers::DriverState;

namespace {

bool finished(CommandPhase p) {
  return p == CommandPhase::done || p == CommandPhase::failed;
}

double farthest(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

}  // namespace

ReplicaMirror::ReplicaMirror(std::vector<Copy> copies) {
  for (Copy& c : copies) {
    CW_CHECK(c.driver != nullptr, "the twin's copy of {} has no driver", c.robot);
    CW_CHECK(c.driver->capabilities().joints == c.chain.dof() && c.home.size() == c.chain.dof(),
             "the twin's copy of {} must take its {} joints", c.robot, c.chain.dof());
    Follower f(std::move(c));
    f.target = f.copy.home;
    followers_.push_back(std::move(f));
  }
}

ReplicaMirror::~ReplicaMirror() {
  stop();
}

std::optional<std::size_t> ReplicaMirror::index_of(const std::string& robot) const {
  for (std::size_t i = 0; i < followers_.size(); ++i) {
    if (followers_[i].copy.robot == robot) return i;
  }
  return std::nullopt;
}

void ReplicaMirror::to_actions(Follower& f, const ReplicaState& state) {
  // The position: joints when the controller reads joints (they changed), else the tool pose when it changed.
  const std::size_t dof = f.copy.chain.dof();
  const ReplicaState* last = f.last ? &*f.last : nullptr;
  // Compared with where the copy was last sent (small steps add up), not with the last state.
  std::optional<std::vector<double>> to;
  const Eigen::VectorXd target = Eigen::Map<const Eigen::VectorXd>(f.target.data(), static_cast<Eigen::Index>(dof));
  if (state.joints.size() == dof) {
    to = state.joints;
  } else if (state.tool_in_base) {
    const Eigen::Isometry3d there = f.copy.chain.forward(target);
    const Eigen::Isometry3d& b = *state.tool_in_base;
    const bool moved = (there.translation() - b.translation()).norm() > kToolTolerance ||
                       Eigen::AngleAxisd(there.linear().transpose() * b.linear()).angle() > kJointTolerance;
    if (moved) {
      const models::IkResult ik = f.copy.chain.inverse(*state.tool_in_base, target);
      if (ik.status == models::IkStatus::kOk) {
        to = std::vector<double>(ik.q.data(), ik.q.data() + ik.q.size());
      } else {
        ++counts_.misses;
      }
    }
  }
  if (to && farthest(*to, f.target) > kJointTolerance) {
    f.target = *to;
    f.todo.push_back(Action{Action::Kind::move, std::move(*to), {}, false});
    // Too far behind: the older moves go (never a grip), the copy goes straight on.
    std::size_t moves = 0;
    for (const Action& a : f.todo) moves += a.kind == Action::Kind::move ? 1 : 0;
    for (auto it = f.todo.begin(); moves > kMaxBehind && it != f.todo.end();) {
      if (it->kind == Action::Kind::move) {
        it = f.todo.erase(it);
        --moves;
        ++counts_.misses;
      } else {
        ++it;
      }
    }
  }
  // The hand: what it held before and holds now.
  const std::optional<std::string> before = last != nullptr ? last->holding : std::nullopt;
  if (before != state.holding) {
    if (before) f.todo.push_back(Action{Action::Kind::open, {}, *before, false});
    if (state.holding) f.todo.push_back(Action{Action::Kind::close, {}, *state.holding, false});
  }
  f.last = state;
}

void ReplicaMirror::push(std::size_t index, ReplicaState state) {
  std::lock_guard lock(mutex_);
  CW_CHECK(index < followers_.size(), "no copy {} in the twin's mirror", index);
  ++counts_.states;
  to_actions(followers_[index], state);
  poke_ = true;
  wake_.notify_all();
}

void ReplicaMirror::start() {
  std::lock_guard lock(mutex_);
  if (started_) return;
  started_ = true;
  for (Follower& f : followers_) {
    f.copy.driver->set_notifier([this] {
      std::lock_guard l(mutex_);
      poke_ = true;
      wake_.notify_all();
    });
  }
  thread_ = std::thread([this] { loop(); });
}

void ReplicaMirror::stop() {
  {
    std::lock_guard lock(mutex_);
    if (!started_ || stopping_) return;
    stopping_ = true;
    wake_.notify_all();
  }
  thread_.join();
  for (Follower& f : followers_) {
    f.copy.driver->set_notifier({});
    f.copy.driver->stop();  // where it stands
  }
}

bool ReplicaMirror::idle() const {
  std::lock_guard lock(mutex_);
  for (const Follower& f : followers_) {
    if (!f.up || f.running || !f.todo.empty()) return false;
  }
  return true;
}

ReplicaMirror::Counts ReplicaMirror::counts() const {
  std::lock_guard lock(mutex_);
  return counts_;
}

bool ReplicaMirror::closing_elsewhere(std::size_t index, const std::string& workpiece) const {
  for (std::size_t i = 0; i < followers_.size(); ++i) {
    if (i == index) continue;
    const Follower& f = followers_[i];
    if (f.running && f.running->kind == Action::Kind::close && f.running->workpiece == workpiece) return true;
    for (const Action& a : f.todo) {
      if (a.kind == Action::Kind::close && a.workpiece == workpiece) return true;
    }
  }
  return false;
}

void ReplicaMirror::loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    poke_ = false;
    advance(lock);
    wake_.wait(lock, [this] { return poke_ || stopping_; });
  }
}

void ReplicaMirror::advance(std::unique_lock<std::mutex>& /*lock: held*/) {
  for (std::size_t i = 0; i < followers_.size(); ++i) {
    Follower& f = followers_[i];
    drivers::RobotDriver& d = *f.copy.driver;
    // Up: connect, home, activate (again after a fault: the copy comes back through reset and home).
    if (d.state() != DriverState::active) {
      if (f.running) {
        ++counts_.misses;
        f.running.reset();
        f.running_id = 0;
      }
      f.up = false;
      // Each call moves it on a state, or starts the homing (whose end notifies): as far as it goes now.
      for (DriverState s = d.state(), was = DriverState::active; s != was && s != DriverState::active;
           was = s, s = d.state()) {
        const bool homing = f.home_id != 0 && !finished(d.poll(f.home_id).phase);
        if (s == DriverState::disconnected) {
          d.connect();
        } else if (s == DriverState::fault) {
          d.reset();
        } else if (s == DriverState::connected && !homing) {
          f.home_id = d.home().id;
        } else if ((s == DriverState::homed || s == DriverState::stopped) && !homing) {
          d.activate();
        }
      }
      if (d.state() != DriverState::active) continue;
    }
    f.up = true;
    if (const CommandPhase p = f.running ? d.poll(f.running_id).phase : CommandPhase::pending; finished(p)) {
      if (p == CommandPhase::failed) ++counts_.misses;
      f.running.reset();
      f.running_id = 0;
    }
  }
  // Then the next actions, every copy's end seen first (a close just done frees another copy's open).
  for (std::size_t i = 0; i < followers_.size(); ++i) {
    Follower& f = followers_[i];
    drivers::RobotDriver& d = *f.copy.driver;
    if (!f.up) continue;
    while (!f.running && !f.todo.empty()) {
      Action& a = f.todo.front();
      if (a.kind == Action::Kind::open && closing_elsewhere(i, a.workpiece)) {
        if (!a.held_back) ++counts_.waits;  // once per open, however many passes it waits
        a.held_back = true;
        break;  // the other copy's close first: this pass again when it is done
      }
      drivers::Command command;
      if (a.kind == Action::Kind::move) {
        command = drivers::MoveJoints{a.joints, 1.0};
      } else {
        drivers::Grip grip;
        grip.action = a.kind == Action::Kind::close ? drivers::Grip::Action::close : drivers::Grip::Action::open;
        command = grip;
      }
      const drivers::Submitted s = d.submit(command);
      if (s.error == drivers::ErrorCode::busy) break;
      Action taken = std::move(a);
      f.todo.pop_front();
      if (!s.accepted()) {
        ++counts_.misses;
        continue;
      }
      (taken.kind == Action::Kind::move ? counts_.moves : counts_.grips) += 1;
      f.running = std::move(taken);
      f.running_id = s.id;
    }
  }
}

}  // namespace cellwright::twin::sim
