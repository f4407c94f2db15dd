// Runtime benchmarks: the message hand-off latency between threads through a MessageQueue (p50/p99 as counters), the
// cost of one lock-step turn (handed to another thread, or staying on one), whole lock-step runs of the exchange
// program on scripted arms (no MuJoCo), in control periods per second, and the exchange and pipeline scenarios in the
// twin: each with the scheduling of old (a thread per participant, every participant every turn) and the default
// (one thread, idle participants passed over), with hand-offs, turns and turns passed over per simulated second and
// the real-time factor as counters. Pin it to one core: taskset -c 0 runtime_bench.
#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "../../tests/controller/runtime/scripted_cell.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/scenario.hpp"

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

// The same round of `participants` that do nothing, all on one thread: what a turn costs without a thread switch.
void BM_LockstepTurnOneThread(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  constexpr std::uint64_t kRoundsPerBatch = 1000;
  std::uint64_t turns = 0;
  for (auto _ : state) {
    LockstepScheduler scheduler(std::vector<std::size_t>(n, 0));
    std::thread runner([&scheduler] {
      LockstepScheduler::Seat seat(scheduler, LockstepScheduler::Thread{0});
      std::uint64_t rounds = 0;
      while (seat.await_turn()) {
        if (seat.id() == 0 && ++rounds > kRoundsPerBatch) {
          scheduler.stop();
          break;
        }
        seat.yield();
      }
    });
    runner.join();
    turns += scheduler.turns();
  }
  state.counters["turn_ns"] =
      benchmark::Counter(static_cast<double>(turns), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_LockstepTurnOneThread)->Arg(2)->Arg(4)->Arg(6)->UseRealTime()->Unit(benchmark::kMillisecond);

// The turns of a lock-step run: range(0) 0 gives every participant a thread of its own and every turn (the scheduling
// before event-driven turns), 1 the default (every turn on the simulation thread, idle participants passed over).
// CPU time of the whole process, all threads (seconds). On a loaded core the wall time says more about the OS's share
// than about the run: a thread that wakes another is favoured over busy neighbours, one that never sleeps is not.
double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void set_counters(benchmark::State& state, const LockstepStats& s, double sim_seconds, double wall_seconds,
                  double cpu_seconds) {
  state.counters["cpu_realtime_factor"] = sim_seconds / cpu_seconds;
  state.counters["handoffs_per_sim_s"] = static_cast<double>(s.handoffs) / sim_seconds;
  state.counters["turns_per_sim_s"] = static_cast<double>(s.turns) / sim_seconds;
  state.counters["skipped_per_sim_s"] = static_cast<double>(s.skipped) / sim_seconds;
  state.counters["pauses_per_sim_s"] = static_cast<double>(s.pauses) / sim_seconds;
  state.counters["realtime_factor"] = sim_seconds / wall_seconds;
}

void choose(Runtime& rt, std::int64_t variant) {
  if (variant == 0) {
    rt.set_lockstep(LockstepThreads::kOwn, false);
  } else {
    rt.set_lockstep(LockstepThreads::kShared, true);
  }
}

// The exchange program end to end in lock-step, scripted arms and a kinematic plant: the runtime's own overhead per
// control period (4 participants: simulation, task control, two robots).
void BM_ExchangeRunLockstep(benchmark::State& state) {
  double periods = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cellwright::testing::ScriptedCell cell;
    Runtime rt(cell.config);
    choose(rt, state.range(0));
    state.ResumeTiming();
    const auto start = Clock::now();
    const double cpu_start = process_cpu_seconds();
    const RunResult r = rt.run();
    const double cpu = process_cpu_seconds() - cpu_start;
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    if (r.outcome != Outcome::kFinished) state.SkipWithError(r.reason.c_str());
    periods += static_cast<double>(r.end_time / cell.config.period);
    set_counters(state, r.lockstep, std::chrono::duration<double>(r.end_time).count(), wall, cpu);
  }
  state.counters["periods_per_s"] = benchmark::Counter(periods, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ExchangeRunLockstep)->Arg(0)->Arg(1)->UseRealTime()->Unit(benchmark::kMillisecond);

// A shipped scenario in the twin (MuJoCo), as `twin run` runs it (run(), not step(): no progress line), with the old
// and the new scheduling; fails if the two event logs differ by a byte.
void BM_ScenarioLockstep(benchmark::State& state, const std::string& file) {
  using namespace cellwright::cell;
  const Scenario s = load_scenario(std::string(CW_SOURCE_DIR) + "/scenes/" + file);
  const Preflight pre = preflight(s, &twin_port());
  if (!pre.ok()) {
    state.SkipWithError((file + " refused: " + pre.problems.front()).c_str());
    return;
  }
  static std::map<std::string, std::string> first_log;  // per scenario, the first variant's
  for (auto _ : state) {
    ScenarioRun run(s, pre, RunOptions{});
    choose(run.runtime(), state.range(0));
    const auto start = Clock::now();
    const double cpu_start = process_cpu_seconds();
    const RunResult r = run.runtime().run();
    const double cpu = process_cpu_seconds() - cpu_start;
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    set_counters(state, r.lockstep, std::chrono::duration<double>(r.end_time).count(), wall, cpu);
    const std::string log = run.runtime().log().text();
    auto [it, fresh] = first_log.emplace(file, log);
    if (!fresh && it->second != log) state.SkipWithError((file + ": the event log differs between variants").c_str());
  }
}
BENCHMARK_CAPTURE(BM_ScenarioLockstep, exchange, std::string("exchange.yaml"))
    ->Arg(0)->Arg(1)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ScenarioLockstep, pipeline, std::string("pipeline.yaml"))
    ->Arg(0)->Arg(1)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
