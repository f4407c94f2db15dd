// EmulatedCell: the controllers of a scenario's cell, emulated in one process over pseudo-terminals, each driving the
// MuJoCo arm of the twin (virtual commissioning: `twin emulate --scenario SCENARIO --robot melfa=movemaster:LINK`).
// Serial drivers (a `twin run --driver ...` in another process, or a test) then drive the simulated robots through
// the real protocols.
//
// What runs: the scenario's World (its cell as it really is, with the feed: make_cell_world), stepped in real time by
// one simulation thread; for each emulated robot, its SimDriver behind an emulate::DriverArm, and the emulator of its
// language (Movemaster EX, VAL II) serving its link on a thread of its own, which is the SimDriver's owner. The cell's
// digital I/O is the World's signal table: an output one controller sets (VAL II `SIGNAL n`) is input n of every
// other (`WAIT SIG(1000+n)`).
//
// Threads: run() on the caller's thread until stop(); stop() from any thread. final_poses() after run() returns.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/emulate/misbehaviour.hpp"
#include "cellwright/cell/report.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

struct EmulatedController {
  std::string robot;                                              // a cell robot
  models::DriverKind language = models::DriverKind::kMovemaster;  // kMovemaster or kVal2
  std::filesystem::path link;                                     // where its pseudo-terminal is published
  std::vector<emulate::Misbehaviour> misbehaviours;               // what it is told to do wrong
};

struct EmulatedCellOptions {
  std::uint64_t seed = 1;  // the misbehaviour plans' (each controller's seed is this plus its index)
  bool echo = true;        // VAL II echoes what it receives
  // Simulation seconds per wall-clock second (`--speed`, > 0): the World, and so every arm's motion, runs this many
  // times faster than real time; a `twin run --realtime --speed X` against it then sees motions take their planned
  // simulated time. The serial lines' pacing and the drivers' deadlines stay on the wall clock.
  double speed = 1.0;
  // Called once every controller's link is published (on run()'s thread), and with one line per event of the
  // emulators (any thread). Either may be empty.
  std::function<void()> on_ready;
  std::function<void(std::string_view)> log;
  // Called (on the robot's emulator thread) with the cell robot and the stored program's line (Movemaster) or step
  // (VAL II) just before the controller runs it (docs/real-robots.md, "Robot programs"). May be empty.
  std::function<void(std::string_view, int)> on_program_line;
};

class EmulatedCell {
 public:
  // Builds the World and the arms. Throws InputError (naming `where`) for a robot that is not in the cell, twice, or a
  // language other than movemaster and val2, and whatever make_cell_world throws.
  EmulatedCell(const Scenario& scenario, std::vector<EmulatedController> controllers, EmulatedCellOptions options,
               const SourceLocation& where);
  ~EmulatedCell();
  EmulatedCell(const EmulatedCell&) = delete;
  EmulatedCell& operator=(const EmulatedCell&) = delete;

  // Runs the cell until stop(). Throws InputError when a link cannot be published or an arm cannot be brought up.
  void run();
  void stop();

  // The cell's workpieces as the simulation has them (after run()).
  std::vector<FinalPose> final_poses() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Parses "ROBOT=movemaster:LINK" / "ROBOT=val2:LINK" (`twin emulate --robot`). Throws InputError naming `where` and
// the text when malformed.
EmulatedController parse_emulated_controller(const std::string& spec, const SourceLocation& where);

}  // namespace cellwright::cell
