// Region exclusion by sub-invariants, deadlock freedom by the state equation, and the guided search for a
// counterexample (structural.hpp says what each proves and why).
#include "cellwright/petri/structural.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_set>

#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/stubborn.hpp"
#include "petri/effects.hpp"
#include "petri/lp.hpp"

namespace cellwright::petri {

namespace {

using detail::GlpkProblem;
using detail::Int128;

// y . C(t) for every t, exactly; true when none is positive.
bool sub_invariant(const detail::Effects& eff, const std::vector<std::uint64_t>& y) {
  for (const auto& e : eff) {
    Int128 change = 0;
    for (const auto& [p, d] : e) change += static_cast<Int128>(y[p]) * d;
    if (change > 0) return false;
  }
  return true;
}

Int128 weighted_initial(const Net& net, const std::vector<std::uint64_t>& y) {
  Int128 sum = 0;
  for (std::size_t p = 0; p < net.num_places(); ++p) sum += static_cast<Int128>(y[p]) * net.places()[p].initial;
  return sum;
}

// Completes `proof` (divisor and bound) from its weights; false when no place inside has a positive weight or the
// bound does not fit.
bool finish_proof(const Net& net, std::size_t k, RegionProof& proof) {
  const Region& r = net.regions()[k];
  if (r.inside.empty()) {
    proof.divisor = 1;
    proof.bound = 0;
    return true;
  }
  std::uint64_t d = std::numeric_limits<std::uint64_t>::max();
  for (PlaceId p : r.inside) d = std::min(d, proof.weight[p]);
  if (d == 0) return false;
  const Int128 b = weighted_initial(net, proof.weight) / static_cast<Int128>(d);
  if (b > static_cast<Int128>(std::numeric_limits<std::uint64_t>::max())) return false;
  proof.divisor = d;
  proof.bound = static_cast<std::uint64_t>(b);
  return true;
}

// The LP of the header comment: minimise y . M0 subject to y . C(t) <= 0, y >= 0, y(inside) >= 1.
std::optional<RegionProof> region_lp(const Net& net, std::size_t k, const detail::Effects& eff) {
  const Region& r = net.regions()[k];
  const int columns = static_cast<int>(net.num_places());
  GlpkProblem problem;
  glp_prob* lp = problem.get();
  glp_set_obj_dir(lp, GLP_MIN);
  glp_add_cols(lp, columns);
  std::vector<bool> inside(net.num_places(), false);
  for (PlaceId p : r.inside) inside[p] = true;
  for (int j = 1; j <= columns; ++j) {
    glp_set_col_bnds(lp, j, GLP_LO, inside[static_cast<std::size_t>(j - 1)] ? 1.0 : 0.0, 0.0);
    glp_set_obj_coef(lp, j, net.places()[static_cast<std::size_t>(j - 1)].initial);
  }
  std::vector<int> ia{0}, ja{0};
  std::vector<double> ar{0.0};
  int rows = 0;
  for (const auto& e : eff) {
    if (e.empty()) continue;
    ++rows;
    for (const auto& [p, d] : e) {
      ia.push_back(rows);
      ja.push_back(static_cast<int>(p) + 1);
      ar.push_back(static_cast<double>(d));
    }
  }
  if (rows > 0) {
    glp_add_rows(lp, rows);
    for (int i = 1; i <= rows; ++i) glp_set_row_bnds(lp, i, GLP_UP, 0.0, 0.0);
    glp_load_matrix(lp, static_cast<int>(ia.size()) - 1, ia.data(), ja.data(), ar.data());
  }
  return detail::optimal_vertex(
      lp,
      [&]() -> std::optional<RegionProof> {
        const auto w = detail::integral(lp, net.num_places());
        if (!w) return std::nullopt;
        RegionProof proof;
        proof.weight.assign(w->begin(), w->end());
        proof.linear_program = true;
        if (finish_proof(net, k, proof) && is_region_proof(net, k, proof)) return proof;
        return std::nullopt;
      },
      // The LP's best bound on the occupancy must be below capacity + 1, else no weighting from it can show the bound.
      [&] { return glp_get_obj_val(lp) < static_cast<double>(r.capacity) + 1.0; });
}

}  // namespace

bool is_region_proof(const Net& net, std::size_t k, const RegionProof& proof) {
  const Region& r = net.regions().at(k);
  if (proof.weight.size() != net.num_places() || proof.divisor < 1) return false;
  for (PlaceId p : r.inside) {
    if (proof.weight[p] < proof.divisor) return false;
  }
  if (std::any_of(proof.weight.begin(), proof.weight.end(), [](std::uint64_t w) { return w > (1ull << 60); })) {
    return false;
  }
  if (!sub_invariant(detail::effects(net), proof.weight)) return false;
  const Int128 bound = weighted_initial(net, proof.weight) / static_cast<Int128>(proof.divisor);
  return bound == static_cast<Int128>(proof.bound) && proof.bound <= r.capacity;
}

std::optional<RegionProof> prove_region_exclusive(const Net& net, std::size_t k) {
  const Region& r = net.regions().at(k);
  const detail::Effects eff = detail::effects(net);
  // The task net's shape first: weight 1 inside and on every shared place that a transition raising the tokens
  // inside takes from (the region's free place).
  RegionProof proof;
  proof.weight.assign(net.num_places(), 0);
  std::vector<bool> inside(net.num_places(), false);
  for (PlaceId p : r.inside) {
    inside[p] = true;
    proof.weight[p] = 1;
  }
  for (const auto& e : eff) {
    std::int64_t raise = 0;
    for (const auto& [p, d] : e) {
      if (inside[p]) raise += d;
    }
    if (raise <= 0) continue;
    for (const auto& [p, d] : e) {
      if (d < 0 && !inside[p] && net.places()[p].origin.robot.empty()) proof.weight[p] = 1;
    }
  }
  if (finish_proof(net, k, proof) && is_region_proof(net, k, proof)) return proof;
  return region_lp(net, k, eff);
}

std::vector<std::optional<std::uint64_t>> place_bounds(const Net& net) {
  const std::size_t np = net.num_places();
  const detail::Effects eff = detail::effects(net);
  std::vector<std::optional<std::uint64_t>> bound(np);
  auto tighten = [&](PlaceId p, std::uint64_t b) {
    if (!bound[p] || b < *bound[p]) bound[p] = b;
  };
  // From a verified sub-invariant y: y(p) * M(p) <= y . M <= y . M0.
  auto use = [&](const std::vector<std::uint64_t>& y) {
    const Int128 total = weighted_initial(net, y);
    for (std::size_t p = 0; p < np; ++p) {
      if (y[p] == 0) continue;
      const Int128 b = total / static_cast<Int128>(y[p]);
      if (b <= static_cast<Int128>(std::numeric_limits<std::uint32_t>::max())) {
        tighten(static_cast<PlaceId>(p), static_cast<std::uint64_t>(b));
      }
    }
  };
  // A place no transition raises keeps at most its initial tokens.
  std::vector<bool> raised(np, false);
  for (const auto& e : eff) {
    for (const auto& [p, d] : e) raised[p] = raised[p] || d > 0;
  }
  for (std::size_t p = 0; p < np; ++p) {
    if (!raised[p]) tighten(static_cast<PlaceId>(p), net.places()[p].initial);
  }
  // Each robot's places.
  std::vector<std::string> robots = net.robots();
  for (const Place& p : net.places()) {
    if (!p.origin.robot.empty() && std::find(robots.begin(), robots.end(), p.origin.robot) == robots.end()) {
      robots.push_back(p.origin.robot);
    }
  }
  for (const std::string& robot : robots) {
    std::vector<std::uint64_t> y(np, 0);
    for (std::size_t p = 0; p < np; ++p) y[p] = net.places()[p].origin.robot == robot ? 1 : 0;
    if (sub_invariant(eff, y)) use(y);
  }
  for (std::size_t k = 0; k < net.regions().size(); ++k) {
    if (const auto proof = prove_region_exclusive(net, k)) use(proof->weight);
  }
  if (!finite_runs(net)) {
    if (const auto w = bounding_weights(net)) use(w->weight);
  }
  return bound;
}

namespace {

// The integer program of the header comment, built once and re-solved with each trap constraint added.
class DeadlockProgram {
 public:
  explicit DeadlockProgram(const Net& net) : net_(net), eff_(detail::effects(net)), bound_(place_bounds(net)) {
    glp_set_obj_dir(lp(), GLP_MIN);
    // One integer column per transition that changes the marking (the others never matter to M).
    column_.assign(net.num_transitions(), 0);
    for (std::size_t t = 0; t < eff_.size(); ++t) {
      if (eff_[t].empty()) continue;
      column_[t] = glp_add_cols(lp(), 1);
      glp_set_col_kind(lp(), column_[t], GLP_IV);
      glp_set_col_bnds(lp(), column_[t], GLP_LO, 0.0, 0.0);
      glp_set_obj_coef(lp(), column_[t], 1.0);
    }
    // M(p) as an affine function of the columns.
    row_of_.resize(net.num_places());
    for (std::size_t t = 0; t < eff_.size(); ++t) {
      for (const auto& [p, d] : eff_[t]) row_of_[p].emplace_back(column_[t], static_cast<double>(d));
    }
    for (std::size_t p = 0; p < net.num_places(); ++p) {
      if (!row_of_[p].empty()) add_row({{static_cast<PlaceId>(p), 1.0}}, {}, 0.0, kLower);  // M(p) >= 0
    }
    for (const Transition& t : net.transitions()) {
      if (!add_disabled(t.inputs)) {
        vacuous_ = true;  // a transition without inputs is always enabled: nothing is ever dead
        return;
      }
    }
    if (!net.final_places().empty() && !add_disabled(net.final_places())) vacuous_ = true;
  }

  // True when no marking can be dead (a transition that needs nothing).
  bool never_dead() const { return vacuous_; }

  void add_trap(const std::vector<PlaceId>& trap) {
    std::vector<std::pair<PlaceId, double>> terms;
    for (PlaceId p : trap) terms.emplace_back(p, 1.0);
    add_row(terms, {}, 1.0, kLower);
  }

  // Solves; returns the verdict, the firing counts in `x` when feasible.
  StateEquationResult::Verdict solve(double time_limit_s, std::vector<std::uint64_t>& x, std::string& reason) {
    glp_smcp sp;
    glp_init_smcp(&sp);
    sp.msg_lev = GLP_MSG_OFF;
    sp.presolve = GLP_OFF;
    const int simplex = glp_simplex(lp(), &sp);
    if (simplex == 0 && glp_get_status(lp()) == GLP_NOFEAS) {
      // The linear relaxation is infeasible: confirmed in exact rational arithmetic before it is believed.
      if (glp_exact(lp(), &sp) == 0 && glp_get_status(lp()) == GLP_NOFEAS) return StateEquationResult::Verdict::kDeadlockFree;
      reason = "GLPK's exact simplex did not confirm the linear relaxation infeasible";
      return StateEquationResult::Verdict::kUnknown;
    }
    if (simplex != 0 || glp_get_status(lp()) != GLP_OPT) {
      reason = fmt::format("GLPK's simplex ended with code {} status {}", simplex, glp_get_status(lp()));
      return StateEquationResult::Verdict::kUnknown;
    }
    glp_iocp ip;
    glp_init_iocp(&ip);
    ip.msg_lev = GLP_MSG_OFF;
    ip.presolve = GLP_OFF;
    ip.tm_lim = static_cast<int>(std::max(1.0, time_limit_s * 1000.0));
    const int code = glp_intopt(lp(), &ip);
    const int status = glp_mip_status(lp());
    if (status == GLP_NOFEAS) {
      // Branch and cut says no integer point exists, in floating point and without a certificate that exact
      // arithmetic could check: not a proof. The check explores instead (never a wrong verdict).
      reason = "the integer program has no solution by GLPK's branch and cut, which is not an exact proof";
      return StateEquationResult::Verdict::kUnknown;
    }
    if (status != GLP_OPT && status != GLP_FEAS) {
      reason = code == GLP_ETMLIM ? fmt::format("the integer program found no answer within {:.0f} s", time_limit_s)
                                  : fmt::format("GLPK's branch and cut ended with code {}", code);
      return StateEquationResult::Verdict::kUnknown;
    }
    x.assign(net_.num_transitions(), 0);
    for (std::size_t t = 0; t < column_.size(); ++t) {
      if (column_[t] == 0) continue;
      const double v = std::round(glp_mip_col_val(lp(), column_[t]));
      x[t] = v > 0 ? static_cast<std::uint64_t>(v) : 0;
    }
    return StateEquationResult::Verdict::kCandidate;
  }

  // M0 + C x, clamped at 0 (a rounding slip would only make the candidate spurious, which the search then shows).
  Marking marking_of(const std::vector<std::uint64_t>& x) const {
    std::vector<std::int64_t> m(net_.num_places());
    for (std::size_t p = 0; p < m.size(); ++p) m[p] = net_.places()[p].initial;
    for (std::size_t t = 0; t < eff_.size(); ++t) {
      if (x[t] == 0) continue;
      for (const auto& [p, d] : eff_[t]) m[p] += d * static_cast<std::int64_t>(x[t]);
    }
    Marking out(m.size());
    for (std::size_t p = 0; p < m.size(); ++p) out[p] = static_cast<Tokens>(std::max<std::int64_t>(0, m[p]));
    return out;
  }

 private:
  enum Kind { kLower, kUpper };

  glp_prob* lp() const { return problem_.get(); }

  // Adds sum terms(M) + sum binaries <= / >= rhs, with M(p) = M0(p) + sum C(p, t) x_t.
  void add_row(const std::vector<std::pair<PlaceId, double>>& terms, const std::vector<std::pair<int, double>>& binaries,
               double rhs, Kind kind) {
    double constant = 0;
    std::vector<double> coef(static_cast<std::size_t>(glp_get_num_cols(lp())) + 1, 0.0);
    for (const auto& [p, a] : terms) {
      constant += a * net_.places()[p].initial;
      for (const auto& [col, d] : row_of_[p]) coef[static_cast<std::size_t>(col)] += a * d;
    }
    for (const auto& [col, a] : binaries) coef[static_cast<std::size_t>(col)] += a;
    std::vector<int> ind{0};
    std::vector<double> val{0.0};
    for (std::size_t j = 1; j < coef.size(); ++j) {
      if (coef[j] != 0) {
        ind.push_back(static_cast<int>(j));
        val.push_back(coef[j]);
      }
    }
    const double b = rhs - constant;
    if (ind.size() == 1) {
      // A constant row: it holds or it does not. One that cannot hold is kept as 0 >= 1 (infeasible), so the
      // program says so.
      if (kind == kLower ? 0.0 >= b : 0.0 <= b) return;
    }
    const int row = glp_add_rows(lp(), 1);
    glp_set_row_bnds(lp(), row, kind == kLower ? GLP_LO : GLP_UP, kind == kLower ? b : 0.0, kind == kLower ? 0.0 : b);
    glp_set_mat_row(lp(), row, static_cast<int>(ind.size()) - 1, ind.data(), val.data());
  }

  // Adds "some arc of `arcs` lacks tokens". Returns false when that cannot hold (no arcs).
  bool add_disabled(const std::vector<Arc>& arcs) {
    if (arcs.empty()) return false;
    std::vector<const Arc*> open;
    for (const Arc& a : arcs) {
      const auto& u = bound_[a.place];
      if (u && *u < a.weight) return true;  // never enough tokens there: always holds
      if (!u) return true;  // no proven bound: not encoded (a weaker program, still sound)
      open.push_back(&a);
    }
    const bool safe = std::all_of(open.begin(), open.end(), [&](const Arc* a) { return a->weight == 1 && *bound_[a->place] == 1; });
    if (safe) {
      std::vector<std::pair<PlaceId, double>> terms;
      for (const Arc* a : open) terms.emplace_back(a->place, 1.0);
      add_row(terms, {}, static_cast<double>(open.size()) - 1.0, kUpper);
      return true;
    }
    std::vector<std::pair<int, double>> pick;
    for (const Arc* a : open) {
      const int z = glp_add_cols(lp(), 1);
      glp_set_col_kind(lp(), z, GLP_BV);
      pick.emplace_back(z, 1.0);
      const double u = static_cast<double>(*bound_[a->place]);
      const double w = static_cast<double>(a->weight);
      // M(p) + (U - W + 1) z <= U
      add_row({{a->place, 1.0}}, {{z, u - w + 1.0}}, u, kUpper);
    }
    add_row({}, pick, 1.0, kLower);
    return true;
  }

  const Net& net_;
  const detail::Effects eff_;
  const std::vector<std::optional<std::uint64_t>> bound_;
  GlpkProblem problem_;
  std::vector<int> column_;                                   // per transition, 0: none
  std::vector<std::vector<std::pair<int, double>>> row_of_;   // per place: (column, C(p, t))
  bool vacuous_ = false;
};

// The largest trap inside the places unmarked in `m`: places are dropped while some transition takes from them and
// gives to no place left.
std::vector<PlaceId> largest_trap_unmarked(const Net& net, const Marking& m) {
  std::vector<bool> in(net.num_places(), false);
  for (std::size_t p = 0; p < m.size(); ++p) in[p] = m[p] == 0;
  for (bool changed = true; changed;) {
    changed = false;
    for (const Transition& t : net.transitions()) {
      const bool gives = std::any_of(t.outputs.begin(), t.outputs.end(), [&](const Arc& a) { return in[a.place]; });
      if (gives) continue;
      for (const Arc& a : t.inputs) {
        if (in[a.place]) {
          in[a.place] = false;
          changed = true;
        }
      }
    }
  }
  std::vector<PlaceId> trap;
  for (std::size_t p = 0; p < in.size(); ++p) {
    if (in[p]) trap.push_back(static_cast<PlaceId>(p));
  }
  return trap;
}

}  // namespace

StateEquationResult deadlock_free_by_state_equation(const Net& net, const StateEquationOptions& options) {
  StateEquationResult r;
  DeadlockProgram program(net);
  if (program.never_dead()) {
    r.verdict = StateEquationResult::Verdict::kDeadlockFree;
    return r;
  }
  for (;;) {
    std::vector<std::uint64_t> x;
    r.verdict = program.solve(options.time_limit_s, x, r.reason);
    if (r.verdict != StateEquationResult::Verdict::kCandidate) return r;
    r.marking = program.marking_of(x);
    r.firings = std::move(x);
    if (r.traps >= options.max_traps) return r;
    const std::vector<PlaceId> trap = largest_trap_unmarked(net, r.marking);
    const bool marked = std::any_of(trap.begin(), trap.end(), [&](PlaceId p) { return net.places()[p].initial > 0; });
    if (!marked) return r;
    program.add_trap(trap);
    ++r.traps;
  }
}

std::optional<std::vector<TransitionId>> guided_deadlock_search(const Net& net,
                                                                const std::vector<std::uint64_t>& firings,
                                                                std::uint64_t max_markings) {
  if (firings.size() != net.num_transitions()) throw std::invalid_argument("guided_deadlock_search: firings per transition");
  struct Hash {
    std::size_t operator()(const Marking& m) const {
      std::size_t h = 1469598103934665603ull;
      for (Tokens v : m) h = (h ^ v) * 1099511628211ull;
      return h;
    }
  };
  std::unordered_set<Marking, Hash> seen;
  std::vector<std::uint64_t> left = firings;
  std::vector<TransitionId> path;
  std::vector<Marking> stack{net.initial_marking()};
  std::vector<TransitionId> next{0};  // per depth: the next transition to try
  seen.insert(stack.back());
  auto dead_end = [&](const Marking& m) { return is_dead(net, m) && !net.is_final(m); };
  if (dead_end(stack.back())) return path;
  while (!stack.empty()) {
    const Marking& m = stack.back();
    TransitionId& t = next.back();
    while (t < net.num_transitions() && (left[t] == 0 || !is_enabled(net, m, t))) ++t;
    if (t == net.num_transitions()) {
      stack.pop_back();
      next.pop_back();
      if (!path.empty()) {
        ++left[path.back()];
        path.pop_back();
      }
      continue;
    }
    const TransitionId fired = t++;
    Marking succ = fire(net, m, fired);
    if (!seen.insert(succ).second) continue;
    if (seen.size() > max_markings) return std::nullopt;
    --left[fired];
    path.push_back(fired);
    if (dead_end(succ)) {
      // Replayed from the start with the firing rule, so that what is returned is a real counterexample.
      Marking replay = net.initial_marking();
      for (TransitionId f : path) fire_in_place(net, replay, f);
      if (dead_end(replay)) return path;
      return std::nullopt;
    }
    stack.push_back(std::move(succ));
    next.push_back(0);
  }
  return std::nullopt;
}

}  // namespace cellwright::petri
