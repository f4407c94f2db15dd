// The ROS 2 messages' bytes (distributed/ros_msgs.hpp): one known message of each type against its layout worked out
// by hand from the CDR rules (offsets below are from the sample's first byte; the CDR origin, which alignment counts
// from, is byte 4, after the encapsulation header), round trips of seeded random messages, and refusals.
#include "cellwright/distributed/ros_msgs.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

namespace cellwright::distributed {
namespace {

std::vector<char> bytes(std::initializer_list<int> values) {
  std::vector<char> out;
  for (int v : values) out.push_back(static_cast<char>(v));
  return out;
}

void append(std::vector<char>& out, const std::vector<char>& more) {
  out.insert(out.end(), more.begin(), more.end());
}

std::vector<char> le_double(double v) {
  std::vector<char> out(8);
  std::memcpy(out.data(), &v, 8);  // the machine is little-endian (x86-64, arm64), as the CDR_LE header says
  return out;
}

// Where the layouts below differ from the naive one (packed, or aligned from the sample's first byte), the test would
// fail: the 8-byte alignment of a double is from the CDR origin (byte 4), so a double lands at byte 44, not 40 or 48.
TEST(RosMsgs, JointStateHasRmwFastrtpsLayoutByteByByte) {
  JointState m;
  m.header.stamp = {1, 500'000'000};
  m.header.frame_id = "w";
  m.name = {"joint1"};
  m.position = {0.5};
  m.velocity = {0.25};
  std::vector<char> want = bytes({0x00, 0x01, 0x00, 0x00,  // 0: encapsulation CDR_LE, options 0
                                  0x01, 0x00, 0x00, 0x00,  // 4: header.stamp.sec = 1 (int32)
                                  0x00, 0x65, 0xcd, 0x1d,  // 8: header.stamp.nanosec = 500000000 (uint32)
                                  0x02, 0x00, 0x00, 0x00,  // 12: header.frame_id length 2 (with the NUL)
                                  'w',  0x00, 0x00, 0x00,  // 16: "w", NUL, 2 bytes of padding to 4
                                  0x01, 0x00, 0x00, 0x00,  // 20: name count 1
                                  0x07, 0x00, 0x00, 0x00,  // 24: name[0] length 7
                                  'j',  'o',  'i',  'n',  't', '1', 0x00, 0x00,  // 28: "joint1", NUL, 1 byte padding
                                  0x01, 0x00, 0x00, 0x00,                        // 36: position count 1 (CDR offset 32)
                                  0x00, 0x00, 0x00, 0x00});  // 40: padding: CDR offset 36 -> 40, a multiple of 8
  append(want, le_double(0.5));                              // 44: position[0]
  append(want, bytes({0x01, 0x00, 0x00, 0x00,                // 52: velocity count 1
                      0x00, 0x00, 0x00, 0x00}));             // 56: padding to CDR offset 56
  append(want, le_double(0.25));                             // 60: velocity[0]
  append(want, bytes({0x00, 0x00, 0x00, 0x00}));             // 68: effort count 0; 72 bytes in all
  EXPECT_EQ(encode_joint_state(m), want);
  EXPECT_EQ(decode_joint_state(want), m);
}

TEST(RosMsgs, TfMessageHasRmwFastrtpsLayoutByteByByte) {
  TransformStamped t = make_transform({2, 0}, "w", "b", Eigen::Isometry3d(Eigen::Translation3d(1, 2, 3)));
  std::vector<char> want = bytes({0x00, 0x01, 0x00, 0x00,          // 0: encapsulation
                                  0x01, 0x00, 0x00, 0x00,          // 4: transforms count 1
                                  0x02, 0x00, 0x00, 0x00,          // 8: stamp.sec 2
                                  0x00, 0x00, 0x00, 0x00,          // 12: stamp.nanosec 0
                                  0x02, 0x00, 0x00, 0x00,          // 16: frame_id length 2
                                  'w',  0x00, 0x00, 0x00,          // 20: "w", NUL, padding
                                  0x02, 0x00, 0x00, 0x00,          // 24: child_frame_id length 2
                                  'b',  0x00,                      // 28: "b", NUL
                                  0,    0,    0,    0,    0, 0});  // 30: padding to CDR offset 32 (8-aligned)
  for (double v : {1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0}) append(want, le_double(v));  // 36: translation, rotation xyzw
  ASSERT_EQ(want.size(), 92u);
  EXPECT_EQ(encode_tf({t}), want);
  std::vector<TransformStamped> back = decode_tf(want);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0], t);
}

TEST(RosMsgs, StringHasRmwFastrtpsLayoutByteByByte) {
  EXPECT_EQ(encode_string("hi"), bytes({0x00, 0x01, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 'h', 'i', 0x00}));
  // An empty string is its length 1 and the NUL (ROS's and Fast CDR's convention).
  EXPECT_EQ(encode_string(""), bytes({0x00, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(decode_string(encode_string("{\"t\":1}")), "{\"t\":1}");
}

std::string random_text(std::mt19937& random, std::size_t most) {
  std::string s(random() % (most + 1), ' ');
  for (char& c : s) c = static_cast<char>('!' + random() % 90);
  return s;
}

TEST(RosMsgs, SeededRandomMessagesRoundTrip) {
  std::mt19937 random(28);
  std::uniform_real_distribution<double> value(-10, 10);
  for (int k = 0; k < 200; ++k) {
    JointState m;
    m.header.stamp = {static_cast<std::int32_t>(random() % 100000), static_cast<std::uint32_t>(random() % 1000000000)};
    m.header.frame_id = random_text(random, 12);
    std::size_t n = random() % 9;
    for (std::size_t j = 0; j < n; ++j) {
      m.name.push_back(random_text(random, 20));
      m.position.push_back(value(random));
      if (k % 2 == 0) m.velocity.push_back(value(random));
    }
    ASSERT_EQ(decode_joint_state(encode_joint_state(m)), m);

    std::vector<TransformStamped> tf;
    for (std::size_t j = random() % 5; j > 0; --j) {
      Eigen::Isometry3d pose =
          Eigen::Translation3d(value(random), value(random), value(random)) *
          Eigen::AngleAxisd(value(random), Eigen::Vector3d(value(random), 1, value(random)).normalized());
      tf.push_back(make_transform(m.header.stamp, random_text(random, 10), random_text(random, 10), pose));
    }
    ASSERT_EQ(decode_tf(encode_tf(tf)), tf);
    std::string text = random_text(random, 300);
    ASSERT_EQ(decode_string(encode_string(text)), text);
  }
}

TEST(RosMsgs, RosTimeFromSimulationTime) {
  EXPECT_EQ(to_ros_time(std::chrono::milliseconds(2'340)), (RosTime{2, 340'000'000}));
  EXPECT_THROW(to_ros_time(std::chrono::milliseconds(-1)), WireError);
}

TEST(RosMsgs, BadSamplesAreRefusedSayingWhy) {
  JointState m;
  m.name = {"a", "b"};
  m.position = {1, 2};
  std::vector<char> good = encode_joint_state(m);
  for (std::size_t cut = 0; cut + 4 <= good.size(); ++cut) {
    std::vector<char> shorter(good.begin(), good.begin() + static_cast<long>(cut));
    EXPECT_THROW(decode_joint_state(shorter), WireError) << cut;
  }
  // A count of 2^32 - 1 names: refused before anything is allocated.
  std::vector<char> huge = good;
  std::memset(huge.data() + 20, 0xff, 4);  // the name count (after the stamp and an empty frame_id)
  try {
    decode_joint_state(huge);
    FAIL() << "a name count of 2^32 - 1 was taken";
  } catch (const WireError& e) {
    EXPECT_NE(std::string(e.what()).find("4294967295 name elements"), std::string::npos) << e.what();
  }
  // A string without its NUL.
  std::vector<char> no_nul = encode_string("abc");
  no_nul.back() = 'd';
  EXPECT_THROW(decode_string(no_nul), WireError);
  // Bytes after the message.
  std::vector<char> longer = encode_string("abc");
  longer.resize(longer.size() + 8, 0);
  EXPECT_THROW(decode_string(longer), WireError);
  std::vector<char> tf = encode_tf({make_transform({}, "a", "b", Eigen::Isometry3d::Identity())});
  tf[4] = 3;  // three transforms announced, one there
  EXPECT_THROW(decode_tf(tf), WireError);
}

}  // namespace
}  // namespace cellwright::distributed
