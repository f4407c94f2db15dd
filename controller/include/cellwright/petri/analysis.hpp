// Analysis before run: explore the reachability graph and report deadlocks, boundedness, dead transitions and the
// mutual exclusion of every critical region.
//
// Exploration is breadth-first, so the firing sequence reported for a deadlock is a shortest one. Markings are stored
// bit-packed (each place in as many bits as the largest count seen needs; widening repacks the store), with a 32-bit
// open-addressing hash set and a parent link per marking: typically 15-30 bytes per marking for robot programs. It
// stops cleanly at `max_states` and says so rather than exhausting memory. Unboundedness is found without running
// forever: when a new marking strictly covers one of its ancestors on its BFS path (Karp-Miller), the places that grew
// are unbounded and exploration stops. The covering test runs only for markings that hold more tokens in all than
// every marking before them on their BFS path, which keeps it cheap (never, for nets that conserve tokens) and is
// still complete: every unbounded net is reported unbounded, given enough max_states to reach the covering.
//
// Partial-order reduction (AnalysisOptions::reduction = kStubborn; stubborn.hpp says how and why it is sound): only
// the transitions of a stubborn set are fired from each marking, so a program of many robots that mostly work
// independently is explored along far fewer interleavings. What the reduced search guarantees, once complete:
//  - deadlocks: every reachable dead marking is found, so `deadlocks` and `final_states` are exact, and the reported
//    deadlock path is still a shortest one (deadlock_path_shortest stays true) unless the net was reduced first
//    (AnalysisOptions::agglomerate, below);
//  - mutual exclusion: each region's verdict and its largest occupancy (max_inside) are exact; the witness path to a
//    violation may be longer than the shortest one (RegionCheck::witness_shortest is false);
//  - boundedness: an unbounded witness found is real; "bounded" is claimed only for nets shown bounded structurally
//    (structurally_bounded(): every run finite, or a weighting of the places that no firing increases, found by
//    difference constraints or by a linear program and checked exactly); for any other net that the reduced search
//    finds no covering in, analyze() explores fully instead and says so in reduction_note;
//  - `states` and `edges` count what was explored (reduced == true), not the reachability graph; place_bounds and
//    dead_transitions are not computed.
// Under kStubborn the net is first reduced (agglomerate.hpp: commands that always follow one another fused; a
// lock-step barrier becomes one transition per robot) unless AnalysisOptions::agglomerate is false, and the reduced
// net is analysed as below; its results are told in the original net's terms (paths expanded and replayed, place ids
// mapped), with the same verdicts and counts of dead markings, paths not necessarily shortest, and states and edges
// counting the reduced net's markings (AnalysisResult::net_reduction says how far it was reduced).
// Under kStubborn a region shown exclusive by a place invariant (structural.hpp) is not watched by the search (no
// condition V for it, no proviso on its account): its verdict is the proof's, and max_inside the most seen. And the
// reduced search has a budget (AnalysisOptions::exploration_budget): when it runs out, and every region is proved
// and the net bounded by its structure, deadlock freedom is decided by the state equation as an integer program
// (proved: OK), or a deadlock is found by a search its solution guides (a real, replayed firing sequence, not
// necessarily shortest); only what that leaves undecided is explored on up to max_states, and a stop there says why
// the structural checks did not decide. complete then means every verdict was decided; explored_all whether the
// exploration itself ended.
//
// Thread safety: analyze() and the report functions are re-entrant and share no state; a Net may be analysed from
// several threads at once. A progress callback runs on the analysing thread.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

// Which interleavings the exploration visits.
enum class Reduction : std::uint8_t {
  kNone,      // every interleaving: exact state and edge counts, place bounds, dead transitions
  kStubborn,  // stubborn sets: deadlocks, region verdicts and boundedness preserved (see above), far fewer markings
};
// "none", "stubborn".
const char* to_string(Reduction r);
// The inverse of to_string; throws std::invalid_argument naming the value for anything else.
Reduction parse_reduction(std::string_view name);

// How far an exploration has got, for a progress display.
struct AnalysisProgress {
  std::uint64_t markings = 0;  // stored so far
  std::uint64_t edges = 0;     // firings explored so far
  std::uint64_t queue = 0;     // markings stored but not expanded yet
  double seconds = 0;          // since the exploration started
  bool reduced = false;        // a stubborn-set exploration
};

struct AnalysisOptions {
  // Stop with complete == false beyond this many stored markings (at least 1; values above 2^32 - 2 act as 2^32 - 2).
  std::uint64_t max_states = 5'000'000;
  std::size_t max_deadlocks_reported = 1;  // how many counterexample paths to keep (the count is always exact)
  Reduction reduction = Reduction::kNone;
  // Called from analyze() once `progress_interval` has passed since the start, and then every interval, while the
  // exploration runs (never for a run that ends sooner). Empty: no calls.
  std::function<void(const AnalysisProgress&)> progress;
  std::chrono::milliseconds progress_interval{1000};
  // When set, read (relaxed) every 256 markings expanded: once true, exploration stops with complete == false and
  // stop_reason "interrupted after N markings" (a user's Ctrl-C, set from another thread). Not owned.
  const std::atomic<bool>* stop = nullptr;
  // Under Reduction::kStubborn: the reduced search stores at most this many markings (or max_states, if smaller)
  // before the structural checks (structural.hpp) decide what it has not: deadlock freedom by the state equation, a
  // deadlock by a search guided by it. Past the budget, a region must have been shown exclusive by a place
  // invariant and the net bounded by its structure, else the search goes on up to max_states as before; so does it
  // when the state equation leaves a candidate that the guided search cannot reach. 0: no budget (explore up to
  // max_states; the structural deadlock check is not used).
  std::uint64_t exploration_budget = 10'000;
  // Under Reduction::kStubborn: reduce the net first (agglomerate.hpp: commands that always follow one another fused
  // into one transition) and explore the reduced net. Verdicts, the numbers of deadlocks and proper ends, and each
  // region's largest occupancy are the original net's; counterexamples are the original net's firing sequences
  // (expanded and replayed), not necessarily shortest (deadlock_path_shortest false); states and edges count the
  // reduced net's markings. No effect when no rule applies (a copy of the net would be explored).
  bool agglomerate = true;
};

struct Deadlock {
  Marking marking;
  std::vector<TransitionId> path;  // shortest firing sequence from the initial marking
};

struct RegionCheck {
  std::string name;
  bool exclusive = true;            // never more than capacity tokens inside
  Tokens max_inside = 0;            // the most tokens found inside at once
  std::optional<Deadlock> witness;  // a path to a violating marking (Deadlock reused as a path holder)
  bool witness_shortest = true;     // the witness path is a shortest one (false under reduction)
  // Shown exclusive by a place sub-invariant (structural.hpp; under Reduction::kStubborn, whenever one exists): then
  // at most `invariant_bound` tokens are ever inside, and max_inside is the most seen by the exploration (<= that).
  bool by_invariant = false;
  Tokens invariant_bound = 0;
};

// Counts and negative findings (a deadlock, an unbounded place, a region violation) are definite; when `complete` is
// false, the absence of a problem only holds for the part explored.
struct AnalysisResult {
  bool complete = false;           // every verdict covers the whole reachable set: it was explored (no state limit,
                                   // net bounded), or what the exploration left was proved (explored_all false)
  std::string stop_reason;         // why exploration stopped early, empty when complete, e.g.
                                   // "state limit of N markings reached; raise --max-states"
  std::uint64_t states = 0;        // reachable markings found
  std::uint64_t edges = 0;         // (marking, transition) firings found
  std::uint64_t deadlocks = 0;     // dead markings that are not proper ends
  std::uint64_t final_states = 0;  // dead markings that are proper ends (every robot done)
  std::vector<Deadlock> deadlock_examples;
  bool bounded = true;                         // false once a covering was found
  std::vector<PlaceId> unbounded_places;       // the places that grew in that covering, ascending
  std::optional<Deadlock> unbounded_witness;   // path to the marking that strictly covers an ancestor
  std::vector<Tokens> place_bounds;            // max tokens seen per place (valid when complete)
  std::vector<TransitionId> dead_transitions;  // never enabled in any reachable marking (valid when complete)
  std::vector<RegionCheck> regions;
  bool mutex_ok = true;
  std::uint64_t stored_bytes = 0;  // memory held by the marking store at the end, for the <= 64 B/marking target
  Reduction reduction = Reduction::kNone;  // what was asked for
  bool reduced = false;                    // states/edges count a reduced exploration (stubborn sets were applied)
  bool deadlock_path_shortest = true;      // deadlock_examples hold shortest paths (true in both modes)
  std::string reduction_note;  // why a requested reduction was not applied (then reduced == false), else empty
  // The exploration covered the whole (reduced) reachability graph. When it stopped at its budget
  // (AnalysisOptions::exploration_budget) and the structural checks decided every property instead, complete is
  // true and this is false; states and edges then count what was explored.
  bool explored_all = false;
  // How the deadlock verdict was reached when not by a complete exploration (empty otherwise), e.g. "no marking that
  // the state equation allows is dead (integer program, 2 trap constraints)".
  std::string deadlock_proof;
  // deadlocks and final_states count every reachable dead marking (a complete exploration). False when the verdict
  // came from the structural checks: then deadlocks is 0 (proved) or the number found (1), final_states what the
  // partial exploration saw.
  bool deadlocks_counted = true;
  bool state_limit_reached = false;  // the exploration stopped at its state limit (max_states or the budget)
  // How the net was reduced before exploring (AnalysisOptions::agglomerate), e.g. "before exploring, the net was
  // reduced from 143000 places and 98000 transitions to ...", empty when it was not.
  std::string net_reduction;

  // Deadlock-free, bounded, every region exclusive, and the exploration was complete.
  bool ok() const { return complete && deadlocks == 0 && bounded && mutex_ok; }
};

// Explores the reachability graph of `net` from its initial marking, reduced as options.reduction says. Throws
// std::invalid_argument if options.max_states is 0; std::bad_alloc only if memory runs out below the state limit.
AnalysisResult analyze(const Net& net, const AnalysisOptions& options = {});

// A firing sequence told in the program's terms: one numbered line per transition, e.g.
// "3. r1 line 2 'Put r2' (hand over r2): r1 begin signal step2.r1>r2", or "3. t7" (name, else id) for foreign nets.
// No trailing newline.
std::string describe_path(const Net& net, const std::vector<TransitionId>& path);
// Which robot is where in a marking, e.g. "r1: waiting for event step2.r2>r1 (line 2 'Put r2'); r2: done", then
// pending events ("pending: event e (x2)") and other marked places ("p3: 2"); for foreign nets just the marked
// places by name (else id).
std::string describe_marking(const Net& net, const Marking& m);

// Human-readable report: the verdict first ("OK: ...", "FAIL: 1 deadlock, region Z not exclusive", "UNKNOWN: ..."),
// then the counts ("explored N markings, E edges", or "N markings explored (reduced), E edges" under reduction, with a
// line saying why when a requested reduction fell back to full exploration), the shortest deadlock path and where the
// robots are stuck, the unbounded witness, each region (a witness path that may not be shortest says "not necessarily
// shortest"), and the transitions never enabled (full exploration only). Ends with a newline.
std::string format_report(const Net& net, const AnalysisResult& r);
// The JSON report. Keys: ok, complete, stop_reason, states, edges, deadlocks, final_states, bounded, mutex_ok,
// stored_bytes, reduction ("none"/"stubborn", as asked), reduced (states and edges count a reduced exploration),
// reduction_note, net_reduction, deadlock_path_shortest, explored_all, deadlock_proof, deadlocks_counted, unbounded_places (place ids), unbounded_path, dead_transitions (transition
// ids; null unless complete and not reduced), place_bounds ({place id: max tokens}; null unless complete and not
// reduced), regions ([{name, exclusive, max_inside, capacity, witness_path, witness_shortest, witness_marking,
// by_invariant, invariant_bound (null unless by_invariant)}]),
// deadlock_path, deadlock_marking ({place id: tokens}, non-zero places only),
// deadlock_description (describe_marking), deadlock_examples ([{path, marking}]). A path is a list of {transition
// (id), name, robot, line, task, motion} ("" and 0 where the net has no origin); absent paths and markings are null.
nlohmann::json to_json(const Net& net, const AnalysisResult& r);

// What a checking command (`twin check`, `twin analyze`) does once it has a net.
struct CheckOptions {
  AnalysisOptions analysis;
  bool json = false;  // print to_json instead of format_report
  // Show progress on stderr (ProgressPrinter, in place when stderr is a terminal) for a run longer than
  // analysis.progress_interval; replaces analysis.progress.
  bool progress = false;
};

// Prints AnalysisProgress as one line, e.g. "checking: 1234567 markings, 850000/s, queue 120345": on a terminal
// overwritten in place ("\r" and erase to the end of the line), else one line per call. finish() erases the line on
// a terminal (so that the report starts on a clean line) and does nothing otherwise.
class ProgressPrinter {
 public:
  ProgressPrinter(std::ostream& out, bool terminal) : out_(out), terminal_(terminal) {}
  void operator()(const AnalysisProgress& p);
  void finish();

 private:
  std::ostream& out_;
  bool terminal_;
  bool shown_ = false;
};

// Early word that an exploration is too large, from its first progress report: when the frontier is still wide (at
// least a tenth of the markings stored are not expanded yet) the state space is still growing, and the note says so
// with the figures and how soon, at the rate so far, the state limit `max_states` will be reached, e.g. "after 1.0 s
// 812345 markings, 260000 not expanded yet (812345/s): still growing; at this rate the state limit of 5000000 is
// reached in about 5 s; --reduction stubborn explores fewer interleavings". Empty when the frontier is narrow (the
// exploration may well end soon) or the limit is reached already.
std::string size_warning(const AnalysisProgress& p, std::uint64_t max_states);

// Word, before any exploring, that `net` is too wide to explore: the fewest firings that take every robot from its
// start place to its done place (each robot's token moves along its own places, one firing at a time), times the
// bytes of a marking (one bit per place at least), is at least 1 GB, or those firings reach `max_states`, e.g. "too
// wide to explore: a run to the end fires at least 3400000 transitions, and each marking on it takes at least 225000
// bytes ...". Empty otherwise, and for nets without robots (foreign nets) or with a robot that cannot finish.
std::string width_warning(const Net& net, std::uint64_t max_states);

// Analyses `net` and prints the outcome to `out`: with options.json the JSON report (to_json) indented by 2 and a
// newline, else "<source>: " and the human report (format_report). An exploration that stopped early (the state limit,
// an interruption) adds a note on stderr with the figures: markings explored, seconds, markings per second and the
// limit; with options.progress, a width_warning is printed on stderr before the analysis starts and a size_warning
// (once) as soon as a progress report calls for it. Returns the checking commands' exit status: 0 if the result is ok(), 1 if not. Throws as analyze() does.
int check_and_report(const Net& net, std::string_view source, const CheckOptions& options, std::ostream& out);

}  // namespace cellwright::petri
