// MemoryIo keeps the DigitalIo contract (digital_io.hpp): requests on a closed unit fail as disconnected, addresses
// beyond the unit are refused with Modbus's illegal-data-address code, and scripted failures close the unit exactly
// when the interface says a real unit would be closed.
#include "cellwright/drivers/memory_io.hpp"

#include <gtest/gtest.h>

namespace cellwright::drivers {
namespace {

TEST(MemoryIo, ClosedUnitAnswersDisconnectedAndCountsTheRequest) {
  MemoryIo io(3, 4);
  std::vector<bool> v;
  EXPECT_EQ(io.read_inputs(0, 4, v).status, IoStatus::disconnected);
  EXPECT_EQ(io.write_coil(0, true).status, IoStatus::disconnected);
  EXPECT_FALSE(io.coil(0));
  EXPECT_EQ(io.requests(), 2);
  EXPECT_EQ(io.writes(), 0);
}

TEST(MemoryIo, WritesCoilsAndReadsInputsTheTestSets) {
  MemoryIo io(3, 4);
  ASSERT_TRUE(io.connect().ok());
  ASSERT_TRUE(io.write_coil(2, true).ok());
  io.set_input(1, true);
  std::vector<bool> v;
  ASSERT_TRUE(io.read_inputs(0, 4, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{false, true, false, false}));
  ASSERT_TRUE(io.read_coils(1, 2, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{false, true}));
  EXPECT_TRUE(io.coil(2));
}

TEST(MemoryIo, AnAddressBeyondTheUnitIsRefusedWithCode2AndLeavesValuesAlone) {
  MemoryIo io(3, 4);
  ASSERT_TRUE(io.connect().ok());
  std::vector<bool> v{true};
  const IoResult r = io.read_inputs(3, 2, v);
  EXPECT_EQ(r.status, IoStatus::exception);
  EXPECT_EQ(r.exception_code, 2);
  EXPECT_NE(r.message.find("3..4"), std::string::npos) << r.message;
  EXPECT_EQ(v, std::vector<bool>{true});
  EXPECT_TRUE(io.is_open());
}

TEST(MemoryIo, ScriptedFailuresComeInOrderAndABrokenLinkClosesTheUnit) {
  MemoryIo io(3, 4);
  ASSERT_TRUE(io.connect().ok());
  io.fail_next(IoStatus::timeout);
  io.fail_next(IoStatus::exception, 4);
  io.fail_next(IoStatus::disconnected);
  std::vector<bool> v;
  EXPECT_EQ(io.read_inputs(0, 1, v).status, IoStatus::timeout);
  EXPECT_TRUE(io.is_open());
  const IoResult e = io.write_coil(0, true);
  EXPECT_EQ(e.status, IoStatus::exception);
  EXPECT_EQ(e.exception_code, 4);
  EXPECT_FALSE(io.coil(0));
  EXPECT_EQ(io.read_inputs(0, 1, v).status, IoStatus::disconnected);
  EXPECT_FALSE(io.is_open());
  ASSERT_TRUE(io.connect().ok());
  EXPECT_TRUE(io.read_inputs(0, 1, v).ok());
}

}  // namespace
}  // namespace cellwright::drivers
