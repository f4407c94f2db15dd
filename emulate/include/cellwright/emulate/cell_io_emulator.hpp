// CellIoEmulator: the paper's cell I/O (the list in drivers/digital_io.hpp) as a DigitalIo that behaves like the
// PLC of a real cell, in real time: served over Modbus TCP by `twin emulate io` (a ModbusServer in front of it), it
// stands in for the cell's conveyors, mill and photo-eyes when the controller runs with `--device NAME=modbus:...`.
//
//   coil 0, coil 1    input and output conveyor run: stored, read back as written
//   coil 2            mill cycle start: a rising edge (off -> on) while the mill is idle starts a cycle; while it is
//                     busy or done an edge is ignored, as a real mill ignores its start button then
//   input 0, input 1  the photo-eyes (a part at the input conveyor's stop, at the output conveyor's drop): as the
//                     script sets them at their times, or set_input(); off otherwise
//   input 2           mill busy: on for process_time seconds from the start
//   input 3           mill done: on when busy goes off; off again take_out_after seconds later (standing in for the
//                     robot taking the part out), or at take_out(), or never when take_out_after < 0
// The mill is idle when neither busy nor done. So the handshake a controller follows is: set coil 2; wait for busy;
// clear coil 2; wait for done; take the part out (docs/devices.md).
//
// Time is the clock's (seconds; by default the steady clock since construction), read at each call: the state is
// brought up to date when a request comes, so nothing here runs on its own and an owner may give a clock of its own
// (a test, or a twin in virtual time). Addresses beyond coils 0..2 and inputs 0..3 are refused with exception 2.
//
// Threads: the owner (the server's thread) calls the DigitalIo methods; set_input, take_out, coil and cycles may be
// called from any thread. The I/O image is a MemoryIo (its coils, inputs and open state), the mill's state is behind a
// mutex of its own.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/digital_io.hpp"
#include "cellwright/drivers/memory_io.hpp"

namespace cellwright::emulate {

// A photo-eye's change at a time: `AT:INPUT=VALUE`, e.g. "2.5:0=1" (input 0 on 2.5 s after the start).
struct InputChange {
  double at = 0;           // seconds after the emulator was made
  std::uint16_t input = 0; // 0 or 1 (the photo-eyes)
  bool value = false;
};

// Parses `AT:INPUT=VALUE` (AT seconds >= 0, INPUT 0 or 1, VALUE 0 or 1). Throws InputError naming `where`, the text and
// the problem.
InputChange parse_input_change(std::string_view text, const SourceLocation& where);

struct CellIoEmulatorOptions {
  double process_time = 5.0;      // seconds the mill is busy after a start (the cell's machine process_time), >= 0
  double take_out_after = -1;     // seconds from done to the part taken out (done clears); < 0: never by itself
  std::vector<InputChange> script;  // photo-eye changes, in any order (applied in time order)
  std::function<double()> clock;    // seconds; empty: the steady clock since construction
};

class CellIoEmulator final : public drivers::DigitalIo {
 public:
  static constexpr std::uint16_t kCoils = 3;
  static constexpr std::uint16_t kInputs = 4;
  static constexpr std::uint16_t kMillStart = 2, kMillBusy = 2, kMillDone = 3;

  // Throws InputError (naming `where`) for a negative or non-finite process time, a script change that is not for
  // input 0 or 1, or at a negative time.
  explicit CellIoEmulator(CellIoEmulatorOptions options = {}, const SourceLocation& where = {"cell I/O", 0, 0});

  std::string describe() const override;  // "emulated cell I/O"
  drivers::IoResult connect() override;
  void close() override;
  bool is_open() const override;
  drivers::IoResult write_coil(std::uint16_t address, bool value) override;
  drivers::IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;
  drivers::IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;

  void set_input(std::uint16_t address, bool value);  // a photo-eye (0 or 1), until the script changes it
  void take_out();                                    // the part is taken out of the mill: done clears
  bool coil(std::uint16_t address) const;
  int cycles() const;                                 // mill cycles started so far

 private:
  double now() const;
  void update(double t);  // applies the script and the mill's timers up to t, into the image

  mutable std::mutex mu_;  // the mill's state and the script (the image has its own)
  CellIoEmulatorOptions options_;
  double epoch_ = 0;  // the steady clock at construction, when no clock was given
  drivers::MemoryIo image_;  // coils as written, inputs as the mill and the photo-eyes set them
  std::size_t next_change_ = 0;
  enum class Mill { idle, busy, done } mill_ = Mill::idle;
  double since_ = 0;  // when the mill entered its state
  int cycles_ = 0;
};

}  // namespace cellwright::emulate
