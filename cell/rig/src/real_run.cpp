// A run of a cell of real robots with no twin (real_run.hpp).
#include "cellwright/cell/real_run.hpp"

#include <fmt/format.h>

#include <memory>
#include <utility>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/modbus/modbus_io.hpp"
#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/real_drivers.hpp"
#include "cellwright/cell/run_wiring.hpp"

namespace cellwright::cell {

std::string describe_sensing(const RealRobot& r) {
  return fmt::format("{}, no wrist force sensor",
                     r.senses_grip ? "grip sensed by its driver" : "no grip sensor (a close is taken as done)");
}

RealRun::RealRun(const Scenario& s, const petri::Net& net, RealRunOptions options) {
  // Every check before anything is connected.
  const auto remote = [&](const std::string& robot) {
    return std::find(options.remote_robots.begin(), options.remote_robots.end(), robot) != options.remote_robots.end();
  };
  for (const Binding& b : s.robots) {
    if (remote(b.name)) continue;  // its agent has its driver
    const auto d = std::find_if(s.drivers.begin(), s.drivers.end(),
                                [&](const DriverChoice& c) { return c.robot == b.name && c.real(); });
    if (d == s.drivers.end()) {
      throw InputError(b.where, fmt::format("robot '{}' ({} in the program) has no real driver, and a run without the "
                                            "twin moves real robots only: give it one with --driver {}=movemaster:PORT "
                                            "or --driver {}=val2:PORT",
                                            b.name, b.label, b.name, b.name));
    }
  }
  // Every device of the program on real I/O: a run without the twin has no twin I/O image.
  const std::vector<runtime::DeviceWiring> wired = cell_devices(s.cell);
  for (const runtime::DeviceWiring& w : wired) {
    if (!task::declares_device(s.program, w.name)) continue;
    const DeviceChoice* choice = find_device_choice(s, w.name);
    if (choice == nullptr || !choice->real()) {
      throw InputError(choice != nullptr ? choice->where : SourceLocation{s.source.string(), 0, 0},
                       fmt::format("device '{}' of the program {} is on the twin's I/O, and a run without the twin "
                                   "has no twin I/O: give it --device {}=modbus:HOST:PORT[/UNIT] (or `devices: {{{}: "
                                   "modbus:HOST:PORT}}` in the scenario)",
                                   w.name, s.program_file.filename().string(), w.name, w.name));
    }
  }
  if (s.feed) {
    throw InputError(s.feed->where,
                     fmt::format("the feed is the twin putting parts on conveyor '{}' while the run goes, and a run "
                                 "of real robots without the twin has no twin to put them there nor an environment "
                                 "model that learns where a real part arrived (a photo-eye on real I/O says only that "
                                 "one is there); run the feed on the twin",
                                 s.feed->conveyor));
  }
  for (const FaultSpec& f : s.faults) {
    throw InputError(f.where, fmt::format("a {} fault is injected by the twin, and a run of real robots without the "
                                          "twin injects nothing: leave the scenario's faults and --fault out",
                                          to_string(f.kind)));
  }
  if (options.perception && *options.perception != runtime::Perception::kCad) {
    throw InputError({"--perception", 0, 0},
                     fmt::format("perception {} is the twin's, and a run of real robots without the twin has only "
                                 "the cell description (cad)",
                                 runtime::to_string(*options.perception)));
  }
  if (!options.perception && s.perception == runtime::Perception::kVision) {
    throw InputError({s.source.string(), 0, 0},
                     "the scenario's perception is vision, whose frames the twin renders, and a run of real robots "
                     "without the twin has no camera: run it with --perception cad");
  }

  runtime::RunConfig config = scenario_run_config(s, net);
  for (const Binding& b : s.robots) {
    if (remote(b.name)) {
      robots_.push_back({b.label, b.name, "an agent (DDS)", false});
      continue;
    }
    const DriverChoice& choice = *std::find_if(s.drivers.begin(), s.drivers.end(),
                                               [&](const DriverChoice& c) { return c.robot == b.name && c.real(); });
    drivers_.push_back(make_real_driver(choice, *s.cell.find_robot(b.name)));
    drivers::SerialDriver& driver = *drivers_.back();
    connect_real_driver(driver, choice);
    bring_up_checked(driver, choice, *s.cell.find_robot(b.name));  // homes, reads and cross-checks: refuses here
    config.drivers[b.name] = &driver;
    if (runtime::GripSensor* grip = runtime::grip_sensor_for(driver, nullptr, grip_sensors_)) {
      config.sensors.grip[b.name] = grip;
    }
    robots_.push_back({b.label, b.name,
                       fmt::format("{} on {}", to_string(choice.kind), choice.serial ? choice.serial->port : ""),
                       driver.capabilities().senses_grip});
  }
  // One Modbus unit per endpoint, with the program's devices on it (connected when the run starts: InputError naming
  // the unit when one cannot be reached).
  for (RealIoUnit& u : real_io_units(s)) {
    io_.push_back(std::make_unique<drivers::ModbusIo>(u.address, drivers::ModbusIoOptions{}, u.where));
    for (const runtime::DeviceWiring& w : u.devices) devices_.push_back({w.name, io_.back()->describe()});
    config.io_units.push_back(runtime::IoUnit{io_.back().get(), true, std::move(u.devices)});
  }
  config.remote_robots = options.remote_robots;
  config.attach_remote = std::move(options.attach_remote);
  config.rejoin_wait = options.rejoin_wait;
  config.plant = nullptr;  // nothing simulated: the robots move by themselves
  config.mode = runtime::Mode::kRealtime;
  config.realtime_speed = options.speed;
  config.perception = runtime::Perception::kCad;
  if (options.log_stream != nullptr) {
    config.log_stream = options.log_stream;
    config.keep_log = false;
  }
  if (options.on_progress) {
    config.observers.push_back(progress_observer(options.progress_every, std::move(options.on_progress)));
  }
  runtime_ = std::make_unique<runtime::Runtime>(std::move(config));
}

RealRun::~RealRun() {
  runtime_.reset();  // joins the threads before the drivers and sensors they use go
}

const runtime::RunResult& RealRun::run() {
  result_ = runtime_->run();
  return *result_;
}

const runtime::EnvironmentModel& RealRun::model() const {
  CW_CHECK(result_.has_value(), "the model of a real run is read after run()");
  return result_->environment;
}

}  // namespace cellwright::cell
