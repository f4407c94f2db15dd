#include "cellwright/petri/net.hpp"

#include <fmt/format.h>

#include <stdexcept>
#include <unordered_set>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::petri {

namespace {

[[noreturn]] void invalid(const Net& net, const std::string& what) {
  throw std::invalid_argument(fmt::format("net '{}': {}", net.name(), what));
}

// Checks one pre- or post-set of transition `t`: places exist, each once, weights positive.
void check_arcs(const Net& net, const Transition& t, const std::vector<Arc>& arcs, const char* side) {
  std::unordered_set<PlaceId> seen;
  for (const Arc& a : arcs) {
    if (a.place >= net.num_places()) {
      invalid(net, fmt::format("transition '{}': {} arc to place #{}, but the net has {} places", t.id, side, a.place,
                               net.num_places()));
    }
    const std::string& pid = net.places()[a.place].id;
    if (a.weight == 0) invalid(net, fmt::format("transition '{}': {} arc to place '{}' has weight 0", t.id, side, pid));
    if (!seen.insert(a.place).second) {
      invalid(net, fmt::format("transition '{}': two {} arcs to place '{}' (give one arc the summed weight)", t.id,
                               side, pid));
    }
  }
}

}  // namespace

Marking Net::initial_marking() const {
  Marking m(places_.size());
  for (std::size_t p = 0; p < places_.size(); ++p) m[p] = places_[p].initial;
  return m;
}

std::optional<PlaceId> Net::find_place(const std::string& id) const {
  auto it = place_index_.find(id);
  if (it == place_index_.end()) return std::nullopt;
  return it->second;
}

std::optional<TransitionId> Net::find_transition(const std::string& id) const {
  auto it = transition_index_.find(id);
  if (it == transition_index_.end()) return std::nullopt;
  return it->second;
}

bool Net::is_final(const Marking& m) const {
  CW_CHECK(m.size() == places_.size(), "marking has {} places, net '{}' has {}", m.size(), name_, places_.size());
  if (final_.empty()) return false;
  for (const Arc& a : final_) {
    if (m[a.place] < a.weight) return false;
  }
  for (const Transition& t : transitions_) {
    bool enabled = true;
    for (const Arc& a : t.inputs) {
      if (m[a.place] < a.weight) {
        enabled = false;
        break;
      }
    }
    if (enabled) return false;
  }
  return true;
}

NetBuilder::NetBuilder(std::string name) {
  net_.name_ = std::move(name);
}

PlaceId NetBuilder::add_place(Place p) {
  net_.places_.push_back(std::move(p));
  return static_cast<PlaceId>(net_.places_.size() - 1);
}

TransitionId NetBuilder::add_transition(Transition t) {
  net_.transitions_.push_back(std::move(t));
  return static_cast<TransitionId>(net_.transitions_.size() - 1);
}

void NetBuilder::add_region(Region r) {
  net_.regions_.push_back(std::move(r));
}

void NetBuilder::set_robots(std::vector<std::string> robots) {
  net_.robots_ = std::move(robots);
}

void NetBuilder::set_final(std::vector<Arc> final_places) {
  net_.final_ = std::move(final_places);
}

Transition& NetBuilder::transition(TransitionId t) {
  return net_.transitions_.at(t);
}

Place& NetBuilder::place(PlaceId p) {
  return net_.places_.at(p);
}

Net NetBuilder::build() && {
  Net& net = net_;
  // Ids index TransitionId/PlaceId as 32-bit values; UINT32_MAX is reserved as "none" by the arbiter.
  if (net.places_.size() >= UINT32_MAX || net.transitions_.size() >= UINT32_MAX) {
    invalid(net, fmt::format("too many places ({}) or transitions ({})", net.places_.size(), net.transitions_.size()));
  }
  net.place_index_.clear();
  net.transition_index_.clear();
  net.place_index_.reserve(net.places_.size());
  net.transition_index_.reserve(net.transitions_.size());
  for (std::size_t p = 0; p < net.places_.size(); ++p) {
    const std::string& id = net.places_[p].id;
    if (id.empty()) invalid(net, fmt::format("place #{} has an empty id", p));
    auto [it, fresh] = net.place_index_.emplace(id, static_cast<PlaceId>(p));
    if (!fresh) invalid(net, fmt::format("duplicate place id '{}' (places #{} and #{})", id, it->second, p));
  }
  for (std::size_t t = 0; t < net.transitions_.size(); ++t) {
    const std::string& id = net.transitions_[t].id;
    if (id.empty()) invalid(net, fmt::format("transition #{} has an empty id", t));
    if (net.place_index_.count(id) != 0) {
      invalid(net, fmt::format("id '{}' is used by both a place and a transition", id));
    }
    auto [it, fresh] = net.transition_index_.emplace(id, static_cast<TransitionId>(t));
    if (!fresh) invalid(net, fmt::format("duplicate transition id '{}' (transitions #{} and #{})", id, it->second, t));
  }

  std::unordered_set<std::string> robots;
  for (const std::string& r : net.robots_) {
    if (r.empty()) invalid(net, "a robot label is empty");
    if (!robots.insert(r).second) invalid(net, fmt::format("duplicate robot label '{}'", r));
  }

  for (const Transition& t : net.transitions_) {
    check_arcs(net, t, t.inputs, "input");
    check_arcs(net, t, t.outputs, "output");
    if (t.starts_robot && *t.starts_robot >= net.robots_.size()) {
      invalid(net, fmt::format("transition '{}' starts a command of robot #{}, but the net has {} robots", t.id,
                               *t.starts_robot, net.robots_.size()));
    }
  }

  std::unordered_set<std::string> region_names;
  for (const Region& r : net.regions_) {
    if (r.name.empty()) invalid(net, "a region has an empty name");
    if (!region_names.insert(r.name).second) invalid(net, fmt::format("duplicate region '{}'", r.name));
    std::unordered_set<PlaceId> seen;
    for (PlaceId p : r.inside) {
      if (p >= net.places_.size()) {
        invalid(net,
                fmt::format("region '{}' names place #{}, but the net has {} places", r.name, p, net.places_.size()));
      }
      if (!seen.insert(p).second) {
        invalid(net, fmt::format("region '{}' names place '{}' twice", r.name, net.places_[p].id));
      }
    }
  }

  std::unordered_set<PlaceId> final_seen;
  for (const Arc& a : net.final_) {
    if (a.place >= net.places_.size()) {
      invalid(net,
              fmt::format("final marking names place #{}, but the net has {} places", a.place, net.places_.size()));
    }
    const std::string& pid = net.places_[a.place].id;
    if (a.weight == 0) invalid(net, fmt::format("final marking needs 0 tokens in place '{}'", pid));
    if (!final_seen.insert(a.place).second) invalid(net, fmt::format("final marking names place '{}' twice", pid));
  }
  return std::move(net_);
}

const char* to_string(PlaceKind k) {
  switch (k) {
    case PlaceKind::kPlain:
      return "plain";
    case PlaceKind::kStart:
      return "start";
    case PlaceKind::kExecuting:
      return "executing";
    case PlaceKind::kWaiting:
      return "waiting";
    case PlaceKind::kDone:
      return "done";
    case PlaceKind::kEvent:
      return "event";
    case PlaceKind::kRegion:
      return "region";
  }
  return "unknown";
}

}  // namespace cellwright::petri
