// The DDS transport of the runtime's queues (docs/distributed.md). Task control sends a robot its commands through
// the robot's command queue and reads every robot's statuses from the status queue (MessageQueue, Fig. 2); robot
// control reads its command queue and pushes into the status queue. Neither knows whether the other end is a thread
// of its process or an agent in another process: these links carry the same queues over DDS.
//
//   task control process                              agent process (twin agent, one robot)
//   command queue r ──> RemoteRobot ── rt/cellwright/<r>/command ──> AgentEndpoint ──> command queue r
//   status queue  <──── RemoteRobot <── rt/cellwright/<r>/status ─── AgentEndpoint <── status queue
//
// Topics are named as ROS 2 names them (the rt/ prefix of a ROS topic), the types are wire.hpp's, the QoS is ROS 2's
// default: reliable, volatile, keep last 10. A third topic, rt/cellwright/<r>/agent (reliable, transient local, keep
// last 1, as ROS 2 latches tf_static), carries the agent's state: ready once it has started (AgentEndpoint::start:
// a command taken before would be dropped, and its status never sent) and its command reader has matched task
// control's writer and its status writer task control's reader. Task control sends nothing before it has seen that
// state and matched both endpoints itself: a volatile reader that matches a writer late loses what the writer sent
// before, so a match seen on one side only is not enough (the first commands were lost without this). Samples are the
// CDR bytes wire.hpp encodes; a sample that does not decode (garbage, another program's command, another robot's
// status) is refused: counted, its reason kept and written to stderr, never pushed into a queue.
//
// Liveliness and order (docs/distributed.md, "Failure behaviour"): every endpoint has automatic liveliness with a
// short lease (DdsOptions::lease, 1 s), and each participant has the same lease for discovery (a participant silent
// for it is dropped with its endpoints: what finds a lost peer with Fast DDS 2.9.1, whose automatic liveliness is kept
// by any peer's announcements: dds_entities.hpp, PeerWatch): task control's end of a robot knows, within about the
// lease, that its agent is gone (killed, its host down, the network cut) and tells the runtime through
// RemoteLink::state(), and an agent knows the same of task control (AgentEndpoint::task_control_lost); the runtime's
// watcher (runtime/remote_watch.hpp) makes that a link_lost fault. An agent is present when its state says ready
// and this side's endpoints match endpoints of the agent's own participant (an agent that was killed stays matched
// until its participant's discovery lease expires: a count of matches would take it for the new one); a lapse is for
// good (only a new process is present again). Each agent process has a session (a number drawn
// as it starts, in its state); commands and statuses are numbered from 1 within a session, and a duplicate or a gap is
// refused (wire.hpp's SequenceCheck): a duplicate is dropped, a gap (a sample lost on the way) also stops the cell
// with the reason, because what was lost would be waited for forever. A status of another session than the present
// agent's (a late one of an agent that was replaced), or of a primitive that is not the command in flight, is refused.
//
// Transport: UDPv4 only by default; Fast DDS's shared-memory transport is off unless asked for (DdsOptions), because
// it keeps files in /dev/shm that a process killed before its clean-up leaves behind.
//
// Threads: each link forwards its outgoing queue on a thread of its own (it pops with a short timeout, so stop()
// ends it promptly) and pushes incoming samples from Fast DDS's listener thread (a blocking push: the queue is
// drained by its reader every turn). Construct, start and stop a link on one thread; refused()/last_refusal() may be
// called from any thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed {

struct DdsOptions {
  int domain = 0;              // DDS domain id, 0..232
  bool shared_memory = false;  // also Fast DDS's shared-memory transport (same host)
  // The liveliness lease of every endpoint (automatic liveliness) and the participant's (discovery's, announced 4
  // times a lease): a peer that gives no sign of life this long is lost. Task control and its agents must use the same
  // lease (DDS matches a reader only with writers whose lease is not longer than its own). At least 20 ms
  // (InputError).
  std::chrono::milliseconds lease{1000};
};

// "rt/cellwright/<robot>/command", "rt/cellwright/<robot>/status". Throws InputError (naming the robot) when the
// name is not a valid ROS 2 topic token (letters, digits, underscores, not starting with a digit).
std::string command_topic(const std::string& robot);
std::string status_topic(const std::string& robot);
std::string agent_topic(const std::string& robot);

// One DDS domain participant (a process has one). Throws InputError for a domain outside 0..232, InternalError
// when Fast DDS cannot create it.
class Participant {
 public:
  Participant(DdsOptions options, const std::string& name);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  int domain() const { return options_.domain; }
  std::chrono::milliseconds lease() const { return options_.lease; }

  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  DdsOptions options_;
  std::unique_ptr<Impl> impl_;
};

// The samples a link refused and why (the last one).
struct Refusals {
  std::uint64_t count = 0;
  std::string last;
};

// Task control's end of one remote robot: writes what task control pushes into the robot's command queue to the
// command topic, and pushes the statuses read from the status topic into the status queue.
class RemoteRobot {
 public:
  // `robot`: the cell robot's name (the topics'), `index` its program index (RobotStatus::robot). The participant
  // and both queues must outlive the link.
  RemoteRobot(Participant& participant, std::string robot, std::size_t index,
              runtime::MessageQueue<runtime::MotionCommand>& commands,
              runtime::MessageQueue<runtime::RobotStatus>& statuses);
  ~RemoteRobot();
  RemoteRobot(const RemoteRobot&) = delete;
  RemoteRobot& operator=(const RemoteRobot&) = delete;

  // Whether an agent is there: its command reader and status writer both matched, and it said it is ready.
  bool agent_present() const;
  // Waits at most `timeout` for the agent; true when it is there.
  bool wait_for_agent(std::chrono::milliseconds timeout) const;
  // Starts forwarding the command queue (commands pushed before are sent then). Idempotent.
  void start();
  // Stops forwarding (commands still queued stay in the queue). Idempotent; the destructor calls it.
  void stop();

  // The agent as this end sees it, any thread (runtime::LinkState): present (ready, both endpoints matched, its
  // liveliness holding), its session, how many times it was lost (its liveliness lapsed, its endpoints left, it said it
  // stopped, or a new agent process for the robot took its place) and how the last loss was noticed, the command in
  // flight, what the arm holds by the grip commands answered.
  runtime::LinkState state() const;
  // Sends the commands in flight again, oldest first, numbered as the next of the present agent's session (after a
  // new agent took over). false when none is in flight or no agent is present.
  bool resend();

  const std::string& robot() const;
  Refusals refusals() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Waits until every robot's agent is there, all within `timeout` together. Throws InputError naming the robots whose
// agent was not found, the domain and how to start one.
void wait_for_agents(const std::vector<RemoteRobot*>& robots, int domain, std::chrono::milliseconds timeout);

// Task control's side of a cell whose robots (some or all) run as agents: gives the Runtime the links of its remote
// robots (RunConfig::attach_remote) and waits for their agents.
//
//   RemoteCell remote(participant);
//   config.remote_robots = {...};
//   config.attach_remote = remote.attach();
//   runtime::Runtime run(std::move(config));      // makes a RemoteRobot per remote robot
//   remote.wait_for_agents(10s);                   // InputError naming the robots whose agent is missing
//   run.run();
//
// The Runtime owns the links; the RemoteCell's waits are for between the Runtime's construction and its end.
class RemoteCell {
 public:
  explicit RemoteCell(Participant& participant) : participant_(participant) {}
  runtime::AttachRemote attach();
  void wait_for_agents(std::chrono::milliseconds timeout) const;

 private:
  Participant& participant_;
  std::vector<RemoteRobot*> robots_;
};

// An agent's end for its robot: pushes the commands read from the command topic (decoded against `program`, the
// program the agent runs) into the robot's command queue, and writes what robot control pushes into the status
// queue to the status topic.
class AgentEndpoint {
 public:
  AgentEndpoint(Participant& participant, std::string robot, std::size_t index, const task::CompiledProgram& program,
                runtime::MessageQueue<runtime::MotionCommand>& commands,
                runtime::MessageQueue<runtime::RobotStatus>& statuses);
  ~AgentEndpoint();
  AgentEndpoint(const AgentEndpoint&) = delete;
  AgentEndpoint& operator=(const AgentEndpoint&) = delete;

  // Whether task control is there: its command writer and status reader both matched.
  bool task_control_present() const;
  // Once task control is no longer present: why it was lost, or empty when it ended (its process said goodbye) or has
  // not gone. Lost: discovery dropped its participant, not heard of for DdsOptions::lease (its process killed, its
  // host down, the network cut: within about the lease, its endpoints unmatched just before). Fast DDS reports the
  // participant's end just after its endpoints': this waits at most `wait` for it.
  std::string task_control_lost(std::chrono::milliseconds wait) const;
  bool wait_for_task_control(std::chrono::milliseconds timeout) const;
  void start();
  void stop();
  // Waits at most `timeout` until the status queue is empty and every status has been written and acknowledged by
  // task control (before the agent exits). false on timeout.
  bool flush(std::chrono::milliseconds timeout);

  Refusals refusals() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Writes bytes as they are as samples of a topic of the command or status type, unchecked: for tests and diagnostics
// (what a faulty or hostile peer could put on a topic, which the readers must refuse).
class RawWriter {
 public:
  // `type` is kCommandTypeName or kStatusTypeName (wire.hpp).
  RawWriter(Participant& participant, const std::string& topic, const char* type);
  ~RawWriter();
  RawWriter(const RawWriter&) = delete;
  RawWriter& operator=(const RawWriter&) = delete;

  bool wait_for_reader(std::chrono::milliseconds timeout) const;
  // false when Fast DDS refused the sample (shorter than a CDR header, or over the type's largest size).
  bool write(const std::vector<char>& bytes);
  bool flush(std::chrono::milliseconds timeout);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Reads the samples of a topic as they are (CDR bytes, checked by whoever decodes them): each is handed to `handle`
// on Fast DDS's listener thread once started (before, it is dropped). QoS as the other topics' (reliable, volatile,
// keep last 10). For the topics built on this transport (replica.hpp: environment-model updates and events).
class RawReader {
 public:
  // `alive`, if given, is told (on Fast DDS's thread) how many matched writers are alive whenever that changes (their
  // liveliness, DdsOptions::lease).
  RawReader(Participant& participant, const std::string& topic, const char* type,
            std::function<void(const std::vector<char>&)> handle, std::function<void(int alive)> alive = {});
  ~RawReader();
  RawReader(const RawReader&) = delete;
  RawReader& operator=(const RawReader&) = delete;

  bool wait_for_writer(std::chrono::milliseconds timeout) const;
  // How many writers match now.
  int writers() const;
  void start();
  void stop();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Registers a type of CDR-byte samples (largest sample `max_size`, header included) with the participant, once: a
// RawWriter or RawReader of a type other than the command, status and agent state needs it first.
void register_type(Participant& participant, const char* name, std::size_t max_size);

}  // namespace cellwright::distributed
