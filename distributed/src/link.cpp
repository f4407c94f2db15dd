#include "cellwright/distributed/link.hpp"

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <atomic>
#include <condition_variable>
#include <algorithm>
#include <cstring>
#include <deque>
#include <set>
#include <functional>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>
#include <type_traits>
#include <random>

#include <fmt/format.h>

#include "cellwright/common/error.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/distributed/wire.hpp"
#include "dds_entities.hpp"

namespace cellwright::distributed {
namespace {

bool valid_token(const std::string& name) {
  if (name.empty() || (name[0] >= '0' && name[0] <= '9')) return false;
  for (char c : name) {
    bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    if (!ok) return false;
  }
  return true;
}

std::string topic(const std::string& robot, const char* leaf) {
  if (!valid_token(robot)) {
    throw InputError(SourceLocation{"robot " + robot},
                     fmt::format("the name '{}' cannot name a ROS 2 topic (letters, digits and underscores, not "
                                 "starting with a digit)",
                                 robot));
  }
  return fmt::format("rt/cellwright/{}/{}", robot, leaf);
}

class ReaderListener : public dds::DataReaderListener {
 public:
  // `handle` gets each sample and the participant of its writer.
  ReaderListener(Matches& matches, std::function<void(const std::vector<char>&, const std::string&)> handle)
      : matches_(matches), handle_(std::move(handle)) {}
  // Called (on Fast DDS's thread) as the liveliness of the matched writers changes; set before the reader is made.
  void on_liveliness(std::function<void(const dds::LivelinessChangedStatus&)> changed) {
    liveliness_ = std::move(changed);
  }
  void on_subscription_matched(dds::DataReader*, const dds::SubscriptionMatchedStatus& info) override {
    matches_.set(info.current_count, info.current_count_change, info.last_publication_handle);
  }
  void on_liveliness_changed(dds::DataReader*, const dds::LivelinessChangedStatus& status) override {
    if (liveliness_) liveliness_(status);
  }
  void on_data_available(dds::DataReader* reader) override {
    take_all(reader, [this](const std::vector<char>& bytes, const dds::SampleInfo& info) {
      handle_(bytes, participant_of(info.publication_handle));
    });
  }

 private:
  Matches& matches_;
  std::function<void(const std::vector<char>&, const std::string&)> handle_;
  std::function<void(const dds::LivelinessChangedStatus&)> liveliness_;
};

}  // namespace

Participant::Participant(DdsOptions options, const std::string& name) : options_(options), impl_(new Impl) {
  if (options.domain < 0 || options.domain > 232) {
    throw InputError(SourceLocation{fmt::format("DDS domain {}", options.domain)}, "outside 0..232");
  }
  if (options.lease < std::chrono::milliseconds(20)) {
    throw InputError(SourceLocation{fmt::format("DDS liveliness lease {} ms", options.lease.count())},
                     "shorter than 20 ms (a lease a busy host cannot keep: agents would be lost that are not)");
  }
  impl_->lease = options.lease;
  dds::DomainParticipantQos qos = dds::PARTICIPANT_QOS_DEFAULT;
  qos.name(name);
  // The participant's lease (discovery's: a participant not heard of for it is dropped, its endpoints unmatched) is
  // the links' lease, announced 4 times a lease: how a lost peer is found (PeerWatch, dds_entities.hpp, says why not
  // by the endpoints' liveliness alone). Fast DDS's default is 20 s, announced every 3 s.
  const auto seconds = [](std::chrono::milliseconds ms, long double part) {
    return eprosima::fastrtps::Duration_t(static_cast<long double>(ms.count()) / 1000.0L / part);
  };
  qos.wire_protocol().builtin.discovery_config.leaseDuration = seconds(options.lease, 1);
  qos.wire_protocol().builtin.discovery_config.leaseDuration_announcementperiod = seconds(options.lease, 4);
  if (!options.shared_memory) {
    qos.transport().use_builtin_transports = false;
    qos.transport().user_transports.push_back(std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>());
  }
  impl_->participant = dds::DomainParticipantFactory::get_instance()->create_participant(
      static_cast<dds::DomainId_t>(options.domain), qos, &impl_->peers, dds::StatusMask::none());
  CW_CHECK(impl_->participant != nullptr, "Fast DDS cannot create a participant on domain {}", options.domain);
  impl_->publisher = impl_->participant->create_publisher(dds::PUBLISHER_QOS_DEFAULT);
  impl_->subscriber = impl_->participant->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
  CW_CHECK(impl_->publisher != nullptr && impl_->subscriber != nullptr, "cannot create a DDS publisher/subscriber");
  impl_->ensure_type(kCommandTypeName, max_command_size());
  impl_->ensure_type(kStatusTypeName, max_status_size());
  impl_->ensure_type(kAgentStateTypeName, max_agent_state_size());
}

Participant::~Participant() {
  impl_->participant->delete_contained_entities();
  dds::DomainParticipantFactory::get_instance()->delete_participant(impl_->participant);
}

std::string command_topic(const std::string& robot) {
  return topic(robot, "command");
}
std::string status_topic(const std::string& robot) {
  return topic(robot, "status");
}
std::string agent_topic(const std::string& robot) {
  return topic(robot, "agent");
}

namespace {

// One direction of a link's traffic: a writer fed from a queue by a thread of its own, or a reader that decodes and
// pushes into a queue. Both directions of a link share the refusal count.
struct RefusalBook {
  mutable std::mutex mutex;
  Refusals refusals;
  void refuse(const std::string& where, const std::string& why) {
    std::lock_guard lock(mutex);
    ++refusals.count;
    refusals.last = why;
    std::cerr << fmt::format("refused a sample on {}: {}\n", where, why);
  }
  Refusals get() const {
    std::lock_guard lock(mutex);
    return refusals;
  }
};

// A DDS writer of CDR bytes and its matches: RawWriter's, and a Forwarder's.
class PlainWriter {
 public:
  PlainWriter(Participant::Impl& p, const std::string& topic_name, const char* type, Qos qos = Qos::kDefault,
              std::function<void()> on_match = {})
      : p_(p), listener_(matches_) {
    matches_.on_change(std::move(on_match));
    dds::DataWriterQos writer_qos = with(dds::DATAWRITER_QOS_DEFAULT, qos, p.lease);
    // Fast DDS sends a heartbeat every 3 s by default, and a reader acknowledges (or asks again for a lost sample)
    // only when it gets one: a lost sample was resent that late, and an agent's last status was acknowledged that
    // late (the agent waits for it before it exits). 100 ms.
    writer_qos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0.1L);
    std::lock_guard lock(p_.mutex);
    writer_ = p_.publisher->create_datawriter(p_.topic(topic_name, type), writer_qos, &listener_);
    CW_CHECK(writer_ != nullptr, "cannot create a DDS writer on {}", topic_name);
  }
  ~PlainWriter() {
    std::lock_guard lock(p_.mutex);
    p_.publisher->delete_datawriter(writer_);
  }
  bool write(const std::vector<char>& bytes) {
    std::vector<char> copy(bytes);
    return writer_->write(&copy);
  }
  bool flush(std::chrono::milliseconds timeout) {
    eprosima::fastrtps::Duration_t wait(static_cast<double>(timeout.count()) / 1000.0);
    return writer_->wait_for_acknowledgments(wait) == ReturnCode_t::RETCODE_OK;
  }
  const Matches& matches() const { return matches_; }

 private:
  Participant::Impl& p_;
  Matches matches_;
  WriterListener listener_;
  dds::DataWriter* writer_ = nullptr;
};

template <typename T>
class Forwarder {
 public:
  Forwarder(Participant::Impl& p, const std::string& topic_name, const char* type, runtime::MessageQueue<T>& queue,
            std::function<std::vector<char>(const T&)> encode, std::function<void()> on_match = {})
      : queue_(queue),
        encode_(std::move(encode)),
        writer_(p, topic_name, type, Qos::kDefault, std::move(on_match)),
        topic_(topic_name) {}
  ~Forwarder() { stop(); }
  void start() {
    if (thread_.joinable()) return;
    stopping_ = false;
    thread_ = std::thread([this] { run(); });
  }
  void stop() {
    stopping_ = true;
    if (thread_.joinable()) thread_.join();
  }
  // Waits until the queue is empty, what was taken from it written, and every sample acknowledged by its readers.
  bool flush(std::chrono::milliseconds timeout) {
    auto deadline = std::chrono::steady_clock::now() + timeout;
    {
      std::unique_lock lock(mutex_);
      if (!written_.wait_until(lock, deadline, [&] { return !in_hand_ && queue_.size() == 0; })) return false;
    }
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    return writer_.flush(std::max(left, std::chrono::milliseconds(0)));
  }
  const Matches& matches() const { return writer_.matches(); }
  // Writes a sample now, from any thread (a command sent again), besides what the forwarding thread writes.
  bool write_now(const std::vector<char>& bytes) { return writer_.write(bytes); }

 private:
  void run() {
    while (!stopping_) {
      T item;
      {
        std::lock_guard lock(mutex_);
        in_hand_ = true;
      }
      runtime::QueueStatus got = queue_.pop_for(item, std::chrono::milliseconds(20));
      if (got == runtime::QueueStatus::ok && !writer_.write(encode_(item))) {
        std::cerr << fmt::format("DDS did not take a sample for {}\n", topic_);
      }
      {
        std::lock_guard lock(mutex_);
        in_hand_ = false;
      }
      written_.notify_all();
      if (got == runtime::QueueStatus::closed) return;
    }
  }

  runtime::MessageQueue<T>& queue_;
  std::function<std::vector<char>(const T&)> encode_;
  PlainWriter writer_;
  std::string topic_;
  std::mutex mutex_;
  std::condition_variable written_;
  bool in_hand_ = false;  // an item may be between the queue and the writer
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

// A DDS reader of CDR bytes: each sample is handed to `handle` on Fast DDS's listener thread once start()ed
// (before, it is dropped: nobody reads yet).
class Receiver {
 public:
  // `handle` gets each sample and the participant of its writer (the 12 bytes of participant_of()).
  Receiver(Participant::Impl& p, const std::string& topic_name, const char* type,
           std::function<void(const std::vector<char>&, const std::string&)> handle, Qos qos = Qos::kDefault,
           std::function<void()> on_match = {},
           std::function<void(const dds::LivelinessChangedStatus&)> on_liveliness = {})
      : p_(p),
        listener_(matches_,
                  [this, handle = std::move(handle)](const std::vector<char>& b, const std::string& from) {
                    if (started_) handle(b, from);
                  }) {
    matches_.on_change(std::move(on_match));
    listener_.on_liveliness(std::move(on_liveliness));
    std::lock_guard lock(p_.mutex);
    dds::Topic* topic = p_.topic(topic_name, type);
    reader_ = p_.subscriber->create_datareader(topic, with(dds::DATAREADER_QOS_DEFAULT, qos, p_.lease), &listener_);
    CW_CHECK(reader_ != nullptr, "cannot create a DDS reader on {}", topic_name);
  }
  ~Receiver() {
    std::lock_guard lock(p_.mutex);
    reader_->set_listener(nullptr);
    p_.subscriber->delete_datareader(reader_);
  }
  void start() { started_ = true; }
  void stop() { started_ = false; }
  const Matches& matches() const { return matches_; }

 private:
  Participant::Impl& p_;
  std::atomic<bool> started_{false};
  Matches matches_;
  ReaderListener listener_;
  dds::DataReader* reader_ = nullptr;
};

// A failed status that stops the cell, about no command (RobotStatus::kNoCommand: task control takes it whatever it
// holds in flight).
runtime::RobotStatus stop_status(std::size_t robot, std::string reason, runtime::SimDuration time) {
  runtime::RobotStatus s;
  s.robot = robot;
  s.outcome = runtime::CommandOutcome::kFailed;
  s.stop_cell = true;
  s.reason = std::move(reason);
  s.time = time;
  return s;
}

bool both_within(const Matches& a, const Matches& b, std::chrono::steady_clock::time_point deadline) {
  return a.wait_until(deadline) && b.wait_until(deadline);
}

}  // namespace

constexpr const char* kEndpointsLeft = "its endpoints left";

struct RemoteRobot::Impl {
  std::string robot;
  std::size_t index;
  std::chrono::milliseconds lease;
  runtime::MessageQueue<runtime::RobotStatus>& status_queue;
  RefusalBook book;

  // What is known of the agent (under `mutex`; changed from Fast DDS's threads and the forwarding thread).
  mutable std::mutex mutex;
  std::uint64_t session = 0;     // the agent's, from its last state
  std::string agent;             // its participant (participant_of), from its last state
  std::condition_variable changed;  // after every update()
  bool said_ready = false;       // its last state
  bool lapsed = false;           // its liveliness lapsed (no writer of its alive)
  bool was_present = false;
  bool built = false;            // every member is made: the match hooks may look at the endpoints
  std::uint64_t losses = 0;
  std::string lost_detail;
  std::uint64_t sent = 0;        // commands sent to this session (the last one's number)
  SequenceCheck status_order;    // this session's statuses
  std::deque<runtime::MotionCommand> in_flight;  // sent and not answered, oldest first
  std::string holding;           // by the grip commands answered done

  Forwarder<runtime::MotionCommand> commands;
  Receiver statuses;
  Receiver state;
  Participant::Impl& participant;
  std::string lost_agent;  // the participant of the agent lost last, and when (under `mutex`)
  std::chrono::steady_clock::time_point lost_at;

  Impl(Participant& p, std::string name, std::size_t robot_index, runtime::MessageQueue<runtime::MotionCommand>& cq,
       runtime::MessageQueue<runtime::RobotStatus>& sq)
      : robot(std::move(name)),
        index(robot_index),
        lease(p.impl().lease),
        status_queue(sq),
        commands(
            p.impl(), command_topic(robot), kCommandTypeName, cq,
            [this](const runtime::MotionCommand& c) { return on_send(c); }, [this] { update(kEndpointsLeft); }),
        statuses(
            p.impl(), status_topic(robot), kStatusTypeName,
            [this](const std::vector<char>& b, const std::string&) { on_status(b); },
            Qos::kDefault, [this] { update(kEndpointsLeft); },
            [this](const dds::LivelinessChangedStatus& l) { on_liveliness(l); }),
        state(
            p.impl(), agent_topic(robot), kAgentStateTypeName,
            [this](const std::vector<char>& b, const std::string& from) { on_state(b, from); },
            Qos::kLatched, [this] {
              if (state.matches().count() == 0) {
                std::lock_guard lock(mutex);
                said_ready = false;  // the agent is gone
                update_locked(kEndpointsLeft);
              }
            }),
        participant(p.impl()) {
    {
      std::lock_guard lock(mutex);
      built = true;
    }
    state.start();
  }
  ~Impl() {
    std::lock_guard lock(mutex);
    built = false;
  }

  // This side's endpoints match the agent's (the participant of its last state): a match seen from the agent's side
  // only is not enough (what is written before this side's match is not delivered), and an old agent's match that
  // has not yet expired is not the new one's.
  bool matched() const { return commands.matches().has(agent) && statuses.matches().has(agent); }
  bool present_locked() const { return built && said_ready && !lapsed && matched(); }
  bool present() const {
    std::lock_guard lock(mutex);
    return present_locked();
  }

  // After any change: a present agent that no longer is, is a loss (`why` says how it was noticed).
  void update(const std::string& why) {
    std::lock_guard lock(mutex);
    update_locked(why);
  }
  void update_locked(const std::string& why) {
    if (!built) return;
    const bool now = present_locked();
    if (was_present && !now) {
      ++losses;
      lost_detail = why;
      lost_agent = agent;
      lost_at = std::chrono::steady_clock::now();
    }
    was_present = now;
    changed.notify_all();
  }

  bool wait_present(std::chrono::steady_clock::time_point deadline) {
    std::unique_lock lock(mutex);
    return changed.wait_until(lock, deadline, [&] { return present_locked(); });
  }

  std::vector<char> on_send(const runtime::MotionCommand& c) {
    std::lock_guard lock(mutex);
    in_flight.push_back(c);
    return encode_command(c, ++sent);
  }

  void on_state(const std::vector<char>& bytes, const std::string& from) {
    AgentState got;
    try {
      got = decode_agent_state(bytes, index);
    } catch (const WireError& e) {
      book.refuse(agent_topic(robot), e.what());
      return;
    }
    {
      std::lock_guard lock(mutex);
      if (got.session != session) {
        // A new agent process for this robot: one still thought present is lost (replaced); the new one takes
        // commands, and numbers its statuses, from 1.
        if (was_present) {
          ++losses;
          lost_detail = fmt::format("a new agent process (session {}) took the place of session {}", got.session,
                                    session);
          was_present = false;
        }
        session = got.session;
        agent = from;
        sent = 0;
        status_order.restart();
        lapsed = false;
      }
      said_ready = got.ready;
      update_locked("it said it stopped");
    }
  }

  // Only the present agent's status writer counts: an old agent's lapse after a new one took its place is not the
  // new one's. A lapse is for good: only a new session (a new agent process) is present again. Taking "alive again"
  // as the lost agent back was wrong: under load, a new agent's writer matching before its state arrived was reported
  // as alive again with the lost agent's handle, and the lost one was taken back (the rejoin test, 3 runs in 6 with
  // two busy loops on the machine).
  void on_liveliness(const dds::LivelinessChangedStatus& l) {
    std::lock_guard lock(mutex);
    if (l.not_alive_count_change <= 0 || participant_of(l.last_publication_handle) != agent) return;
    lapsed = true;
    update_locked(lapse());
  }
  std::string lapse() const {
    return fmt::format("no sign of life from it for its liveliness lease of {:.3g} s (the process killed, its host "
                       "down or the network cut)",
                       static_cast<double>(lease.count()) / 1000.0);
  }

  void on_status(const std::vector<char>& bytes) {
    const std::string where = status_topic(robot);
    runtime::RobotStatus status;
    StatusStamp stamp;
    try {
      status = decode_status(bytes, index, &stamp);
    } catch (const WireError& e) {
      return book.refuse(where, e.what());
    }
    std::string gap;
    {
      std::lock_guard lock(mutex);
      if (stamp.session != session) {
        return book.refuse(where, fmt::format("a status of agent session {}; the agent now is session {}",
                                              stamp.session, session));
      }
      try {
        status_order.accept(stamp.sequence, "status");
      } catch (const WireError& e) {
        if (stamp.sequence <= status_order.last()) return book.refuse(where, e.what());
        gap = e.what();
      }
      if (gap.empty() && status.index != runtime::RobotStatus::kNoCommand) {
        const auto answered = std::find_if(in_flight.begin(), in_flight.end(),
                                           [&](const runtime::MotionCommand& c) { return c.index == status.index; });
        if (answered == in_flight.end()) {
          return book.refuse(where, fmt::format("a status of primitive {}, which is not a command in flight",
                                                status.index));
        }
        if (status.outcome == runtime::CommandOutcome::kDone) {
          const task::Primitive& p = answered->primitive;
          if (p.kind == task::PrimitiveKind::kClose && !p.workpiece.empty()) holding = p.workpiece;
          if (p.kind == task::PrimitiveKind::kOpen) holding.clear();
        }
        in_flight.erase(answered);
      }
    }
    if (!gap.empty()) {
      // A status lost on the way: the command it answered never will be. Refused, and the cell stopped with the
      // reason rather than left waiting.
      book.refuse(where, gap);
      status_queue.push(
          stop_status(index, fmt::format("the link to the agent of {} lost a status: {}", robot, gap), status.time));
      return;
    }
    status_queue.push(std::move(status));
  }

  runtime::LinkState link_state() const {
    std::lock_guard lock(mutex);
    runtime::LinkState s;
    s.present = present_locked();
    s.session = session;
    s.losses = losses;
    s.lost_detail = lost_detail;
    // Endpoints that left because discovery dropped the agent's participant (its lease expired) are a lapse, not a
    // goodbye. Fast DDS reports the participant just after its endpoints: until it has (at most 100 ms), the loss is
    // not shown yet, so that it is shown once, with its cause.
    if (lost_detail == kEndpointsLeft && !lost_agent.empty()) {
      const std::optional<bool> dropped = participant.peers.wait_gone(lost_agent, std::chrono::steady_clock::now());
      if (dropped.value_or(false)) {
        s.lost_detail = lapse();
      } else if (!dropped && std::chrono::steady_clock::now() - lost_at < std::chrono::milliseconds(100)) {
        s.losses = losses - 1;
        s.lost_detail.clear();
      }
    }
    s.in_flight = in_flight.empty() ? -1 : static_cast<int>(in_flight.front().index);
    s.holding = holding;
    for (const runtime::MotionCommand& c : in_flight) {
      if (c.primitive.kind == task::PrimitiveKind::kClose && !c.primitive.workpiece.empty()) {
        s.holding = c.primitive.workpiece;  // it may have gripped it before it was lost
      }
    }
    return s;
  }

  bool resend() {
    std::vector<std::vector<char>> samples;
    {
      std::lock_guard lock(mutex);
      if (in_flight.empty() || !present_locked()) return false;
      for (const runtime::MotionCommand& c : in_flight) samples.push_back(encode_command(c, ++sent));
    }
    bool ok = true;
    for (const auto& bytes : samples) ok = commands.write_now(bytes) && ok;
    return ok;
  }
};

RemoteRobot::RemoteRobot(Participant& participant, std::string robot, std::size_t index,
                         runtime::MessageQueue<runtime::MotionCommand>& commands,
                         runtime::MessageQueue<runtime::RobotStatus>& statuses)
    : impl_(new Impl(participant, std::move(robot), index, commands, statuses)) {}

RemoteRobot::~RemoteRobot() {
  stop();
}

bool RemoteRobot::agent_present() const {
  return impl_->present();
}

runtime::LinkState RemoteRobot::state() const {
  return impl_->link_state();
}

bool RemoteRobot::resend() {
  return impl_->resend();
}

bool RemoteRobot::wait_for_agent(std::chrono::milliseconds timeout) const {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  return impl_->wait_present(deadline);
}

void RemoteRobot::start() {
  impl_->statuses.start();
  impl_->commands.start();
}

void RemoteRobot::stop() {
  impl_->commands.stop();
  impl_->statuses.stop();
}

const std::string& RemoteRobot::robot() const {
  return impl_->robot;
}
Refusals RemoteRobot::refusals() const {
  return impl_->book.get();
}

void wait_for_agents(const std::vector<RemoteRobot*>& robots, int domain, std::chrono::milliseconds timeout) {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  std::vector<std::string> missing;
  for (RemoteRobot* r : robots) {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (!r->wait_for_agent(std::max(left, std::chrono::milliseconds(0)))) missing.push_back(r->robot());
  }
  if (missing.empty()) return;
  throw InputError(SourceLocation{fmt::format("DDS domain {}", domain)},
                   fmt::format("no agent for robot{} {} on DDS domain {} within {:.1f} s (a real-time run: start "
                               "one per robot on its real driver: twin agent SCENARIO --robot {} --driver KIND:PORT "
                               "--domain {}; an agent without --driver takes lock-step turns on the twin's robot, "
                               "for a run without --realtime or --speed)",
                               missing.size() > 1 ? "s" : "", fmt::join(missing, ", "), domain,
                               static_cast<double>(timeout.count()) / 1000.0, missing.front(), domain));
}

namespace {

// A RemoteRobot as the Runtime's RemoteLink, with the robot's model updates and events (replica.hpp) carried into
// the run's model and log.
class DdsLink : public runtime::RemoteLink {
 public:
  DdsLink(Participant& p, const std::string& cell, std::size_t i,
          runtime::MessageQueue<runtime::MotionCommand>& commands, runtime::MessageQueue<runtime::RobotStatus>& statuses)
      : robot(p, cell, i, commands, statuses), participant(p), name(cell), index(i) {}
  void start() override {
    if (replica) replica->start();
    robot.start();
  }
  void stop() override {
    robot.stop();
    if (replica) replica->stop();
  }
  runtime::LinkState state() const override { return robot.state(); }
  bool resend() override { return robot.resend(); }
  void share(runtime::SharedEnvironment& environment, runtime::EventLog& log) override {
    replica = share_into(participant, name, index, environment, log);
  }
  RemoteRobot robot;
  Participant& participant;
  std::string name;
  std::size_t index;
  std::unique_ptr<RobotSubscriber> replica;
};

}  // namespace

runtime::AttachRemote RemoteCell::attach() {
  return [this](std::size_t index, const std::string& cell, runtime::MessageQueue<runtime::MotionCommand>& commands,
                runtime::MessageQueue<runtime::RobotStatus>& statuses) -> std::unique_ptr<runtime::RemoteLink> {
    auto link = std::make_unique<DdsLink>(participant_, cell, index, commands, statuses);
    robots_.push_back(&link->robot);
    return link;
  };
}

void RemoteCell::wait_for_agents(std::chrono::milliseconds timeout) const {
  distributed::wait_for_agents(robots_, participant_.domain(), timeout);
}

// A number for an agent process, drawn as it starts: never 0, and another process's with a chance of 2^-64.
std::uint64_t draw_session() {
  std::random_device device;
  std::uint64_t n = 0;
  while (n == 0) {
    n = (static_cast<std::uint64_t>(device()) << 32) ^ device() ^
        static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  }
  return n;
}

struct AgentEndpoint::Impl {
  std::size_t index;
  std::uint64_t session = draw_session();
  RefusalBook book;
  std::mutex order_mutex;
  SequenceCheck command_order;  // the commands task control sent this session
  std::uint64_t statuses_sent = 0;  // the forwarding thread's
  // Declared (so built) before the endpoints whose matches call announce(), and destroyed after them.
  std::mutex state_mutex;  // one state written at a time, in the order of the changes
  std::optional<bool> said;
  bool built = false;  // announce() may look at the endpoints (under state_mutex)
  // start() was called: the command reader hands samples on. Ready is said only then: a command taken before would
  // be dropped by the reader, and its status would never come.
  bool started = false;
  Participant::Impl& participant;
  std::string task_control;  // its participant (participant_of), the last one matched on both endpoints; state_mutex
  PlainWriter state;
  Receiver commands;
  Forwarder<runtime::RobotStatus> statuses;

  Impl(Participant& p, const std::string& robot, std::size_t robot_index, const task::CompiledProgram& program,
       runtime::MessageQueue<runtime::MotionCommand>& cq, runtime::MessageQueue<runtime::RobotStatus>& sq)
      : index(robot_index),
        participant(p.impl()),
        state(p.impl(), agent_topic(robot), kAgentStateTypeName, Qos::kLatched),
        commands(
            p.impl(), command_topic(robot), kCommandTypeName,
            [this, &program, &cq, &sq, robot_index, where = command_topic(robot)](const std::vector<char>& b,
                                                                                  const std::string&) {
              on_command(b, program, robot_index, cq, sq, where);
            },
            Qos::kDefault, [this] { announce(); }),
        statuses(
            p.impl(), status_topic(robot), kStatusTypeName, sq,
            [this](const runtime::RobotStatus& s) { return encode_status(s, {session, ++statuses_sent}); },
            [this] { announce(); }) {
    {
      std::lock_guard lock(state_mutex);
      built = true;
    }
    announce();
  }
  ~Impl() {
    std::lock_guard lock(state_mutex);
    built = false;
  }

  bool present() const { return commands.matches().count() > 0 && statuses.matches().count() > 0; }


  // A command from task control: decoded, in its order, into the command queue; else refused. A gap (a command lost
  // on the way) is also reported to task control as a failed status that stops the cell: the lost command would
  // otherwise be waited for.
  void on_command(const std::vector<char>& bytes, const task::CompiledProgram& program, std::size_t robot_index,
                  runtime::MessageQueue<runtime::MotionCommand>& cq, runtime::MessageQueue<runtime::RobotStatus>& sq,
                  const std::string& where) {
    runtime::MotionCommand command;
    std::uint64_t number = 0;
    try {
      command = decode_command(bytes, program, robot_index, &number);
    } catch (const WireError& e) {
      return book.refuse(where, e.what());
    }
    std::string gap;
    {
      std::lock_guard lock(order_mutex);
      try {
        command_order.accept(number, "command");
      } catch (const WireError& e) {
        if (number <= command_order.last()) return book.refuse(where, e.what());
        gap = e.what();
      }
    }
    if (!gap.empty()) {
      book.refuse(where, gap);
      sq.push(stop_status(robot_index,
                          fmt::format("the agent of {} lost a command: {}", program.robots[robot_index], gap),
                          command.sent));
      return;
    }
    cq.push(std::move(command));
  }

  void set_started(bool value) {
    {
      std::lock_guard lock(state_mutex);
      started = value;
    }
    announce();
  }

  // Writes the agent's state when it changed (called from Fast DDS's listener threads as matches change).
  void announce() {
    std::lock_guard lock(state_mutex);
    if (!built) return;
    for (const std::string& p : commands.matches().participants()) {
      if (statuses.matches().has(p)) task_control = p;
    }
    bool now = started && present();
    if (said == now) return;
    said = now;
    state.write(encode_agent_state(index, {now, session}));
  }
};

AgentEndpoint::AgentEndpoint(Participant& participant, std::string robot, std::size_t index,
                             const task::CompiledProgram& program,
                             runtime::MessageQueue<runtime::MotionCommand>& commands,
                             runtime::MessageQueue<runtime::RobotStatus>& statuses) {
  CW_CHECK(index < program.programs.size(), "agent robot index outside the program");
  impl_.reset(new Impl(participant, robot, index, program, commands, statuses));
}

AgentEndpoint::~AgentEndpoint() {
  stop();
}

bool AgentEndpoint::task_control_present() const {
  return impl_->present();
}

std::string AgentEndpoint::task_control_lost(std::chrono::milliseconds wait) const {
  std::string task_control;
  {
    std::lock_guard lock(impl_->state_mutex);
    task_control = impl_->task_control;
  }
  if (task_control.empty()) return {};
  const std::optional<bool> dropped =
      impl_->participant.peers.wait_gone(task_control, std::chrono::steady_clock::now() + wait);
  if (!dropped.value_or(false)) return {};
  return fmt::format("no sign of life from task control for the lease of {:.3g} s (its process killed, its host "
                     "down or the network cut)",
                     static_cast<double>(impl_->participant.lease.count()) / 1000.0);
}

bool AgentEndpoint::wait_for_task_control(std::chrono::milliseconds timeout) const {
  return both_within(impl_->commands.matches(), impl_->statuses.matches(), std::chrono::steady_clock::now() + timeout);
}

void AgentEndpoint::start() {
  impl_->commands.start();
  impl_->statuses.start();
  impl_->set_started(true);
}

void AgentEndpoint::stop() {
  impl_->set_started(false);
  impl_->statuses.stop();
  impl_->commands.stop();
}

bool AgentEndpoint::flush(std::chrono::milliseconds timeout) {
  return impl_->statuses.flush(timeout);
}

Refusals AgentEndpoint::refusals() const {
  return impl_->book.get();
}

struct RawWriter::Impl {
  Impl(Participant& p, const std::string& topic, const char* type) : writer(p.impl(), topic, type) {}
  PlainWriter writer;
};

RawWriter::RawWriter(Participant& participant, const std::string& topic, const char* type)
    : impl_(new Impl(participant, topic, type)) {}
RawWriter::~RawWriter() = default;
bool RawWriter::wait_for_reader(std::chrono::milliseconds timeout) const {
  return impl_->writer.matches().wait_until(std::chrono::steady_clock::now() + timeout);
}
bool RawWriter::write(const std::vector<char>& bytes) {
  return impl_->writer.write(bytes);
}
bool RawWriter::flush(std::chrono::milliseconds timeout) {
  return impl_->writer.flush(timeout);
}

struct RawReader::Impl {
  Impl(Participant& p, const std::string& topic, const char* type, std::function<void(const std::vector<char>&)> h,
       std::function<void(int)> alive)
      : reader(
            p.impl(), topic, type, [h = std::move(h)](const std::vector<char>& b, const std::string&) { h(b); },
            Qos::kDefault, {},
            alive ? std::function<void(const dds::LivelinessChangedStatus&)>(
                        [alive = std::move(alive)](const dds::LivelinessChangedStatus& l) { alive(l.alive_count); })
                  : std::function<void(const dds::LivelinessChangedStatus&)>()) {}
  Receiver reader;
};

RawReader::RawReader(Participant& participant, const std::string& topic, const char* type,
                     std::function<void(const std::vector<char>&)> handle, std::function<void(int)> alive)
    : impl_(new Impl(participant, topic, type, std::move(handle), std::move(alive))) {}
RawReader::~RawReader() = default;
int RawReader::writers() const {
  return impl_->reader.matches().count();
}
bool RawReader::wait_for_writer(std::chrono::milliseconds timeout) const {
  return impl_->reader.matches().wait_until(std::chrono::steady_clock::now() + timeout);
}
void RawReader::start() {
  impl_->reader.start();
}
void RawReader::stop() {
  impl_->reader.stop();
}

void register_type(Participant& participant, const char* name, std::size_t max_size) {
  std::lock_guard lock(participant.impl().mutex);
  participant.impl().ensure_type(name, max_size);
}

}  // namespace cellwright::distributed
