// Val2Driver: a Unimation PUMA arm under VAL II, driven through its monitor over RS-232 (docs/real-robots.md, "VAL II";
// the serial line, pacing, timing and the communication thread are SerialDriver's, serial_driver.hpp).
//
// THE MONITOR. Every call becomes one monitor line ended by Val2Options::line_end (CR). The monitor may echo the line
// (Val2Options::echo: by default an echoed copy, the first non-blank line, is skipped); its answer is zero or more
// lines, each ended by CR LF, CR alone or LF alone, then the prompt (Val2Options::prompt, `.`) at the start of a line
// with nothing after it but spaces or tabs (a prompt `. `). The prompt's return is the line's completion (assumed by
// the page: the monitor takes the next line only when a DO instruction has finished). Blank lines are skipped, and
// BEL bytes (0x07, a terminal's bell, rung before an error line) are dropped wherever they come.
//
// WHAT EACH CALL SENDS (numbers: val2_protocol.hpp's format_number, at most three decimals, a point whatever the
// locale; locations: trans_text, with Val2Options::orientation):
//   connect()            an empty line; the prompt must come back (see RESYNC)
//   home()               DO READY                                      deadline: home_timeout
//   MoveJoints           [SPEED n] DO MOVE #PPOINT(j1,...,j6)          joint angles in degrees
//   MovePose joint       [SPEED n] DO MOVE TRANS(x,y,z,o,a,t)         mm, degrees
//   MovePose linear      [SPEED n] DO MOVES TRANS(x,y,z,o,a,t)
//   Grip open / close    DO OPENI / DO CLOSEI
//   SetOutput n on/off   DO SIGNAL n / DO SIGNAL -n                    n in 1..32
//   WaitInput n on/off   DO WAIT SIG(1000+n) / DO WAIT SIG(-(1000+n))  e.g. DO WAIT SIG(-1005)
//   request_position()   WHERE                                         answer: val2_protocol.hpp's WhereParser in
//                                                                      Val2Options::where_layout; a reading without
//                                                                      the joint row has no joints
//   reset() (after it)   an empty line; the prompt must come back (see RESYNC)
// `SPEED n` (n = round(speed × 100), within 1..100) goes out before a motion only when n differs from the last one
// the monitor took since the driver connected or was reset; it is a line of its own, answered by the prompt. WHERE's
// hand opening, when printed, is read and dropped (the interface reads no gripper width).
//
// CAPABILITIES: 6 joints, joint_control, cartesian_control, linear_motion, full_orientation, prefers_pose, gripper
// (open/close only: no width, no force), 32 digital outputs and 32 inputs, reads_joints and reads_pose,
// queue_depth 2, reads_while_moving false (WHERE waits its turn behind the motions), max_joint_speed and
// max_tool_speed from Val2Options.
//
// DEADLINES (nothing waits without one):
//   - a line that starts no motion (SPEED, DO OPENI/CLOSEI, DO SIGNAL, WHERE, the empty line): serial.reply_timeout;
//   - a motion: its expected duration at the commanded speed plus motion_margin. The expected duration is the
//     largest joint travel over that joint's speed (MoveJoints), or the tool's distance over max_tool_speed and its
//     turn over the slowest wrist joint's speed, whichever is longer (MovePose linear), from where the previous
//     motion ended or the last WHERE said; when that start is not known (after home(), a pose move before a joint
//     move or the other way round, an error), and for every joint-interpolated MovePose (the driver has no inverse
//     kinematics), the slowest joint's whole travel (joint_travel over max_joint_speed) is the bound;
//   - DO READY: home_timeout (the READY location's distance is the controller's, unknown here);
//   - DO WAIT: the WaitInput's timeout, or input_wait_limit when it is zero ("as long as it takes" within a bound:
//     nothing may block for ever; disconnect() interrupts the wait at once, and a hang-up ends it too).
//
// ERRORS (a command's outcome; robot_driver.hpp says which put the driver in fault):
//   - a line starting with `*` before the prompt: classify_error() (val2_protocol.hpp) — unreachable (the command
//     fails, the driver goes on), protocol, hardware or unknown (fault); the message quotes the controller's line. The
//     driver still waits for the prompt that follows (serial.reply_timeout); a missing one is a protocol fault.
//   - garbage: any line that is not the echo, a blank line, an error line, the prompt or (WHERE only) the header and
//     the two lines of numbers, and any byte outside printable ASCII (tab, CR, LF and BEL aside), or an unfinished line
//     longer than 512 bytes: protocol, fault, at once; the message quotes the bytes (SerialDriver::printable) and
//     everything received for the command (Link::received_text).
//   - bytes that arrive between the prompt and the next command (the monitor spoke on its own): that command is not
//     sent and fails with protocol, or hardware or unknown if the bytes are an error line of that class.
//   - silence past the deadline: protocol, fault (chosen over timeout, which fails a command only and would let the
//     next line go to a monitor still busy with this one; over connection_lost, because a serial line gives no sign
//     of a cut cable, the link may well be up, and reset()'s empty line both checks it and resynchronises). The
//     message says what was sent and how long the driver waited.
//   - exception: DO WAIT past its deadline fails with timeout (robot_driver.hpp: WaitInput's timeout fails the command
//     only), and the monitor still owes its prompt: before the next line the driver waits for it
//     (serial.reply_timeout); if it comes the driver goes on, if not that command fails with timeout too without being
//     sent.
//   - the line hung up (end of file, EIO): connection_lost, fault; reset() then leaves the driver disconnected and
//     connect() opens the port again.
//   - a port that cannot be opened or configured: connect() throws InputError naming the port and errno's text.
// No line is sent twice: a command that failed is not repeated.
//
// RESYNC (connect and clear_error). Bytes already received are discarded, an empty line is sent, and the driver
// waits (serial.reply_timeout) for a prompt after which the line stays quiet for resync_quiet; lines before it (the
// end of what the monitor was doing when a fault struck) are skipped. A monitor that does not answer fails connect()
// (connection_lost, connect_problem() says why) or, after reset(), faults the driver again (protocol).
//
// CHOICES WHERE THE PAGE IS SILENT (all settings below): the line end (CR), the orientation convention (the page's
// tool-down Z-Y-Z; VAL's published one is `val`), the monitor's world frame and tool point (frames: the base link and
// the TCP), the prompt, the WHERE layout, the echo, the maximum speeds (the project's PUMA 560 URDF estimates),
// the deadlines above, the quiet times, the optional WHERE header and hand value, and that a prompt `.` during a WHERE
// answer still missing its numbers counts only after prompt_settle of quiet (a number line may start with `.`).
//
// THREADS: as SerialDriver. The owner thread calls the RobotDriver methods; the communication thread writes and reads
// the port and keeps the protocol's state (the monitor speed, where the last motion ended, an owed prompt).
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/controller_frames.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"
#include "cellwright/drivers/val2/val2_protocol.hpp"

namespace cellwright::drivers {

// What ends each line the driver sends.
enum class Val2LineEnd : std::uint8_t { cr, crlf, lf };

// Whether the monitor echoes the lines it is sent.
enum class Val2Echo : std::uint8_t {
  maybe,   // a copy of the line, when it is the first line of the answer, is skipped (the page's)
  always,  // the first line of the answer must be the copy: any other first line is garbage
  never,   // no copy comes: a line equal to the command is garbage
};

// The VAL II line's defaults: 9600 baud, 8 data bits, no parity, 1 stop bit, no handshake.
SerialOptions val2_serial_defaults();

struct Val2Options {
  SerialOptions serial = val2_serial_defaults();
  Val2LineEnd line_end = Val2LineEnd::cr;
  val2::Orientation orientation = val2::Orientation::tool_down;
  // The monitor's world frame and tool point (controller_frames.hpp): every TRANS sent is frames.to_controller() of
  // the MovePose, every WHERE's world values frames.from_controller(). Identity by default (the page's assumption).
  ControllerFrames frames;
  // The monitor's prompt, at the start of a line ("." for VAL II; ">" for Kawasaki AS). Not empty, printable ASCII,
  // no spaces.
  std::string prompt = ".";
  val2::WhereLayout where_layout = val2::WhereLayout::val2;
  Val2Echo echo = Val2Echo::maybe;
  // Joint speeds at SPEED 100, rad/s, and each joint's widest move (its range), rad, in joint order (six each).
  // Defaults: the project's PUMA 560 URDF (models/urdf/puma560.urdf), velocity limits and joint ranges.
  std::vector<double> max_joint_speed = {2.0, 2.0, 2.5, 4.0, 4.0, 4.0};
  std::vector<double> joint_travel = {5.585054, 4.712389, 4.712389, 4.886922, 3.490658, 9.285152};
  // The tool's speed at SPEED 100, m/s (an estimate of the order of the arm's).
  double max_tool_speed = 0.5;
  // Added to a motion's expected duration to make its deadline.
  std::chrono::nanoseconds motion_margin = std::chrono::seconds(2);
  // The deadline of DO READY.
  std::chrono::nanoseconds home_timeout = std::chrono::seconds(60);
  // The deadline of DO WAIT when the WaitInput's timeout is zero.
  std::chrono::nanoseconds input_wait_limit = std::chrono::hours(1);
  // A lone `.` while a WHERE answer still misses its numbers is the prompt only after this much quiet.
  std::chrono::nanoseconds prompt_settle = std::chrono::milliseconds(20);
  // RESYNC: the quiet after the prompt that ends it.
  std::chrono::nanoseconds resync_quiet = std::chrono::milliseconds(100);
};

class Val2Driver final : public SerialDriver {
 public:
  // Throws InputError (naming options.serial.where) when max_joint_speed or joint_travel do not hold six positive
  // finite values, or max_tool_speed is not positive, or a duration is negative. Opens nothing: connect() does.
  explicit Val2Driver(Val2Options options);
  ~Val2Driver() override;  // disconnect()s: the communication thread must end before the protocol goes

  const Val2Options& options() const { return options_; }
  // The world values (X, Y, Z, O, A, T as printed, before any conversion) of the last WHERE answered; nullopt before
  // one. For commissioning (cell/rig's bring-up check), which tries other conventions on them. Any thread.
  std::optional<val2::Location> last_location() const;

 private:
  Outcome greet(Link& link) override;
  Outcome execute(Link& link, const JobCopy& job) override;
  Outcome clear_error(Link& link) override;

  // The protocol's state: the communication thread's own (and connect()'s, before that thread starts).
  struct State {
    std::optional<int> speed_percent;           // the last SPEED the monitor took
    std::optional<std::vector<double>> joints;  // rad, where the last motion ended (if known)
    std::optional<Eigen::Isometry3d> pose;      // the same for the tool
    std::optional<std::string> owed_prompt;     // a DO WAIT given up on, whose prompt has not come
    std::optional<val2::Location> where_world;  // the last WHERE's world values, as printed
  };

  class Session;  // one job's exchanges (val2_driver.cpp)

  const Val2Options options_;
  State state_;
  mutable std::mutex location_mutex_;
  std::optional<val2::Location> last_location_;  // guarded by location_mutex_
};

}  // namespace cellwright::drivers
