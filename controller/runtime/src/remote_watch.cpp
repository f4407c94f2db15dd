#include "cellwright/runtime/remote_watch.hpp"

#include <utility>

#include <fmt/format.h>

namespace cellwright::runtime {

RemoteWatch::RemoteWatch(std::size_t robot, std::string label, std::string cell, RemoteLink& link,
                         MessageQueue<RobotStatus>& statuses, EventLog& log, const RecoveryOptions& recovery,
                         SimDuration rejoin_wait)
    : robot_(robot),
      label_(std::move(label)),
      cell_(std::move(cell)),
      link_(link),
      statuses_(statuses),
      log_(log),
      recovery_(recovery),
      rejoin_wait_(rejoin_wait) {}

bool RemoteWatch::step(SimDuration now) {
  if (phase_ == Phase::kStopped) return false;
  const LinkState s = link_.state();
  if (phase_ == Phase::kUp) {
    if (s.losses == seen_losses_) {
      if (s.present) session_ = s.session;
      return false;
    }
    if (s.in_flight < 0) {
      // Lost while idle: nothing was lost yet. Replaced already: the new agent takes the next command.
      if (s.present) {
        seen_losses_ = s.losses;
        session_ = s.session;
      }
      return false;
    }
    seen_losses_ = s.losses;
    ++faults_;
    lost_session_ = session_;
    primitive_ = s.in_flight;
    detected_ = now;
    detail_ = fmt::format("the agent of {} was lost with primitive {} in hand: {}", cell_, primitive_, s.lost_detail);
    log_.fault_detected(now, label_, primitive_, to_string(Symptom::link_lost), detail_);
    if (!recovery_.enabled) {
      stop(now, detail_, false);
      return true;
    }
    const DecisionTree& tree = recovery_.tree ? *recovery_.tree : DecisionTree::standard();
    const auto attempts = static_cast<std::uint64_t>(recovery_.max_attempts > 0 ? recovery_.max_attempts : 0);
    diagnosis_ = tree.diagnose(Symptom::link_lost, [&](Question q) {
      // Fewer than max_attempts recoveries of this robot's link before this one; nothing else can be asked of an
      // agent that is gone.
      return q == Question::retries_left && faults_ <= attempts;
    });
    log_.diagnosis(now, label_, to_string(Symptom::link_lost), diagnosis_.cause, to_string(diagnosis_.action),
                   diagnosis_.path);
    if (diagnosis_.action == Action::stop_cell) {
      stop(now, fmt::format("{}: {}", diagnosis_.cause, detail_), true);
      return true;
    }
    if (rejoin_wait_.count() <= 0) {
      stop(now,
           fmt::format("{}: {}; no new agent is waited for (the run's rejoin wait is 0): the cell is stopped",
                       diagnosis_.cause, detail_),
           true);
      return true;
    }
    deadline_ = now + rejoin_wait_;
    phase_ = Phase::kWaiting;
  }
  // Waiting for an agent (a new process, or the same one heard again).
  if (s.present) {
    const bool replaced = s.session != lost_session_;
    if (replaced && !s.holding.empty()) {
      stop(now,
           fmt::format("{}: {}; a new agent is there, but {} holds {}: re-homing would carry it along a way no check "
                       "has cleared; take the part out and home the arm by hand",
                       diagnosis_.cause, detail_, cell_, s.holding),
           true);
      return true;
    }
    if (replaced && !link_.resend()) {
      stop(now, fmt::format("{}: {}; a new agent is there, but the interrupted command could not be sent to it",
                            diagnosis_.cause, detail_),
           true);
      return true;
    }
    log_.recovery_end(now, label_, diagnosis_.cause, to_string(diagnosis_.action), true,
                      replaced ? fmt::format("a new agent of {} (session {}) brought its robot up and was sent "
                                             "primitive {} again",
                                             cell_, s.session, primitive_)
                               : fmt::format("the agent of {} is heard again (the same session)", cell_),
                      now - detected_);
    session_ = s.session;
    seen_losses_ = s.losses;
    phase_ = Phase::kUp;
    return false;
  }
  if (now >= deadline_) {
    stop(now,
         fmt::format("{}: {}; no agent came back within {} s", diagnosis_.cause, detail_,
                     format_sim_time(rejoin_wait_)),
         true);
    return true;
  }
  return false;
}

void RemoteWatch::stop(SimDuration now, const std::string& why, bool recovering) {
  if (recovering) {
    log_.recovery_end(now, label_, diagnosis_.cause, to_string(diagnosis_.action), false, why, now - detected_);
  }
  RobotStatus s;
  s.robot = robot_;
  // Not the primitive's index: its status may be on its way from the agent that was lost (task control takes one
  // status per command); "no command" stops (or fails) the run whatever task control holds in flight.
  s.index = RobotStatus::kNoCommand;
  s.outcome = CommandOutcome::kFailed;
  s.reason = why;
  s.stop_cell = recovering;
  s.time = now;
  const QueueStatus pushed = statuses_.try_push(std::move(s));
  CW_CHECK(pushed == QueueStatus::ok || pushed == QueueStatus::closed, "robot {}: status queue refused: {}", label_,
           to_string(pushed));
  phase_ = Phase::kStopped;
}

}  // namespace cellwright::runtime
