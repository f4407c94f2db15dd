// Internal to the Petri net library: the net effect of each transition (the columns of the incidence matrix), shared
// by the structural checks (stubborn.cpp, subinvariant.cpp).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri::detail {

// Per transition: (place, delta) pairs for the places whose count its firing changes, delta != 0, each place once,
// in first-seen order (inputs, then outputs).
using Effects = std::vector<std::vector<std::pair<PlaceId, std::int64_t>>>;

inline Effects effects(const Net& net) {
  Effects out;
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

}  // namespace cellwright::petri::detail
