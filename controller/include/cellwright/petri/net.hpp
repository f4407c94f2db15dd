// Place/transition nets: the fixed structure (Net) and the changing state (Marking), kept apart as in MuJoCo's
// mjModel/mjData. A Net is built once by NetBuilder, validated, and never changes; a Marking is a plain value.
// Firing, the enabled set, arbitration and analysis are free functions over the two (firing.hpp, analysis.hpp).
//
// Thread safety: a Net is immutable after build() and may be read from any number of threads at once.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

namespace cellwright::petri {

using PlaceId = std::uint32_t;
using TransitionId = std::uint32_t;
using Tokens = std::uint32_t;

// A marking: tokens per place, indexed by PlaceId. A value type: copy it, compare it, hash it.
using Marking = std::vector<Tokens>;

// What a place or transition stands for in the user's task program, so that analysis results (a deadlock's firing
// sequence, a dead transition) can be told in the program's own terms. Empty for nets read from PNML files that
// Cellwright did not write.
struct Origin {
  std::string robot;   // robot label ("r1"), empty for shared places (semaphores, regions, events)
  int line = 0;        // 1-based line of the task-level command in the program file, 0 if none
  int column = 0;      // 1-based column of that command
  std::string task;    // the task-level command as written ("Pick A")
  std::string motion;  // the motion-level command ("approach A")
  int primitive = -1;  // index into the robot's primitive program (task/compile.hpp), -1 if none
};

// What a place means at run time (paper section 2): a robot executing a command, a robot waiting for a message, a
// robot watching a sensor, or a shared object (event/semaphore, critical-region resource).
enum class PlaceKind : std::uint8_t {
  kPlain,      // no declared meaning (nets read from foreign PNML)
  kStart,      // a robot before its first command
  kExecuting,  // a robot executing a motion primitive (move/open/close); its sensor condition ends it
  kWaiting,    // a robot waiting for an event (wait primitive)
  kDone,       // a robot that has finished its program
  kEvent,      // an event object / semaphore: tokens are pending signals
  kRegion,     // the free-resource place of a critical region: a token means the region is free
};

struct Place {
  std::string id;    // unique, stable identifier (PNML id)
  std::string name;  // human-readable label
  Tokens initial = 0;
  PlaceKind kind = PlaceKind::kPlain;
  Origin origin;
};

struct Arc {
  PlaceId place = 0;
  Tokens weight = 1;
};

struct Transition {
  std::string id;
  std::string name;
  std::vector<Arc> inputs;   // pre-set with weights; at most one arc per place
  std::vector<Arc> outputs;  // post-set with weights; at most one arc per place
  Origin origin;             // the command whose begin (or end) this transition is
  // The robot command whose execution starts when this transition fires: robot index into Net::robots() and index
  // into that robot's primitive program. Empty when the firing starts no command (a pure end, a foreign net).
  std::optional<std::uint32_t> starts_robot;
  int starts_primitive = -1;
};

// A critical region: while any token is in one of `inside`, the robot holding it is in the region. The mutual
// exclusion property is: in every reachable marking, the tokens in `inside` add up to at most `capacity`.
struct Region {
  std::string name;
  std::vector<PlaceId> inside;
  Tokens capacity = 1;
};

class NetBuilder;

class Net {
 public:
  const std::string& name() const { return name_; }
  const std::vector<Place>& places() const { return places_; }
  const std::vector<Transition>& transitions() const { return transitions_; }
  const std::vector<Region>& regions() const { return regions_; }
  // Robot labels, in the order used by Transition::starts_robot and arbitration. Empty for foreign nets.
  const std::vector<std::string>& robots() const { return robots_; }
  // A dead marking that covers this partial marking is a proper end (every robot done), not a deadlock. Empty means
  // every dead marking is a deadlock.
  const std::vector<Arc>& final_places() const { return final_; }

  std::size_t num_places() const { return places_.size(); }
  std::size_t num_transitions() const { return transitions_.size(); }
  // Each place's initial tokens, indexed by PlaceId.
  Marking initial_marking() const;

  // The place or transition with this id, or nullopt. Constant time (hash lookup).
  std::optional<PlaceId> find_place(const std::string& id) const;
  std::optional<TransitionId> find_transition(const std::string& id) const;

  // True when `m` is dead and covers final_places(): the program finished. Always false when final_places() is
  // empty. Throws InternalError if m.size() != num_places().
  bool is_final(const Marking& m) const;

 private:
  friend class NetBuilder;
  std::string name_;
  std::vector<Place> places_;
  std::vector<Transition> transitions_;
  std::vector<Region> regions_;
  std::vector<std::string> robots_;
  std::vector<Arc> final_;
  std::unordered_map<std::string, PlaceId> place_index_;
  std::unordered_map<std::string, TransitionId> transition_index_;
};

// Builds a Net and validates it on build(): ids non-empty and unique (places and transitions share one id space, as
// in PNML), arcs name existing places, no duplicate arc to one place within a transition's pre- or post-set (a place
// may be in both the pre- and the post-set: a self-loop), weights positive; regions have a non-empty, unique name and
// name existing places, each once; robot labels are non-empty and unique and Transition::starts_robot indexes them;
// final places exist, each once, with positive weights. Violations throw std::invalid_argument naming the element
// (callers that read files wrap it in an InputError with the file position). add_* return the new element's index;
// they do not validate (so that arcs may be fixed up before build()). A NetBuilder is used by one thread.
class NetBuilder {
 public:
  explicit NetBuilder(std::string name = "net");
  PlaceId add_place(Place p);
  TransitionId add_transition(Transition t);
  void add_region(Region r);
  void set_robots(std::vector<std::string> robots);
  void set_final(std::vector<Arc> final_places);
  // Mutable access while building (e.g. to add an arc to a place created later). Throws std::out_of_range for an
  // index not returned by add_*.
  Transition& transition(TransitionId t);
  Place& place(PlaceId p);
  std::size_t num_places() const { return net_.places_.size(); }
  std::size_t num_transitions() const { return net_.transitions_.size(); }
  // Validates (see above) and returns the net; the builder is moved from. Throws std::invalid_argument.
  Net build() &&;

 private:
  Net net_;
};

// "plain", "start", "executing", "waiting", "done", "event", "region".
const char* to_string(PlaceKind k);

}  // namespace cellwright::petri
