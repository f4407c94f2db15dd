// `twin analyze <net.pnml>`: read a Petri net from PNML (written by Cellwright or by TINA, PIPE, LoLA/MCC, ePNK) and
// analyse its reachability graph: deadlocks, boundedness, dead transitions, mutual exclusion of critical regions.
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/dot.hpp"
#include "cellwright/petri/pnml.hpp"
#include "commands.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

void add_analyze(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("analyze",
                                 "Analyse a Petri net read from a PNML file: deadlocks, boundedness, dead transitions, "
                                 "mutual exclusion. Exit 0 only if it is deadlock-free, bounded, mutually exclusive "
                                 "and fully explored; 1 if not; 2 on bad input; 130 if interrupted (Ctrl-C).");
  struct Args {
    std::string net;
    bool json = false;
    std::uint64_t max_states = petri::AnalysisOptions{}.max_states;
    std::string reduction = "none";
    std::string dot;
    std::string net_id;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("net", args->net, "P/T net in PNML (.pnml)")->required();
  cmd->add_flag("--json", args->json, "print the analysis as JSON");
  cmd->add_option("--max-states", args->max_states, "stop exploring beyond this many markings (then exit 1)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--reduction", args->reduction,
                  "which interleavings to explore: none (all) or stubborn (partial-order reduction); "
                  "default none")
      ->check(CLI::IsMember({"none", "stubborn"}));
  cmd->add_option("--dot", args->dot, "also write the net as Graphviz DOT to this file");
  cmd->add_option("--net-id", args->net_id, "the id of the <net> to read when the file holds several (default: first)");
  cmd->callback([run, args] {
    *run = [args] {
      petri::PnmlReadOptions read;
      read.net_id = args->net_id;
      const petri::PnmlDocument doc = petri::read_pnml_document(args->net, read);
      if (doc.net_ids.size() > 1 && args->net_id.empty()) {
        // Not an error (taking the first net is the common convention), but the user should know.
        std::string ids;
        for (const std::string& id : doc.net_ids) ids += (ids.empty() ? "'" : ", '") + id + "'";
        std::fprintf(stderr, "%s: note: the file holds %zu nets (%s); analysing the first (choose with --net-id)\n",
                     args->net.c_str(), doc.net_ids.size(), ids.c_str());
      }
      if (!args->dot.empty()) petri::write_dot(doc.net, args->dot);
      petri::CheckOptions options;
      options.analysis.max_states = args->max_states;
      options.analysis.reduction = petri::parse_reduction(args->reduction);
      options.progress = true;
      options.json = args->json;
      return run_check_until_signal("twin analyze", [&](const std::atomic<bool>& stop) {
        options.analysis.stop = &stop;  // Ctrl-C ends the exploration cleanly
        return petri::check_and_report(doc.net, args->net, options, std::cout);
      });
    };
  });
}

}  // namespace cellwright::tools
