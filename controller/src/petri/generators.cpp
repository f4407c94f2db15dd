#include "cellwright/petri/generators.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <random>
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

std::string lockstep_program(int robots, int lines, std::uint32_t repeat) {
  if (robots < 1 || lines < 1) {
    throw std::invalid_argument(
        fmt::format("lockstep_program: need robots >= 1 and lines >= 1; got {} robots, {} lines", robots, lines));
  }
  if (repeat > 0 && (lines % 4 == 1 || lines % 4 == 2)) {
    throw std::invalid_argument(fmt::format(
        "lockstep_program: a loop's body must end with every robot's hands empty: {} lines leave workpieces held "
        "(use a number of lines that is 0 or 3 modulo 4)",
        lines));
  }
  const int pairs = (robots + 1) / 2;
  std::string out = fmt::format("# {} robots in one lock-step table of {} lines{} (generators::lockstep_program)\n",
                                robots, lines, repeat > 0 ? fmt::format(", repeated {} times", repeat) : std::string());
  auto names = [](const char* prefix, int n) {
    std::string s;
    for (int i = 1; i <= n; ++i) s += fmt::format(" {}{}", prefix, i);
    return s;
  };
  out += "robot" + names("r", robots) + "\n";
  out += "workpiece" + names("W", pairs) + "\n";
  out += "location" + names("L", pairs) + "\n";
  out += "semaphore" + names("s", pairs) + "\n";
  out += "steps\n  r1";
  for (int r = 2; r <= robots; ++r) out += fmt::format(" | r{}", r);
  out += "\n";
  if (repeat > 0) out += fmt::format("repeat {}\n", repeat);
  for (int line = 0; line < lines; ++line) {
    std::vector<std::string> cells(static_cast<std::size_t>(robots));
    for (int j = 0; j < pairs; ++j) {
      const int g = 2 * j, t = 2 * j + 1;  // 0-based columns of giver and taker
      const bool alone = t >= robots;
      auto& gc = cells[static_cast<std::size_t>(g)];
      switch (line % 4) {
        case 0:
          gc = fmt::format("Pick W{}", j + 1);
          break;
        case 1:
          if (!alone) {
            gc = fmt::format("Put r{}", t + 1);
            cells[static_cast<std::size_t>(t)] = fmt::format("Get r{}", g + 1);
          }
          break;
        case 2:
          (alone ? gc : cells[static_cast<std::size_t>(t)]) = fmt::format("Place L{}", j + 1);
          break;
        default:
          if (!alone) {
            gc = fmt::format("signal s{}", j + 1);
            cells[static_cast<std::size_t>(t)] = fmt::format("wait s{}", j + 1);
          }
          break;
      }
    }
    out += "  " + fmt::format("{}", fmt::join(cells, " | ")) + "\n";
  }
  if (repeat > 0) out += "end\n";
  out += "end\n";
  return out;
}

std::string shared_region_program(int robots) {
  if (robots < 1) throw std::invalid_argument(fmt::format("shared_region_program: need robots >= 1; got {}", robots));
  std::string out =
      fmt::format("# {} free sequences sharing one region, each entering it twice (generators::shared_region_program)\n",
                  robots);
  out += "robot";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" r{}", i);
  out += "\nworkpiece";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" A{}", i);
  out += "\nlocation";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" F{} O{}", i, i);
  out += "\nregion zone\n";
  for (int i = 1; i <= robots; ++i) {
    out += fmt::format(
        "sequence r{0}\n  Pick A{0}\n  enter zone\n  Place F{0}\n  leave zone\n  home\n  enter zone\n  Pick A{0}\n"
        "  leave zone\n  Place O{0}\nend\n",
        i);
  }
  return out;
}

std::string philosophers_program(int robots) {
  if (robots < 2) throw std::invalid_argument(fmt::format("philosophers_program: need robots >= 2; got {}", robots));
  std::string out = fmt::format(
      "# {} robots each taking its own region and its neighbour's (generators::philosophers_program)\n", robots);
  out += "robot";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" r{}", i);
  out += "\nworkpiece";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" A{}", i);
  out += "\nlocation";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" F{}", i);
  out += "\nregion";
  for (int i = 1; i <= robots; ++i) out += fmt::format(" Z{}", i);
  out += "\n";
  for (int i = 1; i <= robots; ++i) {
    out += fmt::format(
        "sequence r{0}\n  Pick A{0}\n  enter Z{0}\n  enter Z{1}\n  Place F{0}\n  leave Z{1}\n  leave Z{0}\n  home\nend\n",
        i, i % robots + 1);
  }
  return out;
}

namespace {

// Deterministic on every platform (the standard distributions are not): values from the engine, reduced by modulo.
class Dice {
 public:
  explicit Dice(std::uint64_t seed) : rng_(seed) {}
  std::uint32_t below(std::uint32_t n) { return static_cast<std::uint32_t>(rng_() % n); }
  bool chance(std::uint32_t in) { return below(in) == 0; }  // 1 in `in`

 private:
  std::mt19937_64 rng_;
};

struct Op {
  enum Kind { kMove, kSignal, kWait, kEnter, kLeave, kSneak } kind = kMove;
  std::size_t object = 0;  // event or region index
};

}  // namespace

Net random_cell(std::uint64_t seed) {
  Dice dice(seed);
  const std::size_t robots = 1 + dice.below(4);
  const std::size_t declared_events = dice.below(4);
  const std::size_t regions = dice.below(3);
  std::vector<std::vector<Op>> ops(robots);
  std::vector<Tokens> event_initial;
  for (std::size_t e = 0; e < declared_events; ++e) event_initial.push_back(dice.chance(4) ? 1 : 0);
  auto new_event = [&] {
    event_initial.push_back(0);
    return event_initial.size() - 1;
  };
  std::vector<std::vector<bool>> inside(robots, std::vector<bool>(regions, false));
  auto random_ops = [&](std::size_t r, std::uint32_t count) {
    for (std::uint32_t i = 0; i < count; ++i) {
      const std::uint32_t pick = dice.below(10);
      if (pick < 3 || (pick < 7 && declared_events == 0) || (pick >= 7 && regions == 0)) {
        ops[r].push_back({Op::kMove, 0});
      } else if (pick < 5) {
        ops[r].push_back({Op::kSignal, dice.below(static_cast<std::uint32_t>(declared_events))});
      } else if (pick < 7) {
        ops[r].push_back({Op::kWait, dice.below(static_cast<std::uint32_t>(declared_events))});
      } else {
        const std::size_t z = dice.below(static_cast<std::uint32_t>(regions));
        if (inside[r][z]) {
          ops[r].push_back({Op::kLeave, z});
          inside[r][z] = false;
        } else {
          ops[r].push_back({dice.chance(12) ? Op::kSneak : Op::kEnter, z});
          inside[r][z] = true;
        }
      }
    }
  };
  auto handover = [&](std::size_t giver, std::size_t taker) {
    const std::size_t ready = new_event(), gripped = new_event(), released = new_event();
    ops[giver].insert(ops[giver].end(),
                      {{Op::kMove, 0}, {Op::kSignal, ready}, {Op::kWait, gripped}, {Op::kSignal, released}});
    ops[taker].insert(ops[taker].end(), {{Op::kWait, ready}, {Op::kSignal, gripped}, {Op::kWait, released}});
  };
  // A lock-step table among the first `table` robots (at least two), the others free sequences.
  const std::size_t table = robots >= 2 && dice.chance(3) ? 2 + dice.below(static_cast<std::uint32_t>(robots - 1)) : 0;
  if (table > 0) {
    const std::uint32_t lines = 1 + dice.below(3);
    for (std::uint32_t line = 0; line < lines; ++line) {
      for (std::size_t r = 0; r < table; ++r) random_ops(r, dice.below(3));
      if (dice.chance(3)) {
        const std::size_t g = dice.below(static_cast<std::uint32_t>(table));
        handover(g, (g + 1 + dice.below(static_cast<std::uint32_t>(table - 1))) % table);
      }
      if (line + 1 == lines) break;
      std::vector<std::vector<std::size_t>> barrier(table, std::vector<std::size_t>(table));
      for (std::size_t a = 0; a < table; ++a) {
        for (std::size_t b = 0; b < table; ++b) {
          if (a != b) barrier[a][b] = new_event();
        }
      }
      for (std::size_t a = 0; a < table; ++a) {
        for (std::size_t b = 0; b < table; ++b) {
          if (a != b) ops[a].push_back({Op::kSignal, barrier[a][b]});
        }
        for (std::size_t b = 0; b < table; ++b) {
          if (a != b) ops[a].push_back({Op::kWait, barrier[b][a]});
        }
      }
    }
  }
  for (std::size_t r = table; r < robots; ++r) random_ops(r, dice.below(6));
  if (robots >= 2 && table == 0 && dice.chance(3)) {
    const std::size_t g = dice.below(static_cast<std::uint32_t>(robots));
    handover(g, (g + 1 + dice.below(static_cast<std::uint32_t>(robots - 1))) % robots);
  }
  std::vector<bool> loops(robots);
  for (std::size_t r = 0; r < robots; ++r) {
    loops[r] = dice.chance(4);
    // Leave what is still entered (a looping robot always does, so that its next round starts outside).
    for (std::size_t z = 0; z < regions; ++z) {
      if (inside[r][z] && (loops[r] || !dice.chance(8))) {
        ops[r].push_back({Op::kLeave, z});
        inside[r][z] = false;
      }
    }
    if (ops[r].empty()) ops[r].push_back({Op::kMove, 0});
  }

  NetBuilder b(fmt::format("random-cell-{}", seed));
  std::vector<PlaceId> event_place;
  for (std::size_t e = 0; e < event_initial.size(); ++e) {
    Place p;
    p.id = fmt::format("e{}", e);
    p.name = fmt::format("event e{}", e);
    p.initial = event_initial[e];
    p.kind = PlaceKind::kEvent;
    event_place.push_back(b.add_place(std::move(p)));
  }
  std::vector<PlaceId> free_place;
  std::vector<Region> region(regions);
  for (std::size_t z = 0; z < regions; ++z) {
    Place p;
    p.id = fmt::format("Z{}.free", z);
    p.name = fmt::format("region Z{} free", z);
    p.initial = dice.chance(6) ? 2 : 1;
    p.kind = PlaceKind::kRegion;
    free_place.push_back(b.add_place(std::move(p)));
    region[z].name = fmt::format("Z{}", z);
  }
  std::vector<std::string> labels;
  std::vector<Arc> final_places;
  for (std::size_t r = 0; r < robots; ++r) {
    const std::string robot = fmt::format("r{}", r + 1);
    labels.push_back(robot);
    const std::vector<Op>& list = ops[r];
    std::vector<PlaceId> at;
    std::vector<bool> in(regions, false);
    for (std::size_t k = 0; k <= list.size(); ++k) {
      if (k == list.size() && loops[r]) break;
      Place p;
      p.id = fmt::format("{}.p{}", robot, k);
      p.name = p.id;
      p.initial = k == 0 ? 1 : 0;
      p.kind = k == 0                          ? PlaceKind::kStart
               : k == list.size()              ? PlaceKind::kDone
               : list[k - 1].kind == Op::kWait ? PlaceKind::kWaiting
                                               : PlaceKind::kExecuting;
      p.origin.robot = robot;
      p.origin.line = static_cast<int>(k);
      at.push_back(b.add_place(std::move(p)));
    }
    for (std::size_t k = 0; k < list.size(); ++k) {
      const Op& op = list[k];
      Transition t;
      t.id = fmt::format("{}.t{}", robot, k);
      t.name = t.id;
      t.origin.robot = robot;
      t.origin.line = static_cast<int>(k + 1);
      const PlaceId to = k + 1 < at.size() ? at[k + 1] : at[0];
      t.inputs.push_back({at[k], 1});
      t.outputs.push_back({to, 1});
      switch (op.kind) {
        case Op::kMove:
          break;
        case Op::kSignal:
          t.outputs.push_back({event_place[op.object], 1});
          break;
        case Op::kWait:
          t.inputs.push_back({event_place[op.object], 1});
          break;
        case Op::kEnter:
          t.inputs.push_back({free_place[op.object], 1});
          in[op.object] = true;
          break;
        case Op::kSneak:
          in[op.object] = true;
          break;
        case Op::kLeave:
          t.outputs.push_back({free_place[op.object], 1});
          in[op.object] = false;
          break;
      }
      // The place this transition leads to is inside every region the robot is in after it.
      for (std::size_t z = 0; z < regions; ++z) {
        if (in[z] && to != at[0]) region[z].inside.push_back(to);
      }
      b.add_transition(std::move(t));
    }
    if (!loops[r]) final_places.push_back({at.back(), 1});
  }
  for (Region& z : region) b.add_region(std::move(z));
  b.set_robots(std::move(labels));
  b.set_final(std::move(final_places));
  return std::move(b).build();
}

Net random_net(std::uint64_t seed) {
  Dice dice(seed);
  NetBuilder b(fmt::format("random-net-{}", seed));
  const std::size_t places = 2 + dice.below(5);
  const std::size_t transitions = 2 + dice.below(5);
  for (std::size_t p = 0; p < places; ++p) plain(b, fmt::format("p{}", p), dice.below(3));
  for (std::size_t t = 0; t < transitions; ++t) {
    std::vector<Arc> in, out;
    for (std::size_t p = 0; p < places; ++p) {
      const auto id = static_cast<PlaceId>(p);
      const std::uint32_t roll = dice.below(8);
      if (roll == 0) in.push_back({id, 1 + dice.below(2)});
      if (roll == 1) out.push_back({id, 1 + dice.below(2)});
      if (roll == 2) {
        in.push_back({id, 1});
        out.push_back({id, 1});
      }
    }
    if (in.empty() && !dice.chance(6))
      in.push_back({static_cast<PlaceId>(dice.below(static_cast<std::uint32_t>(places))), 1});
    transition(b, fmt::format("t{}", t), std::move(in), std::move(out));
  }
  if (dice.chance(2)) {
    Region z;
    z.name = "Z";
    z.inside.push_back(static_cast<PlaceId>(dice.below(static_cast<std::uint32_t>(places))));
    const auto other = static_cast<PlaceId>(dice.below(static_cast<std::uint32_t>(places)));
    if (other != z.inside.front()) z.inside.push_back(other);
    b.add_region(std::move(z));
  }
  return std::move(b).build();
}

}  // namespace cellwright::petri::generators
