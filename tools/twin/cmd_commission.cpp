// `twin commission SCENARIO --driver ROBOT=movemaster|val2:PORT ...`: reads each real controller back after homing,
// cross-checks it against the project's kinematics and proposes the robot's conventions (world frame, orientation
// reading) as the YAML to paste into the cell description (cell/rig's commissioning.hpp; docs/real-robots.md,
// "Commissioning"). Exit 0 when every robot was read and its settings agree or a proposal fits; 1 when not; 2 on bad
// input.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/common/error.hpp"
#include "commands.hpp"

namespace cellwright::tools {

void add_commission(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "commission",
      "Commission real controllers: connect, home, read the position back, cross-check it against the project's "
      "kinematics and propose the robot's conventions (val2:/movemaster: world_offset, world_rotation, orientation) "
      "as YAML for the cell description. Moves nothing but homing. Exit 0 when every robot was read and its settings "
      "agree or a proposal fits, 1 when not, 2 on bad input.");
  struct Args {
    std::string scenario;
    std::vector<std::string> drivers;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("scenario", args->scenario, "the scenario (its cell and program name the robots)")->required();
  cmd->add_option("--driver", args->drivers, "ROBOT=movemaster:PORT or ROBOT=val2:PORT (repeatable)");
  cmd->callback([run, args] {
    *run = [args] {
      cell::Scenario s = cell::load_scenario(args->scenario);
      for (const std::string& d : args->drivers) cell::set_driver(s, d, {"--driver", 0, 0});
      if (!cell::uses_real_drivers(s)) {
        throw InputError({"--driver", 0, 0}, "commissioning is for real drivers, and every robot of the program is "
                                             "simulated: give one with --driver ROBOT=movemaster:PORT or val2:PORT");
      }
      const cell::Commissioning c = cell::commission(s);
      std::printf("%s", cell::format_commissioning(c).c_str());
      return c.ok() ? 0 : 1;
    };
  });
}

}  // namespace cellwright::tools
