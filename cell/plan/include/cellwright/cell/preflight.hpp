// Preflight: what is checked before a scenario may run, the first thing the plan stage does. The program's net is
// analysed, every target is checked for reach, every move is planned, and the plan is swept for collisions through
// the CollisionSweep port (sweep.hpp). A scenario that fails it is refused before anything is built.
//
// What it passes on: the net, the motion plan (computed here, once: the estimate, the robot programs, the dry run and
// the run on the twin take it from the Preflight, none plans again) and the twin's compiled model of the cell that
// the sweep ran on (the run and the estimate use it rather than compiling the cell again).
//
// Thread safety: a pure function of its arguments; any thread may call it.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/net.hpp"

namespace cellwright::cell {

// One place a robot's program sends it to, checked for reach.
struct ReachNeed {
  std::string robot;   // cell robot
  std::string target;  // what it must reach, e.g. "location 'output_drop'", "workpiece 'A' at the input stop"
  std::string why;     // the program command that needs it: "exchange.task:10:14 'Place B'"
};

struct Preflight {
  petri::Net net;
  petri::AnalysisResult analysis;
  std::vector<ReachNeed> needs;           // every (robot, target) pair the program needs, in the order a run meets them
  std::vector<models::ReachCheck> reach;  // the checks run for them (check_reach on the needed targets)
  std::vector<std::string> problems;      // one line per reason the run may not start, empty when it may
  // One line per collision the motion sweep predicts (sweep.hpp: PredictedCollision::text); each is also in
  // `problems`, as "predicted collision: " and the line, after the other problems.
  std::vector<std::string> collisions;
  std::string sweep_summary;  // what the sweep did, one line; "" when it did not run
  // The motion plan (estimate.hpp plan_motions), computed once here when the net passed its check and every target is
  // in reach (else nullopt): its moves that cannot be made are among `problems`. The estimate, the robot programs,
  // the dry run and the run take it from here.
  std::optional<MotionPlan> plan;
  // The twin's compiled model of the cell the sweep ran on (sweep.hpp CollisionSweep::compile), for the run and the
  // estimate to use; null when nothing was swept (no simulator, or the checks before failed).
  std::shared_ptr<const TwinModel> twin;

  // Whether the run may start: no problem or, with `allow_collisions` (twin run --allow-collisions), none but the
  // predicted collisions.
  bool ok(bool allow_collisions = false) const {
    return problems.size() == (allow_collisions ? collisions.size() : 0);
  }
};

// Builds the program's Petri net and analyses it as twin check does (petri::analyze with stubborn-set reduction, whose
// verdicts are those of full exploration; `analysis.states` counts the markings explored: the run is refused unless
// the analysis is complete, deadlock-free, bounded and every region exclusive). A named part that one robot lets go
// of and another goes to (a relay, docs/scenarios.md) must be ordered by the net: each such pair of commands comes in
// one order in every run (explored in full, up to 200,000 markings), else it is a problem naming both commands. Then
// it checks the reach of every target the program's moves need: for each program robot, the grasp and approach poses
// of the locations it moves to, of the places where it picks workpieces (their initial pose, or a conveyor's pick
// point: the stop bar when it has one; a part let go of on a running belt is followed to the belt's stop, and a move
// to it after it rode off a belt without a stop is a problem), and its grasp at the hand-over when it puts or gets
// (a robot missing from the cell's hand-over grasps is a problem); a part a robot put down names that robot and
// command in the reach problem.
// When all of that holds, it also plans every move as robot control will make it (estimate.hpp plan_motions, with
// options.handover_clearance; kept in `plan`) and reports each move that cannot be made: a part held from the side
// that cannot be put down from the side, a taker that cannot wait backed off from the hand-over. When every move can
// be made, it compiles the cell with `collisions` (kept in `twin`), sweeps the moves for collisions on it (sweep.hpp:
// against the static cell, and against the other robots' where the net lets two commands run at once) and lists each
// predicted one in `collisions`. `collisions` is null in a build without the simulator: then nothing is swept, and
// sweep_summary says so.
// Throws InputError only if a URDF cannot be read (load_scenario has read them once already) or, from the sweep,
// when robots overlap at the start (sweep.hpp).
Preflight preflight(const Scenario& scenario, const CollisionSweep* collisions);

}  // namespace cellwright::cell
