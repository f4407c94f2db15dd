// Helpers shared by the simulation tests: the paper's cell, a World with simulation drivers, and running the
// simulation until a command finishes.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "twin/mujoco_fixture.hpp"

namespace cellwright::twin::sim::testing {

using namespace std::chrono_literals;

inline const std::filesystem::path kSource = CW_SOURCE_DIR;

// The paper's cell, loaded once per test program.
inline const models::CellDescription& paper_cell() {
  static const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
  return cell;
}

// The control period the runtime uses.
inline constexpr std::chrono::nanoseconds kPeriod = 10ms;

// Advances `world` period by period until command `id` of `driver` is done or failed, or `limit` of simulation time
// has passed; calls `each` (if given) after every period. Returns the command's last status.
inline drivers::CommandStatus run_until_finished(World& world, drivers::RobotDriver& driver, drivers::CommandId id,
                                                 std::chrono::nanoseconds limit = 20s,
                                                 const std::function<void()>& each = {}) {
  const auto end = world.now() + limit;
  drivers::CommandStatus status = driver.poll(id);
  while (world.now() < end) {
    world.advance(kPeriod);
    if (each) each();
    status = driver.poll(id);
    if (status.phase == drivers::CommandPhase::done || status.phase == drivers::CommandPhase::failed) break;
  }
  return status;
}

// Connects, homes and activates a driver; fails the test if any step does not work.
inline void bring_up(World& world, drivers::RobotDriver& driver) {
  ASSERT_EQ(driver.connect(), drivers::ErrorCode::none);
  const drivers::Submitted home = driver.home();
  ASSERT_TRUE(home.accepted()) << home.message;
  const drivers::CommandStatus s = run_until_finished(world, driver, home.id);
  ASSERT_EQ(s.phase, drivers::CommandPhase::done) << s.message;
  ASSERT_EQ(driver.activate(), drivers::ErrorCode::none);
}

// Submits a command and runs until it finishes; returns its status.
inline drivers::CommandStatus execute(World& world, drivers::RobotDriver& driver, const drivers::Command& command,
                                      std::chrono::nanoseconds limit = 20s, const std::function<void()>& each = {}) {
  const drivers::Submitted s = driver.submit(command);
  if (!s.accepted()) return {0, drivers::CommandPhase::failed, s.error, "refused: " + s.message};
  return run_until_finished(world, driver, s.id, limit, each);
}

// A robot's base pose in the world.
inline Eigen::Isometry3d base_of(const World& world, const std::string& robot) {
  return world.scene().cell().find_robot(robot)->base.transform();
}

// The tool pose (robot base frame) that grasps at world point `p` from above, fingers closing across `yaw`.
inline Eigen::Isometry3d down_at(const World& world, const std::string& robot, const Eigen::Vector3d& p, double yaw) {
  const Eigen::Isometry3d base = base_of(world, robot);
  return base.inverse() * models::grasp_pose(p, models::Approach::kDown, yaw, base);
}

inline drivers::MovePose pose_move(const Eigen::Isometry3d& pose, drivers::Path path, double speed = 0.5) {
  drivers::MovePose m;
  m.pose = pose;
  m.path = path;
  m.speed = speed;
  return m;
}

inline drivers::Grip grip(drivers::Grip::Action action) {
  drivers::Grip g;
  g.action = action;
  return g;
}

// A fixture with a World of the paper's cell (world_), checked for MuJoCo's warnings when the test ends.
class PaperCellTest : public cellwright::testing::MujocoTest {
 protected:
  void SetUp() override {
    MujocoTest::SetUp();
    world_ = std::make_unique<World>(build_scene(paper_cell()));
  }
  void TearDown() override {
    expect_no_data_warnings(world_->data());
    EXPECT_TRUE(world_->drain_warnings().empty());
    MujocoTest::TearDown();
  }

  std::unique_ptr<World> world_;
};

}  // namespace cellwright::twin::sim::testing
