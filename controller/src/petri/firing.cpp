#include "cellwright/petri/firing.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>

#include "cellwright/common/error.hpp"

namespace cellwright::petri {

namespace {

void check_marking(const Net& net, const Marking& m) {
  CW_CHECK(m.size() == net.num_places(), "marking has {} places, net '{}' has {}", m.size(), net.name(),
           net.num_places());
}

void check_transition(const Net& net, TransitionId t) {
  CW_CHECK(t < net.num_transitions(), "transition #{} out of range: net '{}' has {}", t, net.name(),
           net.num_transitions());
}

bool enabled_unchecked(const Transition& tr, const Marking& m) {
  for (const Arc& a : tr.inputs) {
    if (m[a.place] < a.weight) return false;
  }
  return true;
}

// Position of t in a place's round-robin order, which starts right after `last` (0 = served next).
std::uint64_t rr_distance(TransitionId t, TransitionId last, std::size_t num_transitions) {
  if (last == Arbiter::kNone) return t;
  const std::uint64_t n = num_transitions;
  return (static_cast<std::uint64_t>(t) + n - last - 1) % n;
}

}  // namespace

bool is_enabled(const Net& net, const Marking& m, TransitionId t) {
  check_marking(net, m);
  check_transition(net, t);
  return enabled_unchecked(net.transitions()[t], m);
}

std::vector<TransitionId> enabled(const Net& net, const Marking& m) {
  check_marking(net, m);
  std::vector<TransitionId> out;
  const auto& ts = net.transitions();
  for (std::size_t t = 0; t < ts.size(); ++t) {
    if (enabled_unchecked(ts[t], m)) out.push_back(static_cast<TransitionId>(t));
  }
  return out;
}

bool is_dead(const Net& net, const Marking& m) {
  check_marking(net, m);
  for (const Transition& t : net.transitions()) {
    if (enabled_unchecked(t, m)) return false;
  }
  return true;
}

Marking fire(const Net& net, const Marking& m, TransitionId t) {
  Marking next = m;
  fire_in_place(net, next, t);
  return next;
}

void fire_in_place(const Net& net, Marking& m, TransitionId t) {
  check_marking(net, m);
  check_transition(net, t);
  const Transition& tr = net.transitions()[t];
  CW_CHECK(enabled_unchecked(tr, m), "transition '{}' fired but not enabled", tr.id);
  // Check the Tokens range before changing anything, so that m is unchanged if it throws.
  for (const Arc& a : tr.outputs) {
    std::uint64_t after = m[a.place];
    for (const Arc& in : tr.inputs) {
      if (in.place == a.place) after -= in.weight;
    }
    after += a.weight;
    CW_CHECK(after <= std::numeric_limits<Tokens>::max(), "firing '{}' puts {} tokens on place '{}'", tr.id, after,
             net.places()[a.place].id);
  }
  for (const Arc& a : tr.inputs) m[a.place] -= a.weight;
  for (const Arc& a : tr.outputs) m[a.place] += a.weight;
}

Arbiter make_arbiter(const Net& net) {
  Arbiter a;
  a.last_served.assign(net.num_places(), Arbiter::kNone);
  return a;
}

std::vector<TransitionId> choose(const Net& net, const Marking& m, const Arbiter& arbiter,
                                 const std::vector<bool>& allowed) {
  check_marking(net, m);
  const std::size_t nt = net.num_transitions();
  CW_CHECK(arbiter.last_served.size() == net.num_places(), "arbiter has {} places, net '{}' has {}",
           arbiter.last_served.size(), net.name(), net.num_places());
  CW_CHECK(allowed.empty() || allowed.size() == nt, "allowed has {} entries, net '{}' has {} transitions",
           allowed.size(), net.name(), nt);
  const auto& ts = net.transitions();

  std::vector<TransitionId> candidates;
  for (std::size_t t = 0; t < nt; ++t) {
    if ((allowed.empty() || allowed[t]) && enabled_unchecked(ts[t], m)) {
      candidates.push_back(static_cast<TransitionId>(t));
    }
  }
  if (candidates.empty()) return candidates;

  // A place is contested when the candidates together want more tokens than it holds.
  std::vector<std::uint64_t> demand(net.num_places(), 0);
  for (TransitionId t : candidates) {
    for (const Arc& a : ts[t].inputs) demand[a.place] += a.weight;
  }

  // Rank: uncontested transitions first (they always fit), then by worst round-robin position over the contested
  // places, ties by id. The greedy pass below takes every candidate that still fits, so the set is maximal.
  struct Ranked {
    std::uint64_t key;
    TransitionId t;
  };
  std::vector<Ranked> ranked;
  ranked.reserve(candidates.size());
  for (TransitionId t : candidates) {
    std::uint64_t key = 0;
    for (const Arc& a : ts[t].inputs) {
      if (demand[a.place] > m[a.place]) {
        const TransitionId last = arbiter.last_served[a.place];
        CW_CHECK(last == Arbiter::kNone || last < nt, "arbiter names transition #{} of {}", last, nt);
        key = std::max(key, 1 + rr_distance(t, last, nt));
      }
    }
    ranked.push_back({key, t});
  }
  std::sort(ranked.begin(), ranked.end(),
            [](const Ranked& a, const Ranked& b) { return a.key != b.key ? a.key < b.key : a.t < b.t; });

  Marking left = m;
  std::vector<TransitionId> chosen;
  for (const Ranked& r : ranked) {
    if (enabled_unchecked(ts[r.t], left)) {
      for (const Arc& a : ts[r.t].inputs) left[a.place] -= a.weight;
      chosen.push_back(r.t);
    }
  }
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

void fire_chosen(const Net& net, Marking& m, Arbiter& arbiter, const std::vector<TransitionId>& chosen) {
  check_marking(net, m);
  const std::size_t nt = net.num_transitions();
  CW_CHECK(arbiter.last_served.size() == net.num_places(), "arbiter has {} places, net '{}' has {}",
           arbiter.last_served.size(), net.name(), net.num_places());
  std::vector<TransitionId> order = chosen;
  std::sort(order.begin(), order.end());
  CW_CHECK(std::adjacent_find(order.begin(), order.end()) == order.end(), "a transition is chosen twice");
  const auto& ts = net.transitions();

  // Check that the whole step fits before changing anything.
  Marking next = m;
  for (TransitionId t : order) {
    check_transition(net, t);
    CW_CHECK(enabled_unchecked(ts[t], next), "chosen transitions cannot fire together: '{}' lacks tokens", ts[t].id);
    for (const Arc& a : ts[t].inputs) next[a.place] -= a.weight;
  }
  for (TransitionId t : order) {
    for (const Arc& a : ts[t].outputs) {
      CW_CHECK(next[a.place] <= std::numeric_limits<Tokens>::max() - a.weight,
               "firing '{}' overflows the tokens of place '{}'", ts[t].id, net.places()[a.place].id);
      next[a.place] += a.weight;
    }
  }

  // The new last-served of a place is the chosen consumer furthest along its round-robin order.
  Arbiter updated = arbiter;
  std::vector<bool> served(net.num_places(), false);
  for (TransitionId t : order) {
    for (const Arc& a : ts[t].inputs) {
      const TransitionId old = arbiter.last_served[a.place];
      TransitionId& cur = updated.last_served[a.place];
      if (!served[a.place] || rr_distance(t, old, nt) > rr_distance(cur, old, nt)) cur = t;
      served[a.place] = true;
    }
  }
  m = std::move(next);
  arbiter = std::move(updated);
}

}  // namespace cellwright::petri
