// The DDS entities the distributed library's files share (not installed; link.cpp and ros_publisher.cpp use it): a
// DDS type whose samples are CDR bytes encoded by the project's own functions, ROS 2's QoS profiles, and what a
// Participant holds; how many endpoints match one of ours (Matches, kept by the endpoints' listeners).
//
// Threads: as the Participant (link.hpp): entity creation and deletion under Participant::Impl::mutex.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/distributed/link.hpp"

namespace cellwright::distributed {
namespace dds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;

// A DDS type whose samples are the CDR bytes wire.hpp (or ros_msgs.hpp) encodes, encapsulation header included: Fast
// DDS moves them as they are, and decoding (with its checks) is those files', where a refusal can say what was wrong.
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

// With a lease, the endpoint also has automatic liveliness with it (the links' endpoints: DdsOptions::lease): Fast
// DDS asserts a writer's liveliness for it while its process runs and reaches the network, and a reader whose writer
// has given no sign for the lease is told (on_liveliness_changed). A writer announces 4 times a lease. A reader's
// requested lease must not be shorter than the writer's offered one (DDS matches them only then): both ends of a
// link use the same lease. Without one, DDS's default (automatic, infinite), as ROS 2's default profile has it.
template <typename Q>
Q with(Q qos, Qos kind, std::optional<std::chrono::milliseconds> lease = std::nullopt) {
  if (lease) {
    qos.liveliness().kind = dds::AUTOMATIC_LIVELINESS_QOS;
    qos.liveliness().lease_duration =
        eprosima::fastrtps::Duration_t(static_cast<long double>(lease->count()) / 1000.0L);
    if constexpr (std::is_same_v<Q, dds::DataWriterQos>) {
      qos.liveliness().announcement_period =
          eprosima::fastrtps::Duration_t(static_cast<long double>(lease->count()) / 4000.0L);
    }
  }
  qos.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = kind == Qos::kLatched ? dds::TRANSIENT_LOCAL_DURABILITY_QOS : dds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = kind == Qos::kLatched ? 1 : 10;
  return qos;
}

// The participant (process) an endpoint belongs to: the first 12 bytes of its GUID, which an instance handle of it
// holds (DDS names a matched endpoint, and a sample's writer, by handle).
inline std::string participant_of(const dds::InstanceHandle_t& handle) {
  std::string prefix(12, '\0');
  for (std::size_t i = 0; i < prefix.size(); ++i) prefix[i] = static_cast<char>(handle.value[i]);
  return prefix;
}

// The 12 bytes of a GUID prefix, as participant_of() gives them.
inline std::string prefix_bytes(const rtps::GuidPrefix_t& prefix) {
  return std::string(reinterpret_cast<const char*>(prefix.value), 12);
}

// What discovery said of the other participants that went: dropped (no announcement of it for its participant lease,
// which our participants set to DdsOptions::lease: the process killed, its host down, the network cut) or removed
// (it said goodbye: a clean end). Fast DDS removes a participant's endpoints (the matches' callbacks) just before it
// reports the participant itself, on the same thread: wait_gone() waits for that report.
//
// Why the participant's lease and not the endpoints' liveliness: Fast DDS 2.9.1's reader side takes an automatic
// liveliness announcement of any participant as one of every automatic writer it knows (WLPListener asserts the
// kind, not the participant's writers; fixed in later Fast DDS, eProsima/Fast-DDS#4501), so a killed peer's writers
// never lapse while another peer lives (an agent with the other agent running, task control with two agents).
class PeerWatch : public dds::DomainParticipantListener {
 public:
  void on_participant_discovery(dds::DomainParticipant*, rtps::ParticipantDiscoveryInfo&& info) override {
    using S = rtps::ParticipantDiscoveryInfo::DISCOVERY_STATUS;
    if (info.status != S::DROPPED_PARTICIPANT && info.status != S::REMOVED_PARTICIPANT) return;
    {
      std::lock_guard lock(mutex_);
      gone_[prefix_bytes(info.info.m_guid.guidPrefix)] = info.status == S::DROPPED_PARTICIPANT;
    }
    changed_.notify_all();
  }
  // Waits until `participant` (participant_of) has gone, at most until `deadline`: true when it was dropped (its lease
  // expired), false when it said goodbye, nullopt when it has not gone (yet).
  std::optional<bool> wait_gone(const std::string& participant, std::chrono::steady_clock::time_point deadline) const {
    std::unique_lock lock(mutex_);
    if (!changed_.wait_until(lock, deadline, [&] { return gone_.count(participant) > 0; })) return std::nullopt;
    return gone_.at(participant);
  }

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::map<std::string, bool> gone_;
};

struct Participant::Impl {
  dds::DomainParticipant* participant = nullptr;
  PeerWatch peers;  // the participant's listener (~Participant deletes the participant first)
  dds::Publisher* publisher = nullptr;
  dds::Subscriber* subscriber = nullptr;
  std::chrono::milliseconds lease{1000};  // the links' liveliness lease (DdsOptions::lease)
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


// How many endpoints match one of ours, and a wait for it to change.
class Matches {
 public:
  // `changed` is called (on Fast DDS's thread) after every change; set it before the endpoint is created.
  void on_change(std::function<void()> changed) { changed_hook_ = std::move(changed); }
  // `count` endpoints match now; `change` of them (+1 or -1) is the one `handle` names.
  void set(int count, int change = 0, const dds::InstanceHandle_t& handle = {}) {
    {
      std::lock_guard lock(mutex_);
      count_ = count;
      if (change > 0) participants_.insert(participant_of(handle));
      if (change < 0) {
        if (auto it = participants_.find(participant_of(handle)); it != participants_.end()) participants_.erase(it);
      }
    }
    changed_.notify_all();
    if (changed_hook_) changed_hook_();
  }
  int count() const {
    std::lock_guard lock(mutex_);
    return count_;
  }
  // The participants of the matched endpoints.
  std::set<std::string> participants() const {
    std::lock_guard lock(mutex_);
    return {participants_.begin(), participants_.end()};
  }
  // Whether an endpoint of that participant matches (a match seen from this side, not only from the other's).
  bool has(const std::string& participant) const {
    std::lock_guard lock(mutex_);
    return participants_.count(participant) > 0;
  }
  bool wait_until(std::chrono::steady_clock::time_point deadline) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_until(lock, deadline, [&] { return count_ > 0; });
  }

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  int count_ = 0;
  std::multiset<std::string> participants_;  // of the matched endpoints
  std::function<void()> changed_hook_;
};

// A writer's listener that keeps its matches.
class WriterListener : public dds::DataWriterListener {
 public:
  explicit WriterListener(Matches& matches) : matches_(matches) {}
  void on_publication_matched(dds::DataWriter*, const dds::PublicationMatchedStatus& info) override {
    matches_.set(info.current_count, info.current_count_change, info.last_subscription_handle);
  }

 private:
  Matches& matches_;
};

// Takes every sample the reader has and hands each valid one's bytes, and its sample info (the writer's handle), to
// `handle` (a listener's on_data_available).
inline void take_all(dds::DataReader* reader,
                     const std::function<void(const std::vector<char>&, const dds::SampleInfo&)>& handle) {
  std::vector<char> bytes;
  dds::SampleInfo info;
  while (reader->take_next_sample(&bytes, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) handle(bytes, info);
  }
}

}  // namespace cellwright::distributed
