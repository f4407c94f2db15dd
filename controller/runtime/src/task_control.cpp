#include "cellwright/runtime/task_control.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "cellwright/common/error.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::runtime {

std::string_view to_string(CommandOutcome outcome) {
  return outcome == CommandOutcome::kDone ? "done" : "failed";
}

const char* to_string(RobotActivity activity) {
  switch (activity) {
    case RobotActivity::kIdle:
      return "idle";
    case RobotActivity::kBusy:
      return "busy";
    case RobotActivity::kWaiting:
      return "waiting";
    case RobotActivity::kBlocked:
      return "blocked";
  }
  return "?";
}

namespace {

bool net_only(task::PrimitiveKind k) {
  return k == task::PrimitiveKind::kSignal || k == task::PrimitiveKind::kWait || k == task::PrimitiveKind::kLoop;
}

}  // namespace

TaskControl::TaskControl(const petri::Net& net, const task::CompiledProgram& program,
                         std::vector<MessageQueue<MotionCommand>*> robot_inboxes,
                         MessageQueue<RobotStatus>& status_inbox, EventLog& log, RecoveryOptions recovery,
                         SignalFilter signal_filter, MessageQueue<MotionCommand>* device_inbox)
    : net_(net),
      program_(program),
      inboxes_(std::move(robot_inboxes)),
      device_inbox_(device_inbox),
      statuses_(status_inbox),
      log_(log),
      marking_(net.initial_marking()),
      arbiter_(petri::make_arbiter(net)),
      loops_(net, program),
      places_(net.num_places()),
      completed_(net.num_places(), false),
      in_flight_(program.robots.size(), false),
      activity_(program.robots.size(), RobotActivity::kIdle),
      time_(program.robots.size()),
      recovery_(std::move(recovery)),
      signal_filter_(std::move(signal_filter)),
      wait_since_(program.robots.size()) {
  for (petri::PlaceId p = 0; p < net.num_places(); ++p) expected_tokens_.push_back(marking_[p]);
  CW_CHECK(net.robots() == program.robots, "the net's robots are not the program's ({} vs {})", net.robots().size(),
           program.robots.size());
  CW_CHECK(program.programs.size() == program.robots.size(), "{} programs for {} robots", program.programs.size(),
           program.robots.size());
  CW_CHECK(inboxes_.size() == program.robots.size(), "{} robot inboxes for {} robots", inboxes_.size(),
           program.robots.size());
  for (auto* q : inboxes_) CW_CHECK(q != nullptr, "a robot inbox is missing");
  for (std::size_t r = 0; r < program.robots.size(); ++r) {
    const std::string& label = program.robots[r];
    const auto& prims = program.programs[r].primitives;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      const auto p = net.find_place(task::place_id(label, k));
      CW_CHECK(p.has_value(), "the net has no place for primitive {} of robot {}", k, label);
      places_[*p] = {true, r, k};
    }
    CW_CHECK(net.find_place(task::start_place_id(label)) && net.find_place(task::done_place_id(label)),
             "the net has no start or done place for robot {}", label);
  }
  for (const petri::Transition& t : net.transitions()) {
    if (!t.starts_robot) continue;
    CW_CHECK(*t.starts_robot < program.robots.size() && t.starts_primitive >= 0 &&
                 static_cast<std::size_t>(t.starts_primitive) < program.programs[*t.starts_robot].primitives.size(),
             "transition {} starts primitive {} of robot {}, which the program does not have", t.id, t.starts_primitive,
             *t.starts_robot);
  }
}

std::vector<bool> TaskControl::allowed() const {
  std::vector<bool> ok(net_.num_transitions(), true);
  for (petri::TransitionId t = 0; t < net_.num_transitions(); ++t) {
    for (const petri::Arc& a : net_.transitions()[t].inputs) {
      if (places_[a.place].command && !completed_[a.place]) {
        ok[t] = false;
        break;
      }
    }
  }
  loops_.restrict(ok);
  if (!script_.empty()) {
    // Only the script's next transition (none once the script is done).
    for (petri::TransitionId t = 0; t < net_.num_transitions(); ++t) {
      if (script_pos_ >= script_.size() || t != script_[script_pos_]) ok[t] = false;
    }
  }
  return ok;
}

void TaskControl::follow(std::vector<petri::TransitionId> order) {
  CW_CHECK(firings_ == 0, "a firing script given after {} firings", firings_);
  for (const petri::TransitionId t : order) {
    CW_CHECK(t < net_.num_transitions(), "scripted transition {} of a net of {}", t, net_.num_transitions());
  }
  script_ = std::move(order);
  script_pos_ = 0;
}

void TaskControl::drain_statuses(SimDuration now) {
  RobotStatus s;
  while (statuses_.try_pop(s) == QueueStatus::ok) {
    CW_CHECK(s.robot < program_.robots.size(), "status from robot {} of {}", s.robot, program_.robots.size());
    const std::string& label = program_.robots[s.robot];
    if (s.index == RobotStatus::kNoCommand) {
      CW_CHECK(s.outcome == CommandOutcome::kFailed, "robot {} reported success without a command", label);
      if (state_ == State::kRunning) {
        state_ = s.stop_cell ? State::kStopped : State::kFailed;
        reason_ = fmt::format("robot {}: {}", label, s.reason);
      }
      continue;
    }
    CW_CHECK(in_flight_[s.robot], "robot {} reported primitive {} with no command in flight", label, s.index);
    const auto place = net_.find_place(task::place_id(label, s.index));
    CW_CHECK(place && marking_[*place] > 0, "robot {} reported primitive {}, which it is not executing", label,
             s.index);
    in_flight_[s.robot] = false;
    if (s.outcome == CommandOutcome::kDone) {
      completed_[*place] = true;
    } else if (state_ == State::kRunning && s.stop_cell) {
      state_ = State::kStopped;
      reason_ = fmt::format("robot {}: {}", label, s.reason);
    } else if (state_ == State::kRunning) {
      const task::Primitive& p = program_.programs[s.robot].primitives[s.index];
      state_ = State::kFailed;
      reason_ = fmt::format("robot {}, primitive {} '{}' (line {}, {}): {}", label, s.index, task::to_string(p),
                            p.where.line, p.task, s.reason);
    }
  }
  (void)now;
}

void TaskControl::fire_until_quiescent(SimDuration now) {
  for (;;) {
    const std::vector<petri::TransitionId> chosen = petri::choose(net_, marking_, arbiter_, allowed());
    if (chosen.empty()) return;
    petri::fire_chosen(net_, marking_, arbiter_, chosen);
    for (const petri::TransitionId id : chosen) {
      if (script_pos_ < script_.size() && id == script_[script_pos_]) ++script_pos_;
      loops_.fired(id);
      const petri::Transition& t = net_.transitions()[id];
      for (const petri::Arc& a : t.inputs) expected_tokens_[a.place] -= a.weight;
      for (const petri::Arc& a : t.outputs) expected_tokens_[a.place] += a.weight;
      ++firings_;
      last_fired_.push_back(t.id);
      log_.fire(now, t.id, t.origin.robot, t.starts_primitive, t.origin.line, t.origin.task, t.origin.motion);
      if (!t.starts_robot) continue;
      const std::size_t r = *t.starts_robot;
      const auto k = static_cast<std::size_t>(t.starts_primitive);
      const task::Primitive& p = program_.programs[r].primitives[k];
      const petri::PlaceId place = *net_.find_place(task::place_id(program_.robots[r], k));
      if (net_only(p.kind)) {
        // A signal is done as it fires; a wait is gated by its event place; a loop's end by the iteration count (the
        // leader's) or the leader's decision event (a follower's).
        completed_[place] = true;
        if (p.kind == task::PrimitiveKind::kSignal) {
          ++signals_fired_;
          if (signal_filter_) {
            const auto ev = net_.find_place(task::event_place_id(p.event));
            if (ev && marking_[*ev] > 0 && !signal_filter_(SignalSent{now, program_.robots[r], p.event, signals_fired_})) {
              marking_[*ev] -= 1;  // dropped on the way: the event never reaches its place
            }
          }
        }
        continue;
      }
      completed_[place] = false;
      CW_CHECK(!in_flight_[r], "robot {} was sent primitive {} with a command still in flight", program_.robots[r], k);
      in_flight_[r] = true;
      MotionCommand cmd{r, k, p, id, now};
      const bool device = p.kind == task::PrimitiveKind::kDevice;
      CW_CHECK(!device || device_inbox_ != nullptr, "robot {} orders device command '{}' and the run has no device "
               "control", program_.robots[r], task::to_string(p));
      const QueueStatus pushed = (device ? device_inbox_ : inboxes_[r])->try_push(std::move(cmd));
      // Each robot has at most one command in flight, so its inbox (and device control's, sized for one per robot)
      // always has room; closed means the run is over.
      CW_CHECK(pushed == QueueStatus::ok || pushed == QueueStatus::closed, "robot {} {} refused a command: {}",
               program_.robots[r], device ? "device control's inbox" : "inbox", to_string(pushed));
    }
  }
}

void TaskControl::detect_end(SimDuration now) {
  if (state_ != State::kRunning) return;
  if (net_.is_final(marking_)) {
    state_ = State::kFinished;
    finished_at_ = now;
    return;
  }
  if (petri::is_dead(net_, marking_) && recovery_.enabled) {
    // Nothing can fire: a wait whose event was signalled but is not there is a wait that will never end. Every
    // waiting robot is taken up at once (the wait watchdog would only find it later).
    classify(now);
    for (auto& since : wait_since_) {
      if (since) since = now - recovery_.wait_timeout;
    }
    for (std::size_t r = 0; r < program_.robots.size(); ++r) {
      if (activity_[r] == RobotActivity::kWaiting && !wait_since_[r]) wait_since_[r] = now - recovery_.wait_timeout;
    }
    watch_waits(now, true);
    if (state_ != State::kRunning || !petri::is_dead(net_, marking_)) return;
  }
  if (petri::is_dead(net_, marking_)) {
    std::string marked;
    for (petri::PlaceId p = 0; p < net_.num_places(); ++p) {
      if (marking_[p] == 0) continue;
      if (!marked.empty()) marked += ", ";
      marked += marking_[p] == 1 ? net_.places()[p].name : fmt::format("{} x{}", net_.places()[p].name, marking_[p]);
    }
    state_ = State::kFailed;
    reason_ = fmt::format("deadlock: no transition can fire; marked: {}", marked);
  }
}

void TaskControl::classify(SimDuration now) {
  (void)now;
  for (std::size_t r = 0; r < program_.robots.size(); ++r) {
    if (state_ != State::kRunning) {
      activity_[r] = RobotActivity::kIdle;
      continue;
    }
    const std::string& label = program_.robots[r];
    if (marking_[*net_.find_place(task::done_place_id(label))] > 0) {
      activity_[r] = RobotActivity::kIdle;
    } else if (in_flight_[r]) {
      activity_[r] = RobotActivity::kBusy;
    } else {
      activity_[r] = RobotActivity::kBlocked;
      const auto& prims = program_.programs[r].primitives;
      for (std::size_t k = 0; k < prims.size(); ++k) {
        if (prims[k].kind == task::PrimitiveKind::kWait && marking_[*net_.find_place(task::place_id(label, k))] > 0) {
          activity_[r] = RobotActivity::kWaiting;
        }
      }
    }
  }
}

void TaskControl::account_until(SimDuration now) {
  if (now <= accounted_) return;
  const SimDuration dt = now - accounted_;
  for (std::size_t r = 0; r < time_.size(); ++r) {
    switch (activity_[r]) {
      case RobotActivity::kIdle:
        time_[r].idle += dt;
        break;
      case RobotActivity::kBusy:
        time_[r].busy += dt;
        break;
      case RobotActivity::kWaiting:
        time_[r].waiting += dt;
        break;
      case RobotActivity::kBlocked:
        time_[r].blocked += dt;
        break;
    }
  }
  accounted_ = now;
}

TaskControl::State TaskControl::step(SimDuration now) {
  account_until(now);
  last_step_ = now;
  last_fired_.clear();
  if (state_ == State::kRunning) {
    drain_statuses(now);
    if (state_ == State::kRunning) fire_until_quiescent(now);
    detect_end(now);
  }
  classify(now);
  if (state_ == State::kRunning && recovery_.enabled) watch_waits(now, false);
  return state_;
}

void TaskControl::watch_waits(SimDuration now, bool dead) {
  for (std::size_t r = 0; r < program_.robots.size(); ++r) {
    if (activity_[r] != RobotActivity::kWaiting) {
      wait_since_[r].reset();
      continue;
    }
    if (!wait_since_[r]) wait_since_[r] = now;
    if (now - *wait_since_[r] < recovery_.wait_timeout) continue;
    const std::string& label = program_.robots[r];
    const auto& prims = program_.programs[r].primitives;
    std::size_t k = 0;
    for (; k < prims.size(); ++k) {
      if (prims[k].kind == task::PrimitiveKind::kWait && marking_[*net_.find_place(task::place_id(label, k))] > 0) break;
    }
    if (k == prims.size()) continue;
    const auto ev = net_.find_place(task::event_place_id(prims[k].event));
    if (!ev) continue;
    const bool fired = expected_tokens_[*ev] > static_cast<std::int64_t>(marking_[*ev]);
    if (dead && !fired) continue;  // it waits for another robot, which is the one stuck
    log_.fault_detected(now, label, static_cast<int>(k), "wait_timeout",
                        dead ? fmt::format("no transition can fire while {} waits for event {}, which was signalled",
                                           label, prims[k].event)
                             : fmt::format("{} waited {} s for event {}", label,
                                           format_sim_time(now - *wait_since_[r]), prims[k].event));
    const DecisionTree& tree = recovery_.tree ? *recovery_.tree : DecisionTree::standard();
    const Diagnosis d = tree.diagnose(Symptom::wait_timeout, [&](Question q) {
      return q == Question::signal_fired ? fired : q == Question::retries_left;
    });
    log_.diagnosis(now, label, "wait_timeout", d.cause, to_string(d.action), d.path);
    if (d.action == Action::resignal && fired) {
      marking_[*ev] = static_cast<petri::Tokens>(expected_tokens_[*ev]);
      log_.recovery_end(now, label, d.cause, to_string(d.action), true,
                        fmt::format("event {} delivered again", prims[k].event), SimDuration{0});
      wait_since_[r].reset();
      fire_until_quiescent(now);
      detect_end(now);
      classify(now);
      return;
    }
    if (d.action == Action::go_on || d.action == Action::retry || d.action == Action::wait_clear) {
      wait_since_[r] = now;  // look again after another timeout
      continue;
    }
    log_.recovery_end(now, label, d.cause, to_string(d.action), false, "the cell is stopped", now - *wait_since_[r]);
    state_ = State::kStopped;
    reason_ = fmt::format("robot {}: waited {} s for event {}: {}", label, format_sim_time(now - *wait_since_[r]),
                          prims[k].event, d.cause);
    classify(now);
    return;
  }
}

bool TaskControl::any_waiting() const {
  return std::find(activity_.begin(), activity_.end(), RobotActivity::kWaiting) != activity_.end();
}

TaskView TaskControl::view() const {
  TaskView v;
  v.time = last_step_;
  v.marking = marking_;
  v.last_fired = last_fired_;
  v.firings = firings_;
  for (std::size_t r = 0; r < program_.robots.size(); ++r) {
    RobotView rv;
    rv.robot = program_.robots[r];
    rv.activity = activity_[r];
    const auto& prims = program_.programs[r].primitives;
    auto marked = [&](const std::string& id) { return marking_[*net_.find_place(id)] > 0; };
    if (marked(task::done_place_id(rv.robot))) {
      rv.done = true;
      rv.place = task::done_place_id(rv.robot);
    } else if (marked(task::start_place_id(rv.robot))) {
      rv.place = task::start_place_id(rv.robot);
    }
    for (std::size_t k = 0; k < prims.size(); ++k) {
      if (marked(task::place_id(rv.robot, k))) {
        rv.primitive = static_cast<int>(k);
        rv.command = task::to_string(prims[k]);
        rv.place = task::place_id(rv.robot, k);
      }
    }
    v.robots.push_back(std::move(rv));
  }
  return v;
}

}  // namespace cellwright::runtime
