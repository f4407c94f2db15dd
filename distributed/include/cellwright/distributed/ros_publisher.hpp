// The cell as ROS 2 sees it, with no bridge (docs/distributed.md, "ROS 2 sees the cell"): a RosPublisher watches a
// run and publishes, on the DDS domain of its Participant, the topics and types ROS 2 (rmw_fastrtps) uses:
//
//   rt/joint_states       sensor_msgs/JointState  every robot's arm joints in one message, each joint named as its
//                                                 URDF names it, prefixed "<robot>_" (two PUMAs do not clash);
//                                                 positions only (velocity and effort empty)
//   rt/tf                 tf2_msgs/TFMessage      per robot "<robot>_<base link>" -> "<robot>_<flange link>" and
//                                                 flange -> "<robot>_<tool link>" (forward kinematics of the joints
//                                                 published), and "world" -> "workpiece_<name>" for each part present
//   rt/tf_static          tf2_msgs/TFMessage      "world" -> each robot's base link, "conveyor_<name>",
//                                                 "machine_<name>", "location_<name>", "camera_<name>" (MuJoCo's camera
//                                                 frame: it looks along -z), once, latched
//   rt/clock              rosgraph_msgs/Clock     the simulation time (ROS tools run with use_sim_time)
//   rt/cellwright/events  std_msgs/String         each event of the run's log, its JSONL line (unbounded string)
//
// Stamps are simulation time (the run's start is 0 s), as a simulator's are. QoS: ROS 2's default (reliable,
// volatile, keep last 10) for joint_states, tf and clock; tf_static reliable, transient local, keep last 1 (as ROS's
// static broadcaster); events reliable, volatile, keep last RosPublisherOptions::event_depth, so that a burst of
// events is not overwritten before a reader has it (a ROS subscriber with keep last 10 still matches).
//
// Where the values come from: the environment model (robot control writes each robot's joints into it from its
// driver; the parts' poses come from the sensors), read by a RunObserver on the simulation thread every
// 1/rate of simulation time (a short copy under the model's lock), and the event log's typed observer (a copy of
// the event into a queue). Neither waits for DDS: a publishing thread of the RosPublisher's own takes the latest
// copy and the queued events and writes them, at most `rate_hz` times a second of wall time, so a lock-step run
// at 100x publishes as often as a real-time one and no control cycle ever waits for the network. A robot whose robot
// control runs in an agent (RunConfig::remote_robots) is published with the joints this process's model has of it
// (its home: the model is not replicated yet).
//
// Threads: construct, attach, start and stop on one thread (the run's caller); the observers it gives are called on
// the run's threads; counts() from any thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "cellwright/distributed/link.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/runtime.hpp"

namespace cellwright::distributed {

inline constexpr const char* kJointStatesTopic = "rt/joint_states";
inline constexpr const char* kTfTopic = "rt/tf";
inline constexpr const char* kTfStaticTopic = "rt/tf_static";
inline constexpr const char* kClockTopic = "rt/clock";
inline constexpr const char* kEventsTopic = "rt/cellwright/events";
inline constexpr const char* kClockTypeName = "rosgraph_msgs::msg::dds_::Clock_";

struct RosPublisherOptions {
  double rate_hz = 50;             // joint_states, tf and clock at most this often (wall time) and every 1/rate of sim
  std::size_t event_depth = 1000;  // the events writer's history (keep last)
  std::size_t event_queue = 100000;  // events waiting for the publishing thread; more are dropped and counted
};

// What has been published so far.
struct RosCounts {
  std::uint64_t joint_states = 0, tf = 0, events = 0;
  std::uint64_t events_dropped = 0;  // the queue was full (the publishing thread fell that far behind)
};

class RosPublisher {
 public:
  // Reads each robot's URDF for its chain (InputError naming the file, as models::load_robot) and makes the writers
  // (InternalError when Fast DDS cannot). The participant must outlive the publisher.
  RosPublisher(Participant& participant, const models::CellDescription& cell, RosPublisherOptions options = {});
  ~RosPublisher();  // stop()s
  RosPublisher(const RosPublisher&) = delete;
  RosPublisher& operator=(const RosPublisher&) = delete;

  // Adds its observers to a run's configuration (RunConfig::observers, event_observers). Before the Runtime is built.
  void attach(runtime::RunConfig& config);
  // Waits at most `timeout` until every writer has a reader (a test's subscriber); false on timeout.
  bool wait_for_subscribers(std::chrono::milliseconds timeout) const;
  // Publishes tf_static and starts the publishing thread. Idempotent.
  void start();
  // Publishes what is left (the latest state, every queued event), stops the thread and waits at most `flush` for
  // the readers to acknowledge everything. Idempotent; false when the acknowledgements did not all come in time.
  bool stop(std::chrono::milliseconds flush = std::chrono::seconds(2));

  RosCounts counts() const;

  // The names used: "<robot>_<urdf name>" for a robot's joints and links.
  static std::string robot_name(const std::string& robot, const std::string& urdf_name);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// A reader of a ROS topic's samples as CDR bytes (ros_msgs.hpp decodes them), for tests and diagnostics: the QoS is
// the publisher's for that topic (tf_static's latched, the events' deeper history). `handle` is called on Fast DDS's
// listener thread, one sample at a time.
class RosSubscription {
 public:
  RosSubscription(Participant& participant, const std::string& topic, const char* type,
                  std::function<void(const std::vector<char>&)> handle);
  ~RosSubscription();
  RosSubscription(const RosSubscription&) = delete;
  RosSubscription& operator=(const RosSubscription&) = delete;

  // How many writers it matches now.
  int writers() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::distributed
