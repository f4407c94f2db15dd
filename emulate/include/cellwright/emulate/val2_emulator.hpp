// Val2Emulator: a Unimation VAL II monitor (the PUMA's controller) on a pseudo-terminal, speaking the protocol of
// docs/real-robots.md ("VAL II") with an EmulatedArm behind it. The VAL II driver (drivers/…/val2) is written apart
// from this, from the same page, so each checks the other; nothing here comes from the driver.
//
// THE LINE. serve() publishes a PseudoTerminal at a path and prints the prompt: CR LF then `.`. Each line received is
// a monitor command; when it has been done the monitor prints its answer lines (each ended by CR LF) and the prompt
// again. The answer and the prompt start a line of their own: when the output does not stand at the start of a line
// (without echo it stands after the last prompt), CR LF comes first. The monitor takes the next line
// only when the previous command has finished, so a motion's prompt comes when the arm has arrived.
//  - Line ends: CR, LF or CR LF (an LF right after a CR is the CR's partner, not an empty line). Backspace (BS) and
//    DEL erase the character before them, as on a terminal. Lines longer than 255 characters answer `*Syntax error*`.
//  - Echo (option, default on): the line as received (without its end, after erasures) and CR LF, written as soon as
//    the line is taken, before it is carried out.
//  - Case does not matter; spaces and tabs may stand between any two words, numbers and punctuation.
//  - Numbers: an optional sign, digits with or without a point (`12`, `-0.5`, `+.5`, `1e2`), whatever the locale.
//
// THE COMMANDS. Monitor commands: (empty line) → just the prompt; `DO instruction`; `SPEED n`; `WHERE`.
// Instructions after DO: `READY`, `MOVE loc`, `MOVES loc`, `OPENI`, `CLOSEI`, `SPEED n`, `SIGNAL n[,n...]`,
// `WAIT SIG(n)`, where loc is `TRANS(x,y,z,o,a,t)` (mm, degrees) or `#PPOINT(j1,...,j6)` (degrees; MOVES takes only
// TRANS). SPEED takes a percentage in [1, 100] (not necessarily whole: the joint speed fraction is n/100; the speed
// before any SPEED is Val2EmulatorOptions::speed). SIGNAL takes outputs ±1..±32 (several, comma-separated, as VAL II
// allows: all are checked before any is set); WAIT SIG takes ±1001..±1032 (input n − 1000, on or, negative, off;
// it waits as long as it takes). WHERE prints three lines: the doc's header, X Y Z (mm, 2 decimals) O A T (degrees,
// 3 decimals) and the hand opening (mm, 3 decimals), then the six joint angles (degrees, 3 decimals); columns 10
// characters wide for the first value and 11 for each further one.
//  - Orientation: R = Rz(O)·Ry(A)·Rz(T)·Rx(180°); with Val2EmulatorOptions::orientation val, VAL's published
//    convention (all zero: the hand points along −Y, the finger line along +X, the fingers in a horizontal plane; O
//    turns about the vertical, A tilts the hand about its finger line, A = 90 pointing down, T turns the finger line
//    about the approach axis). Locations are the monitor's tool point (Val2EmulatorOptions::tool, in the arm's TCP
//    frame) in its world (Val2EmulatorOptions::world, in the arm's base frame): the arm's TCP is world · L · tool⁻¹. WHERE writes the O, A, T, each in (−180, 180], nearest to the
//    last ones a MOVE or MOVES was given (at first 0, 0, 0): Z-Y-Z angles have two sets per rotation, and a whole
//    family when A is 0 or 180 (then O is kept and T takes the rest), so a location reads back as it was written.
//  - MOVE/MOVES TRANS: inverse kinematics (arm.chain().inverse(), seeded with the joints now, tolerances 1 µm and
//    1 µrad) within the joint limits; none → `*Location out of range*`. #PPOINT: the first joint outside its limits
//    → `*Joint n limit stop*`. READY moves to arm.home().
//  - ABBREVIATIONS: a command or instruction word may be cut to a prefix that is unique among the words this monitor
//    knows (an exact word always wins): monitor commands DO, SPEED, WHERE and the VAL II commands HERE, TEACH, POINT,
//    EDIT, EXECUTE, ABORT, STORE, LOAD, LIST; instructions READY, MOVE, MOVES, OPENI, CLOSEI, SPEED, SIGNAL, WAIT
//    and MOVET, APPRO, DEPART, DRIVE, ALIGN, OPEN, CLOSE, GRASP. So `D MOVES`, `DO RE`, `WH`, `SP 50`, `DO SI 3`,
//    `DO OPENI` work; `DO MOV` (MOVE, MOVES, MOVET), `S` and `DO OPEN` (a VAL II instruction not emulated) answer
//    `*Unknown instruction*`, like any word that is not known or not emulated. Function names (TRANS, #PPOINT, SIG)
//    are written in full.
//  - PROGRAMS (docs/real-robots.md, "Robot programs"; val2/program.hpp): `.PROGRAM name` ... `.END` stores a
//    program (each line answered with the prompt), `.LOCATIONS` ... `.END` named locations (`name x y z o a t`),
//    `EXECUTE name` (or EX, EXE, ...) runs it; the prompt comes when it has ended, after `Program completed` or the
//    failing step's error line and `Program stopped at step n`. Steps may `MOVE`/`MOVES` to a named location.
//
// ERRORS, each a line before the prompt; the command is not carried out:
//   `*Unknown instruction*`   the first word (or the word after DO) is unknown, ambiguous or not emulated
//   `*Syntax error*`          a character that starts no word, number or punctuation; a missing or extra
//                             parenthesis or comma; something after a complete TRANS(...)/#PPOINT(...)/SIG(...)
//   `*Invalid argument*`      a missing, extra or wrong kind of argument: `MOVE P1`, `TRANS` with five values,
//                             `SPEED fast`, `READY 3`, `WAIT 1001`
//   `*Illegal value*`         a number out of its range or not whole where it must be: `SPEED 0`, `SIGNAL 33`,
//                             `WAIT SIG(5)`
//   `*Location out of range*` no joint solution within the limits (or the arm said unreachable)
//   `*Joint n limit stop*`    a #PPOINT beyond joint n's limits (n from 1)
//   `*Servo error*`           the arm could not finish a motion or a grip (in the twin: a collision, a fault); the
//                             arm's message is in Stats::last_failure
//   `*Arm power off*`         only from the `error` misbehaviour
//
// MISBEHAVIOURS (misbehaviour.hpp): one decision of the plan per received line (empty lines count), lines counted
// over the emulator's life:
//   error        echo, `*Arm power off*`, prompt; the line is not carried out
//   unreachable  echo, `*Location out of range*`, prompt; not carried out
//   unknown      echo, `*Invalid format*` (an error the driver's list does not have), prompt; not carried out
//   garbage      echo; the line is carried out, and its answer and prompt are replaced by one line of seeded bytes
//                in 0x80–0xFE (never CR, LF, `.` or `*`) ended by CR LF. No prompt follows: the next line (an empty
//                one, as a driver's reset sends) is answered as usual
//   silent       the line is swallowed: no echo, not carried out, nothing printed
//   drop         the line is not carried out; the pseudo-terminal hangs up (bytes after the line are lost), and
//                after reconnect_delay a fresh one is published at the same path with the prompt (the link points
//                to the hung-up terminal meanwhile). The arm, the speed and the plan go on
//   late         echo, the line is carried out, then its answer and prompt come `delay` later
//
// THREADS. serve() runs on one thread (it calls the arm); stop() and stats() may be called from any thread. The
// arm must not be used by anyone else while serve() runs.
#pragma once

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"
#include "cellwright/emulate/line_pace.hpp"
#include "cellwright/emulate/misbehaviour.hpp"

namespace cellwright::emulate {

struct Val2EmulatorOptions {
  std::uint64_t seed = 1;                   // the misbehaviour plan's and the garbage bytes' generator
  std::vector<Misbehaviour> misbehaviours;  // see above
  bool echo = true;                         // echo each received line (`--no-echo` turns it off)
  std::chrono::nanoseconds reconnect_delay{std::chrono::milliseconds(200)};  // after a drop, before republishing
  double speed = 100;  // the monitor speed (percent, [1, 100]) before any SPEED
  // The monitor's conventions (docs/real-robots.md, "Commissioning"; `twin emulate val2 --orientation --world-offset
  // ...`). Defaults: the page's (tool_down; world = the arm's base link; tool point = the TCP).
  enum class Orientation : std::uint8_t { tool_down, val };
  Orientation orientation = Orientation::tool_down;
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();  // the monitor's world frame in the arm's base frame
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();   // the monitor's tool point in the arm's TCP frame
  // The pseudo-terminal paced as a serial line at this rate (line_pace.hpp: answers reach the host a character time
  // apart, a line is taken when its last byte would have arrived); baud 0, the default: at once.
  LineRate pace;
  // Called on the serving thread with each line received ("< ...") and each answer line ("> ..."), e.g. for
  // `twin emulate --verbose`. May be empty.
  std::function<void(std::string_view)> log;
  // Called on the serving thread with each step's number (from 1) just before `EXECUTE` runs it (docs/real-robots.md,
  // "Robot programs"). May be empty.
  std::function<void(int)> on_program_step;
};

class Val2Emulator {
 public:
  // Keeps a reference to `arm` (it must outlive the emulator). Throws InputError when the arm's chain does not have
  // six joints (VAL II locations are six joint angles) or options.speed is outside [1, 100].
  Val2Emulator(EmulatedArm& arm, Val2EmulatorOptions options);
  ~Val2Emulator();
  Val2Emulator(const Val2Emulator&) = delete;
  Val2Emulator& operator=(const Val2Emulator&) = delete;

  // Publishes a pseudo-terminal at `link` and serves it until stop() (see above for drops). Returns when stopped
  // (at once when stop() came first); the link is removed then. Throws InputError when a pseudo-terminal cannot be
  // published at `link` (see PseudoTerminal). Call it once, from one thread.
  void serve(const std::filesystem::path& link);
  // Makes serve() return soon: wakes its wait and interrupts the arm's blocking call (EmulatedArm::interrupt(): the
  // arm answers interrupted from then on). Idempotent; any thread, before or during serve().
  void stop();

  struct Stats {
    std::uint64_t lines = 0;          // lines received (what the misbehaviour plan counts)
    std::uint64_t commands = 0;       // lines parsed and carried out (successful or not; empty lines included)
    std::uint64_t errors = 0;         // error lines printed (`*...*`), misbehaviours' included
    std::uint64_t misbehaviours = 0;  // lines a misbehaviour applied to
    std::uint64_t connections = 0;    // pseudo-terminals published
    std::uint64_t bytes_in = 0;       // bytes read from the line
    std::uint64_t bytes_out = 0;      // bytes written to it
    std::string last_error;           // the last error line printed
    std::string last_failure;         // the arm's message behind the last `*Servo error*` or arm refusal
  };
  // A copy of the counters now. Any thread.
  Stats stats() const;
  // Waits until at least `count` pseudo-terminals have been published (the first by serve(), then one after each
  // drop), at most `timeout`, or until stop(); true if they have. The path is ready for a host when this returns
  // true. Any thread.
  bool wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::emulate
