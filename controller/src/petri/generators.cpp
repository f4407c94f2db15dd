#include "cellwright/petri/generators.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

namespace cellwright::petri::generators {

namespace {

PlaceId plain(NetBuilder& b, const std::string& id, Tokens initial = 0) {
  Place p;
  p.id = id;
  p.name = id;
  p.initial = initial;
  return b.add_place(std::move(p));
}

void transition(NetBuilder& b, const std::string& id, std::vector<Arc> in, std::vector<Arc> out) {
  Transition t;
  t.id = id;
  t.name = id;
  t.inputs = std::move(in);
  t.outputs = std::move(out);
  b.add_transition(std::move(t));
}

}  // namespace

Net kanban(Tokens n) {
  NetBuilder b(fmt::format("kanban-{}", n));
  PlaceId pm[5], pback[5], pkan[5], pout[5];
  for (int i = 1; i <= 4; ++i) {
    pm[i] = plain(b, fmt::format("Pm{}", i));
    pback[i] = plain(b, fmt::format("Pback{}", i));
    pkan[i] = plain(b, fmt::format("Pkan{}", i), n);
    pout[i] = plain(b, fmt::format("Pout{}", i));
  }
  transition(b, "tin1", {{pkan[1], 1}}, {{pm[1], 1}});
  for (int i = 1; i <= 4; ++i) {
    transition(b, fmt::format("tredo{}", i), {{pm[i], 1}}, {{pback[i], 1}});
    transition(b, fmt::format("tback{}", i), {{pback[i], 1}}, {{pm[i], 1}});
    transition(b, fmt::format("tok{}", i), {{pm[i], 1}}, {{pout[i], 1}});
  }
  transition(b, "tsynch1_23", {{pout[1], 1}, {pkan[2], 1}, {pkan[3], 1}}, {{pkan[1], 1}, {pm[2], 1}, {pm[3], 1}});
  transition(b, "tsynch4_23", {{pout[2], 1}, {pout[3], 1}, {pkan[4], 1}}, {{pkan[2], 1}, {pkan[3], 1}, {pm[4], 1}});
  transition(b, "tout4", {{pout[4], 1}}, {{pkan[4], 1}});
  return std::move(b).build();
}

std::uint64_t kanban_reachable(std::uint64_t n) {
  const std::uint64_t c = (n + 3) * (n + 2) * (n + 1) / 6;
  const std::uint64_t n2 = n * n, n3 = n2 * n, n4 = n3 * n, n5 = n4 * n;
  return c * c * (3 * n5 + 30 * n4 + 115 * n3 + 210 * n2 + 182 * n + 60) / 60;
}

Net philosophers(int n) {
  if (n < 1) throw std::invalid_argument(fmt::format("philosophers: need at least one, got {}", n));
  NetBuilder b(fmt::format("philosophers-{}", n));
  const auto count = static_cast<std::size_t>(n);
  std::vector<PlaceId> think, fork, left, eat;
  for (std::size_t i = 0; i < count; ++i) {
    think.push_back(plain(b, fmt::format("think{}", i), 1));
    fork.push_back(plain(b, fmt::format("fork{}", i), 1));
    left.push_back(plain(b, fmt::format("hasLeft{}", i)));
    eat.push_back(plain(b, fmt::format("eat{}", i)));
  }
  for (std::size_t i = 0; i < count; ++i) {
    const PlaceId right = fork[(i + 1) % count];
    transition(b, fmt::format("takeLeft{}", i), {{think[i], 1}, {fork[i], 1}}, {{left[i], 1}});
    // One philosopher: both forks are the same place; then taking the "right" one needs it back first, so the only
    // possible step is a deadlock after the left fork, as for any n.
    transition(b, fmt::format("takeRight{}", i), {{left[i], 1}, {right, 1}}, {{eat[i], 1}});
    if (right == fork[i]) {
      transition(b, fmt::format("release{}", i), {{eat[i], 1}}, {{think[i], 1}, {fork[i], 1}});
    } else {
      transition(b, fmt::format("release{}", i), {{eat[i], 1}}, {{think[i], 1}, {fork[i], 1}, {right, 1}});
    }
  }
  return std::move(b).build();
}

Net robot_cell(int robots, int steps, int regions) {
  if (robots < 1 || regions < 0 || steps < std::max(2, 3 * regions)) {
    throw std::invalid_argument(fmt::format(
        "robot_cell: need robots >= 1, regions >= 0, steps >= max(2, 3 * regions); got {} robots, {} steps, {} regions",
        robots, steps, regions));
  }
  NetBuilder b(fmt::format("cell-{}x{}-{}", robots, steps, regions));
  std::vector<PlaceId> free;
  std::vector<Region> reg(static_cast<std::size_t>(regions));
  std::vector<int> first(static_cast<std::size_t>(regions));
  for (int k = 0; k < regions; ++k) {
    Place p;
    p.id = fmt::format("Z{}.free", k);
    p.name = fmt::format("region Z{} free", k);
    p.initial = 1;
    p.kind = PlaceKind::kRegion;
    free.push_back(b.add_place(std::move(p)));
    reg[static_cast<std::size_t>(k)].name = fmt::format("Z{}", k);
    first[static_cast<std::size_t>(k)] = k * steps / regions;
  }
  std::vector<std::string> labels;
  for (int r = 0; r < robots; ++r) {
    const std::string robot = fmt::format("r{}", r + 1);
    labels.push_back(robot);
    std::vector<PlaceId> at;
    for (int s = 0; s < steps; ++s) {
      Place p;
      p.id = fmt::format("{}.c{}", robot, s);
      p.name = fmt::format("{} executing step {}", robot, s);
      p.initial = s == 0 ? 1 : 0;
      p.kind = PlaceKind::kExecuting;
      p.origin.robot = robot;
      p.origin.line = s + 1;
      p.origin.task = fmt::format("Step {}", s);
      p.origin.motion = fmt::format("move to station {}", s);
      p.origin.primitive = s;
      at.push_back(b.add_place(std::move(p)));
    }
    for (int s = 0; s < steps; ++s) {
      const int to = (s + 1) % steps;
      Transition t;
      t.id = fmt::format("{}.t{}", robot, s);
      t.name = fmt::format("{} begin step {}", robot, to);
      t.inputs = {{at[static_cast<std::size_t>(s)], 1}};
      t.outputs = {{at[static_cast<std::size_t>(to)], 1}};
      for (int k = 0; k < regions; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if (s == first[kk]) t.inputs.push_back({free[kk], 1});       // enter
        if (s == first[kk] + 2) t.outputs.push_back({free[kk], 1});  // leave
        if (to == first[kk] + 1 || to == first[kk] + 2) reg[kk].inside.push_back(at[static_cast<std::size_t>(to)]);
      }
      t.origin = b.place(at[static_cast<std::size_t>(to)]).origin;
      t.starts_robot = static_cast<std::uint32_t>(r);
      t.starts_primitive = to;
      b.add_transition(std::move(t));
    }
  }
  for (Region& r : reg) b.add_region(std::move(r));
  b.set_robots(std::move(labels));
  return std::move(b).build();
}

std::uint64_t robot_cell_reachable(int robots, int steps, int regions) {
  const auto outside = static_cast<std::uint64_t>(steps - 2 * regions);
  std::uint64_t total = 0;
  for (int j = 0; j <= std::min(regions, robots); ++j) {
    std::uint64_t term = 1;
    for (int i = 0; i < j; ++i)
      term = term * static_cast<std::uint64_t>(regions - i) / static_cast<std::uint64_t>(i + 1);
    for (int i = 0; i < j; ++i) term *= static_cast<std::uint64_t>(robots - i) * 2;
    for (int i = 0; i < robots - j; ++i) term *= outside;
    total += term;
  }
  return total;
}

}  // namespace cellwright::petri::generators
