// ReplicaMirror: the twin's copies (here ScriptedDrivers claiming what a SimDriver claims) of robots whose robot
// control runs in an agent, following the states the agents publish. The test advances the copies as the simulation
// thread would and waits (bounded) for the mirror's thread to react, as a user of the twin would see it: each copy
// goes where its robot was measured and grips as its robot took and let go of parts, in the agent's order; a tool pose
// becomes the joints nearest the copy; a handed-over part is let go of only once the other copy has closed on it;
// a copy far behind skips older positions, never a grip.
#include "cellwright/twin/sim/replica_mirror.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/drivers/scripted_driver.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::twin::sim {
namespace {

using namespace std::chrono_literals;
using drivers::Grip;
using drivers::MoveJoints;
using drivers::ScriptedDriver;
using drivers::ScriptedDriverConfig;

const models::KinematicChain& puma() {
  static const models::KinematicChain chain =
      models::KinematicChain::from_urdf_file(std::string(models::models_dir()) + "/urdf/puma560.urdf");
  return chain;
}

std::vector<double> home_joints() {
  constexpr double kDeg = std::numbers::pi / 180.0;
  return {0, 84 * kDeg, -192 * kDeg, 0, -72 * kDeg, 90 * kDeg};
}

std::vector<double> near_home(double k) {
  std::vector<double> q = home_joints();
  for (std::size_t i = 0; i < q.size(); ++i) q[i] += k * (i % 2 == 0 ? 0.1 : -0.08);
  return q;
}

ScriptedDriverConfig copy_config() {
  ScriptedDriverConfig c;
  c.where = {"cell.yaml", 19, 5};
  drivers::Capabilities& caps = c.capabilities;
  caps.joints = 6;
  caps.joint_control = caps.cartesian_control = caps.linear_motion = caps.full_orientation = true;
  caps.gripper = caps.gripper_width = caps.gripper_force = true;
  caps.gripper_max_width = 0.08;
  caps.gripper_max_force = 40;
  caps.queue_depth = 4;
  caps.reads_joints = caps.reads_pose = caps.reads_while_moving = true;
  c.command_ticks = 5;
  c.home_joints = home_joints();
  c.home_pose = puma().forward(Eigen::Map<const Eigen::VectorXd>(c.home_joints.data(), 6));
  return c;
}

// The copies, and the mirror following them.
struct Cell {
  explicit Cell(std::size_t n) {
    std::vector<ReplicaMirror::Copy> copies;
    for (std::size_t i = 0; i < n; ++i) {
      drivers.push_back(std::make_unique<ScriptedDriver>(copy_config()));
      copies.push_back({"r" + std::to_string(i), drivers.back().get(), puma(), home_joints()});
    }
    mirror = std::make_unique<ReplicaMirror>(std::move(copies));
    mirror->start();
  }
  // Advances the copies `only` (all when empty) a tick at a time, giving the mirror's thread time to answer each
  // notification, until `done` holds; false after 5 s of wall time.
  bool advance_until(const std::function<bool()>& done, const std::vector<std::size_t>& only = {}) {
    const auto until = std::chrono::steady_clock::now() + 5s;
    while (!done()) {
      if (std::chrono::steady_clock::now() > until) return false;
      for (std::size_t i = 0; i < drivers.size(); ++i) {
        if (only.empty() || std::find(only.begin(), only.end(), i) != only.end()) drivers[i]->advance(1);
      }
      std::this_thread::yield();
    }
    return true;
  }
  std::vector<drivers::Command> commands(std::size_t i) const {
    std::vector<drivers::Command> out;
    for (const auto& [id, c] : drivers[i]->accepted()) out.push_back(c);
    return out;
  }
  std::vector<std::unique_ptr<ScriptedDriver>> drivers;
  std::unique_ptr<ReplicaMirror> mirror;
};

ReplicaState joints_holding(std::vector<double> q, std::optional<std::string> holding = std::nullopt) {
  ReplicaState s;
  s.joints = std::move(q);
  s.holding = std::move(holding);
  return s;
}

bool is_move_to(const drivers::Command& c, const std::vector<double>& q, double tolerance = 1e-9) {
  const auto* m = std::get_if<MoveJoints>(&c);
  if (m == nullptr || m->positions.size() != q.size()) return false;
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (std::abs(m->positions[i] - q[i]) > tolerance) return false;
  }
  return true;
}

bool is_grip(const drivers::Command& c, Grip::Action action) {
  const auto* g = std::get_if<Grip>(&c);
  return g != nullptr && g->action == action;
}

TEST(ReplicaMirror, ACopyGoesWhereItsRobotWasMeasuredAndGripsAsItTookAndLetGoInTheAgentsOrder) {
  Cell cell(1);
  ReplicaMirror& m = *cell.mirror;
  m.push(0, joints_holding(home_joints()));        // where it stands: nothing to do
  m.push(0, joints_holding(near_home(1)));
  m.push(0, joints_holding(near_home(1), "A"));   // closed on A there
  m.push(0, joints_holding(near_home(2), "A"));
  m.push(0, joints_holding(near_home(2)));         // let go of A there
  ASSERT_TRUE(cell.advance_until([&] { return m.idle(); }));
  const std::vector<drivers::Command> c = cell.commands(0);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_TRUE(is_move_to(c[0], near_home(1)));
  EXPECT_TRUE(is_grip(c[1], Grip::Action::close));
  EXPECT_TRUE(is_move_to(c[2], near_home(2)));
  EXPECT_TRUE(is_grip(c[3], Grip::Action::open));
  EXPECT_TRUE(m.idle());
  const ReplicaMirror::Counts n = m.counts();
  EXPECT_EQ(n.states, 5);
  EXPECT_EQ(n.moves, 2);
  EXPECT_EQ(n.grips, 2);
  EXPECT_EQ(n.misses, 0);
  EXPECT_FALSE(cell.drivers[0]->gripper_closed());
}

TEST(ReplicaMirror, AToolPoseBecomesTheJointsNearestWhereTheCopyStandsAndAnUnreachableOneIsMissed) {
  Cell cell(1);
  ReplicaMirror& m = *cell.mirror;
  const std::vector<double> q = near_home(1.5);
  ReplicaState s;
  s.tool_in_base = puma().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), 6));
  m.push(0, s);
  ReplicaState far;
  far.tool_in_base = Eigen::Isometry3d(Eigen::Translation3d(5, 5, 5));  // 5 m out: no arm of the cell reaches it
  m.push(0, far);
  ASSERT_TRUE(cell.advance_until([&] { return m.idle(); }));
  const std::vector<drivers::Command> c = cell.commands(0);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_TRUE(is_move_to(c[0], q, 1e-3));
  EXPECT_EQ(m.counts().misses, 1);
}

TEST(ReplicaMirror, AHandedOverPartIsLetGoOfOnlyOnceTheOtherCopyHasClosedOnIt) {
  Cell cell(2);
  ReplicaMirror& m = *cell.mirror;
  // r0 holds A; r1 closes on it (its agent's state came first), then r0 lets go. r1's copy is held back (not
  // advanced): r0's copy must not open before r1's has closed.
  m.push(0, joints_holding(near_home(1), "A"));
  ASSERT_TRUE(cell.advance_until([&] { return cell.commands(0).size() == 2 && m.counts().grips == 1; }, {0}));
  m.push(1, joints_holding(near_home(-1), "A"));
  m.push(0, joints_holding(near_home(1)));
  ASSERT_TRUE(cell.advance_until([&] { return m.counts().waits > 0; }, {0}));
  for (int i = 0; i < 50; ++i) cell.drivers[0]->advance(1);
  for (const drivers::Command& c : cell.commands(0)) EXPECT_FALSE(is_grip(c, Grip::Action::open));
  // r1's copy comes up, moves and closes; then r0's opens.
  ASSERT_TRUE(cell.advance_until([&] { return m.idle(); }));
  const std::vector<drivers::Command> r0 = cell.commands(0), r1 = cell.commands(1);
  ASSERT_EQ(r1.size(), 2u);
  EXPECT_TRUE(is_grip(r1[1], Grip::Action::close));
  ASSERT_EQ(r0.size(), 3u);
  EXPECT_TRUE(is_grip(r0[2], Grip::Action::open));
  EXPECT_TRUE(cell.drivers[1]->gripper_closed());
  EXPECT_FALSE(cell.drivers[0]->gripper_closed());
}

TEST(ReplicaMirror, ACopyFarBehindSkipsOlderPositionsButNeverAGrip) {
  Cell cell(1);
  ReplicaMirror& m = *cell.mirror;
  // 40 positions (each 0.015 rad from the last, beyond the tolerance) and a grip in the middle, pushed before the
  // copy has even come up.
  for (int i = 1; i <= 40; ++i) {
    m.push(0, joints_holding(near_home(0.15 * i), i >= 20 ? std::optional<std::string>("A") : std::nullopt));
  }
  ASSERT_TRUE(cell.advance_until([&] { return m.idle(); }));
  const std::vector<drivers::Command> c = cell.commands(0);
  int moves = 0, closes = 0;
  for (const drivers::Command& x : c) {
    moves += std::holds_alternative<MoveJoints>(x) ? 1 : 0;
    closes += is_grip(x, Grip::Action::close) ? 1 : 0;
  }
  EXPECT_EQ(closes, 1);
  EXPECT_LE(moves, static_cast<int>(ReplicaMirror::kMaxBehind));
  ASSERT_FALSE(c.empty());
  EXPECT_TRUE(is_move_to(c.back(), near_home(0.15 * 40)));  // the newest position is never skipped
  EXPECT_EQ(m.counts().misses, 40 - moves);
}

}  // namespace
}  // namespace cellwright::twin::sim
