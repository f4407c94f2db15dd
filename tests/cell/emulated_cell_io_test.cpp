// EmulatedCell serving the twin's I/O on Modbus TCP (emulated_cell.hpp, "THE I/O, IN VIRTUAL TIME"), driven by
// pymodbus's client (not our code): in lock-step the World advances by one scan at each read of the discrete inputs
// and at no other request; what it refuses to build.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <exception>
#include <string>
#include <thread>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sim/emulated_cell.hpp"
#include "cellwright/common/error.hpp"
#include "drivers/modbus/python_peer.hpp"

namespace cellwright::cell {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::MatchesRegex;

Scenario exchange() { return load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml"); }

std::string error_of(const Scenario& s, std::vector<EmulatedController> controllers, EmulatedCellOptions o) {
  try {
    EmulatedCell cell(s, std::move(controllers), std::move(o), {"test", 0, 0});
  } catch (const InputError& e) {
    return e.what();
  }
  return "built";
}

TEST(EmulatedCellIo, LockStepAdvancesTheTwinOneScanPerReadOfTheDiscreteInputsOnly) {
  if (const std::string why = testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  const Scenario s = exchange();
  EmulatedCellOptions o;
  o.io = emulate::ModbusServerOptions{};  // 127.0.0.1, a free port, unit 1
  o.lockstep = 20ms;
  EmulatedCell cell(s, {}, std::move(o), {"test", 0, 0});
  std::exception_ptr failed;
  std::thread runner([&] {
    try {
      cell.run();
    } catch (...) {
      failed = std::current_exception();
    }
  });
  const std::string endpoint = cell.io_endpoint();
  ASSERT_THAT(endpoint, MatchesRegex("127\\.0\\.0\\.1:[0-9]+"));
  {
    testing::PythonPeer plc({"client", endpoint.substr(endpoint.rfind(':') + 1)});
    ASSERT_EQ(plc.first_line(), "ready");
    EXPECT_EQ(plc.ask("read_coils 0 3"), "ok 1 1 0");
    EXPECT_EQ(plc.ask("write_coil 0 0"), "ok");
    EXPECT_EQ(plc.ask("write_coils 1 0,0"), "ok");
    EXPECT_EQ(cell.sim_time(), 0ns) << "coils read and written: the twin has not moved";
    for (int i = 0; i < 3; ++i) EXPECT_THAT(plc.ask("read_inputs 0 4"), MatchesRegex("ok [01] [01] [01] [01]"));
    EXPECT_EQ(cell.sim_time(), 60ms);
    EXPECT_EQ(plc.ask("read_coils 0 3"), "ok 0 0 0");
    EXPECT_EQ(cell.sim_time(), 60ms);
    EXPECT_EQ(plc.ask("read_inputs 0 1"), "ok 0");
    EXPECT_EQ(cell.sim_time(), 80ms);
  }
  cell.stop();
  runner.join();
  if (failed) std::rethrow_exception(failed);
}

TEST(EmulatedCellIo, RefusesNothingToEmulateALockStepWithoutIoOrWithRobotsAndAScanOffTheTimestep) {
  const Scenario s = exchange();
  EXPECT_THAT(error_of(s, {}, {}), HasSubstr("nothing to emulate"));
  EmulatedCellOptions no_io;
  no_io.lockstep = 10ms;
  EXPECT_THAT(error_of(s, {}, no_io), HasSubstr("lock-step is for the I/O"));
  EmulatedCellOptions with_robot;
  with_robot.io = emulate::ModbusServerOptions{};
  with_robot.lockstep = 10ms;
  EXPECT_THAT(error_of(s, {parse_emulated_controller("puma=val2:/tmp/puma", {"test", 0, 0})}, with_robot),
              HasSubstr("lock-step serves the I/O alone"));
  EmulatedCellOptions odd_scan;
  odd_scan.io = emulate::ModbusServerOptions{};
  odd_scan.lockstep = 7ms;
  EXPECT_THAT(error_of(s, {}, odd_scan),
              HasSubstr("the lock-step scan must be a positive whole number of the cell's timestep (0.005 s)"));
}

TEST(EmulatedCellIo, ParsesWhereTheIoIsServed) {
  const emulate::ModbusServerOptions a = parse_served_io("modbus:127.0.0.1:1502/7", {"--io", 0, 0});
  EXPECT_EQ(a.host, "127.0.0.1");
  EXPECT_EQ(a.port, 1502);
  EXPECT_EQ(a.unit, 7);
  const emulate::ModbusServerOptions b = parse_served_io("modbus:0.0.0.0:0", {"--io", 0, 0});
  EXPECT_EQ(b.port, 0);
  EXPECT_EQ(b.unit, 1);
  for (const char* bad : {"127.0.0.1:502", "modbus:127.0.0.1", "modbus::502", "modbus:h:502/", "modbus:h:502/256",
                          "modbus:h:-1", "modbus:h:502x"}) {
    EXPECT_THROW(parse_served_io(bad, {"--io", 0, 0}), InputError) << bad;
  }
}

}  // namespace
}  // namespace cellwright::cell
