// Reachability-graph exploration (analysis.hpp).
//
// The marking store keeps, per reachable marking: the marking bit-packed (per-place field widths), a parent index and
// the transition that led to it (for shortest counterexamples), and one 32-bit slot in an open-addressing hash set.
// Breadth-first order is the store's insertion order, so the queue is just a cursor into the store.
//
// Field widths start at what the initial marking needs (at least one bit). When a successor needs more, that place
// is widened to exactly the bits it needs and every stored marking is repacked (indices, parents and BFS order are
// kept). This was preferred over bounds from place invariants: it needs no invariant computation, is exact for nets
// without covering invariants (PNML imports, unbounded nets), and widening happens at most 32 times per place and
// usually early in the search.
#include "cellwright/petri/analysis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include "cellwright/common/error.hpp"

namespace cellwright::petri {

namespace {

// Packed markings are stored as the first `bytes` bytes of little-endian 64-bit words.
static_assert(std::endian::native == std::endian::little, "the marking store assumes a little-endian machine");

constexpr std::uint32_t kNone = UINT32_MAX;

// The net in flat arrays: the explorer's inner loop reads nothing else.
struct FlatNet {
  std::size_t places = 0;
  std::size_t transitions = 0;
  std::vector<std::uint32_t> in_begin;  // transitions + 1 offsets into in_place/in_weight
  std::vector<PlaceId> in_place;
  std::vector<Tokens> in_weight;
  std::vector<std::uint32_t> eff_begin;  // net effect of firing: places whose count changes, and by how much
  std::vector<PlaceId> eff_place;
  std::vector<std::int64_t> eff_delta;
  std::vector<std::uint32_t> reg_begin;  // change of each region's tokens inside
  std::vector<std::uint32_t> reg_index;
  std::vector<std::int64_t> reg_delta;
  std::vector<std::int64_t> total_delta;  // change of the token total
};

FlatNet flatten(const Net& net) {
  FlatNet f;
  f.places = net.num_places();
  f.transitions = net.num_transitions();
  std::vector<std::int64_t> delta(f.places, 0);
  for (const Transition& t : net.transitions()) {
    f.in_begin.push_back(static_cast<std::uint32_t>(f.in_place.size()));
    f.eff_begin.push_back(static_cast<std::uint32_t>(f.eff_place.size()));
    f.reg_begin.push_back(static_cast<std::uint32_t>(f.reg_index.size()));
    for (const Arc& a : t.inputs) {
      f.in_place.push_back(a.place);
      f.in_weight.push_back(a.weight);
      delta[a.place] -= a.weight;
    }
    for (const Arc& a : t.outputs) delta[a.place] += a.weight;
    std::int64_t total = 0;
    for (const Arc& a : t.inputs) total -= a.weight;
    for (const Arc& a : t.outputs) total += a.weight;
    f.total_delta.push_back(total);
    // Touched places in first-seen order (inputs, then outputs), each once.
    auto note = [&](PlaceId p) {
      if (delta[p] != 0) {
        f.eff_place.push_back(p);
        f.eff_delta.push_back(delta[p]);
        delta[p] = 0;
      }
    };
    for (const Arc& a : t.inputs) note(a.place);
    for (const Arc& a : t.outputs) note(a.place);
    // Recompute the per-place change for the regions (delta was consumed above).
    for (std::size_t r = 0; r < net.regions().size(); ++r) {
      std::int64_t d = 0;
      for (PlaceId p : net.regions()[r].inside) {
        for (const Arc& a : t.inputs) {
          if (a.place == p) d -= a.weight;
        }
        for (const Arc& a : t.outputs) {
          if (a.place == p) d += a.weight;
        }
      }
      if (d != 0) {
        f.reg_index.push_back(static_cast<std::uint32_t>(r));
        f.reg_delta.push_back(d);
      }
    }
  }
  f.in_begin.push_back(static_cast<std::uint32_t>(f.in_place.size()));
  f.eff_begin.push_back(static_cast<std::uint32_t>(f.eff_place.size()));
  f.reg_begin.push_back(static_cast<std::uint32_t>(f.reg_index.size()));
  return f;
}

// Where each place's count lives in a packed marking.
struct Layout {
  std::vector<std::uint32_t> offset;  // bit offset
  std::vector<std::uint32_t> width;   // 1..32 bits
  std::vector<std::uint64_t> limit;   // largest count the field holds
  std::uint32_t words = 1;            // 64-bit words of an unpacked-to-words marking
  std::uint32_t bytes = 1;            // stored bytes per marking

  explicit Layout(std::vector<std::uint32_t> widths) : width(std::move(widths)) {
    std::uint32_t bits = 0;
    for (std::uint32_t w : width) {
      offset.push_back(bits);
      limit.push_back((std::uint64_t{1} << w) - 1);
      bits += w;
    }
    bits = std::max<std::uint32_t>(bits, 1);
    words = (bits + 63) / 64;
    bytes = (bits + 7) / 8;
  }
};

inline std::uint64_t get_field(const std::uint64_t* w, std::uint32_t off, std::uint32_t width) {
  const std::uint32_t i = off >> 6;
  const std::uint32_t s = off & 63;
  std::uint64_t v = w[i] >> s;
  if (s + width > 64) v |= w[i + 1] << (64 - s);
  return v & ((std::uint64_t{1} << width) - 1);
}

inline void set_field(std::uint64_t* w, std::uint32_t off, std::uint32_t width, std::uint64_t v) {
  const std::uint32_t i = off >> 6;
  const std::uint32_t s = off & 63;
  const std::uint64_t mask = (std::uint64_t{1} << width) - 1;
  w[i] = (w[i] & ~(mask << s)) | (v << s);
  if (s + width > 64) {
    const std::uint32_t hi = s + width - 64;
    w[i + 1] = (w[i + 1] & ~((std::uint64_t{1} << hi) - 1)) | (v >> (64 - s));
  }
}

inline std::uint64_t hash_words(const std::uint64_t* w, std::uint32_t n) {
  std::uint64_t h = 0x243F6A8885A308D3ull ^ n;
  for (std::uint32_t i = 0; i < n; ++i) {
    h ^= w[i] * 0x9E3779B97F4A7C15ull;
    h = std::rotl(h, 29) * 0xBF58476D1CE4E5B9ull;
  }
  // murmur3 finaliser: every input bit reaches the low bits (slot) and the high bits (tag).
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDull;
  h ^= h >> 33;
  h *= 0xC4CEB9FE1A85EC53ull;
  h ^= h >> 33;
  return h;
}

// Fixed-size chunks: growth never copies, and at most one chunk is partly unused (no doubling slack).
constexpr std::uint32_t kChunkShift = 14;
constexpr std::uint32_t kChunkMarkings = 1u << kChunkShift;

// The store: packed markings, parent links and the hash set over them.
class MarkingStore {
 public:
  MarkingStore(std::uint32_t stride, std::uint32_t words, std::uint64_t max_states) : stride_(stride), words_(words) {
    const int idx_bits = std::max(16, static_cast<int>(std::bit_width(max_states)));
    idx_bits_ = static_cast<std::uint32_t>(std::min(idx_bits, 32));
    idx_mask_ = idx_bits_ == 32 ? UINT32_MAX : (1u << idx_bits_) - 1;
    slots_.assign(1024, 0);
  }

  std::uint32_t size() const { return size_; }
  std::uint32_t stride() const { return stride_; }
  std::uint32_t words() const { return words_; }

  const std::uint8_t* packed(std::uint32_t i) const {
    return chunks_[i >> kChunkShift].get() + static_cast<std::size_t>(i & (kChunkMarkings - 1)) * stride_;
  }
  // Copies marking i into `w` (words() words, zero-padded).
  void load(std::uint32_t i, std::uint64_t* w) const {
    w[words_ - 1] = 0;
    std::memcpy(w, packed(i), stride_);
  }
  std::uint32_t parent(std::uint32_t i) const { return link(i).parent; }
  std::uint32_t via(std::uint32_t i) const { return link(i).via; }
  // The largest token total on the BFS path from the initial marking to marking i (saturating at UINT32_MAX).
  std::uint32_t path_max(std::uint32_t i) const { return link(i).path_max; }

  // Looks the packed marking `w` up; returns its index, or kNone if it is not stored.
  std::uint32_t find(const std::uint64_t* w, std::uint64_t h) const {
    const std::size_t mask = slots_.size() - 1;
    const std::uint32_t tag = tag_of(h);
    for (std::size_t pos = h & mask;; pos = (pos + 1) & mask) {
      const std::uint32_t s = slots_[pos];
      if (s == 0) return kNone;
      if ((s & ~idx_mask_) == tag) {
        const std::uint32_t i = (s & idx_mask_) - 1;
        if (std::memcmp(packed(i), w, stride_) == 0) return i;
      }
    }
  }

  // Appends a marking known not to be stored yet; returns its index.
  std::uint32_t insert(const std::uint64_t* w, std::uint64_t h, std::uint32_t parent, std::uint32_t via,
                       std::uint32_t path_max) {
    if ((static_cast<std::uint64_t>(size_) + 1) * 4 > slots_.size() * 3) grow_table();
    const std::uint32_t i = append(w, Link{parent, via, path_max});
    place_slot(i, h);
    return i;
  }

  // Re-encodes every stored marking from layout `from` to `to` (places widened); keeps indices and links.
  void repack(const Layout& from, const Layout& to) {
    const std::vector<std::unique_ptr<std::uint8_t[]>> old = std::move(chunks_);
    const std::uint32_t old_stride = stride_;
    chunks_.clear();
    stride_ = to.bytes;
    words_ = to.words;
    std::vector<std::uint64_t> a(from.words + 1), b(to.words + 1);
    for (std::uint32_t i = 0; i < size_; ++i) {
      const std::size_t in_chunk = i & (kChunkMarkings - 1);
      std::fill(a.begin(), a.end(), 0);
      std::memcpy(a.data(), old[i >> kChunkShift].get() + in_chunk * old_stride, old_stride);
      std::fill(b.begin(), b.end(), 0);
      for (std::size_t p = 0; p < from.width.size(); ++p) {
        set_field(b.data(), to.offset[p], to.width[p], get_field(a.data(), from.offset[p], from.width[p]));
      }
      if (in_chunk == 0) {
        chunks_.push_back(std::make_unique_for_overwrite<std::uint8_t[]>(std::size_t{kChunkMarkings} * stride_));
      }
      std::memcpy(chunks_.back().get() + in_chunk * stride_, b.data(), stride_);
    }
    rehash();
  }

  std::uint64_t bytes() const {
    return chunks_.size() * std::uint64_t{kChunkMarkings} * stride_ +
           links_.size() * std::uint64_t{kChunkMarkings} * sizeof(Link) + slots_.size() * sizeof(std::uint32_t);
  }

 private:
  struct Link {
    std::uint32_t parent;
    std::uint32_t via;
    std::uint32_t path_max;
  };

  const Link& link(std::uint32_t i) const { return links_[i >> kChunkShift][i & (kChunkMarkings - 1)]; }

  std::uint32_t tag_of(std::uint64_t h) const {
    if (idx_bits_ == 32) return 0;
    return static_cast<std::uint32_t>(h >> (32 + idx_bits_)) << idx_bits_;
  }

  std::uint32_t append(const std::uint64_t* w, const Link& link) {
    const std::uint32_t i = size_;
    if ((i & (kChunkMarkings - 1)) == 0) {
      chunks_.push_back(std::make_unique_for_overwrite<std::uint8_t[]>(std::size_t{kChunkMarkings} * stride_));
      links_.push_back(std::make_unique_for_overwrite<Link[]>(kChunkMarkings));
    }
    std::memcpy(chunks_.back().get() + static_cast<std::size_t>(i & (kChunkMarkings - 1)) * stride_, w, stride_);
    links_.back()[i & (kChunkMarkings - 1)] = link;
    ++size_;
    return i;
  }

  void place_slot(std::uint32_t i, std::uint64_t h) {
    const std::size_t mask = slots_.size() - 1;
    std::size_t pos = h & mask;
    while (slots_[pos] != 0) pos = (pos + 1) & mask;
    slots_[pos] = tag_of(h) | (i + 1);
  }

  void grow_table() {
    slots_.assign(slots_.size() * 2, 0);
    rehash();
  }

  void rehash() {
    std::fill(slots_.begin(), slots_.end(), 0);
    std::vector<std::uint64_t> w(words_ + 1);
    for (std::uint32_t i = 0; i < size_; ++i) {
      load(i, w.data());
      place_slot(i, hash_words(w.data(), words_));
    }
  }

  std::uint32_t stride_;
  std::uint32_t words_;
  std::uint32_t idx_bits_ = 32;
  std::uint32_t idx_mask_ = UINT32_MAX;
  std::uint32_t size_ = 0;
  std::vector<std::unique_ptr<std::uint8_t[]>> chunks_;
  std::vector<std::unique_ptr<Link[]>> links_;
  std::vector<std::uint32_t> slots_;
};

std::vector<TransitionId> path_to(const MarkingStore& store, std::uint32_t i) {
  std::vector<TransitionId> path;
  for (; store.parent(i) != kNone; i = store.parent(i)) path.push_back(store.via(i));
  std::reverse(path.begin(), path.end());
  return path;
}

Marking decode(const MarkingStore& store, const Layout& layout, std::uint32_t i) {
  std::vector<std::uint64_t> w(layout.words + 1, 0);
  store.load(i, w.data());
  Marking m(layout.width.size());
  for (std::size_t p = 0; p < m.size(); ++p) {
    m[p] = static_cast<Tokens>(get_field(w.data(), layout.offset[p], layout.width[p]));
  }
  return m;
}

std::uint32_t saturate(std::uint64_t v) {
  return static_cast<std::uint32_t>(std::min<std::uint64_t>(v, UINT32_MAX));
}

std::string place_list(const Net& net, const std::vector<PlaceId>& places) {
  std::string s;
  for (PlaceId p : places) {
    if (!s.empty()) s += ", ";
    s += "'" + net.places()[p].id + "'";
  }
  return s;
}

}  // namespace

AnalysisResult analyze(const Net& net, const AnalysisOptions& options) {
  if (options.max_states == 0) throw std::invalid_argument("analysis: max_states must be at least 1");
  // Indices are 32-bit and UINT32_MAX means "no parent".
  const std::uint64_t max_states = std::min<std::uint64_t>(options.max_states, UINT32_MAX - 1);
  const FlatNet f = flatten(net);
  const std::size_t np = f.places;
  const std::size_t nt = f.transitions;

  AnalysisResult r;
  const Marking initial = net.initial_marking();
  std::vector<std::uint32_t> widths(np);
  for (std::size_t p = 0; p < np; ++p) widths[p] = std::max(1u, static_cast<std::uint32_t>(std::bit_width(initial[p])));
  Layout layout(widths);
  MarkingStore store(layout.bytes, layout.words, max_states);

  // Scratch: the marking being expanded (unpacked and packed) and a successor. One spare word lets set_field write
  // the word after a field that ends exactly on a word boundary without a branch.
  Marking cur(np);
  std::vector<std::uint64_t> cur_w(layout.words + 1, 0), succ_w(layout.words + 1, 0);
  std::vector<std::uint64_t> succ_val(np);

  auto encode = [&](const Marking& m, std::vector<std::uint64_t>& w) {
    std::fill(w.begin(), w.end(), 0);
    for (std::size_t p = 0; p < np; ++p) set_field(w.data(), layout.offset[p], layout.width[p], m[p]);
  };

  std::vector<Tokens> max_seen = initial;
  std::vector<bool> ever_enabled(nt, false);
  const std::size_t nr = net.regions().size();
  r.regions.resize(nr);
  std::vector<std::uint64_t> cur_inside(nr, 0);
  std::vector<std::uint32_t> region_witness(nr, kNone);
  std::vector<std::uint32_t> deadlock_at;
  std::uint32_t unbounded_at = kNone;

  auto inside_sums = [&](const Marking& m, std::vector<std::uint64_t>& sums) {
    for (std::size_t k = 0; k < nr; ++k) {
      std::uint64_t s = 0;
      for (PlaceId p : net.regions()[k].inside) s += m[p];
      sums[k] = s;
    }
  };
  auto note_inside = [&](std::size_t k, std::uint64_t inside, std::uint32_t at) {
    RegionCheck& rc = r.regions[k];
    rc.max_inside = static_cast<Tokens>(std::max<std::uint64_t>(rc.max_inside, inside));
    if (inside > net.regions()[k].capacity && region_witness[k] == kNone) region_witness[k] = at;
  };

  {
    encode(initial, cur_w);
    std::uint64_t total = 0;
    for (Tokens v : initial) total += v;
    const std::uint32_t root =
        store.insert(cur_w.data(), hash_words(cur_w.data(), layout.words), kNone, kNone, saturate(total));
    inside_sums(initial, cur_inside);
    for (std::size_t k = 0; k < nr; ++k) note_inside(k, cur_inside[k], root);
  }

  std::vector<std::uint64_t> anc_w;
  bool stopped = false;
  for (std::uint32_t at = 0; at < store.size() && !stopped; ++at) {
    store.load(at, cur_w.data());
    for (std::size_t p = 0; p < np; ++p) {
      cur[p] = static_cast<Tokens>(get_field(cur_w.data(), layout.offset[p], layout.width[p]));
    }
    inside_sums(cur, cur_inside);
    std::uint64_t cur_total = 0;
    for (Tokens v : cur) cur_total += v;
    const std::uint32_t cur_path_max = store.path_max(at);
    bool any_enabled = false;
    for (std::size_t t = 0; t < nt && !stopped; ++t) {
      bool en = true;
      for (std::uint32_t k = f.in_begin[t]; k < f.in_begin[t + 1]; ++k) {
        if (cur[f.in_place[k]] < f.in_weight[k]) {
          en = false;
          break;
        }
      }
      if (!en) continue;
      any_enabled = true;
      ever_enabled[t] = true;
      ++r.edges;

      // The successor, packed: the parent's words with the changed fields rewritten. A count that does not fit its
      // field widens that place (repacking the store) and the successor is built again.
      bool built = false;
      while (!built && !stopped) {
        built = true;
        std::copy(cur_w.begin(), cur_w.end(), succ_w.begin());
        for (std::uint32_t k = f.eff_begin[t]; k < f.eff_begin[t + 1]; ++k) {
          const PlaceId p = f.eff_place[k];
          const std::uint64_t v = static_cast<std::uint64_t>(static_cast<std::int64_t>(cur[p]) + f.eff_delta[k]);
          if (v <= layout.limit[p]) {
            set_field(succ_w.data(), layout.offset[p], layout.width[p], v);
            continue;
          }
          if (v > std::numeric_limits<Tokens>::max()) {
            r.stop_reason = fmt::format("place '{}' would hold {} tokens, more than the {} a marking can count",
                                        net.places()[p].id, v, std::numeric_limits<Tokens>::max());
            stopped = true;
            break;
          }
          std::vector<std::uint32_t> w = layout.width;
          w[p] = static_cast<std::uint32_t>(std::bit_width(v));
          Layout wider(std::move(w));
          store.repack(layout, wider);
          layout = std::move(wider);
          cur_w.assign(layout.words + 1, 0);
          succ_w.assign(layout.words + 1, 0);
          encode(cur, cur_w);
          built = false;
          break;
        }
      }
      if (stopped) break;

      const std::uint64_t h = hash_words(succ_w.data(), layout.words);
      if (store.find(succ_w.data(), h) != kNone) continue;
      if (store.size() >= max_states) {
        r.stop_reason = fmt::format("state limit of {} markings reached; raise --max-states", max_states);
        stopped = true;
        break;
      }
      const std::uint64_t succ_total =
          static_cast<std::uint64_t>(static_cast<std::int64_t>(cur_total) + f.total_delta[t]);
      const std::uint32_t next = store.insert(succ_w.data(), h, at, static_cast<TransitionId>(t),
                                              std::max(cur_path_max, saturate(succ_total)));

      for (std::uint32_t k = f.eff_begin[t]; k < f.eff_begin[t + 1]; ++k) {
        const PlaceId p = f.eff_place[k];
        const std::uint64_t v = static_cast<std::uint64_t>(static_cast<std::int64_t>(cur[p]) + f.eff_delta[k]);
        max_seen[p] = std::max(max_seen[p], static_cast<Tokens>(v));
      }
      for (std::uint32_t k = f.reg_begin[t]; k < f.reg_begin[t + 1]; ++k) {
        const std::size_t reg = f.reg_index[k];
        note_inside(reg, static_cast<std::uint64_t>(static_cast<std::int64_t>(cur_inside[reg]) + f.reg_delta[k]), next);
      }

      // Karp-Miller: a new marking that covers an ancestor (and differs from it, being new) can repeat the firing
      // sequence between them forever, so the places that grew are unbounded. Checked only when the new marking
      // holds more tokens in all than any marking before it on its BFS path. That is still complete: an unbounded
      // net has an infinite BFS path, along which the token total is unbounded (Dickson's lemma gives an infinite
      // chain m1 < m2 < ... on it); the infinitely many path-maxima of the total contain, again by Dickson, a pair
      // m <= m' with m an ancestor of m', and m' is checked. (Checking only markings that raise some place above
      // every count seen anywhere before is not complete: a sibling branch can always set the new maxima without
      // covering anything, while the pumping branch stays just below them.)
      if (succ_total > cur_path_max) {
        for (std::size_t p = 0; p < np; ++p) succ_val[p] = cur[p];
        for (std::uint32_t k = f.eff_begin[t]; k < f.eff_begin[t + 1]; ++k) {
          succ_val[f.eff_place[k]] =
              static_cast<std::uint64_t>(static_cast<std::int64_t>(cur[f.eff_place[k]]) + f.eff_delta[k]);
        }
        anc_w.assign(layout.words + 1, 0);
        for (std::uint32_t a = at; a != kNone && !stopped; a = store.parent(a)) {
          store.load(a, anc_w.data());
          bool covers = true;
          for (std::size_t p = 0; p < np && covers; ++p) {
            covers = succ_val[p] >= get_field(anc_w.data(), layout.offset[p], layout.width[p]);
          }
          if (!covers) continue;
          for (std::size_t p = 0; p < np; ++p) {
            if (succ_val[p] > get_field(anc_w.data(), layout.offset[p], layout.width[p])) {
              r.unbounded_places.push_back(static_cast<PlaceId>(p));
            }
          }
          r.bounded = false;
          unbounded_at = next;
          r.stop_reason = fmt::format(
              "the net is unbounded: {} grow{} without limit (a firing sequence leads from a reachable marking to a "
              "strictly larger one and can be repeated)",
              place_list(net, r.unbounded_places), r.unbounded_places.size() == 1 ? "s" : "");
          stopped = true;
        }
      }
    }
    if (stopped) break;
    if (!any_enabled) {
      if (net.is_final(cur)) {
        ++r.final_states;
      } else {
        ++r.deadlocks;
        if (deadlock_at.size() < options.max_deadlocks_reported) deadlock_at.push_back(at);
      }
    }
  }

  r.states = store.size();
  r.complete = !stopped;
  r.place_bounds = max_seen;
  if (r.complete) {
    for (std::size_t t = 0; t < nt; ++t) {
      if (!ever_enabled[t]) r.dead_transitions.push_back(static_cast<TransitionId>(t));
    }
  }
  for (std::uint32_t i : deadlock_at) r.deadlock_examples.push_back({decode(store, layout, i), path_to(store, i)});
  if (unbounded_at != kNone)
    r.unbounded_witness = Deadlock{decode(store, layout, unbounded_at), path_to(store, unbounded_at)};
  for (std::size_t k = 0; k < nr; ++k) {
    RegionCheck& rc = r.regions[k];
    rc.name = net.regions()[k].name;
    if (region_witness[k] != kNone) {
      rc.exclusive = false;
      r.mutex_ok = false;
      rc.witness = Deadlock{decode(store, layout, region_witness[k]), path_to(store, region_witness[k])};
    }
  }
  r.stored_bytes = store.bytes();
  return r;
}

}  // namespace cellwright::petri
