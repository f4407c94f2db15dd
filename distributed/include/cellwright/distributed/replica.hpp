// What a robot control in another process (an agent, docs/distributed.md) shares with the rest of the cell besides
// its commands and statuses (link.hpp): its writes into the environment model, and its events.
//
// THE ENVIRONMENT MODEL. Robot control writes its robot's joints, tool pose and holds into the model and the
// workpieces it takes, moves with its hand, releases, claims or sets aside; it reads the other robots' (a hand-over's
// hand_grasp(r1) is where r1's tool really is). In one process they share one model; across processes each agent
// publishes what its robot control changed in a step (a ModelUpdate: its robot's state and each workpiece the step
// changed, whole) on rt/cellwright/<robot>/model, and every other agent and task control apply the updates of the
// robots that are not theirs. Each workpiece is written by one robot at a time (the program hands it over: r2 closes
// on it before r1 opens), so an update never undoes another's.
//
// THE EVENTS. Robot control's events (command_start/end, sensor, faults, recoveries) are logged in the agent's
// process; each goes as its log line (log_event.hpp's encoding, decoded and checked on arrival) on
// rt/cellwright/<robot>/events into task control's log, so that the run's report sees them.
//
// Types (plain CDR, @final, bounded; encoded by hand with Fast CDR as wire.hpp's):
//
//   @final struct Pose_ { double x, y, z, qw, qx, qy, qz; };
//   @final struct Hold_ { boolean set; string<128> workpiece; uint8 approach; double tcp_above_bottom; Pose_ in_hand; };
//   @final struct Workpiece_ { string<128> name; Pose_ pose; double vx, vy, vz; boolean motion_known, present;
//                              string<128> held_by, claimed_by; double confidence; int64 stamp_ns; boolean lost;
//                              string<1024> lost_reason; };
//   @final struct ModelUpdate_ { uint32 robot; uint64 sequence; int64 time_ns; sequence<double, 16> joints;
//                                Hold_ hold; Hold_ dropped_hold; boolean has_tcp; Pose_ tcp;
//                                boolean has_released_tcp; Pose_ released_tcp; sequence<Workpiece_, 64> workpieces; };
//   @final struct RobotEvent_ { uint32 robot; uint64 sequence; string<8192> line; };
//
// `sequence` counts an agent's samples from 1; a receiver counts a gap (a sample lost) as a refusal. A sample that does
// not decode (garbage, another robot's on this robot's topic, a workpiece or event the cell does not know) is refused.
//
// Threads: encode/decode/changes/apply are pure functions. The publishers are called from one thread (the agent's
// step thread); a subscriber hands samples over on Fast DDS's listener thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/distributed/link.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/log_event.hpp"

namespace cellwright::distributed {

inline constexpr const char* kModelUpdateTypeName = "cellwright::msg::dds_::ModelUpdate_";
inline constexpr const char* kRobotEventTypeName = "cellwright::msg::dds_::RobotEvent_";
inline constexpr std::size_t kNameBound = 128;
inline constexpr std::size_t kEventLineBound = 8192;
inline constexpr std::size_t kMaxJoints = 16;
inline constexpr std::size_t kMaxWorkpieces = 64;

// "rt/cellwright/<robot>/model", "rt/cellwright/<robot>/events" (InputError for a robot name that is no ROS 2 token).
std::string model_topic(const std::string& robot);
std::string events_topic(const std::string& robot);

// What one step of one robot control changed in the model.
struct ModelUpdate {
  std::size_t robot = 0;       // program index
  std::uint64_t sequence = 0;  // 1, 2, ...
  runtime::SimDuration time{0};
  runtime::RobotState state;  // name, joints, hold, dropped_hold, tcp, released_tcp (not `fixed`, grip, force)
  std::vector<runtime::WorkpieceState> workpieces;  // whole, `fixed` unset
};

// What changed from `before` to `after` for robot `robot` (cell name, program index): nullopt when nothing. Only the
// robot's own state is compared, and every workpiece.
std::optional<ModelUpdate> changes(const runtime::EnvironmentModel& before, const runtime::EnvironmentModel& after,
                                   const std::string& robot, std::size_t index);

// Writes the update into `model`: the robot's state (its grip and force readings kept) and each workpiece (its geometry
// kept). Throws WireError for a robot or workpiece the model does not have.
void apply(runtime::EnvironmentModel& model, const ModelUpdate& update);

// Throws WireError when a value does not fit its field (more joints or workpieces than the bounds).
std::vector<char> encode_model_update(const ModelUpdate& update);
// Throws WireError (see the top); `robot` is the topic's program index.
ModelUpdate decode_model_update(const std::vector<char>& bytes, std::size_t robot);
std::size_t max_model_update_size();

std::vector<char> encode_robot_event(std::size_t robot, std::uint64_t sequence, const std::string& line);
// The event and its sequence number; throws WireError (a line that is no event of the log included).
std::pair<runtime::LogEvent, std::uint64_t> decode_robot_event(const std::vector<char>& bytes, std::size_t robot);
std::size_t max_robot_event_size();

// An agent's writers: its robot's model updates and events.
class AgentPublisher {
 public:
  AgentPublisher(Participant& participant, const std::string& robot, std::size_t index);
  ~AgentPublisher();
  AgentPublisher(const AgentPublisher&) = delete;
  AgentPublisher& operator=(const AgentPublisher&) = delete;
  // Publishes what changed (changes()); nothing when nothing did.
  void publish_changes(const runtime::EnvironmentModel& before, const runtime::EnvironmentModel& after,
                       runtime::SimDuration now);
  // Publishes one event (as its log line).
  void publish_event(const runtime::LogEvent& event);
  // Waits until every sample is acknowledged by the readers; false on timeout.
  bool flush(std::chrono::milliseconds timeout);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A reader of one robot's model updates and events: hands each update to `on_update` and each event to `on_event`
// (either may be empty: not read), on Fast DDS's listener thread, once started.
class RobotSubscriber {
 public:
  RobotSubscriber(Participant& participant, const std::string& robot, std::size_t index,
                  std::function<void(const ModelUpdate&)> on_update,
                  std::function<void(const runtime::LogEvent&)> on_event);
  ~RobotSubscriber();
  RobotSubscriber(const RobotSubscriber&) = delete;
  RobotSubscriber& operator=(const RobotSubscriber&) = delete;
  void start();
  void stop();
  // Samples refused (garbage, a gap in the sequence, an update the model cannot take) and the last reason.
  Refusals refusals() const;
  std::uint64_t updates() const;
  std::uint64_t events() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Task control's side: the subscriber of one remote robot applying its updates into `environment` and logging its
// events into `log` (as they arrive).
std::unique_ptr<RobotSubscriber> share_into(Participant& participant, const std::string& robot, std::size_t index,
                                            runtime::SharedEnvironment& environment, runtime::EventLog& log);

}  // namespace cellwright::distributed
