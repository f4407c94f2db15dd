// Nets shared by the Petri net tests, built with NetBuilder, and a naive reachability oracle to check the explorer.
#pragma once

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/program.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::petri::testnets {

inline PlaceId add_place(NetBuilder& b, const std::string& id, Tokens initial = 0, PlaceKind kind = PlaceKind::kPlain) {
  Place p;
  p.id = id;
  p.name = id;
  p.initial = initial;
  p.kind = kind;
  return b.add_place(std::move(p));
}

inline TransitionId add_transition(NetBuilder& b, const std::string& id, std::vector<Arc> in, std::vector<Arc> out) {
  Transition t;
  t.id = id;
  t.name = id;
  t.inputs = std::move(in);
  t.outputs = std::move(out);
  return b.add_transition(std::move(t));
}

// `robots` robots, each looping forever: outside -> (take the region token) inside -> (give it back) outside. The
// region place starts with `free` tokens; the region's capacity is 1.
inline Net region_loop(int robots, Tokens free = 1) {
  NetBuilder b(fmt::format("loop-{}", robots));
  const PlaceId region = add_place(b, "free", free, PlaceKind::kRegion);
  Region reg;
  reg.name = "Z";
  std::vector<std::string> labels;
  for (int i = 0; i < robots; ++i) {
    const std::string r = fmt::format("r{}", i + 1);
    labels.push_back(r);
    Place out;
    out.id = r + ".out";
    out.name = r + " outside";
    out.initial = 1;
    out.kind = PlaceKind::kExecuting;
    out.origin.robot = r;
    const PlaceId o = b.add_place(out);
    Place in = out;
    in.id = r + ".in";
    in.name = r + " inside";
    in.initial = 0;
    const PlaceId p = b.add_place(in);
    reg.inside.push_back(p);
    Transition enter;
    enter.id = r + ".enter";
    enter.inputs = {{o, 1}, {region, 1}};
    enter.outputs = {{p, 1}};
    enter.origin.robot = r;
    b.add_transition(enter);
    Transition leave;
    leave.id = r + ".leave";
    leave.inputs = {{p, 1}};
    leave.outputs = {{o, 1}, {region, 1}};
    leave.origin.robot = r;
    b.add_transition(leave);
  }
  b.add_region(reg);
  b.set_robots(labels);
  return std::move(b).build();
}

// Breadth-first exploration the obvious way (std::map of full markings), as an oracle for analyze().
struct NaiveResult {
  bool complete = true;  // false when more than `cap` markings exist
  std::uint64_t states = 0;
  std::uint64_t edges = 0;
  std::uint64_t deadlocks = 0;
  std::uint64_t final_states = 0;
  std::optional<std::size_t> first_deadlock_depth;
  std::vector<Tokens> bounds;
  std::vector<bool> ever_enabled;
  std::vector<std::uint64_t> region_max;
  std::vector<std::optional<std::size_t>> region_violation_depth;
};

inline NaiveResult naive_explore(const Net& net, std::uint64_t cap) {
  NaiveResult r;
  r.bounds.assign(net.num_places(), 0);
  r.ever_enabled.assign(net.num_transitions(), false);
  r.region_max.assign(net.regions().size(), 0);
  r.region_violation_depth.assign(net.regions().size(), std::nullopt);
  std::map<Marking, std::size_t> depth;
  std::deque<Marking> queue;
  const Marking m0 = net.initial_marking();
  depth[m0] = 0;
  queue.push_back(m0);
  while (!queue.empty()) {
    const Marking m = queue.front();
    queue.pop_front();
    const std::size_t d = depth[m];
    for (std::size_t p = 0; p < m.size(); ++p) r.bounds[p] = std::max(r.bounds[p], m[p]);
    for (std::size_t k = 0; k < net.regions().size(); ++k) {
      std::uint64_t inside = 0;
      for (PlaceId p : net.regions()[k].inside) inside += m[p];
      r.region_max[k] = std::max(r.region_max[k], inside);
      if (inside > net.regions()[k].capacity && !r.region_violation_depth[k]) r.region_violation_depth[k] = d;
    }
    const std::vector<TransitionId> en = enabled(net, m);
    if (en.empty()) {
      if (net.is_final(m)) {
        ++r.final_states;
      } else {
        ++r.deadlocks;
        if (!r.first_deadlock_depth) r.first_deadlock_depth = d;
      }
    }
    for (TransitionId t : en) {
      r.ever_enabled[t] = true;
      ++r.edges;
      Marking next = fire(net, m, t);
      if (depth.count(next) != 0) continue;
      if (depth.size() >= cap) {
        r.complete = false;
        r.states = depth.size();
        return r;
      }
      depth.emplace(next, d + 1);
      queue.push_back(std::move(next));
    }
  }
  r.states = depth.size();
  return r;
}

// Replays a firing sequence from the initial marking; every step must be enabled (fire throws otherwise).
inline Marking replay(const Net& net, const std::vector<TransitionId>& path) {
  Marking m = net.initial_marking();
  for (TransitionId t : path) fire_in_place(net, m, t);
  return m;
}

// A random task program with loops, from `seed` (the same text on every platform): 1 to 4 robots, some in a lock-step
// table whose body runs in a `repeat` (lines before and after it too), the others in free sequences, some of which
// loop on their own. Commands are drawn so that the program compiles: a robot picks (the class `part`) only with
// empty hands, places (on OUT) or hands over (Put/Get, table only) only what it holds, enters only regions it is
// outside of and leaves only those it is in; each loop body ends with lines that bring every robot back to what it
// held and where it was at the body's start, and the program with lines that leave every region. Semaphores are
// signalled and waited for at random, so deadlocks, and unbounded semaphores in loops, occur among the seeds.
// With `devices`, the program also declares a machine `mill`, a conveyor `belt` and a photo-eye `eye` on it, and the
// robots command them at random: load the mill (Place mill) and unload it (Pick part from mill) as their hands allow,
// start it and wait for its cycle, run, accumulate and stop the belt, wait for the eye (docs/task-language.md,
// "Devices"): device commands out of order deadlock in the net, and a robot's device commands run between its waits
// for the device's states, so the net reduction fuses around them.
inline std::string random_looping_program(std::uint64_t seed, bool devices = false) {
  std::mt19937_64 rng(seed);
  auto below = [&](std::uint64_t n) { return rng() % n; };
  const std::size_t robots = 1 + below(4);
  const std::size_t table = below(robots + 1);  // the first `table` robots; 0: no table
  const std::size_t semaphores = below(3), regions = below(3);
  std::string out = fmt::format("# random looping program {}\nrobot", seed);
  for (std::size_t r = 0; r < robots; ++r) out += fmt::format(" r{}", r + 1);
  out += "\nworkpiece part from IN\nlocation IN OUT\n";
  for (std::size_t k = 0; k < semaphores; ++k) {
    out += fmt::format("semaphore s{}{}\n", k + 1, below(4) == 0 ? " = 1" : "");
  }
  for (std::size_t z = 0; z < regions; ++z) out += fmt::format("region Z{}\n", z + 1);
  if (devices) out += "machine mill\nconveyor belt\nsensor eye on belt\n";

  struct State {
    bool holding = false;
    std::vector<bool> inside;
    bool operator==(const State&) const = default;
  };
  std::vector<State> state(robots, State{false, std::vector<bool>(regions, false)});
  // One command for robot r that its state allows (empty: none), applied to its state. No Put/Get here.
  auto command = [&](std::size_t r) -> std::string {
    State& st = state[r];
    switch (below(devices ? 13 : 7)) {
      case 0:
        if (st.holding) break;
        st.holding = true;
        return "Pick part";
      case 1:
        if (!st.holding) break;
        st.holding = false;
        return "Place OUT";
      case 2:
        if (semaphores == 0) break;
        return fmt::format("signal s{}", 1 + below(semaphores));
      case 3:
        if (semaphores == 0) break;
        return fmt::format("wait s{}", 1 + below(semaphores));
      case 4: {
        if (regions == 0) break;
        const std::size_t z = below(regions);
        st.inside[z] = !st.inside[z];
        return fmt::format("{} Z{}", st.inside[z] ? "enter" : "leave", z + 1);
      }
      case 7:
        if (!st.holding) break;
        st.holding = false;
        return "Place mill";
      case 8:
        if (st.holding) break;
        st.holding = true;
        return "Pick part from mill";
      case 9:
        return below(2) == 0 ? "start mill" : "wait mill";
      case 10:
        return below(2) == 0 ? "run belt" : "accumulate belt";
      case 11:
        return "stop belt";
      case 12:
        return "wait eye";
      default:
        break;
    }
    return {};
  };
  // One step toward `goal` for robot r (empty when it is there).
  auto restore = [&](std::size_t r, const State& goal) -> std::string {
    State& st = state[r];
    for (std::size_t z = 0; z < regions; ++z) {
      if (st.inside[z] != goal.inside[z]) {
        st.inside[z] = goal.inside[z];
        return fmt::format("{} Z{}", goal.inside[z] ? "enter" : "leave", z + 1);
      }
    }
    if (st.holding != goal.holding) {
      st.holding = goal.holding;
      return goal.holding ? "Pick part" : "Place OUT";
    }
    return {};
  };
  auto table_line = [&](bool handover) {
    std::vector<std::string> cells(table);
    if (handover && table >= 2 && below(3) == 0) {
      const std::size_t g = below(table), t = (g + 1 + below(table - 1)) % table;
      if (state[g].holding && !state[t].holding) {
        cells[g] = fmt::format("Put r{}", t + 1);
        cells[t] = fmt::format("Get r{}", g + 1);
        state[g].holding = false;
        state[t].holding = true;
      }
    }
    for (std::size_t r = 0; r < table; ++r) {
      if (cells[r].empty()) cells[r] = command(r);
    }
    return cells;
  };
  auto emit = [&](const std::vector<std::string>& cells) {
    if (std::all_of(cells.begin(), cells.end(), [](const std::string& c) { return c.empty(); })) return false;
    out += "  " + fmt::format("{}", fmt::join(cells, " | ")) + "\n";
    return true;
  };
  // Lines until every table robot is back at `goal` (a loop's start, or outside every region at the end).
  auto restore_table = [&](const std::vector<State>& goal) {
    for (;;) {
      std::vector<std::string> cells(table);
      for (std::size_t r = 0; r < table; ++r) cells[r] = restore(r, goal[r]);
      if (!emit(cells)) return;
    }
  };
  auto outside = [&](std::size_t r) { return State{state[r].holding, std::vector<bool>(regions, false)}; };

  if (table > 0) {
    out += "steps\n  r1";
    for (std::size_t r = 1; r < table; ++r) out += fmt::format(" | r{}", r + 1);
    out += "\n";
    for (std::uint64_t n = below(2); n > 0; --n) emit(table_line(true));
    const std::vector<State> start(state.begin(), state.end());
    out += fmt::format("repeat {}\n", 1 + below(5));
    bool any = false;
    for (std::uint64_t n = 1 + below(3); n > 0; --n) any = emit(table_line(true)) || any;
    restore_table(start);
    if (!any && state == start) {  // a body is not empty: every robot picks or places, then back
      std::vector<std::string> cells(table);
      for (std::size_t r = 0; r < table; ++r) {
        cells[r] = state[r].holding ? "Place OUT" : "Pick part";
        state[r].holding = !state[r].holding;
      }
      emit(cells);
      restore_table(start);
    }
    out += "end\n";
    for (std::uint64_t n = below(2); n > 0; --n) emit(table_line(true));
    std::vector<State> goal;
    for (std::size_t r = 0; r < table; ++r) goal.push_back(outside(r));
    restore_table(goal);
    out += "end\n";
  }
  for (std::size_t r = table; r < robots; ++r) {
    out += fmt::format("sequence r{}\n", r + 1);
    auto line = [&](const std::string& c) {
      if (!c.empty()) out += "  " + c + "\n";
      return !c.empty();
    };
    for (std::uint64_t n = below(3); n > 0; --n) line(command(r));
    if (below(2) == 0) {
      const State start = state[r];
      out += fmt::format("repeat {}\n", 1 + below(5));
      bool any = false;
      for (std::uint64_t n = 1 + below(4); n > 0; --n) any = line(command(r)) || any;
      while (line(restore(r, start))) any = true;
      if (!any) {
        line(state[r].holding ? "Place OUT" : "Pick part");
        state[r].holding = !state[r].holding;
        line(restore(r, start));
      }
      out += "end\n";
    }
    for (std::uint64_t n = below(2); n > 0; --n) line(command(r));
    while (line(restore(r, outside(r)))) {
    }
    out += "end\n";
  }
  return out;
}

// The net of a task-level program given as text (named generated.task in errors).
inline Net program_net(const std::string& text) {
  return task::to_net(task::compile(task::parse_program(text, "generated.task")));
}

}  // namespace cellwright::petri::testnets
