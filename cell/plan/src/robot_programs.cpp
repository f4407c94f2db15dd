// The post-processors (robot_programs.hpp): the motion plan's tool poses and the program's events, written in the
// Movemaster EX and VAL II languages.
#include "cellwright/cell/robot_programs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <set>

#include "cellwright/common/files.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/cell/estimate.hpp"
#include "conventions.hpp"

namespace cellwright::cell {

namespace {

using cell::Scenario;
using task::PrimitiveKind;
using task::TargetKind;

// The 5-axis rule's tolerance for an approach axis out of the arm's plane (docs/real-robots.md, yaw_tolerance).
constexpr double kYawToleranceDeg = 0.5;
// Movemaster line numbers go up in tens, so that a line can be put in by hand.
constexpr int kLineStep = 10;

std::string file_name(const std::filesystem::path& p) {
  return p.filename().string();
}

std::string where_text(const SourceLocation& w) {
  return fmt::format("{}:{}:{}", file_name(w.file), w.line, w.column);
}

std::string language_name(models::DriverKind k) {
  return k == models::DriverKind::kMovemaster ? "Movemaster EX" : "VAL II";
}

// Input n of a controller waited for: VAL II `WAIT SIG(1000+n)`; the Movemaster jumps back onto its own line while
// input n is off (`TB -n,L`, L filled in when the lines are numbered).
std::string wait_input(models::DriverKind k, int n) {
  return k == models::DriverKind::kMovemaster ? fmt::format("TB -{},{{}}", n) : fmt::format("WAIT SIG({})", 1000 + n);
}

// Output n of a controller set on or off: VAL II `SIGNAL n` / `SIGNAL -n`, the Movemaster `OB +n` / `OB -n`.
std::string set_output(models::DriverKind k, int n, bool on) {
  return k == models::DriverKind::kMovemaster ? fmt::format("OB {}{}", on ? '+' : '-', n)
                                              : fmt::format("SIGNAL {}{}", on ? "" : "-", n);
}

// What a generated program does with devices, for the refusals.
constexpr const char* kGenerated =
    "a generated program waits for a photo-eye wired to its controller's input (`sensor: {signal: n}`) and runs a "
    "belt wired to its controller's output (`run_signal: n`); machines, and whatever is wired only to the cell's I/O "
    "unit, are driven by the cell controller (twin run) or a PLC (docs/devices.md, \"Generated robot programs and the "
    "I/O\")";

// The stop eye named `name` of a conveyor of the cell (nullptr: none; a drop eye is not one).
const models::ConveyorSpec* stop_eye_conveyor(const models::CellDescription& cell, const std::string& name) {
  for (const models::ConveyorSpec& c : cell.conveyors) {
    if (c.stop_eye && c.stop_eye_name == name) return &c;
  }
  return nullptr;
}

// How an event or region of the program is carried out.
struct EventUse {
  std::vector<std::pair<std::size_t, std::size_t>> signals, waits;  // (program robot, primitive)
};

// The net's check result, as the headers quote it.
std::string check_text(const petri::AnalysisResult& a, bool has_regions) {
  return fmt::format("deadlock-free and bounded, {} reachable markings explored{}{}", a.states,
                     a.reduction == petri::Reduction::kStubborn ? " (stubborn-set reduction)" : "",
                     has_regions ? ", every region exclusive" : "");
}

// The events' wires and the regions left out; refuses what wires cannot do.
std::vector<IoChannel> assign_channels(const Scenario& s, std::set<std::string>& local_regions) {
  const task::CompiledProgram& prog = s.program;
  std::map<std::string, EventUse> uses;
  for (std::size_t r = 0; r < prog.programs.size(); ++r) {
    const auto& prims = prog.programs[r].primitives;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      if (prims[k].kind == PrimitiveKind::kSignal) uses[prims[k].event].signals.emplace_back(r, k);
      if (prims[k].kind == PrimitiveKind::kWait) uses[prims[k].event].waits.emplace_back(r, k);
    }
  }
  std::vector<IoChannel> channels;
  for (const task::Semaphore& sem : prog.semaphores) {
    const EventUse& u = uses[sem.name];
    std::set<std::size_t> robots;
    for (const auto& [r, k] : u.signals) robots.insert(r);
    for (const auto& [r, k] : u.waits) robots.insert(r);
    // A device's states order its commands in the net; the device itself holds them (a waited eye is on or not):
    // no wire. Its commands are written, or refused, one by one (Writer::device).
    if (robots.empty() || !sem.device.empty()) continue;
    const std::string kind = sem.region ? "region" : sem.inserted ? "event" : "semaphore";
    if (sem.region) {
      if (robots.size() > 1) {
        std::string who;
        for (std::size_t r : robots) who += fmt::format("{}{}", who.empty() ? "" : " and ", s.robot_of(prog.robots[r]));
        throw InputError(sem.declared,
                         fmt::format("region '{}' is shared by {}: plain I/O wires between two controllers cannot "
                                     "arbitrate a critical region (both may find it free at once); order the robots "
                                     "with semaphores signalled once instead",
                                     sem.name, who));
      }
      local_regions.insert(sem.name);
      continue;
    }
    if (sem.initial != 0 || u.signals.size() != 1 || u.waits.size() != 1 || robots.size() != 2) {
      throw InputError(sem.declared,
                       fmt::format("{} '{}' (initial {}, signalled {} times, waited on {} times, by {} robot(s)) "
                                   "cannot be an I/O wire: a wire carries one event, from one controller's output to "
                                   "another's input, set once and never counted",
                                   kind, sem.name, sem.initial, u.signals.size(), u.waits.size(), robots.size()));
    }
    IoChannel c;
    c.channel = static_cast<int>(channels.size()) + 1;
    c.event = sem.name;
    c.from = prog.robots[u.signals[0].first];
    c.to = prog.robots[u.waits[0].first];
    channels.push_back(std::move(c));
  }
  return channels;
}

// Refuses a class's location on a running belt where no part comes to rest: a belt without a stop, or a location
// further from its stop bar than robot control looks for a class's part (0.25 m, robot_control.cpp).
void stop_of(const Scenario& s, const models::ConveyorSpec& c, const models::LocationSpec& at,
             const cell::MotionPlan::ClassTake& take, const petri::Net& net) {
  constexpr double kStopReach = 0.25;
  const double along = (c.pose.transform().inverse() * at.pose.xyz).x() + c.length / 2;
  if (c.stop && std::abs(c.leave - along) <= kStopReach) return;
  const petri::Transition& t = net.transitions()[take.transition];
  CW_CHECK(t.starts_robot.has_value(), "a class take on a transition that starts no primitive");
  const task::Primitive& p = s.program.programs[*t.starts_robot].primitives[static_cast<std::size_t>(t.starts_primitive)];
  throw InputError(at.where,
                   fmt::format("robot '{}' ({}) takes a part of class '{}' at {} ({} '{}'), which lies on conveyor "
                               "'{}' {}: the belt carries a part on from there, and no sensor can tell when one is "
                               "there; take it at the conveyor's stop",
                               s.robot_of(s.program.robots[*t.starts_robot]), s.program.robots[*t.starts_robot],
                               take.label, take.location, where_text(p.where), p.task, c.name,
                               c.stop ? fmt::format("{:.2f} m before its stop bar", c.leave - along)
                                      : std::string("(it has no stop)")));
}

// The DriverChoice of a program robot.
const cell::DriverChoice& driver_of(const Scenario& s, const std::string& cell_robot) {
  for (const cell::DriverChoice& d : s.drivers) {
    if (d.robot == cell_robot) return d;
  }
  throw InternalError(fmt::format("no driver choice for robot {}", cell_robot));
}

// One robot's program being written: its locations/positions and lines.
struct Writer {
  const Scenario& s;
  std::size_t r;  // program robot
  models::DriverKind language;
  const std::vector<IoChannel>& channels;
  const std::set<std::string>& local_regions;
  RobotProgram out;

  // Locations (VAL II) or positions (Movemaster), deduplicated by their text.
  std::vector<std::pair<std::string, std::string>> locations;  // (name or number, values text)
  std::map<std::string, std::string> location_by_values;
  std::set<std::string> location_names;  // upper case (VAL II names are case-insensitive)

  std::vector<std::string> lines;  // program lines, not numbered yet
  int eye_waited = 0;  // the input of the photo-eye the program waited for since its last move (0: none)

  bool movemaster() const { return language == models::DriverKind::kMovemaster; }

  const IoChannel* channel_of(const std::string& event) const {
    for (const IoChannel& c : channels) {
      if (c.event == event) return &c;
    }
    return nullptr;
  }

  // Adds a program line (numbered later: Movemaster lines after the PD block, VAL II steps after the header); returns
  // its index. A Movemaster line's "{}" is its own number.
  int add(const std::string& text) {
    lines.push_back(text);
    return static_cast<int>(lines.size()) - 1;
  }

  // Whether `event` is a device's state (a place of the net that the device itself holds: no line).
  bool device_state(const std::string& event) const {
    for (const task::Semaphore& sem : s.program.semaphores) {
      if (sem.name == event) return !sem.device.empty();
    }
    return false;
  }

  // A device primitive on the robot controller's own wires: a wait for a photo-eye wired to its input, a belt run or
  // stopped by its output; refused otherwise (a machine, a device on the cell's I/O unit only).
  int device(const task::Primitive& p) {
    const std::string head = fmt::format("robot '{}' ({}): '{}' cannot be written as a {} program: ", out.cell_robot,
                                         out.robot, p.task, language_name(language));
    switch (p.op) {
      case task::DeviceOp::kAwaitOn: {
        const models::ConveyorSpec* c = stop_eye_conveyor(s.cell, p.device);
        if (c == nullptr || c->sensor == 0) {
          throw InputError(p.where, fmt::format("{}photo-eye '{}' is wired to no robot controller input{}; {}. Wire "
                                                "it to an input (a stop eye's `sensor: {{signal: n}}` in {}), or run "
                                                "the program with twin run",
                                                head, p.device, c == nullptr ? " (only a stop eye can be)" : "",
                                                kGenerated, file_name(s.cell_file)));
        }
        eye_waited = c->sensor;
        return add(wait_input(language, c->sensor));
      }
      case task::DeviceOp::kRun:
      case task::DeviceOp::kAccumulate:
      case task::DeviceOp::kStop: {
        const models::ConveyorSpec* c = s.cell.find_conveyor(p.device);
        CW_CHECK(c != nullptr, "device {} of a preflight that passed is no conveyor of the cell", p.device);
        if (c->run_signal == 0) {
          throw InputError(p.where,
                           fmt::format("{}conveyor '{}' has no drive wired to a robot controller output{}; {}. Wire "
                                       "its drive to an output (`run_signal: n` in {}), or run the program with "
                                       "twin run",
                                       head, p.device,
                                       c->run_io.wired() ? fmt::format(" (it runs by coil {} of the cell's I/O unit)",
                                                                       c->run_io.address)
                                                         : std::string(),
                                       kGenerated, file_name(s.cell_file)));
        }
        // Accumulating is the belt's own doing (its stop eye holds it): the program only runs it.
        return add(set_output(language, c->run_signal, p.op != task::DeviceOp::kStop));
      }
      case task::DeviceOp::kStart:
      case task::DeviceOp::kAwaitDone:
        throw InputError(p.where, fmt::format("{}machine '{}' is started and watched through the cell's I/O unit "
                                              "(its start coil, its busy and done inputs), which no robot controller "
                                              "drives; {}. Run the program with twin run (`--device {}=modbus:...` "
                                              "for the real machine)",
                                              head, p.device, kGenerated, p.device));
    }
    throw InternalError(fmt::format("device operation {} not handled", static_cast<int>(p.op)));
  }

  // The name (VAL II) or number (Movemaster) of the location with these values, added when new.
  std::string location(const std::string& values, const task::Target& t) {
    if (auto it = location_by_values.find(values); it != location_by_values.end()) return it->second;
    std::string name;
    if (movemaster()) {
      name = std::to_string(locations.size() + 1);
    } else {
      const char* kind = t.kind == TargetKind::kAbove          ? "above"
                         : t.kind == TargetKind::kAt           ? "at"
                         : t.kind == TargetKind::kHandover     ? "hover"
                         : t.kind == TargetKind::kHandApproach ? "happr"
                                                               : "hgrasp";
      std::string object;
      for (const char c : t.object) object.push_back(std::isalnum(static_cast<unsigned char>(c)) ? c : '.');
      const std::string base = fmt::format("{}.{}", kind, object);
      name = base;
      for (int n = 2;; ++n) {
        std::string upper = name;
        for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
        if (location_names.insert(upper).second) break;
        name = fmt::format("{}.{}", base, n);
      }
    }
    locations.emplace_back(name, values);
    location_by_values.emplace(values, name);
    return name;
  }

  // The line of one primitive (-1: none).
  int primitive(const task::Primitive& p, const cell::PlannedCommand& planned,
                const models::KinematicChain& chain) {
    switch (p.kind) {
      case PrimitiveKind::kOpen:
        return add(movemaster() ? "GO" : "OPENI");
      case PrimitiveKind::kClose:
        return add(movemaster() ? "GC" : "CLOSEI");
      case PrimitiveKind::kSignal:
      case PrimitiveKind::kWait: {
        if (local_regions.count(p.event) != 0 || device_state(p.event)) return -1;
        const IoChannel& c = *channel_of(p.event);
        if (p.kind == PrimitiveKind::kSignal) return add(set_output(language, c.channel, true));
        // The Movemaster jumps back onto itself while input n is off: it waits here for the other's output.
        return add(wait_input(language, c.channel));
      }
      case PrimitiveKind::kLoop:
        // A loop needs a counter and a jump in the controller's language (and, with several robots, the leader's
        // decision wired to the others); not written yet, so refused rather than unrolled or dropped.
        throw InputError(p.where, fmt::format("robot '{}': '{}' cannot be written as a {} program yet: loops are "
                                              "run from the cell controller only",
                                              out.robot, p.task, movemaster() ? "Movemaster EX" : "VAL II"));
      case PrimitiveKind::kDevice:
        return device(p);
      case PrimitiveKind::kMove:
        break;
    }
    eye_waited = 0;
    if (p.target.kind == TargetKind::kPark) {
      throw InputError(p.where, fmt::format("robot '{}': '{}' cannot be written as a {} program yet: park poses are "
                                            "run from the cell controller only",
                                            out.robot, p.task, movemaster() ? "Movemaster EX" : "VAL II"));
    }
    if (p.target.kind == TargetKind::kHome) return add(movemaster() ? "NT" : "READY");
    CW_CHECK(!planned.goal.empty(), "robot {} primitive {}: no planned goal after a passed preflight", planned.robot,
             planned.primitive);
    const Eigen::Isometry3d tool = chain.forward(
        Eigen::Map<const Eigen::VectorXd>(planned.goal.data(), static_cast<Eigen::Index>(planned.goal.size())));
    if (movemaster()) {
      std::string why;
      const std::optional<MovemasterPose> pose = movemaster_pose(tool, kYawToleranceDeg, why);
      if (!pose) {
        throw InputError(p.where, fmt::format("robot '{}' ({}) on a Movemaster cannot make '{}' ('{}'): {}",
                                              out.cell_robot, out.robot, task::to_string(p), p.task, why));
      }
      const std::string values =
          fmt::format("{},{},{},{},{}", movemaster_number(pose->x), movemaster_number(pose->y),
                      movemaster_number(pose->z), movemaster_number(pose->p), movemaster_number(pose->r));
      return add(fmt::format("MO {}", location(values, p.target)));
    }
    const std::array<double, 6> v = val2_trans(tool);
    std::string values;
    for (const double x : v) values += fmt::format("{}{}", values.empty() ? "" : " ", val2_number(x));
    return add(fmt::format("MOVE {}", location(values, p.target)));
  }
};

}  // namespace

void set_language(Scenario& s, const std::string& spec, const SourceLocation& where) {
  const std::size_t eq = spec.find('=');
  const std::size_t colon = spec.find(':', eq == std::string::npos ? 0 : eq);
  if (eq == std::string::npos || eq == 0) {
    throw InputError(where, fmt::format("'{}': write ROBOT=movemaster, ROBOT=val2 or ROBOT=sim", spec));
  }
  const std::string robot = spec.substr(0, eq);
  const std::string kind = spec.substr(eq + 1, colon == std::string::npos ? std::string::npos : colon - eq - 1);
  for (cell::DriverChoice& d : s.drivers) {
    if (d.robot != robot) continue;
    if (kind == "movemaster") {
      d.kind = models::DriverKind::kMovemaster;
    } else if (kind == "val2") {
      d.kind = models::DriverKind::kVal2;
    } else if (kind == "sim") {
      d.kind = models::DriverKind::kSim;
    } else {
      throw InputError(where, fmt::format("'{}': the language must be movemaster, val2 or sim, not '{}'", spec, kind));
    }
    d.where = where;
    return;
  }
  throw InputError(where, fmt::format("'{}': '{}' is not a robot of the cell {}", spec, robot, file_name(s.cell_file)));
}

RobotPrograms generate_robot_programs(const Scenario& s, const cell::Preflight& pre) {
  const task::CompiledProgram& prog = s.program;
  if (!pre.ok()) {
    std::string why;
    for (const std::string& p : pre.problems) why += "\n  " + p;
    throw InputError(
        {s.source.string(), 0, 0},
        fmt::format("refused: the program must pass the preflight before robot programs are written:{}", why));
  }
  // Every robot's language first: a simulated robot has none.
  std::vector<models::DriverKind> languages;
  for (const std::string& label : prog.robots) {
    const cell::DriverChoice& d = driver_of(s, s.robot_of(label));
    if (d.kind == models::DriverKind::kSim) {
      throw InputError(d.where.file.empty() ? SourceLocation{s.source.string(), 0, 0} : d.where,
                       fmt::format("robot '{}' ({}) runs on the sim driver: it has no robot language; put it on "
                                   "movemaster or val2 (the scenario's drivers:, or --driver {}=movemaster|val2)",
                                   d.robot, label, d.robot));
    }
    languages.push_back(d.kind);
  }
  std::set<std::string> local_regions;
  RobotPrograms result;
  result.channels = assign_channels(s, local_regions);
  const int highest = static_cast<int>(result.channels.size());
  for (std::size_t r = 0; r < prog.robots.size(); ++r) {
    const int limit = languages[r] == models::DriverKind::kMovemaster ? kMovemasterChannels : kVal2Channels;
    if (highest > limit) {
      throw InputError({s.program_file.string(), 0, 0},
                       fmt::format("the program needs {} I/O channels; robot '{}' ({}) on {} has {}", highest,
                                   s.robot_of(prog.robots[r]), prog.robots[r], language_name(languages[r]), limit));
    }
  }
  result.check = check_text(pre.analysis, !prog.regions.empty());

  // The sensors' inputs and the belts' drives are wired to every controller: no event wire may use their numbers.
  for (const models::ConveyorSpec& c : s.cell.conveyors) {
    if (c.sensor != 0 && c.sensor <= highest) {
      throw InputError(c.sensor_where,
                       fmt::format("input {} is the part-present sensor of conveyor '{}', but the program's events "
                                   "need the wires 1..{}; wire the sensor to a higher input",
                                   c.sensor, c.name, highest));
    }
    if (c.run_signal != 0 && c.run_signal <= highest) {
      throw InputError(c.run_signal_where,
                       fmt::format("output {} runs conveyor '{}', but the program's events need the wires 1..{}; "
                                   "wire the belt's drive to a higher output",
                                   c.run_signal, c.name, highest));
    }
  }
  // A belt's drive hangs on one wire: one controller runs and stops it (two outputs on it could not stop it).
  std::map<std::string, std::size_t> belt_driver;  // conveyor -> the program robot that runs it
  for (std::size_t r = 0; r < prog.robots.size(); ++r) {
    for (const task::Primitive& p : prog.programs[r].primitives) {
      if (p.kind != PrimitiveKind::kDevice || p.op == task::DeviceOp::kStart || p.op == task::DeviceOp::kAwaitDone ||
          p.op == task::DeviceOp::kAwaitOn) {
        continue;
      }
      const models::ConveyorSpec* c = s.cell.find_conveyor(p.device);
      if (c == nullptr || c->run_signal == 0) continue;  // refused where it stands (Writer::device)
      const auto [it, first] = belt_driver.emplace(p.device, r);
      if (!first && it->second != r) {
        throw InputError(p.where,
                         fmt::format("robot '{}' ({}): '{}': conveyor '{}' is also run or stopped by robot '{}' ({}); "
                                     "its drive hangs on one wire, which one controller's output drives: let one "
                                     "robot run and stop it",
                                     s.robot_of(prog.robots[r]), prog.robots[r], p.task, p.device,
                                     s.robot_of(prog.robots[it->second]), prog.robots[it->second]));
      }
    }
  }

  CW_CHECK(pre.plan.has_value(), "a preflight that passed without a motion plan");
  const cell::MotionPlan& plan = *pre.plan;  // the preflight's: planned once

  // A part that comes later on a conveyor (fed, or riding to the stop): the first move to it waits for the
  // conveyor's part-present sensor, as robot control waits until it sees the part there. Named parts have their
  // arrival gates; a part of a class that the feed brings is taken by the moves of plan.feed_takes.
  std::map<std::pair<std::size_t, std::size_t>, const models::ConveyorSpec*> sensor_waits;  // (robot, primitive)
  auto wait_for_sensor = [&](petri::TransitionId transition, const std::string& part, const std::string& conveyor,
                             const std::string& when) {
    const petri::Transition& t = pre.net.transitions()[transition];
    CW_CHECK(t.starts_robot.has_value(), "arrival of {} on a transition that starts no primitive", part);
    const std::size_t r = *t.starts_robot;
    const auto k = static_cast<std::size_t>(t.starts_primitive);
    const models::ConveyorSpec& c = *s.cell.find_conveyor(conveyor);
    if (c.sensor == 0) {
      const task::Primitive& p = prog.programs[r].primitives[k];
      throw InputError(c.where,
                       fmt::format("robot '{}' ({}) goes to {} ({} '{}') before it has ridden conveyor '{}' to its "
                                   "stop{}: its controller must wait for the part, but the conveyor has no "
                                   "part-present sensor; give it one ('sensor: {{signal: n}}', "
                                   "docs/cell-description.md)",
                                   s.robot_of(prog.robots[r]), prog.robots[r], part, where_text(p.where), p.task,
                                   c.name, when));
    }
    sensor_waits.emplace(std::make_pair(r, k), &c);
  };
  for (const cell::ArrivalGate& g : plan.gates) {
    wait_for_sensor(g.transition, fmt::format("workpiece '{}'", g.workpiece), g.conveyor,
                    fmt::format(" (at {:.1f} s by the plan)", g.ready));
  }
  // A named part let go of on a running belt rides on to the belt's stop (the plan has it there): no program can wait
  // for it there, as no sensor tells which part has come.
  for (const cell::MotionPlan::BeltRide& ride : plan.belt_rides) {
    const petri::Transition& t = pre.net.transitions()[ride.transition];
    CW_CHECK(t.starts_robot.has_value(), "a belt ride on a transition that starts no primitive");
    const std::size_t r = *t.starts_robot;
    const task::Primitive& p = prog.programs[r].primitives[static_cast<std::size_t>(t.starts_primitive)];
    throw InputError(p.where,
                     fmt::format("robot '{}' ({}) goes to workpiece '{}' ('{}') after {} let go of it on conveyor "
                                 "'{}', which carries it on: no sensor tells the program when it has come to rest at "
                                 "the belt's stop; take it as a part of a class at the conveyor's stop "
                                 "(`workpiece part from LOC`, LOC at the stop, the belt with a sensor)",
                                 s.robot_of(prog.robots[r]), prog.robots[r], ride.workpiece, p.task, ride.put,
                                 ride.conveyor));
  }
  // A part of a class arrives at the class's location: a belt that brings it there must tell it with its sensor;
  // elsewhere it is put there by a robot (the program's events order that) or fed (the feed's conveyor's sensor).
  for (const cell::MotionPlan::ClassTake& take : plan.class_takes) {
    const models::LocationSpec* at = s.cell.find_location(take.location);
    CW_CHECK(at != nullptr, "class {} is taken from {}, which the cell does not have", take.label, take.location);
    const std::string part =
        take.fed ? std::string("the next part the feed brings")
                 : fmt::format("the next part of class '{}' at {}", take.label, take.location);
    if (const models::ConveyorSpec* belt = running_belt_under(s.cell, at->pose.xyz)) {
      stop_of(s, *belt, *at, take, pre.net);
      wait_for_sensor(take.transition, part, belt->name, "");
    } else if (take.fed) {
      CW_CHECK(s.feed.has_value(), "a move takes a fed part, but the scenario has no feed");
      wait_for_sensor(take.transition, part, s.feed->conveyor, "");
    }
  }

  for (std::size_t r = 0; r < prog.robots.size(); ++r) {
    const std::string& label = prog.robots[r];
    const models::RobotSpec& spec = *s.cell.find_robot(s.robot_of(label));
    const models::KinematicChain chain = models::robot_chain(spec);
    Writer w{s, r, languages[r], result.channels, local_regions, {}, {}, {}, {}, {}};
    w.out.robot = label;
    w.out.cell_robot = spec.name;
    w.out.language = languages[r];
    w.out.name = spec.name;
    w.out.file_name = spec.name + (w.movemaster() ? ".movemaster" : ".val2");

    // Set-up: the speed, and the outputs this controller drives turned off.
    w.add(w.movemaster() ? fmt::format("SP {}", kMovemasterSpeedLevel) : fmt::format("SPEED {}", kVal2Speed));
    std::vector<int> outputs;
    for (const IoChannel& c : result.channels) {
      if (c.from == label) outputs.push_back(c.channel);
    }
    // The belts this robot runs (stopped at the start, as the net has them), by output.
    std::map<int, const models::ConveyorSpec*> belts_here;
    for (const auto& [conveyor, driver] : belt_driver) {
      if (driver == r) belts_here.emplace(s.cell.find_conveyor(conveyor)->run_signal, s.cell.find_conveyor(conveyor));
    }
    for (const auto& [n, c] : belts_here) outputs.push_back(n);
    if (w.movemaster()) {
      for (const int n : outputs) w.add(fmt::format("OB -{}", n));
    } else if (!outputs.empty()) {
      std::string list;
      for (const int n : outputs) list += fmt::format("{}-{}", list.empty() ? "" : ",", n);
      w.add("SIGNAL " + list);
    }
    const auto& prims = prog.programs[r].primitives;
    std::string last_task;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      const task::Primitive& p = prims[k];
      const std::string task_line = fmt::format("; {} {}", where_text(p.where), p.task);
      if (!w.movemaster() && task_line != last_task) w.add(task_line);
      last_task = task_line;
      // (Not again when the program has just waited for that eye itself: `wait S` before the Pick.)
      if (const auto it = sensor_waits.find({r, k}); it != sensor_waits.end() && w.eye_waited != it->second->sensor) {
        w.add(wait_input(w.language, it->second->sensor));
      }
      w.out.primitive_line.push_back(w.primitive(p, plan.commands[r][k], chain));
    }
    w.add(w.movemaster() ? "ED" : "; end");

    // The header: what was generated from what.
    const std::string c = w.movemaster() ? "'" : ";";
    std::vector<std::string> header = {
        fmt::format("{} {} ({}), {}: written by twin compile --robot-language; do not edit", c, spec.name, label,
                    language_name(languages[r])),
        fmt::format("{} program: {}", c, file_name(s.program_file)),
        fmt::format("{} scenario: {}", c, file_name(s.source)),
        fmt::format("{} cell: {} ({}), robot {} as {}", c, s.cell.name, file_name(s.cell_file), spec.name, label),
        fmt::format("{} net: {}", c, result.check),
        fmt::format("{} poses: the tool in the robot's base frame, mm and degrees ({})", c,
                    w.movemaster() ? "x,y,z,p,r, the 5-axis rule" : "TRANS x,y,z,o,a,t"),
    };
    for (const IoChannel& ch : result.channels) {
      const bool out_here = ch.from == label, in_here = ch.to == label;
      if (!out_here && !in_here) continue;
      const std::string other = s.robot_of(out_here ? ch.to : ch.from);
      const std::string io =
          w.movemaster()
              ? (out_here ? fmt::format("OB +{}", ch.channel) : fmt::format("TB -{}", ch.channel))
              : (out_here ? fmt::format("SIGNAL {}", ch.channel) : fmt::format("WAIT SIG({})", 1000 + ch.channel));
      header.push_back(fmt::format("{} I/O {}: {} = {} {} {} ({})", c, ch.channel, io, ch.event,
                                   out_here ? "to" : "from", other, out_here ? ch.to : ch.from));
    }
    // The photo-eyes it waits for (before a move to a part its belt brings, or at `wait S`) and the belts it runs.
    std::map<int, const models::ConveyorSpec*> eyes_here;
    for (const auto& [at, conveyor] : sensor_waits) {
      if (at.first == r) eyes_here.emplace(conveyor->sensor, conveyor);
    }
    for (const task::Primitive& p : prims) {
      if (p.kind != PrimitiveKind::kDevice || p.op != task::DeviceOp::kAwaitOn) continue;
      if (const models::ConveyorSpec* eye = stop_eye_conveyor(s.cell, p.device)) eyes_here.emplace(eye->sensor, eye);
    }
    for (const auto& [n, conveyor] : eyes_here) {
      const std::string wait = wait_input(w.language, n);
      header.push_back(fmt::format("{} I/O {}: {} = a part at the stop of conveyor {} (its sensor)", c, n,
                                   wait.substr(0, wait.find(',')), conveyor->name));
    }
    for (const auto& [n, conveyor] : belts_here) {
      header.push_back(fmt::format("{} I/O {}: {} / {} = run / stop conveyor {} (its drive)", c, n,
                                   set_output(w.language, n, true), set_output(w.language, n, false), conveyor->name));
    }
    if (!local_regions.empty()) {
      std::string names;
      for (const std::string& z : local_regions) names += " " + z;
      header.push_back(fmt::format("{} regions used by this robot alone, no wire needed:{}", c, names));
    }
    if (w.movemaster()) {
      header.push_back("' a host sends the numbered lines (not these comments), then RN");
    }

    std::vector<std::string> file;
    std::vector<int> number(w.lines.size());  // each program line's number or step
    if (w.movemaster()) {
      // The positions first (PD), then the program, every line numbered in tens.
      file = header;
      int n = 0;
      for (const auto& [position, values] : w.locations) {
        file.push_back(fmt::format("{} PD {},{}", n += kLineStep, position, values));
      }
      for (std::size_t i = 0; i < w.lines.size(); ++i) {
        number[i] = n += kLineStep;
        file.push_back(fmt::format("{} {}", n, fmt::format(fmt::runtime(w.lines[i]), n)));
      }
    } else {
      file.push_back(fmt::format(".PROGRAM {}", spec.name));
      for (const std::string& h : header) file.push_back(h);
      for (std::size_t i = 0; i < w.lines.size(); ++i) {
        number[i] = static_cast<int>(header.size() + i + 1);
        file.push_back(w.lines[i].starts_with(';') ? w.lines[i] : "  " + w.lines[i]);
      }
      file.push_back(".END");
      file.push_back(".LOCATIONS");
      for (const auto& [name, values] : w.locations) file.push_back(fmt::format("{} {}", name, values));
      file.push_back(".END");
    }
    for (int& line : w.out.primitive_line) {
      if (line >= 0) line = number[static_cast<std::size_t>(line)];
    }
    for (const std::string& l : file) {
      w.out.text += l + "\n";
      if (!(w.movemaster() && l.starts_with('\''))) w.out.host_lines.push_back(l);
    }
    result.robots.push_back(std::move(w.out));
  }
  return result;
}

void write_robot_programs(const RobotPrograms& programs, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError({dir.string(), 0, 0}, fmt::format("cannot create the directory: {}", ec.message()));
  for (const RobotProgram& p : programs.robots) write_file_atomically(dir / p.file_name, p.text);
}

}  // namespace cellwright::cell
