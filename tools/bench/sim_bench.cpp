// Simulation speed on the paper's cell: raw mj_step against World::advance with both simulation drivers following
// trajectories (the overhead of the drivers, belt wrapping, collision and warning checks). Target: World steps per
// second at least half of raw mj_step. Counters: steps_per_s (simulated steps per wall-clock second), rt_factor
// (simulated seconds per wall-clock second) and, for the World, ratio_to_raw (against raw mj_step of the cell at
// rest, measured in the same process on the same compiled model just before: moving arms cost more to step than arms
// at rest) and ratio_to_same_path (the time inside mj_step on the World's own trajectory, from MuJoCo's timers, over
// the wall time: the share of the physics; same_path_raw_steps_per_s is mj_step's own rate there).
#include <benchmark/benchmark.h>
#include <mujoco/mujoco.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace {

using namespace cellwright;
using namespace std::chrono_literals;

const models::CellDescription& cell() {
  static const models::CellDescription c = models::load_cell(std::filesystem::path(CW_SOURCE_DIR) / "scenes/cell.yaml");
  return c;
}

// MuJoCo's timers (mjData::timer) run while mjcb_time is set: microseconds of the steady clock.
mjtNum steady_us() {
  return static_cast<mjtNum>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                 std::chrono::steady_clock::now().time_since_epoch())
                                 .count()) /
         1000.0;
}

// Raw mj_step on its own copy of the scene's initial state, wrapping nothing and checking nothing; returns steps/s.
double raw_steps_per_second(const twin::Scene& scene, int steps) {
  std::unique_ptr<mjData, void (*)(mjData*)> d(mj_makeData(scene.model()), mj_deleteData);
  mj_copyData(d.get(), scene.model(), scene.data());
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < steps; ++i) mj_step(scene.model(), d.get());
  return steps / std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void BM_RawMjStep(benchmark::State& state) {
  twin::Scene scene = twin::build_scene(cell());
  std::unique_ptr<mjData, void (*)(mjData*)> d(mj_makeData(scene.model()), mj_deleteData);
  mj_copyData(d.get(), scene.model(), scene.data());
  std::int64_t steps = 0;
  for (auto _ : state) {
    mj_step(scene.model(), d.get());
    ++steps;
  }
  state.counters["steps_per_s"] = benchmark::Counter(static_cast<double>(steps), benchmark::Counter::kIsRate);
  state.counters["rt_factor"] =
      benchmark::Counter(static_cast<double>(steps) * scene.model()->opt.timestep, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RawMjStep)->Unit(benchmark::kMicrosecond);

// Keeps a driver moving: whenever its last move is done, it goes to the other end of a 0.6 rad swing of joint 1 (and
// smaller swings of the others) at full speed.
struct Mover {
  twin::sim::SimDriver* driver;
  std::vector<double> a, b;
  drivers::CommandId last = 0;
  bool to_b = true;

  void keep_moving() {
    if (last != 0 && driver->poll(last).phase != drivers::CommandPhase::done) return;
    last = driver->submit(drivers::MoveJoints{to_b ? b : a, 1.0}).id;
    to_b = !to_b;
  }
};

void BM_WorldAdvance(benchmark::State& state) {
  twin::sim::World world(twin::build_scene(cell()));
  const double raw = raw_steps_per_second(world.scene(), 2000);
  std::vector<Mover> movers;
  for (const auto& r : cell().robots) {
    twin::sim::SimDriver& d = world.add_sim_driver(r.name);
    d.connect();
    const auto home = d.home();
    while (d.poll(home.id).phase != drivers::CommandPhase::done) world.advance(10ms);
    d.activate();
    Mover m{&d, r.home, r.home};
    m.b[0] += 0.6;
    m.b[1] -= 0.1;
    m.b[2] += 0.15;
    m.b[5] += 0.5;
    movers.push_back(m);
  }
  mjcb_time = steady_us;  // MuJoCo's timers: the time inside mj_step on this very trajectory
  const double in_step_before = world.scene().data()->timer[mjTIMER_STEP].duration;
  const std::int64_t start_steps = world.steps();
  const auto start = std::chrono::steady_clock::now();
  for (auto _ : state) {
    for (Mover& m : movers) m.keep_moving();
    world.advance(10ms);  // the runtime's control period: 2 steps of the cell's 5 ms
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto steps = static_cast<double>(world.steps() - start_steps);
  state.counters["steps_per_s"] = benchmark::Counter(steps, benchmark::Counter::kIsRate);
  state.counters["rt_factor"] =
      benchmark::Counter(steps * world.scene().model()->opt.timestep, benchmark::Counter::kIsRate);
  const double in_step = (world.scene().data()->timer[mjTIMER_STEP].duration - in_step_before) * 1e-6;
  mjcb_time = nullptr;
  state.counters["raw_steps_per_s"] = raw;
  state.counters["ratio_to_raw"] = steps / wall / raw;
  state.counters["same_path_raw_steps_per_s"] = steps / in_step;
  state.counters["ratio_to_same_path"] = in_step / wall;
  if (!world.drain_warnings().empty()) state.SkipWithError("MuJoCo warned during the benchmark");
}
BENCHMARK(BM_WorldAdvance)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
