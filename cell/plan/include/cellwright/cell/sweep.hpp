// Collisions found before the run, a port of the plan stage: every motion of the program's motion plan (estimate.hpp
// plan_motions) swept through a model of the cell's geometry, against the static cell and, for commands the program's Petri net lets
// run at the same time, against the other robots. Preflight (scenario.hpp) runs it and refuses a run with a predicted
// collision; docs/scenarios.md ("Preflight") says what a user sees.
//
// What is swept. Each program robot, per place of its chain in the net (to_net.hpp: start, one per primitive, done),
// occupies a set of poses while that place is marked:
//  - a move: the joint-interpolated path the driver follows from the plan's `from` to its `goal` (robot control sends
//    joint targets; the quintic time scaling changes when the arm is where, not where it goes), sampled so that no
//    point of any collision geom of the arm or of the part it carries moves more than `resolution` between two samples
//    (checked on the samples themselves: the step is refined until it holds);
//  - any other command (grip, signal, wait), and the start and the end: one pose, where the robot's last move left
//    it (home at the start), with the part and fingers as during that move.
// The arm's fingers stand as the plan's last grip left them (open, closed, or on the part), and a carried part rides
// in the tool at the pose the plan grasped it with.
//
// What counts as a collision: a contact (the twin's: cell/sim/sweep.hpp, MuJoCo's collision detection on the cell's
// scene with its own collision filters) deeper than `depth` between
//  - a robot (its links, fingers and the part it carries) and the static cell: the floor, the conveyors' frames and
//    stop bars, the machines and their fixtures, the other robots' pedestals, and the robots the program does not
//    use (at home all along); or
//  - two robots (each with the part it carries), in two poses that the net can hold at once (below).
// Not counted, by design: a robot against its own pedestal (its mount) and against the part it carries (the grip),
// a carried part against the conveyor belts (belts collide with parts only: putting a part down is the point), and
// the parts that are not carried (they move as the program runs: picking one up means touching it; a run's physics
// judges those), a robot's links against each other (the scene does not simulate self-collision), and the fault
// injection's obstacles (put in the cell during a run). A part both robots hold at a hand-over is gripped by both.
//
// Which motions overlap in time: the net's reachability graph, explored in full (every interleaving; at most
// `max_states` markings), gives the pairs of places of two robots that are marked together. Two such commands are
// swept against each other conservatively: every pose of one against every pose of the other, not on a common time
// base. The run's timing is not the estimate's (parts arrive when the feed and the belts bring them, a camera takes
// frames, real drivers run at their own speed), so a timeline would be a guess; the net's concurrency is not. A net
// with more markings than `max_states` is swept as if every two commands of two robots could overlap (said in
// `concurrency`).
//
// The sweep does not re-plan: a move that collides is reported, not routed through a via point (the drivers follow the
// plan as it is).
//
// Planning needs no simulator: preflight (preflight.hpp) asks a CollisionSweep, which the twin implements
// (cell/sim/sweep.hpp: TwinSweep); a build without the simulator has none, and says that it did not sweep.
//
// Thread safety: plain values; a CollisionSweep's sweep() is const and may be called from any thread.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/petri/net.hpp"
#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

struct SweepOptions {
  double resolution = 0.005;          // m: the most any point of a swept arm moves between two samples
  double depth = 0.002;               // m: contacts shallower than this are touching, not colliding
  std::uint64_t max_states = 200000;  // markings of the net explored for concurrency
};

// One side of a predicted collision.
struct SweepParty {
  std::string robot;  // cell robot; "" for the static cell
  std::string body;   // what is hit, in the cell's names: "link 'link3'", "workpiece 'A' (carried)",
                      // "conveyor 'input' (frame)", "machine 'mill' (fixture)", "the floor", "robot 'melfa''s pedestal"
  std::string command;  // the robot's command, "move at(A)"; "before its first command", "after its last command"
  std::string source;   // the program line of the task-level command: "exchange.task:7:3 'Pick A'" ("" if none)
  std::size_t sample = 0, samples = 1;  // where on the motion: sample i of n (0 = its start, n - 1 = its end)
};

// One collision: a robot's command against one body of the static cell, or two robots' commands that the net lets
// run at once. The samples are where it begins (the first pose found in contact); the bodies are the deepest pair.
struct PredictedCollision {
  SweepParty a, b;                  // a: a robot; b: the static cell or another robot
  double depth = 0;                 // m, the deepest overlap found between the two sides during the command(s)
  std::vector<std::string> bodies;  // every pair of bodies found in contact, "link 'link6' / machine 'mill'"
  // One line: "robot 'r1' hits machine 'pillar' during 'move above(M)' (one.task:7:3 'Place M'), from 37% of the
  // way (sample 50 of 133): its link 'link6' 314 mm deep (8 pairs of bodies in contact in all)"; for two robots
  // both commands and where on them, and that the net lets them run at once.
  std::string text() const;
};

struct SweepReport {
  // Against the static cell (by robot, command, body hit), then between robots (by the two robots and commands).
  std::vector<PredictedCollision> collisions;
  std::size_t motions = 0;        // moves swept
  std::size_t samples = 0;        // poses checked against the static cell
  std::size_t pairs = 0;          // pairs of commands of two robots that can run at once, swept
  std::uint64_t pose_checks = 0;  // poses checked for contacts in all (against the cell and robot against robot)
  std::uint64_t states = 0;       // markings explored for concurrency
  bool exhaustive = true;         // the markings were all explored (false: every two commands taken as concurrent)
  std::string concurrency;        // how concurrency was found, one sentence
  bool ok() const { return collisions.empty(); }
};

// The simulator's compiled model of one scenario's cell (its MuJoCo scene, defined by cell/sim/sweep.hpp): made once
// by the port, the sweep runs on it, and the preflight carries it (Preflight::twin) to the estimate and the run, so
// that a run compiles its cell once. The plan stage only carries it: the type is complete in cell/sim alone.
struct TwinModel;

// The port.
class CollisionSweep {
 public:
  virtual ~CollisionSweep() = default;
  // Compiles `scenario`'s cell as its runs will have it (its parts where the scenario's perturbation puts them, the
  // obstacles its faults may put in the cell; neither changes what the sweep finds: it parks the parts it does not
  // carry and ignores the obstacles). Throws InputError when the cell's geometry cannot be read (a URDF) or the
  // simulator rejects it.
  virtual std::shared_ptr<const TwinModel> compile(const Scenario& scenario) const = 0;
  // Sweeps the plan of `scenario`'s program (`net` is its task::to_net, `plan` its plan_motions) on `model` (compile()
  // of the scenario) as the top says. Throws InputError only when robots overlap at the start (at home: one error
  // naming the bodies and the depth, at the cell file's robot entry, rather than a collision for every command that
  // starts there; the twin's: twin/scene.hpp start_overlaps).
  virtual SweepReport sweep(const TwinModel& model, const Scenario& scenario, const petri::Net& net,
                            const MotionPlan& plan, const SweepOptions& options = {}) const = 0;
};

}  // namespace cellwright::cell
