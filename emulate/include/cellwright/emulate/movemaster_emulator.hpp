// MovemasterEmulator: a Mitsubishi Movemaster EX (RV-M1 class) controller on a pseudo-terminal, driving an
// EmulatedArm. It speaks the protocol of docs/real-robots.md ("The serial line", "Movemaster EX") byte for byte, so
// that the Movemaster driver, written apart from it from the same page, can be checked against it; and it does what it
// is told to do wrong ("What the emulators can be told to do wrong").
//
// WHAT IT ACCEPTS. One command a line; a line ends at CR LF, LF or CR. Mnemonics in either case; spaces around and
// between fields; numbers with or without a sign, a leading zero, a point and decimals. Lines holding only spaces are
// skipped (not counted, not answered). Lines longer than 256 bytes are format errors. XON/XOFF bytes are dropped.
//   NT                 move to arm.home() (joint-interpolated, at the current speed)
//   MP x,y,z,p,r       move joint-interpolated to a pose (mm, degrees; the 5-axis rule of the doc): the tool frame
//                      is built from the pose, the arm's inverse kinematics is solved seeded from where it stands
//   PD n,x,y,z,p,r     define position n (1–629)
//   MS n,k[,O|C]       move in a straight line to position n (k, 0–99 intermediate points, is checked and otherwise
//                      ignored: the arm moves straight); the letter sets the gripper first, O open, C closed (a
//                      letter left out leaves it as it is); an undefined position is error 2
//   GO, GC             open, close the gripper
//   GP s,r,t           grip force: kept (0–15, 0–15, 0–99); the emulated hand closes fully whatever it is
//   SP n[,H|L]         speed level 0–9: every later motion runs at (n + 1)/10 of the arm's top joint speeds. The
//                      level at power-on is options.speed_level. The acceleration letter is kept and has no effect.
//   TL l               tool length, mm (0–300): the tool point is (l − nominal_tool_length_mm) mm along the tool's z
//                      axis from the chain's tip, for MP, MS and WH. At power-on l is the nominal length.
//   WH                 answers x,y,z,p,r of the tool point now: each number signed, one decimal (+250.0,-0.5,...)
//   ER                 answers the error register: 0 none, 1 hardware error, 2 position or format error
//   RS                 clears the error register
// and the program commands (docs/real-robots.md, "Robot programs"; assumed syntax):
//   n COMMAND          (n 1–2048) stores program line n, not executed; a line that does not parse is error 2
//   MO n[,O|C]         joint-interpolated move to position n (the letter as MS's)
//   OB ±n              output bit n (1–16) on (+) or off (−)
//   TB ±n,L / GT L     in a program: jump to line L if input bit n is on (+) / off (−); jump to line L
//   ED                 in a program: its end
//   RN [a]             runs the stored program from its first line (or line a), like a motion: the next line is
//                      read when it has ended; a failing line sets the register and ends the run
//   NW                 deletes the stored program
// Answers (WH, ER only) end with options.reply_line_end (CR LF). An unknown command, a wrong number of fields, a
// field that is not a number or letter of its kind, or a value out of its range is a format error: error 2, nothing
// done. An unreachable pose (no azimuth, outside the joint limits, out of reach) is error 2, nothing moves. An arm
// that fails (the twin's collision) is error 1; after error 1 the controller is halted (assumed): it executes
// nothing but ER, RS and WH until RS. After error 2 only the failing command is skipped. Error 1 is not overwritten
// by a later error 2.
//
// ONE COMMAND AT A TIME. The next line is taken only when the previous command has finished, so the ER a host sends
// after a motion is answered at the motion's end.
//
// MISBEHAVIOUR. One decision of the MisbehaviourPlan (seeded with options.seed) per counted line:
//   error / unreachable  the register becomes 1 / 2 and the command is not executed (ER and WH still answer: ER with
//                        the new value)
//   garbage              the command is executed; its answer, or if it has none the next answer, is replaced by
//                        bytes that are not the protocol (kGarbage, ended by the line end)
//   silent               the line is thrown away: not executed, not answered
//   drop                 the line is thrown away and the pseudo-terminal hung up; the path is gone for
//                        reconnect_delay, then a fresh pseudo-terminal is published there. The controller's state
//                        (arm, register, positions, speed, tool) persists; bytes sent after the dropped line are lost.
//   late                 the command is executed, then its answer (if any) and the reading of the next line wait the
//                        misbehaviour's delay
//   unknown              as error, with the register 9 (a code the manual does not list); like 2, it does not halt
//                        the controller
#pragma once

#include <array>
#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/emulate/emulated_arm.hpp"
#include "cellwright/emulate/line_port.hpp"
#include "cellwright/emulate/misbehaviour.hpp"

namespace cellwright::emulate {

namespace movemaster {
class Executor;
class Program;
}  // namespace movemaster

struct MovemasterEmulatorOptions {
  std::uint64_t seed = 1;
  std::vector<Misbehaviour> misbehaviours;
  // The TL length (mm) at which the tool point is the arm chain's tip (its `tcp` link).
  double nominal_tool_length_mm = 0;
  // The controller's conventions (docs/real-robots.md, "Commissioning"; `twin emulate movemaster --world-offset ...`):
  // its world frame in the arm's base frame, its tool point (at the nominal TL) in the arm's TCP frame, and how it
  // reads p and r (pitch_down -90 or 90; roll_sense +1 right-handed about the approach axis, or -1). Defaults: the
  // page's.
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  double pitch_down_deg = -90;
  int roll_sense = 1;
  // How long the path stays gone after a `drop`.
  std::chrono::nanoseconds reconnect_delay = std::chrono::milliseconds(200);
  // The SP level at power-on (0–9). (assumed: the doc does not say.)
  int speed_level = 4;
  // What ends WH's and ER's answers: "\r\n" or "\n" (the doc allows both).
  std::string reply_line_end = "\r\n";
  // The pseudo-terminal paced as a serial line at this rate (line_pace.hpp; the Movemaster's 7E2 is 11 bits a
  // character); baud 0, the default: at once.
  LineRate pace{0, 11};
  // Called on the serving thread with one line of text per event (a line received, an answer, why the register was
  // set, a misbehaviour, a new pseudo-terminal), e.g. for `twin emulate --verbose`. May be empty.
  std::function<void(std::string_view)> log;
  // Called on the serving thread with each stored program line's number just before `RN` runs it (docs/real-robots.md,
  // "Robot programs"). May be empty.
  std::function<void(int)> on_program_line;
};

class MovemasterEmulator {
 public:
  // What replaces an answer under `garbage`: not a reply of the protocol (bytes outside printable ASCII).
  static constexpr std::string_view kGarbage = "\x02#?\x7f~garbage\x1b";

  struct Stats {
    std::uint64_t lines = 0;     // lines counted (the misbehaviour plan's numbering), empty lines not included
    std::uint64_t executed = 0;  // commands parsed and executed (whatever the outcome; not those a misbehaviour
                                 // took, nor those ignored while halted)
    std::uint64_t format_errors = 0;
    std::array<std::uint64_t, 3> er_answers{};     // ER answered 0, 1, 2 (garbled answers included)
    std::array<std::uint64_t, 7> misbehaviours{};  // done, by MisbehaviourKind
    std::uint64_t publications = 0;                // pseudo-terminals published (1 + drops served so far)
  };

  // Keeps `arm` (which must outlive the emulator). Throws InputError if options.speed_level is not 0–9 or
  // reply_line_end is not CR LF or LF. Nothing is published yet.
  MovemasterEmulator(EmulatedArm& arm, MovemasterEmulatorOptions options);
  ~MovemasterEmulator();
  MovemasterEmulator(const MovemasterEmulator&) = delete;
  MovemasterEmulator& operator=(const MovemasterEmulator&) = delete;

  // Publishes a pseudo-terminal at `link` (a symbolic link; one already there is replaced) and serves it until
  // stop(); after a `drop`, publishes a fresh one at the same path. Returns after stop(), with the path removed.
  // Throws InputError when the pseudo-terminal cannot be published (the link's directory is missing, a file that is
  // not a link is in the way). Call it once, on the thread that is to serve.
  void serve(const std::filesystem::path& link);
  // Makes serve() return soon: ends its wait for a line, a late answer or a reconnect at once, and interrupts the arm
  // (the motion in progress ends; the arm takes no further commands). Final: the emulator cannot serve again. Any
  // thread, any time (before serve() too: serve() then returns at once).
  void stop();

  // Waits until at least `count` pseudo-terminals have been published (the first by serve(), then one after each
  // drop), at most `timeout`; true if so. The path is ready for a host when this returns true. Any thread.
  bool wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const;
  // The counts so far. Any thread.
  Stats stats() const;

 private:
  // Counts one line and serves it; false when serving must end (stop()).
  bool serve_line(const ReceivedLine& line, const std::filesystem::path& link);
  // Stores a numbered program line under misbehaviour `m` (if any); false on stop().
  bool store_line(std::string_view text, const std::optional<Misbehaviour>& m);
  // Writes an answer line (or the garbage in its place); false on stop().
  bool answer(std::string text, bool garble);
  void log(std::string_view text) const;
  template <typename F>
  void tally(F&& f) {
    std::lock_guard lock(stats_mutex_);
    f(stats_);
  }

  EmulatedArm& arm_;
  const MovemasterEmulatorOptions options_;
  MisbehaviourPlan plan_;
  std::unique_ptr<movemaster::Executor> executor_;
  std::unique_ptr<movemaster::Program> program_;  // the stored program (numbered lines, RN, NW)
  LinePort port_;
  bool garble_next_answer_ = false;  // a garbage line had no answer of its own

  mutable std::mutex stats_mutex_;
  Stats stats_;
};

}  // namespace cellwright::emulate
