// Preflight (preflight.hpp).
#include "cellwright/cell/preflight.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <optional>
#include <set>

#include "cellwright/cell/estimate.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::cell {

namespace {

// Where a workpiece is, for the reach checks: the point its bottom rests on and the yaw of a grasp there.
struct Spot {
  std::string text;  // "location 'input_pick'", "workpiece 'A' at the stop of conveyor 'input'"
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double yaw = 0;
  double grasp_height = 0.02;
  double approach_height = 0.08;
  bool handover = false;  // at the hand-over (reach is checked with the hand-over grasps)
  std::string put_by;     // "robot 'puma' put it there (relay.task:12:3 'Place S')", if a robot did
  std::string gone;       // why no robot can take the part from here (it rode off a belt's end), else ""
};

Spot location_spot(const models::LocationSpec& l) {
  Spot s;
  s.text = fmt::format("location '{}'", l.name);
  s.point = l.pose.xyz;
  s.yaw = l.pose.rpy.z();
  s.grasp_height = l.grasp_height;
  s.approach_height = l.approach_height;
  return s;
}

// Where a part riding conveyor `c` comes to rest: against its stop bar, or at its end (where it falls off).
Spot belt_spot(const models::ConveyorSpec& c, const models::WorkpieceSpec& w) {
  Spot s;
  s.yaw = c.pose.rpy.z();
  s.grasp_height = w.size.z() / 2;
  s.point = c.belt_point(c.leave - (c.stop ? w.size.x() / 2 : 0.0));
  s.text = fmt::format("workpiece '{}' at the {} of conveyor '{}'", w.name, c.stop ? "stop" : "end", c.name);
  return s;
}

// Where a workpiece is picked first: a conveyor carries it to its stop bar (or its end); otherwise it stays where it
// was put. A cell location at that point (within 1 cm) lends its name, yaw and heights.
Spot initial_spot(const models::CellDescription& cell, const models::WorkpieceSpec& w,
                  const std::optional<Feed>& feed) {
  std::string conveyor = w.on;
  if (feed && std::find(feed->workpieces.begin(), feed->workpieces.end(), w.name) != feed->workpieces.end()) {
    conveyor = feed->conveyor;
  }
  Spot s;
  s.yaw = w.pose.rpy.z();
  s.grasp_height = w.size.z() / 2;
  if (const models::ConveyorSpec* c = cell.find_conveyor(conveyor)) {
    s = belt_spot(*c, w);
    s.yaw = w.pose.rpy.z();
  } else {
    s.point = w.pose.xyz - Eigen::Vector3d(0, 0, w.size.z() / 2);
    s.text = fmt::format("workpiece '{}' where it starts", w.name);
  }
  for (const auto& l : cell.locations) {
    if ((l.pose.xyz - s.point).norm() < 0.01) {
      Spot named = location_spot(l);
      named.text = fmt::format("workpiece '{}' at location '{}'", w.name, l.name);
      return named;
    }
  }
  return s;
}

// Whether, in every run of `net`, transition `first` fires before transition `then` can: with `first` never firing,
// no reachable marking enables `then`. nullopt when the net has more than `limit` markings without `first`.
std::optional<bool> always_before(const petri::Net& net, petri::TransitionId first, petri::TransitionId then,
                                  std::size_t limit) {
  std::set<petri::Marking> seen{net.initial_marking()};
  std::vector<petri::Marking> todo{net.initial_marking()};
  while (!todo.empty()) {
    const petri::Marking m = std::move(todo.back());
    todo.pop_back();
    if (petri::is_enabled(net, m, then)) return false;
    for (petri::TransitionId t : petri::enabled(net, m)) {
      if (t == first) continue;
      petri::Marking next = petri::fire(net, m, t);
      if (seen.insert(next).second) {
        if (seen.size() > limit) return std::nullopt;
        todo.push_back(std::move(next));
      }
    }
  }
  return true;
}

std::string command_text(const task::Primitive& p) {
  return fmt::format("{}:{}:{} '{}'", std::filesystem::path(p.where.file).filename().string(), p.where.line,
                     p.where.column, p.task);
}

}  // namespace

Preflight preflight(const Scenario& s, const CollisionSweep* collisions) {
  Preflight out;
  out.net = task::to_net(s.program);
  // The reduced search of twin check: its verdicts (deadlock, boundedness, every region) are those of full
  // exploration (petri/analysis.hpp), so a program twin check passes quickly is not slow or refused here.
  petri::AnalysisOptions check;
  check.reduction = petri::Reduction::kStubborn;
  out.analysis = petri::analyze(out.net, check);
  if (!out.analysis.ok()) {
    const std::string report = petri::format_report(out.net, out.analysis);
    out.problems.push_back(fmt::format("the program {} fails the check (twin check): {}", s.program_file.string(),
                                       report.substr(0, report.find('\n'))));
    return out;  // a program that cannot finish is not worth a reach check
  }

  // A relay: a named part one robot lets go of and another goes to. The net must order the two commands, one way or
  // the other, in every run: else the taker may go for the part before it has been put down (or the giver let go of
  // it while the taker is on its way), and the run follows no fixed order of where the part is.
  constexpr std::size_t kOrderLimit = 200'000;  // markings: as the sweep's full exploration
  std::set<std::pair<std::string, std::string>> unordered;
  for (std::size_t x = 0; x < s.program.robots.size(); ++x) {
    const auto& goes = s.program.programs[x].primitives;
    for (std::size_t k = 0; k < goes.size(); ++k) {
      const task::Primitive& go = goes[k];
      const bool to_object = go.kind == task::PrimitiveKind::kMove &&
                             (go.target.kind == task::TargetKind::kAbove || go.target.kind == task::TargetKind::kAt);
      if (!to_object || std::find(s.program.workpieces.begin(), s.program.workpieces.end(), go.target.object) ==
                            s.program.workpieces.end()) {
        continue;
      }
      for (std::size_t y = 0; y < s.program.robots.size(); ++y) {
        const auto& lets = s.program.programs[y].primitives;
        for (std::size_t j = 0; y != x && j < lets.size(); ++j) {
          const task::Primitive& let = lets[j];
          if (let.kind != task::PrimitiveKind::kOpen || let.workpiece != go.target.object) continue;
          if (unordered.count({command_text(go), command_text(let)}) != 0) continue;
          const auto id = [&](std::size_t robot, std::size_t primitive) {
            return *out.net.find_transition(task::transition_id(s.program.robots[robot], primitive));
          };
          const std::optional<bool> after = always_before(out.net, id(y, j + 1), id(x, k), kOrderLimit);
          const std::optional<bool> before =
              after.value_or(false) ? after : always_before(out.net, id(x, k), id(y, j), kOrderLimit);
          if (after.value_or(false) || before.value_or(false)) continue;
          unordered.insert({command_text(go), command_text(let)});
          const std::string how =
              "order them: a semaphore signalled after the put-down and waited for before the pick, or the two on "
              "later lines of the steps table (docs/scenarios.md, \"Relaying a part between robots\")";
          out.problems.push_back(
              after && before
                  ? fmt::format("robot '{}' goes to workpiece '{}' ({}) that robot '{}' lets go of ({}), but nothing in "
                                "the program orders the two: a run may start the one before the other has finished, "
                                "in either order; {}",
                                s.robot_of(s.program.robots[x]), s.workpiece_of(go.target.object), command_text(go),
                                s.robot_of(s.program.robots[y]), command_text(let), how)
                  : fmt::format("robot '{}' goes to workpiece '{}' ({}) that robot '{}' lets go of ({}), but the net "
                                "has more than {} markings: whether the program orders the two was not shown; {}",
                                s.robot_of(s.program.robots[x]), s.workpiece_of(go.target.object), command_text(go),
                                s.robot_of(s.program.robots[y]), command_text(let), kOrderLimit, how));
        }
      }
    }
  }
  if (!out.problems.empty()) return out;  // where a part is depends on the run: the reach checks would mislead

  // Follow one run of the net (any run: the analysis shows every run reaches the end) to learn where each workpiece is
  // when a robot goes to it. Primitives start when their transition fires.
  std::map<std::string, Spot> where_is;  // cell workpiece -> where it lies now
  for (const auto& b : s.workpieces) {
    where_is[b.name] = initial_spot(s.cell, *s.cell.find_workpiece(b.name), s.feed);
  }
  std::map<std::string, std::string> holding;          // cell robot -> cell workpiece it holds
  std::map<std::string, Spot> last_target;             // cell robot -> the spot of its last move (for open)
  std::set<std::pair<std::string, std::string>> seen;  // (robot, target text) already needed
  std::vector<std::pair<ReachNeed, Spot>> needs;

  auto need = [&](const std::string& robot, const Spot& spot, const task::Primitive& p) {
    if (!seen.insert({robot, spot.text}).second) return;
    needs.push_back({ReachNeed{robot, spot.text, command_text(p)}, spot});
  };
  auto spot_of_object = [&](const std::string& mover, const std::string& label) -> std::optional<Spot> {
    if (const task::WorkpieceClass* c = task::find_class(s.program, label)) {
      // A part of a class is picked where the class's parts arrive.
      (void)mover;
      return location_spot(*s.cell.find_location(s.location_of(c->from)));
    }
    if (std::find(s.program.workpieces.begin(), s.program.workpieces.end(), label) != s.program.workpieces.end()) {
      const std::string& w = s.workpiece_of(label);
      // A workpiece in a gripper is not a place to go to.
      for (const auto& [robot, held] : holding) {
        if (held == w) return std::nullopt;
      }
      Spot spot = where_is.at(w);
      // Putting something down on a workpiece (stacking) goes onto its top.
      if (holding.count(mover) != 0) {
        spot.point.z() += s.cell.find_workpiece(w)->size.z();
        spot.text = fmt::format("the top of {}", spot.text);
      }
      return spot;
    }
    return location_spot(*s.cell.find_location(s.location_of(label)));
  };

  petri::Marking m = out.net.initial_marking();
  petri::Arbiter arbiter = petri::make_arbiter(out.net);
  task::LoopControl loops(out.net, s.program);
  while (!petri::is_dead(out.net, m)) {
    std::vector<bool> allowed;
    loops.restrict(allowed);
    const auto chosen = petri::choose(out.net, m, arbiter, allowed);
    if (chosen.empty()) break;  // only a decision the counts rule out is enabled: cannot happen after a passed check
    for (petri::TransitionId t : chosen) loops.fired(t);
    for (petri::TransitionId t : chosen) {
      const petri::Transition& tr = out.net.transitions()[t];
      if (!tr.starts_robot) continue;
      const std::string& label = s.program.robots[*tr.starts_robot];
      const std::string& robot = s.robot_of(label);
      const task::Primitive& p =
          s.program.programs[*tr.starts_robot].primitives[static_cast<std::size_t>(tr.starts_primitive)];
      switch (p.kind) {
        case task::PrimitiveKind::kMove: {
          const task::Target& target = p.target;
          if (target.kind == task::TargetKind::kAbove || target.kind == task::TargetKind::kAt) {
            if (auto spot = spot_of_object(robot, target.object); spot && !spot->gone.empty()) {
              if (seen.insert({robot, spot->gone}).second) {
                out.problems.push_back(fmt::format("robot '{}' goes to workpiece '{}' ({}), but {}", robot,
                                                   s.workpiece_of(target.object), command_text(p), spot->gone));
              }
            } else if (spot) {
              // A coordinated block's robots go to their own grasp points on the workpiece, not its centre: robot
              // control solves each arm's target when the segment runs (docs/runtime.md, "Coordinated blocks"), and
              // the motion plan checks it with the same function (plan_motions).
              if (!p.segment) need(robot, *spot, p);
              last_target[robot] = *spot;
            }
          } else if (target.kind == task::TargetKind::kHandover || target.kind == task::TargetKind::kHandApproach ||
                     target.kind == task::TargetKind::kHandGrasp) {
            Spot h;
            h.handover = true;
            h.text = s.cell.handover ? fmt::format("the hand-over '{}'", s.cell.handover->name) : "the hand-over";
            need(robot, h, p);
            last_target[robot] = h;
          }
          break;
        }
        case task::PrimitiveKind::kClose:
          if (!p.workpiece.empty()) {
            holding[robot] = task::find_class(s.program, p.workpiece) != nullptr ? fmt::format("class {}", p.workpiece)
                                                                                 : s.workpiece_of(p.workpiece);
          }
          break;
        case task::PrimitiveKind::kOpen:
          if (!p.workpiece.empty() && task::find_class(s.program, p.workpiece) != nullptr) {
            holding.erase(robot);  // a class's part is not followed further: the next Pick takes a new one
          } else if (!p.workpiece.empty()) {
            const std::string& w = s.workpiece_of(p.workpiece);
            if (auto it = last_target.find(robot); it != last_target.end()) {
              Spot put = it->second;
              put.text = put.handover ? put.text : fmt::format("workpiece '{}' on {}", w, it->second.text);
              put.put_by = fmt::format("robot '{}' put it there ({})", robot, command_text(p));
              put.gone.clear();
              // Let go of on a running belt, the part rides on: to the stop bar, where a robot may take it once it
              // rests there (robot control waits until it does), or off the belt's end.
              if (const models::ConveyorSpec* belt = put.handover ? nullptr : running_belt_under(s.cell, put.point)) {
                put = belt_spot(*belt, *s.cell.find_workpiece(w));
                put.put_by = fmt::format("robot '{}' let go of it on the running conveyor '{}' ({}), which carries it "
                                         "there",
                                         robot, belt->name, command_text(p));
                if (!belt->stop) {
                  put.gone = fmt::format("robot '{}' lets go of it on conveyor '{}' ({}), which carries it off its "
                                         "end: give the belt a stop bar (stop: true), and the part is taken where it "
                                         "stops",
                                         robot, belt->name, command_text(p));
                }
              }
              where_is[w] = put;
            }
            holding.erase(robot);
          }
          break;
        case task::PrimitiveKind::kSignal:
        case task::PrimitiveKind::kWait:
        case task::PrimitiveKind::kLoop:
        case task::PrimitiveKind::kDevice:  // no robot motion
          break;
      }
    }
    petri::fire_chosen(out.net, m, arbiter, chosen);
  }

  // One check_reach call over a cell whose reach lists are exactly the needs. check_reach reports locations in order
  // (grasp, then approach, per robot) and then the hand-over grasps in order; `owner` maps each check to its need.
  models::CellDescription probe = s.cell;
  probe.locations.clear();
  const std::optional<models::HandoverSpec>& handover = s.cell.handover;
  if (probe.handover) probe.handover->grasps.clear();
  std::vector<std::size_t> location_need, handover_need;
  for (std::size_t i = 0; i < needs.size(); ++i) {
    const auto& [n, spot] = needs[i];
    out.needs.push_back(n);
    if (spot.handover) {
      const models::HandoverGrasp* g = nullptr;
      if (handover) {
        for (const auto& candidate : handover->grasps) {
          if (candidate.robot == n.robot) g = &candidate;
        }
      }
      if (g == nullptr) {
        out.problems.push_back(fmt::format("robot '{}' must take part in a hand-over ({}), but the cell {} {}", n.robot,
                                           n.why, s.cell_file.filename().string(),
                                           handover
                                               ? fmt::format("gives it no grasp at the hand-over '{}'", handover->name)
                                               : std::string("has no hand-over")));
        continue;
      }
      probe.handover->grasps.push_back(*g);
      handover_need.push_back(i);
      continue;
    }
    models::LocationSpec l;
    l.name = fmt::format("need{}", i);
    l.pose.xyz = spot.point;
    l.pose.rpy = Eigen::Vector3d(0, 0, spot.yaw);
    l.reach = {n.robot};
    l.grasp_height = spot.grasp_height;
    l.approach_height = spot.approach_height;
    l.where = {s.source.string(), 0, 0};
    probe.locations.push_back(std::move(l));
    location_need.push_back(i);
  }
  if (probe.handover && probe.handover->grasps.empty()) probe.handover.reset();
  out.reach = models::check_reach(probe);
  CW_CHECK(out.reach.size() == 2 * location_need.size() + handover_need.size(), "{} reach checks for {} + {} needs",
           out.reach.size(), location_need.size(), handover_need.size());
  for (std::size_t k = 0; k < out.reach.size(); ++k) {
    models::ReachCheck& c = out.reach[k];
    const bool at_location = k < 2 * location_need.size();
    const std::size_t i = at_location ? location_need[k / 2] : handover_need[k - 2 * location_need.size()];
    const ReachNeed& n = out.needs[i];
    c.target = at_location ? fmt::format("{} ({})", n.target, k % 2 == 0 ? "grasp" : "approach") : n.target;
    const std::string& put_by = needs[i].second.put_by;
    c.where = {s.source.string(), 0, 0};
    if (c.reachable) continue;
    out.problems.push_back(fmt::format(
        "robot '{}' cannot reach {}, needed by {}: the gripper pose at ({:.3f}, {:.3f}, {:.3f}) is {:.3f} m from its "
        "first joint (maximum reach {:.3f} m){}{}",
        c.robot, c.target, n.why, c.tcp_world.translation().x(), c.tcp_world.translation().y(),
        c.tcp_world.translation().z(), c.distance, c.max_reach, c.reason.empty() ? "" : ": " + c.reason,
        put_by.empty() ? "" : "; " + put_by));
  }

  // Every move as robot control will make it: a part held from the side is put down from the side, a taker waits
  // backed off from the hand-over; check_reach's grasps from above do not cover those.
  if (out.problems.empty()) {
    runtime::TargetOptions targets;
    targets.handover_clearance = s.options.handover_clearance;
    out.plan = plan_motions(s, out.net, targets);
    for (std::string& p : out.plan->problems()) out.problems.push_back(std::move(p));
    if (out.problems.empty() && collisions == nullptr) {
      out.sweep_summary = "collisions not swept: this twin was built without the simulator (CW_SIM=OFF)";
    } else if (out.problems.empty()) {
      out.twin = collisions->compile(s);
      const SweepReport sweep = collisions->sweep(*out.twin, s, out.net, *out.plan);
      for (const PredictedCollision& c : sweep.collisions) {
        out.collisions.push_back(c.text());
        out.problems.push_back("predicted collision: " + out.collisions.back());
      }
      out.sweep_summary = fmt::format(
          "swept {} moves ({} poses against the static cell) and {} pairs of commands of two robots ({}); {} poses "
          "checked",
          sweep.motions, sweep.samples, sweep.pairs, sweep.concurrency, sweep.pose_checks);
    }
  }
  return out;
}

}  // namespace cellwright::cell
