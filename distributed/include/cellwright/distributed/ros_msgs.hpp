// ROS 2 messages the cell publishes (docs/distributed.md, "ROS 2 sees the cell"): sensor_msgs/JointState,
// tf2_msgs/TFMessage and std_msgs/String, as DDS samples with the bytes ROS 2's rmw_fastrtps writes for them, so that
// ROS 2 tools (ros2 topic echo, rviz, robot_state_publisher) read them with no bridge and no package of ours.
//
// The wire: plain CDR (XCDR1), little-endian, the 4-byte encapsulation header first (00 01 00 00: CDR_LE, no
// options); alignment is counted from the byte after the header; every primitive is aligned to its own size (a
// float64 to 8, an int32/uint32 to 4); a string is a uint32 length that counts its terminating NUL, its bytes and the
// NUL (an empty string: length 1 and one NUL); a sequence is a uint32 element count and the elements; a struct is its
// members in order with no padding of its own. ROS 2 message definitions map to these IDL types (each ROS type
// `pkg/msg/Name` is `pkg::msg::dds_::Name_` on the wire):
//
//   builtin_interfaces::msg::dds_::Time_    { int32 sec; uint32 nanosec; }
//   std_msgs::msg::dds_::Header_            { Time_ stamp; string frame_id; }
//   sensor_msgs::msg::dds_::JointState_     { Header_ header; sequence<string> name; sequence<double> position;
//                                             sequence<double> velocity; sequence<double> effort; }
//   geometry_msgs::msg::dds_::Vector3_      { double x, y, z; }
//   geometry_msgs::msg::dds_::Quaternion_   { double x, y, z, w; }
//   geometry_msgs::msg::dds_::Transform_    { Vector3_ translation; Quaternion_ rotation; }
//   geometry_msgs::msg::dds_::TransformStamped_ { Header_ header; string child_frame_id; Transform_ transform; }
//   tf2_msgs::msg::dds_::TFMessage_         { sequence<TransformStamped_> transforms; }
//   std_msgs::msg::dds_::String_            { string data; }
//   rosgraph_msgs::msg::dds_::Clock_        { Time_ clock; }
//
// All strings and sequences are unbounded, as in the ROS definitions. The offsets a test checks byte by byte
// (tests/distributed/ros_msgs_test.cpp) are listed there for one known message of each type.
//
// decode_*() never trusts the bytes: a sample cut short, a count larger than the bytes left could hold, a string
// without its NUL, or more than 3 bytes after the message is refused with a WireError (wire.hpp) saying what was wrong.
//
// Threads: pure functions, any thread.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

#include "cellwright/distributed/wire.hpp"
#include "cellwright/runtime/clock.hpp"

namespace cellwright::distributed {

inline constexpr const char* kJointStateTypeName = "sensor_msgs::msg::dds_::JointState_";
inline constexpr const char* kTfMessageTypeName = "tf2_msgs::msg::dds_::TFMessage_";
inline constexpr const char* kStringTypeName = "std_msgs::msg::dds_::String_";

// builtin_interfaces/Time.
struct RosTime {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;  // 0..999999999
  bool operator==(const RosTime&) const = default;
};

// Simulation time as a ROS time (the run's start is 0 s). WireError for a time before 0 or past 2^31 s.
RosTime to_ros_time(runtime::SimDuration t);

// std_msgs/Header.
struct RosHeader {
  RosTime stamp;
  std::string frame_id;
  bool operator==(const RosHeader&) const = default;
};

// sensor_msgs/JointState. The arrays are empty or as long as `name` (ROS's rule; encode does not check it, decode
// does not either: a ROS publisher may send any lengths).
struct JointState {
  RosHeader header;
  std::vector<std::string> name;
  std::vector<double> position, velocity, effort;
  bool operator==(const JointState&) const = default;
};

// geometry_msgs/TransformStamped: `child_frame_id`'s pose in `header.frame_id`'s frame.
struct TransformStamped {
  RosHeader header;
  std::string child_frame_id;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // x, y, z, w on the wire
  bool operator==(const TransformStamped& o) const {
    return header == o.header && child_frame_id == o.child_frame_id && translation == o.translation &&
           rotation.coeffs() == o.rotation.coeffs();
  }
};

// A TransformStamped of `child` in `parent` at `pose` (the rotation normalized).
TransformStamped make_transform(RosTime stamp, const std::string& parent, const std::string& child,
                                const Eigen::Isometry3d& pose);

std::vector<char> encode_joint_state(const JointState& message);
JointState decode_joint_state(const std::vector<char>& bytes);

// tf2_msgs/TFMessage.
std::vector<char> encode_tf(const std::vector<TransformStamped>& transforms);
std::vector<TransformStamped> decode_tf(const std::vector<char>& bytes);

// rosgraph_msgs/Clock: { builtin_interfaces/Time clock; }.
std::vector<char> encode_clock(RosTime clock);
RosTime decode_clock(const std::vector<char>& bytes);

// std_msgs/String.
std::vector<char> encode_string(const std::string& data);
std::string decode_string(const std::vector<char>& bytes);

}  // namespace cellwright::distributed
