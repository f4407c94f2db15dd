// The plan's collision sweep (cell/sweep.hpp) in the twin: each pose of a swept motion is set on its own data of the
// cell's compiled MuJoCo scene (scene.hpp) and MuJoCo finds the contacts deeper than SweepOptions::depth. MuJoCo's
// kinematics (mj_kinematics) poses each sample once and the sweep keeps where it put the moving robot's collision
// geoms and its part; MuJoCo's narrow phase (its collision functions, mjCOLLISIONFUNC) then tests only the pairs of
// geoms whose contacts count (the moving robot and its part against the static cell; two robots' against each
// other), with mj_collision's own filters (contype/conaffinity, weld and parent bodies, the scene's <exclude>s, the
// bounding-sphere and plane tests, the larger margin) and in mj_collision's order: the same contacts, bit for bit, as
// a full mj_collision of the posed scene gives for those pairs, without testing every other pair of the scene at
// every pose (mj_collision also stops at the scene's nconmax contacts in all; the sweep's pairs never are). And the
// twin as the plan's port
// (cell/twin_port.hpp): it compiles a scenario's cell once (TwinModel), sweeps on it, and estimates on it from the
// preflight's plan with the simulation drivers' timing, building no run.
//
// Thread safety: sweep_motions is a pure function of its arguments (it makes its own mjData); any thread may call
// it, and SimulatedTwin's methods with it.
#pragma once

#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"
#include "cellwright/cell/twin_port.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/twin/scene.hpp"

namespace cellwright::cell {

// The twin's compiled model of a scenario's cell (declared for the plan by cell/sweep.hpp, which carries it from the
// preflight's sweep to the estimate and the run): compile_cell's scene (run.hpp), reset and never stepped; its users
// take their own data (Scene::share()) or, as the sweep, make their own mjData.
struct TwinModel {
  twin::Scene scene;
};

// Sweeps the plan of `scenario`'s program (`net` is its task::to_net, `plan` its plan_motions) as cell/sweep.hpp
// says, on `scene` (the cell compiled: compile_cell or twin::build_scene of the scenario's cell; the sweep parks
// the parts it does not carry and ignores the fault injection's obstacles, so either gives the same report). Throws
// twin::start_overlap_error when robots overlap at the start.
SweepReport sweep_motions(const twin::Scene& scene, const Scenario& scenario, const petri::Net& net,
                          const MotionPlan& plan, const SweepOptions& options = {});
// The same on the scenario's cell compiled here; also throws InputError as twin::build_scene does (a URDF that cannot
// be read).
SweepReport sweep_motions(const Scenario& scenario, const petri::Net& net, const MotionPlan& plan,
                          const SweepOptions& options = {});

// The twin as the plan's port: compile() is compile_cell (run.hpp), the cell as a run of the scenario has it;
// sweep() is sweep_motions on it; estimate() is estimate_cycle_time of the preflight's net and plan with
// twin_estimate_options (run.hpp: the timing ScenarioRun gives the estimate too) on the preflight's compiled cell,
// building no run, World, driver or renderer.
class SimulatedTwin final : public TwinPort {
 public:
  std::shared_ptr<const TwinModel> compile(const Scenario& scenario) const override;
  SweepReport sweep(const TwinModel& model, const Scenario& scenario, const petri::Net& net, const MotionPlan& plan,
                    const SweepOptions& options = {}) const override;
  Estimate estimate(const Scenario& scenario, const Preflight& preflight) const override;
};

// One SimulatedTwin, for the callers of the plan that have the twin.
const TwinPort& twin_port();

}  // namespace cellwright::cell
