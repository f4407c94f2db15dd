// The fixture of robot control's unit tests (robot_control_test.cpp: the contract of one command without recovery;
// robot_recovery_test.cpp: what recovery does instead of failing). One RobotControl driven directly, turn by turn, as
// the lock-step runtime would: the simulation's turn (the scripted controller runs one tick, the model's clock moves
// on), then robot control's step(). The PUMA of the paper's cell sits behind a ScriptedDriver (through ReadbackDriver,
// which can misreport read-backs, and a FaultyDriver when faults_ is set).
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "cellwright/drivers/faulty_driver.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "cellwright/task/compile.hpp"
#include "controller/runtime/readback_driver.hpp"
#include "controller/runtime/scripted_cell.hpp"

namespace cellwright::runtime::test {

using cellwright::testing::paper_cell;
using cellwright::testing::ReadbackDriver;
using cellwright::testing::scripted_arm;
using std::chrono::milliseconds;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using K = task::TargetKind;

inline constexpr std::uint64_t kMoveTicks = 120;
inline constexpr std::uint64_t kGripTicks = 40;

inline task::Primitive move(K kind, std::string object = "") {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kMove;
  p.target = {kind, std::move(object)};
  return p;
}

inline task::Primitive close_on(std::string workpiece) {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kClose;
  p.workpiece = std::move(workpiece);
  return p;
}

inline task::Primitive open_from(std::string workpiece) {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kOpen;
  p.workpiece = std::move(workpiece);
  return p;
}

// The primitives robot control executes (move, open, close) of program robot `robot` in the paper's exchange
// (scenes/exchange.task, Table 1), with their indices in that robot's program.
inline std::vector<std::pair<std::size_t, task::Primitive>> exchange_motions(const std::string& robot) {
  const task::CompiledProgram program = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/exchange.task");
  std::vector<std::pair<std::size_t, task::Primitive>> out;
  for (const task::RobotProgram& p : program.programs) {
    if (p.robot != robot) continue;
    for (std::size_t i = 0; i < p.primitives.size(); ++i) {
      const task::PrimitiveKind k = p.primitives[i].kind;
      if (k == task::PrimitiveKind::kMove || k == task::PrimitiveKind::kOpen || k == task::PrimitiveKind::kClose) {
        out.emplace_back(i, p.primitives[i]);
      }
    }
  }
  return out;
}

inline Eigen::VectorXd to_eigen(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

class RobotControlTest : public ::testing::Test {
 protected:
  RobotControlTest()
      : spec_(*paper_cell().find_robot("puma")),
        chain_(models::KinematicChain::from_urdf_file(spec_.urdf)),
        env_(make_environment_model(paper_cell())),
        inbox_(4),
        statuses_(8) {}

  // The PUMA's scripted controller as the runtime's tests have it: joint moves, a gripper with a force, joint
  // read-backs queued behind the motions.
  drivers::ScriptedDriverConfig joint_arm() const { return scripted_arm(spec_, {kMoveTicks, kGripTicks}); }

  // A Cartesian controller (as a Movemaster): tool poses only, straight-line moves, the tool pose read back.
  drivers::ScriptedDriverConfig pose_arm() const {
    drivers::ScriptedDriverConfig c = joint_arm();
    c.capabilities.joint_control = false;
    c.capabilities.cartesian_control = true;
    c.capabilities.linear_motion = true;
    c.capabilities.full_orientation = true;
    c.capabilities.reads_joints = false;
    c.capabilities.reads_pose = true;
    c.home_pose = chain_.forward(to_eigen(spec_.home));
    return c;
  }

  // Robot control of program robot r1 (the PUMA) over `config`'s scripted controller (behind a FaultyDriver when
  // faults_ is set); connected unless told not to. Without recovery unless recovery_ is set: these tests check the
  // contract of one command (robot_recovery_test.cpp checks what recovery does instead of failing).
  bool recovery_ = false;
  std::map<std::string, std::string> classes_;  // workpiece classes of the program: label -> cell location
  void make(drivers::ScriptedDriverConfig config, MotionOptions options = {}, bool connect = true) {
    options.recovery.enabled = recovery_;
    scripted_ = std::make_unique<drivers::ScriptedDriver>(std::move(config));
    driver_ = std::make_unique<ReadbackDriver>(*scripted_);
    drivers::RobotDriver* owner = driver_.get();
    if (faults_) {
      faulty_ = std::make_unique<drivers::FaultyDriver>(*driver_, *faults_);
      owner = faulty_.get();
    }
    NameMap names;
    names.robots = {{"r1", "puma"}, {"r2", "melfa"}};
    names.objects = {{"A", "A"}, {"B", "output_drop"}};
    names.classes = classes_;
    control_ = std::make_unique<RobotControl>(0, "r1", "puma", *owner, chain_, spec_.grip_force, names, env_, inbox_,
                                              statuses_, log_, options, await_fresh_truth_);
    if (connect) control_->connect();
  }

  // One lock-step period of 1 ms.
  void turn() {
    scripted_->advance(1);
    now_ += milliseconds(1);
    env_.write([&](EnvironmentModel& m) { m.time = now_; });
    control_->step(now_);
  }

  template <typename Pred>
  bool turn_until(Pred pred, int max_turns = 3000) {
    for (int i = 0; i < max_turns; ++i) {
      if (pred()) return true;
      turn();
    }
    return pred();
  }

  void bring_up() {
    ASSERT_TRUE(turn_until([&] { return control_->phase() == RobotPhase::kReady; }));
  }

  void send(std::size_t index, task::Primitive p) {
    MotionCommand c;
    c.robot = 0;
    c.index = index;
    c.primitive = std::move(p);
    c.sent = now_;
    ASSERT_EQ(inbox_.try_push(std::move(c)), QueueStatus::ok);
  }

  std::optional<RobotStatus> status() {
    RobotStatus s;
    if (statuses_.try_pop(s) != QueueStatus::ok) return std::nullopt;
    return s;
  }

  // Turns until robot control reports a status; fails the test when none comes.
  RobotStatus next_status(int max_turns = 3000) {
    std::optional<RobotStatus> s;
    for (int i = 0; i < max_turns && !s; ++i) {
      turn();
      s = status();
    }
    EXPECT_TRUE(s.has_value()) << "no status after " << max_turns << " turns";
    return s.value_or(RobotStatus{});
  }

  // Sends `p` as primitive `index` and runs it to its status.
  RobotStatus run(std::size_t index, task::Primitive p) {
    send(index, std::move(p));
    return next_status();
  }

  std::vector<nlohmann::json> events(const std::string& type) const {
    std::vector<nlohmann::json> out;
    for (const std::string& line : log_.lines()) {
      nlohmann::json j = nlohmann::json::parse(line);
      if (j["type"] == type) out.push_back(std::move(j));
    }
    return out;
  }
  std::vector<std::string> sensor_conditions() const {
    std::vector<std::string> out;
    for (const auto& e : events("sensor")) out.push_back(e["condition"]);
    return out;
  }

  RobotState robot() const {
    return env_.read([](const EnvironmentModel& m) { return *m.find_robot("puma"); });
  }
  WorkpieceState part(const std::string& name) const {
    return env_.read([&](const EnvironmentModel& m) { return *m.find_workpiece(name); });
  }
  // What the grip sensor says: a part's name, "" for nothing, nullopt for "cannot tell".
  void set_fingers(std::optional<std::string> between) {
    std::optional<GripReading> grip;
    if (between) grip = GripReading::of(*between);
    env_.write([&](EnvironmentModel& m) { m.find_robot("puma")->grip = std::move(grip); });
  }

  // The driver commands the scripted controller accepted, in order.
  std::vector<drivers::Command> sent() const {
    std::vector<drivers::Command> out;
    for (auto& [id, c] : scripted_->accepted()) out.push_back(c);
    return out;
  }

  const models::RobotSpec& spec_;
  const models::KinematicChain chain_;
  SharedEnvironment env_;
  MessageQueue<MotionCommand> inbox_;
  MessageQueue<RobotStatus> statuses_;
  EventLog log_;
  SimDuration now_{0};
  std::unique_ptr<drivers::ScriptedDriver> scripted_;
  std::unique_ptr<ReadbackDriver> driver_;
  std::optional<drivers::FaultPlan> faults_;
  bool await_fresh_truth_ = false;
  std::unique_ptr<drivers::FaultyDriver> faulty_;
  std::unique_ptr<RobotControl> control_;  // last: it refers to everything above
};

}  // namespace cellwright::runtime::test
