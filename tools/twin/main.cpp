// `twin`: the Cellwright command line. Thin: it dispatches to the subcommands in cmd_*.cpp.
#include <malloc.h>

#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "cellwright/common/error.hpp"
#include "commands.hpp"
#include "simulator.hpp"
#include "version.hpp"

namespace {

// "twin 0.1.0 (MuJoCo 2.2.2)": the project's version from CMake, and the MuJoCo library's, which decides the physics
// ("no simulator (CW_SIM=OFF)" in a build for real robots only).
std::string version_text() {
  return fmt::format("twin {} ({})", CELLWRIGHT_VERSION, cellwright::tools::simulator_version());
}

}  // namespace

int main(int argc, char** argv) {
  // Large blocks from the heap, and the heap kept: every mjData (3.7 MB with the cell's buffers) would otherwise be
  // a fresh mmap, each of its pages a page fault when MuJoCo clears it, and a run makes about seven (the compiler's
  // own, the preflight's scene and its sweep, the run's). Kept, the next one reuses the freed pages: about 1,000 page
  // faults and about 3 % of a lock-step run's CPU less (docs/simulation.md). 32 MB is glibc's largest mmap threshold.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  CLI::App app{"twin: Cellwright cell controller and digital twin for multi-robot workcells. Every command exits 0 on "
               "success, 1 when its input was processed and the verdict is negative, 2 on bad input or usage, 130 when "
               "an analysis (check, analyze) is interrupted with Ctrl-C (its --help says which)."};
  app.require_subcommand(1);
  app.set_version_flag("--version", version_text(), "print the version of twin and of MuJoCo, and exit");
  cellwright::tools::Command run;
  cellwright::tools::add_compile(app, &run);
  cellwright::tools::add_check(app, &run);
  cellwright::tools::add_analyze(app, &run);
  cellwright::tools::add_snapshot(app, &run);
  cellwright::tools::add_run(app, &run);
  cellwright::tools::add_step(app, &run);
  cellwright::tools::add_serve(app, &run);
  cellwright::tools::add_emulate(app, &run);
  cellwright::tools::add_campaign(app, &run);
  cellwright::tools::add_test(app, &run);
  cellwright::tools::add_commission(app, &run);
  cellwright::tools::add_calibrate(app, &run);
  cellwright::tools::add_agent(app, &run);
  // A first word that is no option and no command is a mistyped command: say so (CLI11 would call it an unexpected
  // argument).
  if (argc > 1 && argv[1][0] != '-') {
    std::string names;
    bool known = false;
    for (const CLI::App* sub : app.get_subcommands({})) {
      known = known || sub->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      std::fprintf(stderr, "twin: unknown command '%s' (commands: %s; twin --help tells more)\n", argv[1],
                   names.c_str());
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  try {
    // --out, the old name of -o/--output, is still accepted; both at once are refused rather than one silently winning.
    for (CLI::App* sub : app.get_subcommands()) {
      if (sub->get_option_no_throw("--out") != nullptr && sub->count("--out") > 0 && sub->count("--output") > 0) {
        throw cellwright::InputError({"--out", 0, 0}, "the old name of -o/--output, given with it: give one of them");
      }
    }
    return run ? run() : 2;
  } catch (const cellwright::InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "twin: error: %s\n", e.what());
    return 2;
  }
}
