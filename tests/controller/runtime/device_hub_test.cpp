// Device control as the runtime runs it (device_hub.hpp): commands from task control's queue executed on the I/O
// units, a status back for each, the devices' states in the log, and the faults a real unit brings (a failed request,
// a machine that never finishes, a photo-eye that sees a part the model does not have), each ending in a status, never
// a hang. The unit is the MemoryIo test double, driven by the test between turns.
#include "cellwright/runtime/device_hub.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cellwright/drivers/memory_io.hpp"
#include "controller/runtime/device_primitive.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

using cellwright::testing::device_primitive;
constexpr auto device = device_primitive;

// The paper's I/O list on one unit: coil 0 input belt run, coil 2 mill start; input 0 the input stop eye, 2 mill
// busy, 3 mill done. The mill's fixture is at (0, 0.6, 0.43), the eye looks at (0.6, -0.55, 0.5).
struct Cell {
  drivers::MemoryIo io{3, 4, "unit1"};
  task::CompiledProgram program;
  MessageQueue<MotionCommand> inbox{8};
  MessageQueue<RobotStatus> statuses{8};
  EventLog log;
  SharedEnvironment env;
  std::unique_ptr<DeviceHub> hub;

  explicit Cell(bool real = false, RecoveryOptions recovery = {}) {
    program.robots = {"r1", "r2"};
    DeviceWiring belt{"input", 0, -1, -1, SimDuration{0}, DeviceKind::kConveyor, {0.6, -0.55, 0.5}};
    DeviceWiring eye{"input_eye", -1, 0, -1, seconds(60), DeviceKind::kSensor, {0.6, -0.55, 0.5}};
    DeviceWiring mill{"mill", 2, 3, 2, seconds(15), DeviceKind::kMachine, {0, 0.6, 0.43}};
    hub = std::make_unique<DeviceHub>(std::vector<IoUnit>{IoUnit{&io, real, {belt, eye, mill}}},
                                      std::map<std::string, std::string>{
                                          {"IN", "input"}, {"in_stop", "input_eye"}, {"M", "mill"}},
                                      program, inbox, statuses, log, env, std::move(recovery));
    hub->connect();
  }
  void send(std::size_t robot, std::size_t index, const task::Primitive& p) {
    ASSERT_EQ(inbox.try_push(MotionCommand{robot, index, p, 0, SimDuration{0}}), QueueStatus::ok);
  }
  std::vector<RobotStatus> take() {
    std::vector<RobotStatus> out;
    RobotStatus s;
    while (statuses.try_pop(s) == QueueStatus::ok) out.push_back(s);
    return out;
  }
  // The log's lines of one type.
  std::vector<std::string> lines(const std::string& type) const {
    std::vector<std::string> out;
    for (const std::string& l : log.lines()) {
      if (l.find("\"type\":\"" + type + "\"") != std::string::npos) out.push_back(l);
    }
    return out;
  }
  void part_at(const std::string& name, const Eigen::Vector3d& p) {
    env.write([&](EnvironmentModel& m) {
      WorkpieceState w;
      w.name = name;
      w.pose.translation() = p;
      m.workpieces.push_back(w);
    });
  }
};

TEST(DeviceHub, TheFirstTurnLogsEveryDevicesStateAndLaterTurnsOnlyChanges) {
  Cell c;
  c.io.write_coil(0, true);
  c.hub->step(milliseconds(10));
  EXPECT_EQ(c.lines("device"),
            (std::vector<std::string>{
                R"({"t":0.0100,"type":"device","device":"input","kind":"conveyor","state":"running","workpiece":""})",
                R"({"t":0.0100,"type":"device","device":"input_eye","kind":"sensor","state":"off","workpiece":""})",
                R"({"t":0.0100,"type":"device","device":"mill","kind":"machine","state":"idle","workpiece":""})"}));
  c.hub->step(milliseconds(20));
  EXPECT_EQ(c.lines("device").size(), 3u);
  c.io.set_input(0, true);
  c.hub->step(milliseconds(30));
  ASSERT_EQ(c.lines("device").size(), 4u);
  EXPECT_EQ(c.lines("device").back(),
            R"({"t":0.0300,"type":"device","device":"input_eye","kind":"sensor","state":"on","workpiece":""})");
}

TEST(DeviceHub, AMachineCycleOrderedByARobotIsReportedToTaskControlWithThePartProcessed) {
  Cell c;
  c.part_at("A", {0.01, 0.6, 0.46});
  c.send(1, 7, device("M", task::DeviceOp::kStart));
  c.hub->step(milliseconds(10));
  EXPECT_TRUE(c.io.coil(2));  // start set, waiting for busy
  EXPECT_TRUE(c.take().empty());
  c.io.set_input(2, true);
  c.hub->step(milliseconds(20));
  EXPECT_FALSE(c.io.coil(2));
  const auto done = c.take();
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].robot, 1u);
  EXPECT_EQ(done[0].index, 7u);
  EXPECT_EQ(done[0].outcome, CommandOutcome::kDone);
  EXPECT_THAT(c.lines("device").back(), HasSubstr(R"("device":"mill","kind":"machine","state":"busy","workpiece":"A")"));
  // The robot's command is in the log as its own, naming the unit.
  EXPECT_THAT(c.lines("command_start").at(0), HasSubstr(R"("robot":"r2","primitive":7,"command":"device M start")"));
  EXPECT_THAT(c.lines("command_start").at(0), HasSubstr(R"("detail":"unit1 mill")"));
  EXPECT_THAT(c.lines("command_end").at(0), HasSubstr(R"("ok":true)"));
}

TEST(DeviceHub, TwoDevicesWorkSideBySideAndOneDevicesCommandsOneAfterTheOther) {
  Cell c;
  c.send(0, 1, device("in_stop", task::DeviceOp::kAwaitOn));
  c.send(1, 2, device("IN", task::DeviceOp::kRun));
  c.hub->step(milliseconds(10));
  auto s = c.take();
  ASSERT_EQ(s.size(), 1u);  // the belt runs at once; the eye is still off
  EXPECT_EQ(s[0].robot, 1u);
  c.io.set_input(0, true);
  c.hub->step(milliseconds(20));
  s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].robot, 0u);
}

TEST(DeviceHub, AMachineNeverDoneStopsTheCellAtItsLimitNamingTheMachine) {
  Cell c;
  c.send(0, 4, device("M", task::DeviceOp::kAwaitDone));
  c.hub->step(seconds(1));
  c.hub->step(seconds(16));
  EXPECT_TRUE(c.take().empty());
  c.hub->step(seconds(17));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s[0].stop_cell);
  EXPECT_THAT(s[0].reason, HasSubstr("device_timeout: device mill: done (input 3) not seen within 15.000 s"));
  EXPECT_THAT(c.lines("fault_detected").at(0), HasSubstr(R"("symptom":"device_timeout")"));
  EXPECT_THAT(c.lines("diagnosis").at(0), HasSubstr(R"("action":"stop_cell")"));
  // Stopped: a later command is answered at once, not executed.
  c.send(1, 9, device("IN", task::DeviceOp::kRun));
  c.hub->step(seconds(18));
  EXPECT_FALSE(c.io.coil(0));
  EXPECT_EQ(c.take().at(0).outcome, CommandOutcome::kFailed);
}

TEST(DeviceHub, AFailedRequestIsTriedAgainAfterConnectingAgainThenTheCellIsStopped) {
  Cell c;
  c.hub->step(milliseconds(10));
  c.io.fail_next(drivers::IoStatus::disconnected);
  c.send(0, 3, device("IN", task::DeviceOp::kRun));
  c.hub->step(milliseconds(20));
  EXPECT_TRUE(c.take().empty());  // connected again: done again next turn
  EXPECT_THAT(c.lines("recovery_end").at(0), HasSubstr(R"("action":"retry","ok":true)"));
  c.hub->step(milliseconds(30));
  auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kDone);
  EXPECT_TRUE(c.io.coil(0));
  // A unit that keeps failing: after max_attempts the cell is stopped.
  c.send(0, 5, device("IN", task::DeviceOp::kStop));
  for (int i = 0; i < 8; ++i) c.io.fail_next(drivers::IoStatus::exception, 4);
  for (int i = 4; i < 12; ++i) c.hub->step(milliseconds(10 * i));
  s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s[0].stop_cell);
  EXPECT_THAT(s[0].reason, HasSubstr("io_failed: device input: "));
  EXPECT_THAT(s[0].reason, HasSubstr("on unit1 failed: exception"));
  EXPECT_THAT(c.lines("diagnosis").back(), HasSubstr(R"("cause":"io_unit_down","action":"stop_cell")"));
}

TEST(DeviceHub, ARealEyeSeeingAPartTheModelDoesNotHaveStopsTheCellAfterTheContradictionTime) {
  Cell c(true);
  c.hub->step(milliseconds(10));
  c.io.set_input(0, true);
  for (int i = 2; i <= 101; ++i) c.hub->step(milliseconds(10 * i));  // seen from 0.02 s: 0.99 s of it
  EXPECT_TRUE(c.lines("fault_detected").empty());
  c.hub->step(milliseconds(1020));
  ASSERT_EQ(c.lines("fault_detected").size(), 1u);
  EXPECT_THAT(c.lines("fault_detected")[0], HasSubstr(R"("symptom":"device_contradiction")"));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_TRUE(s[0].stop_cell);
  EXPECT_EQ(s[0].index, RobotStatus::kNoCommand);
}

TEST(DeviceHub, ARealEyeSeeingAPartTheModelHasIsNoFault) {
  Cell c(true);
  c.part_at("A", {0.59, -0.55, 0.53});
  c.io.set_input(0, true);
  for (int i = 1; i <= 300; ++i) c.hub->step(milliseconds(10 * i));
  EXPECT_TRUE(c.lines("fault_detected").empty());
  EXPECT_TRUE(c.take().empty());
}

TEST(DeviceHub, AStartThatFailedLeavesNoStartCoilOnOnceTheRunIsOver) {
  // Busy never comes: the start times out with its coil still set; the end of the run clears it, so that the next
  // run's start is a rising edge the machine sees.
  Cell c;
  c.send(0, 2, device("M", task::DeviceOp::kStart));
  c.hub->step(seconds(1));
  c.hub->step(seconds(17));
  ASSERT_EQ(c.take().size(), 1u);
  EXPECT_TRUE(c.io.coil(2));
  c.hub->close(false);
  EXPECT_FALSE(c.io.coil(2));
}

TEST(DeviceHub, TheStartStopsTheProgramsBeltsAndLogsEveryDevicesStateAtTheRunsFirstInstant) {
  // A report counts a device's time from the run's start: its first state must be there at 0, not at the first turn.
  // A belt left running (by a PLC, an earlier run) is stopped: the program's net starts it stopped.
  Cell c;
  ASSERT_TRUE(c.io.write_coil(0, true).ok());
  c.hub->start(SimDuration{0});
  EXPECT_FALSE(c.io.coil(0));
  EXPECT_THAT(c.lines("device").at(0), HasSubstr(R"("device":"input","kind":"conveyor","state":"stopped")"));
  ASSERT_EQ(c.lines("device").size(), 3u);
  for (const std::string& l : c.lines("device")) EXPECT_THAT(l, HasSubstr(R"({"t":0.0000,"type":"device")"));
  c.hub->step(milliseconds(10));
  EXPECT_EQ(c.lines("device").size(), 3u);
}

TEST(DeviceHub, AStopLeavesNoBeltRunningAndACompletedRunLeavesThemAsTheProgramDid) {
  {
    Cell c;
    c.send(0, 1, device("IN", task::DeviceOp::kRun));
    c.hub->step(milliseconds(10));
    ASSERT_TRUE(c.io.coil(0));
    c.hub->close(true);
    EXPECT_FALSE(c.io.coil(0));
  }
  Cell c;
  c.send(0, 1, device("IN", task::DeviceOp::kRun));
  c.hub->step(milliseconds(10));
  c.hub->close(false);
  EXPECT_TRUE(c.io.coil(0));
}

TEST(DeviceHub, AStartDoneAgainAfterAFailureDoesNotStartTheMachineTwice) {
  // The start coil was written, then the unit failed before busy was read: connected again, the command is begun
  // again. The machine is busy already (it took the first start): the start is only cleared, never written again.
  Cell c;
  c.hub->step(milliseconds(10));
  c.send(0, 2, device("M", task::DeviceOp::kStart));
  c.hub->step(milliseconds(20));  // busy and done read, start written; busy not yet on
  ASSERT_TRUE(c.io.coil(2));
  c.io.set_input(2, true);        // the mill is busy
  c.io.fail_next(drivers::IoStatus::disconnected);
  c.hub->step(milliseconds(30));  // the busy read fails: connected again
  ASSERT_THAT(c.lines("recovery_end").at(0), HasSubstr(R"("action":"retry","ok":true)"));
  const int writes = c.io.writes();
  c.hub->step(milliseconds(40));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kDone);
  EXPECT_FALSE(c.io.coil(2));
  EXPECT_EQ(c.io.writes(), writes + 1);  // the clear alone
}

TEST(DeviceHub, AShortCycleWhoseBusyFallsBetweenTwoReadsStillEndsTheStart) {
  // Busy came and went between two turns; done is new: the start was taken.
  Cell c;
  c.send(0, 2, device("M", task::DeviceOp::kStart));
  c.hub->step(milliseconds(10));
  ASSERT_TRUE(c.io.coil(2));
  c.io.set_input(3, true);
  c.hub->step(milliseconds(20));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kDone);
  EXPECT_FALSE(c.io.coil(2));
}

TEST(DeviceHub, ADeadUnitIsAskedOnceATurnNotOnceForEachOfItsDevices) {
  Cell c;
  c.hub->step(milliseconds(10));
  const int before = c.io.requests();
  c.io.fail_next(drivers::IoStatus::timeout);
  c.hub->step(milliseconds(20));  // the first read fails: the unit's two other devices are not read this turn
  EXPECT_EQ(c.io.requests(), before + 1);
  EXPECT_EQ(c.lines("fault_detected").size(), 1u);
}

TEST(DeviceHub, ATreeThatAnswersGoOnToADeviceFaultHasItDoneAgainOnlyMaxAttemptsTimes) {
  RecoveryOptions r;
  r.max_attempts = 2;
  r.tree = std::make_shared<DecisionTree>(DecisionTree::parse(R"(
io_failed: {cause: flaky_unit, action: go_on}
)", "test.yaml"));
  Cell c(false, r);
  c.send(0, 3, device("IN", task::DeviceOp::kRun));
  for (int i = 0; i < 3; ++i) c.io.fail_next(drivers::IoStatus::exception, 4);
  for (int i = 1; i <= 3; ++i) c.hub->step(milliseconds(10 * i));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s[0].stop_cell);
  EXPECT_EQ(c.lines("fault_detected").size(), 3u);
  EXPECT_THAT(c.lines("recovery_end").back(), HasSubstr("2 attempts failed: the cell is stopped"));
}

TEST(DeviceHub, ScatteredFailuresOfTheStateReadsDoNotAddUpToAStop) {
  // A unit that loses a request now and then over a long run: each is recovered, and none counts against the next.
  Cell c;
  for (int i = 0; i < 6; ++i) {
    c.io.fail_next(drivers::IoStatus::timeout);
    c.hub->step(seconds(2 * i + 1));  // the read fails: connected again
    c.hub->step(seconds(2 * i + 2));  // the reads come back
  }
  EXPECT_TRUE(c.take().empty());
  EXPECT_EQ(c.lines("fault_detected").size(), 6u);
  for (const std::string& l : c.lines("fault_detected")) EXPECT_THAT(l, HasSubstr(R"("robot":"","primitive":-1)"));
  EXPECT_THAT(c.lines("diagnosis").back(), HasSubstr(R"("action":"retry")"));
}

TEST(DeviceHub, WithRecoveryOffTheFirstFaultFailsTheCommand) {
  RecoveryOptions r;
  r.enabled = false;
  Cell c(false, r);
  c.io.fail_next(drivers::IoStatus::timeout);
  c.send(0, 3, device("IN", task::DeviceOp::kRun));
  c.hub->step(milliseconds(10));
  const auto s = c.take();
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].outcome, CommandOutcome::kFailed);
  EXPECT_FALSE(s[0].stop_cell);
}

}  // namespace
}  // namespace cellwright::runtime
