// The cost of the cycle-time estimate printed before a run (target: well under a second): for each shipped scenario,
// plan the motions, time the commands and simulate the timed net (estimate_cycle_time), the scenario loaded and its
// net made once outside the timing. Also the shift (scenes/pipeline_shift.yaml) made 1,000 parts long (feed count
// 1,000, the loop 999 times), whose timed run grows with the parts while the net does not.
//
// The robots' timing is fixed here (joints 2 rad/s at half speed, 0.2 s shortest move, fingers 5 cm/s): `twin run`
// takes it from the simulated drivers, which needs the MuJoCo scene; the plan, the net and the number of firings,
// which are what the estimate costs, are the same. The counters: the estimated cycle (with this timing, so not
// `twin run`'s figure) and the timed run's firings.
//
//   cmake --build build --target estimate_bench
//   taskset -c 0 build/tools/estimate_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <string>

#include "cellwright/task/to_net.hpp"
#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {
namespace {

EstimateOptions timing(const Scenario& s) {
  EstimateOptions o;
  for (const Binding& b : s.robots) {
    RobotTiming t;
    t.max_joint_speed.assign(6, 2.0);
    o.robots[b.name] = t;
  }
  return o;
}

void estimate(benchmark::State& state, Scenario s) {
  const petri::Net net = task::to_net(s.program);
  const EstimateOptions options = timing(s);
  Estimate e;
  for (auto _ : state) {
    e = estimate_cycle_time(s, net, plan_motions(s, net, {}), options);  // the plan included, as a preflight makes it
    benchmark::ClobberMemory();  // (DoNotOptimize on a double may clobber it with this library and GCC)
  }
  if (!e.run.finished) state.SkipWithError("the estimate's timed run did not finish");
  state.counters["cycle_estimated_s"] = e.cycle_time;
  state.counters["firings"] = static_cast<double>(e.run.firings.size());
}

Scenario scene(const std::string& file) {
  return load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/" + file);
}

void BM_Estimate(benchmark::State& state, const std::string& file) {
  estimate(state, scene(file));
}

void BM_EstimateShiftOf1000Parts(benchmark::State& state) {
  Scenario s = scene("pipeline_shift.yaml");
  s.feed->count = 1000;
  for (task::RobotProgram& p : s.program.programs) {
    for (task::Loop& l : p.loops) l.count = 999;  // the first part before the loop, the last part's Place after it
  }
  estimate(state, std::move(s));
}

BENCHMARK_CAPTURE(BM_Estimate, exchange, std::string("exchange.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Estimate, pipeline, std::string("pipeline.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Estimate, pipeline_shift, std::string("pipeline_shift.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Estimate, pipeline_single, std::string("pipeline_single.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Estimate, single, std::string("single.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Estimate, vision, std::string("vision.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EstimateShiftOf1000Parts)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cellwright::cell

BENCHMARK_MAIN();
