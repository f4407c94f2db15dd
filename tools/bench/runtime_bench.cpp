// Runtime benchmarks: the message hand-off latency between threads through a MessageQueue (p50/p99 as counters), the
// cost of one lock-step turn, and whole lock-step runs of the exchange program on scripted arms (no MuJoCo), in
// control periods per second.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

#include "../../tests/controller/runtime/scripted_cell.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/runtime.hpp"

namespace {

using namespace cellwright::runtime;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<std::int64_t> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1));
  return static_cast<double>(v[i]);
}

// One message to a thread blocked in pop() and its answer back: the latency is measured one way, from push() to the
// moment pop() returns on the other thread (how long a robot-control thread takes to see a command).
void BM_QueueHandoffLatency(benchmark::State& state) {
  MessageQueue<Clock::time_point> to_worker(4);
  MessageQueue<std::int64_t> back(4);
  std::thread worker([&] {
    while (auto sent = to_worker.pop()) {
      const auto latency = std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - *sent).count();
      if (back.push(latency) != QueueStatus::ok) return;
    }
  });
  std::vector<std::int64_t> samples;
  samples.reserve(1 << 16);
  for (auto _ : state) {
    to_worker.push(Clock::now());
    const auto latency = back.pop();
    samples.push_back(*latency);
  }
  to_worker.close();
  back.close();
  worker.join();
  state.counters["p50_ns"] = percentile(samples, 0.50);
  state.counters["p99_ns"] = percentile(samples, 0.99);
}
BENCHMARK(BM_QueueHandoffLatency)->UseRealTime();

// A lock-step round of `participants` threads that do nothing in their turns: the scheduler's own cost per turn.
void BM_LockstepTurn(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  constexpr std::uint64_t kRoundsPerBatch = 1000;
  std::uint64_t turns = 0;
  for (auto _ : state) {
    LockstepScheduler scheduler(n);
    std::vector<std::thread> threads;
    for (std::size_t id = 0; id < n; ++id) {
      threads.emplace_back([&scheduler, id] {
        LockstepScheduler::Seat seat(scheduler, id);
        std::uint64_t mine = 0;
        while (seat.await_turn()) {
          if (id == 0 && ++mine > kRoundsPerBatch) {
            scheduler.stop();
            break;
          }
          seat.yield();
        }
      });
    }
    for (auto& t : threads) t.join();
    turns += scheduler.turns();
  }
  state.counters["turn_ns"] =
      benchmark::Counter(static_cast<double>(turns), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["turns"] = static_cast<double>(turns);
}
BENCHMARK(BM_LockstepTurn)->Arg(2)->Arg(4)->Arg(6)->UseRealTime()->Unit(benchmark::kMillisecond);

// The exchange program end to end in lock-step, scripted arms and a kinematic plant: the runtime's own overhead per
// control period (4 threads: simulation, task control, two robots).
void BM_ExchangeRunLockstep(benchmark::State& state) {
  double periods = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cellwright::testing::ScriptedCell cell;
    Runtime rt(cell.config);
    state.ResumeTiming();
    const RunResult r = rt.run();
    if (r.outcome != Outcome::kFinished) state.SkipWithError(r.reason.c_str());
    periods += static_cast<double>(r.end_time / cell.config.period);
  }
  state.counters["periods_per_s"] = benchmark::Counter(periods, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ExchangeRunLockstep)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
