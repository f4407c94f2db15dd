// The serial drivers of real robots (real_drivers.hpp).
#include "cellwright/cell/real_drivers.hpp"

#include <fmt/format.h>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::cell {

namespace {

drivers::SerialLine line_of(const models::SerialSettings& s) {
  drivers::SerialLine line;
  line.port = s.port;
  line.baud = s.baud;
  line.data_bits = s.data_bits;
  line.parity = s.parity == models::Parity::kEven  ? drivers::Parity::even
                : s.parity == models::Parity::kOdd ? drivers::Parity::odd
                                                   : drivers::Parity::none;
  line.stop_bits = s.stop_bits;
  line.rts_cts = s.rts_cts;
  line.xon_xoff = s.xon_xoff;
  return line;
}

// The robot's conventions (its cell entry's `val2:` / `movemaster:`, docs/cell-description.md) as driver options.
void set_conventions(const models::Val2Conventions& c, drivers::Val2Options& o) {
  using C = models::Val2Conventions;
  o.orientation = c.orientation == C::Orientation::kZyz   ? drivers::val2::Orientation::zyz
                  : c.orientation == C::Orientation::kVal ? drivers::val2::Orientation::val
                                                          : drivers::val2::Orientation::tool_down;
  o.frames = {c.frames.world, c.frames.tool};
  o.line_end = c.line_end == models::LineEnd::kCrLf ? drivers::Val2LineEnd::crlf
               : c.line_end == models::LineEnd::kLf ? drivers::Val2LineEnd::lf
                                                    : drivers::Val2LineEnd::cr;
  o.prompt = c.prompt;
  o.where_layout = c.where == C::WhereLayout::kAsTwoBlock ? drivers::val2::WhereLayout::as_two_block
                                                          : drivers::val2::WhereLayout::val2;
  o.echo = c.echo == C::Echo::kAlways  ? drivers::Val2Echo::always
           : c.echo == C::Echo::kNever ? drivers::Val2Echo::never
                                       : drivers::Val2Echo::maybe;
}

void set_conventions(const models::MovemasterConventions& c, drivers::MovemasterOptions& o) {
  o.line_end = c.line_end == models::LineEnd::kCr   ? drivers::movemaster::LineEnd::cr
               : c.line_end == models::LineEnd::kLf ? drivers::movemaster::LineEnd::lf
                                                    : drivers::movemaster::LineEnd::crlf;
  o.completion = c.completion == models::MovemasterConventions::Completion::kPoll
                     ? drivers::MovemasterOptions::Completion::poll
                     : drivers::MovemasterOptions::Completion::er;
  o.ms_open_letter = c.ms_open_letter;
  o.frames = {c.frames.world, c.frames.tool};
  o.pitch_down_deg = c.pitch_down_deg;
  o.roll_sense = c.roll_sense;
}

}  // namespace

std::unique_ptr<drivers::SerialDriver> make_real_driver(const DriverChoice& choice, const models::RobotSpec& robot) {
  CW_CHECK(choice.real() && choice.serial.has_value(), "robot {}: no real driver to make", choice.robot);
  const models::KinematicChain chain = models::robot_chain(robot);
  std::vector<double> speeds, travel;
  for (const models::JointLimit& l : chain.limits()) {
    speeds.push_back(l.velocity > 0 ? l.velocity : 1.0);
    travel.push_back(l.upper - l.lower);
  }
  if (choice.kind == models::DriverKind::kMovemaster) {
    drivers::MovemasterOptions o;
    o.serial.line = line_of(*choice.serial);
    o.serial.where = choice.where;
    o.joints = chain.dof();
    o.max_joint_speed = speeds;
    o.gripper_max_force = robot.grip_force;
    set_conventions(robot.movemaster, o);
    return std::make_unique<drivers::MovemasterDriver>(std::move(o));
  }
  drivers::Val2Options o;
  o.serial.line = line_of(*choice.serial);
  o.serial.where = choice.where;
  set_conventions(robot.val2, o);
  if (chain.dof() == 6) {
    o.max_joint_speed = speeds;
    o.joint_travel = travel;
  }
  return std::make_unique<drivers::Val2Driver>(std::move(o));
}

void connect_real_driver(drivers::SerialDriver& driver, const DriverChoice& choice) {
  const drivers::ErrorCode e = driver.connect();  // throws InputError naming the port when it cannot be opened
  if (e != drivers::ErrorCode::none) {
    throw InputError(choice.where, fmt::format("robot '{}' on the {} driver: {}", choice.robot, to_string(choice.kind),
                                               driver.connect_problem()));
  }
}

}  // namespace cellwright::cell
