// DeviceHub: the device-control participant's work (issue 26; paper Fig. 2's "interact with and control ancillary
// equipment"): it owns the cell's I/O units (DigitalIo: the twin's I/O image, a Modbus TCP unit), executes the device
// primitives task control sends it (a machine's start and done, a belt's run and stop, waiting for a photo-eye), tells
// task control when each ended, logs every device's state, and senses the devices' faults.
//
// ONE TURN, step(now):
//   1. take the commands from the inbox: each goes to its device's queue (a device executes its commands one after
//      the other, in the order they came; devices work side by side); a `command_start` is logged for the robot whose
//      program ordered it, naming the unit ("twin", "modbus 127.0.0.1:1502 unit 1");
//   2. advance each device's command (DeviceControl::poll: the I/O requests it needs now); at its end a
//      `command_end` is logged and a RobotStatus goes to task control, as a robot's would;
//   3. read every device's state from its unit (a machine's busy and done inputs, a conveyor's run coil, a photo-eye's
//      input) and log a `device` event for each that changed (the first turn logs every device): the same events come
//      from the twin and from real I/O.
// FAULTS (docs/faults.md), each sensed, diagnosed by the decision tree and acted on, never a hang:
//   io_failed         a request to the unit failed (timeout, Modbus exception, connection lost, garbled reply): the
//                     tree's `retry` closes and connects the unit again and does the command again (at most
//                     RecoveryOptions::max_attempts times for one command; a machine's start begun again is not
//                     written twice when busy or done shows it was taken); a failed state read in step 3 is the same
//                     symptom for the cell ("" robot). A tree that answers go_on or wait_clear has the command (or
//                     the read) done again, counted the same way: when the attempts run out the cell stops;
//   device_timeout    an awaited input did not come within the device's limit (a machine never done, a photo-eye never
//                     on): the tree stops the cell;
//   device_contradiction  a photo-eye on a unit that is not the twin says a part is there and the environment model
//                     has none within 6 cm of the eye for RecoveryOptions::contradiction_time: stop the cell.
// A stop answers the command's robot with RobotStatus::stop_cell (the run ends "stopped"); with recovery disabled the
// first fault fails the run. A fault of the state read with no command of that device pending stops the cell through
// the status of the first robot of the program (task control ends the run on it).
//
// Threads: used by its participant only (lock-step: in its turn; real time: its own thread). The units' DigitalIo
// objects are called from there alone (the DigitalIo rule). The queues and the log are shared and thread-safe.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/runtime/device_control.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/runtime/messages.hpp"
#include "cellwright/runtime/recovery.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

// One I/O unit of the cell and the devices wired to it (cell names, the addresses of the cell description).
struct IoUnit {
  drivers::DigitalIo* io = nullptr;  // not owned; it must outlive the run
  // Not the twin (a real unit, or an emulator of one): its photo-eyes are checked against the environment model.
  bool real = false;
  std::vector<DeviceWiring> devices;
};

class DeviceHub {
 public:
  // `units`: every device the program uses must be wired on exactly one (InternalError otherwise; the Runtime
  // checks the user's side first). `devices`: program device label -> cell device name. The queues, log and model
  // are shared with the other participants and must outlive the hub.
  DeviceHub(std::vector<IoUnit> units, std::map<std::string, std::string> devices,
            const task::CompiledProgram& program, MessageQueue<MotionCommand>& inbox,
            MessageQueue<RobotStatus>& statuses, EventLog& log, const SharedEnvironment& env,
            RecoveryOptions recovery);

  // Connects every unit; InputError naming the unit and the reason when one cannot be reached (no thread runs yet).
  void connect();
  // The run starts at `now`: stops every conveyor of the program (its net starts them stopped, as a PLC's outputs are
  // at power-up), then reads and logs every device's state (step 3 alone), so that the log has each device's state
  // from the start. Called once, after connect(), before the first step(), by the thread that will own it.
  void start(SimDuration now);
  // One turn (see the top). Non-blocking beyond the units' own request timeouts. A unit whose request failed is not
  // asked again in the same turn (its other devices wait for the next one).
  void step(SimDuration now);
  // The run is over: clears every machine's start coil (a start that failed may have left it on, and a machine's
  // next start must be a rising edge); `cell_stopped` (the run did not complete): stops every conveyor too; then
  // closes every unit. Called by the Runtime once its threads have ended.
  void close(bool cell_stopped);

 private:
  struct Device {
    DeviceWiring wiring;
    std::size_t unit = 0;
    std::unique_ptr<DeviceControl> control;
    std::deque<MotionCommand> queue;  // the head is being executed once begun
    bool begun = false;
    int attempts = 0;                 // recoveries of the head command
    std::string state;                // last logged state ("" none yet)
    std::optional<SimDuration> contradicted_since;
  };

  void take_commands(SimDuration now);
  void advance(Device& d, SimDuration now);
  void watch(Device& d, SimDuration now);
  // A device fault: logged, diagnosed, acted on. `of_command`: the device's pending command failed (its robot's
  // fault); false: the device's state read (the cell's: robot "").
  void fault(Device& d, Symptom symptom, const std::string& detail, SimDuration now, bool of_command);
  void answer(const MotionCommand& c, CommandOutcome outcome, const std::string& reason, bool stop_cell,
              SimDuration now);
  std::string machine_workpiece(const Device& d) const;
  bool model_has_part_near(const Eigen::Vector3d& p) const;

  std::vector<IoUnit> units_;
  std::vector<Device> devices_;
  std::map<std::string, std::size_t> by_label_;  // program device label -> index into devices_
  const task::CompiledProgram& program_;
  MessageQueue<MotionCommand>& inbox_;
  MessageQueue<RobotStatus>& statuses_;
  EventLog& log_;
  const SharedEnvironment& env_;
  RecoveryOptions recovery_;
  bool stopped_ = false;  // the cell was stopped by a device fault: no further commands are executed
  std::vector<bool> unit_down_;  // per unit: a request failed this turn
};

}  // namespace cellwright::runtime
