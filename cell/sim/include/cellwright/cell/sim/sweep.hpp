// The plan's collision sweep (cell/sweep.hpp) in the twin: each pose of a swept motion is set on a copy of the cell's
// MuJoCo scene (scene.hpp, built once per sweep) and MuJoCo's collision detection (mj_kinematics + mj_collision, with
// the scene's own collision filters) finds the contacts deeper than SweepOptions::depth.
//
// Thread safety: sweep_motions is a pure function of its arguments (it builds its own scene); any thread may call it,
// and TwinSweep's sweep() with it.
#pragma once

#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"
#include "cellwright/cell/twin_port.hpp"
#include "cellwright/petri/net.hpp"

namespace cellwright::cell {

// Sweeps the plan of `scenario`'s program (`net` is its task::to_net, `plan` its plan_motions) as cell/sweep.hpp
// says. Throws InputError as twin::build_scene does (a URDF that cannot be read), and twin::start_overlap_error when
// robots overlap at the start.
SweepReport sweep_motions(const Scenario& scenario, const petri::Net& net, const MotionPlan& plan,
                          const SweepOptions& options = {});

// The twin as the plan's port: sweep_motions, and the estimate with the timing of the simulation drivers the run
// would build (ScenarioRun's).
class SimulatedTwin final : public TwinPort {
 public:
  SweepReport sweep(const Scenario& scenario, const petri::Net& net, const MotionPlan& plan,
                    const SweepOptions& options = {}) const override;
  Estimate estimate(const Scenario& scenario, const petri::Net& net) const override;
};

// One SimulatedTwin, for the callers of the plan that have the twin.
const TwinPort& twin_port();

}  // namespace cellwright::cell
