// Graphviz DOT drawing of a net, for people: `twin analyze --dot net.dot` then `dot -Tsvg net.dot -o net.svg`.
//
// Places are circles holding their token count (empty when 0), with the place's name and, for nets compiled from a
// task program, the robot and program line underneath. Transitions are boxes labelled with their name and the
// command they begin or end (robot, line, task-level and motion-level command). Arcs of weight > 1 carry the weight.
// Node names in the DOT text are generated ("p0", "t3"), so any id is safe; every text taken from the net (ids,
// names, commands) is escaped for DOT, and the net ids are kept as node tooltips.
//
// Thread safety: re-entrant; shares no state.
#pragma once

#include <optional>
#include <string>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

struct DotOptions {
  // Tokens to draw; the net's initial marking when empty. Must have one entry per place.
  std::optional<Marking> marking;
  // Group each robot's places and transitions (by Origin::robot) in a box labelled with the robot; shared places
  // (events, regions) stay outside.
  bool cluster_per_robot = false;
  // Graph layout direction, a Graphviz rankdir value: "TB" (top to bottom) or "LR" (left to right).
  std::string rankdir = "TB";
};

// The net as a DOT digraph. Throws InternalError (a caller's bug) if options.marking has the wrong size or rankdir
// is not one of TB, LR, BT, RL.
std::string to_dot(const Net& net, const DotOptions& options = {});

// Writes to_dot(net, options) to `path`. Throws InputError({path}, "cannot write: <the system's reason>") if the file
// cannot be created or written.
void write_dot(const Net& net, const std::string& path, const DotOptions& options = {});

}  // namespace cellwright::petri
