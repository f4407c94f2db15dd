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
    out_.workpieces = declared_names(program_, NameKind::kWorkpiece);
    out_.locations = declared_names(program_, NameKind::kLocation);
    for (std::size_t r = 0; r < out_.robots.size(); ++r) {
      robot_index_[out_.robots[r]] = r;
      out_.programs.push_back({out_.robots[r], {}});
    }
    state_.resize(out_.robots.size());
    for (const Declaration& d : program_.declarations) {
      if (d.kind == NameKind::kSemaphore) out_.semaphores.push_back({d.name, d.initial, false, d.where, false});
      if (d.kind == NameKind::kRegion) {
        out_.semaphores.push_back({d.name, 1, true, d.where, false});
        region_index_[d.name] = out_.regions.size();
        out_.regions.push_back({d.name, {}});
      }
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
    out_.semaphores.push_back({name, 0, false, where, true});
  }

  static std::string held_since(const Holding& h) { return fmt::format("{} (since line {})", h.workpiece, h.line); }

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
        for (std::size_t other : table) {
          const auto& h = state_[other].holding;
          if (other != r && h && h->workpiece == x) {
            fail(cmd.argument_where, fmt::format("{} cannot pick {}: robot {} is holding it (since line {})", name, x,
                                                 out_.robots[other], h->line));
          }
        }
        emit.motion("approach " + x).open("").move(TargetKind::kAbove, x);
        emit.motion("grasp " + x).move(TargetKind::kAt, x).close(x);
        emit.motion("lift up " + x).move(TargetKind::kAbove, x);
        st.holding = Holding{x, cmd.where.line};
        return;
      }
      case CommandKind::kPlace: {
        if (!st.holding) fail(cmd.where, fmt::format("{} cannot place on {}: it is holding nothing", name, x));
        const std::string w = st.holding->workpiece;
        if (w == x) fail(cmd.argument_where, fmt::format("{} cannot place {} on itself", name, x));
        emit.motion("approach " + x).move(TargetKind::kAbove, x);
        emit.motion("put down " + w).move(TargetKind::kAt, x);
        emit.motion("release " + w).open(w);
        emit.motion("depart " + x).move(TargetKind::kAbove, x);
        st.holding.reset();
        return;
      }
      case CommandKind::kSignal:
        emit.motion("signal " + x).signal(x);
        return;
      case CommandKind::kWait:
        emit.motion("wait " + x).wait(x);
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
      case CommandKind::kPut:
      case CommandKind::kGet:
        fail(cmd.where, fmt::format("{} is only allowed in the steps table, where the matching {} stands on the "
                                    "same line",
                                    to_string(cmd.kind), cmd.kind == CommandKind::kPut ? "Get" : "Put"));
    }
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
    for (const Command& cmd : seq.commands) compile_command(r, cmd, {});
    expect_outside_regions(r);
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
    for (std::size_t l = 0; l < table.lines.size(); ++l) {
      const StepLine& line = table.lines[l];
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
      if (l + 1 < table.lines.size() && rows.size() > 1) barrier(table, line, rows);
    }
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
