// The wiring every run of a scenario shares (run_wiring.hpp).
#include <algorithm>
#include "cellwright/cell/run_wiring.hpp"

#include <fmt/format.h>

#include <chrono>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::cell {

namespace {

runtime::SimDuration seconds(double s) {
  return std::chrono::duration_cast<runtime::SimDuration>(std::chrono::duration<double>(s));
}

}  // namespace

runtime::RunConfig scenario_run_config(const Scenario& s, const petri::Net& net) {
  runtime::RunConfig config;
  config.program = s.program;
  config.net = net;
  config.cell = s.cell;
  config.binding.where = {s.source.string(), 0, 0};
  for (const Binding& b : s.robots) config.binding.robots[b.label] = {b.name, b.where};
  for (const Binding& b : s.workpieces) config.binding.objects[b.label] = {b.name, b.where};
  for (const Binding& b : s.locations) {
    // A machine's label is bound to its fixture for the moves; the runtime binds its device itself (same name).
    const auto& m = s.program.machines;
    if (std::find(m.begin(), m.end(), b.label) == m.end()) config.binding.objects[b.label] = {b.name, b.where};
  }
  config.period = seconds(s.options.control_period);
  config.limits.sim_time = seconds(s.limits.sim_time);
  config.limits.settle = seconds(s.options.settle_time);
  config.limits.wall_time = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(s.limits.wall_time));
  config.motion.targets.handover_clearance = s.options.handover_clearance;
  config.motion.recovery = s.recovery;
  config.motion.safety = s.safety;
  return config;
}

std::vector<runtime::DeviceWiring> cell_devices(const models::CellDescription& cell) {
  std::vector<runtime::DeviceWiring> out;
  for (const models::MachineSpec& m : cell.machines) {
    runtime::DeviceWiring w;
    w.name = m.name;
    w.kind = runtime::DeviceKind::kMachine;
    w.coil = m.start_io.address;
    w.busy = m.busy_io.address;
    w.input = m.done_io.address;
    w.at = m.fixture_top().xyz;
    if (w.coil >= 0 && w.busy >= 0 && w.input >= 0) out.push_back(w);
  }
  for (const models::ConveyorSpec& c : cell.conveyors) {
    runtime::DeviceWiring w;
    w.name = c.name;
    w.kind = runtime::DeviceKind::kConveyor;
    w.coil = c.run_io.address;
    w.at = c.belt_point(c.leave);
    if (w.coil >= 0) out.push_back(w);
    const auto eye = [&](const std::string& name, const models::IoAddress& io, double s) {
      runtime::DeviceWiring e;
      e.name = name;
      e.kind = runtime::DeviceKind::kSensor;
      e.input = io.address;
      e.at = c.belt_point(s);
      if (e.input >= 0) out.push_back(e);
    };
    if (c.stop_eye) eye(c.stop_eye_name, c.stop_eye_io, c.leave);
    if (c.drop_eye) eye(c.drop_eye_name, c.drop_eye_io, c.enter);
  }
  return out;
}

std::vector<RealIoUnit> real_io_units(const Scenario& scenario) {
  std::vector<RealIoUnit> out;
  for (const runtime::DeviceWiring& w : cell_devices(scenario.cell)) {
    const DeviceChoice* choice = find_device_choice(scenario, w.name);
    if (choice == nullptr || !choice->real()) continue;
    auto unit = std::find_if(out.begin(), out.end(),
                             [&](const RealIoUnit& u) { return u.address.str() == choice->modbus->str(); });
    if (unit == out.end()) unit = out.insert(out.end(), RealIoUnit{*choice->modbus, choice->where, {}});
    unit->devices.push_back(w);
  }
  return out;
}

void refuse_lockstep_with_real_drivers(const Scenario& s, bool realtime) {
  if (!uses_real_drivers(s) || realtime) return;
  for (const DriverChoice& d : s.drivers) {
    if (!d.real()) continue;
    throw InputError(d.where, fmt::format("robot '{}' is on the real {} driver, and lock-step is refused with a "
                                          "real driver: a real arm moves on the wall clock and cannot wait for the "
                                          "simulation's steps; run with --realtime",
                                          d.robot, to_string(d.kind)));
  }
}

runtime::RunObserver progress_observer(runtime::SimDuration every,
                                       std::function<void(runtime::SimDuration, std::uint64_t)> progress) {
  return {every, false, [progress = std::move(progress)](const runtime::Observation& o) {
            progress(o.time, o.firings);
          }};
}

}  // namespace cellwright::cell
