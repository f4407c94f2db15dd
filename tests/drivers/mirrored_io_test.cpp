// A real unit mirrored into another (mirrored_io.hpp): the real unit answers, its coils are shown on the mirror.
#include "cellwright/drivers/mirrored_io.hpp"

#include <gtest/gtest.h>

#include <memory>

#include "cellwright/drivers/memory_io.hpp"

namespace cellwright::drivers {
namespace {

struct Pair {
  MemoryIo* real = nullptr;  // owned by the mirrored unit
  MemoryIo mirror{3, 4, "twin"};
  std::unique_ptr<MirroredIo> unit;
  Pair() {
    auto r = std::make_unique<MemoryIo>(3, 4, "plc");
    real = r.get();
    unit = std::make_unique<MirroredIo>(std::move(r), mirror);
    EXPECT_TRUE(mirror.connect().ok());
  }
};

TEST(MirroredIo, ConnectingCopiesTheRealCoilsOfItsDevicesIntoTheMirror) {
  // The mirror's belt runs (as the twin starts), the PLC left it stopped and the mill's start on: the mirror shows
  // the real unit's coils of the devices on it, and only those.
  Pair p;
  ASSERT_TRUE(p.mirror.write_coil(0, true).ok());
  ASSERT_TRUE(p.mirror.write_coil(1, true).ok());
  ASSERT_TRUE(p.real->connect().ok());
  ASSERT_TRUE(p.real->write_coil(2, true).ok());
  p.real->close();
  p.unit->mirror_coil(0);
  p.unit->mirror_coil(2);
  p.unit->mirror_coil(-1);  // not wired: ignored
  ASSERT_TRUE(p.unit->connect().ok());
  EXPECT_FALSE(p.mirror.coil(0));
  EXPECT_TRUE(p.mirror.coil(1));  // a device not on this unit: the mirror's own
  EXPECT_TRUE(p.mirror.coil(2));
}

TEST(MirroredIo, AWriteTheRealUnitTakesIsMirroredAndOneItRefusesIsNot) {
  Pair p;
  ASSERT_TRUE(p.unit->connect().ok());
  EXPECT_TRUE(p.unit->write_coil(1, true).ok());
  EXPECT_TRUE(p.mirror.coil(1));
  p.real->fail_next(IoStatus::exception, 4);
  const IoResult r = p.unit->write_coil(0, true);
  EXPECT_EQ(r.status, IoStatus::exception);
  EXPECT_FALSE(p.mirror.coil(0));
}

TEST(MirroredIo, ACoilReadFromTheRealUnitIsShownOnTheMirror) {
  // Someone else (the PLC's own logic) stopped the belt: the next read shows it in the mirror.
  Pair p;
  ASSERT_TRUE(p.unit->connect().ok());
  ASSERT_TRUE(p.unit->write_coil(0, true).ok());
  ASSERT_TRUE(p.real->write_coil(0, false).ok());
  std::vector<bool> v;
  ASSERT_TRUE(p.unit->read_coils(0, 1, v).ok());
  EXPECT_FALSE(v.at(0));
  EXPECT_FALSE(p.mirror.coil(0));
}

TEST(MirroredIo, ReadsAndTheLinksStateAreTheRealUnits) {
  Pair p;
  EXPECT_FALSE(p.unit->is_open());
  EXPECT_EQ(p.unit->describe(), p.real->describe());
  ASSERT_TRUE(p.unit->connect().ok());
  p.real->set_input(3, true);
  p.mirror.set_input(3, false);
  std::vector<bool> v;
  ASSERT_TRUE(p.unit->read_inputs(3, 1, v).ok());
  EXPECT_TRUE(v.at(0));
  p.unit->close();
  EXPECT_FALSE(p.real->is_open());
  EXPECT_TRUE(p.mirror.is_open());
}

TEST(MirroredIo, ACoilTheRealUnitCannotReadAtConnectIsLeftAsTheMirrorHasIt) {
  Pair p;
  ASSERT_TRUE(p.mirror.write_coil(0, true).ok());
  p.unit->mirror_coil(0);
  p.real->fail_next(IoStatus::exception, 2);
  EXPECT_TRUE(p.unit->connect().ok());
  EXPECT_TRUE(p.mirror.coil(0));
}

}  // namespace
}  // namespace cellwright::drivers
