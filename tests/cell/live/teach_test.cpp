// Teaching (cell/live/teach.hpp) on the exchange scenario's cell: the teach pose is a copy (the world untouched),
// joint jogs clamp at the URDF limits, seeded random jogs undone return to the same pose, Cartesian jogs move the tool
// along the world's axes with its orientation kept or are refused with the pose unchanged, and the collisions at the
// teach pose name what the robot touches.
#include "cellwright/cell/live/teach.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>

#include "cellwright/cell/sim/run.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::cell {
namespace {

const std::string kExchange = std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml";

TeachRequest jog(const std::string& robot, int joint, double delta) {
  TeachRequest r{robot, TeachAction::kJoint, joint, "", delta, {}};
  return r;
}
TeachRequest cartesian(const std::string& robot, const std::string& axis, double delta) {
  return TeachRequest{robot, TeachAction::kCartesian, -1, axis, delta, {}};
}
TeachRequest begin(const std::string& robot) { return TeachRequest{robot, TeachAction::kBegin, -1, "", 0, {}}; }

class Teaching : public ::testing::Test {
 protected:
  Teaching() : scenario_(load_scenario(kExchange)), world_(make_cell_world(scenario_).world) {}
  std::vector<double> qpos() const {
    const mjData* d = world_->data();
    return std::vector<double>(d->qpos, d->qpos + world_->scene().model()->nq);
  }
  Scenario scenario_;
  std::unique_ptr<twin::sim::World> world_;
};

TEST_F(Teaching, BeginStartsFromTheRobotsJointsAndNothingTouchesTheWorld) {
  Teacher t(scenario_);
  const std::vector<double> before = qpos();
  const TeachState s = t.apply(begin("puma"), *world_);
  EXPECT_TRUE(s.active);
  const twin::RobotIds* ids = world_->scene().find_robot("puma");
  ASSERT_EQ(static_cast<std::size_t>(s.joints.size()), ids->qpos_adr.size());
  for (std::size_t k = 0; k < ids->qpos_adr.size(); ++k) {
    EXPECT_EQ(s.joints[static_cast<Eigen::Index>(k)], world_->data()->qpos[ids->qpos_adr[k]]);
  }
  // The tool is where the twin's own TCP site is.
  const mjtNum* site = world_->data()->site_xpos + 3 * ids->tcp_site;
  EXPECT_LT((s.tool.translation() - Eigen::Vector3d(site[0], site[1], site[2])).norm(), 1e-6);
  t.apply(jog("puma", 1, 0.3), *world_);
  t.apply(cartesian("puma", "z", 0.02), *world_);
  EXPECT_EQ(qpos(), before) << "teaching moved the run's robot";
  // A robot named by its program label is the cell's robot.
  EXPECT_EQ(t.apply(begin("r2"), *world_).robot, "melfa");
  EXPECT_EQ(t.active(), (std::vector<std::string>{"melfa", "puma"}));
}

TEST_F(Teaching, SeededRandomJointJogsUndoneReturnToTheSamePose) {
  Teacher t(scenario_);
  const models::KinematicChain chain = models::robot_chain(*scenario_.cell.find_robot("puma"));
  const TeachState s0 = t.apply(begin("puma"), *world_);
  const Eigen::VectorXd start = s0.joints;
  std::mt19937 rng(29);
  std::uniform_int_distribution<int> joint(0, static_cast<int>(chain.dof()) - 1);
  std::uniform_real_distribution<double> delta(-0.3, 0.3);
  std::vector<std::pair<int, double>> jogs;
  Eigen::VectorXd q = start;
  while (jogs.size() < 40) {
    const int j = joint(rng);
    const double d = delta(rng);
    const auto& lim = chain.limits()[static_cast<std::size_t>(j)];
    if (q[j] + d <= lim.lower || q[j] + d >= lim.upper) continue;  // stay clear of the limits: no clamping
    q[j] += d;
    jogs.emplace_back(j, d);
    const TeachState s = t.apply(jog("puma", j, d), *world_);
    EXPECT_TRUE(s.reason.empty()) << s.reason;
  }
  for (auto it = jogs.rbegin(); it != jogs.rend(); ++it) t.apply(jog("puma", it->first, -it->second), *world_);
  const TeachState back = *t.state("puma");
  EXPECT_LT((back.joints - start).norm(), 1e-12);
  EXPECT_LT((back.tool.matrix() - s0.tool.matrix()).norm(), 1e-9);
}

TEST_F(Teaching, AJointJogStopsAtTheLimitAndSaysSo) {
  Teacher t(scenario_);
  const models::KinematicChain chain = models::robot_chain(*scenario_.cell.find_robot("puma"));
  t.apply(begin("puma"), *world_);
  const TeachState s = t.apply(jog("puma", 2, 100), *world_);
  EXPECT_EQ(s.joints[2], chain.limits()[2].upper);
  EXPECT_EQ(s.at_limit, std::vector<int>{2});
  EXPECT_NE(s.reason.find("limit"), std::string::npos) << s.reason;
  const TeachState off = t.apply(jog("puma", 2, -0.1), *world_);
  EXPECT_TRUE(off.at_limit.empty());
  EXPECT_TRUE(off.reason.empty());
}

TEST_F(Teaching, CartesianJogsMoveTheToolAlongTheWorldAxesOrAreRefused) {
  Teacher t(scenario_);
  const TeachState s0 = t.apply(begin("puma"), *world_);
  for (const char* axis : {"x", "y", "z"}) {
    const TeachState s1 = t.apply(cartesian("puma", axis, 0.02), *world_);
    ASSERT_TRUE(s1.reachable) << axis << ": " << s1.reason;
    Eigen::Vector3d want = s0.tool.translation();
    want[axis[0] - 'x'] += 0.02;
    EXPECT_LT((s1.tool.translation() - want).norm(), 1e-4) << axis;
    EXPECT_LT(Eigen::AngleAxisd(s1.tool.linear().transpose() * s0.tool.linear()).angle(), 1e-3) << axis;
    const TeachState s2 = t.apply(cartesian("puma", axis, -0.02), *world_);
    EXPECT_LT((s2.tool.translation() - s0.tool.translation()).norm(), 1e-4) << axis;
  }
  const TeachState turned = t.apply(cartesian("puma", "yaw", 0.2), *world_);
  ASSERT_TRUE(turned.reachable) << turned.reason;
  EXPECT_LT((turned.tool.translation() - s0.tool.translation()).norm(), 1e-4);
  EXPECT_NEAR(Eigen::AngleAxisd(turned.tool.linear() * s0.tool.linear().transpose()).angle(), 0.2, 1e-3);
  // Out of reach: the pose stays, the reply says why.
  const TeachState far = t.apply(cartesian("puma", "x", 5), *world_);
  EXPECT_FALSE(far.reachable);
  EXPECT_FALSE(far.reason.empty());
  EXPECT_EQ(far.joints, turned.joints);
}

TEST_F(Teaching, CollisionsAtTheTeachPoseNameWhatTheRobotTouches) {
  Teacher t(scenario_);
  TeachState s = t.apply(begin("puma"), *world_);
  EXPECT_TRUE(s.collisions.empty()) << s.collisions.front().a << " / " << s.collisions.front().b;
  // Down through whatever is under the tool (a belt, a stand or the floor), 1 cm at a time until something is hit.
  for (int i = 0; i < 200 && s.collisions.empty(); ++i) {
    s = t.apply(cartesian("puma", "z", -0.01), *world_);
    if (!s.reachable) s = t.apply(jog("puma", 1, 0.05), *world_);
  }
  ASSERT_FALSE(s.collisions.empty()) << "the PUMA went down to z = " << s.tool.translation().z() << " touching nothing";
  const TeachContact& c = s.collisions.front();
  EXPECT_EQ(c.a.rfind("puma ", 0), 0u) << c.a;
  EXPECT_FALSE(c.b.empty());
  EXPECT_GT(c.depth, kTeachContactDepth);
  EXPECT_LT((c.pos - s.tool.translation()).norm(), 1.5) << "the contact is near the arm";
  const nlohmann::json j = nlohmann::json::parse(teach_json(s));
  EXPECT_EQ(j["collisions"][0]["a"], c.a);
  EXPECT_EQ(j["collisions"][0]["pos"].size(), 3u);
}

TEST_F(Teaching, BadRequestsAreRefused) {
  Teacher t(scenario_);
  EXPECT_THROW(t.apply(begin("kuka"), *world_), LiveRefusal);
  EXPECT_THROW(t.apply(jog("puma", 0, 0.1), *world_), LiveRefusal) << "not being taught";
  t.apply(begin("puma"), *world_);
  EXPECT_THROW(t.apply(jog("puma", 6, 0.1), *world_), LiveRefusal);
  EXPECT_THROW(t.apply(TeachRequest{"puma", TeachAction::kJoints, -1, "", 0, {0, 0}}, *world_), LiveRefusal);
  EXPECT_THROW(t.apply(TeachRequest{"puma", TeachAction::kJoints, -1, "", 0, {0, 0, 0, 0, 0, 100}}, *world_),
               LiveRefusal);
  const TeachState end = t.apply(TeachRequest{"puma", TeachAction::kEnd, -1, "", 0, {}}, *world_);
  EXPECT_FALSE(end.active);
  EXPECT_EQ(t.state("puma"), nullptr);
  EXPECT_EQ(teach_json(end), R"({"active":false,"robot":"puma","type":"teach"})");
  // Parsing: every field checked.
  EXPECT_EQ(parse_teach(R"({"type":"teach","robot":"puma","action":"joint","joint":2,"delta":0.1})").joint, 2);
  EXPECT_THROW(parse_teach(R"({"type":"teach","action":"begin"})"), LiveRefusal);
  EXPECT_THROW(parse_teach(R"({"type":"teach","robot":"puma","action":"fly"})"), LiveRefusal);
  EXPECT_THROW(parse_teach(R"({"type":"teach","robot":"puma","action":"joint","joint":1.5,"delta":0.1})"), LiveRefusal);
  EXPECT_THROW(parse_teach(R"({"type":"teach","robot":"puma","action":"cartesian","axis":"w","delta":0.1})"),
               LiveRefusal);
  EXPECT_THROW(parse_teach(R"({"type":"teach","robot":"puma","action":"joints","joints":[0,"a"]})"), LiveRefusal);
}

}  // namespace
}  // namespace cellwright::cell
