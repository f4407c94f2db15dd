// `twin compile <program> [--json] [--dot] [--pnml FILE]`: compile a task-level program and print the primitive
// programs per robot (or their JSON form, or the Petri net as Graphviz DOT), optionally writing the net as PNML.
// Exit 0 on success, 2 on bad input (the message names file, line and column).
#include <cstdio>
#include <memory>
#include <string>

#include "cellwright/petri/dot.hpp"
#include "cellwright/petri/pnml.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "commands.hpp"

namespace cellwright::tools {

void add_compile(CLI::App& app, Command* run) {
  struct Options {
    std::string program;
    bool json = false;
    bool dot = false;
    std::string pnml;
  };
  auto opts = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("compile", "Compile a task-level program to primitive robot programs");
  sub->add_option("program", opts->program, "task-level program file (.task)")->required();
  sub->add_flag("--json", opts->json, "print the compiled program as JSON instead of the listing");
  sub->add_flag("--dot", opts->dot, "print the program's Petri net as Graphviz DOT (e.g. | dot -Tsvg > net.svg)");
  sub->add_option("--pnml", opts->pnml, "also write the Petri net to this PNML file (ISO/IEC 15909-2 P/T net)");
  sub->get_option("--dot")->excludes("--json");
  sub->callback([run, opts] {
    *run = [opts] {
      const task::CompiledProgram compiled = task::compile_file(opts->program);
      std::string text;
      if (opts->dot || !opts->pnml.empty()) {
        const petri::Net net = task::to_net(compiled);
        if (!opts->pnml.empty()) petri::write_pnml(net, opts->pnml);
        if (opts->dot) {
          petri::DotOptions dot;
          dot.cluster_per_robot = true;
          dot.marking = net.initial_marking();
          text = petri::to_dot(net, dot);
        }
      }
      if (!opts->dot) {
        text = opts->json ? task::to_json(compiled).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n"
                          : task::format_listing(compiled);
      }
      std::fwrite(text.data(), 1, text.size(), stdout);
      return std::fflush(stdout) == 0 ? 0 : 2;
    };
  });
}

}  // namespace cellwright::tools
