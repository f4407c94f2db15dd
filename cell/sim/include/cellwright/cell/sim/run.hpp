// One run of a scenario on the simulated cell: everything `twin run`, `twin step` and the pipeline benchmark share.
// It builds the World (with the scenario's perturbation of where parts really are) on the cell the preflight's sweep
// compiled (Preflight::twin: the MuJoCo model is compiled once per run; compiled here only when the preflight swept
// nothing), the simulation drivers, the plant (with the scenario's workpiece feed), the detector when the perception
// is vision, the cycle-time estimate from the preflight's motion plan (Preflight::plan: planned once per run) and the
// Runtime (given the cell description as written: the controller does not know the perturbation);
// after the run it turns the result into the report and writes the outputs.
// The scenario's faults (docs/faults.md) are put in place here: the physical ones and the camera's by the plant
// (sim::FaultInjector; the scene gets the obstacle bodies), the detection noise by a sim::NoisyDetector around the
// detector, the driver faults by a drivers::FaultyDriver around the robot's simulation driver (each reported to the
// plant as it is chosen), lost_signal by a signal filter (RunConfig::signal_filter) that drops the n-th signal. The
// injections are logged here, not by the runtime: the plant's at the end of its advance() and the lost signals in
// the filter, into the Runtime's log (docs/faults.md).
// Sensors (RunConfig::sensors) are the twin's (WorldPlant::sensors()); a real robot's grip is its driver's where the
// driver can tell (capabilities().senses_grip; the Movemaster EX and VAL II drivers cannot), its twin copy's else.
//
// Order of use (main thread):
//    Scenario s = load_scenario(file);            // InputError: bad input
//    Preflight p = preflight(s, &twin_port());   // !p.ok(): refuse, nothing built (preflight.hpp)
//    ScenarioRun run(s, p, options);              // builds, starts no thread
//    RunResult r = run.runtime().run();           // or runtime().step() ...
//    Report rep = run.report();
//    run.write_outputs(dir, rep, run.snapshot(800, 600));
//
// Threads: a ScenarioRun is used by one thread, the caller's; the Runtime it holds starts and joins the others.
// world() and snapshot() may be used only while the runtime's threads are not running (before run(), between
// steps, after the run).
#pragma once

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/faulty_driver.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/streamed_log.hpp"
#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/twin/sim/mirrored_driver.hpp"
#include "cellwright/twin/sim/replica_mirror.hpp"
#include "cellwright/twin/sim/twin_io.hpp"
#include "cellwright/twin/sim/world.hpp"
#include "cellwright/twin/sim/world_plant.hpp"
#include "cellwright/twin/video.hpp"
#include "cellwright/vision/camera_source.hpp"

namespace cellwright::cell {

namespace sim = twin::sim;  // the simulator's World, drivers and plant

struct RunOptions {
  std::optional<bool> realtime;  // overrides the scenario's options.realtime when set (`--realtime`)
  // Real time only (`--speed X`): simulation seconds per wall-clock second (the runtime's realtime_speed); > 0.
  // Above 1 only with emulated controllers that run as fast (`twin emulate --scenario ... --speed X`): a real arm
  // moves at its own pace, so its run would see every motion take X times longer than planned.
  double speed = 1.0;
  // Called on the simulation thread every `progress_every` of simulation time with the time and the firings so far.
  // Must be short and must not touch the ScenarioRun.
  std::function<void(runtime::SimDuration, std::uint64_t)> on_progress;
  runtime::SimDuration progress_every = std::chrono::seconds(1);
  // Overrides the scenario's perception when set (`--perception`). Vision without a `vision:` entry in the scenario
  // looks through the cell's first camera.
  std::optional<runtime::Perception> perception;
  // Called on the image-processing thread after each camera frame (`--save-frames`). Must not touch the ScenarioRun.
  // Without vision perception: called on the simulation thread with plain frames (no sightings, no predictions) of
  // the scenario's vision camera, else the cell's first, every vision period (`vision.period`, default 0.4 s); the
  // constructor throws InputError if the cell has no camera.
  std::function<void(const runtime::VisionFrame&)> on_frame;
  // If not empty, the event log is streamed to this file as the run writes it (created, or emptied, when the
  // ScenarioRun is built, with its directory) and kept nowhere else: the run's memory does not grow with its length, report() reads the
  // file back, and runtime().log().text() is not available. A run that dies leaves every line logged so far in it.
  // Empty: the log is kept in memory (tests, benchmarks).
  std::filesystem::path events_file;
  // A video of the run (`--video`, video.hpp): the file is opened when the ScenarioRun is built (InputError if it
  // cannot be written), frames are recorded on the simulation thread at multiples of 1/fps of simulation time (the
  // event log is the same with and without), and finish_video() adds the verdict and closes it.
  std::optional<twin::VideoOptions> video;
  // Real cameras (`--camera NAME=SOURCE`, vision/camera_source.hpp): vision's frames come from the source instead of
  // the twin's renderer. NAME must be the camera vision looks through, and the perception vision; a live device
  // needs a real-time run; the twin's camera faults (frame_lost, detection_noise) cannot be injected into a real
  // camera. The source is opened (its first frame read) when the ScenarioRun is built: InputError otherwise.
  std::vector<std::string> cameras;
  // Called with the runtime's configuration just before the Runtime is built, to add watchers of the run
  // (RunConfig::observers, event_observers: `--ros-domain`'s ROS 2 publisher, distributed/ros_publisher.hpp).
  std::function<void(runtime::RunConfig&)> configure;
  // Robots whose robot control runs in an agent on its real driver (`twin run --agents remote` in real time,
  // docs/distributed.md): this process has no driver of theirs, and their copies in the twin follow the states of
  // their robots the caller pushes into replica_mirror() (sim::ReplicaMirror: the agents' replicated model updates).
  // The caller makes them remote in the runtime's configuration (configure: RunConfig::remote_robots). Real time
  // only, and without the scenario's faults (they are injected into this process's drivers and twin, which do not
  // drive these robots): InputError.
  std::vector<std::string> followed;
  std::string followed_via;  // where their agents are, for the report (DriverUse::port: "DDS domain N")
};

// The scenario's cell as it really is, compiled: its parts where the scenario's perturbation puts them (drawn with its
// seed), with the obstacle bodies its faults need (sim::FaultInjector::scene_options). Throws InputError if MuJoCo
// rejects the cell.
twin::Scene compile_cell(const Scenario& scenario);

// The scenario's cell as it really is: the World (perturbed parts moved by the scenario's seed, fed parts parked) and
// the feed events that bring the parked parts in. The World runs on `compiled` (compile_cell of the scenario, its
// model shared: Scene::share()), or on the cell compiled here when it is null. Throws InputError if MuJoCo rejects
// the cell.
struct CellWorld {
  std::unique_ptr<sim::World> world;
  std::vector<sim::FeedEvent> feed;
};
CellWorld make_cell_world(const Scenario& scenario, const twin::Scene* compiled = nullptr);

// The options of the simulation driver a run gives robot `robot` (a cell robot of the program).
sim::SimDriverOptions sim_driver_options(const Scenario& scenario, const std::string& robot);

// The estimate's options (estimate.hpp) for `scenario` run on the twin whose compiled cell is `scene`: per program
// robot the timing of the simulation driver a run gives it (sim_driver_options: its joint speeds, sim_joint_speeds;
// its minimum move time and finger speed; the fingers' travel, the grip force and the finger servos' stiffness of the
// scene) at `motion_speed` (the runtime's MotionOptions::speed), the control period and the physics step. The one
// timing set-up: ScenarioRun and the twin's estimate without a run (SimulatedTwin::estimate) both call it. Throws
// InputError as sim_joint_speeds (reading the robots' URDFs).
EstimateOptions twin_estimate_options(const Scenario& scenario, const twin::Scene& scene, double motion_speed);

// The cell's workpieces as `world` has them now (ground truth: parked parts are not present, a part both finger pads
// of a robot touch is held by it). Only while nothing steps the world.
std::vector<FinalPose> final_poses_of(const sim::World& world);

class ScenarioRun {
 public:
  // Builds the World (feed workpieces parked) on the preflight's compiled cell (or the cell compiled here when it has
  // none), a simulation driver per program robot, the plant that feeds workpieces at their times, the estimate (of
  // the preflight's plan) and the Runtime (with the preflight's net). `preflight` is preflight(scenario, ...), which
  // planned the program (InternalError if it has no plan: a run follows a preflight that passed, or only found
  // collisions).
  // A robot on a real driver (DriverChoice::real) is driven through it, its simulation driver being the copy that
  // follows it in the twin (sim::MirroredDriver); its driver is connected here, so that a port that cannot be opened
  // or a controller that does not answer is an error before anything runs. Real drivers need real time.
  // A device on real I/O (Scenario::devices, DeviceChoice::real) is driven on its Modbus unit (one connection per
  // HOST:PORT/UNIT) at the cell's addresses, and every coil written there is written into the twin's I/O image too,
  // so that the twin mirrors it; the other devices are the twin's (TwinIo). Real devices need real time too; their
  // units are connected when the run starts (InputError naming the unit when one cannot be reached).
  // Throws InputError if MuJoCo rejects the cell, a driver's configuration cannot work, a real driver cannot connect,
  // or a real driver or device would run lock-step; nothing runs yet.
  ScenarioRun(const Scenario& scenario, const Preflight& preflight, RunOptions options = {});
  ~ScenarioRun();
  ScenarioRun(const ScenarioRun&) = delete;
  ScenarioRun& operator=(const ScenarioRun&) = delete;

  const Scenario& scenario() const { return scenario_; }
  const Estimate& estimate() const { return estimate_; }
  runtime::Runtime& runtime() { return *runtime_; }
  sim::World& world() { return *world_; }
  // The robots on real drivers, with their copies in the twin (empty when all are simulated).
  const std::vector<std::unique_ptr<sim::MirroredDriver>>& mirrors() const { return mirrors_; }
  // The copies of RunOptions::followed robots (started, following what is pushed), or nullptr when there are none.
  sim::ReplicaMirror* replica_mirror() { return replica_mirror_.get(); }
  // After the run, with RunOptions::followed: steps the twin (nothing else: the runtime has ended) until the copies
  // have done what the last states pushed asked of them, at most `most` of simulation time. Returns whether they
  // did. The copies then stop where they stand. Same threads rule as report().
  bool settle_followers(runtime::SimDuration most);
  bool realtime() const { return realtime_; }
  runtime::Perception perception() const { return perception_; }

  // The cell's workpieces as the simulation has them now (ground truth: parked parts are not present, a part both
  // finger pads of a robot touch is held by it). Only while the runtime's threads are not running.
  std::vector<FinalPose> final_poses() const;

  // The report of the run so far (make_report on the runtime's event log, or its file, final_poses() and the
  // estimate). Only while the runtime's threads are not running: after run(), or between steps (then the log has no
  // run_end yet). Throws InputError if the streamed log cannot be written or read back.
  Report report() const;

  // Where the event log is streamed (RunOptions::events_file; it moves when write_outputs moves it), or empty.
  const std::filesystem::path& events_file() const { return streamed_ ? streamed_->file() : no_file_; }

  // write_outputs() below with this run's events: the log's text, or the streamed file moved into `dir` as
  // events.jsonl (copied when `dir` is on another file system); with a video, index.html shows it (by its path
  // relative to `dir`). Same threads rule as report().
  void write_outputs(const std::filesystem::path& dir, const Report& report, const cv::Mat& final_image);

  // The overview camera's view of the cell now (a copy of the simulation state is rendered, headless; the camera
  // frames every visible body, the workpieces wherever they are included), with each workpiece of the scenario's
  // expectations that is in the picture marked and named with its expected place ("A (output)") at its final pose.
  cv::Mat snapshot(int width, int height) const;

  // With RunOptions::video, after the run (or when it was quit): the final state held with the report's verdict,
  // then the file closed. Returns the video's file, or empty without a video (or when called again). Throws
  // InputError naming the file if recording failed. Same threads rule as report().
  std::filesystem::path finish_video(const Report& report);

 private:
  // The I/O units (RunConfig::io_units): the twin's, and the real ones of Scenario::devices, mirrored into it.
  // InputError (naming the choice) for a real device in a lock-step run.
  void wire_devices(runtime::RunConfig& config);

  const Scenario& scenario_;
  std::unique_ptr<StreamedLog> streamed_;  // the event log's file (RunOptions::events_file), or none
  const std::filesystem::path no_file_;     // events_file() without one
  bool realtime_ = false;
  runtime::Perception perception_ = runtime::Perception::kTruth;
  std::unique_ptr<sim::World> world_;
  std::vector<std::unique_ptr<sim::MirroredDriver>> mirrors_;  // real robots, with their copies in world_
  std::unique_ptr<sim::ReplicaMirror> replica_mirror_;  // RunOptions::followed's copies in world_, or none
  std::vector<std::string> followed_;                   // RunOptions::followed
  std::string followed_via_;                            // RunOptions::followed_via
  std::vector<std::unique_ptr<drivers::FaultyDriver>> faulty_;  // simulated robots with driver faults
  std::vector<std::unique_ptr<runtime::GripSensor>> grip_sensors_;  // real robots' grip sensors, on their drivers
  std::unique_ptr<vision::CameraSource> camera_;  // RunOptions::cameras: vision's frames, or none (the twin's)
  std::unique_ptr<runtime::Plant> plant_;
  sim::WorldPlant* world_plant_ = nullptr;  // plant_, the World's
  std::unique_ptr<sim::TwinIo> twin_io_;                       // the twin's I/O image: the simulated devices' unit
  std::vector<std::unique_ptr<drivers::DigitalIo>> real_io_;  // Scenario::devices' real units, mirrored into twin_io_
  Estimate estimate_;
  std::unique_ptr<twin::VideoRecorder> video_;  // with RunOptions::video; fed by the simulation thread
  std::filesystem::path video_file_;      // its file, kept when finish_video() has closed it
  std::unique_ptr<runtime::Runtime> runtime_;
};

}  // namespace cellwright::cell
