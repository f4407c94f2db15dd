// EmulatedCell (emulated_cell.hpp).
#include "cellwright/cell/sim/emulated_cell.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <set>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/emulate/driver_arm.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/twin_io.hpp"
#include "cellwright/twin/sim/world_plant.hpp"

namespace cellwright::cell {

namespace sim = twin::sim;  // the simulator's World, drivers and plant

namespace {

// The simulation thread's step: the cell's control period (the twin's World advances by whole timesteps).
constexpr std::chrono::milliseconds kPeriod{10};

// The I/O image in lock-step: each read of the discrete inputs first advances the twin by one scan (`advance`, on the
// serving thread, which is the simulation thread), then reads the inputs as of after it. Everything else passes.
class LockstepIo final : public drivers::DigitalIo {
 public:
  LockstepIo(drivers::DigitalIo& image, std::function<void()> advance)
      : image_(image), advance_(std::move(advance)) {}
  std::string describe() const override { return image_.describe(); }
  drivers::IoResult connect() override { return image_.connect(); }
  void close() override { image_.close(); }
  bool is_open() const override { return image_.is_open(); }
  drivers::IoResult write_coil(std::uint16_t address, bool value) override { return image_.write_coil(address, value); }
  drivers::IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override {
    return image_.read_coils(first, count, values);
  }
  drivers::IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override {
    advance_();
    return image_.read_inputs(first, count, values);
  }

 private:
  drivers::DigitalIo& image_;
  std::function<void()> advance_;
};

}  // namespace

struct EmulatedCell::Impl {
  struct Robot {
    EmulatedController controller;
    sim::SimDriver* driver = nullptr;
    std::unique_ptr<emulate::DriverArm> arm;
    std::unique_ptr<emulate::MovemasterEmulator> movemaster;
    std::unique_ptr<emulate::Val2Emulator> val2;
    std::thread thread;
    std::string error;  // why it stopped early, if it did
  };

  Impl(const Scenario& s, EmulatedCellOptions o) : scenario(s), options(std::move(o)) {}

  const Scenario& scenario;
  EmulatedCellOptions options;
  std::unique_ptr<sim::World> world;
  std::unique_ptr<sim::WorldPlant> plant;
  std::vector<Robot> robots;
  std::atomic<std::int64_t> sim_ns{0};  // the World's time after the last advance, for sim_time()
  // The I/O (options.io): the image, its lock-step decorator, the server in front of one of them.
  std::unique_ptr<sim::TwinIo> twin_io;
  std::unique_ptr<LockstepIo> lockstep_io;
  std::unique_ptr<emulate::ModbusServer> server;

  std::mutex mutex;
  std::condition_variable cv;
  bool stopping = false;
  std::atomic<bool> stop_requested{false};  // the same, read by the serving loop without the lock

  // Steps the World by dt (on the simulation thread); first a belt whose drive hangs on a controller's output
  // (`run_signal`) is run or stopped as that wire is now.
  void advance(std::chrono::nanoseconds dt) {
    const auto& conveyors = scenario.cell.conveyors;
    for (std::size_t c = 0; c < conveyors.size(); ++c) {
      if (conveyors[c].run_signal != 0) world->set_belt_run(c, world->signals().get(conveyors[c].run_signal));
    }
    plant->advance(dt);
    sim_ns = world->now().count();
  }

  // The simulation thread with the I/O served: paced, or lock-step (emulated_cell.hpp).
  void simulate_serving(std::chrono::steady_clock::duration wall_period) {
    if (options.lockstep) {
      // The World advances only inside reads of the discrete inputs (LockstepIo); the wait bounds how soon a stop is
      // seen.
      while (!stop_requested) server->serve(std::chrono::milliseconds(100));
      return;
    }
    auto next = std::chrono::steady_clock::now();
    while (!stop_requested) {
      next += wall_period;
      // Serves what arrives until the next period is due: between two steps, never during one. At least once a
      // period, so that a twin slower than the wall clock still answers.
      auto now = std::chrono::steady_clock::now();
      do {
        server->serve(std::max(std::chrono::nanoseconds(0), std::chrono::nanoseconds(next - now)));
        now = std::chrono::steady_clock::now();
      } while (now < next && !stop_requested);
      if (stop_requested) break;
      advance(kPeriod);
    }
  }

  void stop_all() {
    stop_requested = true;
    {
      std::lock_guard lock(mutex);
      stopping = true;
    }
    cv.notify_all();
    for (Robot& r : robots) {
      if (r.movemaster) r.movemaster->stop();
      if (r.val2) r.val2->stop();
      if (r.arm) r.arm->interrupt();
    }
  }

  void serve(Robot& r) {
    try {
      const emulate::ArmResult up = r.arm->start();
      if (!up.ok()) {
        r.error = fmt::format("robot '{}' could not be brought up in the twin: {}", r.controller.robot, up.message);
        stop_all();
        return;
      }
      if (r.movemaster) r.movemaster->serve(r.controller.link);
      if (r.val2) r.val2->serve(r.controller.link);
    } catch (const std::exception& e) {
      r.error = e.what();
      stop_all();
    }
  }
};

EmulatedController parse_emulated_controller(const std::string& spec, const SourceLocation& where) {
  const std::size_t eq = spec.find('=');
  const std::size_t colon = spec.find(':', eq == std::string::npos ? 0 : eq);
  if (eq == std::string::npos || eq == 0 || colon == std::string::npos || colon + 1 == spec.size()) {
    throw InputError(where, fmt::format("'{}': write ROBOT=movemaster:LINK or ROBOT=val2:LINK", spec));
  }
  EmulatedController c;
  c.robot = spec.substr(0, eq);
  const std::string language = spec.substr(eq + 1, colon - eq - 1);
  if (language == "movemaster") {
    c.language = models::DriverKind::kMovemaster;
  } else if (language == "val2") {
    c.language = models::DriverKind::kVal2;
  } else {
    throw InputError(where,
                     fmt::format("'{}': the controller language must be movemaster or val2, got '{}'", spec, language));
  }
  c.link = spec.substr(colon + 1);
  return c;
}

emulate::ModbusServerOptions parse_served_io(std::string_view spec, const SourceLocation& where) {
  constexpr std::string_view kScheme = "modbus:";
  if (spec.substr(0, kScheme.size()) != kScheme) {
    throw InputError(where, fmt::format("'{}': write modbus:HOST:PORT or modbus:HOST:PORT/UNIT", spec));
  }
  std::string_view rest = spec.substr(kScheme.size());
  int unit = 1;
  if (const std::size_t slash = rest.rfind('/'); slash != std::string_view::npos) {
    const std::string_view u = rest.substr(slash + 1);
    const auto [end, ec] = std::from_chars(u.data(), u.data() + u.size(), unit);
    if (u.empty() || ec != std::errc() || end != u.data() + u.size() || unit < 0 || unit > 255) {
      throw InputError(where, fmt::format("'{}': the unit '{}' is not a number within 0..255", spec, u));
    }
    rest = rest.substr(0, slash);
  }
  emulate::ModbusServerOptions out;
  try {
    out = emulate::parse_listen_address(rest, where);
  } catch (const InputError&) {
    throw InputError(where, fmt::format("'{}': '{}' is not HOST:PORT with a port within 0..65535 (0: a free one)",
                                        spec, rest));
  }
  out.unit = unit;
  return out;
}

EmulatedCell::EmulatedCell(const Scenario& scenario, std::vector<EmulatedController> controllers,
                           EmulatedCellOptions options, const SourceLocation& where)
    : impl_(std::make_unique<Impl>(scenario, std::move(options))) {
  Impl& m = *impl_;
  if (!(m.options.speed > 0 && std::isfinite(m.options.speed))) {
    throw InputError(where, fmt::format("the speed must be a positive number, got {}", m.options.speed));
  }
  std::set<std::string> seen;
  for (const EmulatedController& c : controllers) {
    if (scenario.cell.find_robot(c.robot) == nullptr) {
      throw InputError(
          where, fmt::format("'{}' is not a robot of the cell {}", c.robot, scenario.cell_file.filename().string()));
    }
    if (!seen.insert(c.robot).second) throw InputError(where, fmt::format("robot '{}' is emulated twice", c.robot));
    if (c.language != models::DriverKind::kMovemaster && c.language != models::DriverKind::kVal2) {
      throw InputError(where, fmt::format("robot '{}': only movemaster and val2 controllers are emulated", c.robot));
    }
  }
  if (m.options.lockstep && !m.options.io) throw InputError(where, "lock-step is for the I/O (--io)");
  if (controllers.empty() && !m.options.io) {
    throw InputError(where, "nothing to emulate: give a robot controller or the I/O (--robot, --io)");
  }
  if (m.options.lockstep && !controllers.empty()) {
    throw InputError(where, "lock-step serves the I/O alone: the robot controllers' serial lines run on the wall "
                            "clock (leave out --robot, or run paced)");
  }
  CellWorld cell = make_cell_world(scenario);
  m.world = std::move(cell.world);
  m.plant = std::make_unique<sim::WorldPlant>(*m.world, std::move(cell.feed));
  if (m.options.lockstep) {
    const std::chrono::nanoseconds scan = *m.options.lockstep;
    const std::chrono::nanoseconds step = m.world->timestep();
    if (scan.count() <= 0 || scan.count() % step.count() != 0) {
      throw InputError(where, fmt::format("the lock-step scan must be a positive whole number of the cell's timestep "
                                          "({} s), got {} s",
                                          std::chrono::duration<double>(step).count(),
                                          std::chrono::duration<double>(scan).count()));
    }
  }
  if (m.options.io) {
    m.twin_io = std::make_unique<sim::TwinIo>(*m.world);
    drivers::DigitalIo* served = m.twin_io.get();
    if (m.options.lockstep) {
      m.lockstep_io = std::make_unique<LockstepIo>(*m.twin_io, [&m] { m.advance(*m.options.lockstep); });
      served = m.lockstep_io.get();
    }
    m.server = std::make_unique<emulate::ModbusServer>(*served, *m.options.io, SourceLocation{"--io", 0, 0});
    if (m.options.log) {
      m.server->set_hook([log = m.options.log](const emulate::ServedRequest& r) {
        log(fmt::format("modbus client {}: function {}, {} value(s) from {}: {}", r.client, r.function, r.count,
                        r.address, r.exception_code == 0 ? std::string("ok")
                                                         : fmt::format("exception {}", r.exception_code)));
      });
    }
  }
  std::uint64_t index = 0;
  for (EmulatedController& c : controllers) {
    Impl::Robot r;
    const models::RobotSpec& spec = *scenario.cell.find_robot(c.robot);
    sim::SimDriverOptions driver_options;
    driver_options.where = where;
    r.driver = &m.world->add_sim_driver(c.robot, driver_options);
    const twin::RobotIds& ids = *m.world->scene().find_robot(c.robot);
    emulate::DriverArmOptions arm_options;
    arm_options.home = spec.home;
    arm_options.gripper_width = 2 * (ids.finger_range[1] - ids.finger_range[0]);
    sim::World* world = m.world.get();
    arm_options.read_input = [world](int channel) {
      return channel >= 1 && static_cast<std::size_t>(channel) <= world->signals().size() &&
             world->signals().get(channel);
    };
    r.arm = std::make_unique<emulate::DriverArm>(*r.driver, r.driver->kinematics(), arm_options);
    const std::uint64_t seed = m.options.seed + index++;
    std::function<void(int)> on_line;
    if (m.options.on_program_line) {
      on_line = [f = m.options.on_program_line, robot = c.robot](int line) { f(robot, line); };
    }
    if (c.language == models::DriverKind::kMovemaster) {
      emulate::MovemasterEmulatorOptions o;
      o.seed = seed;
      o.misbehaviours = c.misbehaviours;
      o.log = m.options.log;
      o.on_program_line = on_line;
      r.movemaster = std::make_unique<emulate::MovemasterEmulator>(*r.arm, std::move(o));
    } else {
      emulate::Val2EmulatorOptions o;
      o.seed = seed;
      o.misbehaviours = c.misbehaviours;
      o.echo = m.options.echo;
      o.log = m.options.log;
      o.on_program_step = on_line;
      r.val2 = std::make_unique<emulate::Val2Emulator>(*r.arm, std::move(o));
    }
    r.controller = std::move(c);
    m.robots.push_back(std::move(r));
  }
}

EmulatedCell::~EmulatedCell() {
  impl_->stop_all();
  for (Impl::Robot& r : impl_->robots) {
    if (r.thread.joinable()) r.thread.join();
  }
}

void EmulatedCell::stop() {
  impl_->stop_all();
}

void EmulatedCell::run() {
  Impl& m = *impl_;
  // The simulation thread: the World paced to the wall clock (at options.speed), one control period at a time.
  const auto wall_period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(kPeriod) / m.options.speed);
  std::thread sim([&m, wall_period] {
    if (m.server) {
      m.simulate_serving(wall_period);
      return;
    }
    auto next = std::chrono::steady_clock::now();
    std::unique_lock lock(m.mutex);
    while (!m.stopping) {
      next += wall_period;
      if (m.cv.wait_until(lock, next, [&] { return m.stopping; })) break;
      lock.unlock();
      m.advance(kPeriod);
      lock.lock();
    }
  });
  for (Impl::Robot& r : m.robots) r.thread = std::thread([&m, &r] { m.serve(r); });
  bool ready = true;
  for (Impl::Robot& r : m.robots) {
    // Published once each arm is home and its emulator serves (the arms home in the twin first: up to a minute).
    const bool published = r.movemaster ? r.movemaster->wait_published(1, std::chrono::seconds(60))
                                        : r.val2->wait_published(1, std::chrono::seconds(60));
    ready = ready && published;
  }
  if (ready && m.options.on_ready) m.options.on_ready();
  {
    std::unique_lock lock(m.mutex);
    m.cv.wait(lock, [&] { return m.stopping; });
  }
  m.stop_all();
  for (Impl::Robot& r : m.robots) {
    if (r.thread.joinable()) r.thread.join();
  }
  sim.join();
  for (const Impl::Robot& r : m.robots) {
    if (!r.error.empty()) throw InputError({m.scenario.source.string(), 0, 0}, r.error);
  }
  if (!ready) {
    throw InputError({m.scenario.source.string(), 0, 0}, "the emulated controllers did not come up within a minute");
  }
}

std::vector<FinalPose> EmulatedCell::final_poses() const {
  return final_poses_of(*impl_->world);
}

std::string EmulatedCell::io_endpoint() const {
  return impl_->server ? impl_->server->endpoint() : std::string();
}

std::chrono::nanoseconds EmulatedCell::sim_time() const {
  return std::chrono::nanoseconds(impl_->sim_ns.load());
}

}  // namespace cellwright::cell
