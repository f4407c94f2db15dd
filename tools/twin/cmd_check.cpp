// `twin check <program>`: compile a task-level program, build its Petri net and analyse it before anything runs.
#include <charconv>
#include <cstdint>
#include <iostream>
#include <string>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "commands.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

void add_check(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("check",
                                 "Compile a task program and check its Petri net for deadlocks, boundedness and "
                                 "mutual exclusion. Exit 0 only if all hold; 1 if not; 2 on bad input; 130 if "
                                 "interrupted (Ctrl-C).");
  struct Args {
    std::string program;
    bool json = false;
    std::uint64_t max_states = petri::AnalysisOptions{}.max_states;
    std::string reduction = "stubborn";
    std::uint64_t exploration_budget = petri::AnalysisOptions{}.exploration_budget;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("program", args->program, "task-level program (.task)")->required();
  cmd->add_flag("--json", args->json, "print the analysis as JSON");
  cmd->add_option("--max-states", args->max_states, "stop exploring beyond this many markings")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--reduction", args->reduction,
                  "which interleavings to explore: none (all) or stubborn (partial-order reduction); "
                  "default stubborn")
      ->check(CLI::IsMember({"none", "stubborn"}));
  cmd->add_option("--exploration-budget", args->exploration_budget,
                  "with --reduction stubborn: markings explored before the structural checks (place invariants, the "
                  "state equation) decide what the exploration has not; 0: no budget, explore up to --max-states; "
                  "default 10000")
      ->check(CLI::Validator(
          [](const std::string& value) -> std::string {
            std::uint64_t n = 0;
            const char* end = value.data() + value.size();
            const auto [ptr, ec] = std::from_chars(value.data(), end, n);
            if (value.empty() || ec != std::errc() || ptr != end) {
              return "'" + value + "' is not a whole number of markings, 0 or more (0: no budget)";
            }
            return {};
          },
          "N>=0"));
  cmd->callback([run, args] {
    *run = [args] {
      petri::CheckOptions options;
      options.analysis.max_states = args->max_states;
      options.analysis.reduction = petri::parse_reduction(args->reduction);
      options.analysis.exploration_budget = args->exploration_budget;
      options.progress = true;
      options.json = args->json;
      const petri::Net net = task::to_net(task::compile_file(args->program));
      return run_check_until_signal("twin check", [&](const std::atomic<bool>& stop) {
        options.analysis.stop = &stop;  // Ctrl-C ends the exploration cleanly
        return petri::check_and_report(net, args->program, options, std::cout);
      });
    };
  });
}

}  // namespace cellwright::tools
