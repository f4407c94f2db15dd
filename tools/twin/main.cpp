// `twin`: the Cellwright command line. Thin: it dispatches to the subcommands in cmd_*.cpp.
#include <cstdio>
#include <exception>

#include "cellwright/common/error.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"twin: Cellwright cell controller and digital twin for multi-robot workcells"};
  app.require_subcommand(1);
  cellwright::tools::Command run;
  cellwright::tools::add_compile(app, &run);
  cellwright::tools::add_check(app, &run);
  cellwright::tools::add_analyze(app, &run);
  cellwright::tools::add_snapshot(app, &run);
  cellwright::tools::add_run(app, &run);
  cellwright::tools::add_step(app, &run);
  cellwright::tools::add_emulate(app, &run);
  cellwright::tools::add_campaign(app, &run);
  cellwright::tools::add_test(app, &run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  try {
    return run ? run() : 2;
  } catch (const cellwright::InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "twin: error: %s\n", e.what());
    return 2;
  }
}
