// Petri net engine figures: reachability exploration speed and memory (targets: >= 1,000,000 markings/s on one core,
// <= 64 bytes per stored marking, counting packed markings, parent links and hash table), and the token-game rate
// the task-control thread can sustain on a 100-transition net. Rates are per CPU second (the machine is shared; CPU
// time is what one core delivers), Google Benchmark's default. And `twin check` at scale: a lock-step program of 12
// and of 50 robots and 20 lines (target: under 1 s, with the net reduction and the stubborn sets), the shared-region and philosophers programs
// of 12 and 50 robots (issue 27; target under 1 s each, decided by the structural checks past the exploration budget), full vs reduced markings where full
// exploration is feasible; the same table inside a `repeat` (a cyclic net, shown bounded by a weighting of its places
// before the reduced search is trusted), and the shift program of the pipeline written for a shift.
//
//   cmake --build build --target petri_bench && build/tools/petri_bench
//   taskset -c 0 build/tools/petri_bench --benchmark_filter=Check --benchmark_repetitions=5
//   taskset -c 0 build/tools/petri_bench --benchmark_filter='CheckSharedRegion|CheckPhilosophers|CheckLockStep/robots:(12|50)'
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//       (add --benchmark_report_aggregates_only=true for the medians alone)
#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <cstdint>
#include <string>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/petri/generators.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/program.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::petri {
namespace {

// Explores `net` completely each iteration; reports markings/s, bytes per marking and the sizes, and fails the run if
// the count differs from the closed form.
void explore(benchmark::State& state, const Net& net, std::uint64_t expected) {
  AnalysisResult r;
  std::uint64_t markings = 0;
  std::uint64_t edges = 0;
  for (auto _ : state) {
    r = analyze(net);
    markings += r.states;
    edges += r.edges;
    benchmark::DoNotOptimize(r.states);
  }
  if (!r.complete || r.states != expected) {
    state.SkipWithError(("expected " + std::to_string(expected) + " markings, got " + std::to_string(r.states) +
                         (r.complete ? "" : " (" + r.stop_reason + ")"))
                            .c_str());
    return;
  }
  state.counters["markings"] = static_cast<double>(r.states);
  state.counters["edges"] = static_cast<double>(r.edges);
  state.counters["markings/s"] = benchmark::Counter(static_cast<double>(markings), benchmark::Counter::kIsRate);
  state.counters["edges/s"] = benchmark::Counter(static_cast<double>(edges), benchmark::Counter::kIsRate);
  state.counters["bytes/marking"] = static_cast<double>(r.stored_bytes) / static_cast<double>(r.states);
}

// 8 robots cycling through 8 command places each, sharing two critical regions: 1,507,328 markings, 66 places.
void BM_ExploreRobotCell(benchmark::State& state) {
  const int robots = static_cast<int>(state.range(0));
  const Net net = generators::robot_cell(robots, 8, 2);
  explore(state, net, generators::robot_cell_reachable(robots, 8, 2));
}
BENCHMARK(BM_ExploreRobotCell)->Arg(8)->Unit(benchmark::kMillisecond);

// The classic Kanban model with N = 5 cards per station: 2,546,432 markings (published), 16 places up to 5 tokens.
void BM_ExploreKanban(benchmark::State& state) {
  const auto n = static_cast<Tokens>(state.range(0));
  explore(state, generators::kanban(n), generators::kanban_reachable(n));
}
BENCHMARK(BM_ExploreKanban)->Arg(5)->Unit(benchmark::kMillisecond);

// What `twin check` does with a program text: parse, compile, build the net, analyse it, fully (stubborn false) or
// with stubborn sets. Counters: markings explored, transitions of the net, whether the program passed, whether the
// reduction was applied (a cyclic net that cannot be shown bounded is explored fully: reduced 0).
void check(benchmark::State& state, const std::string& text, bool stubborn, bool agglomerate = true) {
  AnalysisOptions options;
  options.reduction = stubborn ? Reduction::kStubborn : Reduction::kNone;
  options.agglomerate = agglomerate;
  AnalysisResult r;
  std::size_t transitions = 0;
  for (auto _ : state) {
    const Net net = task::to_net(task::compile(task::parse_program(text, "check.task")));
    r = analyze(net, options);
    transitions = net.num_transitions();
    benchmark::DoNotOptimize(r.states);
  }
  if (!r.complete) {
    state.SkipWithError(("exploration stopped: " + r.stop_reason).c_str());
    return;
  }
  state.counters["markings"] = static_cast<double>(r.states);
  state.counters["transitions"] = static_cast<double>(transitions);
  state.counters["agglomerated"] = r.net_reduction.empty() ? 0 : 1;
  state.counters["ok"] = r.ok() ? 1 : 0;
  state.counters["reduced"] = r.reduced ? 1 : 0;
  state.counters["explored_all"] = r.explored_all ? 1 : 0;  // 0: past the exploration budget, decided structurally
}

// A generated lock-step program (generators::lockstep_program). The 50-robot table: target under 1 s (issue 27);
// agglomerate:0 shows it without the net reduction (agglomerate.hpp), as it was checked before: ~55 s.
void BM_CheckLockStep(benchmark::State& state) {
  check(state, generators::lockstep_program(static_cast<int>(state.range(0)), static_cast<int>(state.range(1))),
        state.range(2) != 0, state.range(3) != 0);
}
BENCHMARK(BM_CheckLockStep)
    ->ArgNames({"robots", "lines", "stubborn", "agglomerate"})
    ->Args({12, 20, 1, 1})
    ->Args({12, 20, 1, 0})
    ->Args({50, 20, 1, 1})
    ->Args({50, 20, 1, 0})
    ->Args({2, 20, 0, 1})
    ->Args({2, 20, 1, 1})
    ->Args({4, 2, 0, 1})
    ->Args({4, 2, 1, 1})
    ->Args({6, 2, 0, 1})
    ->Args({6, 2, 1, 1})
    ->Args({4, 4, 0, 1})
    ->Args({4, 4, 1, 1})
    ->Unit(benchmark::kMillisecond);

// The same table as the body of a `repeat 1000` loop: the leader r1 tells every other robot again or exit after each
// iteration, so the net is cyclic (and as large for 3 iterations as for 1000).
void BM_CheckLockStepLoop(benchmark::State& state) {
  check(state, generators::lockstep_program(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)), 1000),
        state.range(2) != 0);
}
BENCHMARK(BM_CheckLockStepLoop)
    ->ArgNames({"robots", "lines", "stubborn"})
    ->Args({12, 20, 1})
    ->Args({2, 20, 0})
    ->Args({2, 20, 1})
    ->Args({4, 4, 0})
    ->Args({4, 4, 1})
    ->Unit(benchmark::kMillisecond);

// A sequence-style looping program: the shipped shift program (a table whose loop pipelines pick, hand-over and
// place) and, for scale, 6 copies of it side by side (12 robots: pairs rI, rI+1 in one table, looping together).
std::string shift_program(int pairs) {
  std::string robots, header, first, second, body1, last;
  for (int k = 0; k < pairs; ++k) {
    const int g = 2 * k + 1, t = 2 * k + 2;
    const std::string sep = k == 0 ? "" : " | ";
    robots += fmt::format(" r{} r{}", g, t);
    header += fmt::format("{}r{} | r{}", sep, g, t);
    first += fmt::format("{}Pick part |", sep);
    second += fmt::format("{}Put r{} | Get r{}", sep, t, g);
    body1 += fmt::format("{}Pick part | Place OUT", sep);
    last += fmt::format("{} | Place OUT", sep);
  }
  return fmt::format(
      "robot{}\nworkpiece part from IN\nlocation IN OUT\nsteps\n  {}\n  {}\n  {}\nrepeat 999\n  {}\n  {}\nend\n  "
      "{}\nend\n",
      robots, header, first, second, body1, second, last);
}
void BM_CheckShift(benchmark::State& state) {
  check(state, shift_program(static_cast<int>(state.range(0))), state.range(1) != 0);
}
BENCHMARK(BM_CheckShift)
    ->ArgNames({"pairs", "stubborn"})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Args({6, 1})
    ->Unit(benchmark::kMillisecond);

// Issue 27's shapes: free sequences that each enter one shared region twice (must pass: the region is exclusive by
// its place invariant, deadlock freedom by the state equation), and "philosophers" that each take their own region
// and their neighbour's (must be refused: the deadlock is found by a search guided by the state equation's solution).
// Target: under 1 s for 12 and for 50 robots.
void BM_CheckSharedRegion(benchmark::State& state) {
  check(state, generators::shared_region_program(static_cast<int>(state.range(0))), true);
}
BENCHMARK(BM_CheckSharedRegion)->ArgNames({"robots"})->Arg(12)->Arg(50)->Unit(benchmark::kMillisecond);

void BM_CheckPhilosophers(benchmark::State& state) {
  check(state, generators::philosophers_program(static_cast<int>(state.range(0))), true);
}
BENCHMARK(BM_CheckPhilosophers)->ArgNames({"robots"})->Arg(12)->Arg(50)->Unit(benchmark::kMillisecond);

// The token game as the task-control thread plays it: choose a maximal fair step, fire it. 10 robots x 10 steps =
// 100 transitions, sharing three regions.
void BM_TokenGameChooseFire(benchmark::State& state) {
  const Net net = generators::robot_cell(10, 10, 3);
  Marking m = net.initial_marking();
  Arbiter arbiter = make_arbiter(net);
  std::uint64_t fired = 0;
  for (auto _ : state) {
    const std::vector<TransitionId> step = choose(net, m, arbiter);
    fire_chosen(net, m, arbiter, step);
    fired += step.size();
  }
  state.counters["transitions"] = static_cast<double>(net.num_transitions());
  state.counters["firings/s"] = benchmark::Counter(static_cast<double>(fired), benchmark::Counter::kIsRate);
  state.counters["steps/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_TokenGameChooseFire);

// One firing at a time: the enabled set, then fire one of them (rotating, so every robot moves).
void BM_TokenGameEnabledFire(benchmark::State& state) {
  const Net net = generators::robot_cell(10, 10, 3);
  Marking m = net.initial_marking();
  std::uint64_t fired = 0;
  std::size_t turn = 0;
  for (auto _ : state) {
    const std::vector<TransitionId> en = enabled(net, m);
    fire_in_place(net, m, en[turn++ % en.size()]);
    ++fired;
  }
  state.counters["transitions"] = static_cast<double>(net.num_transitions());
  state.counters["firings/s"] = benchmark::Counter(static_cast<double>(fired), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_TokenGameEnabledFire);

}  // namespace
}  // namespace cellwright::petri

BENCHMARK_MAIN();
