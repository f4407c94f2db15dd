// CellIoEmulator: the paper's cell I/O as a PLC would hold it, on a clock the test turns: the mill's handshake (start
// on a rising edge while idle, busy for the process time, then done until the part is taken out), the belts' coils,
// the photo-eyes' script, and the DigitalIo contract (closed unit, addresses it does not have).
#include "cellwright/emulate/cell_io_emulator.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace cellwright::emulate {
namespace {

using drivers::IoStatus;

CellIoEmulatorOptions options(double process_time, double take_out_after, std::vector<InputChange> script = {}) {
  CellIoEmulatorOptions o;
  o.process_time = process_time;
  o.take_out_after = take_out_after;
  o.script = std::move(script);
  return o;
}

// The emulator on the test's clock `t`, connected.
struct Rig {
  double t = 0;
  CellIoEmulator io;
  Rig(double process_time, double take_out_after, std::vector<InputChange> script = {})
      : io(with_clock(options(process_time, take_out_after, std::move(script)), &t)) {
    EXPECT_TRUE(io.connect().ok());
  }
  static CellIoEmulatorOptions with_clock(CellIoEmulatorOptions o, double* t) {
    o.clock = [t] { return *t; };
    return o;
  }
  // Inputs 0..3: eye 0, eye 1, busy, done.
  std::vector<bool> inputs() {
    std::vector<bool> v;
    EXPECT_TRUE(io.read_inputs(0, 4, v).ok());
    return v;
  }
};

const std::vector<bool> kIdle{false, false, false, false}, kBusy{false, false, true, false},
    kDone{false, false, false, true};

TEST(CellIoEmulator, AStartEdgeMakesTheMillBusyForTheProcessTimeThenDoneUntilTakenOut) {
  Rig r(5, 2);
  EXPECT_EQ(r.inputs(), kIdle);
  r.t = 1;
  ASSERT_TRUE(r.io.write_coil(2, true).ok());
  EXPECT_EQ(r.inputs(), kBusy);
  ASSERT_TRUE(r.io.write_coil(2, false).ok());  // the controller clears start once it sees busy
  r.t = 5.99;
  EXPECT_EQ(r.inputs(), kBusy);
  r.t = 6.0;
  EXPECT_EQ(r.inputs(), kDone);
  r.t = 7.99;
  EXPECT_EQ(r.inputs(), kDone);
  r.t = 8.0;
  EXPECT_EQ(r.inputs(), kIdle) << "done clears take_out_after seconds after it rose";
  EXPECT_EQ(r.io.cycles(), 1);
}

TEST(CellIoEmulator, TheTimersRunWithoutRequestsBetween) {
  Rig r(5, 2);
  ASSERT_TRUE(r.io.write_coil(2, true).ok());
  r.t = 100;  // nobody asked for a minute and more: the mill went through done and was emptied
  EXPECT_EQ(r.inputs(), kIdle);
}

TEST(CellIoEmulator, AStartWhileBusyOrDoneIsIgnoredAndAHeldStartIsNoEdge) {
  Rig r(5, -1);
  ASSERT_TRUE(r.io.write_coil(2, true).ok());
  ASSERT_TRUE(r.io.write_coil(2, false).ok());
  r.t = 2;
  ASSERT_TRUE(r.io.write_coil(2, true).ok());  // while busy
  ASSERT_TRUE(r.io.write_coil(2, false).ok());
  r.t = 6;
  EXPECT_EQ(r.inputs(), kDone) << "the second start did not lengthen the cycle";
  ASSERT_TRUE(r.io.write_coil(2, true).ok());  // while done
  r.t = 60;
  EXPECT_EQ(r.inputs(), kDone) << "without take_out_after, done stays until the part is taken out";
  EXPECT_EQ(r.io.cycles(), 1);
  r.io.take_out();
  EXPECT_EQ(r.inputs(), kIdle);
  ASSERT_TRUE(r.io.write_coil(2, true).ok());  // held on since t = 6: no rising edge
  EXPECT_EQ(r.inputs(), kIdle);
  ASSERT_TRUE(r.io.write_coil(2, false).ok());
  ASSERT_TRUE(r.io.write_coil(2, true).ok());
  EXPECT_EQ(r.inputs(), kBusy);
  EXPECT_EQ(r.io.cycles(), 2);
}

TEST(CellIoEmulator, BeltCoilsAreStoredAndTheScriptMovesThePhotoEyes) {
  Rig r(5, -1, {{3, 1, true}, {1, 0, true}, {2, 0, false}});
  ASSERT_TRUE(r.io.write_coil(0, true).ok());
  ASSERT_TRUE(r.io.write_coil(1, true).ok());
  ASSERT_TRUE(r.io.write_coil(1, false).ok());
  std::vector<bool> v;
  ASSERT_TRUE(r.io.read_coils(0, 3, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{true, false, false}));
  EXPECT_EQ(r.inputs(), kIdle);
  r.t = 1;
  EXPECT_EQ(r.inputs(), (std::vector<bool>{true, false, false, false}));
  r.t = 2.5;
  EXPECT_EQ(r.inputs(), kIdle);
  r.t = 3;
  EXPECT_EQ(r.inputs(), (std::vector<bool>{false, true, false, false}));
  r.io.set_input(1, false);
  EXPECT_EQ(r.inputs(), kIdle) << "an eye stays as set until the script changes it";
}

TEST(CellIoEmulator, KeepsTheDigitalIoContract) {
  Rig r(5, -1);
  std::vector<bool> v{true};
  auto e = r.io.read_inputs(3, 2, v);
  EXPECT_EQ(e.status, IoStatus::exception);
  EXPECT_EQ(e.exception_code, 2);
  EXPECT_EQ(v, std::vector<bool>{true});
  EXPECT_EQ(r.io.write_coil(3, true).exception_code, 2);
  r.io.close();
  EXPECT_EQ(r.io.write_coil(2, true).status, IoStatus::disconnected);
  EXPECT_EQ(r.io.cycles(), 0);
}

TEST(CellIoEmulator, BadOptionsAndScriptTextAreInputErrors) {
  EXPECT_THROW(CellIoEmulator(options(-1, -1)), InputError);
  EXPECT_THROW(CellIoEmulator(options(5, -1, {{1, 2, true}})), InputError);
  const InputChange c = parse_input_change("2.5:1=1", {"--input", 0, 0});
  EXPECT_DOUBLE_EQ(c.at, 2.5);
  EXPECT_EQ(c.input, 1);
  EXPECT_TRUE(c.value);
  for (const char* bad : {"2.5:2=1", "x:0=1", "-1:0=1", "2.5:0=2", "2.5=1", "2.5:0"}) {
    try {
      parse_input_change(bad, {"--input", 0, 0});
      ADD_FAILURE() << bad << " was taken";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + bad + "'"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace cellwright::emulate
