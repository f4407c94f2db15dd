// Reachability-graph exploration (analysis.hpp).
//
// The marking store keeps, per reachable marking: the marking bit-packed (per-place field widths), a parent index and
// the transition that led to it (for shortest counterexamples), and one 32-bit slot in an open-addressing hash set.
// Breadth-first order is the store's insertion order, so the queue is just a cursor into the store.
//
// Field widths start at what the initial marking needs (at least one bit). When a successor needs more, that place
// is widened to the bits it needs plus one and every stored marking is repacked (indices, parents and BFS order are
// kept). This was preferred over bounds from place invariants: it needs no invariant computation, is exact for nets
// without covering invariants (PNML imports, unbounded nets), and widening happens at most 32 times per place and
// usually early in the search.
#include "cellwright/petri/analysis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstring>
#include <iterator>
#include <limits>
#include <memory>
#include <stdexcept>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/agglomerate.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/structural.hpp"
#include "cellwright/petri/stubborn.hpp"

namespace cellwright::petri {

namespace {

// Packed markings are stored as the first `bytes` bytes of little-endian 64-bit words, and fields are read through
// unaligned 64-bit loads.
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
  // Each transition is listed under one of its input places (the one with the fewest consumers), so that only the
  // transitions listed under marked places need an enabling test; transitions without inputs are always tested.
  std::vector<std::uint32_t> trigger_begin;  // places + 1 offsets into trigger
  std::vector<TransitionId> trigger;
  std::vector<TransitionId> sources;
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

  std::vector<std::uint32_t> consumers(f.places, 0);
  for (PlaceId p : f.in_place) ++consumers[p];
  std::vector<std::vector<TransitionId>> under(f.places);
  for (std::size_t t = 0; t < f.transitions; ++t) {
    if (f.in_begin[t] == f.in_begin[t + 1]) {
      f.sources.push_back(static_cast<TransitionId>(t));
      continue;
    }
    PlaceId best = f.in_place[f.in_begin[t]];
    for (std::uint32_t k = f.in_begin[t]; k < f.in_begin[t + 1]; ++k) {
      if (consumers[f.in_place[k]] < consumers[best]) best = f.in_place[k];
    }
    under[best].push_back(static_cast<TransitionId>(t));
  }
  for (const auto& list : under) {
    f.trigger_begin.push_back(static_cast<std::uint32_t>(f.trigger.size()));
    f.trigger.insert(f.trigger.end(), list.begin(), list.end());
  }
  f.trigger_begin.push_back(static_cast<std::uint32_t>(f.trigger.size()));
  return f;
}

// A field's position, precomputed: first byte, shift within it, and the mask (= the largest count it holds).
// Access reads or writes the 8 bytes starting at the field's first byte (little-endian): a field of at most 32 bits
// shifted by at most 7 fits, so no field straddles two reads. Buffers of packed markings carry one spare word for it.
struct Field {
  std::uint32_t byte = 0;
  std::uint32_t shift = 0;
  std::uint64_t mask = 1;
};

inline std::uint64_t get(const std::uint64_t* w, const Field& f) {
  std::uint64_t v;
  std::memcpy(&v, reinterpret_cast<const unsigned char*>(w) + f.byte, 8);
  return (v >> f.shift) & f.mask;
}

inline void set(std::uint64_t* w, const Field& f, std::uint64_t v) {
  unsigned char* at = reinterpret_cast<unsigned char*>(w) + f.byte;
  std::uint64_t word;
  std::memcpy(&word, at, 8);
  word = (word & ~(f.mask << f.shift)) | (v << f.shift);
  std::memcpy(at, &word, 8);
}

// Where each place's count lives in a packed marking.
struct Layout {
  std::vector<std::uint32_t> offset;  // bit offset
  std::vector<std::uint32_t> width;   // 1..32 bits
  std::vector<Field> field;           // offset and width, precomputed for access
  std::uint32_t words = 1;            // 64-bit words of an unpacked-to-words marking
  std::uint32_t bytes = 1;            // stored bytes per marking
  std::vector<PlaceId> bit_place;     // the place each bit belongs to (kNone for padding)
  bool unit = true;                   // every field is one bit wide: counts are popcounts

  explicit Layout(std::vector<std::uint32_t> widths) : width(std::move(widths)) {
    std::uint32_t bits = 0;
    for (std::uint32_t w : width) {
      offset.push_back(bits);
      field.push_back(Field{bits >> 3, bits & 7, (std::uint64_t{1} << w) - 1});
      bits += w;
      unit = unit && w == 1;
    }
    bits = std::max<std::uint32_t>(bits, 1);
    words = (bits + 63) / 64;
    bytes = (bits + 7) / 8;
    bit_place.assign(std::size_t{words} * 64, UINT32_MAX);
    for (std::size_t p = 0; p < width.size(); ++p) {
      std::fill_n(bit_place.begin() + offset[p], width[p], static_cast<PlaceId>(p));
    }
  }
};

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
  MarkingStore(std::uint32_t stride, std::uint32_t words, std::uint64_t max_states) {
    set_shape(stride, words);
    const int idx_bits = std::max(16, static_cast<int>(std::bit_width(max_states)));
    idx_bits_ = static_cast<std::uint32_t>(std::min(idx_bits, 32));
    idx_mask_ = idx_bits_ == 32 ? UINT32_MAX : (1u << idx_bits_) - 1;
    slots_.assign(1024, 0);
  }

  std::uint32_t size() const { return size_; }

  // Copies marking i into `w` (its words, zero-padded). Records are read and written a word at a time: the last
  // word of a record may reach into the next record or the chunk's padding, and is masked.
  void load(std::uint32_t i, std::uint64_t* w) const {
    const std::uint8_t* p = packed(i);
    for (std::uint32_t k = 0; k < words_; ++k) std::memcpy(&w[k], p + 8 * k, 8);
    w[words_ - 1] &= tail_mask_;
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
        if (equals(i, w)) return i;
      }
    }
  }

  // Hints for a lookup of `w` soon: fetch its slot's cache line; then (once that has arrived) the record of the first
  // slot whose tag matches. Lookups of a batch of successors so overlap their cache misses.
  void prefetch_slot(std::uint64_t h) const { __builtin_prefetch(&slots_[h & (slots_.size() - 1)]); }
  void prefetch_record(std::uint64_t h) const {
    const std::size_t mask = slots_.size() - 1;
    const std::uint32_t tag = tag_of(h);
    for (std::size_t pos = h & mask;; pos = (pos + 1) & mask) {
      const std::uint32_t s = slots_[pos];
      if (s == 0) return;
      if ((s & ~idx_mask_) == tag) {
        __builtin_prefetch(packed((s & idx_mask_) - 1));
        return;
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
    const std::uint32_t old_words = words_;
    const std::uint64_t old_tail = tail_mask_;
    chunks_.clear();
    set_shape(to.bytes, to.words);
    std::vector<std::uint64_t> a(from.words + 1), b(to.words + 1);
    for (std::uint32_t i = 0; i < size_; ++i) {
      const std::uint8_t* rec =
          old[i >> kChunkShift].get() + static_cast<std::size_t>(i & (kChunkMarkings - 1)) * old_stride;
      for (std::uint32_t k = 0; k < old_words; ++k) std::memcpy(&a[k], rec + 8 * k, 8);
      a[old_words - 1] &= old_tail;
      std::fill(b.begin(), b.end(), 0);
      for (std::size_t p = 0; p < from.width.size(); ++p) {
        set(b.data(), to.field[p], get(a.data(), from.field[p]));
      }
      if ((i & (kChunkMarkings - 1)) == 0) chunks_.push_back(new_chunk());
      write(i, b.data());
    }
    rehash();
  }

  std::uint64_t bytes() const {
    return chunks_.size() * chunk_bytes() + links_.size() * std::uint64_t{kChunkMarkings} * sizeof(Link) +
           slots_.size() * sizeof(std::uint32_t);
  }

 private:
  struct Link {
    std::uint32_t parent;
    std::uint32_t via;
    std::uint32_t path_max;
  };

  const Link& link(std::uint32_t i) const { return links_[i >> kChunkShift][i & (kChunkMarkings - 1)]; }

  void set_shape(std::uint32_t stride, std::uint32_t words) {
    stride_ = stride;
    words_ = words;
    const std::uint32_t tail = stride - 8 * (words - 1);  // bytes of the record in its last word, 1..8
    tail_mask_ = tail == 8 ? ~std::uint64_t{0} : (std::uint64_t{1} << (8 * tail)) - 1;
  }
  // One chunk of records plus 8 bytes, so that word-wise access to the last record stays inside.
  std::size_t chunk_bytes() const { return std::size_t{kChunkMarkings} * stride_ + 8; }
  std::unique_ptr<std::uint8_t[]> new_chunk() const {
    auto c = std::make_unique_for_overwrite<std::uint8_t[]>(chunk_bytes());
    std::memset(c.get() + chunk_bytes() - 8, 0, 8);
    return c;
  }
  std::uint8_t* packed(std::uint32_t i) const {
    return chunks_[i >> kChunkShift].get() + static_cast<std::size_t>(i & (kChunkMarkings - 1)) * stride_;
  }
  bool equals(std::uint32_t i, const std::uint64_t* w) const {
    const std::uint8_t* p = packed(i);
    std::uint64_t diff = 0;
    for (std::uint32_t k = 0; k + 1 < words_; ++k) {
      std::uint64_t v;
      std::memcpy(&v, p + 8 * k, 8);
      diff |= v ^ w[k];
    }
    std::uint64_t last;
    std::memcpy(&last, p + 8 * (words_ - 1), 8);
    return (diff | ((last ^ w[words_ - 1]) & tail_mask_)) == 0;
  }
  // Records are appended in index order, so bytes written past record i belong to the not yet written record i + 1
  // (or to the chunk's padding).
  void write(std::uint32_t i, const std::uint64_t* w) {
    std::uint8_t* p = packed(i);
    for (std::uint32_t k = 0; k < words_; ++k) std::memcpy(p + 8 * k, &w[k], 8);
  }

  std::uint32_t tag_of(std::uint64_t h) const {
    if (idx_bits_ == 32) return 0;
    return static_cast<std::uint32_t>(h >> (32 + idx_bits_)) << idx_bits_;
  }

  std::uint32_t append(const std::uint64_t* w, const Link& link) {
    const std::uint32_t i = size_;
    if ((i & (kChunkMarkings - 1)) == 0) {
      chunks_.push_back(new_chunk());
      links_.push_back(std::make_unique_for_overwrite<Link[]>(kChunkMarkings));
    }
    write(i, w);
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

  std::uint32_t stride_ = 1;
  std::uint32_t words_ = 1;
  std::uint64_t tail_mask_ = 0xFF;
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
    m[p] = static_cast<Tokens>(get(w.data(), layout.field[p]));
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

// One exploration: the store, the scratch buffers and what has been found so far.
class Explorer {
 public:
  // With `stubborn`, only the enabled transitions of a stubborn set are fired from each marking; with `proviso` too,
  // a marking whose reduced successors include an already expanded one is expanded fully (stubborn.hpp). `finite`:
  // every run is known to be finite (finite_runs()), so no marking can cover an ancestor and the Karp-Miller test is
  // skipped (it scans the places of every ancestor of each marking that raises the token total).
  Explorer(const Net& net, const AnalysisOptions& options, StubbornSets* stubborn, bool proviso, bool finite = false)
      : net_(net),
        options_(options),
        stubborn_(stubborn),
        proviso_(proviso),
        finite_(finite),
        f_(flatten(net)),
        max_states_(std::min<std::uint64_t>(options.max_states, UINT32_MAX - 1)),
        max_examples_(options.max_deadlocks_reported),
        initial_(net.initial_marking()),
        layout_(initial_widths(initial_)),
        store_(layout_.bytes, layout_.words, max_states_),
        max_seen_(initial_),
        ever_enabled_(f_.transitions, false),
        region_witness_(net.regions().size(), kNone),
        cur_inside_(net.regions().size()),
        cur_inside_known_(net.regions().size()) {
    r_.regions.resize(net.regions().size());
    for (TransitionId t : f_.sources) sources_.push_back(t);
    cand_bits_.assign((f_.transitions + 63) / 64, 0);
    reshape();
  }

  AnalysisResult run() {
    encode(initial_, cur_w_);
    std::uint64_t total = 0;
    for (Tokens v : initial_) total += v;
    const std::uint32_t root =
        store_.insert(cur_w_.data(), hash_words(cur_w_.data(), layout_.words), kNone, kNone, saturate(total));
    for (std::size_t k = 0; k < net_.regions().size(); ++k) note_inside(k, inside_of(cur_w_.data(), k), root);

    start_ = std::chrono::steady_clock::now();
    next_progress_ = start_ + options_.progress_interval;
    for (std::uint32_t at = 0; at < store_.size() && !stopped_; ++at) {
      if ((at & 255) == 0) {
        if (options_.progress) report_progress(at);
        if (options_.stop != nullptr && options_.stop->load(std::memory_order_relaxed)) {
          stop(fmt::format("interrupted after {} markings", store_.size()));
          break;
        }
      }
      expand(at);
    }
    return finish();
  }

 private:
  static constexpr std::size_t kBatch = 32;  // successors whose lookups are overlapped

  void report_progress(std::uint32_t at) {
    const auto now = std::chrono::steady_clock::now();
    if (now < next_progress_) return;
    next_progress_ = now + options_.progress_interval;
    AnalysisProgress p;
    p.markings = store_.size();
    p.edges = r_.edges;
    p.queue = store_.size() - at;
    p.seconds = std::chrono::duration<double>(now - start_).count();
    p.reduced = stubborn_ != nullptr;
    options_.progress(p);
  }

  static std::vector<std::uint32_t> initial_widths(const Marking& m) {
    std::vector<std::uint32_t> w(m.size());
    for (std::size_t p = 0; p < m.size(); ++p) w[p] = std::max(1u, static_cast<std::uint32_t>(std::bit_width(m[p])));
    return w;
  }

  // Buffers, arc fields and region masks follow the layout. Packed buffers carry one spare word for field access.
  void reshape() {
    in_field_.clear();
    for (PlaceId p : f_.in_place) in_field_.push_back(layout_.field[p]);
    eff_field_.clear();
    for (PlaceId p : f_.eff_place) eff_field_.push_back(layout_.field[p]);
    const std::size_t stride = layout_.words + 1;
    cur_w_.assign(stride, 0);
    anc_w_.assign(stride, 0);
    batch_w_.assign(stride * kBatch, 0);
    const std::size_t nr = net_.regions().size();
    region_mask_.assign(nr, std::vector<std::uint64_t>(layout_.words, 0));
    region_unit_.assign(nr, true);
    for (std::size_t k = 0; k < nr; ++k) {
      for (PlaceId p : net_.regions()[k].inside) {
        region_unit_[k] = region_unit_[k] && layout_.width[p] == 1;
        region_mask_[k][layout_.offset[p] >> 6] |= std::uint64_t{1} << (layout_.offset[p] & 63);
      }
    }
  }

  std::uint64_t value(const std::uint64_t* w, PlaceId p) const { return get(w, layout_.field[p]); }

  void encode(const Marking& m, std::vector<std::uint64_t>& w) const {
    std::fill(w.begin(), w.end(), 0);
    for (std::size_t p = 0; p < m.size(); ++p) set(w.data(), layout_.field[p], m[p]);
  }

  Marking decode_words(const std::uint64_t* w) const {
    Marking m(f_.places);
    for (std::size_t p = 0; p < m.size(); ++p) m[p] = static_cast<Tokens>(value(w, static_cast<PlaceId>(p)));
    return m;
  }

  std::uint64_t total_of(const std::uint64_t* w) const {
    std::uint64_t sum = 0;
    if (layout_.unit) {
      for (std::uint32_t i = 0; i < layout_.words; ++i) sum += static_cast<std::uint64_t>(std::popcount(w[i]));
    } else {
      for (std::size_t p = 0; p < f_.places; ++p) sum += value(w, static_cast<PlaceId>(p));
    }
    return sum;
  }

  // Tokens inside region k: a popcount under a mask when its places are one bit wide.
  std::uint64_t inside_of(const std::uint64_t* w, std::size_t k) const {
    std::uint64_t sum = 0;
    if (region_unit_[k]) {
      for (std::uint32_t i = 0; i < layout_.words; ++i) {
        sum += static_cast<std::uint64_t>(std::popcount(w[i] & region_mask_[k][i]));
      }
    } else {
      for (PlaceId p : net_.regions()[k].inside) sum += value(w, p);
    }
    return sum;
  }

  void note_inside(std::size_t k, std::uint64_t inside, std::uint32_t at) {
    RegionCheck& rc = r_.regions[k];
    rc.max_inside = static_cast<Tokens>(std::max<std::uint64_t>(rc.max_inside, inside));
    if (inside > net_.regions()[k].capacity && region_witness_[k] == kNone) region_witness_[k] = at;
  }

  // The enabled transitions of cur_w_, ascending: only those listed under a marked place (found from the set bits)
  // and the source transitions are tested. Ascending order keeps successors, and so the reported paths, independent
  // of the layout.
  void find_enabled() {
    enabled_.clear();
    for (TransitionId t : sources_) cand_bits_[t >> 6] |= std::uint64_t{1} << (t & 63);
    PlaceId last = kNone;
    for (std::uint32_t i = 0; i < layout_.words; ++i) {
      for (std::uint64_t bits = cur_w_[i]; bits != 0; bits &= bits - 1) {
        const PlaceId p = layout_.bit_place[i * 64 + static_cast<std::uint32_t>(std::countr_zero(bits))];
        if (p == last) continue;
        last = p;
        for (std::uint32_t k = f_.trigger_begin[p]; k < f_.trigger_begin[p + 1]; ++k) {
          cand_bits_[f_.trigger[k] >> 6] |= std::uint64_t{1} << (f_.trigger[k] & 63);
        }
      }
    }
    for (std::size_t cw = 0; cw < cand_bits_.size(); ++cw) {
      for (; cand_bits_[cw] != 0; cand_bits_[cw] &= cand_bits_[cw] - 1) {
        const auto t = static_cast<TransitionId>(cw * 64 + static_cast<std::size_t>(std::countr_zero(cand_bits_[cw])));
        bool en = true;
        for (std::uint32_t k = f_.in_begin[t]; k < f_.in_begin[t + 1] && en; ++k) {
          en = get(cur_w_.data(), in_field_[k]) >= f_.in_weight[k];
        }
        if (en) enabled_.push_back(t);
      }
    }
  }

  // Writes the successor of cur_w_ under t into `out`. Returns false when a count did not fit its field: then the
  // place has been widened and the store repacked (every packed buffer is stale), or, past the Tokens range,
  // exploration has stopped.
  bool build(TransitionId t, std::uint64_t* out) {
    for (std::uint32_t i = 0; i < layout_.words; ++i) out[i] = cur_w_[i];
    for (std::uint32_t k = f_.eff_begin[t]; k < f_.eff_begin[t + 1]; ++k) {
      const Field& fld = eff_field_[k];
      const auto v = static_cast<std::uint64_t>(static_cast<std::int64_t>(get(cur_w_.data(), fld)) + f_.eff_delta[k]);
      if (v <= fld.mask) {
        set(out, fld, v);
        continue;
      }
      const PlaceId p = f_.eff_place[k];
      if (v > std::numeric_limits<Tokens>::max()) {
        stop(fmt::format("place '{}' would hold {} tokens, more than the {} a marking can count", net_.places()[p].id,
                         v, std::numeric_limits<Tokens>::max()));
        return false;
      }
      const Marking cur = decode_words(cur_w_.data());
      std::vector<std::uint32_t> widths = layout_.width;
      // One bit of headroom: a place that outgrows its field usually keeps growing, and each repack costs a pass over
      // the whole store.
      widths[p] = std::min(32u, static_cast<std::uint32_t>(std::bit_width(v)) + 1);
      Layout wider(std::move(widths));
      store_.repack(layout_, wider);
      layout_ = std::move(wider);
      reshape();
      encode(cur, cur_w_);
      return false;
    }
    return true;
  }

  void stop(std::string reason) {
    r_.stop_reason = std::move(reason);
    stopped_ = true;
  }

  void expand(std::uint32_t at) {
    store_.load(at, cur_w_.data());
    find_enabled();
    if (enabled_.empty()) {
      const Marking cur = decode_words(cur_w_.data());
      if (net_.is_final(cur)) {
        ++r_.final_states;
      } else {
        ++r_.deadlocks;
        if (deadlock_at_.size() < max_examples_) deadlock_at_.push_back(at);
      }
      return;
    }
    for (TransitionId t : enabled_) ever_enabled_[t] = true;
    cur_total_known_ = false;
    std::fill(cur_inside_known_.begin(), cur_inside_known_.end(), false);
    if (stubborn_ == nullptr) {
      fire_all(at, enabled_);
      return;
    }
    stubborn_->choose(
        enabled_, [this](PlaceId p) { return static_cast<Tokens>(value(cur_w_.data(), p)); }, chosen_);
    const bool back = fire_all(at, chosen_);
    if (!(proviso_ && back && chosen_.size() < enabled_.size()) || stopped_) return;
    // Ignoring proviso: a reduced successor was expanded already (a cycle may close here), so fire the rest too.
    rest_.clear();
    std::set_difference(enabled_.begin(), enabled_.end(), chosen_.begin(), chosen_.end(), std::back_inserter(rest_));
    fire_all(at, rest_);
  }

  // Fires each of `ts` (enabled) from marking `at` (loaded in cur_w_) and stores the successors. Returns true when
  // one of them is a marking expanded before (index <= at).
  bool fire_all(std::uint32_t at, const std::vector<TransitionId>& ts) {
    r_.edges += ts.size();
    bool back = false;
    for (std::size_t b = 0; b < ts.size() && !stopped_; b += kBatch) {
      const std::size_t n = std::min(kBatch, ts.size() - b);
      // Build the batch's successors and start fetching their hash slots; a widening restarts the batch.
      std::size_t built = 0;
      while (built < n) {
        std::uint64_t* w = &batch_w_[built * (layout_.words + 1)];
        if (!build(ts[b + built], w)) {
          if (stopped_) return back;
          built = 0;
          continue;
        }
        hash_[built] = hash_words(w, layout_.words);
        store_.prefetch_slot(hash_[built]);
        ++built;
      }
      for (std::size_t j = 0; j < n; ++j) store_.prefetch_record(hash_[j]);
      for (std::size_t j = 0; j < n && !stopped_; ++j) {
        back = add(at, ts[b + j], &batch_w_[j * (layout_.words + 1)], hash_[j]) || back;
      }
    }
    return back;
  }

  // Stores the successor `w` of marking `at` under t unless it is known, and checks it. Returns true when it was
  // known and already expanded (index <= at).
  bool add(std::uint32_t at, TransitionId t, const std::uint64_t* w, std::uint64_t h) {
    const std::uint32_t known = store_.find(w, h);
    if (known != kNone) return known <= at;
    if (store_.size() >= max_states_) {
      state_limit_ = true;
      stop(fmt::format("state limit of {} markings reached; raise --max-states", max_states_));
      return false;
    }
    const std::uint32_t parent_max = store_.path_max(at);
    // Only a transition that adds tokens can exceed the path maximum, which is at least the parent's total.
    const bool adds = f_.total_delta[t] > 0;
    std::uint64_t total = 0;
    if (adds) {
      if (!cur_total_known_) {
        cur_total_ = total_of(cur_w_.data());
        cur_total_known_ = true;
      }
      total = cur_total_ + static_cast<std::uint64_t>(f_.total_delta[t]);
    }
    const std::uint32_t next = store_.insert(w, h, at, t, std::max(parent_max, saturate(total)));

    for (std::uint32_t k = f_.eff_begin[t]; k < f_.eff_begin[t + 1]; ++k) {
      if (f_.eff_delta[k] > 0) {
        Tokens& seen = max_seen_[f_.eff_place[k]];
        seen = std::max(seen, static_cast<Tokens>(get(w, eff_field_[k])));
      }
    }
    // Only a transition that adds tokens to a region can raise its maximum or break its capacity.
    for (std::uint32_t k = f_.reg_begin[t]; k < f_.reg_begin[t + 1]; ++k) {
      if (f_.reg_delta[k] <= 0) continue;
      const std::size_t reg = f_.reg_index[k];
      if (!cur_inside_known_[reg]) {
        cur_inside_[reg] = inside_of(cur_w_.data(), reg);
        cur_inside_known_[reg] = true;
      }
      note_inside(reg, cur_inside_[reg] + static_cast<std::uint64_t>(f_.reg_delta[k]), next);
    }
    if (adds && total > parent_max && !finite_) check_covering(at, next, w);
    return false;
  }

  // Karp-Miller: a new marking that covers an ancestor (and differs from it, being new) can repeat the firing
  // sequence between them forever, so the places that grew are unbounded. Checked only when the new marking holds
  // more tokens in all than any marking before it on its BFS path. That is still complete: an unbounded net has an
  // infinite BFS path, along which the token total is unbounded (Dickson's lemma gives an infinite chain
  // m1 < m2 < ... on it); the infinitely many path-maxima of the total contain, again by Dickson, a pair m <= m' with
  // m an ancestor of m', and m' is checked. (Checking only markings that raise some place above every count seen
  // anywhere before is not complete: a sibling branch can keep setting the new maxima without covering anything,
  // while the pumping branch stays just below them.)
  void check_covering(std::uint32_t parent, std::uint32_t next, const std::uint64_t* w) {
    for (std::uint32_t a = parent; a != kNone; a = store_.parent(a)) {
      store_.load(a, anc_w_.data());
      bool covers = true;
      if (layout_.unit) {  // one bit per place: no bit set in the ancestor that is clear in w
        for (std::uint32_t i = 0; i < layout_.words && covers; ++i) covers = (anc_w_[i] & ~w[i]) == 0;
      }
      for (std::size_t p = 0; p < f_.places && covers && !layout_.unit; ++p) {
        covers = value(w, static_cast<PlaceId>(p)) >= value(anc_w_.data(), static_cast<PlaceId>(p));
      }
      if (!covers) continue;
      for (std::size_t p = 0; p < f_.places; ++p) {
        if (value(w, static_cast<PlaceId>(p)) > value(anc_w_.data(), static_cast<PlaceId>(p))) {
          r_.unbounded_places.push_back(static_cast<PlaceId>(p));
        }
      }
      r_.bounded = false;
      unbounded_at_ = next;
      stop(fmt::format(
          "the net is unbounded: {} grow{} without limit (a firing sequence leads from a reachable marking to a "
          "strictly larger one and can be repeated)",
          place_list(net_, r_.unbounded_places), r_.unbounded_places.size() == 1 ? "s" : ""));
      return;
    }
  }

  AnalysisResult finish() {
    r_.states = store_.size();
    r_.complete = !stopped_;
    r_.explored_all = r_.complete;
    r_.state_limit_reached = state_limit_;
    r_.reduced = stubborn_ != nullptr;
    if (!r_.reduced) r_.place_bounds = max_seen_;
    if (r_.complete && !r_.reduced) {
      for (std::size_t t = 0; t < f_.transitions; ++t) {
        if (!ever_enabled_[t]) r_.dead_transitions.push_back(static_cast<TransitionId>(t));
      }
    }
    for (std::uint32_t i : deadlock_at_) {
      r_.deadlock_examples.push_back({decode(store_, layout_, i), path_to(store_, i)});
    }
    if (unbounded_at_ != kNone) {
      r_.unbounded_witness = Deadlock{decode(store_, layout_, unbounded_at_), path_to(store_, unbounded_at_)};
    }
    for (std::size_t k = 0; k < net_.regions().size(); ++k) {
      RegionCheck& rc = r_.regions[k];
      rc.name = net_.regions()[k].name;
      rc.witness_shortest = !r_.reduced;
      if (region_witness_[k] != kNone) {
        rc.exclusive = false;
        r_.mutex_ok = false;
        rc.witness = Deadlock{decode(store_, layout_, region_witness_[k]), path_to(store_, region_witness_[k])};
      }
    }
    r_.stored_bytes = store_.bytes();
    return std::move(r_);
  }

  const Net& net_;
  const AnalysisOptions& options_;
  StubbornSets* const stubborn_;
  const bool proviso_;
  const bool finite_;
  std::chrono::steady_clock::time_point start_, next_progress_;
  const FlatNet f_;
  const std::uint64_t max_states_;
  const std::size_t max_examples_;
  const Marking initial_;
  Layout layout_;
  MarkingStore store_;

  AnalysisResult r_;
  bool stopped_ = false;
  bool state_limit_ = false;
  std::vector<Tokens> max_seen_;
  std::vector<bool> ever_enabled_;
  std::vector<std::uint32_t> region_witness_;
  std::vector<std::uint32_t> deadlock_at_;
  std::uint32_t unbounded_at_ = kNone;

  // Scratch for the marking being expanded.
  std::vector<TransitionId> sources_;
  std::vector<std::uint64_t> cand_bits_;
  std::vector<TransitionId> enabled_;
  std::vector<TransitionId> chosen_, rest_;  // the reduced expansion: stubborn, then the rest (proviso)
  std::vector<std::uint64_t> cur_w_, anc_w_, batch_w_;
  std::vector<Field> in_field_;   // per input arc (parallel to FlatNet::in_place)
  std::vector<Field> eff_field_;  // per effect (parallel to FlatNet::eff_place)
  std::uint64_t hash_[kBatch] = {};
  std::vector<std::vector<std::uint64_t>> region_mask_;
  std::vector<bool> region_unit_;
  std::uint64_t cur_total_ = 0;
  bool cur_total_known_ = false;
  std::vector<std::uint64_t> cur_inside_;
  std::vector<bool> cur_inside_known_;
};

}  // namespace

const char* to_string(Reduction r) {
  switch (r) {
    case Reduction::kNone:
      return "none";
    case Reduction::kStubborn:
      return "stubborn";
  }
  return "?";
}

Reduction parse_reduction(std::string_view name) {
  if (name == "none") return Reduction::kNone;
  if (name == "stubborn") return Reduction::kStubborn;
  throw std::invalid_argument(fmt::format("unknown reduction '{}' (expected none or stubborn)", name));
}

namespace {

// Region proofs into the result: each proved region is exclusive whatever the exploration saw.
void apply_region_proofs(AnalysisResult& r, const std::vector<std::optional<RegionProof>>& proofs) {
  for (std::size_t k = 0; k < proofs.size() && k < r.regions.size(); ++k) {
    if (!proofs[k]) continue;
    RegionCheck& rc = r.regions[k];
    CW_CHECK(rc.exclusive, "region {} was proved exclusive by a place invariant but explored not exclusive", rc.name);
    rc.by_invariant = true;
    rc.invariant_bound = static_cast<Tokens>(proofs[k]->bound);
  }
}

}  // namespace

namespace {

// The stubborn-set analysis of `net` (analysis.hpp: the budget, the structural checks, the fallback to full
// exploration).
AnalysisResult analyze_stubborn(const Net& net, const AnalysisOptions& options) {

  // Regions shown exclusive by a place invariant need no observing: they leave condition V and the proviso.
  std::vector<std::optional<RegionProof>> proofs;
  std::vector<bool> watched;
  bool any_watched = false;
  for (std::size_t k = 0; k < net.regions().size(); ++k) {
    proofs.push_back(prove_region_exclusive(net, k));
    watched.push_back(!proofs.back());
    any_watched = any_watched || watched.back();
  }
  // Deadlocks need no proviso; watched regions do once runs can be infinite (the state space may have cycles).
  const bool finite = finite_runs(net);
  StubbornSets stubborn(net, watched);
  const bool proviso = !finite && any_watched;
  auto finish = [&](AnalysisResult r) {
    r.reduction = Reduction::kStubborn;
    apply_region_proofs(r, proofs);
    return r;
  };

  const bool budgeted = options.exploration_budget > 0 && options.exploration_budget < options.max_states;
  AnalysisOptions first = options;
  if (budgeted) first.max_states = options.exploration_budget;
  AnalysisResult r = Explorer(net, first, &stubborn, proviso, finite).run();
  if (budgeted && r.state_limit_reached) {
    // The budget ran out. What the structure decides is taken from it; anything else is explored on.
    const bool bounded = finite || structurally_bounded(net);
    std::string why_not;
    if (!bounded) why_not = "the net is not shown bounded by its structure";
    if (any_watched) why_not = "a region has no place invariant showing it exclusive";
    std::optional<AnalysisResult> decided;
    if (why_not.empty() && r.deadlocks > 0) {
      // A deadlock already found (breadth-first: on a shortest path); the others are not counted.
      decided = std::move(r);
      decided->deadlock_proof = "found by the exploration before its budget ran out; further deadlocks not counted";
    } else if (why_not.empty()) {
      const StateEquationResult se = deadlock_free_by_state_equation(net);
      const std::string traps =
          se.traps == 0 ? std::string() : fmt::format(", {} trap constraint{}", se.traps, se.traps == 1 ? "" : "s");
      if (se.verdict == StateEquationResult::Verdict::kDeadlockFree) {
        decided = std::move(r);
        decided->deadlock_proof = fmt::format(
            "no marking the state equation allows is dead without being a proper end (integer program{})", traps);
      } else if (se.verdict == StateEquationResult::Verdict::kCandidate) {
        if (auto path = guided_deadlock_search(net, se.firings, 20'000)) {
          decided = std::move(r);
          Marking m = net.initial_marking();
          for (TransitionId t : *path) fire_in_place(net, m, t);
          decided->deadlocks = 1;
          decided->deadlock_examples.assign(1, Deadlock{m, *path});
          decided->deadlock_path_shortest = false;
          decided->deadlock_proof = fmt::format(
              "found by a search guided by the state equation's firing counts{} (not necessarily shortest; "
              "further deadlocks not counted)",
              traps);
        } else {
          why_not = fmt::format(
              "the state equation allows a dead marking{} that a search guided by it could not reach", traps);
        }
      } else {
        why_not = "the state equation was not decided: " + se.reason;
      }
    }
    if (decided) {
      decided->complete = true;
      decided->stop_reason.clear();
      decided->deadlocks_counted = false;
      decided->bounded = true;
      return finish(std::move(*decided));
    }
    // Explore on, up to the state limit.
    r = Explorer(net, options, &stubborn, proviso, finite).run();
    if (!r.complete && r.state_limit_reached) r.stop_reason += "; past the exploration budget, " + why_not;
  }
  // A complete reduced search without a covering says nothing about boundedness unless the structure does.
  if (r.complete && !finite && !structurally_bounded(net)) {
    AnalysisResult full = Explorer(net, options, nullptr, false).run();
    full.reduction = Reduction::kStubborn;
    full.reduction_note =
        "explored fully: the net has cycles and no weighting of its places that no firing increases was found (the "
        "net is not structurally bounded, or GLPK's answer could not be confirmed), and the reduced search cannot "
        "show boundedness";
    return full;
  }
  return finish(std::move(r));
}

// A firing sequence of agg.net replayed in `original`: the marking reached, or nullopt if the expansion does not fire
// (which the rules exclude).
std::optional<Marking> replay_expanded(const Net& original, const std::vector<TransitionId>& path) {
  Marking m = original.initial_marking();
  for (TransitionId t : path) {
    if (!is_enabled(original, m, t)) return std::nullopt;
    fire_in_place(original, m, t);
  }
  return m;
}

// The result of analysing agg.net told in terms of `original`: paths expanded, markings replayed (a deadlock's
// completed by the delayed transitions), place ids mapped. nullopt if a counterexample does not carry over (the
// caller then analyses `original` itself).
std::optional<AnalysisResult> lift(const Net& original, const Agglomeration& agg, AnalysisResult r) {
  for (Deadlock& d : r.deadlock_examples) {
    d.path = agg.expand(d.path);
    std::optional<Marking> m = replay_expanded(original, d.path);
    if (!m) return std::nullopt;
    m = complete_dead(original, agg, std::move(*m), d.path);
    if (!m || original.is_final(*m)) return std::nullopt;
    d.marking = std::move(*m);
  }
  if (r.unbounded_witness) {
    r.unbounded_witness->path = agg.expand(r.unbounded_witness->path);
    std::optional<Marking> m = replay_expanded(original, r.unbounded_witness->path);
    if (!m) return std::nullopt;
    r.unbounded_witness->marking = std::move(*m);
  }
  for (PlaceId& p : r.unbounded_places) p = agg.place(p);
  std::sort(r.unbounded_places.begin(), r.unbounded_places.end());
  for (std::size_t k = 0; k < r.regions.size(); ++k) {
    RegionCheck& rc = r.regions[k];
    if (!rc.witness) continue;
    rc.witness->path = agg.expand(rc.witness->path);
    std::optional<Marking> m = replay_expanded(original, rc.witness->path);
    if (!m) return std::nullopt;
    std::uint64_t inside = 0;
    for (PlaceId p : original.regions()[k].inside) inside += (*m)[p];
    if (inside <= original.regions()[k].capacity) return std::nullopt;
    rc.witness->marking = std::move(*m);
    rc.witness_shortest = false;
  }
  // Full exploration of the reduced net (its fallback) counts and bounds the reduced net's markings only.
  r.place_bounds.clear();
  r.dead_transitions.clear();
  r.reduced = true;
  r.deadlock_path_shortest = false;
  std::size_t fused = 0;
  for (const auto& e : agg.expansion) fused += e.size() > 1 ? 1 : 0;
  r.net_reduction = fmt::format(
      "before exploring, the net was reduced from {} places and {} transitions to {} and {} ({} fused transitions: "
      "commands that always follow one another, {} post- and {} pre-agglomerations)",
      original.num_places(), original.num_transitions(), agg.net.num_places(), agg.net.num_transitions(), fused,
      agg.post, agg.pre);
  return r;
}

}  // namespace

AnalysisResult analyze(const Net& net, const AnalysisOptions& options) {
  if (options.max_states == 0) throw std::invalid_argument("analysis: max_states must be at least 1");
  if (options.reduction == Reduction::kNone) return Explorer(net, options, nullptr, false).run();
  if (options.agglomerate) {
    const Agglomeration agg = agglomerate(net);
    if (agg.changed()) {
      if (std::optional<AnalysisResult> r = lift(net, agg, analyze_stubborn(agg.net, options))) return std::move(*r);
    }
  }
  return analyze_stubborn(net, options);
}

}  // namespace cellwright::petri
