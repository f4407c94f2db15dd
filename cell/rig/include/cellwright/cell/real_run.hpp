// A run of a cell of real robots with no twin (`twin run SCENARIO --driver ROBOT=movemaster|val2:PORT ...` in a
// `twin` built without the simulator, docs/real-robots.md): the scenario's program on the robots' serial controllers,
// in real time, with nothing simulated. The rig's part of it: the runtime's configuration (run_wiring.hpp, the same
// as the simulated rig's) with
//  - the real drivers (real_drivers.hpp) of every robot of the program, connected here, so that a port that cannot
//    be opened or a controller that does not answer is an error before anything runs;
//  - no plant (runtime.hpp: the first thread keeps the clock and reads the sensors);
//  - the sensors the drivers have (sensors.hpp): a grip sensor on a driver that can sense its grip
//    (capabilities().senses_grip: a DriverGripSensor), none on one that cannot (the Movemaster EX and VAL II
//    drivers: a close is then taken as done); no wrist force, safety or part sensor (none of the cell's is wired yet);
//  - the program's devices (its machines, conveyors and photo-eyes) on their Modbus units (Scenario::devices: every
//    one must be on real I/O, since there is no twin I/O image), one connection per HOST:PORT/UNIT, at the cell's `io`
//    addresses;
//  - perception from the cell description only (Perception::kCad: the controller's model keeps what it knows of the
//    parts, each held part moving with its hand).
// There is no truth: where the parts end up is what the controller's environment model says at the end (model()),
// which the report must present as such (report.hpp, RunSetup::parts_from_model). Nothing is injected: the twin
// injects the scenario's faults, and a run without it refuses them.
//
// Order of use (main thread):
//    Preflight p = preflight(s, nullptr);           // refuse when !p.ok()
//    RealRun run(s, p.net, options);                // InputError: see the constructor; connects the drivers
//    run.run();                                      // blocks; runtime().request_stop() from another thread ends it
//    make the report from the log and final_poses_of(run.model()) (cell/report)
// Threads: a RealRun is used by one thread, the caller's, but for runtime().request_stop(); its Runtime starts and
// joins the others.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

struct RealRunOptions {
  // Simulation seconds per wall-clock second (the runtime's realtime_speed); > 0. Above 1 only with emulated
  // controllers that move as fast (`twin emulate ... --time-scale 1/X`): a real arm moves at its own pace.
  double speed = 1.0;
  // The perception asked for on the command line, if any: only kCad can be had without a twin (InputError else).
  std::optional<runtime::Perception> perception;
  // Called on the runtime's first thread every `progress_every` with the time and the firings so far.
  std::function<void(runtime::SimDuration, std::uint64_t)> on_progress;
  runtime::SimDuration progress_every = std::chrono::seconds(1);
  // Where the event log is streamed (a StreamedLog's stream, cell/report), kept nowhere else; nullptr: kept in memory
  // (runtime().log().text()).
  std::ostream* log_stream = nullptr;
  // Cell robots whose robot control is an agent in another process (`twin run --agents remote`, docs/distributed.md):
  // no driver here (the agent has it), their queues carried by `attach_remote` (runtime.hpp RunConfig::remote_robots).
  std::vector<std::string> remote_robots;
  runtime::AttachRemote attach_remote;
  // How long a remote robot whose agent was lost waits for a new one (runtime.hpp RunConfig::rejoin_wait); 0: the
  // cell is stopped at once.
  runtime::SimDuration rejoin_wait{0};
};

// One device of the run on real I/O, for a person.
struct RealDevice {
  std::string device;  // cell device name
  std::string unit;    // "modbus 127.0.0.1:1502 unit 1"
};

// One robot of the run, for a person and the report.
struct RealRobot {
  std::string label, robot;  // program label, cell robot
  std::string driver;        // "val2 on /dev/ttyUSB0", or "an agent" for a remote robot
  bool senses_grip = false;  // its grip is sensed by its driver; false: no grip sensor, a close is taken as done
};

// "grip sensed by its driver" or "no grip sensor (a close is taken as done)", and "no wrist force sensor".
std::string describe_sensing(const RealRobot& robot);

class RealRun {
 public:
  // Builds the drivers, connects them, wires the sensors and builds the Runtime (no thread starts). Throws InputError
  // (nothing runs) when a robot of the program has no real driver (naming it and saying how to give one: --driver
  // ROBOT=movemaster:PORT or val2:PORT), a device of the program is not on real I/O (naming it and saying how to
  // put it there: --device NAME=modbus:HOST:PORT), the scenario asks for faults (the twin injects them), the
  // perception asked for is the twin's (truth from --perception, vision), the scenario has a feed (parts put on a
  // belt while the run goes, which nothing real senses yet; naming the feed), a driver cannot be made or connected,
  // or the runtime refuses the configuration. The devices' units are connected when run() starts (InputError naming
  // the unit when one cannot be reached, before anything moves).
  RealRun(const Scenario& scenario, const petri::Net& net, RealRunOptions options = {});
  ~RealRun();
  RealRun(const RealRun&) = delete;
  RealRun& operator=(const RealRun&) = delete;

  runtime::Runtime& runtime() { return *runtime_; }
  const runtime::Runtime& runtime() const { return *runtime_; }
  // The program's robots, in program order.
  const std::vector<RealRobot>& robots() const { return robots_; }
  // The program's devices, each on its unit, in the cell's order.
  const std::vector<RealDevice>& devices() const { return devices_; }
  runtime::Perception perception() const { return runtime::Perception::kCad; }

  // Runs to the end (runtime().run()), keeps the result and returns it.
  const runtime::RunResult& run();
  // The controller's environment model at the end of run() (InternalError before): the parts where it believes them.
  const runtime::EnvironmentModel& model() const;

 private:
  std::vector<std::unique_ptr<drivers::SerialDriver>> drivers_;
  std::vector<std::unique_ptr<runtime::GripSensor>> grip_sensors_;
  std::vector<RealRobot> robots_;
  std::vector<std::unique_ptr<drivers::DigitalIo>> io_;  // the Modbus units, one per endpoint
  std::vector<RealDevice> devices_;
  std::unique_ptr<runtime::Runtime> runtime_;
  std::optional<runtime::RunResult> result_;
};

}  // namespace cellwright::cell
