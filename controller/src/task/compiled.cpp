// Text forms of compiled programs: primitive names, the `twin compile` listing and the JSON form.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "cellwright/task/compile.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::task {

const char* to_string(PrimitiveKind k) {
  switch (k) {
    case PrimitiveKind::kMove:
      return "move";
    case PrimitiveKind::kOpen:
      return "open";
    case PrimitiveKind::kClose:
      return "close";
    case PrimitiveKind::kSignal:
      return "signal";
    case PrimitiveKind::kWait:
      return "wait";
    case PrimitiveKind::kLoop:
      return "loop";
    case PrimitiveKind::kDevice:
      return "device";
  }
  return "?";
}

const char* to_string(DeviceOp op) {
  switch (op) {
    case DeviceOp::kStart:
      return "start";
    case DeviceOp::kAwaitDone:
      return "await done";
    case DeviceOp::kRun:
      return "run";
    case DeviceOp::kStop:
      return "stop";
    case DeviceOp::kAccumulate:
      return "accumulate";
    case DeviceOp::kAwaitOn:
      return "await on";
  }
  return "?";
}

std::string device_state_event(const std::string& device, const char* state) {
  return fmt::format("{}.{}", device, state);
}

std::string loop_again_event(const Loop& loop, const std::string& follower) {
  return fmt::format("{}.{}>{}.again", loop.name, loop.leader, follower);
}

std::string loop_exit_event(const Loop& loop, const std::string& follower) {
  return fmt::format("{}.{}>{}.exit", loop.name, loop.leader, follower);
}

std::string loop_taken_event(const Loop& loop, const std::string& follower) {
  return fmt::format("{}.{}>{}.taken", loop.name, follower, loop.leader);
}

std::string segment_event(const std::string& block, int k, int count, const std::string& from, const std::string& to) {
  return k > count ? fmt::format("{}.end.{}>{}", block, from, to) : fmt::format("{}.s{}.{}>{}", block, k, from, to);
}

bool declares_device(const CompiledProgram& p, const std::string& name) {
  return std::find(p.machines.begin(), p.machines.end(), name) != p.machines.end() ||
         std::find(p.conveyors.begin(), p.conveyors.end(), name) != p.conveyors.end() ||
         std::any_of(p.sensors.begin(), p.sensors.end(), [&](const SensorDecl& s) { return s.name == name; });
}

const WorkpieceClass* find_class(const CompiledProgram& program, const std::string& name) {
  for (const WorkpieceClass& c : program.classes) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

namespace {

const char* target_kind_name(TargetKind k) {
  switch (k) {
    case TargetKind::kAbove:
      return "above";
    case TargetKind::kAt:
      return "at";
    case TargetKind::kHandover:
      return "handover";
    case TargetKind::kHandApproach:
      return "hand_approach";
    case TargetKind::kHandGrasp:
      return "hand_grasp";
    case TargetKind::kHome:
      return "home";
    case TargetKind::kPark:
      return "park";
  }
  return "?";
}

std::string location(const SourceLocation& where) {
  if (where.line <= 0) return "-";
  if (where.column <= 0) return fmt::format("{}", where.line);
  return fmt::format("{}:{}", where.line, where.column);
}

nlohmann::json location_json(const SourceLocation& where) {
  return {{"file", where.file}, {"line", where.line}, {"column", where.column}};
}

std::string names(const std::vector<std::string>& list) {
  return list.empty() ? std::string("none") : fmt::format("{}", fmt::join(list, " "));
}

}  // namespace

std::string to_string(const Target& t) {
  if (t.kind == TargetKind::kHome) return "home";
  if (t.kind == TargetKind::kPark) return "park";
  return fmt::format("{}({})", target_kind_name(t.kind), t.object);
}

namespace {

std::string plain_text(const Primitive& p) {
  switch (p.kind) {
    case PrimitiveKind::kMove:
      return fmt::format("move {}", to_string(p.target));
    case PrimitiveKind::kOpen:
      return p.workpiece.empty() ? std::string("open") : fmt::format("open {}", p.workpiece);
    case PrimitiveKind::kClose:
      return p.workpiece.empty() ? std::string("close") : fmt::format("close {}", p.workpiece);
    case PrimitiveKind::kSignal:
    case PrimitiveKind::kWait:
      return fmt::format("{} {}", to_string(p.kind), p.event);
    case PrimitiveKind::kLoop:
      // The loop's name is "loopL", L the line of its `repeat`, which is where the kLoop primitive points.
      return fmt::format("loop loop{}", p.where.line);
    case PrimitiveKind::kDevice:
      return fmt::format("device {} {}", p.device, to_string(p.op));
  }
  return "?";
}

}  // namespace

std::string to_string(const Primitive& p) {
  if (!p.segment) return plain_text(p);
  const Segment& s = *p.segment;
  return fmt::format("{} [{} {}/{}: {} follows {}]", plain_text(p), s.block, s.index, s.count, s.follower, s.master);
}

std::string format_listing(const CompiledProgram& compiled) {
  // Column widths over the whole listing, so every robot's program lines up the same way.
  std::size_t index_w = 1;
  std::size_t text_w = 0;
  std::size_t where_w = 0;
  std::size_t task_w = 0;
  for (const RobotProgram& prog : compiled.programs) {
    index_w = std::max(index_w, fmt::format("{}", prog.primitives.size()).size());
    for (const Primitive& p : prog.primitives) {
      text_w = std::max(text_w, to_string(p).size());
      where_w = std::max(where_w, location(p.where).size());
      task_w = std::max(task_w, p.task.size());
    }
  }
  std::string out = fmt::format("program {}\nrobots: {}\nworkpieces: {}\n", compiled.file, names(compiled.robots),
                                names(compiled.workpieces));
  if (!compiled.classes.empty()) {
    std::vector<std::string> classes;
    for (const WorkpieceClass& c : compiled.classes) classes.push_back(fmt::format("{} from {}", c.name, c.from));
    out += fmt::format("workpiece classes: {}\n", fmt::join(classes, ", "));
  }
  out += fmt::format("locations: {}\n", names(compiled.locations));
  if (!compiled.machines.empty()) out += fmt::format("machines: {}\n", names(compiled.machines));
  if (!compiled.conveyors.empty()) out += fmt::format("conveyors: {}\n", names(compiled.conveyors));
  if (!compiled.sensors.empty()) {
    std::vector<std::string> sensors;
    for (const SensorDecl& d : compiled.sensors) sensors.push_back(fmt::format("{} on {}", d.name, d.conveyor));
    out += fmt::format("sensors: {}\n", fmt::join(sensors, ", "));
  }
  for (const RobotProgram& prog : compiled.programs) {
    const std::size_t n = prog.primitives.size();
    out += n == 0 ? fmt::format("\nrobot {}: no primitives\n", prog.robot)
                  : fmt::format("\nrobot {}: {} primitive{}\n", prog.robot, n, n == 1 ? "" : "s");
    for (std::size_t i = 0; i < n; ++i) {
      const Primitive& p = prog.primitives[i];
      out += fmt::format("  {:>{}}  {:<{}}  # {:<{}}  {:<{}}  {}\n", i, index_w, to_string(p), text_w,
                         location(p.where), where_w, p.task, task_w, p.motion);
    }
    for (const Loop& l : prog.loops) {
      const std::string decision =
          l.leader != prog.robot ? fmt::format("{} waits for {}'s decision", l.end, l.leader)
          : l.followers.empty()  ? fmt::format("{} decides again or exit", l.end)
                                 : fmt::format("{} decides again or exit and tells {}", l.end, fmt::join(l.followers, " "));
      out += fmt::format("  {} (repeat {}): body [{}, {}), {}{}\n", l.name, l.count, l.begin, l.end, decision,
                         !l.paced                  ? ""
                         : l.leader == prog.robot ? ", once each has taken the last (cooperating sequences)"
                                                   : ", and says it has taken it (cooperating sequences)");
    }
  }
  if (compiled.semaphores.empty()) {
    out += "\nsemaphores and events: none\n";
  } else {
    std::size_t name_w = 4;
    for (const Semaphore& s : compiled.semaphores) name_w = std::max(name_w, s.name.size());
    out += fmt::format("\nsemaphores and events\n  {:<{}}  initial  kind       source\n", "name", name_w);
    for (const Semaphore& s : compiled.semaphores) {
      const char* kind = s.region ? "region" : !s.device.empty() ? "device" : s.inserted ? "event" : "semaphore";
      out += fmt::format("  {:<{}}  {:>7}  {:<9}  {}\n", s.name, name_w, s.initial, kind, location(s.declared));
    }
  }
  if (compiled.regions.empty()) {
    out += "\nregions: none\n";
  } else {
    out += "\nregions (primitive index ranges [after enter, leave) per robot)\n";
    for (const RegionUse& r : compiled.regions) {
      std::vector<std::string> spans;
      for (const RegionSpan& s : r.spans) spans.push_back(fmt::format("{} [{}, {})", s.robot, s.begin, s.end));
      out += fmt::format("  {}: {}\n", r.name, spans.empty() ? "not used" : fmt::format("{}", fmt::join(spans, ", ")));
    }
  }
  if (!compiled.coordinated.empty()) {
    out += "\ncoordinated blocks (primitive index ranges [first barrier, after the last) per robot)\n";
    for (const CoordinatedUse& c : compiled.coordinated) {
      std::vector<std::string> runs;
      for (const CoordinatedUse::Run& r : c.runs) {
        runs.push_back(fmt::format("{} [{}, {}) line {}", r.robot, r.begin, r.end, r.where.line));
      }
      out += fmt::format("  {} ({}): master {}, follower {}, carrying {}, {} segments: {}\n", c.name,
                         location(c.where), c.master, c.follower, c.workpiece, c.segments.size(),
                         runs.empty() ? "not run" : fmt::format("{}", fmt::join(runs, ", ")));
      for (std::size_t k = 0; k < c.segments.size(); ++k) out += fmt::format("    {:>2}. {}\n", k + 1, c.segments[k]);
    }
  }
  return out;
}

nlohmann::json to_json(const CompiledProgram& compiled) {
  nlohmann::json programs = nlohmann::json::array();
  for (const RobotProgram& prog : compiled.programs) {
    nlohmann::json prims = nlohmann::json::array();
    for (std::size_t i = 0; i < prog.primitives.size(); ++i) {
      const Primitive& p = prog.primitives[i];
      nlohmann::json j = {{"index", i},           {"kind", to_string(p.kind)},
                          {"text", to_string(p)}, {"where", location_json(p.where)},
                          {"task", p.task},       {"motion", p.motion}};
      switch (p.kind) {
        case PrimitiveKind::kMove:
          j["target"] = {{"kind", target_kind_name(p.target.kind)}, {"object", p.target.object}};
          break;
        case PrimitiveKind::kOpen:
        case PrimitiveKind::kClose:
          j["workpiece"] = p.workpiece;
          break;
        case PrimitiveKind::kSignal:
        case PrimitiveKind::kWait:
          j["event"] = p.event;
          break;
        case PrimitiveKind::kLoop:
          j["loop"] = p.loop;
          break;
        case PrimitiveKind::kDevice:
          j["device"] = p.device;
          j["op"] = to_string(p.op);
          break;
      }
      if (p.segment) {
        j["segment"] = {{"block", p.segment->block},
                        {"index", p.segment->index},
                        {"count", p.segment->count},
                        {"master", p.segment->master},
                        {"follower", p.segment->follower}};
      }
      prims.push_back(std::move(j));
    }
    nlohmann::json loops = nlohmann::json::array();
    for (const Loop& l : prog.loops) {
      nlohmann::json j = {{"name", l.name},        {"where", location_json(l.where)},
                          {"count", l.count},      {"begin", l.begin},
                          {"end", l.end},          {"leader", l.leader},
                          {"followers", l.followers}};
      if (l.paced) j["paced"] = true;  // a loop of cooperating sequences (compiled.hpp, Loop)
      loops.push_back(std::move(j));
    }
    programs.push_back({{"robot", prog.robot}, {"primitives", std::move(prims)}, {"loops", std::move(loops)}});
  }
  nlohmann::json semaphores = nlohmann::json::array();
  for (const Semaphore& s : compiled.semaphores) {
    nlohmann::json j = {{"name", s.name},
                        {"initial", s.initial},
                        {"region", s.region},
                        {"inserted", s.inserted},
                        {"declared", location_json(s.declared)}};
    if (!s.device.empty()) j["device"] = s.device;
    semaphores.push_back(std::move(j));
  }
  nlohmann::json regions = nlohmann::json::array();
  for (const RegionUse& r : compiled.regions) {
    nlohmann::json spans = nlohmann::json::array();
    for (const RegionSpan& s : r.spans) spans.push_back({{"robot", s.robot}, {"begin", s.begin}, {"end", s.end}});
    regions.push_back({{"name", r.name}, {"spans", std::move(spans)}});
  }
  nlohmann::json classes = nlohmann::json::array();
  for (const WorkpieceClass& c : compiled.classes) {
    classes.push_back({{"name", c.name}, {"from", c.from}, {"where", location_json(c.where)}});
  }
  nlohmann::json sensors = nlohmann::json::array();
  for (const SensorDecl& d : compiled.sensors) sensors.push_back({{"name", d.name}, {"conveyor", d.conveyor}});
  nlohmann::json out = {{"file", compiled.file},
          {"robots", compiled.robots},
          {"workpieces", compiled.workpieces},
          {"classes", std::move(classes)},
          {"locations", compiled.locations},
          {"programs", std::move(programs)},
          {"semaphores", std::move(semaphores)},
          {"regions", std::move(regions)}};
  // Coordinated blocks only when the program has some, so that the JSON of a program without them is as before.
  if (!compiled.coordinated.empty()) {
    nlohmann::json blocks = nlohmann::json::array();
    for (const CoordinatedUse& c : compiled.coordinated) {
      nlohmann::json runs = nlohmann::json::array();
      for (const CoordinatedUse::Run& r : c.runs) {
        runs.push_back({{"robot", r.robot}, {"where", location_json(r.where)}, {"begin", r.begin}, {"end", r.end}});
      }
      blocks.push_back({{"name", c.name},
                        {"where", location_json(c.where)},
                        {"master", c.master},
                        {"follower", c.follower},
                        {"workpiece", c.workpiece},
                        {"segments", c.segments},
                        {"runs", std::move(runs)}});
    }
    out["coordinated"] = std::move(blocks);
  }
  // Devices only when the program declares some, so that the JSON of a program without them is as before.
  if (!compiled.machines.empty() || !compiled.conveyors.empty() || !compiled.sensors.empty()) {
    out["machines"] = compiled.machines;
    out["conveyors"] = compiled.conveyors;
    out["sensors"] = std::move(sensors);
  }
  return out;
}

}  // namespace cellwright::task
