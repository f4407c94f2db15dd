// The twin's devices (world.hpp, "DEVICES") and its I/O image (twin_io.hpp), on the paper's cell (scenes/cell.yaml:
// coil 0 input run, 1 output run, 2 mill start; discrete input 0 input eye, 1 output drop eye, 2 mill busy, 3 mill
// done): accumulating belts, a stopped belt, the photo-eyes, the mill's cycle and the processed part's colour in a
// rendered frame.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/twin/render.hpp"
#include "cellwright/twin/sim/twin_io.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "twin/mujoco_fixture.hpp"
#include "twin/sim/sim_helpers.hpp"

namespace cellwright::twin::sim {
namespace {

using namespace testing;  // NOLINT: the simulation test helpers

constexpr std::uint16_t kInputRun = 0, kOutputRun = 1, kMillStart = 2;
constexpr std::uint16_t kInputEye = 0, kOutputDrop = 1, kMillBusy = 2, kMillDone = 3;

class DevicesTest : public cellwright::testing::MujocoTest {
 protected:
  static const WorkpieceTruth& part(const WorldTruth& t, const std::string& name) {
    for (const auto& w : t.workpieces) {
      if (w.name == name) return w;
    }
    throw std::logic_error("no workpiece " + name);
  }
  static Eigen::Vector3d where(World& w, const std::string& name) {
    return part(w.truth(), name).pose.translation();
  }
  static bool input(TwinIo& io, std::uint16_t address) {
    std::vector<bool> v;
    const drivers::IoResult r = io.read_inputs(address, 1, v);
    EXPECT_TRUE(r.ok()) << r.message;
    return r.ok() && v.at(0);
  }
  static void write(TwinIo& io, std::uint16_t address, bool value) {
    const drivers::IoResult r = io.write_coil(address, value);
    ASSERT_TRUE(r.ok()) << r.message;
  }
  // Advances period by period until the input conveyor's stop eye is on (A at the stop), at most 60 s.
  static void until_at_stop(World& w) {
    while (w.now() < 60s && !w.devices().conveyors[0].stop_eye) w.advance(kPeriod);
    ASSERT_TRUE(w.devices().conveyors[0].stop_eye) << "A did not reach the stop within 60 s";
  }
};

TEST_F(DevicesTest, AnAccumulatingBeltStopsWhileItsStopEyeIsBlockedAndRunsWhenThePartIsTaken) {
  World w(build_scene(paper_cell()));
  ASSERT_TRUE(paper_cell().conveyors[0].accumulate);
  EXPECT_TRUE(w.devices().conveyors[0].running);
  until_at_stop(w);
  EXPECT_TRUE(w.signals().get(16)) << "the eye is the robots' input 16 too";
  w.advance(100ms);
  // The belt stands still, and so does the queue behind A: nothing slides on a moving belt.
  EXPECT_FALSE(w.devices().conveyors[0].running);
  EXPECT_LT(std::abs(w.truth().conveyors[0].belt_speed), 1e-3);
  const Eigen::Vector3d a = where(w, "A"), b = where(w, "B");
  w.advance(2s);
  EXPECT_LT((where(w, "A") - a).norm(), 1e-3);
  EXPECT_LT((where(w, "B") - b).norm(), 1e-3) << "B stops where it was when the belt stopped";
  EXPECT_EQ(part(w.truth(), "A").location, "input_pick");

  // A taken: the eye clears, the belt runs again and brings B to the stop.
  ASSERT_TRUE(w.park("A").ok());
  EXPECT_FALSE(w.devices().conveyors[0].stop_eye);
  w.advance(100ms);
  EXPECT_TRUE(w.devices().conveyors[0].running);
  EXPECT_NEAR(w.truth().conveyors[0].belt_speed, paper_cell().conveyors[0].speed, 0.005);
  until_at_stop(w);
  EXPECT_EQ(part(w.truth(), "B").location, "input_pick");
  EXPECT_TRUE(w.new_collisions().empty());
}

TEST_F(DevicesTest, AStoppedBeltCarriesNothingUntilItsRunCoilIsSetAgain) {
  World w(build_scene(paper_cell()));
  TwinIo io(w);
  ASSERT_TRUE(io.connect().ok());
  std::vector<bool> coils;
  ASSERT_TRUE(io.read_coils(kInputRun, 3, coils).ok());
  EXPECT_EQ(coils, (std::vector<bool>{true, true, false})) << "the belts run from the start, the mill waits";

  w.advance(1s);
  write(io, kInputRun, false);
  // A write takes effect at the next step: until then the devices are as the last step left them.
  EXPECT_TRUE(w.devices().conveyors[0].run);
  ASSERT_TRUE(io.read_coils(kInputRun, 1, coils).ok());
  EXPECT_FALSE(coils[0]) << "the coil reads back as written";
  w.step();
  EXPECT_FALSE(w.devices().conveyors[0].run);
  EXPECT_FALSE(w.devices().conveyors[0].running);
  w.advance(100ms);
  const Eigen::Vector3d a = where(w, "A");
  w.advance(3s);
  EXPECT_LT((where(w, "A") - a).norm(), 1e-3) << "a stopped belt carries nothing";
  EXPECT_LT(std::abs(w.truth().conveyors[0].belt_speed), 1e-3);

  write(io, kInputRun, true);
  w.advance(2s);
  EXPECT_GT(where(w, "A").x() - a.x(), 0.08) << "running again: about 0.05 m/s";
}

TEST_F(DevicesTest, ThePhotoEyesAreTheImagesDiscreteInputs) {
  WorldOptions options;
  options.parked = {"C"};
  World w(build_scene(paper_cell()), options);
  TwinIo io(w);
  ASSERT_TRUE(io.connect().ok());
  EXPECT_FALSE(input(io, kInputEye));
  EXPECT_FALSE(input(io, kOutputDrop));
  // A part put down at the output conveyor's entry lies across its drop eye until the belt carries it on.
  ASSERT_TRUE(w.feed("C", "output").ok());
  EXPECT_TRUE(input(io, kOutputDrop));
  EXPECT_TRUE(w.devices().conveyors[1].drop_eye);
  w.advance(2s);
  EXPECT_FALSE(input(io, kOutputDrop)) << "0.1 m downstream after 2 s";
  until_at_stop(w);
  EXPECT_TRUE(input(io, kInputEye));
}

TEST_F(DevicesTest, TheMillProcessesALoadedPartForItsProcessTimeAndItComesOutInTheProcessedColour) {
  const models::MachineSpec& mill = paper_cell().machines.at(0);
  ASSERT_EQ(mill.process_time, 5.0);
  WorldOptions options;
  options.parked = {"D"};
  World w(build_scene(paper_cell()), options);
  TwinIo io(w);
  ASSERT_TRUE(io.connect().ok());

  // Empty: a start is ignored.
  write(io, kMillStart, true);
  w.advance(100ms);
  EXPECT_EQ(w.devices().machines[0].state, MachineState::idle);
  EXPECT_FALSE(input(io, kMillBusy));
  write(io, kMillStart, false);

  // D put on the fixture: loaded once it rests there.
  Eigen::Isometry3d on = mill.fixture_top().transform();
  on.translation().z() += 0.03;  // D is 6 cm tall: its centre 3 cm above the plate
  ASSERT_TRUE(w.place("D", on).ok());
  w.advance(300ms);
  DeviceStates d = w.devices();
  EXPECT_EQ(d.machines[0].state, MachineState::loaded);
  EXPECT_EQ(d.machines[0].part, "D");

  // The overhead camera sees D in its own colour.
  const int camera = w.scene().camera_id("overhead");
  Renderer renderer(w.scene().model(), 640, 480);
  const auto colour_of_d = [&] {
    const cv::Mat image = renderer.render_camera(w.render_data(), camera, 640, 480, RenderQuality::kVision);
    const std::optional<cv::Point2d> p =
        camera_model(w.scene().model(), w.data(), camera, 640, 480).project(where(w, "D") + Eigen::Vector3d(0, 0, 0.03));
    EXPECT_TRUE(p.has_value());
    return image.at<cv::Vec3b>(static_cast<int>(std::lround(p->y)), static_cast<int>(std::lround(p->x)));
  };
  const cv::Vec3b yellow = colour_of_d();  // BGR
  EXPECT_GT(yellow[2], yellow[0] + 80) << "D is yellow: much more red than blue";

  // A rising edge of the start coil: busy from the next step, for 5 s of simulated time.
  write(io, kMillStart, true);
  w.step();
  EXPECT_TRUE(input(io, kMillBusy));
  EXPECT_FALSE(input(io, kMillDone));
  const auto started = w.now();
  while (w.devices().machines[0].busy() && w.now() < started + 10s) w.step();
  EXPECT_EQ(w.now() - started, 5s);
  EXPECT_FALSE(input(io, kMillBusy));
  EXPECT_TRUE(input(io, kMillDone));
  d = w.devices();
  EXPECT_EQ(d.machines[0].state, MachineState::done);
  EXPECT_EQ(d.machines[0].cycles, 1);
  EXPECT_EQ(d.processed, std::vector<std::string>{"D"});
  EXPECT_TRUE(w.processed("D"));

  // Processed: bare metal, grey, in the camera's frame (the World's own data, as the vision thread renders it) and
  // in a copy of the state (as the run's snapshot renders it).
  const cv::Vec3b grey = colour_of_d();
  EXPECT_LT(std::abs(int(grey[2]) - int(grey[0])), 30) << "grey: red and blue alike";
  std::unique_ptr<mjData, void (*)(mjData*)> copy(mj_makeData(w.scene().model()), mj_deleteData);
  mj_copyData(copy.get(), w.scene().model(), w.data());
  const cv::Mat snapshot = renderer.render_camera(copy.get(), camera, 640, 480, RenderQuality::kVision);
  const cv::Mat again = renderer.render_camera(w.render_data(), camera, 640, 480, RenderQuality::kVision);
  EXPECT_EQ(cv::norm(snapshot, again, cv::NORM_INF), 0.0);

  // A second start while done is ignored; taking D off is the unload.
  write(io, kMillStart, false);
  write(io, kMillStart, true);
  w.advance(100ms);
  EXPECT_EQ(w.devices().machines[0].state, MachineState::done);
  ASSERT_TRUE(w.park("D").ok());
  d = w.devices();
  EXPECT_EQ(d.machines[0].state, MachineState::idle);
  EXPECT_EQ(d.machines[0].unloads, 1);
  EXPECT_FALSE(input(io, kMillDone));
  EXPECT_TRUE(w.processed("D")) << "for good";
}

TEST_F(DevicesTest, TheImageRefusesWhatTheCellDoesNotWire) {
  World w(build_scene(paper_cell()));
  TwinIo io(w);
  std::vector<bool> v{true};
  drivers::IoResult r = io.read_inputs(kInputEye, 1, v);
  EXPECT_EQ(r.status, drivers::IoStatus::disconnected) << "closed until connect()";
  ASSERT_TRUE(io.connect().ok());
  EXPECT_EQ(io.describe(), "twin");

  r = io.write_coil(3, true);
  EXPECT_EQ(r.status, drivers::IoStatus::exception);
  EXPECT_EQ(r.exception_code, 2);
  EXPECT_NE(r.message.find("3"), std::string::npos) << r.message;
  r = io.read_inputs(kInputEye, 5, v);  // 0..3 are wired, 4 is not
  EXPECT_EQ(r.exception_code, 2) << r.message;
  EXPECT_EQ(v, std::vector<bool>{true}) << "unchanged when refused";
  r = io.read_coils(kMillStart, 2, v);
  EXPECT_EQ(r.exception_code, 2) << r.message;
  r = io.read_inputs(0, 2001, v);
  EXPECT_EQ(r.exception_code, 3) << r.message;
  ASSERT_TRUE(io.read_inputs(kInputEye, 4, v).ok());
  EXPECT_EQ(v.size(), 4u);
  EXPECT_EQ(io.wiring().front(), "coil 0: the run of conveyor 'input'");
  io.close();
  EXPECT_EQ(io.write_coil(kInputRun, false).status, drivers::IoStatus::disconnected);
  EXPECT_TRUE(w.belt_run(0)) << "nothing written while closed";
}

}  // namespace
}  // namespace cellwright::twin::sim
