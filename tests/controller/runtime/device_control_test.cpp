// Device control on a DigitalIo (issue 26), against the MemoryIo test double: each device primitive's requests, and
// the faults it ends with instead of hanging (a failed request, an input that never comes).
#include "cellwright/runtime/device_control.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cellwright/drivers/memory_io.hpp"
#include "controller/runtime/device_primitive.hpp"

namespace cellwright::runtime {
namespace {

using std::chrono::seconds;
using ::testing::HasSubstr;

using cellwright::testing::device_primitive;
constexpr auto device = device_primitive;

// The paper's I/O list: coils 0 input belt run, 2 mill start; inputs 0 input stop eye, 2 mill busy, 3 mill done.
struct Unit {
  drivers::MemoryIo io{3, 4, "unit1"};
  DeviceControl control{io,
                        {{"IN", 0, -1, -1, SimDuration{0}},
                         {"in_stop", -1, 0, -1, seconds(30)},
                         {"mill", 2, 3, 2, seconds(12)}}};
  Unit() { EXPECT_TRUE(io.connect().ok()); }
};

TEST(DeviceControl, AMachineCycleSetsStartSeesBusyClearsStartThenWaitsForDone) {
  Unit u;
  u.control.begin(device("mill", task::DeviceOp::kStart), seconds(0));
  EXPECT_EQ(u.control.poll(seconds(0)).outcome, DeviceOutcome::kPending);
  EXPECT_TRUE(u.io.coil(2));  // start set, busy not seen yet
  u.io.set_input(2, true);
  EXPECT_EQ(u.control.poll(seconds(1)).outcome, DeviceOutcome::kDone);
  EXPECT_FALSE(u.io.coil(2));  // start cleared once the machine answered busy
  u.control.begin(device("mill", task::DeviceOp::kAwaitDone), seconds(1));
  EXPECT_EQ(u.control.poll(seconds(5)).outcome, DeviceOutcome::kPending);
  u.io.set_input(3, true);
  EXPECT_EQ(u.control.poll(seconds(9)).outcome, DeviceOutcome::kDone);
}

TEST(DeviceControl, ConveyorRunAndStopWriteItsRunCoil) {
  Unit u;
  u.control.begin(device("IN", task::DeviceOp::kAccumulate), seconds(0));
  EXPECT_EQ(u.control.poll(seconds(0)).outcome, DeviceOutcome::kDone);
  EXPECT_TRUE(u.io.coil(0));
  u.control.begin(device("IN", task::DeviceOp::kStop), seconds(1));
  EXPECT_EQ(u.control.poll(seconds(1)).outcome, DeviceOutcome::kDone);
  EXPECT_FALSE(u.io.coil(0));
  u.control.begin(device("in_stop", task::DeviceOp::kAwaitOn), seconds(1));
  EXPECT_EQ(u.control.poll(seconds(2)).outcome, DeviceOutcome::kPending);
  u.io.set_input(0, true);
  EXPECT_EQ(u.control.poll(seconds(3)).outcome, DeviceOutcome::kDone);
}

TEST(DeviceControl, AMachineNeverDoneIsAFaultAfterItsLimit) {
  Unit u;
  u.control.begin(device("mill", task::DeviceOp::kAwaitDone), seconds(0));
  EXPECT_EQ(u.control.poll(seconds(12)).outcome, DeviceOutcome::kPending);
  const DeviceStep s = u.control.poll(seconds(13));
  EXPECT_EQ(s.outcome, DeviceOutcome::kFault);
  EXPECT_EQ(s.reason, "device mill: done (input 3) not seen within 12.000 s");
}

TEST(DeviceControl, AFailedRequestIsAFaultNamingTheDeviceAndTheUnit) {
  Unit u;
  u.io.fail_next(drivers::IoStatus::exception, 2);
  u.control.begin(device("IN", task::DeviceOp::kRun), seconds(0));
  DeviceStep s = u.control.poll(seconds(0));
  EXPECT_EQ(s.outcome, DeviceOutcome::kFault);
  EXPECT_THAT(s.reason, HasSubstr("device IN: writing run (coil 0) on unit1 failed"));
  EXPECT_THAT(s.reason, HasSubstr("exception"));
  u.io.fail_next(drivers::IoStatus::disconnected);
  u.control.begin(device("in_stop", task::DeviceOp::kAwaitOn), seconds(1));
  s = u.control.poll(seconds(1));
  EXPECT_EQ(s.outcome, DeviceOutcome::kFault);
  EXPECT_THAT(s.reason, HasSubstr("device in_stop: reading photo-eye (input 0)"));
  EXPECT_THAT(s.reason, HasSubstr("disconnected"));
}

TEST(DeviceControl, ADeviceTheUnitDoesNotWireIsAFault) {
  Unit u;
  u.control.begin(device("OUT", task::DeviceOp::kRun), seconds(0));
  const DeviceStep s = u.control.poll(seconds(0));
  EXPECT_EQ(s.outcome, DeviceOutcome::kFault);
  EXPECT_THAT(s.reason, HasSubstr("device OUT: not wired to"));
}

}  // namespace
}  // namespace cellwright::runtime
