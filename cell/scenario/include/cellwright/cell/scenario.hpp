// A scenario: everything `twin run` needs to execute a task program on the simulated cell and judge the result — the
// cell, the program, how the program's labels map onto the cell, which driver runs each robot, the workpiece feed,
// the limits and the expected outcome. docs/scenarios.md documents every field of the YAML file.
//
// Loading is in two stages, both before any thread starts:
//  1. load_scenario() reads the YAML file, the cell description and the task program, and binds every program label
//     to a cell object. Anything wrong with the input throws InputError naming the file, line and field.
//  2. the plan stage's preflight() (preflight.hpp) builds the program's Petri net, analyses it (as `twin check`
//     does), checks that every robot can reach every place its program sends it to, plans every move and sweeps the
//     moves for collisions. It reports rather than throws; Preflight::ok() says whether the run may start.
//
// Thread safety: plain values and re-entrant functions; any thread may call them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/modbus/modbus_io.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/task/compiled.hpp"
#include "cellwright/twin/faults.hpp"

namespace cellwright::cell {

// The faults a scenario asks the twin to inject are the twin's fault vocabulary (twin/faults.hpp).
using twin::fault_fields;
using twin::fault_kind;
using twin::fault_kind_names;
using twin::FaultCommand;
using twin::FaultKind;
using twin::FaultSpec;
using twin::FaultTarget;
using twin::is_driver_fault;
using twin::kFaultKinds;
using twin::needs_vision;
using twin::parse_fault;
using twin::parse_fault_text;
using twin::target_of;
using twin::to_text;

// One program label bound to a cell object: robot r1 -> puma, workpiece A -> A, location B -> output_drop.
struct Binding {
  std::string label;     // as declared in the program
  std::string name;      // the cell object it stands for
  SourceLocation where;  // the binding in the scenario file (the `robots`/`bind` entry), or the `program` field when
                         // the label is bound to the cell object of the same name by default
};

// The driver of one cell robot.
// A real driver (movemaster, val2) talks over `serial`: the cell's line settings for the robot, with the port given
// in the scenario (`drivers: {melfa: movemaster:/dev/ttyUSB0}`) or on the command line (`--driver`) taking the place
// of the cell's; without settings in the cell, the driver's defaults (docs/real-robots.md).
struct DriverChoice {
  std::string robot;  // cell robot name
  models::DriverKind kind = models::DriverKind::kSim;
  SourceLocation where;  // the `drivers` entry, or the robot in the cell file when the cell's choice is used
  std::optional<models::SerialSettings> serial;  // set for a real driver whose port is known
  bool real() const { return kind != models::DriverKind::kSim; }
};

// Where one device of the cell gets its I/O (docs/devices.md, "Which unit"): the twin's I/O image, or a Modbus TCP
// unit at the cell's `io` addresses (a PLC, a remote-I/O module: real I/O). Chosen in the scenario (`devices: {mill:
// modbus:127.0.0.1:1502/1, input: twin}`) or on the command line (`--device NAME=modbus:HOST:PORT[/UNIT]`, which
// replaces the scenario's choice). `device` is a machine, conveyor or photo-eye of the cell that its `io` keys wire
// and that the program declares.
struct DeviceChoice {
  std::string device;                            // cell device name
  std::optional<drivers::ModbusAddress> modbus;  // set: on this Modbus TCP unit; unset: the twin's I/O
  SourceLocation where;                          // the `devices` entry or `--device`
  bool real() const { return modbus.has_value(); }
};

// Workpieces put on a conveyor during the run, one every `period` seconds from `start` on, in the listed order. They
// are cell workpieces: before their turn they are kept out of the cell (the simulated world parks them), then they
// appear at rest on the conveyor's entry point (ConveyorSpec::enter).
//
// A shift: with `count` greater than the list, the list's bodies are fed again and again in list order, each once it
// has left the cell (carried to the end of another conveyor: the world takes it out there and reports it as
// delivered), so that a few bodies make a thousand parts. An arrival whose body is still in the cell waits for it.
struct Feed {
  std::string conveyor;
  std::vector<std::string> workpieces;  // cell workpiece names, in order of arrival
  double start = 0;                     // s, sim time of the first arrival
  double period = 0;                    // s between arrivals (> 0 when more than one)
  std::size_t count = 0;                // parts fed in all (at least workpieces.size())
  SourceLocation where;

  // Whether bodies are fed more than once.
  bool recycles() const { return count > workpieces.size(); }
  // In a shift, the conveyors that carry parts out of the cell: every conveyor of the cell but the feed's (the world
  // takes a part out at the end of one, and its body is free to be fed again). Empty when the feed does not recycle;
  // the scenario loader refuses a recycling feed with none.
  std::vector<const models::ConveyorSpec*> exits(const models::CellDescription& cell) const;
  // The body of the i-th part fed.
  const std::string& workpiece_at(std::size_t i) const { return workpieces[i % workpieces.size()]; }

  // Sim time at which workpieces[i] arrives.
  double arrival(std::size_t i) const { return start + period * static_cast<double>(i); }
  // Whether the feed brings this cell workpiece.
  bool feeds(std::string_view workpiece) const {
    return std::find(workpieces.begin(), workpieces.end(), workpiece) != workpieces.end();
  }
};

// The place of an expectation that the scenario expects the controller to lose the part (`expect: {A: lost}`, e.g.
// with an unreachable or missing fault): the run is judged by whether the controller declared it lost.
inline constexpr std::string_view kLostPlace = "lost";

// Where a workpiece must end up: a cell location, conveyor or machine (its fixture or top), within `tolerance`; or
// place == kLostPlace: the controller must declare the part lost (docs/faults.md section 5).
struct Expectation {
  std::string workpiece;  // cell workpiece name
  std::string place;      // cell location, conveyor or machine name, or "lost"
  double tolerance = 0;   // m (not used for "lost")
  SourceLocation where;

  // The scenario expects the part to be lost (place "lost").
  bool lost() const { return place == kLostPlace; }
};

struct Limits {
  double sim_time = 300;  // s of simulated time; the run fails when the program has not finished by then
  double wall_time = 0;   // s of wall-clock time; 0 = no limit
};

struct Options {
  bool realtime = false;         // pace the simulation to the wall clock (default: lock-step on the virtual clock)
  double control_period = 0.01;  // s of sim time between the control threads' turns
  double settle_time = 1.0;      // s simulated after the program finishes, before the outcome is judged
  // m: how far a taker's tool stays back from the hand-over grasp while it waits for the giver (hand_approach);
  // the runtime's TargetOptions default unless the scenario sets it.
  double handover_clearance = runtime::TargetOptions{}.handover_clearance;
};

// The camera the image-processing thread looks through (perception: vision).
struct VisionSettings {
  std::string camera;   // a cell camera
  double period = 0.4;  // s of simulation time between frames
  SourceLocation where;
};

// Where listed workpieces really start or arrive, unknown to the cell description (and so to the controller's model):
// each is moved in its own frame (x along the conveyor it rides, or as the location it stands at is turned) by
// between half and all of `offset` along each axis, either way, and turned by up to `yaw` either way; amounts and signs
// are drawn from the scenario's seed.
struct Perturbation {
  std::vector<std::string> workpieces;               // cell workpiece names
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();  // m, along the part's x and y
  double yaw = 0;                                    // radians
  SourceLocation where;
};

// The offsets a perturbation gives each of its workpieces (a pose in the part's nominal frame), drawn from `seed`:
// the same seed gives the same offsets.
std::map<std::string, Eigen::Isometry3d> draw_perturbation(const Perturbation& p, std::uint64_t seed);

struct Scenario {
  std::filesystem::path source;        // the scenario file (absolute)
  std::filesystem::path cell_file;     // absolute
  std::filesystem::path program_file;  // absolute
  models::CellDescription cell;        // the cell description, with the scenario's own `locations` appended
  task::CompiledProgram program;
  std::uint64_t seed = 1;
  std::vector<Binding> robots;        // one per program robot, in program order
  std::vector<Binding> workpieces;    // one per program workpiece, in program order
  std::vector<Binding> locations;     // one per program location, in program order
  std::vector<DriverChoice> drivers;  // one per cell robot, in cell order
  // The devices put on a unit explicitly (`devices:`, then `--device`), in the order given, each device once; a
  // device of the program not listed is on the twin's I/O.
  std::vector<DeviceChoice> devices;
  std::optional<Feed> feed;
  Limits limits;
  std::vector<Expectation> expect;  // in file order
  Options options;
  runtime::Perception perception = runtime::Perception::kTruth;  // `perception:` truth (default), vision or cad
  std::optional<VisionSettings> vision;                          // set when perception is vision
  std::optional<Perturbation> perturb;
  // How the controller recovers from faults (`recovery:`, docs/faults.md): the decision tree (the standard one unless
  // the scenario names a file) and the watchdogs' times.
  runtime::RecoveryOptions recovery;
  std::filesystem::path recovery_file;  // absolute; empty: the standard tree
  // The safety layer (`safety:`): the limits of a coordinated carry (carry_error m, carry_turn degrees in the file,
  // squeeze_force N); the rest as runtime::SafetyOptions has them.
  runtime::SafetyOptions safety;
  // Faults to inject on purpose (`faults:`, and `twin run --fault`), in file order (docs/faults.md).
  std::vector<FaultSpec> faults;

  // The cell object bound to a program label of that kind; throws InternalError for an unknown label (the loader
  // binds every label, so that is a bug).
  const std::string& robot_of(std::string_view label) const;
  const std::string& workpiece_of(std::string_view label) const;
  const std::string& location_of(std::string_view label) const;
};

// Reads a scenario file, the cell description and the task program it names (paths relative to the scenario file),
// compiles the program and binds its labels. Throws InputError naming the scenario file, line, column and field when:
// the file is missing or is not YAML; a field is unknown, missing, given twice or of the wrong type or range; the
// cell or program file is missing or wrong (the error from load_cell / compile, which names that file); a location
// of the scenario reuses a cell name or is `at` nothing of the cell; a binding
// names a label the program does not declare, or a cell object that does not exist or is of the wrong kind; a
// program robot, workpiece or location is bound to nothing in the cell (no explicit binding and no cell object of the
// same name); two labels are bound to one cell object; a driver is named for a robot that is not in the cell, is not
// one of sim/movemaster/val2, or is a real driver (movemaster, val2) whose serial port is not known; the feed names an
// unknown conveyor or workpiece, a workpiece twice, or lacks a period for several workpieces; an expectation names an
// unknown workpiece or place (`lost` is always a place); a fault is wrong (faults.hpp: parse_fault), or needs
// perception vision (frame_lost, detection_noise) and the scenario's perception is not vision; a `devices` entry names
// no machine, conveyor or photo-eye of the cell, one whose `io` lacks an address device control needs, one the
// program does not declare, or a unit that is neither `twin` nor a well-formed modbus:HOST:PORT[/UNIT].
Scenario load_scenario(const std::filesystem::path& yaml_file);

// As load_scenario, from YAML text; `source` names the text in errors and its directory resolves relative paths.
Scenario parse_scenario(std::string_view yaml_text, const std::filesystem::path& source);

// "sim", "movemaster", "val2".
const char* to_string(models::DriverKind kind);

// Puts robot ROBOT on a driver as `spec` says: "ROBOT=sim", "ROBOT=movemaster[:PORT]" or "ROBOT=val2[:PORT]" (the
// command line's `--driver`), replacing the scenario's choice; nothing else of the scenario changes. Throws
// InputError naming `where` and the text when the spec is malformed, names no robot of the cell, or leaves a real
// driver without a port.
void set_driver(Scenario& scenario, const std::string& spec, const SourceLocation& where);
// True when some robot the program uses runs on a real driver.
bool uses_real_drivers(const Scenario& scenario);

// Puts devices on units as `specs` say, each "NAME=modbus:HOST:PORT[/UNIT]" or "NAME=twin" (the command line's
// `--device`), replacing the scenario's choice for NAME or adding one; nothing else of the scenario changes. Throws
// InputError naming `where` and the text when a spec is malformed, NAME is no device of the cell, has no complete
// `io` addresses or is not declared by the program, the address is bad (drivers::parse_modbus_address), or two
// specs name one device.
void set_devices(Scenario& scenario, const std::vector<std::string>& specs, const SourceLocation& where);
// The choice for cell device `name`, or nullptr when it is on the twin's I/O by default.
const DeviceChoice* find_device_choice(const Scenario& scenario, std::string_view name);
// True when some device is on real I/O (a Modbus unit).
bool uses_real_devices(const Scenario& scenario);

}  // namespace cellwright::cell
