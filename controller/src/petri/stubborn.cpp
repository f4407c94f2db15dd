// Stubborn sets and the structural facts the reduced search relies on (stubborn.hpp).
#include "cellwright/petri/stubborn.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>

namespace cellwright::petri {

namespace {

// Net effect of each transition on each place it touches: (place, delta) pairs, delta != 0.
std::vector<std::vector<std::pair<PlaceId, std::int64_t>>> effects(const Net& net) {
  std::vector<std::vector<std::pair<PlaceId, std::int64_t>>> out;
  out.reserve(net.num_transitions());
  for (const Transition& t : net.transitions()) {
    std::vector<std::pair<PlaceId, std::int64_t>> e;
    auto add = [&](PlaceId p, std::int64_t d) {
      for (auto& [q, v] : e) {
        if (q == p) {
          v += d;
          return;
        }
      }
      e.emplace_back(p, d);
    };
    for (const Arc& a : t.inputs) add(a.place, -static_cast<std::int64_t>(a.weight));
    for (const Arc& a : t.outputs) add(a.place, a.weight);
    std::erase_if(e, [](const auto& pv) { return pv.second == 0; });
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace

bool finite_runs(const Net& net) {
  const auto eff = effects(net);
  const std::size_t nt = net.num_transitions();
  // unknown_raisers[p]: raisers of p not yet shown finite. A transition becomes finite once some place it takes from
  // (net) has none left.
  std::vector<std::uint32_t> unknown_raisers(net.num_places(), 0);
  std::vector<std::vector<TransitionId>> takers(net.num_places());
  std::vector<std::vector<PlaceId>> raised(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    for (const auto& [p, d] : eff[t]) {
      if (d > 0) {
        ++unknown_raisers[p];
        raised[t].push_back(p);
      } else {
        takers[p].push_back(static_cast<TransitionId>(t));
      }
    }
  }
  std::vector<bool> finite(nt, false);
  std::vector<TransitionId> work;
  auto release = [&](PlaceId p) {
    for (TransitionId t : takers[p]) {
      if (!finite[t]) {
        finite[t] = true;
        work.push_back(t);
      }
    }
  };
  for (std::size_t p = 0; p < net.num_places(); ++p) {
    if (unknown_raisers[p] == 0) release(static_cast<PlaceId>(p));
  }
  std::size_t count = 0;
  while (!work.empty()) {
    const TransitionId t = work.back();
    work.pop_back();
    ++count;
    for (PlaceId p : raised[t]) {
      if (--unknown_raisers[p] == 0) release(p);
    }
  }
  return count == nt;
}

bool structurally_bounded(const Net& net) {
  if (finite_runs(net)) return true;
  const auto eff = effects(net);
  const std::size_t np = net.num_places();
  // Robot places get free weights, node index = place id; node np is the zero (y = 0) reference.
  std::vector<bool> robot(np, false);
  for (std::size_t p = 0; p < np; ++p) robot[p] = !net.places()[p].origin.robot.empty();
  struct Edge {
    std::uint32_t from, to;
    std::int64_t w;  // y(to) - y(from) <= w
  };
  std::vector<Edge> edges;
  const auto zero = static_cast<std::uint32_t>(np);
  auto fail_family = [&] {
    // Some transition moves robot tokens other than one at a time: fall back to every place weighing 1.
    std::fill(robot.begin(), robot.end(), false);
  };
  for (int attempt = 0; attempt < 2; ++attempt) {
    edges.clear();
    bool fits = true;
    for (const auto& e : eff) {
      std::int64_t rest = 0;  // weight-1 places: sum of their net change
      std::uint32_t from = zero, to = zero;
      int n_from = 0, n_to = 0;
      for (const auto& [p, d] : e) {
        if (!robot[p]) {
          rest += d;
        } else if (d == -1) {
          from = p;
          ++n_from;
        } else if (d == 1) {
          to = p;
          ++n_to;
        } else {
          fits = false;
        }
      }
      if (n_from > 1 || n_to > 1) fits = false;
      if (!fits) break;
      // y(to) - y(from) + rest <= 0, with y(zero) = 0 for an absent end.
      if (from == zero && to == zero) {
        if (rest > 0) return false;
        continue;
      }
      edges.push_back({from, to, -rest});
    }
    if (fits) break;
    if (attempt == 1) return false;
    fail_family();
  }
  // Every free weight at least 1: y(zero) - y(p) <= -1.
  for (std::uint32_t p = 0; p < np; ++p) {
    if (robot[p]) edges.push_back({p, zero, -1});
  }
  // Bellman-Ford from a virtual source at distance 0 to every node: feasible iff no negative cycle.
  std::vector<std::int64_t> dist(np + 1, 0);
  for (std::size_t pass = 0; pass <= np + 1; ++pass) {
    bool changed = false;
    for (const Edge& e : edges) {
      if (dist[e.from] + e.w < dist[e.to]) {
        dist[e.to] = dist[e.from] + e.w;
        changed = true;
      }
    }
    if (!changed) return true;
  }
  return false;
}

StubbornSets::StubbornSets(const Net& net)
    : net_(net),
      consumers_(net.num_places()),
      raisers_(net.num_places()),
      region_lowers_(net.num_transitions(), false),
      stamp_(net.num_transitions(), 0),
      enabled_stamp_(net.num_transitions(), 0) {
  const auto eff = effects(net);
  std::vector<std::vector<std::size_t>> regions_of(net.num_places());
  for (std::size_t k = 0; k < net.regions().size(); ++k) {
    for (PlaceId p : net.regions()[k].inside) regions_of[p].push_back(k);
  }
  for (std::size_t t = 0; t < net.num_transitions(); ++t) {
    const auto id = static_cast<TransitionId>(t);
    for (const Arc& a : net.transitions()[t].inputs) consumers_[a.place].push_back(id);
    std::vector<std::int64_t> region_delta(net.regions().size(), 0);
    for (const auto& [p, d] : eff[t]) {
      if (d > 0) raisers_[p].push_back(id);
      for (std::size_t k : regions_of[p]) region_delta[k] += d;
    }
    bool raises = false;
    for (std::int64_t d : region_delta) {
      raises = raises || d > 0;
      if (d < 0) region_lowers_[t] = true;
    }
    if (raises) region_raisers_.push_back(id);
  }
}

void StubbornSets::push(TransitionId t) {
  if (stamp_[t] == gen_) return;
  stamp_[t] = gen_;
  stack_.push_back(t);
}

std::size_t StubbornSets::closure(TransitionId key, std::size_t limit, const std::function<Tokens(PlaceId)>& tokens) {
  ++gen_;
  stack_.clear();
  push(key);
  std::size_t enabled_in = 0;
  bool region_raisers_in = false;
  while (!stack_.empty()) {
    const TransitionId t = stack_.back();
    stack_.pop_back();
    const Transition& tr = net_.transitions()[t];
    if (enabled_stamp_[t] == marking_gen_) {
      if (++enabled_in >= limit) return limit;
      for (const Arc& a : tr.inputs) {
        for (TransitionId c : consumers_[a.place]) push(c);
      }
      if (region_lowers_[t] && !region_raisers_in) {
        region_raisers_in = true;
        for (TransitionId r : region_raisers_) push(r);
      }
    } else {
      // Scapegoat: the insufficiently marked input place with the fewest raisers.
      const std::vector<TransitionId>* best = nullptr;
      for (const Arc& a : tr.inputs) {
        if (tokens(a.place) >= a.weight) continue;
        const auto& r = raisers_[a.place];
        if (best == nullptr || r.size() < best->size()) best = &r;
      }
      if (best != nullptr) {
        for (TransitionId r : *best) push(r);
      }
    }
  }
  return enabled_in;
}

void StubbornSets::choose(const std::vector<TransitionId>& enabled, const std::function<Tokens(PlaceId)>& tokens,
                          std::vector<TransitionId>& out) {
  ++marking_gen_;
  for (TransitionId t : enabled) enabled_stamp_[t] = marking_gen_;
  std::size_t best = enabled.size();
  TransitionId best_key = enabled.front();
  std::uint32_t best_gen = 0;  // the closure generation holding the best set, 0: none (take every enabled one)
  for (TransitionId key : enabled) {
    const std::size_t n = closure(key, best, tokens);
    if (n < best) {
      best = n;
      best_key = key;
      best_gen = gen_;
      if (best == 1) break;
    }
  }
  out.clear();
  if (best_gen == 0) {
    out = enabled;
    return;
  }
  if (best_gen != gen_) closure(best_key, std::numeric_limits<std::size_t>::max(), tokens);
  for (TransitionId t : enabled) {
    if (stamp_[t] == gen_) out.push_back(t);
  }
}

}  // namespace cellwright::petri
