// DeviceControl: the device-control work for one I/O unit (issue 26): it executes the task program's device
// primitives (compiled.hpp, PrimitiveKind::kDevice: a machine's start and done, a conveyor's run and stop, a
// photo-eye's input) on a DigitalIo (drivers/digital_io.hpp), and says when each is done or why it failed.
//
// It is a step machine, not a thread: begin() takes a device primitive, poll() makes the I/O requests it needs now and
// returns kPending until the primitive is done. Whoever owns the unit calls both (the DigitalIo rules: one owner
// thread); in lock-step the caller polls once per turn, in real time at a set period, so nothing here sleeps or
// blocks beyond one request. The runtime's device-control participant (device_hub.hpp) owns one per device.
//
// What each operation does on the unit (the device's addresses come from the cell description's `io` keys):
//   start       machine: read busy and done; write start = 1; poll until busy is on, or done comes on (a cycle
//               shorter than a poll); write start = 0; done. Begun again after a failure (`again`): when busy or done
//               is already on, the earlier write started the cycle, so start is only cleared (a machine is never
//               started twice for one command).
//   await done  machine: poll done until on; done
//   run         conveyor: write run = 1; done (accumulate: the same, the belt stops itself at its stop eye)
//   stop        conveyor: write run = 0; done
//   await on    sensor: poll its input until on; done
// Faults, never a hang: a request that fails (timeout, exception, disconnected, protocol) ends the primitive with
// kFault and the unit's message; an awaited input that is not seen within the device's `limit` (for a machine's busy
// and done: set from its process_time by the caller) ends it with kFault naming the device, the input and the limit.
// The decision tree's action (device_hub.hpp, docs/faults.md): a failed request is tried again after connecting the
// unit again (io_failed), an input that never comes stops the cell (device_timeout).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

enum class DeviceKind { kMachine, kConveyor, kSensor };

// "machine", "conveyor", "sensor".
const char* to_string(DeviceKind kind);

// One device's wiring on the unit. Addresses -1: not wired (a primitive that needs it faults).
struct DeviceWiring {
  std::string name;      // the cell's device name
  int coil = -1;         // machine: start; conveyor: run
  int input = -1;        // machine: done; sensor: its photo-eye
  int busy = -1;         // machine: busy
  SimDuration limit{0};  // how long an awaited input may take; 0: no limit
  DeviceKind kind = DeviceKind::kMachine;
  // Where a machine's part rests (its fixture's top) or where a photo-eye looks (world, m): what the environment
  // model is asked about the device (the part in the machine; a part at the eye).
  Eigen::Vector3d at = Eigen::Vector3d::Zero();
};

enum class DeviceOutcome { kPending, kDone, kFault };

struct DeviceStep {
  DeviceOutcome outcome = DeviceOutcome::kPending;
  std::string reason;      // kFault: what failed, naming the device
  bool timed_out = false;  // kFault: an awaited input did not come within the limit (else a request failed)
};

class DeviceControl {
 public:
  // `io` must outlive this object; its owner thread is the only caller of begin() and poll().
  DeviceControl(drivers::DigitalIo& io, std::vector<DeviceWiring> devices);

  // Starts device primitive `p` at `now`. InternalError if another primitive is still pending or `p` is not a
  // device primitive; a device this unit does not wire is a fault reported by the next poll(). `again`: the same
  // primitive is begun again after a fault (the unit may have done part of it: see start at the top).
  void begin(const task::Primitive& p, SimDuration now, bool again = false);
  // Advances the pending primitive (see the top); kDone or kFault end it. Without a pending primitive: kDone.
  DeviceStep poll(SimDuration now);

 private:
  DeviceStep fault(std::string reason);
  DeviceStep write(int address, bool value, const char* what);
  // Reads input `address` into `on`; false with a fault in `out` when it is not wired or the request failed.
  bool read_input(int address, const char* what, bool& on, DeviceStep& out);
  // true when input `address` is on; a fault (request failed, or the limit passed) in `out`.
  bool input_on(int address, const char* what, SimDuration now, DeviceStep& out);
  // Whether the awaited input is overdue (the device's limit passed since since_): the fault in `out` if so.
  bool overdue(int address, const char* what, SimDuration now, DeviceStep& out);

  drivers::DigitalIo& io_;
  std::vector<DeviceWiring> devices_;
  std::optional<task::Primitive> current_;
  const DeviceWiring* device_ = nullptr;
  SimDuration since_{0};
  bool written_ = false;      // start: the start coil is set, waiting for busy
  bool again_ = false;        // begun again after a fault
  bool done_before_ = false;  // start: the done input was on before the start was written
};

}  // namespace cellwright::runtime
