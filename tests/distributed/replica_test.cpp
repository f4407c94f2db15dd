// What an agent shares besides commands and statuses (distributed/replica.hpp): its step's changes to the environment
// model and its events. What one robot control writes reaches another process's model as it was; bytes that are not
// an update or an event are refused with a reason.
#include "cellwright/distributed/replica.hpp"

#include <gtest/gtest.h>

#include <random>

#include "cellwright/distributed/wire.hpp"
#include "cellwright/models/cell.hpp"

namespace cellwright::distributed {
namespace {

runtime::EnvironmentModel model() {
  return runtime::make_environment_model(models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml"));
}

// The PUMA's step: it moved and closed on A, which it now carries 5 cm higher.
runtime::EnvironmentModel after_grasp(const runtime::EnvironmentModel& before) {
  runtime::EnvironmentModel m = before;
  runtime::RobotState& puma = *m.find_robot("puma");
  for (std::size_t j = 0; j < puma.joints.size(); ++j) puma.joints[j] += 0.01 * static_cast<double>(j + 1);
  Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();
  tcp.translation() = Eigen::Vector3d(0.03, -0.55, 0.62);
  tcp.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  puma.tcp = tcp;
  runtime::Hold hold;
  hold.workpiece = "A";
  hold.tcp_above_bottom = 0.04;
  hold.in_hand.translation() = Eigen::Vector3d(0, 0, 0.03);
  puma.hold = hold;
  runtime::WorkpieceState& a = *m.find_workpiece("A");
  a.held_by = "puma";
  a.claimed_by = "puma";
  a.pose.translation() += Eigen::Vector3d(0, 0, 0.05);
  a.stamp = std::chrono::milliseconds(1230);
  return m;
}

TEST(Replica, AStepsChangesReachAnotherModelAsTheyWere) {
  const runtime::EnvironmentModel before = model();
  const runtime::EnvironmentModel after = after_grasp(before);
  std::optional<ModelUpdate> u = changes(before, after, "puma", 0);
  ASSERT_TRUE(u.has_value());
  ASSERT_EQ(u->workpieces.size(), 1u);  // A only: the others did not change
  EXPECT_EQ(u->workpieces[0].name, "A");
  u->sequence = 3;
  const ModelUpdate got = decode_model_update(encode_model_update(*u), 0);
  EXPECT_EQ(got.sequence, 3u);

  runtime::EnvironmentModel elsewhere = model();  // another process's model, before the update
  apply(elsewhere, got);
  const runtime::RobotState& puma = *elsewhere.find_robot("puma");
  EXPECT_EQ(puma.joints, after.find_robot("puma")->joints);
  ASSERT_TRUE(puma.hold.has_value());
  EXPECT_EQ(puma.hold->workpiece, "A");
  EXPECT_DOUBLE_EQ(puma.hold->tcp_above_bottom, 0.04);
  ASSERT_TRUE(puma.tcp.has_value());
  EXPECT_TRUE(puma.tcp->isApprox(*after.find_robot("puma")->tcp, 1e-12));
  const runtime::WorkpieceState& a = *elsewhere.find_workpiece("A");
  EXPECT_EQ(a.held_by, "puma");
  EXPECT_EQ(a.claimed_by, "puma");
  EXPECT_EQ(a.stamp, std::chrono::milliseconds(1230));
  EXPECT_TRUE(a.pose.isApprox(after.find_workpiece("A")->pose, 1e-12));
  EXPECT_NE(a.fixed, nullptr);  // its geometry is the receiving model's own
  // Nothing else changed there, and a step that changes nothing sends nothing.
  EXPECT_EQ(elsewhere.find_robot("melfa")->joints, before.find_robot("melfa")->joints);
  EXPECT_FALSE(changes(after, after, "puma", 0).has_value());
}

TEST(Replica, BytesThatAreNoUpdateOfThisRobotAreRefused) {
  const runtime::EnvironmentModel before = model();
  ModelUpdate u = *changes(before, after_grasp(before), "puma", 0);
  u.sequence = 1;
  const std::vector<char> bytes = encode_model_update(u);
  EXPECT_THROW(decode_model_update(bytes, 1), WireError);  // the PUMA's update on the MELFA's topic
  for (std::size_t cut : {std::size_t{0}, std::size_t{3}, std::size_t{20}, bytes.size() / 2, bytes.size() - 8}) {
    EXPECT_THROW(decode_model_update(std::vector<char>(bytes.begin(), bytes.begin() + static_cast<long>(cut)), 0),
                 WireError)
        << "cut at " << cut;
  }
  std::mt19937 random(28);
  int refused = 0;
  for (int i = 0; i < 200; ++i) {
    std::vector<char> garbage(4 + random() % 400);
    for (char& c : garbage) c = static_cast<char>(random());
    garbage[0] = 0;
    garbage[1] = 1;  // a CDR little-endian header: the body is what must be refused
    try {
      (void)decode_model_update(garbage, 0);
    } catch (const WireError&) {
      ++refused;
    }
  }
  EXPECT_EQ(refused, 200);
  // An update that decodes but names what this cell does not have is refused by apply, the model untouched.
  u.workpieces[0].name = "Z";
  runtime::EnvironmentModel m = model();
  EXPECT_THROW(apply(m, decode_model_update(encode_model_update(u), 0)), WireError);
  EXPECT_EQ(m.find_robot("puma")->joints, before.find_robot("puma")->joints);
}

TEST(Replica, AnEventComesBackAsItsLogLineAndALineThatIsNoEventIsRefused) {
  runtime::events::CommandEnd end;
  end.t = std::chrono::milliseconds(4560);
  end.robot = "r2";
  end.primitive = 3;
  end.command = "move hand_grasp(r1)";
  end.ok = false;
  end.reason = "closed on nothing";
  const std::string line = runtime::encode(runtime::LogEvent{end});
  const auto [event, sequence] = decode_robot_event(encode_robot_event(1, 9, line), 1);
  EXPECT_EQ(sequence, 9u);
  EXPECT_EQ(runtime::encode(event), line);
  EXPECT_THROW(decode_robot_event(encode_robot_event(1, 9, line), 0), WireError);  // another robot's topic
  EXPECT_THROW(decode_robot_event(encode_robot_event(1, 10, "{\"t\":1,\"type\":\"nonsense\"}"), 1), WireError);
  EXPECT_THROW(decode_robot_event(encode_robot_event(1, 11, "not json"), 1), WireError);
}

}  // namespace
}  // namespace cellwright::distributed
