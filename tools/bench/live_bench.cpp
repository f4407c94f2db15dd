// What a live-view frame costs the run (docs/live-view.md, "Real time"): in `twin serve --realtime` the frames of a
// run that goes are built on the runtime's simulation thread, 30 a second of wall time while someone watches, so
// their cost is taken from the simulation's budget. Measured here on scenes/exchange.yaml stepped lock-step to 10 s
// of simulated time (both robots' joints, the parts, the marking, the commands so far in the Gantt): one
// live_frame_json (30 a second take 30 times that of each second of the simulation thread), and its size; one
// Foxglove scene message of the bodies that move (foxglove_scene.hpp: built besides the frame while a Foxglove client
// subscribes) and one of the whole cell (a run's base, once a run). For comparison, one control period of that run
// (10 ms of simulation: physics, sensors, task and robot control).
//
//   cmake --build build --target live_bench
//   taskset -c 0 build/tools/live_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <chrono>
#include <memory>
#include <string>

#include "cellwright/cell/live/foxglove_scene.hpp"
#include "cellwright/cell/live/live.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/sim/sweep.hpp"

namespace {

using namespace cellwright;
using namespace cellwright::cell;

struct ExchangeAt10s {
  Scenario scenario = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml");
  Preflight preflight = cell::preflight(scenario, &twin_port());
  std::unique_ptr<ScenarioRun> run = std::make_unique<ScenarioRun>(scenario, preflight, RunOptions{});
  runtime::StepState state;
  ExchangeAt10s() {
    do {
      state = run->runtime().step(std::chrono::seconds(10));
    } while (!state.ended && state.time < std::chrono::seconds(10));
  }
};

void BM_LiveFrame(benchmark::State& st) {
  ExchangeAt10s at;
  FaultMarks marks;
  std::size_t bytes = 0;
  for (auto _ : st) {
    const std::string frame = live_frame_json(*at.run, LiveFrameState{"playing", &at.state}, marks);
    bytes = frame.size();
    benchmark::DoNotOptimize(frame.data());
  }
  st.counters["frame_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_LiveFrame)->Unit(benchmark::kMillisecond);

// A Foxglove scene message: arg 0 the bodies that move (each frame), 1 the whole cell (each run's base).
void BM_FoxgloveScene(benchmark::State& st) {
  ExchangeAt10s at;
  FaultMarks marks;
  std::size_t bytes = 0;
  for (auto _ : st) {
    const std::string scene = foxglove_scene_json(*at.run, st.range(0) == 1, marks, foxglove_now_ns());
    bytes = scene.size();
    benchmark::DoNotOptimize(scene.data());
  }
  st.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_FoxgloveScene)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// One lock-step control period of the same run: the 1000 periods from 10 s to 20 s of simulated time.
void BM_ControlPeriod(benchmark::State& st) {
  ExchangeAt10s at;
  runtime::SimDuration t = at.state.time;
  for (auto _ : st) {
    t += std::chrono::milliseconds(10);
    benchmark::DoNotOptimize(at.run->runtime().step(t).time);
  }
}
BENCHMARK(BM_ControlPeriod)->Unit(benchmark::kMillisecond)->Iterations(1000);

}  // namespace

BENCHMARK_MAIN();
