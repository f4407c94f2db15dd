// Reading a scenario file and checking it before anything runs (scenario.hpp; format in docs/scenarios.md).
#include "cellwright/cell/scenario.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include "cellwright/common/files.hpp"
#include "cellwright/models/yaml_fields.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/loop_control.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::cell {

std::vector<const models::ConveyorSpec*> Feed::exits(const models::CellDescription& cell) const {
  std::vector<const models::ConveyorSpec*> out;
  if (!recycles()) return out;
  for (const models::ConveyorSpec& c : cell.conveyors) {
    if (c.name != conveyor) out.push_back(&c);
  }
  return out;
}

namespace {

// YAML with positions in every error: the project's one field reader (yaml_fields.hpp).
using models::yaml::describe;
using models::yaml::Doc;
using models::yaml::Fields;
using models::yaml::Range;

// What a scenario cannot need (docs/scenarios.md, "Bounds"): times beyond about eleven days would overflow nothing
// (the clock counts nanoseconds in 64 bits, up to 292 years) but are typos; the rest as in the cell (models::bounds).
constexpr double kMaxSeconds = 1e6;
constexpr Range kDuration{0, kMaxSeconds, true, "s"};     // a period, a timeout, a limit: more than 0
constexpr Range kInstant{0, kMaxSeconds, false, "s"};     // a start time: 0 or later
constexpr Range kLength{0, models::bounds::kMaxReach, true, "m"};  // a height, a clearance, a tolerance
constexpr Range kStandSize{models::bounds::kMinSize, models::bounds::kMaxReach, false, "m"};  // a stand's footprint
constexpr double kMinStandHeight = 0.01;  // m: a location lower than this rests on the floor, not on a stand

std::string list_names(const std::vector<std::string>& names) {
  if (names.empty()) return "none";
  std::string out;
  for (const auto& n : names) out += fmt::format("{}{}", out.empty() ? "" : ", ", n);
  return out;
}

template <typename T>
std::vector<std::string> names_of(const std::vector<T>& items) {
  std::vector<std::string> out;
  for (const auto& i : items) out.push_back(i.name);
  return out;
}

std::filesystem::path resolve(const std::filesystem::path& base_dir, const std::string& p) {
  std::filesystem::path path(p);
  if (path.is_relative()) path = base_dir / path;
  return path.lexically_normal();
}

std::optional<models::DriverKind> driver_kind(const std::string& s) {
  if (s == "sim") return models::DriverKind::kSim;
  if (s == "movemaster") return models::DriverKind::kMovemaster;
  if (s == "val2") return models::DriverKind::kVal2;
  return std::nullopt;
}

// The driver `text` ("sim", "movemaster", "val2:/dev/ttyS1") chooses for cell robot `robot`. The port replaces the
// cell's; the cell's other line settings stay, or the driver's defaults when the cell has none.
DriverChoice choose_driver(const models::RobotSpec& robot, const std::string& text, const SourceLocation& where) {
  const std::size_t colon = text.find(':');
  const std::string name = text.substr(0, colon);
  const auto kind = driver_kind(name);
  if (!kind) {
    throw InputError(where, fmt::format("the driver of robot '{}' must be sim, movemaster or val2 (with a port after "
                                        "':' for the last two), got '{}'",
                                        robot.name, text));
  }
  DriverChoice d;
  d.robot = robot.name;
  d.kind = *kind;
  d.where = where;
  if (colon != std::string::npos) {
    const std::string port = text.substr(colon + 1);
    if (*kind == models::DriverKind::kSim) {
      throw InputError(where, fmt::format("robot '{}': the sim driver takes no port, got '{}'", robot.name, text));
    }
    if (port.empty()) throw InputError(where, fmt::format("robot '{}': no port after '{}:'", robot.name, name));
    if (robot.serial && robot.driver == *kind) {
      d.serial = robot.serial;
    } else if (*kind == models::DriverKind::kMovemaster) {
      d.serial = models::SerialSettings{"", 9600, 7, models::Parity::kEven, 2, true, true};
    } else {
      d.serial = models::SerialSettings{"", 9600, 8, models::Parity::kNone, 1, false, false};
    }
    d.serial->port = port;
  } else if (*kind != models::DriverKind::kSim && robot.serial && robot.driver == *kind) {
    d.serial = robot.serial;
  }
  return d;
}

// A real driver must know its port.
void check_driver(const DriverChoice& d) {
  if (d.real() && !d.serial) {
    throw InputError(d.where, fmt::format("robot '{}' on the {} driver needs a serial port: give it with the driver "
                                          "({}:/dev/ttyUSB0) or in the cell (`serial: {{port: ...}}`)",
                                          d.robot, to_string(d.kind), to_string(d.kind)));
  }
}

// What device control needs of cell device `name` and its `io` key lacks: "" when it is all there, "?" when the cell
// has no machine, conveyor or photo-eye of that name.
std::string io_lacking(const models::CellDescription& cell, const std::string& name) {
  if (const models::MachineSpec* m = cell.find_machine(name)) {
    if (m->start_io.address >= 0 && m->busy_io.address >= 0 && m->done_io.address >= 0) return "";
    return fmt::format("machine '{}' needs `io: {{start: COIL, busy: INPUT, done: INPUT}}`", name);
  }
  if (const models::ConveyorSpec* c = cell.find_conveyor(name)) {
    return c->run_io.address >= 0 ? "" : fmt::format("conveyor '{}' needs `io: {{run: COIL}}`", name);
  }
  for (const models::ConveyorSpec& c : cell.conveyors) {
    if ((c.stop_eye && c.stop_eye_name == name) || (c.drop_eye && c.drop_eye_name == name)) {
      const models::IoAddress& io = c.stop_eye && c.stop_eye_name == name ? c.stop_eye_io : c.drop_eye_io;
      return io.address >= 0 ? "" : fmt::format("photo-eye '{}' of conveyor '{}' needs `io: INPUT`", name, c.name);
    }
  }
  return "?";
}

// The unit `text` ("twin", "modbus:HOST:PORT[/UNIT]") chosen for device `name` of the scenario's cell and program.
// InputError at `where_name` for the device, at `where_text` for the unit.
DeviceChoice choose_device(const Scenario& s, const std::string& name, const std::string& text,
                           const SourceLocation& where_name, const SourceLocation& where_text) {
  const std::string lacking = io_lacking(s.cell, name);
  if (lacking == "?") {
    std::vector<std::string> known;
    for (const models::MachineSpec& m : s.cell.machines) known.push_back(m.name);
    for (const models::ConveyorSpec& c : s.cell.conveyors) {
      known.push_back(c.name);
      if (c.stop_eye) known.push_back(c.stop_eye_name);
      if (c.drop_eye) known.push_back(c.drop_eye_name);
    }
    throw InputError(where_name, fmt::format("the cell {} has no device '{}' (its machines, conveyors and photo-eyes: "
                                             "{})",
                                             s.cell_file.filename().string(), name, list_names(known)));
  }
  if (!lacking.empty()) {
    throw InputError(where_name, fmt::format("device '{}' is not wired to I/O in the cell {}: {} "
                                             "(docs/cell-description.md, \"io\")",
                                             name, s.cell_file.filename().string(), lacking));
  }
  if (!task::declares_device(s.program, name)) {
    throw InputError(where_name, fmt::format("the program {} does not declare device '{}', so nothing would drive it "
                                             "(declare it: `machine`, `conveyor` or `sensor ... on`)",
                                             s.program_file.filename().string(), name));
  }
  DeviceChoice d;
  d.device = name;
  d.where = where_text;
  if (text != "twin") {
    if (!text.starts_with("modbus:")) {
      throw InputError(where_text, fmt::format("device '{}': the unit must be twin or modbus:HOST:PORT[/UNIT], got "
                                               "'{}'",
                                               name, text));
    }
    d.modbus = drivers::parse_modbus_address(text, where_text);
  }
  return d;
}

// Reads an error of another file (the cell, the program) and says that the scenario led there, keeping the other
// file's position: that is where the user must look.
template <typename F>
auto with_context(const Doc& doc, const YAML::Node& field, const std::string& what, F&& fn) {
  try {
    return fn();
  } catch (const InputError& e) {
    if (e.where().file == doc.file() || e.where().line > 0) throw;
    // The other file could not be opened: point at the scenario field that names it.
    throw InputError(doc.at(field), fmt::format("{}: {}", what, e.what()));
  }
}

// The kind of label in a program, and the labels of that kind.
struct LabelKind {
  const char* noun;                        // "robot"
  const std::vector<std::string>* labels;  // the program's labels of that kind
};

// Every name the cell already uses (all kinds share one namespace in the cell description).
std::vector<std::string> cell_names(const models::CellDescription& c) {
  std::vector<std::string> out;
  for (const auto& x : c.robots) out.push_back(x.name);
  for (const auto& x : c.conveyors) out.push_back(x.name);
  for (const auto& x : c.machines) out.push_back(x.name);
  for (const auto& x : c.workpieces) out.push_back(x.name);
  for (const auto& x : c.locations) out.push_back(x.name);
  for (const auto& x : c.cameras) out.push_back(x.name);
  for (const auto& x : c.lights) out.push_back(x.name);
  if (c.handover) out.push_back(c.handover->name);
  return out;
}

// A location of the scenario, in the cell description's format (docs/cell-description.md): `at` a conveyor's entry
// or exit point or a machine's fixture plus a world `offset`, or an explicit `pose`; `yaw` in degrees; optional
// grasp and approach heights. Which robots must reach it follows from the program (preflight).
models::LocationSpec read_location(const Doc& doc, const models::CellDescription& cell, const YAML::Node& n) {
  const Fields f(doc, n, "a location of the scenario",
                 {"name", "at", "offset", "pose", "yaw", "grasp_height", "approach_height", "stand"});
  models::LocationSpec l;
  l.where = doc.at(n);
  l.name = f.word("name");
  const std::vector<std::string> taken = cell_names(cell);
  const bool valid = (std::isalpha(static_cast<unsigned char>(l.name[0])) || l.name[0] == '_') &&
                     std::all_of(l.name.begin(), l.name.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
                     });
  if (!valid || l.name.size() > 64) {
    doc.fail(f.node("name"), fmt::format("location name '{}' is not valid: use letters, digits, '_' and '-', starting "
                                         "with a letter or '_', at most 64 characters",
                                         l.name));
  }
  if (std::find(taken.begin(), taken.end(), l.name) != taken.end()) {
    doc.fail(f.node("name"), fmt::format("location '{}': the name is already used in the cell", l.name));
  }
  if (f.has("at") == f.has("pose")) {
    doc.fail(n, fmt::format("location '{}' needs either 'at' or 'pose'", l.name));
  }
  const double yaw =
      f.within_or("yaw", 0.0, Range{-models::bounds::kAngle, models::bounds::kAngle, false, "degrees"}) *
      std::numbers::pi / 180.0;
  auto vec3 = [&](const YAML::Node& v, const std::string& what) {
    if (!v.IsSequence() || v.size() != 3) doc.fail(v, fmt::format("{} must be a list of 3 numbers", what));
    Eigen::Vector3d out;
    for (std::size_t i = 0; i < 3; ++i) {
      double x = 0;
      if (!v[i].IsScalar() || !YAML::convert<double>::decode(v[i], x) || !std::isfinite(x)) {
        doc.fail(v[i], fmt::format("{} must be a list of 3 numbers, got {}", what, describe(v[i])));
      }
      f.within_of(v[i], what, Range{-models::bounds::kPosition, models::bounds::kPosition, false, "m"});
      out[static_cast<Eigen::Index>(i)] = x;
    }
    return out;
  };
  if (f.has("pose")) {
    const Fields pf(doc, f.node("pose"), fmt::format("the pose of location '{}'", l.name), {"xyz"});
    l.pose.xyz = vec3(pf.node("xyz"), pf.field("xyz"));
    l.pose.rpy = Eigen::Vector3d(0, 0, yaw);
  } else {
    const std::string ref = f.word("at");
    const auto dot = ref.rfind('.');
    const std::string object = dot == std::string::npos ? ref : ref.substr(0, dot);
    const std::string point = dot == std::string::npos ? "" : ref.substr(dot + 1);
    if (const models::ConveyorSpec* c = cell.find_conveyor(object);
        c != nullptr && (point == "enter" || point == "leave")) {
      l.pose.xyz = c->belt_point(point == "enter" ? c->enter : c->leave);
      l.pose.rpy = Eigen::Vector3d(0, 0, c->pose.rpy.z() + yaw);
    } else if (const models::MachineSpec* m = cell.find_machine(object); m != nullptr && point == "fixture") {
      l.pose = m->fixture_top();
      l.pose.rpy.z() += yaw;
    } else {
      doc.fail(f.node("at"), fmt::format("location '{}': 'at' must be <conveyor>.enter, <conveyor>.leave or "
                                         "<machine>.fixture of the cell, got '{}'",
                                         l.name, ref));
    }
    if (f.has("offset")) l.pose.xyz += vec3(f.node("offset"), f.field("offset"));
  }
  l.grasp_height = f.within_or("grasp_height", l.grasp_height, kLength);
  l.approach_height = f.within_or("approach_height", l.approach_height, kLength);
  if (f.has("stand")) {
    // A stand built under the location: its footprint [x, y]; it reaches from the floor up to the location.
    const YAML::Node& v = f.node("stand");
    if (!v.IsSequence() || v.size() != 2) {
      doc.fail(v, fmt::format("{} must be a list of 2 sizes [x, y] in m", f.field("stand")));
    }
    Eigen::Vector2d size;
    for (std::size_t i = 0; i < 2; ++i) {
      size[static_cast<Eigen::Index>(i)] = f.within_of(v[i], f.field("stand"), kStandSize);
    }
    if (l.pose.xyz.z() < kMinStandHeight) {
      doc.fail(v, fmt::format("location '{}' is {:.3f} m above the floor: a stand under it must be at least {} m high",
                              l.name, l.pose.xyz.z(), kMinStandHeight));
    }
    l.stand = size;
  }
  return l;
}

}  // namespace

void set_driver(Scenario& scenario, const std::string& spec, const SourceLocation& where) {
  const std::size_t eq = spec.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw InputError(where, fmt::format("'{}': write ROBOT=sim, ROBOT=movemaster:PORT or ROBOT=val2:PORT", spec));
  }
  const std::string robot = spec.substr(0, eq);
  const models::RobotSpec* r = scenario.cell.find_robot(robot);
  if (r == nullptr) {
    throw InputError(where,
                     fmt::format("'{}' names '{}', which is not a robot of the cell {} (robots: {})", spec, robot,
                                 scenario.cell_file.filename().string(), list_names(names_of(scenario.cell.robots))));
  }
  DriverChoice d = choose_driver(*r, spec.substr(eq + 1), where);
  check_driver(d);
  for (DriverChoice& c : scenario.drivers) {
    if (c.robot == robot) c = std::move(d);
  }
}

void set_devices(Scenario& scenario, const std::vector<std::string>& specs, const SourceLocation& where) {
  std::vector<std::string> given;
  for (const std::string& spec : specs) {
    const std::size_t eq = spec.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw InputError(where, fmt::format("'{}': expected NAME=modbus:HOST:PORT[/UNIT] or NAME=twin", spec));
    }
    const std::string name = spec.substr(0, eq);
    if (std::find(given.begin(), given.end(), name) != given.end()) {
      throw InputError(where, fmt::format("'{}': device '{}' is given twice", spec, name));
    }
    given.push_back(name);
    DeviceChoice d;
    try {
      d = choose_device(scenario, name, spec.substr(eq + 1), where, where);
    } catch (const InputError& e) {
      throw InputError(where, fmt::format("'{}': {}", spec, e.problem()));
    }
    auto it = std::find_if(scenario.devices.begin(), scenario.devices.end(),
                           [&](const DeviceChoice& c) { return c.device == name; });
    if (it != scenario.devices.end()) {
      *it = std::move(d);
    } else {
      scenario.devices.push_back(std::move(d));
    }
  }
}

const DeviceChoice* find_device_choice(const Scenario& scenario, std::string_view name) {
  for (const DeviceChoice& d : scenario.devices) {
    if (d.device == name) return &d;
  }
  return nullptr;
}

bool uses_real_devices(const Scenario& scenario) {
  return std::any_of(scenario.devices.begin(), scenario.devices.end(), [](const DeviceChoice& d) { return d.real(); });
}

bool uses_real_drivers(const Scenario& scenario) {
  for (const DriverChoice& d : scenario.drivers) {
    if (!d.real()) continue;
    for (const Binding& b : scenario.robots) {
      if (b.name == d.robot) return true;
    }
  }
  return false;
}

const char* to_string(models::DriverKind kind) {
  switch (kind) {
    case models::DriverKind::kSim:
      return "sim";
    case models::DriverKind::kMovemaster:
      return "movemaster";
    case models::DriverKind::kVal2:
      return "val2";
  }
  return "?";
}

namespace {

const std::string& find_binding(const std::vector<Binding>& bindings, std::string_view label, const char* kind) {
  for (const auto& b : bindings) {
    if (b.label == label) return b.name;
  }
  CW_CHECK(false, "no binding for {} label '{}'", kind, label);
  static const std::string none;
  return none;
}

}  // namespace

const std::string& Scenario::robot_of(std::string_view label) const {
  return find_binding(robots, label, "robot");
}
const std::string& Scenario::workpiece_of(std::string_view label) const {
  return find_binding(workpieces, label, "workpiece");
}
const std::string& Scenario::location_of(std::string_view label) const {
  return find_binding(locations, label, "location");
}

std::map<std::string, Eigen::Isometry3d> draw_perturbation(const Perturbation& p, std::uint64_t seed) {
  // The engine's raw output, not a std:: distribution: those are allowed to differ between standard libraries.
  std::mt19937_64 rng(seed);
  const auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };  // [0, 1)
  std::map<std::string, Eigen::Isometry3d> out;
  for (const std::string& w : p.workpieces) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int i = 0; i < 2; ++i) {
      const double amount = p.offset[i] * (0.5 + 0.5 * unit());
      d[i] = unit() < 0.5 ? -amount : amount;
    }
    const double yaw = p.yaw * (2 * unit() - 1);
    Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
    offset.translation() = d;
    offset.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    out[w] = offset;
  }
  return out;
}

Scenario parse_scenario(std::string_view yaml_text, const std::filesystem::path& source) {
  const Doc doc(source.string(), models::yaml::MissingField::kSayRequired);
  const YAML::Node root = models::yaml::load(yaml_text, doc, "not a valid YAML file");
  if (!root.IsDefined() || root.IsNull()) throw InputError({doc.file(), 1, 0}, "the scenario file is empty");
  const Fields f(doc, root, "the scenario",
                 {"cell", "program", "seed", "locations", "drivers", "devices", "robots", "bind", "feed", "limits",
                  "expect", "tolerance", "options", "perception", "vision", "perturb", "faults", "recovery",
                  "safety"});
  const std::filesystem::path dir = source.parent_path();

  Scenario s;
  s.source = source;

  // The cell and the program: their own loaders report errors in their own files.
  s.cell_file = resolve(dir, f.word("cell"));
  s.cell = with_context(doc, f.node("cell"), fmt::format("field 'cell' names '{}'", f.word("cell")),
                        [&] { return models::load_cell(s.cell_file); });
  s.program_file = resolve(dir, f.word("program"));
  s.program = with_context(doc, f.node("program"), fmt::format("field 'program' names '{}'", f.word("program")),
                           [&] { return task::compile_file(s.program_file); });
  if (f.has("seed")) {
    const YAML::Node& n = f.node("seed");
    std::uint64_t seed = 0;
    if (!n.IsScalar() || !YAML::convert<std::uint64_t>::decode(n, seed) || n.Scalar().starts_with("-")) {
      doc.fail(n, fmt::format("{} must be a whole number from 0 to 2^64-1, got {}", f.field("seed"), describe(n)));
    }
    s.seed = seed;
  }

  // --- places of this scenario, added to the cell before anything is bound to them ---
  if (f.has("locations")) {
    const YAML::Node& list = f.node("locations");
    if (!list.IsSequence()) {
      doc.fail(list, fmt::format("{} must be a list of locations, got {}", f.field("locations"), describe(list)));
    }
    for (const YAML::Node& n : list) s.cell.locations.push_back(read_location(doc, s.cell, n));
  }

  // --- bindings ---
  const YAML::Node& program_node = f.node("program");
  auto bind_labels = [&](const std::vector<std::string>& labels, const char* noun,
                         const std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>>& given,
                         const std::vector<std::string>& cell_names, const char* cell_noun, const char* field_name,
                         std::vector<Binding>& out) {
    for (const auto& label : labels) {
      Binding b;
      b.label = label;
      auto it = std::find_if(given.begin(), given.end(), [&](const auto& g) { return g.first == label; });
      if (it != given.end()) {
        const YAML::Node& v = it->second.second;
        b.name = f.word_of(v, fmt::format("the cell {} bound to {} '{}'", cell_noun, noun, label));
        b.where = doc.at(it->second.first);
        if (std::find(cell_names.begin(), cell_names.end(), b.name) == cell_names.end()) {
          doc.fail(v,
                   fmt::format("{} '{}' is bound to '{}', which is not a {} of the cell {} ({}s: {})", noun, label,
                               b.name, cell_noun, s.cell_file.filename().string(), cell_noun, list_names(cell_names)));
        }
      } else {
        b.name = label;
        b.where = f.has(field_name) ? doc.at(f.key_node(field_name)) : doc.at(program_node);
        if (std::find(cell_names.begin(), cell_names.end(), label) == cell_names.end()) {
          throw InputError(
              b.where, fmt::format("program {} '{}' ({}) is bound to nothing in the cell {}: it has no {} named "
                                   "'{}' ({}s: {}); bind it with `{}: {{{}: <{}>}}`",
                                   noun, label, s.program_file.filename().string(), s.cell_file.filename().string(),
                                   cell_noun, label, cell_noun, list_names(cell_names), field_name, label, cell_noun));
        }
      }
      out.push_back(std::move(b));
    }
    // Two labels on one cell object would make two program entities fight over one thing.
    for (std::size_t i = 0; i < out.size(); ++i) {
      for (std::size_t j = i + 1; j < out.size(); ++j) {
        if (out[i].name == out[j].name) {
          throw InputError(out[j].where, fmt::format("program {}s '{}' and '{}' are both bound to the cell {} '{}'",
                                                     noun, out[i].label, out[j].label, cell_noun, out[j].name));
        }
      }
    }
  };

  std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> robot_map, bind_map;
  if (f.has("robots")) robot_map = f.word_map("robots");
  if (f.has("bind")) bind_map = f.word_map("bind");
  for (const auto& [label, nodes] : robot_map) {
    if (std::find(s.program.robots.begin(), s.program.robots.end(), label) == s.program.robots.end()) {
      doc.fail(nodes.first,
               fmt::format("field 'robots' binds '{}', which is not a robot of the program {} (robots: {})", label,
                           s.program_file.filename().string(), list_names(s.program.robots)));
    }
  }
  std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> wp_map, loc_map;
  for (const auto& entry : bind_map) {
    const std::string& label = entry.first;
    if (std::find(s.program.workpieces.begin(), s.program.workpieces.end(), label) != s.program.workpieces.end()) {
      wp_map.push_back(entry);
    } else if (std::find(s.program.locations.begin(), s.program.locations.end(), label) != s.program.locations.end()) {
      loc_map.push_back(entry);
    } else {
      const bool robot = std::find(s.program.robots.begin(), s.program.robots.end(), label) != s.program.robots.end();
      doc.fail(entry.second.first,
               fmt::format("field 'bind' binds '{}', which is not a workpiece or location of the program {}{} "
                           "(workpieces: {}; locations: {})",
                           label, s.program_file.filename().string(), robot ? " (robots are bound under 'robots')" : "",
                           list_names(s.program.workpieces), list_names(s.program.locations)));
    }
  }
  bind_labels(s.program.robots, "robot", robot_map, names_of(s.cell.robots), "robot", "robots", s.robots);
  bind_labels(s.program.workpieces, "workpiece", wp_map, names_of(s.cell.workpieces), "workpiece", "bind",
              s.workpieces);
  bind_labels(s.program.locations, "location", loc_map, names_of(s.cell.locations), "location", "bind", s.locations);
  // A program machine is the cell machine of its name, and robots reach into it at its fixture: the machine's label
  // stands for the location at the fixture (`at: M.fixture`) in every move (`Place M`), for the plan as for the run.
  for (const std::string& label : s.program.machines) {
    const models::MachineSpec* m = s.cell.find_machine(label);
    if (m == nullptr) {
      doc.fail(program_node, fmt::format("the program declares machine '{}', which is not a machine of the cell {} "
                                         "(machines: {})",
                                         label, s.cell_file.filename().string(), list_names(names_of(s.cell.machines))));
    }
    const models::LocationSpec* at = s.cell.fixture_location(*m);
    const std::string fixture = at != nullptr ? at->name : std::string();
    if (fixture.empty()) {
      doc.fail(program_node, fmt::format("machine '{}' has no location at its fixture, where robots put parts into "
                                         "it: add one to the cell's or the scenario's locations, e.g. `- {{name: "
                                         "{}_fixture, at: {}.fixture}}`",
                                         label, label, label));
    }
    s.locations.push_back(Binding{label, fixture, doc.at(program_node)});
  }

  // --- drivers: the cell's choice unless the scenario overrides it ---
  std::map<std::string, std::pair<YAML::Node, YAML::Node>> driver_given;
  if (f.has("drivers")) {
    for (const auto& [robot, nodes] : f.word_map("drivers")) {
      if (s.cell.find_robot(robot) == nullptr) {
        doc.fail(nodes.first,
                 fmt::format("field 'drivers' names '{}', which is not a robot of the cell {} (robots: {})", robot,
                             s.cell_file.filename().string(), list_names(names_of(s.cell.robots))));
      }
      driver_given.emplace(robot, nodes);
    }
  }
  for (const auto& r : s.cell.robots) {
    DriverChoice d;
    d.robot = r.name;
    d.kind = r.driver;
    d.where = r.where;
    d.serial = r.serial;
    if (auto it = driver_given.find(r.name); it != driver_given.end()) {
      const YAML::Node& v = it->second.second;
      const std::string text = f.word_of(v, fmt::format("the driver of robot '{}'", r.name));
      try {
        d = choose_driver(r, text, doc.at(v));
      } catch (const InputError& e) {
        doc.fail(v, e.problem());
      }
    }
    check_driver(d);
    s.drivers.push_back(std::move(d));
  }

  // --- devices: the twin's I/O unless the scenario puts one on a unit ---
  if (f.has("devices")) {
    for (const auto& [name, nodes] : f.word_map("devices")) {
      const YAML::Node& v = nodes.second;
      const std::string text = f.word_of(v, fmt::format("the unit of device '{}'", name));
      s.devices.push_back(choose_device(s, name, text, doc.at(nodes.first), doc.at(v)));
    }
  }

  // --- feed ---
  if (f.has("feed")) {
    const Fields ff(doc, f.node("feed"), "field 'feed'", {"conveyor", "workpieces", "start", "period", "count"});
    Feed feed;
    feed.where = doc.at(f.key_node("feed"));
    feed.conveyor = ff.word("conveyor");
    if (s.cell.find_conveyor(feed.conveyor) == nullptr) {
      doc.fail(ff.node("conveyor"),
               fmt::format("the feed's conveyor '{}' is not a conveyor of the cell (conveyors: {})", feed.conveyor,
                           list_names(names_of(s.cell.conveyors))));
    }
    const YAML::Node& list = ff.node("workpieces");
    if (!list.IsSequence() || list.size() == 0) {
      doc.fail(list, fmt::format("{} must be a non-empty list of cell workpieces, got {}", ff.field("workpieces"),
                                 describe(list)));
    }
    std::map<std::string, int> seen;
    for (const auto& e : list) {
      const std::string w = ff.word_of(e, fmt::format("an entry of {}", ff.field("workpieces")));
      if (s.cell.find_workpiece(w) == nullptr) {
        doc.fail(e, fmt::format("the feed names workpiece '{}', which is not in the cell (workpieces: {})", w,
                                list_names(names_of(s.cell.workpieces))));
      }
      if (auto it = seen.find(w); it != seen.end()) {
        doc.fail(e, fmt::format("the feed names workpiece '{}' twice (first on line {}): a workpiece arrives once", w,
                                it->second));
      }
      seen.emplace(w, doc.at(e).line);
      feed.workpieces.push_back(w);
    }
    feed.start = ff.within_or("start", 0.0, kInstant);
    if (feed.workpieces.size() > 1 && !ff.has("period")) {
      doc.fail(f.node("feed"),
               fmt::format("field 'feed' lists {} workpieces but no 'period' (seconds between arrivals)",
                           feed.workpieces.size()));
    }
    feed.period = ff.within_or("period", 0.0, kDuration);
    feed.count = feed.workpieces.size();
    if (ff.has("count")) {
      const double count = ff.positive("count");
      if (count != std::floor(count) || count > 1e6 || count < static_cast<double>(feed.workpieces.size())) {
        doc.fail(ff.node("count"),
                 fmt::format("{} must be a whole number of parts from {} (the workpieces listed) to 1000000, got {}",
                             ff.field("count"), feed.workpieces.size(), ff.node("count").Scalar()));
      }
      feed.count = static_cast<std::size_t>(count);
      if (feed.count > 1 && !ff.has("period")) {
        doc.fail(f.node("feed"), "field 'feed' has a 'count' of more than one part but no 'period'");
      }
    }
    if (feed.recycles() && feed.exits(s.cell).empty()) {
      doc.fail(ff.node("count"), fmt::format("the feed brings {} parts with {} bodies, but the cell has no other "
                                             "conveyor than '{}' to carry parts out on, so no body is ever free again",
                                             feed.count, feed.workpieces.size(), feed.conveyor));
    }
    s.feed = std::move(feed);
  }

  // --- perception ---
  if (f.has("perception")) {
    const std::string p = f.word("perception");
    if (p == "truth") {
      s.perception = runtime::Perception::kTruth;
    } else if (p == "vision") {
      s.perception = runtime::Perception::kVision;
    } else if (p == "cad") {
      s.perception = runtime::Perception::kCad;
    } else {
      doc.fail(f.node("perception"),
               fmt::format("{} must be truth, vision or cad, got '{}'", f.field("perception"), p));
    }
  }
  if (f.has("vision") && s.perception != runtime::Perception::kVision) {
    doc.fail(f.key_node("vision"), "field 'vision' is given but 'perception' is not vision");
  }
  if (s.perception == runtime::Perception::kVision) {
    VisionSettings v;
    v.where = doc.at(f.has("vision") ? f.key_node("vision") : f.key_node("perception"));
    if (f.has("vision")) {
      const Fields vf(doc, f.node("vision"), "field 'vision'", {"camera", "period"});
      if (vf.has("camera")) v.camera = vf.word("camera");
      v.period = vf.within_or("period", v.period, kDuration);
      if (!v.camera.empty() && s.cell.find_camera(v.camera) == nullptr) {
        doc.fail(vf.node("camera"), fmt::format("the vision camera '{}' is not a camera of the cell (cameras: {})",
                                                v.camera, list_names(names_of(s.cell.cameras))));
      }
    }
    if (v.camera.empty()) {
      if (s.cell.cameras.empty()) {
        doc.fail(f.node("perception"), "perception: vision needs a camera, and the cell has none");
      }
      v.camera = s.cell.cameras.front().name;
    }
    s.vision = v;
  }
  if (f.has("recovery")) {
    // A decision tree file, or {tree, enabled, max_attempts, part_wait, wait_timeout, command_timeout,
    // progress_limit, progress_timeout}.
    const YAML::Node& n = f.node("recovery");
    std::string tree;
    if (n.IsScalar()) {
      tree = f.word("recovery");
    } else {
      const Fields rf(doc, n, "field 'recovery'",
                      {"tree", "enabled", "max_attempts", "part_wait", "wait_timeout", "command_timeout",
                       "progress_limit", "progress_timeout"});
      if (rf.has("tree")) tree = rf.word("tree");
      s.recovery.enabled = rf.boolean_or("enabled", true);
      const auto count = [&](const char* key, int& out) {
        if (!rf.has(key)) return;
        const double a = rf.positive(key);
        if (a != std::floor(a) || a > 100) {
          doc.fail(rf.node(key), fmt::format("{} must be a whole number from 1 to 100, got {}", rf.field(key), a));
        }
        out = static_cast<int>(a);
      };
      count("max_attempts", s.recovery.max_attempts);
      count("progress_limit", s.recovery.progress_limit);
      const auto duration = [&](const char* key, runtime::SimDuration& out) {
        if (rf.has(key)) out = std::chrono::duration_cast<runtime::SimDuration>(
                              std::chrono::duration<double>(rf.within(key, kDuration)));
      };
      duration("part_wait", s.recovery.part_wait);
      duration("wait_timeout", s.recovery.wait_timeout);
      duration("command_timeout", s.recovery.command_timeout);
      duration("progress_timeout", s.recovery.progress_timeout);
    }
    if (!tree.empty()) {
      s.recovery_file = resolve(dir, tree);
      s.recovery.tree = std::make_shared<const runtime::DecisionTree>(runtime::DecisionTree::load(s.recovery_file));
    }
  }
  if (f.has("safety")) {
    // The limits of a coordinated carry (docs/runtime.md, "Coordinated blocks"): {carry_error (m), carry_turn
    // (degrees), squeeze_force (N)}.
    const Fields sf(doc, f.node("safety"), "field 'safety'", {"carry_error", "carry_turn", "squeeze_force"});
    s.safety.carry_error = sf.within_or("carry_error", s.safety.carry_error, Range{0, 0.5, true, "m"});
    s.safety.carry_turn =
        sf.within_or("carry_turn", s.safety.carry_turn * 180.0 / std::numbers::pi, Range{0, 90, true, "degrees"}) *
        std::numbers::pi / 180.0;
    s.safety.squeeze_force = sf.within_or("squeeze_force", s.safety.squeeze_force, Range{0, 10000, true, "N"});
  }
  if (f.has("perturb")) {
    const Fields pf(doc, f.node("perturb"), "field 'perturb'", {"workpieces", "offset", "yaw"});
    Perturbation p;
    p.where = doc.at(f.key_node("perturb"));
    const YAML::Node& list = pf.node("workpieces");
    if (!list.IsSequence() || list.size() == 0) {
      doc.fail(list, fmt::format("{} must be a non-empty list of cell workpieces, got {}", pf.field("workpieces"),
                                 describe(list)));
    }
    for (const auto& e : list) {
      const std::string w = pf.word_of(e, fmt::format("an entry of {}", pf.field("workpieces")));
      if (s.cell.find_workpiece(w) == nullptr) {
        doc.fail(e, fmt::format("{} names workpiece '{}', which is not in the cell (workpieces: {})",
                                pf.field("workpieces"), w, list_names(names_of(s.cell.workpieces))));
      }
      if (std::find(p.workpieces.begin(), p.workpieces.end(), w) != p.workpieces.end()) {
        doc.fail(e, fmt::format("{} names workpiece '{}' twice", pf.field("workpieces"), w));
      }
      p.workpieces.push_back(w);
    }
    if (pf.has("offset")) {
      const YAML::Node& v = pf.node("offset");
      if (!v.IsSequence() || v.size() != 2) {
        doc.fail(v, fmt::format("{} must be a list of 2 numbers (m along the part's x and y), got {}",
                                pf.field("offset"), describe(v)));
      }
      for (std::size_t i = 0; i < 2; ++i) {
        double x = 0;
        if (!v[i].IsScalar() || !YAML::convert<double>::decode(v[i], x) || !std::isfinite(x) || x < 0 || x > 0.5) {
          doc.fail(v[i],
                   fmt::format("{} must hold 2 numbers from 0 to 0.5 (m), got {}", pf.field("offset"), describe(v[i])));
        }
        p.offset[static_cast<Eigen::Index>(i)] = x;
      }
    }
    if (pf.has("yaw")) {
      const double yaw = pf.number("yaw");
      if (yaw < 0 || yaw > 180) {
        doc.fail(pf.node("yaw"), fmt::format("{} must be from 0 to 180 (degrees), got {}", pf.field("yaw"), yaw));
      }
      p.yaw = yaw * std::numbers::pi / 180.0;
    }
    // A part riding a conveyor must stay on its belt however the draw falls: across the belt it may move at most
    // half the belt's width less half its own diagonal.
    for (const std::string& w : p.workpieces) {
      const models::WorkpieceSpec& spec = *s.cell.find_workpiece(w);
      const bool fed = s.feed && s.feed->feeds(w);
      const models::ConveyorSpec* belt = s.cell.find_conveyor(fed ? s.feed->conveyor : spec.on);
      if (belt == nullptr) continue;
      const double room = belt->width / 2 - std::hypot(spec.size.x(), spec.size.y()) / 2;
      if (p.offset.y() > room) {
        doc.fail(pf.node("offset"),
                 fmt::format("{} moves workpiece '{}' up to {} m across conveyor '{}', which leaves it room for {:.3f} "
                             "m (half its width less half the part's diagonal)",
                             pf.field("offset"), w, p.offset.y(), belt->name, std::max(room, 0.0)));
      }
    }
    s.perturb = std::move(p);
  }

  // --- limits and options ---
  if (f.has("limits")) {
    const Fields lf(doc, f.node("limits"), "field 'limits'", {"sim_time", "wall_time"});
    s.limits.sim_time = lf.within_or("sim_time", s.limits.sim_time, kDuration);
    s.limits.wall_time = lf.within_or("wall_time", 0.0, kDuration);
  }
  if (f.has("options")) {
    const Fields of(doc, f.node("options"), "field 'options'",
                    {"realtime", "control_period", "settle_time", "handover_clearance"});
    s.options.realtime = of.boolean_or("realtime", s.options.realtime);
    s.options.control_period = of.within_or("control_period", s.options.control_period, Range{0, 1, true, "s"});
    s.options.settle_time = of.within_or("settle_time", s.options.settle_time, kInstant);
    s.options.handover_clearance = of.within_or("handover_clearance", s.options.handover_clearance, kLength);
    // The simulation advances a whole number of physics steps per control period.
    const double steps = s.options.control_period / s.cell.timestep;
    if (steps < 1 - 1e-9 || std::abs(steps - std::round(steps)) > 1e-6) {
      doc.fail(of.node("control_period"),
               fmt::format("{} must be a whole multiple of the cell's simulation time step ({} s), got {}",
                           of.field("control_period"), s.cell.timestep, s.options.control_period));
    }
  }

  if (s.vision && s.vision->period < s.options.control_period) {
    doc.fail(f.has("vision") ? f.node("vision") : f.node("perception"),
             fmt::format("the vision period ({} s) must be at least the control period ({} s): one frame per period at "
                         "most",
                         s.vision->period, s.options.control_period));
  }

  // Times that cannot work together: the run ends at sim_time whatever is still to come.
  {
    const auto check_before_end = [&](bool given, const YAML::Node& node, const std::string& what, double t) {
      if (given && t >= s.limits.sim_time) {
        doc.fail(node, fmt::format("{} is {} s, but the run ends at the simulation time limit of {} s ({}): it "
                                   "cannot work; raise the limit or shorten the time",
                                   what, t, s.limits.sim_time,
                                   f.has("limits") ? "field 'sim_time' of field 'limits'" : "the default"));
      }
    };
    const std::optional<YAML::Node> options = f.get("options");
    const std::optional<YAML::Node> feed = f.get("feed");
    check_before_end(options && (*options)["settle_time"], options ? (*options)["settle_time"] : YAML::Node(),
                     "field 'settle_time' of field 'options' (simulated after the program finishes)",
                     s.options.settle_time);
    check_before_end(options && (*options)["control_period"], options ? (*options)["control_period"] : YAML::Node(),
                     "field 'control_period' of field 'options'", s.options.control_period);
    check_before_end(feed && feed->IsMap() && (*feed)["start"], feed ? (*feed)["start"] : YAML::Node(),
                     "field 'start' of field 'feed' (the first part's arrival)", s.feed ? s.feed->start : 0.0);
  }

  // --- expected outcome ---
  const double tolerance = f.within_or("tolerance", 0.02, kLength);
  if (f.has("expect")) {
    std::vector<std::string> places;
    for (const auto& l : s.cell.locations) places.push_back(l.name);
    for (const auto& c : s.cell.conveyors) places.push_back(c.name);
    for (const auto& m : s.cell.machines) places.push_back(m.name);
    for (const auto& [workpiece, nodes] : f.word_map("expect")) {
      Expectation e;
      e.workpiece = workpiece;
      e.where = doc.at(nodes.first);
      e.tolerance = tolerance;
      if (s.cell.find_workpiece(workpiece) == nullptr) {
        doc.fail(nodes.first, fmt::format("field 'expect' names workpiece '{}', which is not in the cell (workpieces: "
                                          "{}); expectations use cell names, not program labels",
                                          workpiece, list_names(names_of(s.cell.workpieces))));
      }
      const YAML::Node& v = nodes.second;
      YAML::Node place_node = v;
      if (v.IsMap()) {
        const Fields ef(doc, v, fmt::format("the expectation for '{}'", workpiece), {"at", "tolerance"});
        place_node = ef.node("at");
        e.tolerance = ef.within_or("tolerance", tolerance, kLength);
      }
      e.place = f.word_of(place_node, fmt::format("where workpiece '{}' must end up", workpiece));
      if (!e.lost() && std::find(places.begin(), places.end(), e.place) == places.end()) {
        doc.fail(place_node, fmt::format("workpiece '{}' is expected at '{}', which is not a location, conveyor or "
                                         "machine of the cell, nor 'lost' (they are: {})",
                                         workpiece, e.place, list_names(places)));
      }
      s.expect.push_back(std::move(e));
    }
  }

  // --- faults to inject (docs/faults.md) ---
  if (f.has("faults")) {
    const YAML::Node& list = f.node("faults");
    if (!list.IsSequence()) {
      doc.fail(list, fmt::format("{} must be a list of faults, got {}", f.field("faults"), describe(list)));
    }
    for (const YAML::Node& n : list) {
      FaultSpec fault = parse_fault(doc, n, s.cell);
      if (needs_vision(fault.kind) && s.perception != runtime::Perception::kVision) {
        doc.fail(n["kind"], fmt::format("a {} fault needs perception vision (the camera), and the scenario's "
                                        "perception is {}",
                                        to_string(fault.kind), runtime::to_string(s.perception)));
      }
      s.faults.push_back(std::move(fault));
    }
  }
  return s;
}

Scenario load_scenario(const std::filesystem::path& yaml_file) {
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(yaml_file, ec).lexically_normal();
  std::string text;
  try {
    text = read_file(abs);
  } catch (const InputError& e) {
    throw InputError({yaml_file.string(), 0, 0}, fmt::format("cannot read the scenario: {}", e.problem()));
  }
  return parse_scenario(text, abs);
}

// --- preflight ------------------------------------------------------------------------------------------------------

}  // namespace cellwright::cell
