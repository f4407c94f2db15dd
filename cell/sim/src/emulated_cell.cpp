// EmulatedCell (emulated_cell.hpp).
#include "cellwright/cell/sim/emulated_cell.hpp"

#include <fmt/format.h>

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
#include "cellwright/twin/sim/world_plant.hpp"

namespace cellwright::cell {

namespace sim = twin::sim;  // the simulator's World, drivers and plant

namespace {

// The simulation thread's step: the cell's control period (the twin's World advances by whole timesteps).
constexpr std::chrono::milliseconds kPeriod{10};

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

  std::mutex mutex;
  std::condition_variable cv;
  bool stopping = false;

  void stop_all() {
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
  CellWorld cell = make_cell_world(scenario);
  m.world = std::move(cell.world);
  m.plant = std::make_unique<sim::WorldPlant>(*m.world, std::move(cell.feed));
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
    auto next = std::chrono::steady_clock::now();
    std::unique_lock lock(m.mutex);
    while (!m.stopping) {
      next += wall_period;
      if (m.cv.wait_until(lock, next, [&] { return m.stopping; })) break;
      lock.unlock();
      m.plant->advance(kPeriod);
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

}  // namespace cellwright::cell
