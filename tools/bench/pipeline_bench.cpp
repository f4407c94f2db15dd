// Throughput of the pipelined scenario: two arms (scenes/pipeline.yaml: the PUMA picks, hands over to the MELFA,
// which puts down, both working at once) against one arm doing the same work of taking the three fed parts off the
// input conveyor (scenes/pipeline_single.yaml). Each benchmark runs its scenario once, headless and lock-step (the
// result is deterministic, so one run is the figure), and reports parts per minute, the measured and estimated cycle
// times and the real-time factor (simulated seconds per wall second) as counters. At the end a table compares them.
#include <benchmark/benchmark.h>

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
    f.parts = report.parts_completed;
    f.parts_per_min = report.throughput.value_or(0.0);
    f.measured = report.finished_at.value_or(0.0);
    f.estimated = report.estimated_cycle_time.value_or(0.0);
    f.realtime_factor = std::chrono::duration<double>(result.end_time).count() / wall;
    f.ok = report.ok();
    f.failure = report.ok() ? "" : report.failures.front();
  }
  state.counters["parts_per_min"] = f.parts_per_min;
  state.counters["parts"] = static_cast<double>(f.parts);
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
BENCHMARK(BM_PipelineTwoRobots)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_PipelineSingleRobot)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::printf("\nthroughput of the pipelined scenario (3 fed parts)\n");
  std::printf("%-34s %10s %6s %12s %12s %10s  %s\n", "", "parts/min", "parts", "cycle (s)", "estimate (s)", "sim/wall",
              "outcome");
  for (const auto& [name, f] : results()) {
    std::printf("%-34s %10.2f %6zu %12.2f %12.2f %10.2f  %s\n", name.c_str(), f.parts_per_min, f.parts, f.measured,
                f.estimated, f.realtime_factor, f.ok ? "ok" : f.failure.c_str());
  }
  return 0;
}
