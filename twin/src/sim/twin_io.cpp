#include "cellwright/twin/sim/twin_io.hpp"

#include <fmt/format.h>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

namespace {
constexpr int kIllegalDataAddress = 2;
constexpr int kIllegalDataValue = 3;
constexpr std::uint16_t kMaxBits = 2000;  // Modbus: at most 2000 coils or inputs in one read
}  // namespace

TwinIo::TwinIo(World& world) : world_(world) {
  const models::CellDescription& cell = world.scene().cell();
  const auto wire = [](std::map<std::uint16_t, Wire>& wires, const models::IoAddress& a, Point point,
                       std::size_t device, std::string meaning) {
    if (!a.wired()) return;
    // The cell description refuses two devices on one address (models/cell.hpp); a clash here is our bug.
    const bool fresh =
        wires.emplace(static_cast<std::uint16_t>(a.address), Wire{point, device, std::move(meaning)}).second;
    CW_CHECK(fresh, "address {} wired twice", a.address);
  };
  for (std::size_t i = 0; i < cell.conveyors.size(); ++i) {
    const models::ConveyorSpec& c = cell.conveyors[i];
    wire(coils_, c.run_io, Point::belt_run, i, fmt::format("the run of conveyor '{}'", c.name));
    wire(inputs_, c.stop_eye_io, Point::stop_eye, i, fmt::format("sensor '{}'", c.stop_eye_name));
    wire(inputs_, c.drop_eye_io, Point::drop_eye, i, fmt::format("sensor '{}'", c.drop_eye_name));
  }
  for (std::size_t m = 0; m < cell.machines.size(); ++m) {
    const models::MachineSpec& mc = cell.machines[m];
    wire(coils_, mc.start_io, Point::machine_start, m, fmt::format("the start of machine '{}'", mc.name));
    wire(inputs_, mc.busy_io, Point::machine_busy, m, fmt::format("machine '{}' busy", mc.name));
    wire(inputs_, mc.done_io, Point::machine_done, m, fmt::format("machine '{}' done", mc.name));
  }
}

drivers::IoResult TwinIo::connect() {
  open_ = true;
  return {};
}

void TwinIo::close() { open_ = false; }

bool TwinIo::is_open() const { return open_; }

drivers::IoResult TwinIo::check(const char* what, const std::map<std::uint16_t, Wire>& wires, std::uint16_t first,
                                std::uint16_t count) const {
  CW_CHECK(count > 0, "{} of 0 addresses", what);
  if (!open_) {
    return {drivers::IoStatus::disconnected, 0, fmt::format("twin: {} at {}: not connected", what, first)};
  }
  if (count > kMaxBits) {
    return {drivers::IoStatus::exception, kIllegalDataValue,
            fmt::format("twin: {} of {} addresses from {}: at most {} at once", what, count, first, kMaxBits)};
  }
  for (std::uint32_t a = first; a < std::uint32_t{first} + count; ++a) {
    if (a > 0xFFFF || !wires.contains(static_cast<std::uint16_t>(a))) {
      return {drivers::IoStatus::exception, kIllegalDataAddress,
              fmt::format("twin: {} at {}: the cell wires nothing there", what, a)};
    }
  }
  return {};
}

drivers::IoResult TwinIo::write_coil(std::uint16_t address, bool value) {
  drivers::IoResult r = check("write coil", coils_, address, 1);
  if (!r.ok()) return r;
  const Wire& w = coils_.at(address);
  if (w.point == Point::belt_run) {
    world_.set_belt_run(w.device, value);
  } else {
    world_.set_machine_start(w.device, value);
  }
  return r;
}

drivers::IoResult TwinIo::read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  drivers::IoResult r = check("read coils", coils_, first, count);
  if (!r.ok()) return r;
  std::vector<bool> out(count);
  for (std::uint16_t i = 0; i < count; ++i) {
    const Wire& w = coils_.at(static_cast<std::uint16_t>(first + i));
    out[i] = w.point == Point::belt_run ? world_.belt_run(w.device) : world_.machine_start(w.device);
  }
  values = std::move(out);
  return r;
}

drivers::IoResult TwinIo::read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  drivers::IoResult r = check("read discrete inputs", inputs_, first, count);
  if (!r.ok()) return r;
  const DeviceStates d = world_.devices();
  std::vector<bool> out(count);
  for (std::uint16_t i = 0; i < count; ++i) {
    const Wire& w = inputs_.at(static_cast<std::uint16_t>(first + i));
    switch (w.point) {
      case Point::stop_eye:
        out[i] = d.conveyors[w.device].stop_eye;
        break;
      case Point::drop_eye:
        out[i] = d.conveyors[w.device].drop_eye;
        break;
      case Point::machine_busy:
        out[i] = d.machines[w.device].busy();
        break;
      case Point::machine_done:
        out[i] = d.machines[w.device].done();
        break;
      case Point::belt_run:
      case Point::machine_start:
        CW_CHECK(false, "a coil among the inputs");
    }
  }
  values = std::move(out);
  return r;
}

std::vector<std::string> TwinIo::wiring() const {
  std::vector<std::string> out;
  for (const auto& [a, w] : coils_) out.push_back(fmt::format("coil {}: {}", a, w.meaning));
  for (const auto& [a, w] : inputs_) out.push_back(fmt::format("discrete input {}: {}", a, w.meaning));
  return out;
}

}  // namespace cellwright::twin::sim
