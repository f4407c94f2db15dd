// Throughput of one arm against two. The pipelined scenario: two arms (scenes/pipeline.yaml: the PUMA picks, hands
// over to the MELFA, which puts down, both working at once) against one arm doing the same work of taking the three
// fed parts off the input conveyor (scenes/pipeline_single.yaml). The relay: twelve parts relayed over a belt by two
// arms in loops with one decision (scenes/relay_belt.yaml) against one arm taking the same twelve parts to a take-away
// belt (scenes/relay_single.yaml). Each benchmark runs its scenario once, headless and lock-step (the result is
// deterministic, so one run is the figure), and reports parts per minute (over the completed parts, or in steady
// state for parts of a class), the steady state (seconds per part from the second placement on), the measured and estimated cycle times and the real-time factor (simulated seconds per
// wall second) as counters. At the end a table compares them, with the two-arm/one-arm ratios of the steady state.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <string>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/scenario.hpp"

namespace {

using namespace cellwright::cell;

struct Figures {
  double parts_per_min = 0;
  std::size_t parts = 0;
  double measured = 0, estimated = 0, realtime_factor = 0;
  double steady = 0;  // s per part from the second placement on (0: fewer than three placements)
  bool ok = false;
  std::string failure;
};
std::map<std::string, Figures>& results() {
  static std::map<std::string, Figures> r;
  return r;
}

void run_scenario(benchmark::State& state, const std::string& name, const std::string& file) {
  const Scenario s = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/" + file);
  const Preflight pre = preflight(s, &twin_port());
  if (!pre.ok()) {
    state.SkipWithError((file + " refused: " + pre.problems.front()).c_str());
    return;
  }
  Figures f;
  for (auto _ : state) {
    RunOptions options;
    options.realtime = false;
    ScenarioRun run(s, pre, options);
    const auto start = std::chrono::steady_clock::now();
    const auto result = run.runtime().run();
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const Report report = run.report();
    // Named parts with expectations count as completed; parts of a class (the relay) as placed.
    f.parts = std::max(report.parts_completed, report.placed_at.size());
    f.parts_per_min = report.throughput.value_or(report.steady_throughput.value_or(0.0));
    f.measured = report.finished_at.value_or(0.0);
    f.estimated = report.estimated_cycle_time.value_or(0.0);
    f.steady = report.steady_cycle.value_or(0.0);
    f.realtime_factor = std::chrono::duration<double>(result.end_time).count() / wall;
    f.ok = report.ok();
    f.failure = report.ok() ? "" : report.failures.front();
  }
  state.counters["parts_per_min"] = f.parts_per_min;
  state.counters["parts"] = static_cast<double>(f.parts);
  state.counters["steady_s_per_part"] = f.steady;
  state.counters["cycle_measured_s"] = f.measured;
  state.counters["cycle_estimated_s"] = f.estimated;
  state.counters["realtime_factor"] = f.realtime_factor;
  state.counters["ok"] = f.ok ? 1 : 0;
  results()[name] = f;
}

void BM_PipelineTwoRobots(benchmark::State& state) {
  run_scenario(state, "two robots (pipeline.yaml)", "pipeline.yaml");
}
void BM_PipelineSingleRobot(benchmark::State& state) {
  run_scenario(state, "one robot (pipeline_single.yaml)", "pipeline_single.yaml");
}
void BM_RelayTwoRobots(benchmark::State& state) {
  run_scenario(state, "two robots (relay_belt.yaml)", "relay_belt.yaml");
}
void BM_RelaySingleRobot(benchmark::State& state) {
  run_scenario(state, "one robot (relay_single.yaml)", "relay_single.yaml");
}
BENCHMARK(BM_PipelineTwoRobots)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_PipelineSingleRobot)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_RelayTwoRobots)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_RelaySingleRobot)->Iterations(1)->Unit(benchmark::kSecond);

// "two robots (X)" against "one robot (Y)": the steady-state ratio, when both ran (a --benchmark_filter may leave one
// out).
void print_ratio(const char* what, const std::string& two, const std::string& one) {
  const auto a = results().find(two);
  const auto b = results().find(one);
  if (a == results().end() || b == results().end()) return;
  if (a->second.steady <= 0 || b->second.steady <= 0) {
    std::printf("%s: no steady state (fewer than three placements)\n", what);
    return;
  }
  std::printf("%s: %.2f s per part with two arms, %.2f s with one: %.2f times the throughput\n", what,
              a->second.steady, b->second.steady, b->second.steady / a->second.steady);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::printf("\nthroughput: the pipelined scenario (3 fed parts), the relay (12 fed parts)\n");
  std::printf("%-34s %10s %6s %12s %12s %12s %10s  %s\n", "", "parts/min", "parts", "steady (s)", "cycle (s)",
              "estimate (s)", "sim/wall", "outcome");
  for (const auto& [name, f] : results()) {
    std::printf("%-34s %10.2f %6zu %12.2f %12.2f %12.2f %10.2f  %s\n", name.c_str(), f.parts_per_min, f.parts, f.steady,
                f.measured, f.estimated, f.realtime_factor, f.ok ? "ok" : f.failure.c_str());
  }
  print_ratio("pipelined", "two robots (pipeline.yaml)", "one robot (pipeline_single.yaml)");
  print_ratio("relay", "two robots (relay_belt.yaml)", "one robot (relay_single.yaml)");
  return 0;
}
