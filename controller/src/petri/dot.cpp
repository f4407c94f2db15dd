// Graphviz DOT export (see dot.hpp).
#include "cellwright/petri/dot.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::petri {
namespace {

// A DOT double-quoted string. Inside quotes DOT only treats \" specially, but labels and tooltips are escStrings
// where Graphviz also reads \\, \n, \l, \N, ...: doubling every backslash keeps the text exactly as written, and a
// trailing backslash can no longer swallow the closing quote.
std::string quoted(std::string_view s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      default:
        // Other control characters are not printable and would be invalid in SVG output.
        out += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? ' ' : c;
        break;
    }
  }
  out += '"';
  return out;
}

// Lines joined with DOT's centred line break; each line is escaped separately.
std::string label(const std::vector<std::string>& lines) {
  std::string joined;
  for (const std::string& line : lines) {
    if (!joined.empty()) joined += '\n';
    joined += line;
  }
  return quoted(joined);
}

// "r1, line 2" from an Origin, or "" when it names neither robot nor line.
std::string where(const Origin& o) {
  std::string s = o.robot;
  if (o.line > 0) s += fmt::format("{}line {}", s.empty() ? "" : ", ", o.line);
  return s;
}

std::vector<std::string> place_lines(const Place& p) {
  std::vector<std::string> lines{p.name.empty() ? p.id : p.name};
  if (const std::string w = where(p.origin); !w.empty()) lines.push_back(w);
  return lines;
}

std::vector<std::string> transition_lines(const Transition& t) {
  std::vector<std::string> lines{t.name.empty() ? t.id : t.name};
  std::string w = where(t.origin);
  if (!t.origin.task.empty()) w += fmt::format("{}{}", w.empty() ? "" : ": ", t.origin.task);
  if (!w.empty()) lines.push_back(w);
  if (!t.origin.motion.empty()) lines.push_back(fmt::format("({})", t.origin.motion));
  return lines;
}

// Fill colours tell shared objects from robot states at a glance.
const char* place_fill(PlaceKind k) {
  switch (k) {
    case PlaceKind::kEvent:
      return "lightblue";
    case PlaceKind::kRegion:
      return "khaki";
    case PlaceKind::kDone:
      return "palegreen";
    default:
      return "white";
  }
}

}  // namespace

std::string to_dot(const Net& net, const DotOptions& options) {
  const Marking marking = options.marking.has_value() ? *options.marking : net.initial_marking();
  CW_CHECK(marking.size() == net.num_places(), "marking has {} entries for {} places", marking.size(),
           net.num_places());
  CW_CHECK(options.rankdir == "TB" || options.rankdir == "LR" || options.rankdir == "BT" || options.rankdir == "RL",
           "rankdir '{}' is not TB, LR, BT or RL", options.rankdir);

  std::string out = fmt::format("digraph {} {{\n", quoted(net.name()));
  out += fmt::format("  rankdir={};\n  forcelabels=true;\n", options.rankdir);
  out += "  node [fontname=\"Helvetica\", fontsize=10];\n  edge [fontname=\"Helvetica\", fontsize=10];\n";

  const auto place_node = [&](PlaceId p) {
    const Place& place = net.places()[p];
    const Tokens n = marking[p];
    return fmt::format(
        "p{} [shape=circle, width=0.45, style=filled, fillcolor={}, label={}, xlabel={}, "
        "tooltip={}];\n",
        p, place_fill(place.kind), quoted(n == 0 ? std::string() : std::to_string(n)), label(place_lines(place)),
        quoted("place " + place.id));
  };
  const auto transition_node = [&](TransitionId t) {
    const Transition& tr = net.transitions()[t];
    return fmt::format("t{} [shape=box, style=filled, fillcolor=gray92, label={}, tooltip={}];\n", t,
                       label(transition_lines(tr)), quoted("transition " + tr.id));
  };

  // Robots in the net's order, then any other robot named only in an Origin, in order of appearance.
  std::vector<std::string> robots;
  std::map<std::string, std::size_t> robot_index;
  const auto robot_cluster = [&](const std::string& robot) -> std::size_t {
    const auto [it, inserted] = robot_index.emplace(robot, robots.size());
    if (inserted) robots.push_back(robot);
    return it->second;
  };
  const auto cluster_of = [&](const Origin& o) -> std::size_t {
    return !options.cluster_per_robot || o.robot.empty() ? SIZE_MAX : robot_cluster(o.robot);
  };
  for (const std::string& r : net.robots()) robot_cluster(r);

  std::vector<std::string> clustered;  // node lines per robot
  std::string outside;
  const auto emit = [&](std::size_t cluster, std::string line) {
    if (cluster == SIZE_MAX) {
      outside += "  " + line;
      return;
    }
    if (clustered.size() <= cluster) clustered.resize(cluster + 1);
    clustered[cluster] += "    " + line;
  };
  for (PlaceId p = 0; p < net.num_places(); ++p) emit(cluster_of(net.places()[p].origin), place_node(p));
  for (TransitionId t = 0; t < net.num_transitions(); ++t) {
    emit(cluster_of(net.transitions()[t].origin), transition_node(t));
  }

  for (std::size_t k = 0; k < clustered.size(); ++k) {
    if (clustered[k].empty()) continue;
    out +=
        fmt::format("  subgraph cluster_{} {{\n    label={};\n    style=rounded;\n", k, quoted("robot " + robots[k]));
    out += clustered[k];
    out += "  }\n";
  }
  out += outside;

  const auto weight = [](Tokens w) { return w > 1 ? fmt::format(" [label=\"{}\"]", w) : std::string(); };
  for (TransitionId t = 0; t < net.num_transitions(); ++t) {
    const Transition& tr = net.transitions()[t];
    for (const Arc& a : tr.inputs) out += fmt::format("  p{} -> t{}{};\n", a.place, t, weight(a.weight));
    for (const Arc& a : tr.outputs) out += fmt::format("  t{} -> p{}{};\n", t, a.place, weight(a.weight));
  }
  out += "}\n";
  return out;
}

void write_dot(const Net& net, const std::string& path, const DotOptions& options) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) throw InputError({path, 0, 0}, std::string("cannot write: ") + std::strerror(errno));
  const std::string text = to_dot(net, options);
  const bool written = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (std::fclose(f) != 0 || !written) {
    throw InputError({path, 0, 0}, std::string("cannot write: ") + std::strerror(errno));
  }
}

}  // namespace cellwright::petri
