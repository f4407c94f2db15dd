#include "cellwright/task/to_net.hpp"

#include <fmt/format.h>

#include <map>

namespace cellwright::task {

std::string place_id(const std::string& robot, std::size_t primitive) {
  return fmt::format("{}.p{}", robot, primitive);
}
std::string transition_id(const std::string& robot, std::size_t primitive) {
  return fmt::format("{}.t{}", robot, primitive);
}
std::string loop_again_transition_id(const std::string& robot, std::size_t primitive) {
  return fmt::format("{}.again{}", robot, primitive);
}
std::string start_place_id(const std::string& robot) {
  return robot + ".start";
}
std::string done_place_id(const std::string& robot) {
  return robot + ".done";
}
std::string event_place_id(const std::string& event) {
  return "ev." + event;
}

namespace {

petri::Origin origin_of(const std::string& robot, const Primitive& p, std::size_t index) {
  petri::Origin o;
  o.robot = robot;
  o.line = p.where.line;
  o.column = p.where.column;
  o.task = p.task;
  o.motion = p.motion;
  o.primitive = static_cast<int>(index);
  return o;
}

}  // namespace

petri::Net to_net(const CompiledProgram& program) {
  CW_CHECK(program.programs.size() == program.robots.size(), "{} robot programs for {} robots", program.programs.size(),
           program.robots.size());
  petri::NetBuilder b(program.file.empty() ? std::string("program") : program.file);
  b.set_robots(program.robots);

  // Shared places first: events/semaphores and region resources.
  std::map<std::string, petri::PlaceId> shared;
  for (const Semaphore& s : program.semaphores) {
    petri::Place p;
    p.id = event_place_id(s.name);
    p.name = s.region            ? fmt::format("region {} free", s.name)
             : !s.device.empty() ? fmt::format("device {}", s.name)
                                 : fmt::format("event {}", s.name);
    p.initial = s.initial;
    p.kind = s.region ? petri::PlaceKind::kRegion : petri::PlaceKind::kEvent;
    p.origin.line = s.declared.line;
    p.origin.column = s.declared.column;
    shared[s.name] = b.add_place(std::move(p));
  }
  auto shared_place = [&](const std::string& robot, const Primitive& prim) {
    auto it = shared.find(prim.event);
    if (it == shared.end()) {
      throw InputError(prim.where,
                       fmt::format("robot {}: {} of undeclared event '{}'", robot, to_string(prim.kind), prim.event));
    }
    return it->second;
  };
  // A loop's decision event (loopL.LEADER>FOLLOWER.again/exit), which compile() inserts.
  auto decision_place = [&](const std::string& robot, const Primitive& prim, const std::string& event) {
    auto it = shared.find(event);
    if (it == shared.end()) {
      throw InputError(prim.where, fmt::format("robot {}: {} needs the undeclared event '{}'", robot, to_string(prim),
                                               event));
    }
    return it->second;
  };

  std::vector<petri::Arc> final_places;
  // Robot chains; remember each robot's primitive places for the regions.
  std::map<std::string, std::vector<petri::PlaceId>> chain;
  for (std::size_t r = 0; r < program.programs.size(); ++r) {
    const RobotProgram& rp = program.programs[r];
    CW_CHECK(rp.robot == program.robots[r], "program {} is for '{}', expected '{}'", r, rp.robot, program.robots[r]);
    const auto& prims = rp.primitives;
    // The loop each kLoop primitive closes, checked against the program's loop table.
    auto loop_of = [&](std::size_t k) -> const Loop& {
      const int l = prims[k].loop;
      CW_CHECK(l >= 0 && static_cast<std::size_t>(l) < rp.loops.size(), "robot {} primitive {}: loop {} of {}",
               rp.robot, k, l, rp.loops.size());
      const Loop& loop = rp.loops[static_cast<std::size_t>(l)];
      CW_CHECK(loop.end == k && loop.begin <= loop.end, "robot {} loop {}: body [{}, {}) closed by primitive {}",
               rp.robot, loop.name, loop.begin, loop.end, k);
      return loop;
    };
    auto leads = [&](const Loop& loop) { return loop.leader == rp.robot; };

    petri::Place start;
    start.id = start_place_id(rp.robot);
    start.name = fmt::format("{} ready", rp.robot);
    start.initial = 1;
    start.kind = petri::PlaceKind::kStart;
    start.origin.robot = rp.robot;
    const petri::PlaceId start_id = b.add_place(std::move(start));

    std::vector<petri::PlaceId>& places = chain[rp.robot];
    for (std::size_t k = 0; k < prims.size(); ++k) {
      petri::Place p;
      p.id = place_id(rp.robot, k);
      if (prims[k].kind == PrimitiveKind::kLoop) {
        // The leader decides at once (an instant primitive); a follower waits for the leader's decision.
        const Loop& loop = loop_of(k);
        // A paced leader may wait there too: for each follower to have taken its previous decision.
        p.name = leads(loop) ? fmt::format("{} deciding {} (repeat {})", rp.robot, loop.name, loop.count)
                             : fmt::format("{} waiting for {} decision", rp.robot, loop.name);
        p.kind = leads(loop) && !loop.paced ? petri::PlaceKind::kExecuting : petri::PlaceKind::kWaiting;
      } else {
        const bool waiting = prims[k].kind == PrimitiveKind::kWait;
        p.name = waiting ? fmt::format("{} waiting for {}", rp.robot, prims[k].event)
                         : fmt::format("{} executing {}", rp.robot, to_string(prims[k]));
        p.kind = waiting ? petri::PlaceKind::kWaiting : petri::PlaceKind::kExecuting;
      }
      p.origin = origin_of(rp.robot, prims[k], k);
      places.push_back(b.add_place(std::move(p)));
    }

    petri::Place done;
    done.id = done_place_id(rp.robot);
    done.name = fmt::format("{} done", rp.robot);
    done.kind = petri::PlaceKind::kDone;
    done.origin.robot = rp.robot;
    const petri::PlaceId done_id = b.add_place(std::move(done));
    final_places.push_back({done_id, 1});

    // Tk: end of primitive k-1, begin of primitive k (k == n: end of the program).
    for (std::size_t k = 0; k <= prims.size(); ++k) {
      petri::Transition t;
      t.id = transition_id(rp.robot, k);
      t.inputs.push_back({k == 0 ? start_id : places[k - 1], 1});
      if (k > 0 && prims[k - 1].kind == PrimitiveKind::kWait) {
        t.inputs.push_back({shared_place(rp.robot, prims[k - 1]), 1});
      }
      t.outputs.push_back({k == prims.size() ? done_id : places[k], 1});
      if (k > 0 && prims[k - 1].kind == PrimitiveKind::kLoop) {
        // The exit of a loop: the leader tells each follower; a follower goes on once told.
        const Loop& loop = loop_of(k - 1);
        if (leads(loop)) {
          for (const std::string& f : loop.followers) {
            t.outputs.push_back({decision_place(rp.robot, prims[k - 1], loop_exit_event(loop, f)), 1});
            if (loop.paced) t.inputs.push_back({decision_place(rp.robot, prims[k - 1], loop_taken_event(loop, f)), 1});
          }
        } else {
          t.inputs.push_back({decision_place(rp.robot, prims[k - 1], loop_exit_event(loop, rp.robot)), 1});
          if (loop.paced) {
            t.outputs.push_back({decision_place(rp.robot, prims[k - 1], loop_taken_event(loop, rp.robot)), 1});
          }
        }
      }
      if (k < prims.size() && prims[k].kind == PrimitiveKind::kSignal) {
        // If the robot just waited for the same event, this is a self-loop (consume, then produce): kept as two
        // arcs, since the wait must still find a token.
        t.outputs.push_back({shared_place(rp.robot, prims[k]), 1});
      }
      if (k < prims.size()) {
        t.name = fmt::format("{} begin {}", rp.robot, to_string(prims[k]));
        t.origin = origin_of(rp.robot, prims[k], k);
        t.starts_robot = static_cast<std::uint32_t>(r);
        t.starts_primitive = static_cast<int>(k);
      } else {
        t.name = fmt::format("{} finish", rp.robot);
        t.origin.robot = rp.robot;
        if (!prims.empty()) {
          t.origin = origin_of(rp.robot, prims.back(), prims.size() - 1);
          t.origin.primitive = -1;
        }
      }
      b.add_transition(std::move(t));
    }

    // Each loop's again: from its kLoop place back to the body's first primitive, which it begins as Tb does.
    for (std::size_t k = 0; k < prims.size(); ++k) {
      if (prims[k].kind != PrimitiveKind::kLoop) continue;
      const Loop& loop = loop_of(k);
      petri::Transition t;
      t.id = loop_again_transition_id(rp.robot, k);
      t.name = fmt::format("{} repeat {}", rp.robot, loop.name);
      t.inputs.push_back({places[k], 1});
      t.outputs.push_back({places[loop.begin], 1});
      if (leads(loop)) {
        for (const std::string& f : loop.followers) {
          t.outputs.push_back({decision_place(rp.robot, prims[k], loop_again_event(loop, f)), 1});
          if (loop.paced) t.inputs.push_back({decision_place(rp.robot, prims[k], loop_taken_event(loop, f)), 1});
        }
      } else {
        t.inputs.push_back({decision_place(rp.robot, prims[k], loop_again_event(loop, rp.robot)), 1});
        if (loop.paced) t.outputs.push_back({decision_place(rp.robot, prims[k], loop_taken_event(loop, rp.robot)), 1});
      }
      if (prims[loop.begin].kind == PrimitiveKind::kSignal) {
        t.outputs.push_back({shared_place(rp.robot, prims[loop.begin]), 1});
      }
      t.origin = origin_of(rp.robot, prims[k], k);
      t.starts_robot = static_cast<std::uint32_t>(r);
      t.starts_primitive = static_cast<int>(loop.begin);
      b.add_transition(std::move(t));
    }
  }

  for (const RegionUse& use : program.regions) {
    petri::Region region;
    region.name = use.name;
    region.capacity = 1;
    for (const RegionSpan& span : use.spans) {
      auto it = chain.find(span.robot);
      CW_CHECK(it != chain.end(), "region {} names unknown robot {}", use.name, span.robot);
      CW_CHECK(span.begin <= span.end && span.end <= it->second.size(), "region {} span [{}, {}) of {} primitives",
               use.name, span.begin, span.end, it->second.size());
      for (std::size_t k = span.begin; k < span.end; ++k) region.inside.push_back(it->second[k]);
    }
    b.add_region(std::move(region));
  }
  b.set_final(std::move(final_places));
  return std::move(b).build();
}

}  // namespace cellwright::task
