// Compilation: task level -> motion level -> primitives, with compile-time tracking of who holds which workpiece and
// which regions each robot is inside. The expansions and event names are documented in docs/task-language.md.
#include "cellwright/task/compile.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <optional>
#include <utility>

namespace cellwright::task {
namespace {

// Appends primitives to one robot's program, all with the same task-level provenance.
class Emitter {
 public:
  Emitter(std::vector<Primitive>& out, SourceLocation where, std::string task)
      : out_(out), where_(std::move(where)), task_(std::move(task)) {}

  // Sets the motion-level command of the primitives that follow.
  Emitter& motion(std::string m) {
    motion_ = std::move(m);
    return *this;
  }
  Emitter& move(TargetKind kind, const std::string& object) {
    Primitive& p = add(PrimitiveKind::kMove);
    p.target = {kind, object};
    return *this;
  }
  Emitter& open(const std::string& workpiece) {
    add(PrimitiveKind::kOpen).workpiece = workpiece;
    return *this;
  }
  Emitter& close(const std::string& workpiece) {
    add(PrimitiveKind::kClose).workpiece = workpiece;
    return *this;
  }
  Emitter& signal(const std::string& event) {
    add(PrimitiveKind::kSignal).event = event;
    return *this;
  }
  Emitter& wait(const std::string& event) {
    add(PrimitiveKind::kWait).event = event;
    return *this;
  }
  Emitter& loop(int index) {
    add(PrimitiveKind::kLoop).loop = index;
    return *this;
  }
  Emitter& device(const std::string& name, DeviceOp op) {
    Primitive& p = add(PrimitiveKind::kDevice);
    p.device = name;
    p.op = op;
    return *this;
  }

 private:
  Primitive& add(PrimitiveKind kind) {
    Primitive& p = out_.emplace_back();
    p.kind = kind;
    p.where = where_;
    p.task = task_;
    p.motion = motion_;
    return p;
  }

  std::vector<Primitive>& out_;
  SourceLocation where_;
  std::string task_;
  std::string motion_;
};

class Compiler {
 public:
  explicit Compiler(const Program& program) : program_(program) {}

  CompiledProgram run() {
    out_.file = program_.file;
    out_.robots = declared_names(program_, NameKind::kRobot);
    for (const Declaration& d : program_.declarations) {
      if (d.kind != NameKind::kWorkpiece) continue;
      if (d.from.empty()) {
        out_.workpieces.push_back(d.name);
      } else {
        out_.classes.push_back({d.name, d.from, d.where});
      }
    }
    out_.locations = declared_names(program_, NameKind::kLocation);
    out_.machines = declared_names(program_, NameKind::kMachine);
    out_.conveyors = declared_names(program_, NameKind::kConveyor);
    for (const Declaration& d : program_.declarations) {
      if (d.kind == NameKind::kSensor) {
        out_.sensors.push_back({d.name, d.from});
        sensor_conveyor_[d.name] = d.from;
      }
    }
    for (std::size_t r = 0; r < out_.robots.size(); ++r) {
      robot_index_[out_.robots[r]] = r;
      out_.programs.push_back({out_.robots[r], {}, {}});
    }
    state_.resize(out_.robots.size());
    for (const Declaration& d : program_.declarations) {
      if (d.kind == NameKind::kSemaphore) out_.semaphores.push_back({d.name, d.initial, false, d.where, false, {}});
      if (d.kind == NameKind::kRegion) {
        out_.semaphores.push_back({d.name, 1, true, d.where, false, {}});
        region_index_[d.name] = out_.regions.size();
        out_.regions.push_back({d.name, {}});
      }
    }
    // Each device's states, after the user's semaphores and before the events inserted below.
    for (const Declaration& d : program_.declarations) {
      if (d.kind == NameKind::kMachine) {
        add_state(d, kIdle, 1);
        add_state(d, kLoaded, 0);
        add_state(d, kBusy, 0);
        add_state(d, kDone, 0);
      } else if (d.kind == NameKind::kConveyor) {
        add_state(d, kStopped, 1);
        add_state(d, kRunning, 0);
      }
    }
    // The coordinated blocks and their segments, compiled into a robot's program where it runs the block.
    for (const CoordinatedBlock& b : program_.blocks) {
      CoordinatedUse use;
      use.name = b.name;
      use.where = b.where;
      use.master = b.master;
      use.follower = b.follower;
      use.workpiece = b.body.front().argument;
      block_index_[b.name] = out_.coordinated.size();
      out_.coordinated.push_back(std::move(use));
      block_segments_.push_back(segments_of(b));
      for (const SegmentPlan& seg : block_segments_.back()) out_.coordinated.back().segments.push_back(seg.motion);
    }
    // Blocks in source order, so the first error in the file is the one reported.
    bool table_done = !program_.steps.has_value();
    for (const Sequence& seq : program_.sequences) {
      if (!table_done && program_.steps->where.line < seq.where.line) {
        compile_table(*program_.steps);
        table_done = true;
      }
      compile_sequence(seq);
    }
    if (!table_done) compile_table(*program_.steps);
    join_loops();
    return std::move(out_);
  }

 private:
  struct Holding {
    std::string workpiece;
    int line = 0;  // where it was picked or received
  };
  struct Inside {
    std::string region;
    SourceLocation entered;  // the enter command
    std::size_t begin = 0;   // index of the primitive after the region's wait
  };
  struct RobotState {
    std::optional<Holding> holding;
    std::vector<Inside> inside;
  };
  // A robot at the start of a loop's body: where its body begins and what it holds and is inside.
  struct LoopStart {
    std::size_t begin = 0;
    RobotState state;
  };

  [[noreturn]] static void fail(const SourceLocation& where, std::string problem) {
    throw InputError(where, std::move(problem));
  }

  std::size_t robot(const std::string& name) const {
    const auto it = robot_index_.find(name);
    CW_CHECK(it != robot_index_.end(), "'{}' is not a declared robot; was the program made by parse_program?", name);
    return it->second;
  }

  std::vector<Primitive>& primitives(std::size_t r) { return out_.programs[r].primitives; }

  void add_event(const std::string& name, const SourceLocation& where) {
    out_.semaphores.push_back({name, 0, false, where, true, {}});
  }

  // A device's states (compiled.hpp, Semaphore::device).
  static constexpr const char* kIdle = "idle";
  static constexpr const char* kLoaded = "loaded";
  static constexpr const char* kBusy = "busy";
  static constexpr const char* kDone = "done";
  static constexpr const char* kStopped = "stopped";
  static constexpr const char* kRunning = "running";
  void add_state(const Declaration& d, const char* state, std::uint32_t initial) {
    out_.semaphores.push_back({device_state_event(d.name, state), initial, false, d.where, false, d.name});
  }
  static std::string state(const std::string& device, const char* s) { return device_state_event(device, s); }

  // A device action bracketed by its states: wait until the device is in `from`, act, then put it in `to`.
  static void device_step(Emitter& emit, const std::string& device, const char* from, DeviceOp op, const char* to) {
    emit.wait(state(device, from)).device(device, op).signal(state(device, to));
  }

  static std::string held_since(const Holding& h) { return fmt::format("{} (since line {})", h.workpiece, h.line); }

  bool is_class(const std::string& workpiece) const { return find_class(out_, workpiece) != nullptr; }

  // Every command but Put/Get. `table` lists the robots whose holdings are ordered with this command (the steps
  // table's robots, in line order); sequences run unsynchronised, so their holdings are only tracked per robot.
  void compile_command(std::size_t r, const Command& cmd, const std::vector<std::size_t>& table) {
    const std::string& name = out_.robots[r];
    RobotState& st = state_[r];
    Emitter emit(primitives(r), cmd.where, to_string(cmd));
    const std::string& x = cmd.argument;
    switch (cmd.kind) {
      case CommandKind::kPick: {
        if (st.holding)
          fail(cmd.where, fmt::format("{} cannot pick {}: it is already holding {}", name, x, held_since(*st.holding)));
        // Parts of a class are different parts: two robots may each hold one (a pipeline).
        for (std::size_t other : table) {
          const auto& h = state_[other].holding;
          if (other != r && h && h->workpiece == x && !is_class(x)) {
            fail(cmd.argument_where, fmt::format("{} cannot pick {}: robot {} is holding it (since line {})", name, x,
                                                 out_.robots[other], h->line));
          }
        }
        // Out of a machine: only once its cycle is done; the machine is idle again once the part is lifted out.
        const std::string& m = cmd.machine;
        if (!m.empty()) emit.motion("unload " + m).wait(state(m, kDone));
        emit.motion("approach " + x).open("").move(TargetKind::kAbove, x);
        emit.motion("grasp " + x).move(TargetKind::kAt, x).close(x);
        emit.motion("lift up " + x).move(TargetKind::kAbove, x);
        if (!m.empty()) emit.motion("unload " + m).signal(state(m, kIdle));
        st.holding = Holding{x, cmd.where.line};
        return;
      }
      case CommandKind::kPlace: {
        if (!st.holding) fail(cmd.where, fmt::format("{} cannot place on {}: it is holding nothing", name, x));
        const std::string w = st.holding->workpiece;
        if (w == x) fail(cmd.argument_where, fmt::format("{} cannot place {} on itself", name, x));
        if (const WorkpieceClass* c = find_class(out_, x)) {
          fail(cmd.argument_where, fmt::format("{} cannot place on {}: it is a workpiece class (whichever part "
                                               "arrives at {}); place on a location or a named workpiece",
                                               name, x, c->from));
        }
        // Into a machine: only while it is idle (empty); then it is loaded.
        const bool machine = cmd.argument_kind == NameKind::kMachine;
        if (machine) emit.motion("load " + x).wait(state(x, kIdle));
        emit.motion("approach " + x).move(TargetKind::kAbove, x);
        emit.motion("put down " + w).move(TargetKind::kAt, x);
        emit.motion("release " + w).open(w);
        emit.motion("depart " + x).move(TargetKind::kAbove, x);
        if (machine) emit.motion("load " + x).signal(state(x, kLoaded));
        st.holding.reset();
        return;
      }
      case CommandKind::kSignal:
        emit.motion("signal " + x).signal(x);
        return;
      case CommandKind::kWait:
        if (cmd.argument_kind == NameKind::kMachine) {
          device_step(emit.motion("wait for " + x + " done"), x, kBusy, DeviceOp::kAwaitDone, kDone);
        } else if (cmd.argument_kind == NameKind::kSensor) {
          // A photo-eye sees a part its conveyor brings: the wait holds the conveyor running while it lasts.
          const auto c = sensor_conveyor_.find(x);
          CW_CHECK(c != sensor_conveyor_.end(), "sensor '{}' has no conveyor", x);
          emit.motion("wait for " + x).wait(state(c->second, kRunning)).device(x, DeviceOp::kAwaitOn);
          emit.signal(state(c->second, kRunning));
        } else {
          emit.motion("wait " + x).wait(x);
        }
        return;
      case CommandKind::kStart:
        device_step(emit.motion("start " + x), x, kLoaded, DeviceOp::kStart, kBusy);
        return;
      case CommandKind::kRun:
        device_step(emit.motion("run " + x), x, kStopped, DeviceOp::kRun, kRunning);
        return;
      case CommandKind::kAccumulate:
        device_step(emit.motion("accumulate " + x), x, kStopped, DeviceOp::kAccumulate, kRunning);
        return;
      case CommandKind::kStop:
        device_step(emit.motion("stop " + x), x, kRunning, DeviceOp::kStop, kStopped);
        return;
      case CommandKind::kHome:
        emit.motion("home").move(TargetKind::kHome, "");
        return;
      case CommandKind::kPark:
        emit.motion("park").move(TargetKind::kPark, "");
        return;
      case CommandKind::kEnter: {
        for (const Inside& in : st.inside) {
          if (in.region == x) {
            fail(cmd.where,
                 fmt::format("{} is already inside region {} (entered on line {})", name, x, in.entered.line));
          }
        }
        emit.motion("enter " + x).wait(x);
        st.inside.push_back({x, cmd.where, primitives(r).size()});
        return;
      }
      case CommandKind::kLeave: {
        const auto it =
            std::find_if(st.inside.begin(), st.inside.end(), [&](const Inside& in) { return in.region == x; });
        if (it == st.inside.end()) {
          fail(cmd.where, fmt::format("{} cannot leave region {}: it is not inside it", name, x));
        }
        const auto region = region_index_.find(x);
        CW_CHECK(region != region_index_.end(), "'{}' is not a declared region", x);
        out_.regions[region->second].spans.push_back({name, it->begin, primitives(r).size()});
        emit.motion("leave " + x).signal(x);
        st.inside.erase(it);
        return;
      }
      case CommandKind::kCoordinate:
        compile_coordinate(r, cmd, table);
        return;
      case CommandKind::kVia:
        CW_CHECK(false, "'via' outside a coordinated block at line {}; was the program made by parse_program?",
                 cmd.where.line);
        return;
      case CommandKind::kPut:
      case CommandKind::kGet:
        fail(cmd.where, fmt::format("{} is only allowed in the steps table, where the matching {} stands on the "
                                    "same line",
                                    to_string(cmd.kind), cmd.kind == CommandKind::kPut ? "Get" : "Put"));
    }
  }

  // One segment of a coordinated block: a move to a target, or a gripper action.
  struct SegmentPlan {
    PrimitiveKind kind = PrimitiveKind::kMove;
    Target target;          // kMove
    std::string workpiece;  // kOpen/kClose
    std::string motion;     // "approach beam"
  };

  // The segments of a block's body: Pick W (open, above W, at W, close W, above W), each via X (above X), Place X
  // (above X, at X, open W, above X).
  static std::vector<SegmentPlan> segments_of(const CoordinatedBlock& b) {
    std::vector<SegmentPlan> out;
    const std::string& w = b.body.front().argument;
    auto move = [&](TargetKind k, const std::string& object, std::string motion) {
      out.push_back({PrimitiveKind::kMove, {k, object}, {}, std::move(motion)});
    };
    auto grip = [&](PrimitiveKind k, const std::string& workpiece, std::string motion) {
      out.push_back({k, {}, workpiece, std::move(motion)});
    };
    for (const Command& cmd : b.body) {
      const std::string& x = cmd.argument;
      switch (cmd.kind) {
        case CommandKind::kPick:
          grip(PrimitiveKind::kOpen, "", "open for " + w);
          move(TargetKind::kAbove, w, "approach " + w);
          move(TargetKind::kAt, w, "grasp " + w);
          grip(PrimitiveKind::kClose, w, "grasp " + w);
          move(TargetKind::kAbove, w, "lift up " + w);
          break;
        case CommandKind::kVia:
          move(TargetKind::kAbove, x, "carry " + w + " via " + x);
          break;
        case CommandKind::kPlace:
          move(TargetKind::kAbove, x, "approach " + x);
          move(TargetKind::kAt, x, "put down " + w);
          grip(PrimitiveKind::kOpen, w, "release " + w);
          move(TargetKind::kAbove, x, "depart " + x);
          break;
        default:
          CW_CHECK(false, "coordinated block {}: '{}' in its body; was the program made by parse_program?", b.name,
                   to_string(cmd));
      }
    }
    return out;
  }

  // `coordinate B` by robot r: the block's segments, each between barrier pairs with the other robot of the block.
  void compile_coordinate(std::size_t r, const Command& cmd, const std::vector<std::size_t>& table) {
    const std::string& name = out_.robots[r];
    const auto bi = block_index_.find(cmd.argument);
    CW_CHECK(bi != block_index_.end(), "'{}' is not a coordinated block", cmd.argument);
    CoordinatedUse& use = out_.coordinated[bi->second];
    const std::vector<SegmentPlan>& segments = block_segments_[bi->second];
    if (name != use.master && name != use.follower) {
      fail(cmd.argument_where, fmt::format("{} cannot run coordinated block {}: its robots are {} (master) and {} "
                                           "(follower), declared on line {}",
                                           name, use.name, use.master, use.follower, use.where.line));
    }
    for (const CoordinatedUse::Run& run : use.runs) {
      if (run.robot == name) {
        fail(cmd.where, fmt::format("{} already runs coordinated block {} on line {}: a robot runs a block at one "
                                    "place in its program (put it in a loop to repeat it, or declare a second "
                                    "block)",
                                    name, use.name, run.where.line));
      }
    }
    RobotState& st = state_[r];
    if (st.holding) {
      fail(cmd.where, fmt::format("{} cannot run coordinated block {}: it is holding {}, and the block begins by "
                                  "picking {}",
                                  name, use.name, held_since(*st.holding), use.workpiece));
    }
    for (std::size_t other : table) {
      const auto& h = state_[other].holding;
      if (other != r && h && h->workpiece == use.workpiece) {
        fail(cmd.where, fmt::format("{} cannot run coordinated block {}: robot {} is holding {} (since line {})", name,
                                    use.name, out_.robots[other], use.workpiece, h->line));
      }
    }
    const std::string& partner = name == use.master ? use.follower : use.master;
    const int count = static_cast<int>(segments.size());
    if (use.runs.empty()) {
      // The block's events, once, in barrier order.
      for (int k = 1; k <= count + 1; ++k) {
        add_event(segment_event(use.name, k, count, use.master, use.follower), use.where);
        add_event(segment_event(use.name, k, count, use.follower, use.master), use.where);
      }
    }
    std::vector<Primitive>& prims = primitives(r);
    const std::size_t begin = prims.size();
    Emitter emit(prims, cmd.where, to_string(cmd));
    auto barrier = [&](int k) {
      emit.motion(k <= count ? fmt::format("start segment {} together", k) : std::string("stop together"))
          .signal(segment_event(use.name, k, count, name, partner))
          .wait(segment_event(use.name, k, count, partner, name));
    };
    for (int k = 1; k <= count; ++k) {
      barrier(k);
      const SegmentPlan& seg = segments[static_cast<std::size_t>(k - 1)];
      emit.motion(seg.motion);
      switch (seg.kind) {
        case PrimitiveKind::kMove:
          emit.move(seg.target.kind, seg.target.object);
          break;
        case PrimitiveKind::kOpen:
          emit.open(seg.workpiece);
          break;
        default:
          emit.close(seg.workpiece);
          break;
      }
      prims.back().segment = task::Segment{use.name, k, count, use.master, use.follower};
    }
    barrier(count + 1);
    use.runs.push_back({name, cmd.where, begin, prims.size()});
  }

  void expect_outside_regions(std::size_t r) const {
    const auto& inside = state_[r].inside;
    if (!inside.empty()) {
      const Inside& in = inside.front();
      fail(in.entered, fmt::format("the program of {} ends inside region {} (entered here): add 'leave {}'",
                                   out_.robots[r], in.region, in.region));
    }
  }

  void compile_sequence(const Sequence& seq) {
    const std::size_t r = robot(seq.robot);
    std::size_t next_loop = 0;
    LoopStart start;
    for (std::size_t i = 0; i < seq.commands.size(); ++i) {
      if (next_loop < seq.loops.size() && seq.loops[next_loop].begin == i) start = {primitives(r).size(), state_[r]};
      compile_command(r, seq.commands[i], {});
      if (next_loop < seq.loops.size() && seq.loops[next_loop].end == i + 1) {
        close_loop(seq.loops[next_loop], {r}, {start});
        ++next_loop;
      }
    }
    CW_CHECK(next_loop == seq.loops.size(), "sequence {}: loop {} of {} was not reached", seq.robot, next_loop,
             seq.loops.size());
    expect_outside_regions(r);
  }

  // Loops of cooperating sequences (`repeat N with R...`): the loops of a group of sequences become one loop with one
  // decision (compiled.hpp, Loop). Each sequence names the others of its group; the k-th loop of a robot naming a
  // group goes with the k-th loop of each other robot of the group naming it; the counts must agree.
  void join_loops() {
    struct Member {
      std::size_t robot = 0;
      std::size_t loop = 0;  // index in the robot's loops (a sequence's loops are its RobotProgram's, in order)
      const LoopBlock* block = nullptr;
    };
    std::vector<std::vector<std::size_t>> groups;                       // sorted robot indices, by first appearance
    std::map<std::pair<std::size_t, std::size_t>, std::vector<Member>> of;  // (group, robot) -> its loops, in order
    for (const Sequence& seq : program_.sequences) {
      const std::size_t r = robot(seq.robot);
      for (std::size_t l = 0; l < seq.loops.size(); ++l) {
        const LoopBlock& block = seq.loops[l];
        if (block.partners.empty()) continue;
        std::vector<std::size_t> group{r};
        for (std::size_t i = 0; i < block.partners.size(); ++i) {
          const std::string& name = block.partners[i];
          const SourceLocation& where = block.partner_where[i];
          const auto it = robot_index_.find(name);
          if (it == robot_index_.end()) fail(where, fmt::format("'{}' after 'with' is not a declared robot", name));
          if (it->second == r) fail(where, fmt::format("robot '{}' names its own sequence after 'with'", name));
          const bool has_sequence = std::any_of(program_.sequences.begin(), program_.sequences.end(),
                                                [&](const Sequence& s) { return s.robot == name; });
          if (!has_sequence) {
            fail(where, fmt::format("robot '{}' has no sequence for this loop to run with (a loop with partners joins "
                                    "the loops of their sequences)",
                                    name));
          }
          group.push_back(it->second);
        }
        std::sort(group.begin(), group.end());
        const auto g = std::find(groups.begin(), groups.end(), group);
        const std::size_t gi = static_cast<std::size_t>(g - groups.begin());
        if (g == groups.end()) groups.push_back(group);
        of[{gi, r}].push_back({r, l, &block});
      }
    }
    auto names_of = [&](const std::vector<std::size_t>& group, std::size_t except) {
      std::string names;
      for (std::size_t m : group) {
        if (m != except) names += (names.empty() ? "" : " ") + out_.robots[m];
      }
      return names;
    };
    for (std::size_t gi = 0; gi < groups.size(); ++gi) {
      const std::vector<std::size_t>& group = groups[gi];
      // Every member has as many loops naming this group as the others: report the first loop left unmatched.
      std::size_t most = 0;
      for (std::size_t m : group) most = std::max(most, of[{gi, m}].size());
      for (std::size_t k = 0; k < most; ++k) {
        const Member* first = nullptr;
        for (std::size_t m : group) {
          if (k < of[{gi, m}].size()) first = first ? first : &of[{gi, m}][k];
        }
        for (std::size_t m : group) {
          if (k >= of[{gi, m}].size()) {
            fail(first->block->where,
                 fmt::format("the loop of {} runs with {}, but the sequence of {} has {} 'with {}' to run "
                             "with it ({} has {}): write 'repeat {} with {}' in the sequence of {}",
                             out_.robots[first->robot], names_of(group, first->robot), out_.robots[m],
                             k == 0 ? std::string("no loop") : fmt::format("only {} loop{}", k, k == 1 ? "" : "s"),
                             names_of(group, m),
                             out_.robots[first->robot], of[{gi, first->robot}].size(), first->block->count,
                             names_of(group, m), out_.robots[m]));
          }
          const Member& other = of[{gi, m}][k];
          if (other.block->count != first->block->count) {
            fail(other.block->where,
                 fmt::format("the loop of {} repeats {} times, but the loop of {} it runs with (line {}) repeats {} "
                             "times: loops with one decision run the same number of iterations",
                             out_.robots[m], other.block->count, out_.robots[first->robot],
                             first->block->where.line, first->block->count));
          }
        }
        // One loop: the leader is the group's robot declared first.
        const std::size_t leader = group.front();
        const Member& lead = of[{gi, leader}][k];
        const std::string name = fmt::format("loop{}", lead.block->where.line);
        std::vector<std::string> followers;
        for (std::size_t m : group) {
          if (m != leader) followers.push_back(out_.robots[m]);
        }
        for (std::size_t m : group) {
          Loop& loop = out_.programs[m].loops[of[{gi, m}][k].loop];
          loop.name = name;
          loop.leader = out_.robots[leader];
          loop.followers = m == leader ? followers : std::vector<std::string>{};
          loop.paced = true;
        }
        const Loop& decided = out_.programs[leader].loops[lead.loop];
        for (const std::string& f : followers) {
          add_event(loop_again_event(decided, f), lead.block->where);
          add_event(loop_exit_event(decided, f), lead.block->where);
          add_event(loop_taken_event(decided, f), lead.block->where);
          out_.semaphores.back().initial = 1;  // the leader's first decision waits for nothing
        }
      }
    }
  }

  static std::string holding_text(const RobotState& st) {
    return st.holding ? held_since(*st.holding) : std::string("nothing");
  }
  static std::vector<std::string> region_names(const RobotState& st) {
    std::vector<std::string> names;
    for (const Inside& in : st.inside) names.push_back(in.region);
    std::sort(names.begin(), names.end());
    return names;
  }
  static std::string regions_text(const std::vector<std::string>& names) {
    if (names.empty()) return "no region";
    std::string out = names.size() == 1 ? "region " : "regions ";
    for (std::size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : ", ") + names[i];
    return out;
  }

  // The end of a loop's body for the robots `rows` (leader first), whose body starts are `starts`: checks that each
  // robot is as it was at the start (so every iteration runs like the first), then closes each robot's body with a
  // kLoop primitive and records the loop. With followers, the leader's decision events are inserted.
  void close_loop(const LoopBlock& block, const std::vector<std::size_t>& rows, const std::vector<LoopStart>& starts) {
    const std::string loop_text = fmt::format("repeat {}", block.count);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const std::string& name = out_.robots[rows[i]];
      const RobotState& before = starts[i].state;
      const RobotState& after = state_[rows[i]];
      const bool same_holding = before.holding.has_value() == after.holding.has_value() &&
                                (!before.holding || before.holding->workpiece == after.holding->workpiece);
      if (!same_holding) {
        fail(block.where, fmt::format("{} holds {} at the start of the loop's body and {} at its end: an iteration "
                                      "must leave each robot holding what it held when the iteration began",
                                      name, holding_text(before), holding_text(after)));
      }
      const auto regions_before = region_names(before);
      const auto regions_after = region_names(after);
      if (regions_before != regions_after) {
        fail(block.where, fmt::format("{} is inside {} at the start of the loop's body and inside {} at its end: an "
                                      "iteration must leave each robot in the regions it was in when the iteration "
                                      "began",
                                      name, regions_text(regions_before), regions_text(regions_after)));
      }
    }
    Loop loop;
    loop.name = fmt::format("loop{}", block.where.line);
    loop.where = block.where;
    loop.count = block.count;
    loop.leader = out_.robots[rows.front()];
    for (std::size_t i = 1; i < rows.size(); ++i) loop.followers.push_back(out_.robots[rows[i]]);
    for (const std::string& follower : loop.followers) {
      add_event(loop_again_event(loop, follower), block.where);
      add_event(loop_exit_event(loop, follower), block.where);
    }
    for (std::size_t i = 0; i < rows.size(); ++i) {
      RobotProgram& prog = out_.programs[rows[i]];
      Loop mine = loop;
      if (i > 0) mine.followers.clear();
      mine.begin = starts[i].begin;
      mine.end = prog.primitives.size();
      Emitter(prog.primitives, block.where, loop_text).motion("loop").loop(static_cast<int>(prog.loops.size()));
      prog.loops.push_back(std::move(mine));
    }
  }

  // The Put/Get pair that includes the command in column `c` of `line`. Returns the column of the partner.
  std::size_t compile_handover(const StepTable& table, const StepLine& line, std::size_t c,
                               const std::vector<std::size_t>& rows) {
    const Command& cmd = *line.cells[c];
    const bool put = cmd.kind == CommandKind::kPut;
    const std::string& self = table.robots[c];
    const std::string& other = cmd.argument;
    const char* partner_kind = put ? "Get" : "Put";
    if (other == self) {
      fail(cmd.argument_where, fmt::format("{} cannot {} itself", self, put ? "Put to" : "Get from"));
    }
    const std::string needed =
        fmt::format("{} needs '{} {}' in {}'s column on the same line", to_string(cmd), partner_kind, self, other);
    const auto col = std::find(table.robots.begin(), table.robots.end(), other);
    if (col == table.robots.end()) {
      fail(cmd.where, fmt::format("{}, but {} has no column in the steps table", needed, other));
    }
    const auto oc = static_cast<std::size_t>(col - table.robots.begin());
    const std::optional<Command>& partner = line.cells[oc];
    if (!partner) fail(cmd.where, fmt::format("{}, but {}'s cell on this line is empty", needed, other));
    const CommandKind want = put ? CommandKind::kGet : CommandKind::kPut;
    if (partner->kind != want || partner->argument != self) {
      fail(cmd.where, fmt::format("{}, but {}'s cell on this line is '{}'", needed, other, to_string(*partner)));
    }
    const Command& put_cmd = put ? cmd : *partner;
    const Command& get_cmd = put ? *partner : cmd;
    const std::size_t gc = put ? c : oc;  // giver's column
    const std::size_t tc = put ? oc : c;  // taker's column
    const std::string& giver = table.robots[gc];
    const std::string& taker = table.robots[tc];
    RobotState& gs = state_[rows[gc]];
    RobotState& ts = state_[rows[tc]];
    if (!gs.holding) fail(put_cmd.where, fmt::format("{} cannot Put to {}: it is holding nothing", giver, taker));
    if (ts.holding) {
      fail(get_cmd.where,
           fmt::format("{} cannot Get from {}: it is already holding {}", taker, giver, held_since(*ts.holding)));
    }
    const std::string w = gs.holding->workpiece;
    const int n = line.where.line;
    const std::string ready = fmt::format("put{}.{}>{}.ready", n, giver, taker);
    const std::string gripped = fmt::format("put{}.{}>{}.gripped", n, taker, giver);
    const std::string released = fmt::format("put{}.{}>{}.released", n, giver, taker);
    add_event(ready, put_cmd.where);
    add_event(gripped, put_cmd.where);
    add_event(released, put_cmd.where);

    Emitter g(primitives(rows[gc]), put_cmd.where, to_string(put_cmd));
    g.motion("move to hand-over " + taker).move(TargetKind::kHandover, taker);
    g.motion("hand over " + w).signal(ready).wait(gripped).open(w).signal(released);

    Emitter t(primitives(rows[tc]), get_cmd.where, to_string(get_cmd));
    t.motion("approach hand " + giver).open("").move(TargetKind::kHandApproach, giver).wait(ready);
    t.move(TargetKind::kHandGrasp, giver);
    t.motion("grasp " + w).close(w).signal(gripped).wait(released);
    t.motion("depart " + giver).move(TargetKind::kHandApproach, giver);

    ts.holding = Holding{w, n};
    gs.holding.reset();
    return oc;
  }

  void compile_table(const StepTable& table) {
    std::vector<std::size_t> rows;  // robot index of each column
    for (const std::string& name : table.robots) rows.push_back(robot(name));
    std::size_t next_loop = 0;
    std::vector<LoopStart> starts;  // per column, at the start of the current loop's body
    for (std::size_t l = 0; l < table.lines.size(); ++l) {
      const StepLine& line = table.lines[l];
      const LoopBlock* loop = next_loop < table.loops.size() ? &table.loops[next_loop] : nullptr;
      if (loop != nullptr && loop->begin == l) {
        starts.clear();
        for (std::size_t r : rows) starts.push_back({primitives(r).size(), state_[r]});
      }
      CW_CHECK(line.cells.size() == rows.size(), "step line {} has {} cells for {} columns", line.where.line,
               line.cells.size(), rows.size());
      std::vector<bool> done(rows.size(), false);
      for (std::size_t c = 0; c < rows.size(); ++c) {
        if (!line.cells[c] || done[c]) continue;
        const Command& cmd = *line.cells[c];
        if (cmd.kind == CommandKind::kPut || cmd.kind == CommandKind::kGet) {
          done[compile_handover(table, line, c, rows)] = true;
        } else {
          compile_command(rows[c], cmd, rows);
        }
        done[c] = true;
      }
      // The barrier after a loop's last line comes before the leader decides, even at the end of the table.
      const bool closes_loop = loop != nullptr && loop->end == l + 1;
      if ((l + 1 < table.lines.size() || closes_loop) && rows.size() > 1) barrier(table, line, rows);
      if (closes_loop) {
        close_loop(*loop, rows, starts);
        ++next_loop;
      }
    }
    CW_CHECK(next_loop == table.loops.size(), "steps table: loop {} of {} was not reached", next_loop,
             table.loops.size());
    for (std::size_t r : rows) expect_outside_regions(r);
  }

  // The lock-step barrier after `line`: each robot signals every other robot, then waits for every other robot.
  void barrier(const StepTable& table, const StepLine& line, const std::vector<std::size_t>& rows) {
    const auto event = [&](std::size_t from, std::size_t to) {
      return fmt::format("step{}.{}>{}", line.step, table.robots[from], table.robots[to]);
    };
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (std::size_t j = 0; j < rows.size(); ++j) {
        if (i != j) add_event(event(i, j), line.where);
      }
    }
    const std::string task = fmt::format("end of step {}", line.step);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      Emitter e(primitives(rows[i]), line.where, task);
      e.motion("barrier");
      for (std::size_t j = 0; j < rows.size(); ++j) {
        if (i != j) e.signal(event(i, j));
      }
      for (std::size_t j = 0; j < rows.size(); ++j) {
        if (i != j) e.wait(event(j, i));
      }
    }
  }

  const Program& program_;
  CompiledProgram out_;
  std::map<std::string, std::size_t> robot_index_;
  std::map<std::string, std::size_t> region_index_;
  std::map<std::string, std::string> sensor_conveyor_;  // sensor -> its conveyor
  std::map<std::string, std::size_t> block_index_;       // coordinated block -> index in out_.coordinated
  std::vector<std::vector<SegmentPlan>> block_segments_;     // per coordinated block, its segments
  std::vector<RobotState> state_;
};

}  // namespace

CompiledProgram compile(const Program& program) {
  return Compiler(program).run();
}

CompiledProgram compile_file(const std::filesystem::path& path) {
  return compile(load_program(path));
}

}  // namespace cellwright::task
