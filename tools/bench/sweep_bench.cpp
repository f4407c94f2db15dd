// The preflight `twin run` performs, with its motion sweep (target: under 2 s for the exchange and the pipelined
// scenarios): BM_Preflight times the whole preflight (the net and its check, the reach checks, the motion plan and
// the sweep); BM_Sweep the sweep alone (building the scene, sampling every move against the static cell, exploring the
// net for concurrency and sweeping the concurrent pairs), the plan made once outside the timing. The counters say what
// the sweep did: moves, poses against the static cell, concurrent pairs of commands, mj_collision calls, markings.
//
//   cmake --build build --target sweep_bench
//   taskset -c 0 build/tools/sweep_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <string>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/task/to_net.hpp"
#include "cellwright/cell/estimate.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sweep.hpp"

namespace cellwright::cell {
namespace {

Scenario scene(const std::string& file) {
  return load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/" + file);
}

void BM_Preflight(benchmark::State& state, const std::string& file) {
  const Scenario s = scene(file);
  Preflight p;
  for (auto _ : state) {
    p = preflight(s, &twin_port());
    benchmark::ClobberMemory();
  }
  if (!p.ok()) state.SkipWithError("the preflight refused the scenario");
}

void BM_Sweep(benchmark::State& state, const std::string& file) {
  const Scenario s = scene(file);
  const petri::Net net = task::to_net(s.program);
  runtime::TargetOptions targets;
  targets.handover_clearance = s.options.handover_clearance;
  const MotionPlan plan = plan_motions(s, net, targets);
  SweepReport r;
  for (auto _ : state) {
    r = sweep_motions(s, net, plan);
    benchmark::ClobberMemory();
  }
  if (!r.ok()) state.SkipWithError("the sweep predicts a collision");
  state.counters["moves"] = static_cast<double>(r.motions);
  state.counters["static_poses"] = static_cast<double>(r.samples);
  state.counters["pairs"] = static_cast<double>(r.pairs);
  state.counters["pose_checks"] = static_cast<double>(r.pose_checks);
  state.counters["markings"] = static_cast<double>(r.states);
}

BENCHMARK_CAPTURE(BM_Preflight, exchange, std::string("exchange.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Preflight, pipeline, std::string("pipeline.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Sweep, exchange, std::string("exchange.yaml"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Sweep, pipeline, std::string("pipeline.yaml"))->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cellwright::cell

BENCHMARK_MAIN();
