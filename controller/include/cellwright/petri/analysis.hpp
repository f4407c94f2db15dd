// Analysis before run: explore the reachability graph and report deadlocks, boundedness, dead transitions and the
// mutual exclusion of every critical region.
//
// Exploration is breadth-first, so the firing sequence reported for a deadlock is a shortest one. Markings are stored
// bit-packed; it stops cleanly at `max_states` and says so rather than exhausting memory. Unboundedness is found
// without running forever: when a new marking strictly covers one of its ancestors (Karp-Miller), the places that
// grew are unbounded and exploration stops.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

struct AnalysisOptions {
  std::uint64_t max_states = 5'000'000;  // stop with complete == false beyond this many stored markings
  std::size_t max_deadlocks_reported = 1;  // how many counterexample paths to keep (the count is always exact)
};

struct Deadlock {
  Marking marking;
  std::vector<TransitionId> path;  // shortest firing sequence from the initial marking
};

struct RegionCheck {
  std::string name;
  bool exclusive = true;          // never more than capacity tokens inside
  Tokens max_inside = 0;          // the most tokens found inside at once
  std::optional<Deadlock> witness;  // a shortest path to a violating marking (Deadlock reused as a path holder)
};

struct AnalysisResult {
  bool complete = false;           // the whole reachability set was explored (no state limit, net bounded)
  std::string stop_reason;         // why exploration stopped early, empty when complete
  std::uint64_t states = 0;        // reachable markings found
  std::uint64_t edges = 0;         // (marking, transition) firings found
  std::uint64_t deadlocks = 0;     // dead markings that are not proper ends
  std::uint64_t final_states = 0;  // dead markings that are proper ends (every robot done)
  std::vector<Deadlock> deadlock_examples;
  bool bounded = true;
  std::vector<PlaceId> unbounded_places;
  std::optional<Deadlock> unbounded_witness;  // path to the marking that strictly covers an ancestor
  std::vector<Tokens> place_bounds;           // max tokens seen per place (valid when complete)
  std::vector<TransitionId> dead_transitions;  // never enabled in any reachable marking (valid when complete)
  std::vector<RegionCheck> regions;
  bool mutex_ok = true;
  std::uint64_t stored_bytes = 0;  // memory held by the marking store at the end, for the <= 64 B/marking target

  // Deadlock-free, bounded, every region exclusive, and the exploration was complete.
  bool ok() const { return complete && deadlocks == 0 && bounded && mutex_ok; }
};

AnalysisResult analyze(const Net& net, const AnalysisOptions& options = {});

// A firing sequence told in the program's terms: one line per transition, e.g.
// "r1 line 2 'Put r2' (hand over r2): signal step2.r1" or the transition name for foreign nets.
std::string describe_path(const Net& net, const std::vector<TransitionId>& path);
// Which robot is where in a marking, e.g. "r1: waiting for step2.r2 (line 2 'Put r2'); r2: done".
std::string describe_marking(const Net& net, const Marking& m);

// Human-readable report and the JSON report (keys: states, edges, deadlocks, bounded, mutex_ok, complete, ...).
std::string format_report(const Net& net, const AnalysisResult& r);
nlohmann::json to_json(const Net& net, const AnalysisResult& r);

}  // namespace cellwright::petri
