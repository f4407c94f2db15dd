// The serial drivers of real robots, made from a scenario's driver choice (docs/real-robots.md): the Movemaster EX
// driver for `movemaster`, the VAL II driver for `val2`, on the choice's line settings, with the robot's conventions
// (its cell entry's `val2:` / `movemaster:`: line ends, prompt, WHERE layout, echo, orientation reading, world frame and
// tool point) and the robot's kinematics for what the driver needs of it (joint count, speeds). A real connect is then
// cross-checked by commissioning.hpp's bring_up_checked.
#pragma once

#include <memory>

#include "cellwright/drivers/serial/serial_driver.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/cell/scenario.hpp"

namespace cellwright::cell {

// The driver `choice` names for cell robot `robot`, not connected. `choice` must be real (CW_CHECK).
std::unique_ptr<drivers::SerialDriver> make_real_driver(const DriverChoice& choice, const models::RobotSpec& robot);

// Connects `driver`. Throws InputError naming the choice's place (the scenario's `drivers` entry, the cell's robot or
// the command line), the port and the problem, when the port cannot be opened or configured, or the controller does
// not answer as its protocol says.
void connect_real_driver(drivers::SerialDriver& driver, const DriverChoice& choice);

}  // namespace cellwright::cell
