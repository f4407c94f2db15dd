// Robot programs: the post-processors. A scenario's task program, once its Petri net is proven deadlock-free
// (cell::preflight), is written out per robot in the robot controller's own language, as RoboDK's post-processors
// do for one robot: a Movemaster EX program (numbered lines, positions defined with PD) or a VAL II program
// (.PROGRAM ... .END with a .LOCATIONS section), with the cell's real coordinates and the synchronisation turned into
// the controllers' digital I/O (`twin compile PROGRAM --scenario SCENARIO --robot-language -o DIR`).
// docs/real-robots.md, "Robot programs", says what is written and which choices are assumed.
//
// Coordinates: every move's target is the preflight's motion plan's (cell::plan_motions, resolved nominally from the
// cell description: parts wait at their conveyor's stop, held parts move with the hand), and its tool
// pose in the robot's base frame is written in the language's convention: Movemaster x,y,z,p,r (mm, degrees, the
// 5-axis rule), VAL II TRANS(x,y,z,o,a,t) (mm, degrees, O/A/T as the doc defines them). The conversions here are
// written from the doc, apart from the drivers' and the emulators', so that the emulators check them.
//
// Synchronisation: each event the program's robots exchange gets one I/O channel n (from 1, in the order of
// CompiledProgram::semaphores). The signalling controller's output n is wired to input n of the waiting one:
// VAL II signals with `SIGNAL n` and waits with `WAIT SIG(1000+n)`; the Movemaster sets its output bit with `OB +n`
// and waits with a test-bit jump onto its own line (`L TB -n,L`: jump back while input n is off). Each program first
// turns off the outputs it drives. What plain wires cannot do is refused: a counting semaphore used more than once or
// by more than one robot on each side, an event with an initial count, a critical region shared by two controllers.
// A critical region used by one robot only needs no wire (its wait and signal are left out).
//
// Parts that come later: before a robot's first move to a part that rides a conveyor to its stop after the start
// (cell::MotionPlan::gates: fed parts, parts starting away from the stop; cell::MotionPlan::class_takes: a part of a
// class whose location lies on a running belt, which brings it there, or that the feed brings), its program waits for
// that conveyor's part-present sensor, input n = models::ConveyorSpec::sensor (VAL II `WAIT SIG(1000+n)`, Movemaster
// `L TB -n,L`), as robot control waits until it sees the part. A class's location off the belts needs no wait (robots
// put its parts there, ordered by the program's events). Event wires count up from 1; a sensor's input must lie above
// them.
//
// Devices (issue 26; docs/devices.md, "Generated robot programs and the I/O"): a program runs on its controller
// alone, so a device command is written only when the cell wires the device to the controllers' own I/O. `wait S`, S
// a conveyor's stop eye on input n (ConveyorSpec::sensor), waits on that input as above (and the next move does not
// wait for it again); `run C` / `accumulate C` / `stop C`, C a conveyor whose drive is on output n
// (ConveyorSpec::run_signal), set output n on / off (VAL II `SIGNAL n` / `SIGNAL -n`, Movemaster `OB +n` / `OB -n`;
// turned off in the set-up, as the net starts belts stopped). A device's states (task::Semaphore::device) are no
// wires: the device holds them. Refused: a machine's start and wait (its coil and inputs are on the cell's I/O unit),
// a photo-eye on no controller input, a belt without run_signal, a belt run or stopped by two robots.
//
// Output is deterministic: the same inputs give the same bytes (no date, file names without directories).
//
// Thread safety: pure functions of their arguments; any thread may call them.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// One wire of the cell: output `channel` of `from`'s controller to input `channel` of `to`'s.
struct IoChannel {
  int channel = 0;    // 1..
  std::string event;  // the compiled program's event (semaphore) name
  std::string from;   // program robot label that signals it
  std::string to;     // program robot label that waits for it
};

// One robot's program in its controller's language.
struct RobotProgram {
  std::string robot;                                              // program label ("r1")
  std::string cell_robot;                                         // cell robot ("puma")
  models::DriverKind language = models::DriverKind::kMovemaster;  // kMovemaster or kVal2
  std::string name;       // the program's name on the controller: the cell robot's name
  std::string file_name;  // "<cell robot>.movemaster" or "<cell robot>.val2"
  std::string text;       // the file's bytes: header comments, then the program
  // What a host sends, line by line (without line ends), to load the program into the controller: every line of
  // `text` but the header comments a Movemaster does not understand (`'` lines); for VAL II all of it.
  std::vector<std::string> host_lines;
  // Per primitive of the robot's compiled program: the program line that carries it out (the Movemaster line number;
  // the VAL II step number, counting from 1 after .PROGRAM, comments included), or -1 when the primitive needs no
  // line (the wait and signal of a critical region only this robot uses).
  std::vector<int> primitive_line;
};

struct RobotPrograms {
  std::vector<RobotProgram> robots;  // program robot order
  std::vector<IoChannel> channels;   // channel order
  std::string check;                 // the net's check result as the headers quote it
};

// The speed the programs set (as the simulated controller's default: half the arms' top speeds): Movemaster `SP 4`
// ((4 + 1)/10 of top speed in the emulator), VAL II `SPEED 50`.
inline constexpr int kMovemasterSpeedLevel = 4;
inline constexpr int kVal2Speed = 50;
// The highest channel each controller has (VAL II outputs 1–32; the Movemaster's bits, assumed: 1–16).
inline constexpr int kVal2Channels = 32;
inline constexpr int kMovemasterChannels = 16;

// Puts robot ROBOT's program in a language: "ROBOT=movemaster", "ROBOT=val2" or "ROBOT=sim" (a ":PORT" after it is
// accepted and ignored, so that `twin run`'s --driver values work). ROBOT is a cell robot. Throws InputError naming
// `where` and the text when the spec is malformed or names no robot of the cell.
void set_language(cell::Scenario& scenario, const std::string& spec, const SourceLocation& where);

// Writes every program robot's program, its moves from the preflight's motion plan (Preflight::plan). `preflight` is
// cell::preflight(scenario). Throws InputError, naming the
// file and line that cause it, when:
//  - the preflight failed (the net is not deadlock-free, bounded and exclusive, or a move cannot be made): the
//    message lists its problems;
//  - a program robot runs on the `sim` driver (the scenario's `drivers:` or the cell decide the language);
//  - an event cannot be a wire (see the top), a critical region is used by two robots, more channels are needed than
//    a controller has;
//  - a robot must wait for a part that comes later on a conveyor without a part-present sensor (naming the
//    conveyor's line in the cell, the robot and the task line), a class's location lies on a running belt where no
//    part comes to rest (no stop, or more than 0.25 m before the stop bar: naming the location's line), a robot goes
//    to a named part after it was let go of on a running belt (cell::MotionPlan::belt_rides: naming the move's task
//    line), or a sensor's input or a belt's run_signal is one of the event wires' channels (naming its line);
//  - a device command the robot controllers are not wired for (see Devices above; naming the command's line and
//    saying what is generated and how to run the program instead), or a belt run or stopped by two robots;
//  - a Movemaster move needs a tool pose the 5-axis rule cannot express (its approach axis out of the arm's vertical
//    plane by more than 0.5°, or the tool point on the base's z axis).
RobotPrograms generate_robot_programs(const cell::Scenario& scenario, const cell::Preflight& preflight);

// Writes each program as DIR/<file_name>, atomically (cellwright/common/files.hpp), creating DIR if needed. Throws
// InputError naming the path when it cannot.
void write_robot_programs(const RobotPrograms& programs, const std::filesystem::path& dir);

}  // namespace cellwright::cell
