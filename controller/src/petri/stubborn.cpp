// Stubborn sets and finite_runs (stubborn.hpp); the bounding weights are in subinvariant.cpp.
#include "cellwright/petri/stubborn.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>

#include "petri/effects.hpp"

namespace cellwright::petri {

bool finite_runs(const Net& net) {
  const auto eff = detail::effects(net);
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

StubbornSets::StubbornSets(const Net& net, const std::vector<bool>& watched)
    : net_(net),
      consumers_(net.num_places()),
      raisers_(net.num_places()),
      region_lowers_(net.num_transitions(), false),
      stamp_(net.num_transitions(), 0),
      enabled_stamp_(net.num_transitions(), 0) {
  const auto eff = detail::effects(net);
  std::vector<std::vector<std::size_t>> regions_of(net.num_places());
  for (std::size_t k = 0; k < net.regions().size(); ++k) {
    if (!watched.empty() && !watched.at(k)) continue;
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
