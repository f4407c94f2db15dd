// Nets shared by the Petri net tests, built with NetBuilder, and a naive reachability oracle to check the explorer.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "cellwright/petri/net.hpp"

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

}  // namespace cellwright::petri::testnets
