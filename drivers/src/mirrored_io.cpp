// A real I/O unit mirrored into another (mirrored_io.hpp).
#include "cellwright/drivers/mirrored_io.hpp"

#include <utility>

namespace cellwright::drivers {

MirroredIo::MirroredIo(std::unique_ptr<DigitalIo> real, DigitalIo& mirror) : real_(std::move(real)), mirror_(mirror) {}

void MirroredIo::mirror_coil(int address) {
  if (address >= 0) coils_.push_back(static_cast<std::uint16_t>(address));
}

std::string MirroredIo::describe() const { return real_->describe(); }

IoResult MirroredIo::connect() {
  const IoResult r = real_->connect();
  if (!r.ok()) return r;
  std::vector<bool> v;
  for (const std::uint16_t a : coils_) {
    if (real_->read_coils(a, 1, v).ok()) (void)mirror_.write_coil(a, v.at(0));
  }
  return r;
}

void MirroredIo::close() { real_->close(); }

bool MirroredIo::is_open() const { return real_->is_open(); }

IoResult MirroredIo::write_coil(std::uint16_t address, bool value) {
  const IoResult r = real_->write_coil(address, value);
  if (r.ok()) (void)mirror_.write_coil(address, value);
  return r;
}

IoResult MirroredIo::read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  const IoResult r = real_->read_coils(first, count, values);
  if (r.ok()) {
    for (std::size_t i = 0; i < values.size(); ++i) {
      (void)mirror_.write_coil(static_cast<std::uint16_t>(first + i), values[i]);
    }
  }
  return r;
}

IoResult MirroredIo::read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  return real_->read_inputs(first, count, values);
}

}  // namespace cellwright::drivers
