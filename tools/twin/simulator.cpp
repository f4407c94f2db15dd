// Whether this `twin` has the simulator (simulator.hpp).
#include "simulator.hpp"

#include <fmt/format.h>

#include "cellwright/common/error.hpp"

#if CW_SIM
#include <mujoco/mujoco.h>

#include "cellwright/cell/sim/sweep.hpp"
#endif

namespace cellwright::tools {

const cell::TwinPort* simulator() {
#if CW_SIM
  return &cell::twin_port();
#else
  return nullptr;
#endif
}

std::string simulator_version() {
#if CW_SIM
  const int mj = mj_version();
  return fmt::format("MuJoCo {}.{}.{}", mj / 100, mj / 10 % 10, mj % 10);
#else
  return "no simulator (CW_SIM=OFF)";
#endif
}

void needs_simulator(const std::string& what) {
  throw InputError({what, 0, 0}, "needs the simulator, and this twin was built without it (CW_SIM=OFF, for a cell "
                                 "of real robots only): build with -DCW_SIM=ON");
}

void add_unavailable(CLI::App& app, Command* run, const std::string& name, const std::string& description) {
  auto* cmd = app.add_subcommand(name, description + " (needs the simulator: not in this build, CW_SIM=OFF)");
  cmd->allow_extras();
  cmd->callback([run, name] { *run = [name]() -> int { needs_simulator("twin " + name); }; });
}

}  // namespace cellwright::tools
