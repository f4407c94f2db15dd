// Berthelot's agglomerations (agglomerate.hpp).
#include "cellwright/petri/agglomerate.hpp"

#include <algorithm>
#include <deque>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/firing.hpp"

namespace cellwright::petri {

namespace {

constexpr std::uint32_t kGone = UINT32_MAX;

// A transition of the net being reduced. Its expansion is a linked list of original transitions (Reducer::next_),
// so that fusing two transitions concatenates their sequences in constant time.
struct WorkTransition {
  std::vector<Arc> in, out;
  TransitionId first = 0, last = 0;
  bool alive = true;
};

// The producers (or consumers) of a place, as their number and the xor of their indices: enough to name the one
// transition when there is one, and updated in constant time when transitions fuse.
struct Ends {
  std::uint32_t count = 0;
  std::uint32_t xored = 0;
  void add(std::uint32_t t) {
    ++count;
    xored ^= t;
  }
  void remove(std::uint32_t t) {
    --count;
    xored ^= t;
  }
};

Tokens weight_of(const std::vector<Arc>& arcs, PlaceId p) {
  for (const Arc& a : arcs) {
    if (a.place == p) return a.weight;
  }
  return 0;
}

// Adds `a` to `arcs`, merging with an arc to the same place. Returns true when the place is new to `arcs`.
bool add_arc(std::vector<Arc>& arcs, const Arc& a) {
  for (Arc& b : arcs) {
    if (b.place == a.place) {
      b.weight += a.weight;
      return false;
    }
  }
  arcs.push_back(a);
  return true;
}

void remove_arc(std::vector<Arc>& arcs, PlaceId p) {
  arcs.erase(std::remove_if(arcs.begin(), arcs.end(), [p](const Arc& a) { return a.place == p; }), arcs.end());
}

class Reducer {
 public:
  explicit Reducer(const Net& net)
      : net_(net), producers_(net.num_places()), consumers_(net.num_places()), next_(net.num_transitions(), kGone) {
    fixed_.assign(net.num_places(), false);
    for (std::size_t p = 0; p < net.num_places(); ++p) fixed_[p] = net.places()[p].initial > 0;
    for (const Region& r : net.regions()) {
      for (PlaceId p : r.inside) fixed_[p] = true;
    }
    for (const Arc& a : net.final_places()) fixed_[a.place] = true;
    final_.assign(net.num_places(), false);
    for (const Arc& a : net.final_places()) final_[a.place] = true;
    ts_.resize(net.num_transitions());
    for (std::size_t t = 0; t < net.num_transitions(); ++t) {
      const Transition& tr = net.transitions()[t];
      ts_[t].in = tr.inputs;
      ts_[t].out = tr.outputs;
      ts_[t].first = ts_[t].last = static_cast<TransitionId>(t);
      for (const Arc& a : tr.inputs) consumers_[a.place].add(static_cast<std::uint32_t>(t));
      for (const Arc& a : tr.outputs) producers_[a.place].add(static_cast<std::uint32_t>(t));
    }
    place_alive_.assign(net.num_places(), true);
    queued_.assign(net.num_places(), true);
    for (std::size_t p = 0; p < net.num_places(); ++p) work_.push_back(static_cast<PlaceId>(p));
  }

  Agglomeration run() {
    Agglomeration out;
    out.delayed.assign(net_.num_transitions(), false);
    while (!work_.empty()) {
      const PlaceId p = work_.front();
      work_.pop_front();
      queued_[p] = false;
      if (!place_alive_[p] || fixed_[p]) continue;
      if (producers_[p].count != 1 || consumers_[p].count != 1) continue;
      const std::uint32_t h = producers_[p].xored, f = consumers_[p].xored;
      if (h == f || weight_of(ts_[h].out, p) != 1 || weight_of(ts_[f].in, p) != 1) continue;
      if (ts_[f].in.size() == 1 && !ts_[f].out.empty()) {
        post(p, h, f);
        ++out.post;
      } else if (delayable(p, h, f)) {
        for (TransitionId t = ts_[h].first; t != kGone; t = next_[t]) out.delayed[t] = true;
        pre(p, h, f);
        ++out.pre;
      }
    }
    build(out);
    return out;
  }

 private:
  // Pre-agglomeration's conditions beyond the common ones (agglomerate.hpp).
  bool delayable(PlaceId p, std::uint32_t h, std::uint32_t f) const {
    const WorkTransition& th = ts_[h];
    if (th.out.size() != 1 || th.in.empty()) return false;
    for (const Arc& a : th.in) {
      if (a.place == p || final_[a.place] || consumers_[a.place].count != 1) return false;
      if (weight_of(ts_[f].in, a.place) != 0) return false;
    }
    return true;
  }

  void enqueue(PlaceId p) {
    if (place_alive_[p] && !queued_[p]) {
      queued_[p] = true;
      work_.push_back(p);
    }
  }
  void enqueue_around(const WorkTransition& t) {
    for (const Arc& a : t.in) enqueue(a.place);
    for (const Arc& a : t.out) enqueue(a.place);
  }

  // h becomes h;f: f's outputs join h's, f and p go.
  void post(PlaceId p, std::uint32_t h, std::uint32_t f) {
    move_arcs(p, h, f, ts_[h].out, ts_[f].out, producers_);
    link(h, f);
    ts_[h].last = ts_[f].last;
    kill(p, f);
    enqueue_around(ts_[h]);
  }

  // f becomes h;f: h's inputs join f's, h and p go.
  void pre(PlaceId p, std::uint32_t h, std::uint32_t f) {
    move_arcs(p, f, h, ts_[f].in, ts_[h].in, consumers_);
    link(h, f);
    ts_[f].first = ts_[h].first;
    kill(p, h);
    enqueue_around(ts_[f]);
  }

  // The arcs of `gone` (its outputs for post, its inputs for pre) move to `keep`, whose arc to p goes; `ends` (the
  // places' producers or consumers) follow.
  static void move_arcs(PlaceId p, std::uint32_t keep, std::uint32_t gone, std::vector<Arc>& keep_arcs,
                        const std::vector<Arc>& gone_arcs, std::vector<Ends>& ends) {
    remove_arc(keep_arcs, p);
    for (const Arc& a : gone_arcs) {
      ends[a.place].remove(gone);
      if (add_arc(keep_arcs, a)) ends[a.place].add(keep);
    }
  }

  // f's expansion follows h's.
  void link(std::uint32_t h, std::uint32_t f) { next_[ts_[h].last] = ts_[f].first; }

  void kill(PlaceId p, std::uint32_t t) {
    place_alive_[p] = false;
    producers_[p] = {};
    consumers_[p] = {};
    ts_[t].alive = false;
    ts_[t].in = {};
    ts_[t].out = {};
  }

  void build(Agglomeration& out) {
    NetBuilder b(net_.name());
    std::vector<PlaceId> new_id(net_.num_places(), kGone);
    for (std::size_t p = 0; p < net_.num_places(); ++p) {
      if (!place_alive_[p]) continue;
      new_id[p] = b.add_place(net_.places()[p]);
      out.original_place.push_back(static_cast<PlaceId>(p));
    }
    auto map_arcs = [&](const std::vector<Arc>& arcs) {
      std::vector<Arc> mapped;
      mapped.reserve(arcs.size());
      for (const Arc& a : arcs) {
        CW_CHECK(new_id[a.place] != kGone, "agglomeration: an arc to removed place {}", net_.places()[a.place].id);
        mapped.push_back({new_id[a.place], a.weight});
      }
      return mapped;
    };
    for (WorkTransition& w : ts_) {
      if (!w.alive) continue;
      // Named after its first original transition (each original transition is in exactly one expansion, so ids stay
      // unique); reports name the original transitions, from the expansion.
      Transition t = net_.transitions()[w.first];
      t.inputs = map_arcs(w.in);
      t.outputs = map_arcs(w.out);
      b.add_transition(std::move(t));
      std::vector<TransitionId> seq;
      for (TransitionId k = w.first; k != kGone; k = next_[k]) seq.push_back(k);
      out.expansion.push_back(std::move(seq));
    }
    for (Region r : net_.regions()) {
      for (PlaceId& p : r.inside) p = new_id[p];
      b.add_region(std::move(r));
    }
    b.set_robots(net_.robots());
    std::vector<Arc> final_places = net_.final_places();
    for (Arc& a : final_places) a.place = new_id[a.place];
    b.set_final(std::move(final_places));
    out.net = std::move(b).build();
  }

  const Net& net_;
  std::vector<Ends> producers_, consumers_;
  std::vector<TransitionId> next_;  // per original transition: the next in its expansion, kGone at the end
  std::vector<bool> fixed_, final_, place_alive_, queued_;
  std::vector<WorkTransition> ts_;
  std::deque<PlaceId> work_;
};

}  // namespace

std::vector<TransitionId> Agglomeration::expand(const std::vector<TransitionId>& path) const {
  std::vector<TransitionId> out;
  for (TransitionId t : path) {
    CW_CHECK(t < expansion.size(), "agglomeration: transition {} of {}", t, expansion.size());
    out.insert(out.end(), expansion[t].begin(), expansion[t].end());
  }
  return out;
}

Agglomeration agglomerate(const Net& net) {
  return Reducer(net).run();
}

std::optional<Marking> complete_dead(const Net& original, const Agglomeration& agg, Marking marking,
                                     std::vector<TransitionId>& path) {
  // The delayed transitions never compete for tokens (each of their input places feeds them alone), so the order of
  // firing does not matter; a worklist visits a delayed transition again when one of its input places gained.
  std::vector<std::vector<TransitionId>> delayed_consumers(original.num_places());
  std::vector<TransitionId> work;
  for (std::size_t t = 0; t < original.num_transitions(); ++t) {
    if (!agg.delayed[t]) continue;
    work.push_back(static_cast<TransitionId>(t));
    for (const Arc& a : original.transitions()[t].inputs) delayed_consumers[a.place].push_back(static_cast<TransitionId>(t));
  }
  // Each delayed transition fires at most as often as tokens reach it; a cap guards against a net where that is
  // not so (then the caller falls back to the original net).
  std::uint64_t budget = 16 * (std::uint64_t{original.num_transitions()} + 1) + 1'000'000;
  while (!work.empty()) {
    const TransitionId t = work.back();
    work.pop_back();
    if (!is_enabled(original, marking, t)) continue;
    if (budget-- == 0) return std::nullopt;
    fire_in_place(original, marking, t);
    path.push_back(t);
    work.push_back(t);
    for (const Arc& a : original.transitions()[t].outputs) {
      for (TransitionId u : delayed_consumers[a.place]) work.push_back(u);
    }
  }
  if (!is_dead(original, marking)) return std::nullopt;
  return marking;
}

}  // namespace cellwright::petri
