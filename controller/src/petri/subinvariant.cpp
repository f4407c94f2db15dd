// Bounding weightings of the places (stubborn.hpp: bounding_weights, structurally_bounded).
//
// The problem: y >= 1 with y . C(t) <= 0 for every transition t. Task nets have thousands of places, nearly all of
// them the places of robots' chains, and a general LP over all of them (8,800 columns for a dozen robots in a loop)
// takes GLPK most of a second. So the robot places are eliminated exactly first:
//  - Places are split into "path" places R and the rest E. A path place is touched by a transition only as its one
//    token taken (-1) or its one token given (+1), at most one of each per transition: robot places, chosen first,
//    then any other place that fits (a place that does not is moved to E). For a fixed weighting w of E, the
//    conditions on y(R) are difference constraints y(to) - y(from) <= -(C_E(t) . w), with y(zero) = 0 for an absent
//    end and y(r) - y(zero) >= 1: they hold iff the constraint graph has no negative cycle.
//  - Cycles lie inside strongly connected components, so the edges between components constrain nothing; inside a
//    component, a place with one edge in and one out is eliminated by adding the two edges (Fourier-Motzkin), which
//    turns each robot's loop into a single row: its events' weights summed around the loop.
//  - What is left (the weights of E, the potentials of the few places that remain) is the LP, solved by GLPK; first
//    tried with every weight 1 without GLPK (a Bellman-Ford over what is left), which is the old fast test. The
//    reduction is exact both ways, so the LP is feasible iff the net is structurally bounded.
//  - From the LP's w (turned into small-denominator rationals and scaled to integers) the robot places' weights are
//    shortest-path potentials of the whole constraint graph, and the complete weighting is checked exactly
//    (is_bounding_weighting) before it is returned.
//
// Why GLPK and not a solver of our own: what is left is plain LP feasibility, which GLPK, a well-kept Debian library
// (libglpk-dev), solves in well under a millisecond here, and it has an exact rational simplex (glp_exact) for the rare
// answer whose floating-point values do not give back an exact solution. Soundness does not rest on it: a weighting is
// used only after it has been checked with integers.
#include <glpk.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "cellwright/petri/stubborn.hpp"
#include "petri/effects.hpp"
#include "petri/lp.hpp"

namespace cellwright::petri {

namespace {

// 128-bit integers (GCC and Clang), for exact sums of weight * arc weight products.
using detail::Int128;
using detail::UInt128;
using detail::kMaxWeight;
using detail::GlpkProblem;
using detail::integral;


// A difference constraint y(to) - y(from) + sum_e coef_e * w_e <= constant over the path places' potentials y and the
// other places' weights w (terms: (index into E, coef)).
struct Row {
  std::uint32_t from = 0, to = 0;
  std::int64_t constant = 0;
  std::vector<std::pair<std::uint32_t, std::int64_t>> terms;
};

// The constraint system with the path places separated out.
struct System {
  std::size_t nodes = 0;             // path places 0..n-1 (by path index), then zero = n
  std::vector<PlaceId> path_place;   // path index -> place
  std::vector<PlaceId> other_place;  // E index -> place
  std::vector<std::uint32_t> index;  // place -> its path or E index
  std::vector<bool> is_path;         // per place
  std::vector<Row> rows;             // one per transition that changes something, then y(r) >= 1 per path place
};

System build_system(const Net& net, const detail::Effects& eff) {
  const std::size_t np = net.num_places();
  // Path places: every place to begin with; a transition that takes or gives a path place's tokens other than one at a
  // time, or takes (or gives) tokens of two path places, demotes one to E (robot places kept in preference). Demoting
  // never breaks a transition already looked at, so one pass settles it.
  std::vector<bool> path(np, true);
  auto robot = [&](PlaceId p) { return !net.places()[p].origin.robot.empty(); };
  for (const auto& e : eff) {
    PlaceId from = UINT32_MAX, to = UINT32_MAX;
    for (const auto& [p, d] : e) {
      if (!path[p]) continue;
      if (d != 1 && d != -1) {
        path[p] = false;
        continue;
      }
      PlaceId& slot = d < 0 ? from : to;
      if (slot == UINT32_MAX) {
        slot = p;
      } else if (robot(p) && !robot(slot)) {
        path[slot] = false;
        slot = p;
      } else {
        path[p] = false;
      }
    }
  }
  System s;
  s.is_path = path;
  s.index.assign(np, 0);
  for (std::size_t p = 0; p < np; ++p) {
    auto& list = path[p] ? s.path_place : s.other_place;
    s.index[p] = static_cast<std::uint32_t>(list.size());
    list.push_back(static_cast<PlaceId>(p));
  }
  s.nodes = s.path_place.size() + 1;
  const auto zero = static_cast<std::uint32_t>(s.path_place.size());
  for (const auto& e : eff) {
    Row row;
    row.from = row.to = zero;
    for (const auto& [p, d] : e) {
      if (!path[p]) {
        row.terms.emplace_back(s.index[p], d);
      } else if (d < 0) {
        row.from = s.index[p];
      } else {
        row.to = s.index[p];
      }
    }
    if (row.from == zero && row.to == zero && row.terms.empty()) continue;
    s.rows.push_back(std::move(row));
  }
  for (std::uint32_t r = 0; r < zero; ++r) s.rows.push_back(Row{r, zero, -1, {}});
  return s;
}

// Strongly connected components of the rows' graph (iterative Tarjan): component per node, numbered in reverse
// topological order (a component's successors have smaller numbers).
std::vector<std::uint32_t> components(std::size_t nodes, const std::vector<Row>& rows) {
  std::vector<std::uint32_t> begin(nodes + 1, 0), succ(rows.size());
  for (const Row& r : rows) ++begin[r.from + 1];
  std::partial_sum(begin.begin(), begin.end(), begin.begin());
  std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
  for (const Row& r : rows) succ[fill[r.from]++] = r.to;

  constexpr std::uint32_t kUnseen = UINT32_MAX;
  std::vector<std::uint32_t> order(nodes, kUnseen), low(nodes, 0), comp(nodes, kUnseen), next(nodes, 0);
  std::vector<std::uint32_t> stack, call;
  std::uint32_t counter = 0, comps = 0;
  for (std::uint32_t root = 0; root < nodes; ++root) {
    if (order[root] != kUnseen) continue;
    call.push_back(root);
    order[root] = low[root] = counter++;
    next[root] = begin[root];
    stack.push_back(root);
    while (!call.empty()) {
      const std::uint32_t v = call.back();
      if (next[v] < begin[v + 1]) {
        const std::uint32_t w = succ[next[v]++];
        if (order[w] == kUnseen) {
          order[w] = low[w] = counter++;
          next[w] = begin[w];
          stack.push_back(w);
          call.push_back(w);
        } else if (comp[w] == kUnseen) {
          low[v] = std::min(low[v], order[w]);
        }
        continue;
      }
      call.pop_back();
      if (!call.empty()) low[call.back()] = std::min(low[call.back()], low[v]);
      if (low[v] == order[v]) {
        std::uint32_t w;
        do {
          w = stack.back();
          stack.pop_back();
          comp[w] = comps;
        } while (w != v);
        ++comps;
      }
    }
  }
  return comp;
}

// The rows that can lie on a cycle (both ends in one component), with every node of one edge in and one edge out
// eliminated by adding its two rows. Nodes that remain keep their potentials as LP variables.
std::vector<Row> contract(const System& s) {
  const std::vector<std::uint32_t> comp = components(s.nodes, s.rows);
  const auto zero = static_cast<std::uint32_t>(s.nodes - 1);
  std::vector<const Row*> kept;
  std::vector<std::uint32_t> in(s.nodes, 0), out(s.nodes, 0);
  std::vector<const Row*> out_row(s.nodes, nullptr);
  for (const Row& r : s.rows) {
    if (comp[r.from] != comp[r.to]) continue;
    kept.push_back(&r);
    ++in[r.to];
    ++out[r.from];
    out_row[r.from] = &r;
  }
  auto passes_through = [&](std::uint32_t v) { return v != zero && in[v] == 1 && out[v] == 1 && out_row[v]->to != v; };
  std::vector<bool> walked(s.nodes, false);
  std::vector<std::int64_t> acc(s.other_place.size(), 0);
  std::vector<std::uint32_t> touched;
  std::vector<Row> result;
  // Adds the rows from `first` on through pass-through nodes into one row, until a node that stays.
  auto walk = [&](const Row* first, std::uint32_t stop_at) {
    Row sum;
    sum.from = first->from;
    const Row* r = first;
    for (;;) {
      sum.constant += r->constant;
      for (const auto& [e, c] : r->terms) {
        if (acc[e] == 0) touched.push_back(e);
        acc[e] += c;
      }
      const std::uint32_t v = r->to;
      if (v == stop_at || !passes_through(v)) {
        sum.to = v;
        break;
      }
      walked[v] = true;
      r = out_row[v];
    }
    for (std::uint32_t e : touched) {
      if (acc[e] != 0) sum.terms.emplace_back(e, acc[e]);
      acc[e] = 0;
    }
    touched.clear();
    std::sort(sum.terms.begin(), sum.terms.end());
    result.push_back(std::move(sum));
  };
  for (const Row* r : kept) {
    if (!passes_through(r->from)) walk(r, UINT32_MAX);
  }
  // Cycles of pass-through nodes only: one of them stays.
  for (const Row* r : kept) {
    if (passes_through(r->from) && !walked[r->from]) {
      walked[r->from] = true;
      walk(r, r->from);
    }
  }
  return result;
}

// Shortest-path potentials for difference constraints y(to) - y(from) <= length (Bellman-Ford from a virtual source
// at distance 0 to every node). Rows are taken in the given order; `max_passes` bounds the passes. nullopt on a
// negative cycle (or too many passes).
std::optional<std::vector<std::int64_t>> potentials(std::size_t nodes,
                                                    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& ends,
                                                    const std::vector<std::int64_t>& length, std::size_t max_passes) {
  std::vector<std::int64_t> dist(nodes, 0);
  for (std::size_t pass = 0; pass < max_passes; ++pass) {
    bool changed = false;
    for (std::size_t k = 0; k < ends.size(); ++k) {
      const auto [from, to] = ends[k];
      const std::int64_t d = dist[from] + length[k];
      if (d < dist[to]) {
        if (d < -kMaxWeight) return std::nullopt;
        dist[to] = d;
        changed = true;
      }
    }
    if (!changed) return dist;
  }
  return std::nullopt;
}

// The length of `row` (constant - terms . w), or nullopt past the weight limit.
std::optional<std::int64_t> length_of(const Row& row, const std::vector<std::int64_t>& w) {
  Int128 len = row.constant;
  for (const auto& [e, c] : row.terms) len -= static_cast<Int128>(c) * w[e];
  if (len > kMaxWeight || len < -kMaxWeight) return std::nullopt;
  return static_cast<std::int64_t>(len);
}

// True when the contracted rows hold for the other places' weights `w` with some potentials of the remaining nodes.
bool contracted_feasible(const System& s, const std::vector<Row>& rows, const std::vector<std::int64_t>& w) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ends;
  std::vector<std::int64_t> length;
  for (const Row& r : rows) {
    const auto len = length_of(r, w);
    if (!len) return false;
    ends.emplace_back(r.from, r.to);
    length.push_back(*len);
  }
  return potentials(s.nodes, ends, length, rows.size() + 2).has_value();
}

// The complete weighting for the other places' weights `w`: the path places' weights are potentials of every row.
std::optional<std::vector<std::uint64_t>> complete(const Net& net, const System& s,
                                                   const std::vector<std::int64_t>& w) {
  // Rows in topological order of their source's component (sources first), so that the acyclic parts settle in one
  // pass and each pass crosses every loop once.
  const std::vector<std::uint32_t> comp = components(s.nodes, s.rows);
  std::vector<std::size_t> order(s.rows.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return comp[s.rows[a].from] > comp[s.rows[b].from]; });
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ends;
  std::vector<std::int64_t> length;
  for (std::size_t k : order) {
    const auto len = length_of(s.rows[k], w);
    if (!len) return std::nullopt;
    ends.emplace_back(s.rows[k].from, s.rows[k].to);
    length.push_back(*len);
  }
  const auto dist = potentials(s.nodes, ends, length, s.nodes + 1);
  if (!dist) return std::nullopt;
  const std::int64_t at_zero = dist->back();
  std::vector<std::uint64_t> y(net.num_places());
  for (std::size_t p = 0; p < y.size(); ++p) {
    const std::int64_t v = s.is_path[p] ? (*dist)[s.index[p]] - at_zero : w[s.index[p]];
    if (v < 1 || v > kMaxWeight) return std::nullopt;
    y[p] = static_cast<std::uint64_t>(v);
  }
  return y;
}

// The contracted rows as an LP: columns w (>= 1, minimised in sum) for the other places, then a free potential for
// each remaining node but zero (fixed at 0). Returns the weights w, integral and confirmed on the contracted rows.
std::optional<std::vector<std::int64_t>> solve(const System& s, const std::vector<Row>& rows) {
  const std::size_t ne = s.other_place.size();
  const auto zero = static_cast<std::uint32_t>(s.nodes - 1);
  std::vector<int> column(s.nodes, 0);  // node -> its potential's column (0: none)
  int columns = static_cast<int>(ne);
  for (const Row& r : rows) {
    for (std::uint32_t v : {r.from, r.to}) {
      if (v != zero && column[v] == 0) column[v] = ++columns;
    }
  }
  std::vector<const Row*> lp_rows;
  for (const Row& r : rows) {
    const bool any_positive = std::any_of(r.terms.begin(), r.terms.end(), [](const auto& ec) { return ec.second > 0; });
    if (r.from == r.to && !any_positive && r.constant >= 0) continue;  // holds for every w >= 0
    lp_rows.push_back(&r);
  }
  std::vector<int> ia{0}, ja{0};
  std::vector<double> ar{0.0};
  for (std::size_t i = 0; i < lp_rows.size(); ++i) {
    const Row& r = *lp_rows[i];
    const int row = static_cast<int>(i) + 1;
    for (const auto& [e, c] : r.terms) {
      ia.push_back(row);
      ja.push_back(static_cast<int>(e) + 1);
      ar.push_back(static_cast<double>(c));
    }
    if (r.from == r.to) continue;
    for (auto [v, sign] : {std::pair{r.to, 1.0}, std::pair{r.from, -1.0}}) {
      if (v == zero) continue;
      ia.push_back(row);
      ja.push_back(column[v]);
      ar.push_back(sign);
    }
  }
  if (columns == 0) return std::nullopt;

  GlpkProblem problem;
  glp_prob* lp = problem.get();
  glp_set_obj_dir(lp, GLP_MIN);
  glp_add_cols(lp, columns);
  for (int j = 1; j <= columns; ++j) {
    const bool weight = j <= static_cast<int>(ne);
    glp_set_col_bnds(lp, j, weight ? GLP_LO : GLP_FR, weight ? 1.0 : 0.0, 0.0);
    glp_set_obj_coef(lp, j, weight ? 1.0 : 0.0);
  }
  if (!lp_rows.empty()) {
    glp_add_rows(lp, static_cast<int>(lp_rows.size()));
    for (std::size_t i = 0; i < lp_rows.size(); ++i) {
      glp_set_row_bnds(lp, static_cast<int>(i) + 1, GLP_UP, 0.0, static_cast<double>(lp_rows[i]->constant));
    }
    glp_load_matrix(lp, static_cast<int>(ia.size()) - 1, ia.data(), ja.data(), ar.data());
  }
  // A vertex counts only once it is exact integers that satisfy the rows (the exact simplex is tried when the
  // floating-point vertex does not give that back).
  return detail::optimal_vertex(
      lp,
      [&]() -> std::optional<std::vector<std::int64_t>> {
        auto w = integral(lp, ne);
        if (w && contracted_feasible(s, rows, *w)) return w;
        return std::nullopt;
      },
      [] { return true; });
}

}  // namespace

bool is_bounding_weighting(const Net& net, const std::vector<std::uint64_t>& weight) {
  if (weight.size() != net.num_places()) return false;
  if (std::any_of(weight.begin(), weight.end(), [](std::uint64_t w) { return w < 1; })) return false;
  for (const Transition& t : net.transitions()) {
    // Weights below 2^64 and arc weights below 2^32: each product is below 2^96, and a sum of fewer than 2^31 of
    // them stays inside 127 bits.
    Int128 change = 0;
    for (const Arc& a : t.inputs) change -= static_cast<Int128>(weight[a.place]) * a.weight;
    for (const Arc& a : t.outputs) change += static_cast<Int128>(weight[a.place]) * a.weight;
    if (change > 0) return false;
  }
  return true;
}

std::optional<BoundingWeights> bounding_weights(const Net& net) {
  const detail::Effects eff = detail::effects(net);
  const System s = build_system(net, eff);
  const std::vector<Row> rows = contract(s);
  // Every other place weighing 1 first: no LP.
  const std::vector<std::int64_t> ones(s.other_place.size(), 1);
  if (contracted_feasible(s, rows, ones)) {
    if (auto y = complete(net, s, ones); y && is_bounding_weighting(net, *y)) return BoundingWeights{*y, false};
  }
  if (const auto w = solve(s, rows)) {
    if (auto y = complete(net, s, *w); y && is_bounding_weighting(net, *y)) return BoundingWeights{*y, true};
  }
  return std::nullopt;
}

bool structurally_bounded(const Net& net) {
  return finite_runs(net) || bounding_weights(net).has_value();
}

}  // namespace cellwright::petri
