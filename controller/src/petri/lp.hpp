// Internal to the Petri net library: what its linear programs share (subinvariant.cpp, structural.cpp): GLPK's
// problem object with its per-thread environment, and turning GLPK's floating-point answer into exact integers
// (small-denominator rationals scaled by their common denominator). Every answer so obtained is checked with integer
// arithmetic by its caller before it is trusted.
#pragma once

#include <glpk.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <optional>
#include <vector>

namespace cellwright::petri::detail {

// 128-bit integers (GCC and Clang), for exact sums of weight * arc weight products.
__extension__ typedef __int128 Int128;
__extension__ typedef unsigned __int128 UInt128;

// Weights stay below 2^53 (exact in a double).
constexpr std::int64_t kMaxWeight = std::int64_t{1} << 53;

// The rational p/q (q <= max_den) nearest to x by continued fractions, if one is within `tol` of x.
inline bool rational_near(double x, std::uint64_t max_den, double tol, std::uint64_t& num, std::uint64_t& den) {
  if (!(x >= 0) || x > 9.0e15) return false;
  std::uint64_t h0 = 0, h1 = 1, k0 = 1, k1 = 0;  // convergents h/k
  double r = x;
  for (int i = 0; i < 64; ++i) {
    const double a_d = std::floor(r);
    if (a_d > 9.0e15) return false;
    const auto a = static_cast<std::uint64_t>(a_d);
    const UInt128 h2 = static_cast<UInt128>(a) * h1 + h0, k2 = static_cast<UInt128>(a) * k1 + k0;
    if (k2 > max_den || h2 > static_cast<UInt128>(kMaxWeight)) break;
    h0 = h1;
    h1 = static_cast<std::uint64_t>(h2);
    k0 = k1;
    k1 = static_cast<std::uint64_t>(k2);
    if (std::abs(x - static_cast<double>(h1) / static_cast<double>(k1)) <= tol) {
      num = h1;
      den = k1;
      return true;
    }
    const double frac = r - a_d;
    if (frac <= 0) break;
    r = 1.0 / frac;
  }
  return false;
}

// The first `count` columns of GLPK's solution as integers: each value as a small-denominator rational, all scaled
// by the least common multiple of the denominators. nullopt when a value has no such rational or a weight would pass
// 2^53.
inline std::optional<std::vector<std::int64_t>> integral(glp_prob* lp, std::size_t count) {
  constexpr std::uint64_t kMaxDen = 1'000'000;
  std::vector<std::uint64_t> num(count), den(count);
  std::uint64_t lcm = 1;
  for (std::size_t k = 0; k < count; ++k) {
    const double v = glp_get_col_prim(lp, static_cast<int>(k) + 1);
    if (!rational_near(v, kMaxDen, 1e-9 * std::max(1.0, v), num[k], den[k])) return std::nullopt;
    lcm = std::lcm(lcm, den[k]);
    if (lcm > static_cast<std::uint64_t>(kMaxWeight)) return std::nullopt;
  }
  std::vector<std::int64_t> w(count);
  for (std::size_t k = 0; k < count; ++k) {
    const UInt128 v = static_cast<UInt128>(num[k]) * (lcm / den[k]);
    if (v > static_cast<UInt128>(kMaxWeight)) return std::nullopt;
    w[k] = static_cast<std::int64_t>(v);
  }
  return w;
}

// GLPK's problem object and its thread's environment, freed together (GLPK keeps one environment per thread).
class GlpkProblem {
 public:
  GlpkProblem() {
    glp_term_out(GLP_OFF);
    lp_ = glp_create_prob();
  }
  ~GlpkProblem() {
    glp_delete_prob(lp_);
    glp_free_env();
  }
  GlpkProblem(const GlpkProblem&) = delete;
  GlpkProblem& operator=(const GlpkProblem&) = delete;
  glp_prob* get() const { return lp_; }

 private:
  glp_prob* lp_;
};

// Solves `lp` with GLPK's floating-point simplex (presolved) and offers the optimal vertex to `accept` (which reads it
// and returns a checked answer, or nullopt); when that gives nothing, solves again with the exact rational simplex
// from the basis found and offers that vertex. `worth`, after the floating-point solve, can give up before any vertex
// is offered (an optimum too weak to serve). nullopt when a solve does not end optimal or nothing is accepted.
template <typename Accept, typename Worth>
auto optimal_vertex(glp_prob* lp, Accept&& accept, Worth&& worth) -> decltype(accept()) {
  glp_smcp parm;
  glp_init_smcp(&parm);
  parm.msg_lev = GLP_MSG_OFF;
  parm.presolve = GLP_ON;
  if (glp_simplex(lp, &parm) != 0 || glp_get_status(lp) != GLP_OPT || !worth()) return std::nullopt;
  if (auto answer = accept()) return answer;
  parm.presolve = GLP_OFF;
  if (glp_exact(lp, &parm) != 0 || glp_get_status(lp) != GLP_OPT) return std::nullopt;
  return accept();
}

}  // namespace cellwright::petri::detail
