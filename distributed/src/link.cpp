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
#include <cstring>
#include <functional>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "cellwright/common/error.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/distributed/wire.hpp"

namespace cellwright::distributed {
namespace dds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;

namespace {

// A DDS type whose samples are the CDR bytes wire.hpp encodes, encapsulation header included: Fast DDS moves them as
// they are, and decoding (with its checks) is wire.hpp's, where a refusal can say what was wrong.
class CdrBytesType : public dds::TopicDataType {
 public:
  CdrBytesType(const char* name, std::size_t max_size) {
    setName(name);
    m_typeSize = static_cast<std::uint32_t>(max_size);
    m_isGetKeyDefined = false;
  }

  bool serialize(void* data, rtps::SerializedPayload_t* payload) override {
    const auto& bytes = *static_cast<std::vector<char>*>(data);
    if (bytes.size() < 4 || bytes.size() > payload->max_size) return false;
    std::memcpy(payload->data, bytes.data(), bytes.size());
    payload->length = static_cast<std::uint32_t>(bytes.size());
    payload->encapsulation = bytes[1] == 0 ? CDR_BE : CDR_LE;
    return true;
  }

  bool deserialize(rtps::SerializedPayload_t* payload, void* data) override {
    auto& bytes = *static_cast<std::vector<char>*>(data);
    const char* begin = reinterpret_cast<const char*>(payload->data);
    bytes.assign(begin, begin + payload->length);
    return true;
  }

  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<std::vector<char>*>(data)->size()); };
  }

  void* createData() override { return new std::vector<char>(); }
  void deleteData(void* data) override { delete static_cast<std::vector<char>*>(data); }
  bool getKey(void*, rtps::InstanceHandle_t*, bool) override { return false; }
};

// ROS 2's default QoS for topics: reliable, volatile, keep last 10; latched (the agent's state, as tf_static):
// reliable, transient local, keep last 1.
enum class Qos { kDefault, kLatched };

template <typename Q>
Q with(Q qos, Qos kind) {
  qos.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = kind == Qos::kLatched ? dds::TRANSIENT_LOCAL_DURABILITY_QOS : dds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = kind == Qos::kLatched ? 1 : 10;
  return qos;
}

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

// How many endpoints match one of ours, and a wait for it to change.
class Matches {
 public:
  // `changed` is called (on Fast DDS's thread) after every change; set it before the endpoint is created.
  void on_change(std::function<void()> changed) { changed_hook_ = std::move(changed); }
  void set(int count) {
    {
      std::lock_guard lock(mutex_);
      count_ = count;
    }
    changed_.notify_all();
    if (changed_hook_) changed_hook_();
  }
  int count() const {
    std::lock_guard lock(mutex_);
    return count_;
  }
  bool wait_until(std::chrono::steady_clock::time_point deadline) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_until(lock, deadline, [&] { return count_ > 0; });
  }

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  int count_ = 0;
  std::function<void()> changed_hook_;
};

class WriterListener : public dds::DataWriterListener {
 public:
  explicit WriterListener(Matches& matches) : matches_(matches) {}
  void on_publication_matched(dds::DataWriter*, const dds::PublicationMatchedStatus& info) override {
    matches_.set(info.current_count);
  }

 private:
  Matches& matches_;
};

class ReaderListener : public dds::DataReaderListener {
 public:
  ReaderListener(Matches& matches, std::function<void(const std::vector<char>&)> handle)
      : matches_(matches), handle_(std::move(handle)) {}
  void on_subscription_matched(dds::DataReader*, const dds::SubscriptionMatchedStatus& info) override {
    matches_.set(info.current_count);
  }
  void on_data_available(dds::DataReader* reader) override {
    std::vector<char> bytes;
    dds::SampleInfo info;
    while (reader->take_next_sample(&bytes, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) handle_(bytes);
    }
  }

 private:
  Matches& matches_;
  std::function<void(const std::vector<char>&)> handle_;
};

}  // namespace

struct Participant::Impl {
  dds::DomainParticipant* participant = nullptr;
  dds::Publisher* publisher = nullptr;
  dds::Subscriber* subscriber = nullptr;
  std::mutex mutex;  // entity creation and deletion

  void ensure_type(const char* name, std::size_t max_size) {
    if (participant->find_type(name).empty()) {
      dds::TypeSupport type(new CdrBytesType(name, max_size));
      CW_CHECK(type.register_type(participant) == ReturnCode_t::RETCODE_OK, "cannot register a DDS type");
    }
  }

  // The topic `name` of type `type`: created, or the one this participant already has.
  dds::Topic* topic(const std::string& name, const char* type) {
    if (auto* found = participant->lookup_topicdescription(name)) {
      auto* existing = dynamic_cast<dds::Topic*>(found);
      CW_CHECK(existing != nullptr, "a DDS topic description that is no topic");
      return existing;
    }
    dds::Topic* made = participant->create_topic(name, type, dds::TOPIC_QOS_DEFAULT);
    CW_CHECK(made != nullptr, "cannot create the DDS topic {}", name);
    return made;
  }
};

Participant::Participant(DdsOptions options, const std::string& name) : options_(options), impl_(new Impl) {
  if (options.domain < 0 || options.domain > 232) {
    throw InputError(SourceLocation{fmt::format("DDS domain {}", options.domain)}, "outside 0..232");
  }
  dds::DomainParticipantQos qos = dds::PARTICIPANT_QOS_DEFAULT;
  qos.name(name);
  if (!options.shared_memory) {
    qos.transport().use_builtin_transports = false;
    qos.transport().user_transports.push_back(std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>());
  }
  impl_->participant = dds::DomainParticipantFactory::get_instance()->create_participant(
      static_cast<dds::DomainId_t>(options.domain), qos);
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
    dds::DataWriterQos writer_qos = with(dds::DATAWRITER_QOS_DEFAULT, qos);
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
  Receiver(Participant::Impl& p, const std::string& topic_name, const char* type,
           std::function<void(const std::vector<char>&)> handle, Qos qos = Qos::kDefault,
           std::function<void()> on_match = {})
      : p_(p), listener_(matches_, [this, handle = std::move(handle)](const std::vector<char>& b) {
          if (started_) handle(b);
        }) {
    matches_.on_change(std::move(on_match));
    std::lock_guard lock(p_.mutex);
    dds::Topic* topic = p_.topic(topic_name, type);
    reader_ = p_.subscriber->create_datareader(topic, with(dds::DATAREADER_QOS_DEFAULT, qos), &listener_);
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

// What a reader of messages of type T does with a sample: decode it and push it into the queue, or refuse it.
template <typename T>
std::function<void(const std::vector<char>&)> into(runtime::MessageQueue<T>& queue,
                                                   std::function<T(const std::vector<char>&)> decode, RefusalBook& book,
                                                   std::string topic_name) {
  return [&queue, decode = std::move(decode), &book, topic_name = std::move(topic_name)](const std::vector<char>& b) {
    try {
      queue.push(decode(b));
    } catch (const WireError& e) {
      book.refuse(topic_name, e.what());
    }
  };
}

// A flag and a wait for it.
class Flag {
 public:
  void set(bool value) {
    {
      std::lock_guard lock(mutex_);
      value_ = value;
    }
    changed_.notify_all();
  }
  bool get() const {
    std::lock_guard lock(mutex_);
    return value_;
  }
  bool wait_until(std::chrono::steady_clock::time_point deadline) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_until(lock, deadline, [&] { return value_; });
  }

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  bool value_ = false;
};

bool both_within(const Matches& a, const Matches& b, std::chrono::steady_clock::time_point deadline) {
  return a.wait_until(deadline) && b.wait_until(deadline);
}

}  // namespace

struct RemoteRobot::Impl {
  std::string robot;
  RefusalBook book;
  Flag ready;  // the agent's last state
  Forwarder<runtime::MotionCommand> commands;
  Receiver statuses;
  Receiver state;

  Impl(Participant& p, std::string name, std::size_t index, runtime::MessageQueue<runtime::MotionCommand>& cq,
       runtime::MessageQueue<runtime::RobotStatus>& sq)
      : robot(std::move(name)),
        commands(p.impl(), command_topic(robot), kCommandTypeName, cq,
                 [](const runtime::MotionCommand& c) { return encode_command(c); }),
        statuses(p.impl(), status_topic(robot), kStatusTypeName,
                 into<runtime::RobotStatus>(
                     sq, [index](const std::vector<char>& b) { return decode_status(b, index); }, book,
                     status_topic(robot))),
        state(
            p.impl(), agent_topic(robot), kAgentStateTypeName,
            [this, index](const std::vector<char>& b) {
              try {
                ready.set(decode_agent_state(b, index));
              } catch (const WireError& e) {
                book.refuse(agent_topic(robot), e.what());
              }
            },
            Qos::kLatched,
            [this] {
              if (state.matches().count() == 0) ready.set(false);  // the agent is gone
            }) {
    state.start();
  }

  bool present() const { return commands.matches().count() > 0 && statuses.matches().count() > 0 && ready.get(); }
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

bool RemoteRobot::wait_for_agent(std::chrono::milliseconds timeout) const {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  return impl_->commands.matches().wait_until(deadline) && impl_->statuses.matches().wait_until(deadline) &&
         impl_->ready.wait_until(deadline) && impl_->present();
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
                   fmt::format("no agent for robot{} {} on DDS domain {} within {:.1f} s (start one per robot: twin "
                               "agent --robot {} --domain {} ...)",
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

struct AgentEndpoint::Impl {
  std::size_t index;
  RefusalBook book;
  // Declared (so built) before the endpoints whose matches call announce(), and destroyed after them.
  std::mutex state_mutex;  // one state written at a time, in the order of the changes
  std::optional<bool> said;
  bool built = false;  // announce() may look at the endpoints (under state_mutex)
  // start() was called: the command reader hands samples on. Ready is said only then: a command taken before would
  // be dropped by the reader, and its status would never come.
  bool started = false;
  PlainWriter state;
  Receiver commands;
  Forwarder<runtime::RobotStatus> statuses;

  Impl(Participant& p, const std::string& robot, std::size_t robot_index, const task::CompiledProgram& program,
       runtime::MessageQueue<runtime::MotionCommand>& cq, runtime::MessageQueue<runtime::RobotStatus>& sq)
      : index(robot_index),
        state(p.impl(), agent_topic(robot), kAgentStateTypeName, Qos::kLatched),
        commands(
            p.impl(), command_topic(robot), kCommandTypeName,
            into<runtime::MotionCommand>(
                cq,
                [&program, robot_index](const std::vector<char>& b) { return decode_command(b, program, robot_index); },
                book, command_topic(robot)),
            Qos::kDefault, [this] { announce(); }),
        statuses(
            p.impl(), status_topic(robot), kStatusTypeName, sq,
            [](const runtime::RobotStatus& s) { return encode_status(s); }, [this] { announce(); }) {
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
    bool now = started && present();
    if (said == now) return;
    said = now;
    state.write(encode_agent_state(index, now));
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
  return impl_->commands.matches().count() > 0 && impl_->statuses.matches().count() > 0;
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
  Impl(Participant& p, const std::string& topic, const char* type, std::function<void(const std::vector<char>&)> h)
      : reader(p.impl(), topic, type, std::move(h)) {}
  Receiver reader;
};

RawReader::RawReader(Participant& participant, const std::string& topic, const char* type,
                     std::function<void(const std::vector<char>&)> handle)
    : impl_(new Impl(participant, topic, type, std::move(handle))) {}
RawReader::~RawReader() = default;
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
