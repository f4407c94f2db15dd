// MirroredIo: a real I/O unit whose outputs are also shown on a second unit, the mirror (issue 26: a device on real
// I/O is mirrored in the twin's I/O image, so that the twin's snapshots, video and report show it as it is).
//
// WHAT IT DOES. Every call goes to the real unit, and its answer is the answer. A coil written successfully there is
// then written into the mirror (whose answer is ignored: the controller drives the real unit, and a mirror that
// refuses an address changes nothing for it). connect() connects the real unit and then copies into the mirror the
// real unit's value of every coil named with mirror_coil(), so that a belt a PLC left stopped is stopped in the mirror
// too, at the start of a run and again after a reconnect; a coil that cannot be read then is left as the mirror has
// it (the run's own requests meet that failure). Coils read from the real unit are written into the mirror too (device
// control reads every belt's run coil each period, so the mirror follows whoever else switches it). Inputs are not
// copied: the mirror's inputs are its own (the twin's
// sensors), and the controller reads the real ones.
//
// THREADS. The DigitalIo rule: one owner calls it. The mirror must be open (connected by its owner) before this unit
// writes into it, and must outlive this object; the mirror may be shared with other owners if it allows that
// (TwinIo does).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"

namespace cellwright::drivers {

class MirroredIo final : public DigitalIo {
 public:
  MirroredIo(std::unique_ptr<DigitalIo> real, DigitalIo& mirror);

  // A coil of a device on this unit (a belt's run, a machine's start), copied into the mirror at connect(). Negative
  // addresses (not wired) are ignored.
  void mirror_coil(int address);

  std::string describe() const override;
  IoResult connect() override;
  void close() override;
  bool is_open() const override;
  IoResult write_coil(std::uint16_t address, bool value) override;
  IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;
  IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;

 private:
  std::unique_ptr<DigitalIo> real_;
  DigitalIo& mirror_;
  std::vector<std::uint16_t> coils_;
};

}  // namespace cellwright::drivers
