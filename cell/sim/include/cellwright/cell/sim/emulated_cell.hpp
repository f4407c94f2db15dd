// EmulatedCell: a scenario's cell emulated in one process for virtual commissioning: the controllers of its robots over
// pseudo-terminals, each driving the MuJoCo arm of the twin (`twin emulate --scenario SCENARIO --robot
// melfa=movemaster:LINK`), and/or the twin's I/O image served on Modbus TCP to a PLC (`--io modbus:HOST:PORT[/UNIT]`).
// Serial drivers (a `twin run --driver ...` in another process, or a test) then drive the simulated robots through
// the real protocols, and a PLC program drives the belts and the machine through the cell's I/O list.
//
// What runs: the scenario's World (its cell as it really is, with the feed: make_cell_world), stepped by one
// simulation thread; for each emulated robot, its SimDriver behind an emulate::DriverArm, and the emulator of its
// language (Movemaster EX, VAL II) serving its link on a thread of its own, which is the SimDriver's owner. Robots
// that are not emulated hold where they are. The robots' digital I/O is the World's signal table: an output one
// controller sets (VAL II `SIGNAL n`) is input n of every other (`WAIT SIG(1000+n)`). A conveyor whose drive the cell
// wires to the controllers' output n (`run_signal: n`) runs while signal n is on and stands still while it is off,
// from the start and whatever its coil on the I/O below says; the other belts run from the start (or by their coil).
//
// THE I/O, IN VIRTUAL TIME (options.io). The World's TwinIo (twin/sim/twin_io.hpp: the coils and discrete inputs the
// cell description wires, any other address refused with exception 2) behind an emulate::ModbusServer. Requests are
// served on the simulation thread, between two steps, never while the World steps: a coil written takes effect at
// the next step, and every input read in one gap between steps shows the same state. Two ways to run:
//  - paced (default): the World advances one control period (10 ms) at a time at the wall clock's pace (times
//    options.speed); between two periods the thread serves the requests that arrive until the next is due.
//  - lock-step (options.lockstep, the scan): the World advances ONLY when a client reads the discrete inputs
//    (function 2, once it reaches the I/O image, whatever its answer): by exactly one scan of simulated time, and
//    then the read is answered with the inputs after that scan. Reads and writes of coils do not advance it. So a
//    PLC's scan (read the inputs, compute, write the coils) is one scan of the twin's time, whatever the wall clock
//    and the network do: the same sequence of requests gets the same replies, byte for byte, run to run.
//    The robots' serial lines run on the wall clock, so lock-step serves the I/O alone (no controllers).
//
// Threads: run() on the caller's thread until stop(); stop() from any thread. final_poses() after run() returns;
// io_endpoint() and sim_time() from any thread.
#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/emulate/misbehaviour.hpp"
#include "cellwright/emulate/modbus_server.hpp"
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
  // The twin's I/O served on Modbus TCP (see the top); none when empty. A request is logged through `log` (one line).
  std::optional<emulate::ModbusServerOptions> io;
  // Lock-step (see the top): the simulated time the World advances at each read of the discrete inputs, a positive
  // whole number of the cell's timesteps; none: paced. Needs `io` and no controllers; `speed` does not apply.
  std::optional<std::chrono::nanoseconds> lockstep;
};

class EmulatedCell {
 public:
  // Builds the World and the arms, and listens for the I/O's clients. Throws InputError (naming `where`) for a robot
  // that is not in the cell, twice, or a language other than movemaster and val2; nothing to emulate (no controller
  // and no io); a lock-step without io, with controllers, or with a scan that is not a positive whole number of the
  // cell's timesteps; whatever make_cell_world throws, and ModbusServer's (naming "--io") when it cannot listen.
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

  // Where the I/O is served ("127.0.0.1:1502"), empty without options.io.
  std::string io_endpoint() const;
  // The World's simulated time (as of its last step).
  std::chrono::nanoseconds sim_time() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Parses "ROBOT=movemaster:LINK" / "ROBOT=val2:LINK" (`twin emulate --robot`). Throws InputError naming `where` and
// the text when malformed.
EmulatedController parse_emulated_controller(const std::string& spec, const SourceLocation& where);

// Parses "modbus:HOST:PORT[/UNIT]" (`twin emulate --io`: PORT 0..65535, 0 a free one; UNIT 0..255, default 1) into
// where the twin's I/O is served. Throws InputError naming `where` and the text when malformed.
emulate::ModbusServerOptions parse_served_io(std::string_view spec, const SourceLocation& where);

}  // namespace cellwright::cell
