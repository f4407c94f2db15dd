// Subcommands of the `twin` executable. Each lives in its own cmd_<name>.cpp, parses its arguments with CLI11 and
// calls the libraries; none holds logic of its own.
//
// Each add_* function registers the subcommand on `app` and returns the code the subcommand will run. The callback
// returns the process exit status: 0 success, 1 the input was processed but the verdict is negative (a check
// failed, an outcome did not hold), 2 bad input or usage.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace cellwright::tools {

using Command = std::function<int()>;

// Sets *run to the command's action when its subcommand is parsed.
void add_compile(CLI::App& app, Command* run);
void add_check(CLI::App& app, Command* run);
void add_analyze(CLI::App& app, Command* run);
void add_snapshot(CLI::App& app, Command* run);
void add_run(CLI::App& app, Command* run);
void add_step(CLI::App& app, Command* run);
void add_serve(CLI::App& app, Command* run);
void add_emulate(CLI::App& app, Command* run);
void add_commission(CLI::App& app, Command* run);
void add_campaign(CLI::App& app, Command* run);
void add_test(CLI::App& app, Command* run);
void add_calibrate(CLI::App& app, Command* run);
void add_agent(CLI::App& app, Command* run);

}  // namespace cellwright::tools
