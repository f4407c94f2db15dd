// The report of a run, from its event log and the final poses (report.hpp).
#include "cellwright/cell/report.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <istream>
#include <map>
#include <set>
#include <system_error>
#include <tuple>

#include "cellwright/task/to_net.hpp"

namespace cellwright::cell {

using nlohmann::json;
namespace ev = runtime::events;
using runtime::LoggedEvent;

const char* to_string(Activity a) {
  switch (a) {
    case Activity::kMove:
      return "move";
    case Activity::kGrip:
      return "grip";
    case Activity::kWait:
      return "wait";
    case Activity::kBlocked:
      return "blocked";
    case Activity::kPartWait:
      return "part_wait";
  }
  return "?";
}

const char* to_string(DeviceActivity a) {
  switch (a) {
    case DeviceActivity::kBusy:
      return "busy";
    case DeviceActivity::kDone:
      return "done";
    case DeviceActivity::kRunning:
      return "running";
    case DeviceActivity::kOn:
      return "on";
  }
  return "?";
}

const char* to_string(JourneyStep s) {
  switch (s) {
    case JourneyStep::kPicked:
      return "picked";
    case JourneyStep::kHandedOver:
      return "handed over";
    case JourneyStep::kPlaced:
      return "placed";
  }
  return "?";
}

namespace {

// Seconds of simulation time, as the log's text reads (a time on the log's 0.1 ms grid gives the double that its
// 4 decimals parse to).
double seconds(runtime::SimDuration t) {
  return static_cast<double>(t.count()) / 1e9;
}

double round4(double x) {
  return std::round(x * 1e4) / 1e4;
}

// The primitive a command event (on `line`) of `robot` names, refused unless its program (of `count` primitives) has
// it.
std::size_t primitive_of(std::size_t k, std::string_view type, const std::string& robot, std::size_t count,
                         const std::string& file, int line) {
  if (k >= count) {
    throw InputError(
        {file, line, 0},
        fmt::format("{} of robot {} names primitive {}, but its program has {} primitives", type, robot, k, count));
  }
  return k;
}

}  // namespace

namespace {

// The devices' rows built one event at a time (DeviceTimeline): each device's current state and since when; a span
// of a state with a bar becomes a bar when the state changes (or at the run's end).
class DeviceRows {
 public:
  explicit DeviceRows(std::string file) : file_(std::move(file)) {}

  void add(const ev::Device& e, int line, double t) {
    auto it = index_.find(e.device);
    if (it == index_.end()) {
      if (e.kind != "machine" && e.kind != "conveyor" && e.kind != "sensor") {
        throw InputError({file_, line, 0}, fmt::format("device {} has kind \"{}\"; a device is a machine, a conveyor "
                                                       "or a sensor",
                                                       e.device, e.kind));
      }
      DeviceTimeline d;
      d.device = e.device;
      d.kind = e.kind;
      d.state = resting(e.kind);
      it = index_.emplace(e.device, rows_.size()).first;
      rows_.push_back(std::move(d));
      current_.push_back({0.0, std::string()});
    }
    DeviceTimeline& d = rows_[it->second];
    Current& c = current_[it->second];
    if (e.kind != d.kind) {
      throw InputError({file_, line, 0}, fmt::format("device {} is a {} (its first event), not a {}", d.device,
                                                     d.kind, e.kind));
    }
    const std::vector<std::string>& states = states_of(d.kind);
    if (std::find(states.begin(), states.end(), e.state) == states.end()) {
      throw InputError({file_, line, 0}, fmt::format("device {} ({}) has state \"{}\"; a {} is {}", d.device, d.kind,
                                                     e.state, d.kind, fmt::join(states, ", ")));
    }
    const std::string part = d.kind == "machine" ? e.workpiece : std::string();
    if (e.state == d.state) {  // no change of state: the part the model has in it may have become known
      if (c.workpiece.empty()) c.workpiece = part;
      d.workpiece = part.empty() ? d.workpiece : part;
      return;
    }
    close(d, c, t);
    if (e.state == "busy") ++d.cycles_started;
    if (d.state == "busy" && e.state == "done") {
      ++d.cycles_finished;
      const std::string processed = part.empty() ? c.workpiece : part;
      if (!processed.empty()) d.processed.push_back(processed);
    }
    if (e.state == "running" || e.state == "on") ++d.starts;
    d.state = e.state;
    d.workpiece = part;
    c = {t, part};
  }

  std::vector<DeviceTimeline> finish(double end) && {
    for (std::size_t i = 0; i < rows_.size(); ++i) {
      DeviceTimeline& d = rows_[i];
      close(d, current_[i], end);
      for (const DeviceBar& b : d.bars) {
        const double span = b.end - b.start;
        switch (b.activity) {
          case DeviceActivity::kBusy:
            d.busy += span;
            break;
          case DeviceActivity::kDone:
            d.done += span;
            break;
          case DeviceActivity::kRunning:
            d.running += span;
            break;
          case DeviceActivity::kOn:
            d.on += span;
            break;
        }
      }
      d.idle = d.kind == "machine" ? std::max(0.0, end - d.busy - d.done) : 0.0;
      d.utilisation = d.kind == "machine" && end > 0 ? d.busy / end : 0.0;
      d.stopped = d.kind == "conveyor" ? std::max(0.0, end - d.running) : 0.0;
      d.off = d.kind == "sensor" ? std::max(0.0, end - d.on) : 0.0;
    }
    return std::move(rows_);
  }

 private:
  struct Current {
    double since = 0;
    std::string workpiece;  // a machine's part since then
  };

  static std::string resting(const std::string& kind) {
    return kind == "machine" ? "idle" : kind == "conveyor" ? "stopped" : "off";
  }
  static const std::vector<std::string>& states_of(const std::string& kind) {
    static const std::vector<std::string> machine{"idle", "busy", "done"}, conveyor{"running", "stopped"},
        sensor{"on", "off"};
    return kind == "machine" ? machine : kind == "conveyor" ? conveyor : sensor;
  }
  // The bar of d's current state up to `t`, when that state has one.
  static void close(DeviceTimeline& d, const Current& c, double t) {
    std::optional<DeviceActivity> a;
    if (d.state == "busy") a = DeviceActivity::kBusy;
    if (d.state == "done") a = DeviceActivity::kDone;
    if (d.state == "running") a = DeviceActivity::kRunning;
    if (d.state == "on") a = DeviceActivity::kOn;
    if (a && t > c.since) d.bars.push_back({c.since, t, *a, c.workpiece});
  }

  std::string file_;
  std::vector<DeviceTimeline> rows_;
  std::vector<Current> current_;  // as rows_
  std::map<std::string, std::size_t> index_;
};

// A robot's timeline built one event at a time: the robot's path through its program, in firing order. Each firing
// of one of its transitions starts a visit of the primitive it begins (k for transition k, the body's first for a
// loop's again; n: the program's end). A visit lasts until the robot's next firing; its command ended at the first
// command_end of that primitive within it. A visit becomes bars when the next one starts (or at the run's end), so
// only the current visit is held, however long the run. In a program without loops every primitive is visited at
// most once.
class TimelineBuilder {
 public:
  TimelineBuilder(const task::CompiledProgram& program, std::string file)
      : program_(program), file_(std::move(file)), devices_(file_) {}

  void add(const LoggedEvent& le) {
    const double t = seconds(runtime::time_of(le.event));
    tl_.end = std::max(tl_.end, t);
    if (std::holds_alternative<ev::RunEnd>(le.event)) tl_.end = t;
    if (const auto* device = std::get_if<ev::Device>(&le.event)) {
      devices_.add(*device, le.line, t);
      return;
    }
    if (const auto* run_start = std::get_if<ev::RunStart>(&le.event)) {
      if (!started_) start(*run_start, le.line);
      return;
    }
    const auto* fire = std::get_if<ev::Fire>(&le.event);
    const auto* command_start = std::get_if<ev::CommandStart>(&le.event);
    const auto* command_end = std::get_if<ev::CommandEnd>(&le.event);
    const auto* sensor = std::get_if<ev::Sensor>(&le.event);
    if (fire == nullptr && command_start == nullptr && command_end == nullptr && sensor == nullptr) return;
    if (!started_) {
      throw InputError({file_, le.line, 0}, fmt::format("a {} event before run_start", runtime::type_of(le.event)));
    }
    if (fire != nullptr) {
      auto it = transitions_.find(fire->transition);
      if (it == transitions_.end()) return;
      Robot& r = robots_[it->second.first];
      if (r.current) close(it->second.first, t, it->second.second);
      r.current = Visit{it->second.second, t, std::nullopt, false, std::nullopt};
      return;
    }
    const std::string& robot = sensor != nullptr          ? sensor->robot
                               : command_start != nullptr ? command_start->robot
                                                          : command_end->robot;
    auto it = robot_index_.find(robot);
    if (it == robot_index_.end()) return;
    Robot& r = robots_[it->second];
    const task::RobotProgram& rp = program_.programs[r.program];
    if (sensor != nullptr) {  // the timeline's business only when it names one of the robot's primitives
      if (sensor->primitive < rp.primitives.size()) {
        this->sensor(*sensor, it->second, rp.primitives[sensor->primitive], sensor->primitive, t);
      }
      return;
    }
    const std::size_t k =
        primitive_of(command_start != nullptr ? command_start->primitive : command_end->primitive,
                     runtime::type_of(le.event), tl_.robots[it->second].robot, rp.primitives.size(), file_, le.line);
    if (command_start != nullptr) {
      ++tl_.robots[it->second].commands;
    } else if (r.current && r.current->k == k && !r.current->ended) {
      r.current->ended = t;
    }
  }

  Timeline finish() && {
    if (!started_) throw InputError({file_, 0, 0}, "the event log has no run_start event");
    for (std::size_t i = 0; i < robots_.size(); ++i) {
      if (robots_[i].current) close(i, tl_.end, robots_[i].current->k + 1);
    }
    for (RobotTimeline& rt : tl_.robots) {
      for (const Bar& b : rt.bars) {
        const double d = b.end - b.start;
        switch (b.activity) {
          case Activity::kMove:
          case Activity::kGrip:
            rt.busy += d;
            break;
          case Activity::kWait:
            rt.waiting += d;
            break;
          case Activity::kPartWait:
            rt.waiting += d;
            rt.waiting_for_part += d;
            break;
          case Activity::kBlocked:
            rt.blocked += d;
            break;
        }
      }
      rt.idle = std::max(0.0, tl_.end - rt.busy - rt.waiting - rt.blocked);
    }
    tl_.devices = std::move(devices_).finish(tl_.end);
    return std::move(tl_);
  }

 private:
  struct Visit {
    std::size_t k = 0;
    double begin = 0;
    std::optional<double> ended;
    bool part_wait = false;        // a "waiting_for_part" sensor event of this primitive within the visit
    std::optional<double> ready;   // its "part_ready" sensor event
  };

  // A sensor event of robot i about its primitive k (p): the wait for a part, or a step of a part's journey.
  void sensor(const ev::Sensor& e, std::size_t i, const task::Primitive& p, std::size_t k, double t) {
    const std::string& condition = e.condition;
    Robot& r = robots_[i];
    const bool in_visit = r.current && r.current->k == k && !r.current->ended;
    if (condition == "waiting_for_part") {
      if (in_visit && !r.current->ready) r.current->part_wait = true;
      return;
    }
    if (condition == "part_ready") {
      if (in_visit && r.current->part_wait && !r.current->ready) r.current->ready = t;
      return;
    }
    std::optional<JourneyStep> step;
    if (condition == "gripped" && p.task.starts_with("Pick ")) step = JourneyStep::kPicked;
    if (condition == "released" && p.task.starts_with("Put ")) step = JourneyStep::kHandedOver;
    if (condition == "released" && p.task.starts_with("Place ")) step = JourneyStep::kPlaced;
    if (step) tl_.robots[i].marks.push_back({t, *step, e.workpiece});
  }
  struct Robot {
    std::size_t program = 0;  // index in program_.robots
    std::optional<Visit> current;
    bool at_end = false;  // it has visited the program's end: later firings draw nothing
  };

  // Robots as run_start lists them; each must be a robot of the program.
  void start(const ev::RunStart& e, int line) {
    started_ = true;
    for (const ev::RobotName& r : e.robots) {
      RobotTimeline rt;
      rt.robot = r.robot;
      rt.cell = r.cell;
      auto it = std::find(program_.robots.begin(), program_.robots.end(), rt.robot);
      if (it == program_.robots.end()) {
        throw InputError({file_, line, 0}, fmt::format("run_start names robot '{}', which the program {} does not have",
                                                       rt.robot, program_.file));
      }
      const std::size_t index = robots_.size();
      const auto program = static_cast<std::size_t>(it - program_.robots.begin());
      const task::RobotProgram& rp = program_.programs[program];
      for (std::size_t k = 0; k <= rp.primitives.size(); ++k) {
        transitions_[task::transition_id(rt.robot, k)] = {index, k};
      }
      for (const task::Loop& loop : rp.loops) {
        transitions_[task::loop_again_transition_id(rt.robot, loop.end)] = {index, loop.begin};
      }
      robot_index_[rt.robot] = index;
      robots_.push_back({program, std::nullopt, false});
      tl_.robots.push_back(std::move(rt));
    }
  }

  // The bars of robot i's current visit, which ends at `finish`, where the visit of primitive `next` starts.
  void close(std::size_t i, double finish, std::size_t next) {
    Robot& r = robots_[i];
    const Visit v = *r.current;
    r.current.reset();
    const task::RobotProgram& rp = program_.programs[r.program];
    const std::size_t n = rp.primitives.size();
    if (r.at_end) return;
    if (v.k == n) {
      r.at_end = true;  // the program's end
      return;
    }
    std::vector<Bar>& bars = tl_.robots[i].bars;
    const task::Primitive& p = rp.primitives[v.k];
    Bar bar;
    bar.primitive = static_cast<int>(v.k);
    bar.task = p.task;
    bar.label = task::to_string(p);
    bar.start = v.begin;
    switch (p.kind) {
      case task::PrimitiveKind::kMove:
      case task::PrimitiveKind::kOpen:
      case task::PrimitiveKind::kClose: {
        bar.activity = p.kind == task::PrimitiveKind::kMove ? Activity::kMove : Activity::kGrip;
        bar.end = std::clamp(v.ended.value_or(finish), v.begin, std::max(v.begin, finish));
        if (v.part_wait) {  // standing still until the part is ready, then the command proper
          Bar waiting = bar;
          waiting.activity = Activity::kPartWait;
          waiting.end = std::clamp(v.ready.value_or(bar.end), bar.start, bar.end);
          if (waiting.end > waiting.start || !v.ready) bars.push_back(waiting);
          bar.start = waiting.end;
          if (!v.ready) bar.end = bar.start;  // the command ended (or the run stopped) before its part came
        }
        if (bar.end > bar.start || (!v.ended && !v.part_wait)) bars.push_back(bar);
        if (v.ended && finish > bar.end) {
          Bar blocked = bar;
          blocked.activity = Activity::kBlocked;
          blocked.start = bar.end;
          blocked.end = finish;
          blocked.label = next < n ? fmt::format("before {}", task::to_string(rp.primitives[next])) : "before done";
          bars.push_back(std::move(blocked));
        }
        break;
      }
      case task::PrimitiveKind::kWait:
      case task::PrimitiveKind::kDevice:  // waiting for the device's action (its own Gantt rows: the lead's part)
        bar.activity = Activity::kWait;
        bar.end = finish;
        if (bar.end > bar.start) bars.push_back(std::move(bar));
        break;
      case task::PrimitiveKind::kSignal:
      case task::PrimitiveKind::kLoop:
        if (finish > v.begin) {
          bar.activity = Activity::kBlocked;
          bar.end = finish;
          bars.push_back(std::move(bar));
        }
        break;
    }
  }

  const task::CompiledProgram& program_;
  std::string file_;
  DeviceRows devices_;
  bool started_ = false;
  Timeline tl_;
  std::vector<Robot> robots_;                                                    // as tl_.robots
  std::map<std::string, std::pair<std::size_t, std::size_t>> transitions_;       // id -> (robot, primitive begun)
  std::map<std::string, std::size_t> robot_index_;                               // label -> robot
};

}  // namespace

Timeline build_timeline(const std::vector<LoggedEvent>& events, const task::CompiledProgram& program,
                        const std::string& file) {
  TimelineBuilder b(program, file);
  for (const LoggedEvent& e : events) b.add(e);
  return std::move(b).finish();
}

std::vector<std::string> places_of(const models::CellDescription& cell, const models::WorkpieceSpec& spec,
                                   const FinalPose& final, double tolerance) {
  std::vector<std::string> out;
  if (!final.present) {
    out.push_back("not in the cell");
    return out;
  }
  const Eigen::Vector3d centre = final.pose.translation();
  // The lowest point of the part's axis: its bottom centre when it stands upright (a part on its side has no bottom
  // face down, and is at no location).
  const Eigen::Vector3d bottom = centre - final.pose.linear() * Eigen::Vector3d(0, 0, spec.size.z() / 2);
  for (const auto& l : cell.locations) {
    if ((bottom - l.pose.xyz).norm() <= tolerance) out.push_back(l.name);
  }
  for (const auto& c : cell.conveyors) {
    const Eigen::Vector3d local = c.pose.transform().inverse() * bottom;
    if (std::abs(local.x()) <= c.length / 2 + tolerance && std::abs(local.y()) <= c.width / 2 + tolerance &&
        std::abs(local.z() - c.height) <= tolerance) {
      out.push_back(c.name);
    }
  }
  for (const auto& m : cell.machines) {
    const models::Pose top = m.fixture_top();
    const Eigen::Vector3d on_fixture = top.transform().inverse() * bottom;
    const Eigen::Vector3d on_body = m.pose.transform().inverse() * bottom;
    const bool fixture = std::abs(on_fixture.x()) <= m.fixture_size.x() / 2 + tolerance &&
                         std::abs(on_fixture.y()) <= m.fixture_size.y() / 2 + tolerance &&
                         std::abs(on_fixture.z()) <= tolerance;
    const bool body = std::abs(on_body.x()) <= m.size.x() / 2 + tolerance &&
                      std::abs(on_body.y()) <= m.size.y() / 2 + tolerance &&
                      std::abs(on_body.z() - m.size.z()) <= tolerance;
    if (fixture || body) out.push_back(m.name);
  }
  if (!final.held_by.empty()) out.push_back(fmt::format("held by {}", final.held_by));
  if (std::abs(bottom.z()) <= tolerance && out.empty()) out.push_back("floor");
  return out;
}

const char* to_string(PartStatus st) {
  switch (st) {
    case PartStatus::kInPlace:
      return "in_place";
    case PartStatus::kElsewhere:
      return "elsewhere";
    case PartStatus::kHeld:
      return "held";
    case PartStatus::kLost:
      return "lost";
    case PartStatus::kNotArrived:
      return "not_arrived";
    case PartStatus::kScrapped:
      return "scrapped";
  }
  return "?";
}

std::size_t Report::unaccounted() const {
  return static_cast<std::size_t>(
      std::count_if(workpieces.begin(), workpieces.end(), [](const WorkpieceReport& w) { return w.unaccounted; }));
}

std::vector<FinalPose> final_poses_of(const runtime::EnvironmentModel& model) {
  std::vector<FinalPose> out;
  for (const runtime::WorkpieceState& w : model.workpieces) out.push_back({w.name, w.pose, w.present, w.held_by});
  return out;
}

std::string describe_parts_source(const RunSetup& setup) {
  return setup.parts_from_model ? "the controller's model (no twin: nothing sensed where the parts are)" : "the twin";
}

RunSetup setup_of(const Scenario& s) {
  RunSetup setup;
  setup.perception = runtime::to_string(s.perception);
  for (const Binding& b : s.robots) {
    DriverUse d;
    d.robot = b.name;
    d.kind = to_string(models::DriverKind::kSim);
    for (const DriverChoice& c : s.drivers) {
      if (c.robot != b.name || !c.real()) continue;
      d.kind = to_string(c.kind);
      if (c.serial) d.port = c.serial->port;
      // A pseudo-terminal has no arm behind it: it is what `twin emulate` publishes its controller on.
      std::error_code ec;
      const std::filesystem::path target = std::filesystem::canonical(d.port, ec);
      d.emulated = !ec && (target.string().starts_with("/dev/pts/") || target == "/dev/ptmx");
    }
    setup.drivers.push_back(std::move(d));
  }
  for (const FaultSpec& f : s.faults) setup.faults.push_back(to_text(f));
  return setup;
}

namespace {

// The cell robot a name in the log stands for: a program label's binding, else the name itself (a cell name). For
// fault_injected, which names cell robots, a cell robot name comes first.
std::string cell_robot(const Scenario& s, const std::string& name, bool cell_first) {
  if (name.empty()) return name;
  if (cell_first && s.cell.find_robot(name) != nullptr) return name;
  for (const Binding& b : s.robots) {
    if (b.label == name) return b.name;
  }
  return name;
}

// Likewise for workpieces: a cell workpiece name first, else a program label's binding.
std::string cell_workpiece(const Scenario& s, const std::string& name) {
  if (name.empty() || s.cell.find_workpiece(name) != nullptr) return name;
  for (const Binding& b : s.workpieces) {
    if (b.label == name) return b.name;
  }
  return name;
}

std::string format_position(const Eigen::Vector3d& p) {
  return fmt::format("({:.3f}, {:.3f}, {:.3f})", p.x(), p.y(), p.z());
}

// Whether a fault of this kind can be sensed as this symptom (docs/faults.md section 2): a detection is matched only
// to an injection it can be the sign of, so that a fault that did nothing does not take another fault's detection.
bool can_show_as(const std::string& kind, const std::string& symptom) {
  static const std::map<std::string, std::vector<std::string>> signs = {
      {"drop", {"grip_lost", "closed_on_nothing", "part_shifted"}},
      {"slip", {"part_shifted", "grip_lost"}},
      {"misplace", {"part_misplaced", "closed_on_nothing", "closed_on_wrong_part", "target_unreachable"}},
      {"unreachable", {"target_unreachable", "part_misplaced", "no_progress"}},
      {"missing", {"part_not_arrived", "no_progress"}},  // no_progress: a class whose part never comes
      {"obstacle", {"obstacle_seen", "protective_stop"}},
      {"timeout", {"driver_timeout"}},
      {"garbage", {"driver_fault"}},
      {"hardware", {"driver_fault"}},
      {"position", {"position_refused", "position_missed"}},
      {"link_lost", {"link_lost", "driver_fault"}},
      {"lost_signal", {"wait_timeout"}},
      {"frame_lost", {"frame_lost"}},
  };
  const auto it = signs.find(kind);
  if (it == signs.end()) return true;  // detection noise, or a kind this table does not know: any symptom
  return std::find(it->second.begin(), it->second.end(), symptom) != it->second.end();
}

// What the controller made of detection events[detection], of `by`: the first diagnosis of that robot after it (its
// index, or the detection's), its cause and action, and the first recovery_end of that robot after the diagnosis
// (cause and action from it when there was no diagnosis; recovered when ok and before `stop`).
struct Aftermath {
  std::string cause, action;
  std::optional<double> recovered_at;
};
Aftermath aftermath_of(const std::vector<LoggedEvent>& events, std::size_t detection, const std::string& by,
                       std::size_t stop) {
  Aftermath a;
  std::size_t after = detection;
  for (std::size_t k = detection + 1; k < events.size(); ++k) {
    const auto* d = std::get_if<ev::Diagnosis>(&events[k].event);
    if (d != nullptr && d->robot == by) {
      a.cause = d->cause;
      a.action = d->action;
      after = k;
      break;
    }
  }
  for (std::size_t k = after + 1; k < events.size(); ++k) {
    const auto* end = std::get_if<ev::RecoveryEnd>(&events[k].event);
    if (end == nullptr || end->robot != by) continue;
    if (a.cause.empty()) a.cause = end->cause;
    if (a.action.empty()) a.action = end->action;
    if (end->ok && !(stop < k)) a.recovered_at = seconds(end->t);
    break;
  }
  return a;
}

// Why the twin's truth shows nothing physically wrong for detection events[k] of the simulated cell robot `robot`
// (the first `physical` event at or after it), or "" when it does not (or cannot tell).
std::string refuted_by_truth(const std::vector<LoggedEvent>& events, std::size_t k, const std::string& robot,
                             const std::string& symptom) {
  const ev::Physical* physical = nullptr;
  for (std::size_t i = k; i < events.size() && physical == nullptr; ++i) {
    physical = std::get_if<ev::Physical>(&events[i].event);
  }
  if (physical == nullptr) return "";
  if (symptom == "grip_lost" || symptom == "closed_on_nothing") {
    for (const ev::Held& h : physical->held) {
      if (h.robot != robot) continue;
      if (!h.workpiece.empty()) return fmt::format("the twin has {} between the fingers of {}", h.workpiece, robot);
    }
    return "";
  }
  if (symptom == "obstacle_seen" && physical->obstacles == 0) {
    return "the twin has no object in the cell that the cell description lacks";
  }
  return "";
}

// The faults (fault_injected matched to fault_detected, diagnosis, recovery_end), the unexplained faults and false
// alarms of a run.
void match_faults(const Scenario& s, const std::vector<LoggedEvent>& events, Report& r) {
  // The index of the event that stopped the cell if the run ended "stopped", else events.size() (a plain index:
  // GCC 12 warns falsely about an optional one).
  const std::size_t none = events.size();
  std::size_t stop = none;
  for (std::size_t i = 0; i < events.size() && r.outcome == "stopped" && stop == none; ++i) {
    const auto* end = std::get_if<ev::RunEnd>(&events[i].event);
    if (std::holds_alternative<ev::CellStopped>(events[i].event) || (end != nullptr && end->outcome == "stopped")) {
      stop = i;
    }
  }
  if (stop != none) r.stopped_at = seconds(runtime::time_of(events[stop].event));

  // A fault the simulation thread picks up from a driver is logged up to a round after the controller saw its effect
  // (the driver failed the command at once; the injection reaches the log at the next step): a detection of the same
  // robot logged at most two control periods before the injection belongs to it too.
  double period = 0.01;
  for (const LoggedEvent& e : events) {
    if (const auto* start = std::get_if<ev::RunStart>(&e.event)) {
      period = seconds(start->period);
      break;
    }
  }
  const double slack = 2 * period + 1e-9;

  std::vector<bool> matched(events.size(), false);
  std::size_t first_injection = none;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const auto* injected = std::get_if<ev::FaultInjected>(&events[i].event);
    if (injected == nullptr) continue;
    if (first_injection == none) first_injection = i;
    FaultReport f;
    f.kind = injected->kind;
    f.t = seconds(injected->t);
    f.robot = cell_robot(s, injected->robot, true);
    f.workpiece = cell_workpiece(s, injected->workpiece);
    f.detail = injected->detail;
    f.stopped_safely = stop != none && stop > i;

    std::size_t detection = none;
    for (std::size_t k = 0; k < events.size(); ++k) {
      const auto* d = std::get_if<ev::FaultDetected>(&events[k].event);
      if (k == i || matched[k] || d == nullptr) continue;
      if (!can_show_as(f.kind, d->symptom)) continue;
      const bool same_robot = !f.robot.empty() && !d->robot.empty() && cell_robot(s, d->robot, false) == f.robot;
      if (k < i) {
        if (!same_robot || seconds(d->t) < f.t - slack) continue;
      } else if (!f.robot.empty() && !d->robot.empty() && !same_robot) {
        continue;
      }
      detection = k;
      break;
    }
    if (detection != none) {
      matched[detection] = true;
      const auto& d = std::get<ev::FaultDetected>(events[detection].event);
      f.detected = true;
      f.detected_at = seconds(d.t);
      f.detected_by = d.robot;
      f.symptom = d.symptom;
      const Aftermath a = aftermath_of(events, detection, f.detected_by, stop);
      f.cause = a.cause;
      f.action = a.action;
      f.recovered = a.recovered_at.has_value();
      if (a.recovered_at) f.recovery_time = *a.recovered_at - f.t;
    }
    r.faults.push_back(std::move(f));
  }
  // Detections no injection took, with no injection before them (a later detection may be a consequence of an
  // earlier fault), or lost frames with no lost frame injected before them (the camera's frames are lost by nothing
  // else: a real camera's recording that ended): false alarms when the twin's truth shows nothing wrong, else
  // unexplained faults.
  for (std::size_t k = 0; k < events.size(); ++k) {
    const auto* e = std::get_if<ev::FaultDetected>(&events[k].event);
    if (matched[k] || e == nullptr) continue;
    bool may_follow_an_injection = k > first_injection && e->symptom != "frame_lost";
    for (std::size_t i = first_injection; i < k && !may_follow_an_injection; ++i) {
      const auto* injected = std::get_if<ev::FaultInjected>(&events[i].event);
      may_follow_an_injection = injected != nullptr && can_show_as(injected->kind, e->symptom);
    }
    if (may_follow_an_injection) continue;
    Detection d;
    d.t = seconds(e->t);
    d.robot = e->robot;
    d.primitive = e->primitive;
    d.symptom = e->symptom;
    d.detail = e->detail;
    const Aftermath a = aftermath_of(events, k, d.robot, stop);
    d.cause = a.cause;
    d.action = a.action;
    d.recovered = a.recovered_at.has_value();
    const std::string robot = cell_robot(s, d.robot, false);
    const auto driver = std::find_if(r.setup.drivers.begin(), r.setup.drivers.end(),
                                     [&](const DriverUse& u) { return u.robot == robot; });
    const bool simulated = !d.robot.empty() && (driver == r.setup.drivers.end() || !driver->real());
    if (r.setup.twin_truth && simulated) d.truth = refuted_by_truth(events, k, robot, d.symptom);
    (d.truth.empty() ? r.unexplained : r.false_alarms).push_back(std::move(d));
  }
}

// The report of a run built one event at a time: what it keeps grows with the parts and the robots' bars, never with
// the log itself, so the report of a thousand-part shift is built from its file without holding the file.
class ReportBuilder {
 public:
  ReportBuilder(const Scenario& s, std::string file) : s_(s), file_(std::move(file)), timeline_(s.program, file_) {}

  // One sample of a coordinated carry: added to the carry under way of that workpiece and those robots, or begins
  // one.
  void carry(double t, const ev::Carry& c) {
    CarryReport* open = nullptr;
    for (CarryReport& k : r_.carries) {
      if (k.workpiece == c.workpiece && k.a == c.a && k.b == c.b && t - k.end <= 0.05 + 1e-9) open = &k;
    }
    if (open == nullptr) {
      r_.carries.push_back({c.workpiece, c.a, c.b, t, t, 0, c.squeeze, t, c.error, t, c.turn, c.tilt, t});
      open = &r_.carries.back();
    }
    open->end = t;
    ++open->samples;
    if (std::abs(c.squeeze) > std::abs(open->peak_squeeze)) {
      open->peak_squeeze = c.squeeze;
      open->peak_squeeze_t = t;
    }
    if (c.error > open->max_error) {
      open->max_error = c.error;
      open->max_error_t = t;
    }
    open->max_turn = std::max(open->max_turn, c.turn);
    if (c.tilt > open->max_tilt) {
      open->max_tilt = c.tilt;
      open->max_tilt_t = t;
    }
  }

  void add(const LoggedEvent& le) {
    timeline_.add(le);
    const runtime::LogEvent& e = le.event;
    const double t = seconds(runtime::time_of(e));
    if (std::holds_alternative<ev::RunStart>(e) || std::holds_alternative<ev::FaultInjected>(e) ||
        std::holds_alternative<ev::FaultDetected>(e) || std::holds_alternative<ev::Diagnosis>(e) ||
        std::holds_alternative<ev::RecoveryEnd>(e) || std::holds_alternative<ev::CellStopped>(e) ||
        std::holds_alternative<ev::RunEnd>(e) || std::holds_alternative<ev::Physical>(e)) {
      fault_events_.push_back(le);  // few: match_faults looks back and forth among them
    }
    if (const auto* end = std::get_if<ev::RunEnd>(&e)) {
      ended_ = true;
      r_.outcome = end->outcome;
      r_.reason = end->reason;
      r_.firings = end->firings;
    } else if (std::holds_alternative<ev::Fire>(e)) {
      last_fire_ = t;
    } else if (const auto* c = std::get_if<ev::Collision>(&e)) {
      r_.collisions.push_back({t, c->a, c->b, c->depth});
    } else if (const auto* sample = std::get_if<ev::Carry>(&e)) {
      carry(t, *sample);
    } else if (const auto* arrived = std::get_if<ev::WorkpieceArrived>(&e)) {
      const std::string w = cell_workpiece(s_, arrived->workpiece);
      arrived_.insert(w);
      placement_of_.erase(w);  // a body fed anew is a new part
      ++r_.parts_fed;
    } else if (const auto* left = std::get_if<ev::WorkpieceLeft>(&e)) {
      placement_of_.erase(cell_workpiece(s_, left->workpiece));
      ++r_.parts_delivered;
    } else if (const auto* sensor = std::get_if<ev::Sensor>(&e)) {
      this->sensor(*sensor);
    } else if (const auto* lost = std::get_if<ev::WorkpieceLost>(&e)) {  // the first declaration of each part counts
      lost_.try_emplace(cell_workpiece(s_, lost->workpiece), LostPart{t, lost->reason, lost->last_seen});
    } else if (const auto* skipped = std::get_if<ev::Skipped>(&e)) {
      skipped_.insert({skipped->robot, skipped->primitive});
    } else if (const auto* start = std::get_if<ev::CommandStart>(&e)) {
      command(start->robot, start->primitive, le, true, t);
    } else if (const auto* done = std::get_if<ev::CommandEnd>(&e)) {
      command(done->robot, done->primitive, le, done->ok, t);
    }
  }

  Report finish(const std::vector<FinalPose>& finals, std::optional<double> estimated_cycle_time,
                std::optional<RunSetup> setup) && {
    Report r = std::move(r_);
    r.setup = setup ? std::move(*setup) : setup_of(s_);
    r.timeline = std::move(timeline_).finish();
    r.estimated_cycle_time = estimated_cycle_time;
    r.end_time = r.timeline.end;
    if (!ended_) {
      r.outcome = "unfinished";
      r.reason = "the event log has no run_end: the run was cut short";
    }
    if (r.outcome == "finished") r.finished_at = last_fire_;
    if (r.outcome == "stopped") {
      r.failures.push_back(
          fmt::format("the run did not finish: the cell was stopped{}", r.reason.empty() ? "" : ": " + r.reason));
    } else if (r.outcome != "finished") {
      r.failures.push_back(
          fmt::format("the run did not finish: {}{}", r.outcome, r.reason.empty() ? "" : ": " + r.reason));
    }
    match_faults(s_, fault_events_, r);
    // A workpiece is done when the last Place that released it has ended (its depart included).
    std::map<std::string, double> place_end;  // by label
    for (const auto& [w, robot_primitive] : last_release_) {
      if (auto it = end_of_.find(robot_primitive); it != end_of_.end()) place_end[w] = it->second;
    }
    account(r, finals, place_end);
    for (const auto& [t, last] : placed_) {
      if (last) r.placed_at.push_back(t);
    }
    coordination(r);
    if (r.placed_at.size() >= 3) {
      const double span = r.placed_at.back() - r.placed_at[1];
      const auto parts = static_cast<double>(r.placed_at.size() - 2);
      if (span > 0) {
        r.steady_throughput = parts * 60.0 / span;
        r.steady_cycle = span / parts;
      }
    }
    return r;
  }

 private:
  // Cycle times: a workpiece (program label W) is picked when the first command of a "Pick W" starts, and done when
  // the last command of the "Place X" that released it ("open W") has ended. Placements: an open of a Place command
  // that ended well and was not skipped (a skipped open, of a part declared lost, placed nothing).
  // A command event of `robot`'s primitive k (`le`): its start, or its end (`ok`: it ended well).
  void command(const std::string& robot, std::size_t primitive, const LoggedEvent& le, bool ok, double t) {
    const bool start = std::holds_alternative<ev::CommandStart>(le.event);
    const auto it = std::find(s_.program.robots.begin(), s_.program.robots.end(), robot);
    if (it == s_.program.robots.end()) return;  // the timeline has refused robots of run_start it does not know
    const auto& prims = s_.program.programs[static_cast<std::size_t>(it - s_.program.robots.begin())].primitives;
    const std::size_t k = primitive_of(primitive, runtime::type_of(le.event), robot, prims.size(), file_, le.line);
    const task::Primitive& p = prims[k];
    if (p.segment) segment_event(robot, *p.segment, task::to_string(p), start, t);
    if (start) {
      if (p.task.starts_with("Pick ")) pick_start_.try_emplace(p.task.substr(5), t);
      return;
    }
    end_of_[{robot, k}] = t;
    const bool release = p.kind == task::PrimitiveKind::kOpen && !p.workpiece.empty() && p.task.starts_with("Place ");
    if (release) {
      std::size_t last = k;
      while (last + 1 < prims.size() && prims[last + 1].task == p.task && prims[last + 1].where.line == p.where.line &&
             prims[last + 1].where.column == p.where.column) {
        ++last;
      }
      last_release_[p.workpiece] = {robot, last};
    }
    if (!ok) return;
    if (skipped_.erase({robot, k}) != 0) return;
    if (release) {
      const auto body = released_.find({robot, k});
      const std::string w = body != released_.end() ? body->second : cell_workpiece(s_, p.workpiece);
      placement_of_[w] = placed_.size();
      placed_.push_back({t, true});
      placed_last_[w] = true;
    }
  }

  // The part a Place lets go of (its "released" sensor event), and a Pick that grips a part placed before: that
  // placement was not the part's last (a relay: another robot picks it from there).
  void sensor(const ev::Sensor& e) {
    const auto it = std::find(s_.program.robots.begin(), s_.program.robots.end(), e.robot);
    if (it == s_.program.robots.end()) return;
    const auto& prims = s_.program.programs[static_cast<std::size_t>(it - s_.program.robots.begin())].primitives;
    if (e.primitive >= prims.size()) return;
    const task::Primitive& p = prims[e.primitive];
    const std::string& condition = e.condition;
    const std::string w = cell_workpiece(s_, e.workpiece);
    const std::string& robot = e.robot;
    const std::size_t k = e.primitive;
    if (condition == "released" && p.task.starts_with("Place ")) released_[{robot, k}] = w;
    if (condition == "gripped" && p.task.starts_with("Pick ")) {
      placed_last_[w] = false;
      if (auto placed = placement_of_.find(w); placed != placement_of_.end()) {
        placed_[placed->second].second = false;
        placement_of_.erase(placed);
      }
    }
  }

  // A command event of a coordinated segment: the n-th start of (block, index) by `robot` opens its n-th run; an end
  // closes that robot's latest run of it.
  void segment_event(const std::string& robot, const task::Segment& seg, std::string command, bool start, double t) {
    const bool master = robot == seg.master;
    std::size_t& started = segment_runs_[{robot, seg.block, seg.index}];
    if (start) {
      const auto key = std::tuple{seg.block, seg.index, started++};
      auto [it, fresh] = segment_at_.try_emplace(key, segments_.size());
      if (fresh) {
        SegmentTiming s;
        s.block = seg.block;
        s.index = seg.index;
        s.run = std::get<2>(key);
        s.master = seg.master;
        s.follower = seg.follower;
        segments_.push_back({std::move(s), {false, false}});
      }
      auto& [timing, seen] = segments_[it->second];
      (master ? timing.master_start : timing.follower_start) = t;
      if (master) timing.command = std::move(command);
      seen[master ? 0 : 1] = true;
      return;
    }
    if (started == 0) return;
    const auto it = segment_at_.find(std::tuple{seg.block, seg.index, started - 1});
    if (it == segment_at_.end()) return;
    SegmentTiming& timing = segments_[it->second].first;
    (master ? timing.master_end : timing.follower_end) = t;
  }

  // The segments both robots started, with their skews (Report::segments).
  void coordination(Report& r) {
    for (auto& [s, seen] : segments_) {
      if (!seen[0] || !seen[1]) continue;
      s.start_skew = std::abs(s.master_start - s.follower_start);
      if (s.master_end && s.follower_end) s.end_skew = std::abs(*s.master_end - *s.follower_end);
      r.max_start_skew = std::max(r.max_start_skew.value_or(0.0), s.start_skew);
      if (s.end_skew) r.max_end_skew = std::max(r.max_end_skew.value_or(0.0), *s.end_skew);
      r.segments.push_back(std::move(s));
    }
    std::stable_sort(r.segments.begin(), r.segments.end(),
                     [](const SegmentTiming& a, const SegmentTiming& b) { return a.master_start < b.master_start; });
  }

  void account(Report& r, const std::vector<FinalPose>& finals, const std::map<std::string, double>& place_end);

  const Scenario& s_;
  std::string file_;
  TimelineBuilder timeline_;
  Report r_;
  bool ended_ = false;
  std::optional<double> last_fire_;
  std::vector<LoggedEvent> fault_events_;
  std::map<std::string, LostPart> lost_;  // by cell workpiece
  std::set<std::string> arrived_;         // cell workpieces
  std::map<std::string, double> pick_start_;                              // by label
  std::map<std::pair<std::string, std::size_t>, double> end_of_;          // (robot, primitive) -> command_end time
  std::map<std::string, std::pair<std::string, std::size_t>> last_release_;  // label -> (robot, last primitive)
  std::set<std::pair<std::string, std::size_t>> skipped_;  // (robot, primitive) skipped and not yet ended
  // Placements (time, still the part's last) and, by cell workpiece, its latest one that may yet be retracted.
  std::vector<std::pair<double, bool>> placed_;
  std::map<std::string, std::size_t> placement_of_;
  std::map<std::pair<std::string, std::size_t>, std::string> released_;  // (robot, Place's open) -> the part let go
  std::map<std::string, bool> placed_last_;  // by cell workpiece: a Place let it go after its last Pick gripped it
  // Coordinated segments: each run (with which robots started it), by (block, index, run); starts per robot.
  std::vector<std::pair<SegmentTiming, std::array<bool, 2>>> segments_;
  std::map<std::tuple<std::string, int, std::size_t>, std::size_t> segment_at_;
  std::map<std::tuple<std::string, std::string, int>, std::size_t> segment_runs_;  // (robot, block, index) -> starts
};
void ReportBuilder::account(Report& r, const std::vector<FinalPose>& finals,
                            const std::map<std::string, double>& place_end) {
  const Scenario& s = s_;
  std::map<std::string, std::string> label_of;  // cell workpiece -> label
  for (const auto& b : s.workpieces) label_of[b.name] = b.label;
  std::vector<double> picks, places;
  for (const models::WorkpieceSpec& w : s.cell.workpieces) {
    WorkpieceReport wr;
    wr.name = w.name;
    if (auto it = label_of.find(w.name); it != label_of.end()) wr.label = it->second;
    const Expectation* expect = nullptr;
    for (const auto& e : s.expect) {
      if (e.workpiece == w.name) expect = &e;
    }
    wr.tolerance = expect != nullptr ? expect->tolerance : (s.expect.empty() ? 0.02 : s.expect.front().tolerance);
    auto fp = std::find_if(finals.begin(), finals.end(), [&](const FinalPose& f) { return f.name == w.name; });
    if (fp != finals.end()) {
      wr.position = fp->pose.translation();
      wr.at = places_of(s.cell, w, *fp, wr.tolerance);
      wr.final_location = wr.at.empty() ? "elsewhere" : wr.at.front();
    } else {
      wr.final_location = "unknown";
    }
    if (auto it = lost_.find(w.name); it != lost_.end()) wr.lost = it->second;
    wr.arrived = arrived_.count(w.name) > 0;
    const bool expect_lost = expect != nullptr && expect->lost();
    if (wr.lost && !expect_lost) {
      r.failures.push_back(fmt::format(
          "workpiece {}{} was declared lost at t = {:.2f} s{}; last seen {}", w.name,
          expect != nullptr ? fmt::format(" (expected at {})", expect->place) : std::string(), wr.lost->t,
          wr.lost->reason.empty() ? std::string() : " (" + wr.lost->reason + ")",
          wr.lost->last_seen ? "at " + format_position(*wr.lost->last_seen) : std::string("nowhere: it was never seen")));
      // Where it physically is, when that is not what "lost" suggests.
      if (fp != finals.end() && fp->present && !fp->held_by.empty()) {
        r.failures.back() += fmt::format(", but it is held by {}", fp->held_by);
      } else if (expect != nullptr && fp != finals.end() &&
                 std::find(wr.at.begin(), wr.at.end(), expect->place) != wr.at.end()) {
        r.failures.back() += fmt::format(", but it is at {}", expect->place);
      }
    }
    if (expect_lost) {
      wr.expected = expect->place;
      wr.ok = wr.lost.has_value();
      if (!*wr.ok) {
        r.failures.push_back(fmt::format("workpiece {} is expected to be lost, but the controller did not declare it "
                                         "lost; it is {}",
                                         w.name,
                                         wr.at.empty() ? wr.final_location
                                                       : "at " + fmt::format("{}", fmt::join(wr.at, ", "))));
      }
    } else if (expect != nullptr) {
      wr.expected = expect->place;
      wr.ok = std::find(wr.at.begin(), wr.at.end(), expect->place) != wr.at.end();
      if (!*wr.ok && !wr.lost) {
        r.failures.push_back(
            fp == finals.end()
                ? fmt::format("workpiece {} must end at {}, but its final pose is unknown", w.name, expect->place)
                : fmt::format(
                      "workpiece {} must end at {} (within {} m) but is {} at ({:.3f}, {:.3f}, {:.3f})", w.name,
                      expect->place, expect->tolerance,
                      wr.at.empty() ? std::string("elsewhere") : "at " + fmt::format("{}", fmt::join(wr.at, ", ")),
                      wr.position.x(), wr.position.y(), wr.position.z()));
      }
    }
    // The account.
    const bool present = fp != finals.end() && fp->present;
    const bool never_present = fp != finals.end() && !fp->present && !wr.arrived;
    // Where it physically is first; the controller's declaration (wr.lost) only for a part found nowhere else.
    if (never_present) {
      wr.status = PartStatus::kNotArrived;
      wr.where = wr.final_location;
    } else if (present && !fp->held_by.empty()) {
      wr.status = PartStatus::kHeld;
      wr.where = fp->held_by;
    } else if (expect != nullptr && !expect_lost && *wr.ok) {
      wr.status = PartStatus::kInPlace;
      wr.where = expect->place;
    } else if (wr.lost) {
      wr.status = PartStatus::kLost;
      wr.where = wr.final_location;
    } else {
      wr.status = PartStatus::kElsewhere;
      wr.where = wr.final_location;
    }
    // In a cell stopped safely, a part not yet where it should be is accounted where it is found (held, or
    // elsewhere, named): the run says so. Otherwise a part not where the program put it, that the controller did not
    // declare lost, is unaccounted for.
    wr.unaccounted = expect != nullptr && !expect_lost && !*wr.ok && !wr.lost && r.outcome != "stopped";
    if (!wr.label.empty()) {
      if (auto it = pick_start_.find(wr.label); it != pick_start_.end()) wr.pick_start = it->second;
      if (auto it = place_end.find(wr.label); it != place_end.end()) wr.place_end = it->second;
      // Completed: it reached its final place (report.hpp), picked and placed.
      const auto placed_last = placed_last_.find(w.name);
      const bool final_place =
          expect != nullptr
              ? !expect_lost && *wr.ok
              : !wr.lost && placed_last != placed_last_.end() && placed_last->second &&
                    (present ? fp->held_by.empty() && !wr.at.empty() : wr.arrived);
      wr.completed = final_place && wr.pick_start && wr.place_end && *wr.place_end >= *wr.pick_start;
      if (wr.completed) {
        wr.cycle_time = *wr.place_end - *wr.pick_start;
        ++r.parts_completed;
        picks.push_back(*wr.pick_start);
        places.push_back(*wr.place_end);
      }
    }
    r.workpieces.push_back(std::move(wr));
  }
  if (!picks.empty()) {
    const double span = *std::max_element(places.begin(), places.end()) - *std::min_element(picks.begin(), picks.end());
    if (span > 0) r.throughput = static_cast<double>(r.parts_completed) * 60.0 / span;
  }
}

}  // namespace

Report make_report(const Scenario& s, const std::vector<LoggedEvent>& events, const std::vector<FinalPose>& finals,
                   std::optional<double> estimated_cycle_time, const std::string& file, std::optional<RunSetup> setup) {
  ReportBuilder b(s, file);
  for (const LoggedEvent& e : events) b.add(e);
  return std::move(b).finish(finals, estimated_cycle_time, std::move(setup));
}

Report make_report(const Scenario& s, std::istream& jsonl, const std::vector<FinalPose>& finals,
                   std::optional<double> estimated_cycle_time, const std::string& file, std::optional<RunSetup> setup) {
  ReportBuilder b(s, file);
  runtime::read_log(jsonl, file, [&](const LoggedEvent& e) { b.add(e); });
  return std::move(b).finish(finals, estimated_cycle_time, std::move(setup));
}

namespace {

json opt(const std::optional<double>& v) {
  return v ? json(round4(*v)) : json();
}

}  // namespace

json to_json(const Scenario& s, const Report& r) {
  json j;
  j["scenario"] = s.source.filename().string();
  j["program"] = s.program_file.filename().string();
  j["cell"] = s.cell_file.filename().string();
  j["seed"] = s.seed;
  j["perception"] = r.setup.perception;
  json drivers = json::array();
  for (const DriverUse& d : r.setup.drivers) {
    drivers.push_back({{"robot", d.robot}, {"kind", d.kind}, {"port", d.port}, {"emulated", d.emulated}});
  }
  j["drivers"] = std::move(drivers);
  j["requested_faults"] = r.setup.faults;
  if (r.setup.parts_from_model) j["parts_from"] = "controller_model";
  j["result"] = r.ok() ? "ok" : "failed";
  j["failures"] = r.failures;
  j["outcome"] = r.outcome;
  j["reason"] = r.reason;
  j["end_time"] = round4(r.end_time);
  j["firings"] = r.firings;
  j["cycle_time"] = {{"estimated", opt(r.estimated_cycle_time)}, {"measured", opt(r.finished_at)}};
  j["throughput_parts_per_min"] = opt(r.throughput);
  j["parts_completed"] = r.parts_completed;
  json placed_at = json::array();
  for (double t : r.placed_at) placed_at.push_back(round4(t));
  j["flow"] = {{"placed", r.placed_at.size()},
               {"placed_at", std::move(placed_at)},
               {"fed", r.parts_fed},
               {"delivered", r.parts_delivered},
               {"steady_throughput_parts_per_min", opt(r.steady_throughput)},
               {"steady_cycle_s", opt(r.steady_cycle)}};
  if (!r.segments.empty()) {  // only a program with coordinated blocks: the other reports stay as they were
    json segments = json::array();
    for (const SegmentTiming& g : r.segments) {
      segments.push_back({{"block", g.block},
                          {"index", g.index},
                          {"run", g.run},
                          {"command", g.command},
                          {"master", g.master},
                          {"follower", g.follower},
                          {"start", {round4(g.master_start), round4(g.follower_start)}},
                          {"end", {opt(g.master_end), opt(g.follower_end)}},
                          {"start_skew", round4(g.start_skew)},
                          {"end_skew", opt(g.end_skew)}});
    }
    j["coordination"] = {{"segments", std::move(segments)},
                         {"max_start_skew", opt(r.max_start_skew)},
                         {"max_end_skew", opt(r.max_end_skew)}};
  }
  json wps = json::array();
  for (const WorkpieceReport& w : r.workpieces) {
    json wj;
    wj["name"] = w.name;
    wj["label"] = w.label.empty() ? json() : json(w.label);
    wj["final_location"] = w.final_location;
    wj["at"] = w.at;
    wj["position"] = {round4(w.position.x()), round4(w.position.y()), round4(w.position.z())};
    wj["expected"] = w.expected ? json(*w.expected) : json();
    wj["tolerance"] = w.tolerance;
    wj["ok"] = w.ok ? json(*w.ok) : json();
    wj["pick_start"] = opt(w.pick_start);
    wj["place_end"] = opt(w.place_end);
    wj["cycle_time"] = opt(w.cycle_time);
    wj["completed"] = w.completed;
    wps.push_back(std::move(wj));
  }
  j["workpieces"] = std::move(wps);
  json robots = json::array();
  for (const RobotTimeline& t : r.timeline.robots) {
    robots.push_back({{"robot", t.robot},
                      {"cell", t.cell},
                      {"commands", t.commands},
                      {"busy", round4(t.busy)},
                      {"waiting", round4(t.waiting)},
                      {"waiting_for_part", round4(t.waiting_for_part)},
                      {"blocked", round4(t.blocked)},
                      {"idle", round4(t.idle)}});
  }
  j["robots"] = std::move(robots);
  // Only for a log with device events, so that the report of a run without them is what it was.
  if (!r.timeline.devices.empty()) {
    json devices = json::array();
    for (const DeviceTimeline& d : r.timeline.devices) {
      json dj = {{"device", d.device}, {"kind", d.kind}, {"state", d.state}};
      if (d.kind == "machine") {
        dj["workpiece"] = d.workpiece;
        dj["busy"] = round4(d.busy);
        dj["done_waiting"] = round4(d.done);
        dj["idle"] = round4(d.idle);
        dj["utilisation"] = round4(d.utilisation);
        dj["cycles_started"] = d.cycles_started;
        dj["cycles_finished"] = d.cycles_finished;
        dj["processed"] = d.processed;
      } else if (d.kind == "conveyor") {
        dj["running"] = round4(d.running);
        dj["stopped"] = round4(d.stopped);
        dj["starts"] = d.starts;
      } else {
        dj["on"] = round4(d.on);
        dj["off"] = round4(d.off);
        dj["times_on"] = d.starts;
      }
      devices.push_back(std::move(dj));
    }
    j["devices"] = std::move(devices);
  }
  json collisions = json::array();
  for (const auto& c : r.collisions) {
    collisions.push_back({{"t", round4(c.t)}, {"a", c.a}, {"b", c.b}, {"depth", c.depth}});
  }
  j["collisions"] = std::move(collisions);
  // Written only for a run with coordinated carries.
  if (!r.carries.empty()) {
    json carries = json::array();
    for (const CarryReport& c : r.carries) {
      carries.push_back({{"workpiece", c.workpiece}, {"a", c.a}, {"b", c.b}, {"start", round4(c.start)},
                         {"end", round4(c.end)}, {"samples", c.samples}, {"peak_squeeze", c.peak_squeeze},
                         {"peak_squeeze_t", round4(c.peak_squeeze_t)}, {"max_error", c.max_error},
                         {"max_error_t", round4(c.max_error_t)}, {"max_turn", c.max_turn}, {"max_tilt", c.max_tilt},
                         {"max_tilt_t", round4(c.max_tilt_t)}});
    }
    j["carries"] = std::move(carries);
  }

  json account = json::array();
  for (const WorkpieceReport& w : r.workpieces) {
    json a;
    a["workpiece"] = w.name;
    a["status"] = to_string(w.status);
    a["where"] = w.where;
    a["expected"] = w.expected ? json(*w.expected) : json();
    a["unaccounted"] = w.unaccounted;
    if (w.lost) {
      a["lost"] = {{"t", round4(w.lost->t)},
                   {"reason", w.lost->reason},
                   {"last_seen", w.lost->last_seen ? json::array({round4(w.lost->last_seen->x()),
                                                                  round4(w.lost->last_seen->y()),
                                                                  round4(w.lost->last_seen->z())})
                                                   : json()}};
    } else {
      a["lost"] = json();
    }
    account.push_back(std::move(a));
  }
  j["account"] = std::move(account);
  j["unaccounted"] = r.unaccounted();
  j["stopped_at"] = opt(r.stopped_at);
  json faults = json::array();
  for (const FaultReport& f : r.faults) {
    json fj;
    fj["kind"] = f.kind;
    fj["t"] = round4(f.t);
    fj["robot"] = f.robot;
    fj["workpiece"] = f.workpiece;
    fj["detail"] = f.detail;
    fj["detected"] = f.detected;
    fj["detected_at"] = opt(f.detected_at);
    fj["detected_by"] = f.detected_by;
    fj["symptom"] = f.symptom;
    fj["cause"] = f.cause;
    fj["action"] = f.action;
    fj["recovered"] = f.recovered;
    fj["recovery_time"] = opt(f.recovery_time);
    fj["stopped_safely"] = f.stopped_safely;
    faults.push_back(std::move(fj));
  }
  j["faults"] = std::move(faults);
  const auto detections = [](const std::vector<Detection>& list) {
    json out = json::array();
    for (const Detection& d : list) {
      out.push_back({{"t", round4(d.t)},
                     {"robot", d.robot},
                     {"primitive", d.primitive},
                     {"symptom", d.symptom},
                     {"detail", d.detail},
                     {"cause", d.cause},
                     {"action", d.action},
                     {"recovered", d.recovered},
                     {"truth", d.truth}});
    }
    return out;
  };
  j["unexplained_faults"] = detections(r.unexplained);
  j["false_alarms"] = r.false_alarms.size();
  j["false_alarm_detections"] = detections(r.false_alarms);
  return j;
}

std::string describe_device(const DeviceTimeline& d, double end) {
  const auto share = [end](double x) { return end > 0 ? x / end * 100.0 : 0.0; };
  if (d.kind == "machine") {
    std::string out = fmt::format(
        "{} (machine): busy {:.2f} s ({:.0f} %), done waiting {:.2f} s, idle {:.2f} s; cycles {} started, {} finished; "
        "processed {}",
        d.device, d.busy, d.utilisation * 100.0, d.done, d.idle, d.cycles_started, d.cycles_finished,
        d.processed.empty() ? std::string("none") : fmt::format("{}", fmt::join(d.processed, ", ")));
    if (d.state == "busy") {
      out += fmt::format("; busy at the end{} (not processed)",
                         d.workpiece.empty() ? std::string() : " with " + d.workpiece);
    } else if (d.state == "done" && !d.workpiece.empty()) {
      out += fmt::format("; {} still in it at the end", d.workpiece);
    }
    return out;
  }
  if (d.kind == "conveyor") {
    return fmt::format("{} (conveyor): running {:.2f} s ({:.0f} %), stopped {:.2f} s; started {} time(s); {} at the end",
                       d.device, d.running, share(d.running), d.stopped, d.starts, d.state);
  }
  return fmt::format("{} (sensor): on {:.2f} s ({:.0f} %), off {:.2f} s; on {} time(s); {} at the end", d.device, d.on,
                     share(d.on), d.off, d.starts, d.state);
}

std::string describe_driver(const DriverUse& d) {
  if (!d.real()) return fmt::format("{} simulated", d.robot);
  if (d.kind == "agent") return fmt::format("{} on its agent, {}", d.robot, d.port);
  return fmt::format("{} {} {} on {}", d.robot, d.emulated ? "emulated" : "real", d.kind, d.port);
}

namespace {

std::string describe_drivers(const RunSetup& setup) {
  std::vector<std::string> each;
  for (const DriverUse& d : setup.drivers) each.push_back(describe_driver(d));
  return fmt::format("drivers: {}", each.empty() ? std::string("none") : fmt::format("{}", fmt::join(each, ", ")));
}

}  // namespace

std::string format_summary(const Report& r) {
  std::string out;
  out += fmt::format("{}: {} at t = {:.2f} s, {} firings{}\n", r.ok() ? "OK" : "FAILED", r.outcome, r.end_time,
                     r.firings, r.reason.empty() ? "" : " (" + r.reason + ")");
  out += fmt::format("perception {}; {}{}\n", r.setup.perception, describe_drivers(r.setup),
                     r.setup.faults.empty() ? std::string()
                                            : fmt::format("; faults asked for: {}", fmt::join(r.setup.faults, ", ")));
  if (r.setup.parts_from_model) out += fmt::format("parts: where {} has them\n", describe_parts_source(r.setup));
  // A time that is not known (no estimate for a run with no twin, no end for a run that never finished) is "n/a".
  const auto seconds = [](const std::optional<double>& t) {
    return t ? fmt::format("{:.2f} s", *t) : std::string("n/a");
  };
  out += fmt::format("estimated cycle time {}, measured {}\n", seconds(r.estimated_cycle_time),
                     seconds(r.finished_at));
  // Without the twin, nothing saw the parts: what is said of them is the controller's belief, and says so.
  const std::string believed = r.setup.parts_from_model ? " (controller's model)" : "";
  if (r.parts_completed > 0) {
    out += fmt::format("parts completed {}{}, throughput {} parts/min\n", r.parts_completed, believed,
                       r.throughput ? fmt::format("{:.2f}", *r.throughput) : std::string("n/a"));
  }
  if (r.steady_throughput) {
    out += fmt::format("parts placed {} (fed {}, delivered {}); steady state from the 2nd: {:.2f} parts/min, {:.2f} s "
                       "per part\n",
                       r.placed_at.size(), r.parts_fed, r.parts_delivered, *r.steady_throughput, *r.steady_cycle);
  }
  if (!r.segments.empty()) {
    out += fmt::format("coordinated segments {}: start skew at most {}, end skew at most {}\n", r.segments.size(),
                       seconds(r.max_start_skew), seconds(r.max_end_skew));
  }
  for (const RobotTimeline& t : r.timeline.robots) {
    out += fmt::format("  {} ({}): busy {:.2f} s, waiting {:.2f} s (for parts {:.2f} s), blocked {:.2f} s, idle {:.2f} s\n",
                       t.robot, t.cell, t.busy, t.waiting, t.waiting_for_part, t.blocked, t.idle);
  }
  for (const DeviceTimeline& d : r.timeline.devices) out += "  " + describe_device(d, r.timeline.end) + "\n";
  for (const WorkpieceReport& w : r.workpieces) {
    if (!w.expected) continue;
    out +=
        fmt::format("  {} {}: expected {}, is {}{}{}\n", *w.ok ? "ok  " : "FAIL", w.name, *w.expected, w.final_location,
                    believed, w.cycle_time ? fmt::format(" (cycle {:.2f} s)", *w.cycle_time) : std::string());
  }
  // The account of the parts that are not simply in place, or that are unaccounted.
  for (const WorkpieceReport& w : r.workpieces) {
    if (w.status == PartStatus::kInPlace || (!w.expected && w.status == PartStatus::kElsewhere && !w.unaccounted)) {
      continue;
    }
    std::string line = fmt::format("  part {}: {}", w.name, to_string(w.status));
    if (w.lost && w.status != PartStatus::kLost) line += fmt::format(" ({}); declared lost", w.where);
    if (w.lost) {
      line += fmt::format(" at t = {:.2f} s{}, last seen {}", w.lost->t,
                          w.lost->reason.empty() ? std::string() : " (" + w.lost->reason + ")",
                          w.lost->last_seen ? "at " + format_position(*w.lost->last_seen) : std::string("nowhere"));
    } else if (!w.where.empty()) {
      line += fmt::format(" ({})", w.where);
    }
    if (w.unaccounted) line += ": UNACCOUNTED";
    out += line + believed + "\n";
  }
  for (const CarryReport& c : r.carries) {
    out += fmt::format(
        "  carry of {} by {} and {}, t = {:.2f} .. {:.2f} s ({} periods): peak squeeze {:.1f} N {} (t = {:.2f} s), "
        "relative tool error up to {:.1f} mm (t = {:.2f} s) and {:.2f} degrees, tilt up to {:.2f} degrees (t = {:.2f} "
        "s)\n",
        c.workpiece, c.a, c.b, c.start, c.end, c.samples, std::abs(c.peak_squeeze),
        c.peak_squeeze >= 0 ? "pushing" : "pulling", c.peak_squeeze_t, c.max_error, c.max_error_t, c.max_turn,
        c.max_tilt, c.max_tilt_t);
  }
  out += fmt::format("collisions: {}\n", r.collisions.size());
  for (const auto& c : r.collisions) out += fmt::format("  t = {:.3f} s: {} - {} ({:.4f} m)\n", c.t, c.a, c.b, c.depth);
  if (!r.faults.empty() || !r.false_alarms.empty() || !r.unexplained.empty()) {
    out += fmt::format("faults injected: {}, unexplained faults: {}, false alarms: {}\n", r.faults.size(),
                       r.unexplained.size(), r.false_alarms.size());
  }
  for (const FaultReport& f : r.faults) {
    std::string line = fmt::format("  {} at t = {:.2f} s", f.kind, f.t);
    if (!f.robot.empty()) line += " on " + f.robot;
    if (!f.workpiece.empty()) line += " of " + f.workpiece;
    if (!f.detected) {
      line += ": not detected";
    } else {
      line += fmt::format(": detected at t = {:.2f} s ({}{})", *f.detected_at, f.symptom,
                          f.detected_by.empty() ? std::string() : " by " + f.detected_by);
      if (!f.cause.empty() || !f.action.empty()) line += fmt::format(", cause {}, action {}", f.cause, f.action);
      if (f.recovered) line += fmt::format(", recovered in {:.2f} s", *f.recovery_time);
    }
    if (f.stopped_safely) line += ", cell stopped safely";
    out += line + "\n";
  }
  for (const Detection& d : r.unexplained) {
    out += fmt::format("  unexplained fault at t = {:.2f} s: {} by {}{}{}{}\n", d.t, d.symptom,
                       d.robot.empty() ? std::string("the cell") : d.robot,
                       d.detail.empty() ? std::string() : " (" + d.detail + ")",
                       d.cause.empty() && d.action.empty() ? std::string()
                                                           : fmt::format(", cause {}, action {}", d.cause, d.action),
                       d.recovered ? ", recovered" : ", not recovered");
  }
  for (const Detection& d : r.false_alarms) {
    out += fmt::format("  false alarm at t = {:.2f} s: {}{}: {}\n", d.t, d.symptom,
                       d.robot.empty() ? std::string() : " by " + d.robot, d.truth);
  }
  for (const std::string& f : r.failures) out += fmt::format("  failure: {}\n", f);
  return out;
}

}  // namespace cellwright::cell
