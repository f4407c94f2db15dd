// `twin compile <program> [--json] [--dot] [--pnml FILE]`: compile a task-level program and print the primitive
// programs per robot (or their JSON form, or the Petri net as Graphviz DOT), optionally writing the net as PNML.
// `twin compile <program> --scenario SCENARIO --robot-language -o DIR [--driver ROBOT=movemaster|val2]...`: write
// each robot's program in its controller's language (cell/plan/robot_programs.hpp), once the net passed the
// preflight, into a directory that is new, empty or Cellwright's (outputs.hpp; --force for one of the user's own).
// Exit 0 on success, 2 on bad input (the message names file, line and column).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/dot.hpp"
#include "cellwright/petri/pnml.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/robot_programs.hpp"
#include "cellwright/cell/scenario.hpp"
#include "commands.hpp"
#include "simulator.hpp"

namespace cellwright::tools {

namespace {

// --robot-language: the scenario's robots in their controllers' languages, written into the output directory.
template <typename Options>
int write_robot_programs(const Options& o) {
  using namespace cell;
  if (o.out.empty()) throw InputError({"--robot-language", 0, 0}, "needs -o/--output DIR for the robot programs");
  Scenario s = load_scenario(o.scenario);
  std::error_code ec;
  if (!std::filesystem::equivalent(o.program, s.program_file, ec)) {
    throw InputError({o.scenario, 0, 0},
                     fmt::format("the scenario runs {}, not {}", s.program_file.string(), o.program));
  }
  for (const std::string& d : o.drivers) cell::set_language(s, d, {"--driver", 0, 0});
  const Preflight pre = preflight(s, simulator());
  if (!pre.ok()) {
    std::fprintf(stderr, "%s: refused, no robot program was written:\n", o.scenario.c_str());
    for (const std::string& p : pre.problems) std::fprintf(stderr, "  %s\n", p.c_str());
    if (!pre.analysis.ok()) {
      std::fprintf(stderr, "%s: %s", s.program_file.string().c_str(),
                   petri::format_report(pre.net, pre.analysis).c_str());
    }
    return 2;
  }
  const cell::RobotPrograms programs = cell::generate_robot_programs(s, pre);
  // A directory of the user's own is not written over unasked (outputs.hpp): checked with the programs' own names,
  // before anything is written, then marked as Cellwright's.
  std::vector<std::string> files;
  for (const cell::RobotProgram& p : programs.robots) files.push_back(p.file_name);
  cell::check_output_directory(o.out, files, o.force);
  cell::make_output_directory(o.out);
  cell::write_robot_programs(programs, o.out);
  std::printf("net: %s\n", programs.check.c_str());
  if (simulator() == nullptr) std::printf("%s\n", pre.sweep_summary.c_str());  // nothing swept: say so
  for (const cell::RobotProgram& p : programs.robots) {
    std::printf("%s (%s): %s/%s\n", p.cell_robot.c_str(), p.robot.c_str(), o.out.c_str(), p.file_name.c_str());
  }
  for (const cell::IoChannel& c : programs.channels) {
    std::printf("I/O %d: %s, %s -> %s\n", c.channel, c.event.c_str(), s.robot_of(c.from).c_str(),
                s.robot_of(c.to).c_str());
  }
  return std::fflush(stdout) == 0 ? 0 : 2;
}

}  // namespace

void add_compile(CLI::App& app, Command* run) {
  struct Options {
    std::string program;
    bool json = false;
    bool dot = false;
    std::string pnml;
    std::string scenario;
    bool robot_language = false;
    std::string out;
    bool force = false;
    std::vector<std::string> drivers;
  };
  auto opts = std::make_shared<Options>();
  CLI::App* sub = app.add_subcommand("compile",
                                     "Compile a task-level program to primitive robot programs. Exit 0 on success; 2 "
                                     "on bad input (with --robot-language also when the program fails the check).");
  sub->add_option("program", opts->program, "task-level program file (.task)")->required();
  sub->add_flag("--json", opts->json, "print the compiled program as JSON instead of the listing");
  sub->add_flag("--dot", opts->dot, "print the program's Petri net as Graphviz DOT (e.g. | dot -Tsvg > net.svg)");
  sub->add_option("--pnml", opts->pnml, "also write the Petri net to this PNML file (ISO/IEC 15909-2 P/T net)");
  sub->add_option("--scenario", opts->scenario, "the scenario that runs the program (cell, bindings, drivers)");
  sub->add_flag("--robot-language", opts->robot_language,
                "write each robot's program in its controller's language (Movemaster EX, VAL II) into -o DIR");
  sub->add_option("-o,--output", opts->out, "directory for the robot programs (created if needed)");
  sub->add_flag("--force", opts->force,
                "write the robot programs into -o DIR even when it is a directory of your own that holds files of "
                "the same names");
  // The old name, for scripts written before the options were made the same everywhere; not shown in --help.
  sub->add_option("--out", opts->out)->group("");
  sub->add_option("--driver", opts->drivers,
                  "write a robot's program in another language than the scenario's: ROBOT=movemaster or ROBOT=val2 "
                  "(repeatable; a :PORT after it is ignored)");
  sub->get_option("--dot")->excludes("--json");
  for (const char* o : {"--json", "--dot", "--pnml"}) sub->get_option("--robot-language")->excludes(o);
  sub->get_option("--robot-language")->needs("--scenario");
  sub->get_option("--scenario")->needs("--robot-language");
  sub->get_option("--driver")->needs("--robot-language");
  sub->get_option("--force")->needs("--robot-language");
  sub->callback([run, opts] {
    *run = [opts] {
      if (opts->robot_language) return write_robot_programs(*opts);
      // Checked here rather than with CLI11's needs(): the option has two names, and the message should name both.
      if (!opts->out.empty()) {
        throw InputError({"-o/--output", 0, 0},
                         "the output directory is for --robot-language (the robot programs); the listing, --json and "
                         "--dot go to standard output, the net to --pnml FILE");
      }
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
