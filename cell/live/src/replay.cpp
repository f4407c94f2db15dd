#include "cellwright/cell/live/replay.hpp"

#include <nlohmann/json.hpp>

#include "cellwright/cell/estimate.hpp"

namespace cellwright::cell {

CheckOutcome check_program(const petri::Net& net) {
  // The preflight's check (preflight.cpp): stubborn-set reduction, whose verdicts are full exploration's.
  petri::AnalysisOptions options;
  options.reduction = petri::Reduction::kStubborn;
  return check_outcome(net, petri::analyze(net, options));
}

CheckOutcome check_outcome(const petri::Net& net, const petri::AnalysisResult& r) {
  CheckOutcome out;
  out.ok = r.ok();
  const std::string report = petri::format_report(net, r);
  out.summary = report.substr(0, report.find('\n'));
  const petri::Deadlock* witness = nullptr;
  if (r.deadlocks > 0 && !r.deadlock_examples.empty()) {
    out.property = "deadlock";
    witness = &r.deadlock_examples.front();
  } else if (!r.bounded) {
    out.property = "boundedness";
    if (r.unbounded_witness) witness = &*r.unbounded_witness;
  } else if (!r.mutex_ok) {
    out.property = "mutual_exclusion";
    for (const petri::RegionCheck& c : r.regions) {
      if (!c.exclusive && c.witness) {
        witness = &*c.witness;
        break;
      }
    }
  }
  if (witness) {
    out.counterexample = witness->path;
    out.last_marking = petri::describe_marking(net, witness->marking);
  }
  return out;
}

std::string check_json(const petri::Net& net, const CheckOutcome& c) {
  nlohmann::json steps = nlohmann::json::array();
  for (const petri::TransitionId t : c.counterexample) {
    const petri::Transition& tr = net.transitions()[t];
    std::string text = petri::describe_path(net, {t});  // "1. r1 line 2 'wait s1' ...": one step, unnumbered
    if (text.rfind("1. ", 0) == 0) text.erase(0, 3);
    steps.push_back({{"transition", text}, {"line", tr.origin.line}, {"robot", tr.origin.robot}});
  }
  return nlohmann::json{{"type", "check"},
                        {"ok", c.ok},
                        {"summary", c.summary},
                        {"property", c.property},
                        {"counterexample", steps},
                        {"dead_marking", c.last_marking}}
      .dump();
}

std::optional<Preflight> counterexample_preflight(const Scenario& scenario, const Preflight& refused) {
  if (refused.analysis.ok()) return std::nullopt;  // refused for something else (or not refused)
  Preflight p = refused;
  runtime::TargetOptions targets;
  targets.handover_clearance = scenario.options.handover_clearance;
  p.plan = plan_motions(scenario, p.net, targets);
  return p;
}

}  // namespace cellwright::cell
