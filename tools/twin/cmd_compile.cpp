// `twin compile <program> [--json]`: compile a task-level program and print the primitive programs per robot (or
// their JSON form). Exit 0 on success, 2 on bad input (the message names file, line and column).
#include <cstdio>
#include <memory>
#include <string>

#include "cellwright/task/compile.hpp"
#include "commands.hpp"

namespace cellwright::tools {

void add_compile(CLI::App& app, Command* run) {
  struct Options {
    std::string program;
    bool json = false;
  };
  auto opts = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("compile", "Compile a task-level program to primitive robot programs");
  sub->add_option("program", opts->program, "task-level program file (.task)")->required();
  sub->add_flag("--json", opts->json, "print the compiled program as JSON instead of the listing");
  sub->callback([run, opts] {
    *run = [opts] {
      const task::CompiledProgram compiled = task::compile_file(opts->program);
      const std::string text =
          opts->json ? task::to_json(compiled).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n"
                     : task::format_listing(compiled);
      std::fwrite(text.data(), 1, text.size(), stdout);
      return std::fflush(stdout) == 0 ? 0 : 2;
    };
  });
}

}  // namespace cellwright::tools
