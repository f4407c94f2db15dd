#include "cellwright/drivers/digital_io.hpp"

#include <fmt/format.h>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/memory_io.hpp"

namespace cellwright::drivers {

const char* to_string(IoStatus s) {
  switch (s) {
    case IoStatus::ok: return "ok";
    case IoStatus::timeout: return "timeout";
    case IoStatus::exception: return "exception";
    case IoStatus::disconnected: return "disconnected";
    case IoStatus::protocol: return "protocol";
  }
  return "?";
}

MemoryIo::MemoryIo(std::uint16_t coils, std::uint16_t inputs, std::string name)
    : name_(std::move(name)), coils_(coils, false), inputs_(inputs, false) {}

std::string MemoryIo::describe() const { return name_; }

IoResult MemoryIo::connect() {
  std::lock_guard lock(mu_);
  open_ = true;
  return {};
}

void MemoryIo::close() {
  std::lock_guard lock(mu_);
  open_ = false;
}

bool MemoryIo::is_open() const {
  std::lock_guard lock(mu_);
  return open_;
}

IoResult MemoryIo::check(const char* what, std::uint16_t first, std::uint16_t count, std::size_t size) {
  CW_CHECK(count > 0, "MemoryIo: a request for 0 values");
  ++requests_;
  if (!open_) return {IoStatus::disconnected, 0, fmt::format("{}: {}: the unit is not connected", name_, what)};
  if (!failures_.empty()) {
    const auto [status, code] = failures_.front();
    failures_.pop_front();
    if (status == IoStatus::disconnected || status == IoStatus::protocol) open_ = false;
    return {status, code, fmt::format("{}: {}: scripted {}{}", name_, what, to_string(status),
                                      status == IoStatus::exception ? fmt::format(" (code {})", code) : "")};
  }
  if (std::size_t{first} + count > size) {
    return {IoStatus::exception, 2,
            fmt::format("{}: {} {}..{}: illegal data address (the unit has {})", name_, what, first,
                        first + count - 1, size)};
  }
  return {};
}

IoResult MemoryIo::write_coil(std::uint16_t address, bool value) {
  std::lock_guard lock(mu_);
  IoResult r = check("write coil", address, 1, coils_.size());
  if (!r.ok()) return r;
  ++writes_;
  coils_[address] = value;
  return r;
}

IoResult MemoryIo::read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  std::lock_guard lock(mu_);
  IoResult r = check("read coils", first, count, coils_.size());
  if (r.ok()) values.assign(coils_.begin() + first, coils_.begin() + first + count);
  return r;
}

IoResult MemoryIo::read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  std::lock_guard lock(mu_);
  IoResult r = check("read discrete inputs", first, count, inputs_.size());
  if (r.ok()) values.assign(inputs_.begin() + first, inputs_.begin() + first + count);
  return r;
}

void MemoryIo::set_input(std::uint16_t address, bool value) {
  std::lock_guard lock(mu_);
  CW_CHECK(address < inputs_.size(), "MemoryIo: set_input beyond the unit's inputs");
  inputs_[address] = value;
}

bool MemoryIo::coil(std::uint16_t address) const {
  std::lock_guard lock(mu_);
  CW_CHECK(address < coils_.size(), "MemoryIo: coil beyond the unit's coils");
  return coils_[address];
}

void MemoryIo::fail_next(IoStatus status, int exception_code) {
  std::lock_guard lock(mu_);
  failures_.emplace_back(status, exception_code);
}

int MemoryIo::requests() const {
  std::lock_guard lock(mu_);
  return requests_;
}

int MemoryIo::writes() const {
  std::lock_guard lock(mu_);
  return writes_;
}

}  // namespace cellwright::drivers
