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

// The Kanban system of Ciardo & Tilgner (1996): four stations, N kanban cards each. Station i holds parts being
// machined (Pm), sent back for rework (Pback), finished (Pout), and free cards (Pkan). Station 1 feeds stations 2 and
// 3 in one synchronised step, which together feed station 4.
inline Net kanban(Tokens n) {
  NetBuilder b(fmt::format("kanban-{}", n));
  PlaceId pm[5], pback[5], pkan[5], pout[5];
  for (int i = 1; i <= 4; ++i) {
    pm[i] = add_place(b, fmt::format("Pm{}", i));
    pback[i] = add_place(b, fmt::format("Pback{}", i));
    pkan[i] = add_place(b, fmt::format("Pkan{}", i), n);
    pout[i] = add_place(b, fmt::format("Pout{}", i));
  }
  add_transition(b, "tin1", {{pkan[1], 1}}, {{pm[1], 1}});
  for (int i = 1; i <= 4; ++i) {
    add_transition(b, fmt::format("tredo{}", i), {{pm[i], 1}}, {{pback[i], 1}});
    add_transition(b, fmt::format("tback{}", i), {{pback[i], 1}}, {{pm[i], 1}});
    add_transition(b, fmt::format("tok{}", i), {{pm[i], 1}}, {{pout[i], 1}});
  }
  add_transition(b, "tsynch1_23", {{pout[1], 1}, {pkan[2], 1}, {pkan[3], 1}}, {{pkan[1], 1}, {pm[2], 1}, {pm[3], 1}});
  add_transition(b, "tsynch4_23", {{pout[2], 1}, {pout[3], 1}, {pkan[4], 1}}, {{pkan[2], 1}, {pkan[3], 1}, {pm[4], 1}});
  add_transition(b, "tout4", {{pout[4], 1}}, {{pkan[4], 1}});
  return std::move(b).build();
}

// The published closed form for the Kanban net's reachable markings: C(N+3,3)^2 (3N^5+30N^4+115N^3+210N^2+182N+60)/60.
inline std::uint64_t kanban_states(std::uint64_t n) {
  const std::uint64_t c = (n + 3) * (n + 2) * (n + 1) / 6;
  return c * c * (3 * n * n * n * n * n + 30 * n * n * n * n + 115 * n * n * n + 210 * n * n + 182 * n + 60) / 60;
}

// Dining philosophers: each takes the left fork, then the right one, eats, and puts both back. All holding their
// left fork is a deadlock.
inline Net philosophers(int n) {
  NetBuilder b(fmt::format("philosophers-{}", n));
  std::vector<PlaceId> think, fork, left, eat;
  for (int i = 0; i < n; ++i) {
    think.push_back(add_place(b, fmt::format("think{}", i), 1));
    fork.push_back(add_place(b, fmt::format("fork{}", i), 1));
    left.push_back(add_place(b, fmt::format("hasLeft{}", i)));
    eat.push_back(add_place(b, fmt::format("eat{}", i)));
  }
  for (int i = 0; i < n; ++i) {
    const PlaceId right = fork[static_cast<std::size_t>((i + 1) % n)];
    const auto k = static_cast<std::size_t>(i);
    add_transition(b, fmt::format("takeLeft{}", i), {{think[k], 1}, {fork[k], 1}}, {{left[k], 1}});
    add_transition(b, fmt::format("takeRight{}", i), {{left[k], 1}, {right, 1}}, {{eat[k], 1}});
    add_transition(b, fmt::format("release{}", i), {{eat[k], 1}}, {{think[k], 1}, {fork[k], 1}, {right, 1}});
  }
  return std::move(b).build();
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
