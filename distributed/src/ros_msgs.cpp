#include "cellwright/distributed/ros_msgs.hpp"

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <chrono>
#include <limits>

#include <fmt/format.h>

namespace cellwright::distributed {
namespace {

namespace cdr = eprosima::fastcdr;

// Writes a message into a zeroed buffer, twice as large until it fits (the ROS types are unbounded): the padding
// between fields is zeros, so that a message always gives the same bytes.
template <typename Write>
std::vector<char> encode(Write write) {
  for (std::size_t size = 256;; size *= 2) {
    std::vector<char> buffer(size, 0);
    cdr::FastBuffer fast(buffer.data(), buffer.size());
    cdr::Cdr out(fast, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR);
    try {
      out.serialize_encapsulation();
      write(out);
    } catch (const cdr::exception::NotEnoughMemoryException&) {
      continue;
    }
    buffer.resize(out.getSerializedDataLength());
    return buffer;
  }
}

// Reads a message from untrusted bytes: counts are checked against what is left before anything is allocated.
class Reader {
 public:
  Reader(const std::vector<char>& bytes, const char* type)
      : copy_(bytes),
        fast_(copy_.data(), copy_.size()),
        in_(fast_, cdr::Cdr::DEFAULT_ENDIAN, cdr::Cdr::DDS_CDR),
        type_(type) {
    if (bytes.size() < 4) throw WireError(fmt::format("{}: {} bytes, shorter than its header", type, bytes.size()));
  }

  // Runs `read` (the CDR library's own refusals become WireErrors), then refuses more than 3 bytes left over.
  template <typename Read>
  void run(Read read) {
    try {
      in_.read_encapsulation();
      read(*this);
    } catch (const cdr::exception::Exception& e) {
      throw WireError(fmt::format("{}: {} ({} bytes)", type_, e.what(), copy_.size()));
    }
    std::size_t used = in_.getSerializedDataLength();
    if (copy_.size() > used + 3) {
      throw WireError(fmt::format("{}: {} bytes after the message's {}", type_, copy_.size() - used, used));
    }
  }

  template <typename T>
  T get() {
    T value{};
    in_ >> value;
    return value;
  }

  // A sequence's element count, refused when `smallest` bytes per element would not fit in what is left.
  std::uint32_t count(std::size_t smallest, const char* field) {
    auto n = get<std::uint32_t>();
    std::size_t left = copy_.size() - in_.getSerializedDataLength();
    if (static_cast<std::uint64_t>(n) * smallest > left) {
      throw WireError(fmt::format("{}: {} {} elements in {} bytes", type_, n, field, left));
    }
    return n;
  }

  std::string string(const char* field) {
    auto length = get<std::uint32_t>();
    std::size_t left = copy_.size() - in_.getSerializedDataLength();
    if (length == 0) throw WireError(fmt::format("{}.{}: a string of length 0 (CDR counts its NUL)", type_, field));
    if (length > left) throw WireError(fmt::format("{}.{}: {} bytes, {} left", type_, field, length, left));
    std::string text(length, '\0');
    in_.deserializeArray(text.data(), length);
    if (text.back() != '\0') throw WireError(fmt::format("{}.{}: no terminating NUL", type_, field));
    text.pop_back();
    return text;
  }

  std::vector<double> doubles(const char* field) {
    std::vector<double> values(count(8, field));
    for (double& v : values) v = get<double>();
    return values;
  }

  RosTime header_stamp() {
    RosTime t;
    t.sec = get<std::int32_t>();
    t.nanosec = get<std::uint32_t>();
    if (t.nanosec > 999'999'999) throw WireError(fmt::format("{}: a time of {} ns past the second", type_, t.nanosec));
    return t;
  }

  RosHeader header() {
    RosHeader h;
    h.stamp = header_stamp();
    h.frame_id = string("header.frame_id");
    return h;
  }

 private:
  std::vector<char> copy_;  // the CDR reader wants a mutable buffer
  cdr::FastBuffer fast_;
  cdr::Cdr in_;
  const char* type_;
};

void put_header(cdr::Cdr& out, const RosHeader& h) {
  out << h.stamp.sec << h.stamp.nanosec << h.frame_id;
}

void put_doubles(cdr::Cdr& out, const std::vector<double>& values) {
  out << static_cast<std::uint32_t>(values.size());
  for (double v : values) out << v;
}

}  // namespace

RosTime to_ros_time(runtime::SimDuration t) {
  auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(t).count();
  if (ns < 0 || ns / 1'000'000'000 > std::numeric_limits<std::int32_t>::max()) {
    throw WireError(fmt::format("a time of {} ns does not fit a ROS time", ns));
  }
  return RosTime{static_cast<std::int32_t>(ns / 1'000'000'000), static_cast<std::uint32_t>(ns % 1'000'000'000)};
}

TransformStamped make_transform(RosTime stamp, const std::string& parent, const std::string& child,
                                const Eigen::Isometry3d& pose) {
  TransformStamped t;
  t.header = {stamp, parent};
  t.child_frame_id = child;
  t.translation = pose.translation();
  t.rotation = Eigen::Quaterniond(pose.linear()).normalized();
  return t;
}

std::vector<char> encode_joint_state(const JointState& m) {
  return encode([&](cdr::Cdr& out) {
    put_header(out, m.header);
    out << static_cast<std::uint32_t>(m.name.size());
    for (const std::string& n : m.name) out << n;
    put_doubles(out, m.position);
    put_doubles(out, m.velocity);
    put_doubles(out, m.effort);
  });
}

JointState decode_joint_state(const std::vector<char>& bytes) {
  JointState m;
  Reader(bytes, kJointStateTypeName).run([&](Reader& in) {
    m.header = in.header();
    m.name.resize(in.count(5, "name"));  // a string is at least its length and its NUL
    for (std::string& n : m.name) n = in.string("name");
    m.position = in.doubles("position");
    m.velocity = in.doubles("velocity");
    m.effort = in.doubles("effort");
  });
  return m;
}

std::vector<char> encode_tf(const std::vector<TransformStamped>& transforms) {
  return encode([&](cdr::Cdr& out) {
    out << static_cast<std::uint32_t>(transforms.size());
    for (const TransformStamped& t : transforms) {
      put_header(out, t.header);
      out << t.child_frame_id;
      out << t.translation.x() << t.translation.y() << t.translation.z();
      out << t.rotation.x() << t.rotation.y() << t.rotation.z() << t.rotation.w();
    }
  });
}

std::vector<TransformStamped> decode_tf(const std::vector<char>& bytes) {
  std::vector<TransformStamped> transforms;
  Reader(bytes, kTfMessageTypeName).run([&](Reader& in) {
    // Each is at least its stamp (8), two strings (5 each) and seven doubles (56).
    transforms.resize(in.count(74, "transforms"));
    for (TransformStamped& t : transforms) {
      t.header = in.header();
      t.child_frame_id = in.string("child_frame_id");
      for (int k = 0; k < 3; ++k) t.translation[k] = in.get<double>();
      double x = in.get<double>(), y = in.get<double>(), z = in.get<double>(), w = in.get<double>();
      t.rotation = Eigen::Quaterniond(w, x, y, z);
    }
  });
  return transforms;
}

std::vector<char> encode_clock(RosTime clock) {
  return encode([&](cdr::Cdr& out) { out << clock.sec << clock.nanosec; });
}

RosTime decode_clock(const std::vector<char>& bytes) {
  RosTime clock;
  Reader(bytes, "rosgraph_msgs::msg::dds_::Clock_").run([&](Reader& in) { clock = in.header_stamp(); });
  return clock;
}

std::vector<char> encode_string(const std::string& data) {
  return encode([&](cdr::Cdr& out) { out << data; });
}

std::string decode_string(const std::vector<char>& bytes) {
  std::string data;
  Reader(bytes, kStringTypeName).run([&](Reader& in) { data = in.string("data"); });
  return data;
}

}  // namespace cellwright::distributed
