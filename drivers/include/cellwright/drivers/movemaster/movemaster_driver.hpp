// MovemasterDriver: the Mitsubishi Movemaster EX (RV-M1 class) over RS-232, on SerialDriver (serial_driver.hpp), as
// docs/real-robots.md ("The serial line", "Movemaster EX") specifies. The language and the pose convention, as text,
// are in movemaster_protocol.hpp; this is the exchange of lines for each call.
//
// WHAT EACH CALL SENDS (every line ended by MovemasterOptions::line_end; the pacing of serial_driver.hpp between
// any two lines; "ER" below means: send `ER`, wait for its one-digit answer, see ANSWERS)
//   connect()           `ER` (the controller must answer 0; its answer is the last line received before
//                       resync_quiet of quiet: a late answer to a question asked before the link was given up comes
//                       first and is dropped); then, when tool_length_mm is set, `TL l` and `ER`.
//   home()              `NT`, `ER`. The driver forgets where the arm is (the nest is not a pose it knows).
//   MovePose joint      `SP n` when the speed level differs from the one last sent (always after connect or an
//                       error), then `MP x,y,z,p,r`, then ER.
//   MovePose linear     `SP n` as above; `WH` first when the driver does not know where the arm is (after connect,
//                       homing or an error), to count the intermediate points; then `PD slot,x,y,z,p,r`,
//                       `MS slot,k,O|C` (k: one point per 10 mm of travel, at most 99; the letter: the last grip
//                       command's, open before any), then ER.
//   Grip                `GP s,s,t` when a force is given (s = round(force / gripper_max_force × 15), t =
//                       grip_start_time), then `GO` or `GC`, then ER.
//   request_position()  `WH`; its answer `x,y,z,p,r` becomes PositionReading::tool_pose (base frame, metres, the
//                       5-axis convention); no joints.
//   reset()             (on the communication thread, before the next job) `RS`, then `ER` must answer 0.
//   stop()              nothing: the controller cannot be interrupted over the line (serial_driver.hpp, STOP).
// A MovePose whose pose breaks the 5-axis rule (its approach axis more than yaw_tolerance_deg out of the vertical
// plane through the tool point, or the tool point on the base's z axis) is accepted and then fails with unreachable
// without anything being sent. No command is sent again after it failed or went unanswered: nothing is retried.
//
// ANSWERS AND WHAT THEY COME TO
//   `ER` 0              the command is done (completion: er — the answer comes when the motion has ended).
//   `ER` 1              `RS` is sent; the command fails with hardware and the driver enters fault.
//   `ER` 2              `RS` is sent; the command fails with unreachable; the driver goes on.
//   `ER` another number (3..99: a code outside the manual's 0, 1, 2) `RS` is sent; the command fails with unknown and
//                       the driver enters fault, as for 1: the driver cannot tell what the controller's state is.
//   anything else       (a word, bytes outside printable ASCII, the wrong count of numbers in a `WH` answer):
//                       protocol, fault, the message quoting the bytes received for the job.
// Every answer line may end with CR LF, LF alone or CR alone (serial_driver.hpp, Link::read_line), whatever
// MovemasterOptions::line_end sends.
//   silence             past the wait's deadline: connection_lost, fault. Chosen over timeout, which fails only the
//                       command and lets the next one go: after silence the driver cannot tell whether the command
//                       ran, nor match a late answer to its command. Chosen over protocol (whose reset() would send
//                       `RS` on the same line): on RS-232 a pulled cable or a controller switched off shows only as
//                       silence, so the link is treated as lost; reset() then leaves the driver disconnected, and
//                       connect() opens the port afresh (discarding any late answer) and checks the controller
//                       with `ER` before anything moves.
//   hang-up             (end of file, POLLHUP, EIO on the port) connection_lost, fault.
//   a write that cannot finish within reply_timeout (the handshake holds it): connection_lost, fault.
//   bytes nobody asked for, found when a job starts: protocol, fault (they would be taken for the next answer).
// At connect, a non-zero `ER` is answered with `RS` and connect() fails (connect_problem() says what the controller
// answered); the next connect() finds the error cleared. Every problem at connect makes connect() return
// connection_lost with connect_problem() set, as SerialDriver does; a missing port is an InputError naming it.
//
// DEADLINES. Nothing waits without one. An answer to a line that starts no motion: reply_timeout (SerialOptions).
// The `ER` after a motion: its expected duration plus reply_timeout, where the expected duration is a bound, not an
// estimate: longest_motion × 10 / (n + 1) at speed level n (the controller's joint speed at level n is (n + 1)/10 of
// its maximum; the driver knows no joint path, so it cannot estimate a joint-interpolated motion from the two poses).
// Homing: home_time; a grip: grip_time plus the grip force's starting time.
//
// COMPLETION (a setting). er (default): the `ER` answer is the completion. poll: after the motion command the driver
// sends `WH` until two answers poll_period apart agree (the first may wait for the motion, as `ER` would), then sends
// `ER` to learn whether the command succeeded (only `ER` reports errors). Answers that keep changing past the motion's
// deadline: hardware, fault (the arm did not come to rest). The wait between two `WH` watches the line, so a hang-up
// or an unasked-for byte is seen at once.
//
// CAPABILITIES (fixed)
//   joints                 MovemasterOptions::joints (5 for the RV-M1); reads_joints false.
//   joint_control false    `WH` reports no joints, and `MJ` is relative: absolute joint targets would rest on a count
//                          kept on the host that nothing checks.
//   cartesian_control, linear_motion, prefers_pose, reads_pose: true. full_orientation false (5 axes: the yaw
//                          follows the position).
//   gripper, gripper_force true (max: gripper_max_force); gripper_width false (GO/GC only).
//   digital_outputs, digital_inputs 0: the controller's I/O commands are not supported yet (SetOutput and WaitInput
//                          are refused by check_command: the robot has no channels).
//   queue_depth 2 (one job on the line, one waiting behind it); reads_while_moving false (`WH` is answered between
//                          commands only); max_tool_speed, max_joint_speed: from the options.
//
// THREADS. As SerialDriver: the owner thread calls the RobotDriver methods; greet (at connect, on the owner's thread,
// with the communication thread not running), execute and clear_error run on the communication thread, which alone
// keeps the protocol state below (speed level sent, gripper letter, where the arm is). timing() from any thread.
#pragma once

#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/controller_frames.hpp"
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"

namespace cellwright::drivers {

// The settings. Where docs/real-robots.md leaves a choice, the default is the choice made there (or here, marked
// "assumed"); a real controller may need another.
struct MovemasterOptions {
  enum class Completion : std::uint8_t { er, poll };

  // The port and line (SerialLine's defaults are the Movemaster's: 9600 baud, 7E2, RTS/CTS and XON/XOFF), the
  // cell-file location errors name, processing_time (pacing) and reply_timeout (answers to lines that start no
  // motion).
  SerialOptions serial;
  movemaster::LineEnd line_end = movemaster::LineEnd::crlf;  // how the host ends its lines
  Completion completion = Completion::er;
  std::chrono::nanoseconds poll_period = std::chrono::milliseconds(200);  // completion poll: between two `WH`
  char ms_open_letter = 'O';             // the `MS` letter for an open tool ('O' or 'C'); closed is the other
  int linear_slot = 629;                 // the position number `PD` defines for `MS` (1..629)
  std::optional<double> tool_length_mm;  // sent with `TL` at connect when set (mm, >= 0)
  double yaw_tolerance_deg = 0.5;        // how far out of the vertical plane an approach axis may be
  // The controller's world frame and tool point (controller_frames.hpp; identity: the page's), and how it reads pitch
  // and roll (movemaster_protocol.hpp's with_angle_reading; -90 and +1: the page's). A MovePose becomes
  // with_angle_reading(to_xyzpr(frames.to_controller(pose))), a `WH` answer the inverse.
  ControllerFrames frames;
  double pitch_down_deg = -90;  // -90 or 90
  int roll_sense = 1;           // +1 or -1
  movemaster::Acceleration acceleration = movemaster::Acceleration::none;  // `SP n` or `SP n,H` / `SP n,L`
  int grip_start_time = 3;                                                 // `GP`'s starting time t, in 0.1 s (0..99)
  std::size_t joints = 5;                                                  // the arm's axes, reported in capabilities()
  // Assumed values (no source gives them): set them from the arm's data.
  double max_tool_speed = 0.5;          // m/s of the tool at speed 1.0, reported in capabilities()
  std::vector<double> max_joint_speed;  // rad/s per joint at speed 1.0, reported (empty: not known)
  double gripper_max_force = 20.0;      // N, the force that maps to `GP` level 15
  std::chrono::nanoseconds longest_motion = std::chrono::seconds(5);  // the longest motion at speed level 9
  std::chrono::nanoseconds home_time = std::chrono::seconds(30);      // the longest `NT`
  std::chrono::nanoseconds grip_time = std::chrono::seconds(1);       // the longest `GO`/`GC` (plus GP's t)
  // At connect: the quiet after the `ER` answer that makes it the answer to that `ER` (0: none, the first line is).
  std::chrono::nanoseconds resync_quiet = std::chrono::milliseconds(100);
};

class MovemasterDriver final : public SerialDriver {
 public:
  // Checks the options (throws InputError naming options.serial.where and the value when one is out of range); opens
  // nothing: connect() does.
  explicit MovemasterDriver(MovemasterOptions options);
  ~MovemasterDriver() override;  // disconnect(): the communication thread must end before this driver's parts do

  const MovemasterOptions& options() const { return options_; }
  // The last `WH` answer, as the controller wrote it (before any conversion); nullopt before one. For commissioning
  // (cell/rig's bring-up check). Any thread.
  std::optional<movemaster::Xyzpr> last_wh() const;

 private:
  class Exchange;  // one job's lines on the link (movemaster_driver.cpp)

  Outcome greet(Link& link) override;
  Outcome execute(Link& link, const JobCopy& job) override;
  Outcome clear_error(Link& link) override;

  Outcome move(Exchange& ex, const MovePose& command);
  Outcome grip(Exchange& ex, const Grip& command);
  // Waits for the end of a motion (completion: er or poll) with the motion's deadline, then checks `ER`.
  Outcome finish_motion(Exchange& ex, std::chrono::nanoseconds expected);
  // The driver no longer knows the speed level sent or where the arm is (after an error or a reconnect).
  void forget();

  const MovemasterOptions options_;
  // Protocol state: the communication thread's (and greet's, before the thread starts).
  std::optional<int> speed_level_;          // the `SP` level last sent and acknowledged, if known
  bool grip_closed_ = false;                // the last grip command that succeeded (open before any)
  std::optional<movemaster::Xyzpr> where_;  // where the arm is, if known: the last target reached or `WH`
  mutable std::mutex wh_mutex_;
  std::optional<movemaster::Xyzpr> last_wh_;  // guarded by wh_mutex_
};

}  // namespace cellwright::drivers
