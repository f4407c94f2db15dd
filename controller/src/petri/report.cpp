// Analysis results told in the task program's terms (analysis.hpp): firing sequences, markings, the human report and
// the JSON report.
#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <iostream>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/petri/analysis.hpp"

namespace cellwright::petri {

namespace {

const std::string& label(const Place& p) {
  return p.name.empty() ? p.id : p.name;
}
const std::string& label(const Transition& t) {
  return t.name.empty() ? t.id : t.name;
}

// " (line 7 'Put r2')", or "" when the origin names no command.
std::string where(const Origin& o) {
  std::string s;
  if (o.line > 0) s = fmt::format("line {}", o.line);
  if (!o.task.empty()) s += (s.empty() ? "'" : " '") + o.task + "'";
  return s.empty() ? s : " (" + s + ")";
}

bool robot_place(const Place& p) {
  return !p.origin.robot.empty();
}

// What a waiting robot waits for: the shared places that the transitions leaving its place also consume from.
std::string awaited(const Net& net, PlaceId waiting) {
  std::vector<std::string> names;
  for (const Transition& t : net.transitions()) {
    const bool leaves = std::any_of(t.inputs.begin(), t.inputs.end(), [&](const Arc& a) { return a.place == waiting; });
    if (!leaves) continue;
    for (const Arc& a : t.inputs) {
      const Place& p = net.places()[a.place];
      if (a.place == waiting || robot_place(p)) continue;
      if (std::find(names.begin(), names.end(), label(p)) == names.end()) names.push_back(label(p));
    }
  }
  return fmt::format("{}", fmt::join(names, " and "));
}

std::string robot_state(const Net& net, PlaceId id) {
  const Place& p = net.places()[id];
  switch (p.kind) {
    case PlaceKind::kStart:
      return "not started";
    case PlaceKind::kDone:
      return "done";
    case PlaceKind::kExecuting:
      return "executing " + (p.origin.motion.empty() ? label(p) : p.origin.motion) + where(p.origin);
    case PlaceKind::kWaiting: {
      const std::string what = awaited(net, id);
      return (what.empty() ? label(p) : "waiting for " + what) + where(p.origin);
    }
    case PlaceKind::kPlain:
    case PlaceKind::kEvent:
    case PlaceKind::kRegion:
      break;
  }
  return "at " + label(p) + where(p.origin);
}

std::string count_suffix(Tokens n) {
  return n == 1 ? std::string() : fmt::format(" (x{})", n);
}

nlohmann::json path_json(const Net& net, const std::vector<TransitionId>& path) {
  nlohmann::json steps = nlohmann::json::array();
  for (TransitionId t : path) {
    const Transition& tr = net.transitions()[t];
    steps.push_back({{"transition", tr.id},
                     {"name", tr.name},
                     {"robot", tr.origin.robot},
                     {"line", tr.origin.line},
                     {"task", tr.origin.task},
                     {"motion", tr.origin.motion}});
  }
  return steps;
}

nlohmann::json marking_json(const Net& net, const Marking& m) {
  nlohmann::json obj = nlohmann::json::object();
  for (std::size_t p = 0; p < m.size(); ++p) {
    if (m[p] != 0) obj[net.places()[p].id] = m[p];
  }
  return obj;
}

std::string indent(const std::string& text, const std::string& by) {
  std::string out = by;
  for (char c : text) {
    out += c;
    if (c == '\n') out += by;
  }
  return out;
}

std::string plural(std::uint64_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

}  // namespace

std::string describe_path(const Net& net, const std::vector<TransitionId>& path) {
  if (path.empty()) return "(no firing: the initial marking)";
  std::string out;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const Transition& t = net.transitions().at(path[i]);
    const Origin& o = t.origin;
    std::string head = o.robot;
    if (o.line > 0) head += fmt::format("{}line {}", head.empty() ? "" : " ", o.line);
    if (!o.task.empty()) head += (head.empty() ? "'" : " '") + o.task + "'";
    if (!o.motion.empty()) head += (head.empty() ? "(" : " (") + o.motion + ")";
    if (i > 0) out += '\n';
    out += fmt::format("{}. {}{}", i + 1, head.empty() ? "" : head + ": ", label(t));
  }
  return out;
}

std::string describe_marking(const Net& net, const Marking& m) {
  std::vector<std::string> parts;
  // Robots first, in the net's robot order, then robots the net does not list (hand-made nets).
  std::vector<std::string> robots = net.robots();
  for (const Place& p : net.places()) {
    if (robot_place(p) && std::find(robots.begin(), robots.end(), p.origin.robot) == robots.end()) {
      robots.push_back(p.origin.robot);
    }
  }
  for (const std::string& robot : robots) {
    std::vector<std::string> states;
    for (std::size_t p = 0; p < m.size(); ++p) {
      if (m[p] != 0 && net.places()[p].origin.robot == robot) {
        states.push_back(robot_state(net, static_cast<PlaceId>(p)) + count_suffix(m[p]));
      }
    }
    if (!states.empty()) parts.push_back(fmt::format("{}: {}", robot, fmt::join(states, ", ")));
  }
  for (std::size_t p = 0; p < m.size(); ++p) {
    const Place& pl = net.places()[p];
    if (m[p] == 0 || robot_place(pl)) continue;
    switch (pl.kind) {
      case PlaceKind::kRegion:
        break;  // a free region says nothing a reader needs; the robots inside are listed above
      case PlaceKind::kEvent:
        parts.push_back(fmt::format("pending: {}{}", label(pl), count_suffix(m[p])));
        break;
      default:
        parts.push_back(fmt::format("{}: {}", label(pl), m[p]));
        break;
    }
  }
  if (parts.empty()) return "(no tokens)";
  return fmt::format("{}", fmt::join(parts, "; "));
}

std::string format_report(const Net& net, const AnalysisResult& r) {
  std::vector<std::string> problems;
  if (r.deadlocks > 0) {
    problems.push_back(r.deadlocks_counted ? plural(r.deadlocks, "deadlock", "deadlocks") : std::string("deadlock"));
  }
  if (!r.bounded) problems.push_back("unbounded");
  for (const RegionCheck& rc : r.regions) {
    if (!rc.exclusive) problems.push_back(fmt::format("region {} not exclusive", rc.name));
  }
  std::string out;
  if (!problems.empty()) {
    out = fmt::format("FAIL: {}{}\n", fmt::join(problems, ", "), r.complete ? "" : " (exploration stopped early)");
  } else if (!r.complete) {
    out = "UNKNOWN: exploration stopped early; no problem found so far\n";
  } else {
    out = net.regions().empty() ? "OK: no deadlock, bounded\n" : "OK: no deadlock, bounded, mutual exclusion holds\n";
  }
  if (r.reduced) {
    out += fmt::format("{} explored (reduced), {}", plural(r.states, "marking", "markings"),
                       plural(r.edges, "edge", "edges"));
  } else {
    out += fmt::format("explored {}, {}", plural(r.states, "marking", "markings"), plural(r.edges, "edge", "edges"));
  }
  // Proper ends only mean something when the net declares its final marking.
  if (!net.final_places().empty()) out += ", " + plural(r.final_states, "proper end", "proper ends");
  if (r.complete) {
    out += r.explored_all ? " (complete)\n" : "; exploration stopped at its budget, the rest decided from the net's structure\n";
  } else {
    out += fmt::format("; stopped: {}\n", r.stop_reason);
  }
  if (!r.deadlock_proof.empty()) out += (r.deadlocks == 0 ? "no deadlock: " : "deadlock ") + r.deadlock_proof + "\n";
  if (!r.net_reduction.empty()) out += r.net_reduction + "\n";
  if (!r.reduction_note.empty())
    out += fmt::format("reduction {} not applied: {}\n", to_string(r.reduction), r.reduction_note);

  if (!r.deadlock_examples.empty()) {
    const Deadlock& d = r.deadlock_examples.front();
    out += fmt::format("deadlock after {}{}:\n", plural(d.path.size(), "firing", "firings"),
                       r.deadlock_path_shortest ? "" : " (not necessarily shortest)");
    out += indent(describe_path(net, d.path), "  ") + "\n";
    out += "  stuck: " + describe_marking(net, d.marking) + "\n";
  }
  if (r.unbounded_witness) {
    out += fmt::format("unbounded, grows after {}:\n", plural(r.unbounded_witness->path.size(), "firing", "firings"));
    out += indent(describe_path(net, r.unbounded_witness->path), "  ") + "\n";
  }
  for (std::size_t k = 0; k < r.regions.size(); ++k) {
    const RegionCheck& rc = r.regions[k];
    const Tokens cap = k < net.regions().size() ? net.regions()[k].capacity : 1;
    if (rc.exclusive) {
      if (rc.by_invariant) {
        out += fmt::format("region {}: exclusive, by a place invariant (never more than {} inside, capacity {}; at most {} "
                           "seen)\n",
                           rc.name, rc.invariant_bound, cap, rc.max_inside);
      } else {
        out += fmt::format("region {}: exclusive{} (at most {} inside, capacity {})\n", rc.name,
                           r.complete ? "" : " so far", rc.max_inside, cap);
      }
    } else {
      out += fmt::format("region {}: {} inside at once (capacity {})", rc.name, rc.max_inside, cap);
      if (rc.witness) {
        if (rc.witness_shortest) {
          out += fmt::format(", first after {}:\n", plural(rc.witness->path.size(), "firing", "firings"));
        } else {
          out += fmt::format(", after {} (not necessarily shortest):\n",
                             plural(rc.witness->path.size(), "firing", "firings"));
        }
        out += indent(describe_path(net, rc.witness->path), "  ") + "\n";
        out += "  then: " + describe_marking(net, rc.witness->marking) + "\n";
      } else {
        out += "\n";
      }
    }
  }
  if (r.complete && !r.reduced && !r.dead_transitions.empty()) {
    std::vector<std::string> ids;
    constexpr std::size_t kShown = 10;
    for (std::size_t i = 0; i < r.dead_transitions.size() && i < kShown; ++i) {
      ids.push_back(net.transitions()[r.dead_transitions[i]].id);
    }
    out +=
        fmt::format("never enabled: {}{}\n", fmt::join(ids, ", "),
                    r.dead_transitions.size() > kShown ? fmt::format(" and {} more", r.dead_transitions.size() - kShown)
                                                       : std::string());
  }
  return out;
}

nlohmann::json to_json(const Net& net, const AnalysisResult& r) {
  nlohmann::json j;
  j["ok"] = r.ok();
  j["complete"] = r.complete;
  j["stop_reason"] = r.stop_reason;
  j["states"] = r.states;
  j["edges"] = r.edges;
  j["deadlocks"] = r.deadlocks;
  j["final_states"] = r.final_states;
  j["bounded"] = r.bounded;
  j["mutex_ok"] = r.mutex_ok;
  j["stored_bytes"] = r.stored_bytes;
  j["reduction"] = to_string(r.reduction);
  j["reduced"] = r.reduced;
  j["reduction_note"] = r.reduction_note;
  j["net_reduction"] = r.net_reduction;
  j["deadlock_path_shortest"] = r.deadlock_path_shortest;
  j["explored_all"] = r.explored_all;
  j["deadlock_proof"] = r.deadlock_proof;
  j["deadlocks_counted"] = r.deadlocks_counted;

  nlohmann::json unbounded = nlohmann::json::array();
  for (PlaceId p : r.unbounded_places) unbounded.push_back(net.places()[p].id);
  j["unbounded_places"] = unbounded;
  j["unbounded_path"] = r.unbounded_witness ? path_json(net, r.unbounded_witness->path) : nlohmann::json();

  if (r.complete && !r.reduced) {
    nlohmann::json dead = nlohmann::json::array();
    for (TransitionId t : r.dead_transitions) dead.push_back(net.transitions()[t].id);
    j["dead_transitions"] = dead;
    nlohmann::json bounds = nlohmann::json::object();
    for (std::size_t p = 0; p < r.place_bounds.size() && p < net.num_places(); ++p) {
      bounds[net.places()[p].id] = r.place_bounds[p];
    }
    j["place_bounds"] = bounds;
  } else {
    j["dead_transitions"] = nullptr;
    j["place_bounds"] = nullptr;
  }

  nlohmann::json regions = nlohmann::json::array();
  for (std::size_t k = 0; k < r.regions.size(); ++k) {
    const RegionCheck& rc = r.regions[k];
    nlohmann::json reg = {{"name", rc.name},
                          {"exclusive", rc.exclusive},
                          {"max_inside", rc.max_inside},
                          {"capacity", k < net.regions().size() ? net.regions()[k].capacity : 1}};
    reg["witness_path"] = rc.witness ? path_json(net, rc.witness->path) : nlohmann::json();
    reg["witness_shortest"] = rc.witness_shortest;
    reg["by_invariant"] = rc.by_invariant;
    reg["invariant_bound"] = rc.by_invariant ? nlohmann::json(rc.invariant_bound) : nlohmann::json();
    reg["witness_marking"] = rc.witness ? marking_json(net, rc.witness->marking) : nlohmann::json();
    regions.push_back(reg);
  }
  j["regions"] = regions;

  if (r.deadlock_examples.empty()) {
    j["deadlock_path"] = nullptr;
    j["deadlock_marking"] = nullptr;
    j["deadlock_description"] = nullptr;
  } else {
    const Deadlock& d = r.deadlock_examples.front();
    j["deadlock_path"] = path_json(net, d.path);
    j["deadlock_marking"] = marking_json(net, d.marking);
    j["deadlock_description"] = describe_marking(net, d.marking);
  }
  nlohmann::json examples = nlohmann::json::array();
  for (const Deadlock& d : r.deadlock_examples) {
    examples.push_back({{"path", path_json(net, d.path)}, {"marking", marking_json(net, d.marking)}});
  }
  j["deadlock_examples"] = examples;
  return j;
}

void ProgressPrinter::operator()(const AnalysisProgress& p) {
  const double rate = p.seconds > 0 ? static_cast<double>(p.markings) / p.seconds : 0.0;
  const std::string line = fmt::format("checking: {} markings{}, {:.0f}/s, queue {}, {:.0f} s", p.markings,
                                       p.reduced ? " (reduced)" : "", rate, p.queue, p.seconds);
  if (terminal_) {
    out_ << '\r' << line << "\x1b[K" << std::flush;
  } else {
    out_ << line << '\n' << std::flush;
  }
  shown_ = true;
}

void ProgressPrinter::finish() {
  if (terminal_ && shown_) out_ << "\r\x1b[K" << std::flush;
  shown_ = false;
}

std::string size_warning(const AnalysisProgress& p, std::uint64_t max_states) {
  if (p.markings == 0 || p.markings >= max_states || p.seconds <= 0 || p.queue * 10 < p.markings) return "";
  const double rate = static_cast<double>(p.markings) / p.seconds;
  return fmt::format("after {:.1f} s {} markings, {} not expanded yet ({:.0f}/s): still growing; at this rate the state "
                     "limit of {} is reached in about {:.0f} s{}",
                     p.seconds, p.markings, p.queue, rate, max_states,
                     std::ceil(static_cast<double>(max_states - p.markings) / rate),
                     p.reduced ? "" : "; --reduction stubborn explores fewer interleavings");
}

std::string width_warning(const Net& net, std::uint64_t max_states) {
  // Each robot's token runs along its own places: the fewest firings from its start place to its done place.
  std::vector<std::vector<std::pair<PlaceId, PlaceId>>> moves(net.robots().size());
  std::uint64_t firings = 0;
  for (std::size_t r = 0; r < net.robots().size(); ++r) {
    const std::string& robot = net.robots()[r];
    std::vector<std::vector<PlaceId>> next(net.num_places());
    PlaceId start = UINT32_MAX;
    for (std::size_t p = 0; p < net.num_places(); ++p) {
      const Place& pl = net.places()[p];
      if (pl.origin.robot == robot && pl.kind == PlaceKind::kStart) start = static_cast<PlaceId>(p);
    }
    if (start == UINT32_MAX) return "";
    for (const Transition& t : net.transitions()) {
      for (const Arc& a : t.inputs) {
        if (net.places()[a.place].origin.robot != robot) continue;
        for (const Arc& b : t.outputs) {
          if (net.places()[b.place].origin.robot == robot) next[a.place].push_back(b.place);
        }
      }
    }
    std::vector<std::uint64_t> dist(net.num_places(), UINT64_MAX);
    std::vector<PlaceId> queue{start};
    dist[start] = 0;
    std::uint64_t to_done = UINT64_MAX;
    for (std::size_t i = 0; i < queue.size(); ++i) {
      const PlaceId p = queue[i];
      if (net.places()[p].kind == PlaceKind::kDone) {
        to_done = dist[p];
        break;
      }
      for (PlaceId q : next[p]) {
        if (dist[q] == UINT64_MAX) {
          dist[q] = dist[p] + 1;
          queue.push_back(q);
        }
      }
    }
    if (to_done == UINT64_MAX) return "";
    firings += to_done;
  }
  const std::uint64_t bytes = (net.num_places() + 7) / 8;  // at least one bit per place
  const double gigabytes = static_cast<double>(firings + 1) * static_cast<double>(bytes) / 1e9;
  if (firings < max_states && gigabytes < 1.0) return "";
  return fmt::format(
      "too wide to explore: a run to the end fires at least {} transitions, and each marking on it takes at least {} "
      "bytes ({} places), so a complete exploration stores at least {} markings ({:.1f} GB){}; expect the check to stop "
      "early (Ctrl-C ends it) and split the program or check smaller parts",
      firings, bytes, net.num_places(), firings + 1, gigabytes,
      firings >= max_states ? fmt::format(", beyond the state limit of {}", max_states) : std::string());
}

int check_and_report(const Net& net, std::string_view source, const CheckOptions& options, std::ostream& out) {
  AnalysisOptions analysis = options.analysis;
  ProgressPrinter printer(std::cerr, ::isatty(STDERR_FILENO) == 1);
  bool warned = false;
  if (options.progress) {
    analysis.progress = [&](const AnalysisProgress& p) {
      if (!warned) {
        const std::string warning = size_warning(p, analysis.max_states);
        if (!warning.empty()) {
          printer.finish();  // the note on a line of its own, the progress line below it
          std::cerr << source << ": note: " << warning << "\n" << std::flush;
          warned = true;
        }
      }
      printer(p);
    };
  }
  if (options.progress) {
    // Said at once, before any exploring: a net too wide to explore would otherwise run for minutes first.
    const std::string wide = width_warning(net, analysis.max_states);
    if (!wide.empty()) std::cerr << source << ": note: " << wide << "\n" << std::flush;
  }
  const auto start = std::chrono::steady_clock::now();
  const AnalysisResult result = analyze(net, analysis);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  printer.finish();
  if (!result.complete && !result.stop_reason.empty()) {
    // Too large to explore within the limit (or stopped by the user): say how far it got and how fast, so that the
    // user can tell what a larger --max-states would cost.
    std::cerr << fmt::format("{}: note: exploration stopped ({}): {} markings explored in {:.1f} s ({:.0f} markings/s; "
                             "state limit {}){}\n",
                             source, result.stop_reason, result.states, seconds,
                             seconds > 0 ? static_cast<double>(result.states) / seconds : 0.0,
                             analysis.max_states,
                             result.reduced || analysis.reduction == Reduction::kStubborn
                                 ? ""
                                 : "; --reduction stubborn explores fewer interleavings");
  }
  if (options.json) {
    out << to_json(net, result).dump(2) << "\n";
  } else {
    out << source << ": " << format_report(net, result);
  }
  return result.ok() ? 0 : 1;
}

}  // namespace cellwright::petri
