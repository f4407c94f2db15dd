// What the plan stage asks of the simulator a scenario will run on, without linking it (the walls test keeps MuJoCo
// out of cell/ but for cell/sim): a sweep of the motion plan for collisions, and the cycle-time estimate with the
// twin's robots' timing. cell/sim implements it (cell/sim/sweep.hpp: twin_port()); a `twin` built without the
// simulator (CW_SIM=OFF) has none, and its callers say what was not done.
//
// Thread safety: implementations are const and may be used from any thread.
#pragma once

#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"

namespace cellwright::cell {

class TwinPort : public CollisionSweep {
 public:
  // The estimate of `scenario`'s cycle time (estimate.hpp) with the timing of the twin's robots, grippers and belts,
  // from preflight's net and motion plan (`preflight` is preflight(scenario, this), which planned: InternalError if
  // it has no plan) on its compiled cell (Preflight::twin; compiled here when it has none). Builds no run. Throws
  // InputError if the simulator rejects the cell.
  virtual Estimate estimate(const Scenario& scenario, const Preflight& preflight) const = 0;
};

}  // namespace cellwright::cell
