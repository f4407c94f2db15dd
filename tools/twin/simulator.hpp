// Whether this `twin` has the simulator (built with CW_SIM=ON, the default) and what the commands ask of it. A twin
// built for a cell of real robots only (CW_SIM=OFF) links no MuJoCo, OSMesa or Assimp: it checks, compiles and
// analyses programs and brings real robots up (`twin run --dry`), and refuses the commands that need the twin with
// an error that says so (exit 2).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "cellwright/cell/twin_port.hpp"
#include "commands.hpp"

namespace cellwright::tools {

// The simulator as the plan's port (collision sweep, estimate), or null in a build without it.
const cell::TwinPort* simulator();

// "MuJoCo 2.2.2", or "no simulator (CW_SIM=OFF)".
std::string simulator_version();

// Throws InputError naming `what` (a command or an option) and saying that this twin was built without the simulator.
[[noreturn]] void needs_simulator(const std::string& what);

// Registers `name` as a command this build cannot run: its callback throws needs_simulator; any argument is taken.
void add_unavailable(CLI::App& app, Command* run, const std::string& name, const std::string& description);

}  // namespace cellwright::tools
