// The proof that generated robot programs do what `twin run` does: the exchange scenario's programs (the PUMA in
// VAL II, the MELFA in Movemaster EX) are loaded over the pseudo-terminals into the controllers emulated on the twin's
// arms (EmulatedCell), started together with EXECUTE and RN as soon as the cell is up (the PUMA's program waits for the
// part-present sensor at the input conveyor's stop until A is there), and their run gives the same outcome (A on the
// output conveyor) and the same order as the runtime's firings: each robot its primitives in program order, and every
// event signalled before the step after its wait starts, in the same order of events across the cell.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <condition_variable>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/cell/robot_programs.hpp"
#include "cellwright/cell/sim/emulated_cell.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "emulate/program_host.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using cell::Scenario;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// A run told as the primitives robots started, in the order they started: (program robot index, primitive).
using Order = std::vector<std::pair<std::size_t, std::size_t>>;

// Each robot's primitives in the order they started.
std::vector<std::vector<std::size_t>> per_robot(const Order& order, std::size_t robots) {
  std::vector<std::vector<std::size_t>> out(robots);
  for (const auto& [r, k] : order) out[r].push_back(k);
  return out;
}

// Whether `event` is carried by a wire between the controllers (not a device's state, which the device holds).
bool wired(const RobotPrograms& programs, const std::string& event) {
  return std::any_of(programs.channels.begin(), programs.channels.end(),
                     [&](const IoChannel& c) { return c.event == event; });
}

// The wired events in the order they were signalled across the cell. The two robots of a steps-table line signal the
// end of the line to each other at the same time (`stepN.r1>r2`, `stepN.r2>r1`): which comes first is a race, so each
// is told as its line's barrier (`stepN`).
std::vector<std::string> signal_order(const Order& order, const task::CompiledProgram& prog,
                                      const RobotPrograms& programs) {
  std::vector<std::string> out;
  for (const auto& [r, k] : order) {
    const task::Primitive& p = prog.programs[r].primitives[k];
    if (p.kind != task::PrimitiveKind::kSignal || !wired(programs, p.event)) continue;
    out.push_back(p.event.starts_with("step") ? p.event.substr(0, p.event.find('.')) : p.event);
  }
  return out;
}

// Checks that every wait on a wire ended after its event was signalled: the next primitive after the wait that the
// run tells (a device's state has no line in a robot program) starts after the signal.
void expect_waits_after_signals(const Order& order, const task::CompiledProgram& prog, const RobotPrograms& programs,
                                const std::string& run) {
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> at;
  for (std::size_t i = 0; i < order.size(); ++i) at[order[i]] = i;
  for (std::size_t r = 0; r < prog.programs.size(); ++r) {
    const auto& prims = prog.programs[r].primitives;
    for (std::size_t k = 0; k + 1 < prims.size(); ++k) {
      if (prims[k].kind != task::PrimitiveKind::kWait || !wired(programs, prims[k].event)) continue;
      for (std::size_t s = 0; s < prog.programs.size(); ++s) {
        for (std::size_t j = 0; j < prog.programs[s].primitives.size(); ++j) {
          const task::Primitive& p = prog.programs[s].primitives[j];
          if (p.kind != task::PrimitiveKind::kSignal || p.event != prims[k].event) continue;
          std::pair<std::size_t, std::size_t> signal{s, j}, after{r, k + 1};
          while (after.second + 1 < prims.size() && at.count(after) == 0) ++after.second;
          ASSERT_TRUE(at.count(signal) && at.count(after)) << run << ": " << p.event;
          EXPECT_LT(at[signal], at[after])
              << run << ": " << prog.robots[r] << " went on past 'wait " << p.event << "' before it was signalled";
        }
      }
    }
  }
}

// Generates the programs of `scenario` (the PUMA in VAL II, the MELFA in Movemaster EX), runs them on the emulated
// cell and checks them against twin run (see the top); `wait` is the PUMA's wait for the photo-eye, which its program
// must have.
void expect_programs_fire_as_twin_run(const fs::path& scenario, const std::string& wait) {
  Scenario s = cell::load_scenario(scenario);
  set_language(s, "puma=val2", {"test", 0, 0});
  set_language(s, "melfa=movemaster", {"test", 0, 0});
  const cell::Preflight pre = cell::preflight(s, &twin_port());
  const RobotPrograms programs = generate_robot_programs(s, pre);
  const task::CompiledProgram& prog = s.program;
  const std::size_t n = prog.robots.size();

  // twin run, on the simulated drivers (lock-step): the order of the firings that start primitives.
  Order twin_order;
  {
    Scenario sim = s;
    for (const char* d : {"puma=sim", "melfa=sim"}) set_language(sim, d, {"test", 0, 0});
    cell::ScenarioRun run(sim, pre);
    run.runtime().run();
    const cell::Report report = run.report();
    ASSERT_TRUE(report.ok()) << cell::format_summary(report);
    for (const runtime::LoggedEvent& e : runtime::decode_log(run.runtime().log().text(), "events")) {
      const auto* fire = std::get_if<runtime::events::Fire>(&e.event);
      if (fire == nullptr) continue;
      const auto it = std::find(prog.robots.begin(), prog.robots.end(), fire->robot);
      const auto r = static_cast<std::size_t>(it - prog.robots.begin());
      if (fire->primitive >= 0 && static_cast<std::size_t>(fire->primitive) < prog.programs[r].primitives.size()) {
        twin_order.emplace_back(r, static_cast<std::size_t>(fire->primitive));
      }
    }
  }

  // The emulated cell: the programs sent over the lines, then run; the lines each controller runs recorded.
  const fs::path dir = fs::path(::testing::TempDir()) / ("robot_programs_run_" + scenario.stem().string());
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::mutex mutex;
  std::condition_variable changed;
  bool ready = false;
  std::vector<std::pair<std::string, int>> lines_run;  // (cell robot, line or step), in the order they started
  cell::EmulatedCellOptions options;
  options.echo = false;
  options.speed = 4.0;  // the arms move four times faster than real time: the order and outcome are the same
  options.on_ready = [&] {
    std::lock_guard lock(mutex);
    ready = true;
    changed.notify_all();
  };
  options.on_program_line = [&](std::string_view robot, int line) {
    std::lock_guard lock(mutex);
    lines_run.emplace_back(std::string(robot), line);
  };
  std::vector<cell::EmulatedController> controllers;
  for (const RobotProgram& p : programs.robots) {
    controllers.push_back({p.cell_robot, p.language, dir / p.cell_robot, {}});
  }
  cell::EmulatedCell cell(s, controllers, options, {"test", 0, 0});
  auto running = std::async(std::launch::async, [&] { cell.run(); });
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(changed.wait_for(lock, 120s, [&] { return ready; })) << "the emulated controllers did not come up";
  }
  std::vector<std::future<std::string>> outcomes;
  {
    std::vector<std::unique_ptr<emulate::testing::ProgramHost>> hosts;
    for (const RobotProgram& p : programs.robots) {
      auto host = std::make_unique<emulate::testing::ProgramHost>(dir / p.cell_robot);
      if (p.language == models::DriverKind::kMovemaster) {
        EXPECT_TRUE(host->load_movemaster(p.host_lines));
      } else {
        ASSERT_TRUE(host->sync_val2());
        const std::string printed = host->load_val2(p.host_lines);
        EXPECT_EQ(printed.find('*'), std::string::npos) << printed;
      }
      hosts.push_back(std::move(host));
    }
    // Both started at once, each host waiting on its own thread for its program's end. A rides the input conveyor
    // for about 20 s: the PUMA's program waits for the part-present sensor at its stop before its first move to A, as
    // twin run's robot control waits until it sees A there.
    EXPECT_THAT(programs.robots[0].text, ::testing::HasSubstr(wait));
    for (std::size_t i = 0; i < hosts.size(); ++i) {
      emulate::testing::ProgramHost* host = hosts[i].get();
      const RobotProgram& p = programs.robots[i];
      outcomes.push_back(std::async(std::launch::async, [host, &p] {
        if (p.language == models::DriverKind::kMovemaster) {
          return std::string("ER ") + host->run_movemaster(300s).value_or("(no answer)");
        }
        return host->execute_val2(p.name, 300s).value_or("(no prompt)");
      }));
    }
    EXPECT_EQ(outcomes[0].get().find("Program completed") != std::string::npos, true) << "the PUMA's program";
    EXPECT_EQ(outcomes[1].get(), "ER 0") << "the MELFA's program";
  }
  cell.stop();
  running.get();

  // The outcome: A on the output conveyor, as the scenario expects (and as twin run left it).
  const models::WorkpieceSpec& a = *s.cell.find_workpiece("A");
  for (const cell::FinalPose& f : cell.final_poses()) {
    if (f.name != "A") continue;
    EXPECT_THAT(cell::places_of(s.cell, a, f, s.expect.at(0).tolerance), ::testing::Contains("output"));
  }

  // The lines run, told as primitives (a device's states have none: the device holds them).
  Order emulated_order;
  for (const auto& [robot, line] : lines_run) {
    for (std::size_t r = 0; r < n; ++r) {
      if (programs.robots[r].cell_robot != robot) continue;
      const std::vector<int>& lines = programs.robots[r].primitive_line;
      const auto it = std::find(lines.begin(), lines.end(), line);
      if (it != lines.end()) emulated_order.emplace_back(r, static_cast<std::size_t>(it - lines.begin()));
    }
  }
  const auto twin_robots = per_robot(twin_order, n), emulated_robots = per_robot(emulated_order, n);
  for (std::size_t r = 0; r < n; ++r) {
    std::vector<std::size_t> all, with_lines;
    for (std::size_t k = 0; k < prog.programs[r].primitives.size(); ++k) {
      all.push_back(k);
      if (programs.robots[r].primitive_line[k] >= 0) with_lines.push_back(k);
    }
    EXPECT_EQ(twin_robots[r], all) << "twin run, " << prog.robots[r];
    EXPECT_EQ(emulated_robots[r], with_lines) << "robot programs, " << prog.robots[r];
  }
  expect_waits_after_signals(twin_order, prog, programs, "twin run");
  expect_waits_after_signals(emulated_order, prog, programs, "robot programs");
  EXPECT_EQ(signal_order(emulated_order, prog, programs), signal_order(twin_order, prog, programs));
  fs::remove_all(dir);
}

TEST(RobotProgramsRun, ExchangeProgramsOnTheEmulatedCellFireAsTwinRun) {
  expect_programs_fire_as_twin_run(kScenes + "/exchange.yaml", "WAIT SIG(1016)");
}

// Issue 26: the program runs the input belt and waits for its photo-eye itself (tests/data/eye). In the generated
// programs the PUMA sets output 15, which runs the twin's belt (the cell's run_signal: it stands still until then),
// and waits on input 16, which the twin's photo-eye sets when A comes to rest at the stop.
TEST(RobotProgramsRun, ProgramsThatRunTheBeltAndWaitForTheEyeFireAsTwinRun) {
  expect_programs_fire_as_twin_run(std::string(CW_SOURCE_DIR) + "/tests/data/eye/eye.yaml",
                                   "; eye.task:14:3 wait input_eye\n  WAIT SIG(1016)\n");
}

}  // namespace
}  // namespace cellwright::cell
