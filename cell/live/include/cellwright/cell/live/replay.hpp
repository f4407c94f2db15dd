// The program's check in the live view and the replay of its counterexample (docs/live-view.md, "Check and
// counterexample replay").
//
// The check is the preflight's (preflight.hpp: the program's net analysed with stubborn-set reduction, as twin check
// does). A program that fails it has a counterexample: the firing sequence to a dead marking that is not the end
// (deadlock), to a marking covering an earlier one (boundedness), or to a marking with a region over its capacity
// (mutual exclusion). `twin serve` runs it as a replay: the twin run with task control firing exactly that sequence
// (RunConfig::firing_order, TaskControl::follow), so the robots do what the counterexample says, and the run ends
// at its last marking (a deadlock: task control's own "deadlock" failure; otherwise the run is stopped there).
//
// Thread safety: pure functions of their arguments.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/net.hpp"

namespace cellwright::cell {

struct CheckOutcome {
  bool ok = true;
  std::string summary;   // format_report's first line ("OK: ...", "FAIL: 1 deadlock", ...)
  std::string property;  // "deadlock", "boundedness", "mutual_exclusion", or "" when ok
  std::vector<petri::TransitionId> counterexample;  // the firing sequence (empty when ok)
  std::string last_marking;  // describe_marking of where it ends ("" when ok)
};

// What the preflight's analysis `analysis` of `net` (Preflight::analysis) says, and its counterexample when it fails.
CheckOutcome check_outcome(const petri::Net& net, const petri::AnalysisResult& analysis);
// The preflight's check of `net` (the program's) run again: check_outcome of a fresh analysis with its options.
CheckOutcome check_program(const petri::Net& net);

// The "check" message: {"type":"check","ok","summary","property","counterexample":[{"transition","line","robot"}],
// "dead_marking"}.
std::string check_json(const petri::Net& net, const CheckOutcome& check);

// For a scenario whose preflight refused it only because its program fails the check (preflight.analysis not ok):
// the preflight with the motion plan a run needs (plan_motions of the net, which follows the net until it stops).
// nullopt when the preflight refused it for anything else, or passed.
std::optional<Preflight> counterexample_preflight(const Scenario& scenario, const Preflight& refused);

}  // namespace cellwright::cell
