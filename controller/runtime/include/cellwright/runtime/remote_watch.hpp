// RemoteWatch: the runtime's watch over one remote robot's link (runtime.hpp's RemoteLink; docs/distributed.md,
// "Failure behaviour"). A remote robot has no robot control in this process, so the faults robot control would sense
// of its driver cannot be sensed here; what can is the link: its agent lost (the process killed, its host gone, the
// network cut: the link's liveliness lease lapsed) or replaced by a new process.
//
// step(), every control period on the remote robot's thread (real time):
//   - an agent lost while it had work (a command sent and not answered) is the symptom `link_lost` of that robot:
//     `fault_detected` (robot, the primitive in flight, the link's detail), then the decision tree's `diagnosis`
//     (questions: retries_left is "fewer than max_attempts losses of this robot's agent so far"; driver_in_fault and
//     every other question "no": nothing here can ask the lost agent's driver). An agent lost while idle is no fault
//     until it is given work (a command sent to no agent stays in flight, and that is a loss with work in hand).
//   - the action stop_cell, recovery disabled, or RunConfig::rejoin_wait 0 (the default): the cell is stopped at once:
//     a failed status with stop_cell (recovery disabled: without it, the run fails) reaches task control, the run
//     ends (outcome stopped, the reason naming the robot and the lost link) and the other robots are halted as every
//     run's end halts them. `recovery_end` (not ok) says why first.
//   - any other action (the standard tree's first answer is reset_rehome): wait up to rejoin_wait for an agent. One
//     that comes back is a new process (a new session) that has brought its robot up as every agent does before it
//     says it is ready (connected, its arm's position read, homed, activated): that is the re-homing, from where the
//     arm stood. The interrupted command is then sent to it again (RemoteLink::resend) and the run goes on;
//     `recovery_end` ok. The same session reported present again (a network that healed, by a link that can tell: the
//     DDS link takes back no agent whose lease lapsed) is sent nothing again: its reliable streams resume. An arm that holds a part (LinkState::holding) is not re-homed with it (docs/faults.md, "A loaded
//     arm is not homed"): the cell is stopped, naming the part. No agent by the deadline: the cell is stopped.
//   Meanwhile the other robots go on with what does not wait for this one, as with an in-process reset_rehome.
//
// Threads: one RemoteWatch per remote robot, used by that robot's thread only. It pushes into the status queue and
// logs; the link's state may change under it (read once per step).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/runtime/runtime.hpp"

namespace cellwright::runtime {

class RemoteWatch {
 public:
  // `robot`: program index, `label` its program label (the log's robot), `cell` the cell robot's name. All references
  // must outlive the watch.
  RemoteWatch(std::size_t robot, std::string label, std::string cell, RemoteLink& link,
              MessageQueue<RobotStatus>& statuses, EventLog& log, const RecoveryOptions& recovery,
              SimDuration rejoin_wait);

  // One look at the link at simulation time `now` (see the top). Returns true when it pushed a status (task control
  // has something to read).
  bool step(SimDuration now);

  enum class Phase { kUp, kWaiting, kStopped };
  Phase phase() const { return phase_; }

 private:
  // Ends this robot's part: `recovering` (a diagnosis was made): recovery_end not ok and a stop_cell status; else (recovery
  // disabled) a failed status, which fails the run.
  void stop(SimDuration now, const std::string& why, bool recovering);

  std::size_t robot_;
  std::string label_, cell_;
  RemoteLink& link_;
  MessageQueue<RobotStatus>& statuses_;
  EventLog& log_;
  const RecoveryOptions& recovery_;
  SimDuration rejoin_wait_;

  Phase phase_ = Phase::kUp;
  std::uint64_t seen_losses_ = 0;  // losses dealt with
  std::uint64_t faults_ = 0;       // link_lost faults of this robot so far
  std::uint64_t session_ = 0;       // the agent's session last seen present
  std::uint64_t lost_session_ = 0;  // the one that was lost
  std::string detail_;
  int primitive_ = -1;             // the command in flight at the loss
  SimDuration detected_{0};
  SimDuration deadline_{0};
  Diagnosis diagnosis_;
};

}  // namespace cellwright::runtime
