// The cycle-time estimate before a run (estimate.hpp).
#include "cellwright/cell/estimate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/runtime/robot_control.hpp"
#include "cellwright/runtime/segment_target.hpp"
#include "cellwright/task/to_net.hpp"
#include "cellwright/twin/sim/belt_exit.hpp"
#include "cellwright/twin/sim/grip_timing.hpp"
#include "cellwright/twin/sim/move_timing.hpp"
#include "cellwright/twin/sim/trajectory.hpp"

namespace cellwright::cell {

namespace sim = twin::sim;  // the simulator's World, drivers and plant

namespace {

Eigen::VectorXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// Seconds part `w` rides conveyor `c` from `from` (m along the belt from its upstream end) to where it is picked: the
// stop (its centre half its length before the bar) or the leave point. `pick_pose` is set to the part's pose there.
double ride_to_pick(const models::ConveyorSpec& c, const models::WorkpieceSpec& w, double from,
                    Eigen::Isometry3d& pick_pose) {
  const double stop_s = c.stop ? c.leave - w.size.x() / 2 : c.leave;
  pick_pose = Eigen::Isometry3d::Identity();
  pick_pose.linear() = Eigen::AngleAxisd(c.pose.rpy.z(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pick_pose.translation() = c.belt_point(stop_s) + Eigen::Vector3d(0, 0, w.size.z() / 2);
  const double travel = std::max(0.0, stop_s - from);
  return c.speed > 0 ? travel / c.speed : 0.0;
}

// When a part on a conveyor can first be picked: it rides the belt to the stop (or the end), from where it starts
// or, when fed, from the entry point at its arrival time. nullopt for a part not on a conveyor. `conveyor` is set to
// the conveyor it rides.
std::optional<double> pick_ready_time(const models::CellDescription& cell, const models::WorkpieceSpec& w,
                                      const std::optional<Feed>& feed, Eigen::Isometry3d& pick_pose,
                                      std::string& conveyor) {
  std::optional<std::size_t> fed;
  if (feed) {
    auto it = std::find(feed->workpieces.begin(), feed->workpieces.end(), w.name);
    if (it != feed->workpieces.end()) fed = static_cast<std::size_t>(it - feed->workpieces.begin());
  }
  const models::ConveyorSpec* c = cell.find_conveyor(fed ? feed->conveyor : w.on);
  if (c == nullptr) return std::nullopt;
  conveyor = c->name;
  const double start_time = fed ? feed->arrival(*fed) : 0.0;
  const double start_s = fed ? c->enter : (c->pose.transform().inverse() * w.pose.xyz).x() + c->length / 2;
  return start_time + ride_to_pick(*c, w, start_s, pick_pose);
}

// A builder holding all of `net` (places, transitions, regions, robots, final places), to add to.
petri::NetBuilder builder_of(const petri::Net& net) {
  petri::NetBuilder b(net.name());
  for (const petri::Place& p : net.places()) b.add_place(p);
  for (const petri::Transition& t : net.transitions()) b.add_transition(t);
  for (const petri::Region& r : net.regions()) b.add_region(r);
  b.set_robots(net.robots());
  b.set_final(net.final_places());
  return b;
}

// The program's net with the parts' arrivals: per part that arrives late, a place "coming" holding a token until the
// part is there (its duration), a transition "arrived" that fires then, and a place "arrived" on a self-loop of the
// transition that starts the first move to it. The self-loop gives the token back at once: when a loop runs that move
// again, the next part is taken to be waiting already (fed faster than the cell takes them; a slower feed is not
// modelled).
petri::Net with_arrivals(const petri::Net& net, const std::vector<ArrivalGate>& gates, std::vector<double>& durations) {
  petri::NetBuilder b = builder_of(net);
  for (const ArrivalGate& g : gates) {
    petri::Place coming;
    coming.id = fmt::format("arrival.{}.coming", g.workpiece);
    coming.name = fmt::format("{} on its way", g.workpiece);
    coming.initial = 1;
    const petri::PlaceId from = b.add_place(std::move(coming));
    durations.push_back(g.ready);
    petri::Place here;
    here.id = fmt::format("arrival.{}", g.workpiece);
    here.name = fmt::format("{} arrived", g.workpiece);
    const petri::PlaceId id = b.add_place(std::move(here));
    durations.push_back(0.0);
    petri::Transition arrived;
    arrived.id = fmt::format("arrival.{}.arrived", g.workpiece);
    arrived.name = fmt::format("{} arrives", g.workpiece);
    arrived.inputs.push_back({from, 1});
    arrived.outputs.push_back({id, 1});
    b.add_transition(std::move(arrived));
    b.transition(g.transition).inputs.push_back({id, 1});
    b.transition(g.transition).outputs.push_back({id, 1});
  }
  return std::move(b).build();
}

// The feed's net joined to `net` (estimate.hpp, estimate_cycle_time): slots at the feed times, bodies free, parts at
// the stop taken by the plan's feed takes, bodies delivered back by its deliveries. `durations` gets the new places'.
// `delivered` has each delivery's place duration.
petri::Net with_feed(const petri::Net& net, const Feed& feed, const MotionPlan& plan,
                     const std::vector<double>& delivered, double period, std::vector<double>& durations) {
  petri::NetBuilder b = builder_of(net);
  const auto place = [&](const std::string& id, std::string name, petri::Tokens initial, double duration) {
    petri::Place p;
    p.id = id;
    p.name = std::move(name);
    p.initial = initial;
    durations.push_back(duration);
    return b.add_place(std::move(p));
  };
  const auto transition = [&](const std::string& id, std::string name, std::vector<petri::Arc> in,
                              std::vector<petri::Arc> out) {
    petri::Transition t;
    t.id = id;
    t.name = std::move(name);
    t.inputs = std::move(in);
    t.outputs = std::move(out);
    b.add_transition(std::move(t));
  };
  const auto count = static_cast<petri::Tokens>(feed.count);
  const auto bodies = static_cast<petri::Tokens>(feed.workpieces.size());
  const petri::PlaceId first = place("feed.first", "until the first feed time", 1, feed.start);
  const petri::PlaceId due = place("feed.due", "parts still to feed", count, 0.0);
  const petri::PlaceId clock = place("feed.clock", "until the next feed time", 0, feed.period);
  const petri::PlaceId slot = place("feed.slot", "a feed time come", 0, 0.0);
  const petri::PlaceId free = place("feed.free", "bodies free to feed", bodies, 0.0);
  const petri::PlaceId part = place("feed.part", "a part fed, at the stop once it has ridden there", 0,
                                    std::ceil(plan.feed_ride / period - 1e-9) * period);
  transition("feed.begin", "the first feed time", {{first, 1}, {due, 1}}, {{slot, 1}, {clock, 1}});
  transition("feed.tick", "the next feed time", {{clock, 1}, {due, 1}}, {{slot, 1}, {clock, 1}});
  transition("feed.feed", "a body put on the belt", {{slot, 1}, {free, 1}}, {{part, 1}});
  for (petri::TransitionId t : plan.feed_takes) b.transition(t).inputs.push_back({part, 1});
  for (std::size_t d = 0; d < plan.deliveries.size(); ++d) {
    const Delivery& dl = plan.deliveries[d];
    const petri::PlaceId leaving = place(fmt::format("feed.leaving.{}", d),
                                         fmt::format("a part riding {} out of the cell", dl.conveyor), 0, delivered[d]);
    b.transition(dl.transition).outputs.push_back({leaving, 1});
    transition(fmt::format("feed.delivered.{}", d), fmt::format("a part taken out at the end of {}", dl.conveyor),
               {{leaving, 1}}, {{free, 1}});
  }
  return std::move(b).build();
}

// The relays' belts joined to `net` (estimate.hpp, estimate_cycle_time): per belt, a place for the parts let go of on
// it and one for its stop cleared (a token at the start), each timed with the ride to the stop rounded up to the
// control period `period`; the take of the next part at the stop needs one of each. `durations` gets the new places'.
petri::Net with_queue_belts(const petri::Net& net, const MotionPlan& plan, double period,
                            std::vector<double>& durations) {
  petri::NetBuilder b = builder_of(net);
  for (const MotionPlan::QueueBelt& q : plan.queue_belts) {
    const double ride = std::ceil(q.ride / period - 1e-9) * period;
    petri::Place put;
    put.id = fmt::format("queue.{}.put", q.conveyor);
    put.name = fmt::format("a part let go of on {}, at the stop once it has ridden there", q.conveyor);
    const petri::PlaceId put_id = b.add_place(std::move(put));
    durations.push_back(ride);
    petri::Place clear;
    clear.id = fmt::format("queue.{}.clear", q.conveyor);
    clear.name = fmt::format("the stop of {} cleared: the part behind rides up", q.conveyor);
    clear.initial = 1;
    const petri::PlaceId clear_id = b.add_place(std::move(clear));
    durations.push_back(ride);
    for (petri::TransitionId t : q.puts) b.transition(t).outputs.push_back({put_id, 1});
    for (petri::TransitionId t : q.lifts) b.transition(t).outputs.push_back({clear_id, 1});
    for (petri::TransitionId t : q.takes) {
      b.transition(t).inputs.push_back({put_id, 1});
      b.transition(t).inputs.push_back({clear_id, 1});
    }
  }
  return std::move(b).build();
}

// Half the extent of a workpiece along the unit direction `d` (world): where fingers closing along d touch it.
double half_extent(const runtime::WorkpieceState& w, const Eigen::Vector3d& d) {
  const Eigen::Vector3d local = w.pose.linear().transpose() * d;
  const Eigen::Vector3d size = w.size();
  if (w.shape() == models::Shape::kCylinder) {  // size: diameter, -, height; its axis along its z
    return 0.5 * size.x() * std::hypot(local.x(), local.y()) + 0.5 * size.z() * std::abs(local.z());
  }
  return 0.5 * local.cwiseAbs().dot(size);
}

// From the firing that starts a command to the firing after it, in lock-step (see estimate.hpp): the driver's `motion`
// seconds end at a physics step, seen by robot control in the round of that step, a move's read-back one round later,
// the next firing one round after that.
double lockstep_span(double motion, bool move, double period, double step) {
  const double steps = std::ceil(motion / step - 1e-9);
  const double rounds = std::floor(steps * step / period + 1e-9) + 1;
  return (rounds + (move ? 2 : 1)) * period;
}

}  // namespace

std::vector<std::string> MotionPlan::problems() const {
  std::vector<std::string> out;
  for (const auto& robot : commands) {
    for (const PlannedCommand& c : robot) {
      if (!c.problem.empty()) {
        out.push_back(
            fmt::format("robot '{}' ({}) cannot make '{}' ({}): {}", c.cell, c.robot, c.command, c.source, c.problem));
      }
    }
  }
  return out;
}

const models::ConveyorSpec* running_belt_under(const models::CellDescription& cell, const Eigen::Vector3d& point) {
  constexpr double kOnBelt = 0.01;  // m above or below the belt's top surface
  for (const models::ConveyorSpec& c : cell.conveyors) {
    const Eigen::Vector3d local = c.pose.transform().inverse() * point;
    if (c.speed > 0 && std::abs(local.x()) <= c.length / 2 && std::abs(local.y()) <= c.width / 2 &&
        std::abs(local.z() - c.height) <= kOnBelt) {
      return &c;
    }
  }
  return nullptr;
}

MotionPlan plan_motions(const Scenario& s, const petri::Net& net, const runtime::TargetOptions& targets) {
  const task::CompiledProgram& prog = s.program;
  struct Arm {
    std::string cell;
    models::KinematicChain chain;
    Eigen::Isometry3d base;
    bool five_axis = false;  // on a Movemaster EX controller: its yaw follows its position
  };
  std::vector<Arm> arms;
  for (const std::string& label : prog.robots) {
    const models::RobotSpec& spec = *s.cell.find_robot(s.robot_of(label));
    bool five_axis = false;
    for (const DriverChoice& d : s.drivers) {
      if (d.robot == spec.name) five_axis = d.kind == models::DriverKind::kMovemaster;
    }
    arms.push_back({spec.name, models::robot_chain(spec),
                    spec.base.transform(), five_axis});
  }

  MotionPlan plan;
  plan.commands.resize(prog.robots.size());
  for (std::size_t r = 0; r < prog.robots.size(); ++r) {
    const auto& prims = prog.programs[r].primitives;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      PlannedCommand c;
      c.robot = prog.robots[r];
      c.cell = arms[r].cell;
      c.primitive = k;
      c.kind = prims[k].kind;
      c.command = task::to_string(prims[k]);
      c.source = fmt::format("{}:{}:{} '{}'", std::filesystem::path(prims[k].where.file).filename().string(),
                             prims[k].where.line, prims[k].where.column, prims[k].task);
      plan.commands[r].push_back(std::move(c));
    }
  }

  // The environment model the plan follows: parts that ride a conveyor wait at its stop, at rest.
  runtime::EnvironmentModel model = runtime::make_environment_model(s.cell);
  // The feed's ride to the stop, and a shift's exit conveyors as the scenario's run sets them up (run.cpp): every
  // conveyor but the feed's.
  std::vector<sim::BeltExit> exits;
  if (s.feed) {
    const models::ConveyorSpec* entry = s.cell.find_conveyor(s.feed->conveyor);
    CW_CHECK(entry != nullptr, "the feed's conveyor {} is not the cell's", s.feed->conveyor);  // (the loader checks)
    for (const std::string& w : s.feed->workpieces) {
      const models::WorkpieceSpec* body = s.cell.find_workpiece(w);
      CW_CHECK(body != nullptr, "the feed's workpiece {} is not the cell's", w);
      Eigen::Isometry3d at_stop;
      plan.feed_ride = std::max(plan.feed_ride, ride_to_pick(*entry, *body, entry->enter, at_stop));
    }
    for (const models::ConveyorSpec* c : s.feed->exits(s.cell)) exits.emplace_back(*c);
  }
  std::map<std::string, double> ready_at;         // cell workpiece -> when it can be picked
  std::map<std::string, std::string> arrives_on;  // cell workpiece -> the conveyor it rides to its stop
  for (const models::WorkpieceSpec& w : s.cell.workpieces) {
    Eigen::Isometry3d pick = Eigen::Isometry3d::Identity();
    if (auto t = pick_ready_time(s.cell, w, s.feed, pick, arrives_on[w.name])) {
      runtime::WorkpieceState& ws = *model.find_workpiece(w.name);
      ws.pose = pick;
      ws.present = true;
      ready_at[w.name] = *t;
    }
  }
  // What each arm holds, relative to its tool (parts held move with the hand).
  std::map<std::string, std::pair<std::string, Eigen::Isometry3d>> held;  // cell robot -> (workpiece, tcp^-1 part)
  std::map<std::string, double> closed;  // cell robot -> where its fingers closed to (absent: open)
  // Named parts let go of on a running belt, not taken up since: cell workpiece -> (conveyor, the open's source).
  std::map<std::string, std::pair<std::string, std::string>> on_belt;

  auto tcp_of = [&](const Arm& a, const std::vector<double>& q) { return a.base * a.chain.forward(vec(q)); };
  auto bound = [&](const task::Target& t) {
    task::Target out = t;
    if (t.kind == task::TargetKind::kAbove || t.kind == task::TargetKind::kAt) {
      out.object = std::find(prog.workpieces.begin(), prog.workpieces.end(), t.object) != prog.workpieces.end()
                       ? s.workpiece_of(t.object)
                       : s.location_of(t.object);
    } else if (t.kind != task::TargetKind::kHome) {
      out.object = s.robot_of(t.object);
    }
    return out;
  };

  petri::Marking m = net.initial_marking();
  petri::Arbiter arbiter = petri::make_arbiter(net);
  // Workpiece classes, as robot control binds them: a move to a part of a class the arm does not have takes the next
  // body the feed brings (in feed order, round the list), at rest where it stops; a Get's close takes the body the
  // giver holds; the open that lets go of it unbinds it. Each primitive is planned once (the loop bodies' first
  // iteration), so a few bodies suffice.
  std::map<std::string, std::map<std::string, std::string>> instance;  // cell robot -> class label -> cell workpiece
  std::map<std::string, std::string> hand_peer;                        // cell robot -> the robot its hand went to
  std::size_t next_body = 0;
  std::map<std::string, Eigen::Isometry3d> ready_pose;
  for (const models::WorkpieceSpec& w : s.cell.workpieces) ready_pose[w.name] = model.find_workpiece(w.name)->pose;
  // A class whose parts another belt than the feed's brings (a relay: one robot lets them go on that belt, another
  // takes them at its stop) takes no fed body: its moves are planned to its location, as for a class no feed brings.
  auto relayed_class = [&](const std::string& label) {
    const models::LocationSpec* from = s.cell.find_location(s.location_of(task::find_class(prog, label)->from));
    const models::ConveyorSpec* belt = from ? running_belt_under(s.cell, from->pose.transform().translation()) : nullptr;
    return belt != nullptr && belt->name != s.feed->conveyor;
  };
  // Relays over a belt (MotionPlan::QueueBelt), by conveyor: their puts, takes and lifts; and the robots whose next
  // move lifts a part of a relayed class off the stop, with its belt.
  std::map<std::string, MotionPlan::QueueBelt> queues;
  std::map<std::string, std::string> lifting;     // cell robot -> conveyor
  std::map<std::string, std::string> queue_body;  // conveyor -> the body last let go of on it
  // A belt between robots: running, with a stop, not the feed's.
  auto between_robots = [&](const models::ConveyorSpec* belt) {
    return belt != nullptr && belt->stop && !(s.feed && belt->name == s.feed->conveyor);
  };
  // The belt a class's parts ride to its location (the location at the stop of a belt between robots), or nullptr.
  auto queue_belt_of = [&](const std::string& label) -> const models::ConveyorSpec* {
    const models::LocationSpec* from = s.cell.find_location(s.location_of(task::find_class(prog, label)->from));
    const models::ConveyorSpec* belt = from ? running_belt_under(s.cell, from->pose.transform().translation()) : nullptr;
    return between_robots(belt) ? belt : nullptr;
  };
  // Sets `fed` when the class takes a new part from the feed.
  auto bind_class = [&](const std::string& robot, const std::string& label, bool* fed = nullptr) -> std::string {
    auto& mine = instance[robot];
    if (auto it = mine.find(label); it != mine.end()) return it->second;
    std::string body;
    if (auto peer = hand_peer.find(robot); peer != hand_peer.end() && held.count(peer->second) != 0) {
      body = held.at(peer->second).first;
    } else if (s.feed && !s.feed->workpieces.empty() && !relayed_class(label)) {
      if (fed != nullptr) *fed = true;
      body = s.feed->workpiece_at(next_body++);
      runtime::WorkpieceState& ws = *model.find_workpiece(body);
      if (ws.held_by.empty()) ws.pose = ready_pose.at(body);
    }
    if (!body.empty()) mine[label] = body;
    return body;
  };

  // Coordinated blocks, as robot control keeps them (segment_target.hpp): each robot's carry per block, and the
  // master's target of each segment with its tool before it (what the follower composes its own target with).
  std::map<std::pair<std::string, std::string>, runtime::CarryTargets> carries;  // (cell robot, block) -> carry
  struct MasterPost {
    Eigen::Isometry3d target, tool;
  };
  std::map<std::pair<std::string, int>, MasterPost> master_posts;  // (block, segment index) -> the master's

  std::uint64_t guard = 0;
  task::LoopControl loops(net, prog);
  while (!petri::is_dead(net, m) && guard++ < 1'000'000) {
    std::vector<bool> allowed;
    loops.restrict(allowed);
    const auto chosen = petri::choose(net, m, arbiter, allowed);
    if (chosen.empty()) break;
    for (petri::TransitionId t : chosen) loops.fired(t);
    // The masters' segments first: a follower's target is made from its master's.
    auto planned_order = chosen;
    std::stable_partition(planned_order.begin(), planned_order.end(), [&](petri::TransitionId t) {
      const petri::Transition& tr = net.transitions()[t];
      if (!tr.starts_robot) return true;
      const std::size_t r = *tr.starts_robot;
      const task::Primitive& p = prog.programs[r].primitives[static_cast<std::size_t>(tr.starts_primitive)];
      return !p.segment || p.segment->master == prog.robots[r];
    });
    for (petri::TransitionId t : planned_order) {
      const petri::Transition& tr = net.transitions()[t];
      if (!tr.starts_robot) continue;
      const std::size_t r = *tr.starts_robot;
      const std::size_t k = static_cast<std::size_t>(tr.starts_primitive);
      PlannedCommand& c = plan.commands[r][k];
      if (c.reached) {
        // A loop runs its body again: the plan is the first pass's, but a move then starts from where the pass
        // before left the arm (the end of the body), which the estimate times (PlannedCommand::again_from).
        if (c.kind == task::PrimitiveKind::kMove && !c.goal.empty()) {
          runtime::RobotState& again = *model.find_robot(arms[r].cell);
          if (again.joints != c.from) c.again_from = again.joints;
          again.joints = c.goal;
          again.tcp = tcp_of(arms[r], again.joints);
        }
        continue;
      }
      c.reached = true;
      const task::Primitive& p = prog.programs[r].primitives[k];
      const Arm& arm = arms[r];
      runtime::RobotState& rs = *model.find_robot(arm.cell);
      switch (p.kind) {
        case task::PrimitiveKind::kMove: {
          if (auto l = lifting.find(arm.cell); l != lifting.end()) {
            queues[l->second].lifts.push_back(t);  // the move after the close lifts the part off the stop
            lifting.erase(l);
          }
          task::Target target = p.target;
          const bool to_part = target.kind == task::TargetKind::kAbove || target.kind == task::TargetKind::kAt;
          if (to_part && task::find_class(prog, target.object) != nullptr) {
            hand_peer.erase(arm.cell);
            const std::string label = target.object;
            const bool new_part = instance[arm.cell].count(label) == 0;
            bool fed = false;
            const std::string body = bind_class(arm.cell, label, &fed);
            const std::string& from = s.location_of(task::find_class(prog, label)->from);
            target.object = body.empty() ? from : body;
            if (new_part) {
              plan.class_takes.push_back({t, label, from, fed});
              if (const models::ConveyorSpec* belt = queue_belt_of(label)) queues[belt->name].takes.push_back(t);
              // A part that no feed brings has no body here: the class stays taken (by no body) until it is let go.
              if (body.empty()) instance[arm.cell][label] = "";
            }
            if (fed) {
              // Each time this move starts, it takes the next part fed (the feed's net, not a gate of its own).
              plan.feed_takes.push_back(t);
              ready_at.erase(body);
            }
          } else {
            target = bound(p.target);
            if (!to_part && target.kind != task::TargetKind::kHome) hand_peer[arm.cell] = target.object;
          }
          // A part still to come holds back the first move to it.
          if (target.kind == task::TargetKind::kAbove || target.kind == task::TargetKind::kAt) {
            if (auto b = on_belt.find(target.object); b != on_belt.end()) {
              plan.belt_rides.push_back({t, b->first, b->second.first, b->second.second});
              on_belt.erase(b);
            }
            if (auto it = ready_at.find(target.object); it != ready_at.end()) {
              if (it->second > 0) plan.gates.push_back({t, target.object, it->second, arrives_on[target.object]});
              ready_at.erase(it);
            }
          }
          c.from = rs.joints;
          if (auto h = held.find(arm.cell); h != held.end()) std::tie(c.held, c.grip) = h->second;
          if (auto f = closed.find(arm.cell); f != closed.end()) c.closed = f->second;
          runtime::MotionTarget mt;
          bool straight = false;
          if (p.segment) {
            // A coordinated block's segment, as robot control resolves it (segment_target.hpp): the follower's
            // target made from the master's, posted when the master's move was planned.
            const task::Segment& seg = *p.segment;
            runtime::SegmentMove move;
            move.robot = arm.cell;
            move.master = s.robot_of(seg.master);
            move.is_master = seg.master == c.robot;
            move.tool = tcp_of(arm, rs.joints);
            if (auto post = master_posts.find({seg.block, seg.index}); !move.is_master && post != master_posts.end()) {
              move.master_tool = post->second.tool;
              move.master_target = post->second.target;
            }
            mt = runtime::resolve_segment_target(model, target, seg, move, carries[{arm.cell, seg.block}], targets,
                                                 &straight);
          } else {
            mt = runtime::resolve_target(model, arm.cell, target, targets);
          }
          if (mt.resolution != runtime::MotionTarget::Resolution::kOk) {
            c.problem = mt.reason;
            break;
          }
          c.target = mt.description;
          const Eigen::VectorXd from = vec(rs.joints);
          std::optional<Eigen::VectorXd> goal;
          std::optional<Eigen::Isometry3d> goal_pose;  // the pose chosen (base frame)
          std::string why;
          if (!mt.joints.empty()) {
            goal = vec(mt.joints);
          } else {
            // As robot control chooses: the best-ranked pose the arm reaches, the nearest of those; for an arm on a
            // 5-axis controller, only poses it can be told (drivers::out_of_arm_plane).
            int best_rank = 0;
            for (std::size_t i = 0; i < mt.poses.size(); ++i) {
              const int rank = i < mt.rank.size() ? mt.rank[i] : 0;
              if (goal && rank > best_rank) continue;
              const Eigen::Isometry3d in_base = arm.base.inverse() * mt.poses[i];
              if (arm.five_axis && drivers::out_of_arm_plane(in_base) > runtime::MotionOptions{}.arm_plane_tolerance) {
                if (why.empty()) why = "no pose with the approach axis in the 5-axis arm's vertical plane";
                continue;
              }
              const models::IkResult ik = arm.chain.inverse(in_base, from);
              if (ik.status == models::IkStatus::kOk &&
                  (!goal || rank < best_rank || (ik.q - from).norm() < (*goal - from).norm())) {
                goal = ik.q;
                goal_pose = in_base;
                best_rank = rank;
              }
              if (ik.status != models::IkStatus::kOk && why.empty()) why = ik.reason;
            }
          }
          if (!goal) {
            const Eigen::Isometry3d& pose = mt.poses.front();
            c.problem = fmt::format(
                "no joint configuration puts its tool at ({:.3f}, {:.3f}, {:.3f}) pointing ({:.2f}, "
                "{:.2f}, {:.2f}){}: {}",
                pose.translation().x(), pose.translation().y(), pose.translation().z(), pose.linear()(0, 2),
                pose.linear()(1, 2), pose.linear()(2, 2),
                rs.hold ? fmt::format(" holding {}", rs.hold->workpiece) : std::string(), why);
            break;
          }
          c.goal.assign(goal->data(), goal->data() + goal->size());
          if (straight) c.line_to = goal_pose;
          if (p.segment && p.segment->master == c.robot && goal_pose) {
            master_posts[{p.segment->block, p.segment->index}] = {arm.base * *goal_pose, tcp_of(arm, rs.joints)};
          }
          rs.joints = c.goal;
          rs.tcp = tcp_of(arm, rs.joints);
          if (auto h = held.find(arm.cell); h != held.end()) {
            model.find_workpiece(h->second.first)->pose = tcp_of(arm, rs.joints) * h->second.second;
          }
          break;
        }
        case task::PrimitiveKind::kOpen:
        case task::PrimitiveKind::kClose: {
          if (p.kind == task::PrimitiveKind::kOpen) {
            closed.erase(arm.cell);
          } else {
            closed[arm.cell] = 0.0;
          }
          if (p.workpiece.empty()) break;
          const bool of_class = task::find_class(prog, p.workpiece) != nullptr;
          const std::string w = of_class ? bind_class(arm.cell, p.workpiece) : s.workpiece_of(p.workpiece);
          if (of_class && p.kind == task::PrimitiveKind::kOpen) instance[arm.cell].erase(p.workpiece);
          if (of_class && p.kind == task::PrimitiveKind::kClose) {
            if (const models::ConveyorSpec* belt = queue_belt_of(p.workpiece)) lifting[arm.cell] = belt->name;
          }
          if (w.empty()) {
            // A part of a class relayed over a belt has no body here: the fingers close on (and let go of) a part
            // like the one last let go of on that belt.
            const models::ConveyorSpec* belt = of_class ? queue_belt_of(p.workpiece) : nullptr;
            const auto last = belt != nullptr ? queue_body.find(belt->name) : queue_body.end();
            if (last != queue_body.end()) {
              c.contact = half_extent(*model.find_workpiece(last->second), tcp_of(arm, rs.joints).linear().col(1));
              if (p.kind == task::PrimitiveKind::kClose) closed[arm.cell] = *c.contact;
            }
            break;
          }
          runtime::WorkpieceState& ws = *model.find_workpiece(w);
          const Eigen::Isometry3d tcp = tcp_of(arm, rs.joints);
          c.contact = half_extent(ws, tcp.linear().col(1));  // the fingers slide along the tool's y axis (URDF)
          if (p.kind == task::PrimitiveKind::kClose) closed[arm.cell] = *c.contact;
          if (p.kind == task::PrimitiveKind::kClose) {
            rs.released_tcp.reset();
            held[arm.cell] = {w, tcp.inverse() * ws.pose};
            ws.held_by = arm.cell;
            // As robot control records it: held from above when the tool points down, else from the side.
            const bool down = tcp.linear().col(2).z() < -0.7;
            const double bottom = ws.pose.translation().z() - ws.size().z() / 2;
            rs.hold = runtime::Hold{w, down ? models::Approach::kDown : models::Approach::kSide,
                                    tcp.translation().z() - bottom};
            rs.hold->in_hand = held[arm.cell].second;
          } else {
            // As robot control records it: the hand departs straight up from where it let go (resolve_target).
            if (rs.hold) rs.released_tcp = tcp;
            // A body of the shift let go of over an exit conveyor rides out of the cell and is fed again.
            for (const sim::BeltExit& e : exits) {
              const std::optional<double> at = e.along(ws.pose.translation());
              if (!at || e.conveyor().speed <= 0 || !s.feed->feeds(w)) continue;
              const double distance = std::max(0.0, e.out_at() - *at);
              plan.deliveries.push_back({t, r, k, e.conveyor().name, distance, distance / e.conveyor().speed});
              break;
            }
            if (of_class) {
              // A part of a class let go of on a belt between robots: it rides to the stop (the queue's put).
              const Eigen::Vector3d bottom = ws.pose.translation() - Eigen::Vector3d(0, 0, ws.size().z() / 2);
              const models::ConveyorSpec* belt = running_belt_under(s.cell, bottom);
              if (between_robots(belt)) {
                MotionPlan::QueueBelt& q = queues[belt->name];
                q.puts.push_back(t);
                queue_body[belt->name] = w;
                const double along = (belt->pose.transform().inverse() * bottom).x() + belt->length / 2;
                Eigen::Isometry3d at_stop;
                q.ride = std::max(q.ride, ride_to_pick(*belt, *s.cell.find_workpiece(w), along, at_stop));
              }
            }
            if (!of_class) {
              const Eigen::Vector3d bottom = ws.pose.translation() - Eigen::Vector3d(0, 0, ws.size().z() / 2);
              if (const models::ConveyorSpec* belt = running_belt_under(s.cell, bottom)) {
                on_belt[w] = {belt->name, c.source};
                // It rides on to the stop bar (or the end): the next robot to go for it finds it there, at rest
                // (robot control waits until a part rests before it goes for it).
                const double along = (belt->pose.transform().inverse() * bottom).x() + belt->length / 2;
                ride_to_pick(*belt, *s.cell.find_workpiece(w), along, ws.pose);
              }
            }
            held.erase(arm.cell);
            rs.hold.reset();
            if (ws.held_by == arm.cell) ws.held_by.clear();
          }
          break;
        }
        case task::PrimitiveKind::kSignal:
        case task::PrimitiveKind::kWait:
        case task::PrimitiveKind::kLoop:
        case task::PrimitiveKind::kDevice:  // no motion: its time is the estimate's (estimate_cycle_time)
          break;
      }
      // A block's carry ends with its last segment (robot control forgets it then).
      if (p.segment && p.segment->index == p.segment->count) carries.erase({arm.cell, p.segment->block});
    }
    petri::fire_chosen(net, m, arbiter, chosen);
  }
  for (auto& [conveyor, q] : queues) {
    if (q.puts.empty() || q.takes.empty() || q.lifts.empty()) continue;
    q.conveyor = conveyor;
    plan.queue_belts.push_back(std::move(q));
  }
  return plan;
}

Estimate estimate_cycle_time(const Scenario& s, const petri::Net& net, const MotionPlan& plan,
                             const EstimateOptions& options) {
  Estimate est;
  const task::CompiledProgram& prog = s.program;
  std::vector<const RobotTiming*> timing;
  for (const std::string& label : prog.robots) {
    const std::string& cell_name = s.robot_of(label);
    auto it = options.robots.find(cell_name);
    CW_CHECK(it != options.robots.end(), "no timing for robot {}", cell_name);
    timing.push_back(&it->second);
  }
  CW_CHECK(plan.commands.size() == prog.robots.size(), "a motion plan of {} robots for a program of {}",
           plan.commands.size(), prog.robots.size());
  for (std::size_t r = 0; r < prog.robots.size(); ++r) {
    CW_CHECK(plan.commands[r].size() == prog.programs[r].primitives.size(),
             "robot {}: a motion plan of {} commands for {} primitives", prog.robots[r], plan.commands[r].size(),
             prog.programs[r].primitives.size());
  }
  est.notes = plan.problems();

  const double period = options.control_period, step = options.physics_step;
  CW_CHECK(period > 0 && step > 0, "control period {} s, physics step {} s", period, step);
  std::vector<double> durations(net.num_places(), 0.0);
  // A shift's deliveries: from the start of the open to the end of the period in which the world takes the part out.
  std::vector<double> delivered(plan.deliveries.size(), 0.0);
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> delivery_of;  // (robot, primitive) -> delivery
  for (std::size_t d = 0; d < plan.deliveries.size(); ++d) {
    delivery_of[{plan.deliveries[d].robot, plan.deliveries[d].primitive}] = d;
  }
  // A move's least duration as its driver tells it (sim_driver.hpp least_duration): a joint move's quintic profile,
  // or a straight line through the driver's waypoints within the tool-speed limit too (move_timing.hpp).
  std::vector<std::optional<models::KinematicChain>> chains(prog.robots.size());
  const auto least_move = [&](std::size_t r, const PlannedCommand& c, std::string& basis) {
    const RobotTiming& rt = *timing[r];
    CW_CHECK(rt.max_joint_speed.size() == c.goal.size(), "robot {}: {} joint speeds for {} joints", c.cell,
             rt.max_joint_speed.size(), c.goal.size());
    // A move a loop repeats is timed as its repeats make it (from the end of the body; see the top).
    const Eigen::VectorXd from = vec(c.again_from.empty() ? c.from : c.again_from), goal = vec(c.goal);
    if (c.line_to) {
      if (!chains[r]) chains[r].emplace(models::robot_chain(*s.cell.find_robot(c.cell)));
      const sim::StraightLine line =
          sim::straight_line(*chains[r], from, *c.line_to, rt.linear_step, rt.max_waypoint_step, rt.ik);
      if (line.problem.empty()) {
        basis = fmt::format("straight line of {:.3f} m through {} waypoints", line.tool_distance, line.points.size());
        return sim::least_move_duration(sim::JointPath(line.points, line.arc), line.tool_distance,
                                        vec(rt.max_joint_speed), rt.speed, rt.min_move_time, rt.max_tool_speed);
      }
      basis = fmt::format("joint move (the straight line cannot be followed: {}), ", line.problem);
    }
    Eigen::Index j = 0;
    const double largest = (goal - from).cwiseAbs().maxCoeff(&j);
    basis += fmt::format("joint move, largest step {:.3f} rad (joint {}){}", largest, j + 1,
                         c.again_from.empty() ? "" : ", as the loop repeats it");
    return sim::move_duration(from, goal, vec(rt.max_joint_speed), rt.speed, rt.min_move_time);
  };
  // Coordinated segments (docs/runtime.md, "Coordinated blocks"): both robots' moves take the agreed duration, the
  // longer of their least durations; segments are keyed as robot control keys them, by block and occurrence (the
  // n-th segment of the block the robot runs, from 0). The rendezvous: each robot posts its segment in its turn of
  // the round task control starts it in, the follower only once the master's post is there, and both submit from
  // the round after the later post: one period late when the master's turn comes before the follower's in the
  // round (robots take their turns in program order), two when it comes after.
  std::map<std::pair<std::string, std::size_t>, double> agreed;
  const auto segment_key = [](std::map<std::string, std::size_t>& counts, const task::Segment& seg) {
    return std::pair{seg.block, counts[seg.block]++};
  };
  const auto rendezvous = [&](const task::Segment& seg) {
    const auto index = [&](const std::string& label) {
      return std::find(prog.robots.begin(), prog.robots.end(), label) - prog.robots.begin();
    };
    return index(seg.master) < index(seg.follower) ? 1 : 2;
  };
  for (std::size_t r = 0; r < plan.commands.size(); ++r) {
    std::map<std::string, std::size_t> counts;
    for (const PlannedCommand& c : plan.commands[r]) {
      const task::Primitive& p = prog.programs[r].primitives[c.primitive];
      if (!p.segment) continue;
      const auto key = segment_key(counts, *p.segment);
      if (c.kind != task::PrimitiveKind::kMove || c.goal.empty()) continue;
      std::string basis;
      double& both = agreed[key];
      both = std::max(both, least_move(r, c, basis));
    }
  }
  for (std::size_t r = 0; r < plan.commands.size(); ++r) {
    const RobotTiming& rt = *timing[r];
    std::map<std::string, std::size_t> counts;  // segments per block so far
    // Bring-up: the driver homes (the arm to its home joints, the fingers opening), then robot control activates it
    // and takes the first command in the next round.
    const double home = std::max(rt.min_move_time, sim::kFingerMinTime + sim::kFingerRestWindow);
    durations[*net.find_place(task::start_place_id(prog.robots[r]))] = lockstep_span(home, false, period, step);
    double fingers = rt.finger_open;  // where the finger ramp stands (homing opened the fingers)
    // Each loop's body twice: the second pass times its grips from where the body's end left the fingers, as the
    // loop's repeats find them; its durations are the ones kept (the net times every pass so, the first too).
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < plan.commands[r].size(); ++k) {
      order.push_back(k);
      const task::Primitive& p = prog.programs[r].primitives[k];
      if (p.kind != task::PrimitiveKind::kLoop) continue;
      const task::Loop& loop = prog.programs[r].loops.at(static_cast<std::size_t>(p.loop));
      for (std::size_t b = loop.begin; b < loop.end; ++b) order.push_back(b);
    }
    const std::size_t first = est.commands.size();
    for (std::size_t k : order) {
      const PlannedCommand& c = plan.commands[r][k];
      CommandEstimate ce;
      ce.robot = c.robot;
      ce.primitive = c.primitive;
      ce.command = c.command;
      const task::Segment* segment = prog.programs[r].primitives[c.primitive].segment ?
                                         &*prog.programs[r].primitives[c.primitive].segment : nullptr;
      if (c.kind == task::PrimitiveKind::kMove) {
        if (c.goal.empty()) {
          ce.motion = rt.min_move_time;
          ce.basis = c.reached ? "move that cannot be made" : "not reached";
        } else {
          ce.motion = least_move(r, c, ce.basis);
        }
        ce.seconds = lockstep_span(ce.motion, true, period, step);
      } else if (c.kind == task::PrimitiveKind::kOpen) {
        // Letting go of a part the fingers closed on is a release (sim_driver.hpp): from the part's faces to
        // release_clearance beyond them, the part free at once. Any other open opens fully from where the ramp stands.
        const bool releases = c.contact && *c.contact > fingers && *c.contact > rt.finger_closed;
        const double from = releases ? *c.contact : fingers;
        const double to = releases ? std::min(*c.contact + rt.release_clearance, rt.finger_open) : rt.finger_open;
        ce.motion = sim::finger_ramp_duration(from, to, rt.finger_speed) + sim::kFingerRestWindow;
        ce.basis = fmt::format("fingers {} from {:.4f} m to {:.4f} m at {:.3f} m/s", releases ? "release" : "open",
                               from, to, rt.finger_speed);
        if (auto d = delivery_of.find({r, c.primitive}); d != delivery_of.end()) {
          // The part rides from when the fingers' ramp passes its faces (at once if they no longer press it), and is
          // taken out at the end of the period in which it reaches the exit point.
          const double release =
              !releases && c.contact && *c.contact > fingers
                  ? sim::finger_ramp_time_to(fingers, rt.finger_open, *c.contact, rt.finger_speed).value_or(ce.motion)
                  : 0.0;
          const double out = std::ceil(release / step - 1e-9) * step + plan.deliveries[d->second].ride;
          delivered[d->second] = (std::floor(out / period + 1e-9) + 1) * period;
          ce.basis += fmt::format(
              "; lets go of the part after {:.2f} s, {:.3f} m before it leaves the cell on {}: "
              "a body free again {:.2f} s after the open starts",
              release, plan.deliveries[d->second].distance, plan.deliveries[d->second].conveyor, delivered[d->second]);
        }
        fingers = to;
        ce.seconds = lockstep_span(ce.motion, false, period, step);
      } else if (c.kind == task::PrimitiveKind::kClose) {
        const std::optional<double> press =
            c.contact && fingers > rt.finger_closed
                ? sim::finger_press_time(fingers, rt.finger_closed, *c.contact, rt.finger_squeeze, rt.finger_speed)
                : std::nullopt;
        if (press) {
          ce.motion = *press + sim::kFingerRestWindow;
          ce.basis = fmt::format("fingers close from {:.4f} m on a part {:.4f} m wide at {:.3f} m/s", fingers,
                                 2 * *c.contact, rt.finger_speed);
        } else {
          ce.motion = sim::finger_ramp_duration(fingers, rt.finger_closed, rt.finger_speed) + sim::kFingerRestWindow;
          ce.basis = fmt::format("fingers close from {:.4f} m to {:.4f} m at {:.3f} m/s", fingers, rt.finger_closed,
                                 rt.finger_speed);
        }
        fingers = rt.finger_closed;  // the ramp runs on to fully closed (see the top)
        ce.seconds = lockstep_span(ce.motion, false, period, step);
      } else if (c.kind == task::PrimitiveKind::kDevice) {
        // Device control takes a command in the round task control sends it; a machine answers its start at the next
        // physics step and is done process_time after (on the twin: world.hpp), counted from the wait's start (the
        // wait is taken to follow the start at once); a belt's coil and a photo-eye that is on take the round itself
        // (a part's arrival is the pick's gate, not the eye's).
        const task::Primitive& p = prog.programs[r].primitives[c.primitive];
        const models::MachineSpec* machine = s.cell.find_machine(p.device);
        if (p.op == task::DeviceOp::kStart) {
          ce.motion = step;
          ce.basis = fmt::format("machine {} answers its start at the next physics step", p.device);
          ce.seconds = lockstep_span(ce.motion, false, period, step);
        } else if (p.op == task::DeviceOp::kAwaitDone && machine != nullptr) {
          ce.motion = machine->process_time;
          ce.basis = fmt::format("machine {} processes for {:.2f} s", p.device, machine->process_time);
          ce.seconds = lockstep_span(ce.motion, false, period, step);
        } else {
          ce.basis = "device command, done in its round";
          ce.seconds = period;
        }
      } else {
        ce.basis = "net only";  // signal, wait, a loop's end
      }
      if (segment != nullptr) {
        const auto key = segment_key(counts, *segment);
        if (c.kind == task::PrimitiveKind::kMove && !c.goal.empty()) {
          ce.basis += fmt::format("; segment {} of {}: {:.3f} s, the longer arm's", segment->index, segment->block,
                                  agreed.at(key));
          ce.motion = agreed.at(key);
          ce.seconds = lockstep_span(ce.motion, true, period, step);
        }
        ce.seconds += rendezvous(*segment) * period;
      }
      durations[*net.find_place(task::place_id(c.robot, c.primitive))] = ce.seconds;
      if (first + k < est.commands.size()) {
        est.commands[first + k] = std::move(ce);  // the loop's repeat
      } else {
        est.commands.push_back(std::move(ce));
      }
    }
  }
  // A part seen at rest is taken in the round after it came to rest.
  std::vector<ArrivalGate> gates = plan.gates;
  for (ArrivalGate& g : gates) g.ready = std::ceil(g.ready / period - 1e-9) * period;
  est.timed_net = with_arrivals(net, gates, durations);
  if (!plan.feed_takes.empty()) est.timed_net = with_feed(est.timed_net, *s.feed, plan, delivered, period, durations);
  if (!plan.queue_belts.empty()) est.timed_net = with_queue_belts(est.timed_net, plan, period, durations);
  est.place_duration = durations;
  task::LoopControl loops(est.timed_net, prog);
  est.run = simulate_timed(est.timed_net, durations, 1'000'000, &loops);
  // The transitions added to the program's net come after its own.
  for (auto f = est.run.firings.rbegin(); f != est.run.firings.rend(); ++f) {
    if (f->transition < net.num_transitions()) {
      est.cycle_time = f->time;
      break;
    }
  }
  return est;
}

}  // namespace cellwright::cell
