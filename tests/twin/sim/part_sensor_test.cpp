// The part-present sensor at the input conveyor's stop (the cell's `sensor: {signal: 16}`): off while the first part
// rides the belt, on once it rests against the stop, off when it is taken away, on again when the next part arrives;
// the same steps give the same signal changes.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <vector>

#include "cellwright/twin/sim/world.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using ::testing::HasSubstr;
using namespace testing;  // NOLINT: the simulation test helpers

class PartSensorTest : public cellwright::testing::MujocoTest {
 protected:
  static const WorkpieceTruth& part(const WorldTruth& t, const std::string& name) {
    for (const auto& w : t.workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }
  // The input conveyor's sensor signal, from the cell.
  static int sensor() { return paper_cell().find_conveyor("input")->sensor; }
  // How far the part's front face is from the stop bar, along the belt (the input conveyor runs along +x).
  static double gap(const WorkpieceTruth& p) {
    const models::ConveyorSpec& c = *paper_cell().find_conveyor("input");
    return c.belt_point(c.leave).x() - (p.pose.translation().x() + 0.02);
  }
  // Advances period by period until the sensor is on (or `limit`); returns the periods stepped and, in `changes`,
  // the step count of every change of the signal.
  static void run_until_on(World& w, std::chrono::nanoseconds limit, std::vector<std::int64_t>& changes) {
    bool last = w.signals().get(sensor());
    const auto end = w.now() + limit;
    while (w.now() < end && !w.signals().get(sensor())) {
      w.advance(kPeriod);
      if (w.signals().get(sensor()) != last) {
        last = !last;
        changes.push_back(w.steps());
      }
    }
  }
};

TEST_F(PartSensorTest, OnWhileAPartRestsAtTheStopOffWhenItIsTakenAway) {
  ASSERT_EQ(sensor(), 16);
  World w(build_scene(paper_cell()));
  // A starts in a row from the entry point, far from the stop.
  EXPECT_FALSE(w.signals().get(sensor()));
  EXPECT_GT(gap(part(w.truth(), "A")), 0.5);

  // Off all the way along the belt; on once A is at the stop, soon after it got there.
  double reached = -1;  // when A's front face first touched the stop bar
  while (w.now() < 60s && !w.signals().get(sensor())) {
    w.advance(kPeriod);
    const WorkpieceTruth a = part(w.truth(), "A");
    if (reached < 0 && gap(a) < 0.0005) reached = w.time();
    if (w.signals().get(sensor())) {
      EXPECT_LT(std::abs(gap(a)), 0.005) << "on with A " << gap(a) << " m from the stop";
    }
  }
  ASSERT_TRUE(w.signals().get(sensor())) << "A did not trigger the sensor within 60 s";
  ASSERT_GT(reached, 15.0) << "A rides about 19 s to the stop";
  EXPECT_LT(w.time() - reached, 1.0) << "on " << w.time() - reached << " s after A reached the stop";
  EXPECT_EQ(part(w.truth(), "A").location, "input_pick");

  // It stays on while A rests there, with B pushing from behind.
  for (int i = 0; i < 100; ++i) {
    w.advance(kPeriod);
    EXPECT_TRUE(w.signals().get(sensor())) << "at " << w.time() << " s";
  }

  // A taken away: off at once, B right behind it is not at the stop.
  ASSERT_TRUE(w.park("A").ok());
  EXPECT_FALSE(w.signals().get(sensor()));
  w.advance(kPeriod);
  EXPECT_FALSE(w.signals().get(sensor()));
  // B rides on to the stop: on again.
  std::vector<std::int64_t> changes;
  run_until_on(w, 10s, changes);
  EXPECT_TRUE(w.signals().get(sensor())) << "B did not trigger the sensor within 10 s";
  EXPECT_EQ(part(w.truth(), "B").location, "input_pick");
  // The sensor's signal is the only one set: the other signals stay off.
  for (int n = 1; n <= static_cast<int>(w.signals().size()); ++n) {
    if (n != sensor()) {
      EXPECT_FALSE(w.signals().get(n)) << n;
    }
  }
  EXPECT_TRUE(w.new_collisions().empty());
  expect_no_data_warnings(w.data());
  EXPECT_THAT(w.drain_warnings(), ::testing::IsEmpty());
}

TEST_F(PartSensorTest, SameStepsSameSignalChanges) {
  std::vector<std::vector<std::int64_t>> runs(2);
  for (auto& changes : runs) {
    World w(build_scene(paper_cell()));
    run_until_on(w, 30s, changes);
    ASSERT_TRUE(w.signals().get(sensor()));
  }
  ASSERT_FALSE(runs[0].empty());
  EXPECT_EQ(runs[0], runs[1]);
}

TEST_F(PartSensorTest, ASensorBeyondTheWorldsSignalsIsRefused) {
  WorldOptions options;
  options.where = {"cell.yaml", 0, 0};
  options.signals = 8;
  try {
    World w(build_scene(paper_cell()), options);
    ADD_FAILURE() << "accepted a sensor on signal 16 with 8 signals";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("conveyor 'input': its sensor's signal 16 is not one of the cell's 8 digital"));
    EXPECT_EQ(std::filesystem::path(e.where().file).filename(), "cell.yaml");
    EXPECT_GT(e.where().line, 0);
  }
}

}  // namespace
}  // namespace cellwright::twin::sim
