// The wiring every run of a scenario shares, whatever moves the robots: the simulated rig (cell/sim's ScenarioRun,
// the twin as the plant) and a cell of real robots with no twin (real_run.hpp). Each takes the scenario as loaded and
// checked (scenario.hpp) and preflight's net of its program; the rig then adds its drivers, plant (or none), sensors
// and perception to the runtime's configuration this makes.
//
// Thread safety: pure functions of their arguments; any thread may call them.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// The runtime's configuration of a run of `scenario`: its program, `net`, the cell as written (the controller does
// not know a perturbation), the program's bindings, the control period, the limits (sim time, settle, wall time) and
// the motion options (hand-over clearance, the decision tree). No drivers, plant, sensors, mode or perception yet.
runtime::RunConfig scenario_run_config(const Scenario& scenario, const petri::Net& net);

// Every device of the cell, as device control drives it (runtime/device_hub.hpp): each machine (start coil, busy and
// done inputs; `at` its fixture's top), conveyor (run coil) and photo-eye (its input; `at` where it looks), with the
// addresses of the cell description's `io` keys, in the cell's order; a device whose `io` lacks an address it needs
// is left out (the runtime then refuses a program that uses it). Limits are left 0 (the runtime sets them).
std::vector<runtime::DeviceWiring> cell_devices(const models::CellDescription& cell);

// One Modbus unit the scenario puts devices on (its `devices:` key and --device), and those devices' wiring.
struct RealIoUnit {
  drivers::ModbusAddress address;
  SourceLocation where;  // the choice of the unit's first device (for the unit's errors)
  std::vector<runtime::DeviceWiring> devices;
};

// The scenario's devices on real I/O, one entry per HOST:PORT/UNIT in the order its first device has in the cell,
// each with its devices in the cell's order (cell_devices). Devices on the twin's I/O are not in it.
std::vector<RealIoUnit> real_io_units(const Scenario& scenario);

// Refuses a lock-step run (`realtime` false) of a scenario with a robot on a real driver: a real arm moves on the
// wall clock and cannot wait for the simulation's steps. Throws InputError naming the driver's place.
void refuse_lockstep_with_real_drivers(const Scenario& scenario, bool realtime);

// The observer (runtime.hpp's RunObserver) that calls `progress` with the time and the firings so far every `every`
// of simulation time, on the simulation thread: `twin run`'s progress line.
runtime::RunObserver progress_observer(runtime::SimDuration every,
                                       std::function<void(runtime::SimDuration, std::uint64_t)> progress);

}  // namespace cellwright::cell
