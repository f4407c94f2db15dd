#include "cellwright/runtime/device_control.hpp"

#include <fmt/format.h>

#include <chrono>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

const char* to_string(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::kMachine:
      return "machine";
    case DeviceKind::kConveyor:
      return "conveyor";
    case DeviceKind::kSensor:
      return "sensor";
  }
  return "?";
}

DeviceControl::DeviceControl(drivers::DigitalIo& io, std::vector<DeviceWiring> devices)
    : io_(io), devices_(std::move(devices)) {}

void DeviceControl::begin(const task::Primitive& p, SimDuration now, bool again) {
  CW_CHECK(!current_, "device primitive '{}' begun while '{}' is pending", task::to_string(p),
           task::to_string(*current_));
  CW_CHECK(p.kind == task::PrimitiveKind::kDevice, "'{}' is not a device primitive", task::to_string(p));
  current_ = p;
  device_ = nullptr;
  for (const DeviceWiring& d : devices_) {
    if (d.name == p.device) device_ = &d;
  }
  since_ = now;
  written_ = false;
  again_ = again;
  done_before_ = false;
}

DeviceStep DeviceControl::fault(std::string reason) {
  current_.reset();
  return {DeviceOutcome::kFault, std::move(reason)};
}

DeviceStep DeviceControl::write(int address, bool value, const char* what) {
  if (address < 0) return fault(fmt::format("device {}: its {} is not wired", device_->name, what));
  const drivers::IoResult r = io_.write_coil(static_cast<std::uint16_t>(address), value);
  if (!r.ok()) {
    return fault(fmt::format("device {}: writing {} (coil {}) on {} failed: {} {}", device_->name, what, address,
                             io_.describe(), drivers::to_string(r.status), r.message));
  }
  return {DeviceOutcome::kDone, {}};
}

bool DeviceControl::read_input(int address, const char* what, bool& on, DeviceStep& out) {
  if (address < 0) {
    out = fault(fmt::format("device {}: its {} input is not wired", device_->name, what));
    return false;
  }
  std::vector<bool> values;
  const drivers::IoResult r = io_.read_inputs(static_cast<std::uint16_t>(address), 1, values);
  if (!r.ok()) {
    out = fault(fmt::format("device {}: reading {} (input {}) on {} failed: {} {}", device_->name, what, address,
                            io_.describe(), drivers::to_string(r.status), r.message));
    return false;
  }
  on = values.at(0);
  return true;
}

bool DeviceControl::overdue(int address, const char* what, SimDuration now, DeviceStep& out) {
  if (device_->limit.count() <= 0 || now - since_ <= device_->limit) return false;
  out = fault(fmt::format("device {}: {} (input {}) not seen within {:.3f} s", device_->name, what, address,
                          std::chrono::duration<double>(device_->limit).count()));
  out.timed_out = true;
  return true;
}

bool DeviceControl::input_on(int address, const char* what, SimDuration now, DeviceStep& out) {
  bool on = false;
  if (!read_input(address, what, on, out)) return false;
  if (on) return true;
  (void)overdue(address, what, now, out);
  return false;
}

DeviceStep DeviceControl::poll(SimDuration now) {
  if (!current_) return {DeviceOutcome::kDone, {}};
  if (device_ == nullptr) {
    return fault(fmt::format("device {}: not wired to {}", current_->device, io_.describe()));
  }
  DeviceStep step;
  DeviceStep end{DeviceOutcome::kDone, {}};
  switch (current_->op) {
    case task::DeviceOp::kStart: {
      // Busy and done as the machine has them now (done only when wired); false with the fault in `step`.
      bool busy = false;
      bool done = false;
      const auto read_state = [&] {
        return read_input(device_->busy, "busy", busy, step) &&
               (device_->input < 0 || read_input(device_->input, "done", done, step));
      };
      if (!written_) {
        if (!read_state()) return step;
        if (again_ && (busy || done)) {
          // The start written before the fault started the cycle: only clear it.
          end = write(device_->coil, false, "start");
          break;
        }
        done_before_ = done;
        step = write(device_->coil, true, "start");
        if (step.outcome == DeviceOutcome::kFault) return step;
        written_ = true;
        since_ = now;
        step = {};  // pending until busy (or a new done) is seen
      }
      if (!read_state()) return step;
      if (!busy && !(done && !done_before_)) {
        (void)overdue(device_->busy, "busy", now, step);
        return step;
      }
      end = write(device_->coil, false, "start");
      break;
    }
    case task::DeviceOp::kAwaitDone:
      if (!input_on(device_->input, "done", now, step)) return step;
      break;
    case task::DeviceOp::kAwaitOn:
      if (!input_on(device_->input, "photo-eye", now, step)) return step;
      break;
    case task::DeviceOp::kRun:
    case task::DeviceOp::kAccumulate:
      end = write(device_->coil, true, "run");
      break;
    case task::DeviceOp::kStop:
      end = write(device_->coil, false, "run");
      break;
  }
  current_.reset();
  return end;
}

}  // namespace cellwright::runtime
