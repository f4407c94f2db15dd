#include "cellwright/distributed/ros_publisher.hpp"

#include <fastdds/dds/core/status/PublicationMatchedStatus.hpp>
#include <fastdds/dds/core/status/SubscriptionMatchedStatus.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "cellwright/distributed/ros_msgs.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "dds_entities.hpp"

namespace cellwright::distributed {
namespace {

// The first size Fast DDS reserves for a sample of the ROS types (they are unbounded: a larger one is reallocated).
constexpr std::size_t kTypicalSample = 4096;

// The QoS of each topic this file writes (see the header).
template <typename Q>
Q topic_qos(Q qos, const std::string& topic, std::size_t event_depth) {
  qos = with(qos, topic == kTfStaticTopic ? Qos::kLatched : Qos::kDefault);
  if (topic == kEventsTopic) qos.history().depth = static_cast<std::int32_t>(event_depth);
  return qos;
}

const char* type_of_topic(const std::string& topic) {
  if (topic == kJointStatesTopic) return kJointStateTypeName;
  if (topic == kClockTopic) return kClockTypeName;
  if (topic == kEventsTopic) return kStringTypeName;
  return kTfMessageTypeName;
}

class RosWriter {
 public:
  RosWriter(Participant::Impl& p, const std::string& topic, std::size_t event_depth) : p_(p), topic_(topic) {
    dds::DataWriterQos qos = topic_qos(dds::DATAWRITER_QOS_DEFAULT, topic, event_depth);
    qos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0.1L);  // as link.cpp's writers
    std::lock_guard lock(p_.mutex);
    p_.ensure_type(type_of_topic(topic), kTypicalSample);
    writer_ = p_.publisher->create_datawriter(p_.topic(topic, type_of_topic(topic)), qos, &listener_);
    CW_CHECK(writer_ != nullptr, "cannot create a DDS writer on {}", topic);
  }
  ~RosWriter() {
    std::lock_guard lock(p_.mutex);
    p_.publisher->delete_datawriter(writer_);
  }
  void write(std::vector<char> bytes) {
    if (!writer_->write(&bytes)) std::cerr << fmt::format("DDS did not take a sample for {}\n", topic_);
  }
  const Matches& readers() const { return matches_; }
  bool flush(std::chrono::milliseconds timeout) {
    eprosima::fastrtps::Duration_t wait(static_cast<double>(timeout.count()) / 1000.0);
    return writer_->wait_for_acknowledgments(wait) == ReturnCode_t::RETCODE_OK;
  }

 private:
  Participant::Impl& p_;
  std::string topic_;
  Matches matches_;
  WriterListener listener_{matches_};
  dds::DataWriter* writer_ = nullptr;
};

// One cell robot as published: its names and chains.
struct PublishedRobot {
  std::string name;
  Eigen::Isometry3d base;
  std::string base_frame, flange_frame, tool_frame;
  std::vector<std::string> joints;  // prefixed
  models::KinematicChain flange;    // base link -> flange link
  models::KinematicChain tool;      // base link -> tool link
};

// What the observer copied out of the environment model.
struct Snapshot {
  runtime::SimDuration time{0};
  std::vector<std::vector<double>> joints;  // per published robot; empty: the model has no such robot
  std::vector<std::pair<std::string, Eigen::Isometry3d>> parts;  // present workpieces, centre in the world
};

PublishedRobot published(const models::RobotSpec& spec) {
  models::MountedRobot mounted = models::load_robot(spec);
  models::KinematicChain tool = models::robot_chain(spec, mounted);
  models::KinematicChain flange = models::KinematicChain::from_urdf(mounted.arm, spec.base_link, spec.flange_link);
  std::vector<std::string> joints;
  for (const std::string& j : tool.joint_names()) joints.push_back(RosPublisher::robot_name(spec.name, j));
  return PublishedRobot{spec.name,
                        spec.base.transform(),
                        RosPublisher::robot_name(spec.name, spec.base_link),
                        RosPublisher::robot_name(spec.name, spec.flange_link),
                        RosPublisher::robot_name(spec.name, spec.tool_link),
                        std::move(joints),
                        std::move(flange),
                        std::move(tool)};
}

}  // namespace

std::string RosPublisher::robot_name(const std::string& robot, const std::string& urdf_name) {
  return robot + "_" + urdf_name;
}

struct RosPublisher::Impl {
  RosPublisherOptions options;
  std::vector<PublishedRobot> robots;
  std::vector<TransformStamped> statics;
  RosWriter joint_states, tf, tf_static, clock, events;

  std::mutex mutex;  // the hand-over below
  std::condition_variable wake;
  std::optional<Snapshot> latest;  // not yet published
  std::deque<runtime::LogEvent> queued;
  bool stopping = false;
  std::thread thread;
  std::atomic<std::uint64_t> n_joint_states{0}, n_tf{0}, n_events{0}, n_dropped{0};

  Impl(Participant& p, const models::CellDescription& cell, RosPublisherOptions o)
      : options(o),
        joint_states(p.impl(), kJointStatesTopic, o.event_depth),
        tf(p.impl(), kTfTopic, o.event_depth),
        tf_static(p.impl(), kTfStaticTopic, o.event_depth),
        clock(p.impl(), kClockTopic, o.event_depth),
        events(p.impl(), kEventsTopic, o.event_depth) {
    if (!(o.rate_hz > 0 && o.rate_hz <= 1000)) {
      throw InputError(SourceLocation{"ROS publishing rate"}, fmt::format("{} Hz, outside (0, 1000]", o.rate_hz));
    }
    for (const models::RobotSpec& spec : cell.robots) robots.push_back(published(spec));
    const RosTime zero{};
    for (const PublishedRobot& r : robots) statics.push_back(make_transform(zero, "world", r.base_frame, r.base));
    for (const auto& c : cell.conveyors) {
      statics.push_back(make_transform(zero, "world", "conveyor_" + c.name, c.pose.transform()));
    }
    for (const auto& m : cell.machines) {
      statics.push_back(make_transform(zero, "world", "machine_" + m.name, m.pose.transform()));
    }
    for (const auto& l : cell.locations) {
      statics.push_back(make_transform(zero, "world", "location_" + l.name, l.pose.transform()));
    }
    for (const auto& c : cell.cameras) {
      statics.push_back(make_transform(zero, "world", "camera_" + c.name, c.pose.transform()));
    }
  }

  // Simulation thread: a short copy out of the model.
  void observe(const runtime::Observation& o) {
    Snapshot s;
    s.time = o.time;
    s.joints.resize(robots.size());
    o.environment.read([&](const runtime::EnvironmentModel& m) {
      for (std::size_t k = 0; k < robots.size(); ++k) {
        if (const runtime::RobotState* r = m.find_robot(robots[k].name)) s.joints[k] = r->joints;
      }
      for (const runtime::WorkpieceState& w : m.workpieces) {
        if (w.present) s.parts.emplace_back(w.name, w.pose);
      }
    });
    {
      std::lock_guard lock(mutex);
      latest = std::move(s);
    }
    wake.notify_one();
  }

  // The logging thread, under the log's lock: a copy into the queue.
  void queue_event(const runtime::LogEvent& e) {
    {
      std::lock_guard lock(mutex);
      if (queued.size() >= options.event_queue) {
        ++n_dropped;
        return;
      }
      queued.push_back(e);
    }
    wake.notify_one();
  }

  void publish(const Snapshot& s) {
    RosTime stamp = to_ros_time(s.time);
    JointState js;
    js.header.stamp = stamp;
    std::vector<TransformStamped> frames;
    for (std::size_t k = 0; k < robots.size(); ++k) {
      const PublishedRobot& r = robots[k];
      const std::vector<double>& q = s.joints[k];
      if (q.size() != r.joints.size()) continue;  // not in the model, or not this chain's joints
      js.name.insert(js.name.end(), r.joints.begin(), r.joints.end());
      js.position.insert(js.position.end(), q.begin(), q.end());
      if (q.size() != r.flange.dof()) continue;  // a flange chain with joints the tool chain has not: no frames
      Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
      Eigen::Isometry3d flange = r.flange.forward(v);
      frames.push_back(make_transform(stamp, r.base_frame, r.flange_frame, flange));
      frames.push_back(make_transform(stamp, r.flange_frame, r.tool_frame, flange.inverse() * r.tool.forward(v)));
    }
    for (const auto& [name, pose] : s.parts)
      frames.push_back(make_transform(stamp, "world", "workpiece_" + name, pose));
    clock.write(encode_clock(stamp));
    joint_states.write(encode_joint_state(js));
    tf.write(encode_tf(frames));
    ++n_joint_states;
    ++n_tf;
  }

  // The publishing thread: the latest snapshot and the queued events, at most options.rate_hz times a second.
  void run() {
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(1.0 / options.rate_hz));
    std::unique_lock lock(mutex);
    while (true) {
      wake.wait(lock, [&] { return stopping || latest || !queued.empty(); });
      std::optional<Snapshot> s = std::move(latest);
      latest.reset();
      std::deque<runtime::LogEvent> batch;
      batch.swap(queued);
      lock.unlock();
      const auto slot = std::chrono::steady_clock::now() + period;
      for (const runtime::LogEvent& e : batch) {
        events.write(encode_string(runtime::encode(e)));
        ++n_events;
      }
      if (s) {
        try {
          publish(*s);
        } catch (const std::exception& e) {  // this thread must not die of it; the run goes on
          std::cerr << fmt::format("ROS 2 publisher: joint_states/tf at {} ns not published: {}\n", s->time.count(),
                                   e.what());
        }
      }
      lock.lock();
      if (stopping && !latest && queued.empty()) return;
      wake.wait_until(lock, slot, [&] { return stopping; });
    }
  }
};

RosPublisher::RosPublisher(Participant& participant, const models::CellDescription& cell, RosPublisherOptions options)
    : impl_(new Impl(participant, cell, options)) {}

RosPublisher::~RosPublisher() {
  stop(std::chrono::milliseconds(0));
}

void RosPublisher::attach(runtime::RunConfig& config) {
  Impl* im = impl_.get();
  runtime::RunObserver observer;
  observer.every = std::chrono::round<runtime::SimDuration>(std::chrono::duration<double>(1.0 / im->options.rate_hz));
  observer.observe = [im](const runtime::Observation& o) { im->observe(o); };
  config.observers.push_back(std::move(observer));
  config.event_observers.push_back([im](const runtime::LogEvent& e) { im->queue_event(e); });
}

bool RosPublisher::wait_for_subscribers(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const Impl& im = *impl_;
  for (const RosWriter* w : {&im.joint_states, &im.tf, &im.tf_static, &im.events, &im.clock}) {
    if (!w->readers().wait_until(deadline)) return false;
  }
  return true;
}

void RosPublisher::start() {
  if (impl_->thread.joinable()) return;
  impl_->tf_static.write(encode_tf(impl_->statics));
  impl_->stopping = false;
  impl_->thread = std::thread([im = impl_.get()] { im->run(); });
}

bool RosPublisher::stop(std::chrono::milliseconds flush) {
  if (!impl_->thread.joinable()) return true;
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->wake.notify_one();
  impl_->thread.join();
  auto deadline = std::chrono::steady_clock::now() + flush;
  bool acknowledged = true;
  for (RosWriter* w : {&impl_->events, &impl_->joint_states, &impl_->tf, &impl_->clock, &impl_->tf_static}) {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    acknowledged = w->flush(std::max(left, std::chrono::milliseconds(0))) && acknowledged;
  }
  return acknowledged;
}

RosCounts RosPublisher::counts() const {
  return RosCounts{impl_->n_joint_states, impl_->n_tf, impl_->n_events, impl_->n_dropped};
}

namespace {

class SubscriptionListener : public dds::DataReaderListener {
 public:
  explicit SubscriptionListener(std::function<void(const std::vector<char>&)> handle) : handle_(std::move(handle)) {}
  void on_data_available(dds::DataReader* reader) override {
    take_all(reader, [this](const std::vector<char>& bytes, const dds::SampleInfo&) { handle_(bytes); });
  }

 private:
  std::function<void(const std::vector<char>&)> handle_;
};

}  // namespace

struct RosSubscription::Impl {
  Participant::Impl& p;
  SubscriptionListener listener;
  dds::DataReader* reader = nullptr;
  Impl(Participant::Impl& participant, std::function<void(const std::vector<char>&)> handle)
      : p(participant), listener(std::move(handle)) {}
};

RosSubscription::RosSubscription(Participant& participant, const std::string& topic, const char* type,
                                 std::function<void(const std::vector<char>&)> handle)
    : impl_(new Impl(participant.impl(), std::move(handle))) {
  Participant::Impl& p = impl_->p;
  std::lock_guard lock(p.mutex);
  p.ensure_type(type, kTypicalSample);
  impl_->reader = p.subscriber->create_datareader(
      p.topic(topic, type), topic_qos(dds::DATAREADER_QOS_DEFAULT, topic, RosPublisherOptions{}.event_depth),
      &impl_->listener);
  CW_CHECK(impl_->reader != nullptr, "cannot create a DDS reader on {}", topic);
}

RosSubscription::~RosSubscription() {
  std::lock_guard lock(impl_->p.mutex);
  impl_->reader->set_listener(nullptr);
  impl_->p.subscriber->delete_datareader(impl_->reader);
}

int RosSubscription::writers() const {
  dds::SubscriptionMatchedStatus status;
  impl_->reader->get_subscription_matched_status(status);
  return status.current_count;
}

}  // namespace cellwright::distributed
