// TwinIo: the twin's I/O image as a DigitalIo (drivers/digital_io.hpp), the simulated cell's I/O unit. Its coils and
// discrete inputs are the devices of the World (world.hpp, "DEVICES") at the addresses the cell description wires
// them to (docs/cell-description.md, "io"):
//
//   coil        a conveyor's `io: {run: c}`      on: the belt runs (World::set_belt_run); read back as written
//               a machine's `io: {start: c}`     a change from off to on starts a cycle (World::set_machine_start);
//                                                a start while the machine is not loaded is ignored
//   discrete    a conveyor's `sensor: {io: a}`   the stop photo-eye: a part rests against the stop bar
//   input       its `drop_sensor: {io: a}`       the drop photo-eye: a part lies across `enter`
//               a machine's `io: {busy: a}`      on while it processes a part
//               its `io: {done: a}`              on while the part it processed is still in it
//
// The coils start as the World does: every belt's run coil on (the belts run from the start, so a cell run without
// device commands is what it always was), every start coil off. An address the cell does not wire, as a coil or as
// an input, is refused with IoStatus::exception and code 2 (illegal data address), and a read of more than 2000 bits
// with code 3 (illegal data value), as a Modbus unit does; a range is refused as a whole if any address in it is not
// wired. Closed (before connect(), after close()), every call but connect() and close() returns disconnected.
//
// TIMING AND THREADS. The owner (a device-control thread, or a Modbus server serving the twin) calls it while the
// simulation thread steps the World. A coil written takes effect at the World's next physics step (between two
// steps nothing moves); inputs read give the devices as of the last step (World::devices()). Every call returns at
// once: nothing here waits for a step, so in lock-step runs the caller decides when the World steps. The World must
// outlive the TwinIo. One owner calls the DigitalIo methods (as the interface says); they are also safe to call from
// several threads.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/twin/sim/world.hpp"

namespace cellwright::twin::sim {

class TwinIo final : public drivers::DigitalIo {
 public:
  // The I/O image of `world`'s cell, closed until connect().
  explicit TwinIo(World& world);

  std::string describe() const override { return "twin"; }
  drivers::IoResult connect() override;
  void close() override;
  bool is_open() const override;
  drivers::IoResult write_coil(std::uint16_t address, bool value) override;
  drivers::IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;
  drivers::IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;

  // What the cell wires: "coil 0: the run of conveyor 'input'", ... (for messages and `--dry`), coils first.
  std::vector<std::string> wiring() const;

 private:
  enum class Point : std::uint8_t { belt_run, machine_start, stop_eye, drop_eye, machine_busy, machine_done };
  struct Wire {
    Point point;
    std::size_t device;  // index of the conveyor or machine in the cell
    std::string meaning;
  };
  drivers::IoResult check(const char* what, const std::map<std::uint16_t, Wire>& wires, std::uint16_t first,
                          std::uint16_t count) const;

  World& world_;
  std::map<std::uint16_t, Wire> coils_;
  std::map<std::uint16_t, Wire> inputs_;
  std::atomic<bool> open_{false};
};

}  // namespace cellwright::twin::sim
