// The cost of a whole `twin run`: runs scenarios in this process, lock-step, headless (no overview snapshot, no
// outputs written; the camera only if the scenario's perception is vision), and for each prints
//   simulated time, wall time of the run, its real-time factor (simulated / wall);
//   raw: the real-time factor of mj_step alone on the same compiled model and the same trajectory (the simulated time
//   over the wall time spent inside mj_step during the run, from MuJoCo's own timers, mjData::timer, which run because
//   this program sets mjcb_time), and the ratio whole run / raw (target >= 0.8: what the runtime, the drivers and the
//   checks cost on top of the physics);
//   cpu: the process's CPU time during the run (all threads) and simulated seconds per CPU second (less disturbed
//   than the wall clock on a loaded machine);
//   with --raw-seconds S, raw-end: mj_step alone on a copy of the run's end state for S simulated seconds;
//   where mj_step's time goes (position stage with collision detection, velocity and actuation, constraint solver,
//   integration and the rest);
//   the number of physics steps, the constraint rows and contacts the run needed at most (mjData::maxuse_efc,
//   maxuse_con) against the model's njmax and nconmax, and the process's peak resident memory so far (getrusage
//   ru_maxrss; with --repeat the first run's is the figure).
// Usage: run_bench [--repeat N] [--raw-seconds S] scenario.yaml...
// Pin it to one core for figures that compare: taskset -c 0 build/tools/run_bench --repeat 5 scenes/exchange.yaml
// With --repeat N each scenario runs N times and the medians follow the individual runs. Exit 1 if a run's outcome is
// not ok (the figures of a failed run are not worth comparing), 2 on bad input.
#include <mujoco/mujoco.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/scenario.hpp"

namespace {

using namespace cellwright;
using namespace cellwright::cell;
using Clock = std::chrono::steady_clock;

struct Figures {
  double sim = 0, wall = 0, cpu = 0, rtf = 0, raw_rtf = 0, peak_mb = 0;
  double cpu_rtf = 0;      // simulated seconds per CPU second of the process (robust on a loaded machine)
  double raw_end_rtf = 0;  // raw mj_step from the run's end state, on its own
  double position = 0, collision = 0, velocity = 0, solver = 0, rest = 0;  // shares of the time in mj_step
  std::int64_t steps = 0;
  int max_constraints = 0, njmax = 0, max_contacts = 0, nconmax = 0;
  double ratio = 0;  // rtf / raw_rtf
  bool ok = false;
  std::string verdict;
};

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // ru_maxrss is in kilobytes on Linux
}

// CPU time of the whole process (every thread), user and system.
double process_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  return s(u.ru_utime) + s(u.ru_stime);
}
// MuJoCo's timers (mjData::timer) run when mjcb_time is set: microseconds of the steady clock.
mjtNum steady_us() {
  return static_cast<mjtNum>(
             std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count()) /
         1000.0;
}

// Raw mj_step from a copy of `state` (the run's end: the robots' servos hold their targets, the belts run, the parts
// rest where the run left them) for `seconds` of simulated time, nothing else done between the steps: simulated
// seconds per wall second.
double raw_from_end(const mjModel* m, const mjData* state, double seconds) {
  std::unique_ptr<mjData, void (*)(mjData*)> d(mj_makeData(m), mj_deleteData);
  mj_copyData(d.get(), m, state);
  const auto steps = static_cast<std::int64_t>(seconds / m->opt.timestep);
  const auto start = Clock::now();
  for (std::int64_t i = 0; i < steps; ++i) mj_step(m, d.get());
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  return static_cast<double>(steps) * m->opt.timestep / wall;
}

Figures run_once(const std::string& file, double raw_seconds) {
  const Scenario s = load_scenario(file);
  const Preflight pre = preflight(s, &twin_port());
  if (!pre.ok()) throw InputError({file, 0, 0}, "refused: " + pre.problems.front());
  RunOptions options;
  options.realtime = false;
  ScenarioRun run(s, pre, options);
  const mjModel* m = run.world().scene().model();

  Figures f;
  const double cpu_start = process_cpu_seconds();
  const auto start = Clock::now();
  runtime::StepState st;
  do {
    st = run.runtime().step();  // as `twin run` does in lock-step
  } while (!st.ended);
  f.wall = std::chrono::duration<double>(Clock::now() - start).count();
  f.cpu = process_cpu_seconds() - cpu_start;
  f.sim = std::chrono::duration<double>(st.result->end_time).count();
  f.rtf = f.sim / f.wall;
  f.steps = run.world().steps();
  f.max_constraints = run.world().scene().data()->maxuse_efc;
  f.max_contacts = run.world().scene().data()->maxuse_con;
  f.njmax = m->njmax;
  f.nconmax = m->nconmax;
  const Report report = run.report();
  f.ok = report.ok();
  f.verdict = report.ok() ? "ok" : report.failures.front();
  f.peak_mb = peak_rss_mb();  // before raw_from_end makes another mjData
  const mjData* d = run.world().scene().data();
  const double in_step = d->timer[mjTIMER_STEP].duration * 1e-6;  // s of wall time inside mj_step during the run
  f.raw_rtf = f.sim / in_step;
  f.ratio = f.rtf / f.raw_rtf;
  f.cpu_rtf = f.sim / f.cpu;
  auto share = [&](int t) { return d->timer[t].duration * 1e-6 / in_step; };
  f.collision = share(mjTIMER_POS_COLLISION);
  f.position = share(mjTIMER_POSITION);
  f.velocity = share(mjTIMER_VELOCITY) + share(mjTIMER_ACTUATION);
  f.solver = share(mjTIMER_CONSTRAINT);
  f.rest = 1.0 - f.position - f.velocity - share(mjTIMER_ACCELERATION) - f.solver;
  if (raw_seconds > 0) f.raw_end_rtf = raw_from_end(m, d, raw_seconds);
  return f;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void print(const std::string& label, const Figures& f) {
  std::printf(
      "%-26s sim %6.2f s  wall %6.3f s  rtf %5.1fx  raw %5.1fx  ratio %4.2f  cpu %6.3f s  cpu-rtf %5.1fx  "
      "raw-end %5.1fx | step: position %2.0f%% (collision %2.0f%%) velocity %2.0f%% solver %2.0f%% "
      "integration %2.0f%% | steps %6lld  efc %3d/%d  con %3d/%d  peak %6.1f MB  %s\n",
      label.c_str(), f.sim, f.wall, f.rtf, f.raw_rtf, f.ratio, f.cpu, f.cpu_rtf, f.raw_end_rtf, 100 * f.position,
      100 * f.collision, 100 * f.velocity, 100 * f.solver, 100 * f.rest, static_cast<long long>(f.steps),
      f.max_constraints, f.njmax, f.max_contacts, f.nconmax, f.peak_mb, f.verdict.c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  int repeat = 1;
  double raw_seconds = 0.0;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--repeat" || a == "--raw-seconds") && i + 1 < argc) {
      const double v = std::atof(argv[++i]);
      if (!(v > 0)) {
        std::fprintf(stderr, "%s needs a positive number, got '%s'\n", a.c_str(), argv[i]);
        return 2;
      }
      (a == "--repeat" ? void(repeat = static_cast<int>(v)) : void(raw_seconds = v));
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "usage: %s [--repeat N] [--raw-seconds S] scenario.yaml...\n", argv[0]);
      return 2;
    } else {
      files.push_back(a);
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: %s [--repeat N] [--raw-seconds S] scenario.yaml...\n", argv[0]);
    return 2;
  }
  mjcb_time = steady_us;  // MuJoCo's own timers: the time spent inside mj_step during the run
  bool all_ok = true;
  try {
    for (const std::string& file : files) {
      std::vector<Figures> runs;
      for (int r = 0; r < repeat; ++r) {
        runs.push_back(run_once(file, raw_seconds));
        print(file + " #" + std::to_string(r + 1), runs.back());
        all_ok = all_ok && runs.back().ok;
      }
      if (repeat > 1) {
        auto med = [&](auto field) {
          std::vector<double> v;
          for (const Figures& f : runs) v.push_back(static_cast<double>(f.*field));
          return median(v);
        };
        Figures m = runs.front();
        m.wall = med(&Figures::wall);
        m.rtf = med(&Figures::rtf);
        m.raw_rtf = med(&Figures::raw_rtf);
        m.ratio = med(&Figures::ratio);
        m.cpu = med(&Figures::cpu);
        m.cpu_rtf = med(&Figures::cpu_rtf);
        m.raw_end_rtf = med(&Figures::raw_end_rtf);
        // The peak stays the first run's: later ones include the earlier runs' raw measurements.
        print(file + " median", m);
      }
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  return all_ok ? 0 : 1;
}
