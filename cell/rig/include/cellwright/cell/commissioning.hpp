// Commissioning a real controller's conventions (docs/real-robots.md, "Commissioning"): the bring-up cross-check that
// the dry run and every real connect make after homing, and the settings `twin commission` proposes from what the
// controller read back.
//
// THE CROSS-CHECK. After homing, the position is read back once, and:
//  - the read-back joints (VAL II) are compared with the cell's home joints (the controller's READY / nest must be the
//    cell's home): each within kJointTolerance;
//  - the read-back tool pose, converted with the robot's conventions (its `val2:` / `movemaster:` settings), is
//    compared with the project's forward kinematics of the read-back joints, or of the cell's home when the
//    controller reads no joints (the Movemaster's WH): within kPositionTolerance and kRotationTolerance.
// The tolerances are wide against a reading's rounding (0.01 mm and 0.001° in WHERE, 0.1 mm and 0.1° in WH) and an
// old arm's calibration, and narrow against what a wrong convention gives (a world frame at the shoulder is 672 mm
// away; a wrong O, A, T reading is tens of degrees). A disagreement refuses the robot, naming the offset (mm) and the
// rotation (degrees, about an axis) found and the settings that would explain it (suggest_settings below).
//
// THE SUGGESTION. From the read-backs' raw numbers (as the controller printed them), each orientation reading the
// driver knows (VAL II: tool_down, zyz, val; Movemaster: pitch_down ±90 × roll ±1) is tried: the controller's tool
// frames are fitted onto the kinematics' (each frame as four points, its origin and 100 mm along each axis, fitted by
// Eigen::umeyama without scaling), which gives the world frame; the tool transform is kept as set (one home reading
// cannot tell a tool offset from a world offset). The reading whose fit leaves the least residual wins; between
// readings that fit alike (one sample fits every reading exactly), the one whose world frame turns least (a world
// frame is nearly always upright). Printed as the robot entry's YAML keys.
//
// Threads: the caller's (the main thread, before any runtime thread starts).
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "cellwright/cell/scenario.hpp"
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/drivers/serial/serial_driver.hpp"
#include "cellwright/drivers/val2/val2_protocol.hpp"
#include "cellwright/models/cell.hpp"

namespace cellwright::cell {

inline constexpr double kJointTolerance = 1.0;     // degrees, each joint against the cell's home
inline constexpr double kPositionTolerance = 5.0;  // mm, the read-back tool point against the kinematics'
inline constexpr double kRotationTolerance = 2.0;  // degrees, the read-back tool axes against the kinematics'

// One read-back as the check needs it.
struct ReadBack {
  drivers::PositionReading reading;  // as the driver converted it (its conventions applied)
  // The controller's own numbers (Val2Driver::last_location, MovemasterDriver::last_wh), when known.
  std::variant<std::monostate, drivers::val2::Location, drivers::movemaster::Xyzpr> raw;
};

// Takes what `driver` last read (its last_position() and raw numbers).
ReadBack read_back_of(const drivers::SerialDriver& driver);

struct Suggestion {
  std::string yaml;         // "val2: {orientation: val, world_offset: [0, 0, 671.83]}" ("" when nothing to say)
  double residual_mm = 0;   // how far the fitted frames still are from the kinematics' (the worst point)
  std::string limitations;  // what the readings could not tell
};

// The settings that explain `samples` (all of robot `robot`'s), with `kind` the controller's (see above).
Suggestion suggest_settings(const models::RobotSpec& robot, models::DriverKind kind,
                            const std::vector<ReadBack>& samples);

struct CrossCheck {
  std::vector<std::string> problems;  // each a sentence with the values; empty when all agrees
  std::vector<std::string> notes;     // what could not be checked
  bool ok() const { return problems.empty(); }
};

// The cross-check of one home read-back of robot `robot` on a `kind` controller.
CrossCheck cross_check(const models::RobotSpec& robot, models::DriverKind kind, const ReadBack& home);

// Waits for command `id` of `driver` to end, at most `timeout`; its status then ("no answer in time" as the message
// when the time ran out).
drivers::CommandStatus wait_for_command(drivers::RobotDriver& driver, drivers::CommandId id,
                                        std::chrono::nanoseconds timeout);

// Homes `driver` and reads its position. The read-back, or nullopt with *problem saying which step failed and why.
std::optional<ReadBack> home_and_read(drivers::SerialDriver& driver, std::chrono::nanoseconds home_timeout,
                                      std::chrono::nanoseconds read_timeout, std::string* problem);

// Every real connect's bring-up (RealRun, the twin's mirrored robots): homes the connected `driver`, reads it back and
// cross-checks it. Throws InputError naming `choice.where` and every problem (the offset, the rotation, the settings
// that would explain them). The driver is left homed.
void bring_up_checked(drivers::SerialDriver& driver, const DriverChoice& choice, const models::RobotSpec& robot);

// `twin commission SCENARIO --driver ROBOT=KIND:PORT` (docs/real-robots.md, "Commissioning"): for every robot of the
// program on a real driver, connect, home, read the position back once (nothing else moves: see the page for why),
// cross-check it and propose the settings that explain it.
struct CommissionedRobot {
  std::string label, robot, driver;  // program label, cell robot, "val2 /dev/ttyUSB1"
  SourceLocation entry;              // the robot's entry in the cell file
  std::string problem;               // a step that failed (home, read)
  std::optional<ReadBack> home;      // the read-back after homing
  CrossCheck check;
  Suggestion suggestion;
};
struct Commissioning {
  std::vector<CommissionedRobot> robots;
  // Every real robot was read back and a setting fits it within the tolerances.
  bool ok() const;
};

// Throws InputError when a driver cannot be made or connected (as the dry run).
Commissioning commission(const Scenario& scenario);
// The report as text: per robot, what was read, the cross-check, and the YAML to paste.
std::string format_commissioning(const Commissioning& c);

}  // namespace cellwright::cell
