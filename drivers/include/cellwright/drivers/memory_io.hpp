// MemoryIo: a DigitalIo test double, an I/O unit held in memory. Its coils are what the owner last wrote; its
// inputs are what the test sets. A test can also make the next requests fail (timeout, exception, a broken link) and
// read how many requests were made, so that device control can be tested without a network.
//
// Threads: the owner calls the DigitalIo methods; the test controls (set_input, coil, fail_next, requests) may be
// called from any thread. All state is behind one mutex.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "cellwright/drivers/digital_io.hpp"

namespace cellwright::drivers {

class MemoryIo final : public DigitalIo {
 public:
  // A unit with coils 0..coils-1 and discrete inputs 0..inputs-1, all off, closed until connect().
  MemoryIo(std::uint16_t coils, std::uint16_t inputs, std::string name = "memory");

  std::string describe() const override;
  IoResult connect() override;
  void close() override;
  bool is_open() const override;
  IoResult write_coil(std::uint16_t address, bool value) override;
  IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;
  IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;

  // Test controls.
  void set_input(std::uint16_t address, bool value);
  bool coil(std::uint16_t address) const;
  // The next request (any call but close()) fails with `status` (with `exception_code` for exception); queued in
  // order, one per request. A disconnected or protocol failure closes the unit, as the interface says.
  void fail_next(IoStatus status, int exception_code = 0);
  // Requests made so far (connect() excluded), and of them writes.
  int requests() const;
  int writes() const;

 private:
  IoResult check(const char* what, std::uint16_t first, std::uint16_t count, std::size_t size);

  mutable std::mutex mu_;
  std::string name_;
  std::vector<bool> coils_;
  std::vector<bool> inputs_;
  bool open_ = false;
  std::deque<std::pair<IoStatus, int>> failures_;
  int requests_ = 0;
  int writes_ = 0;
};

}  // namespace cellwright::drivers
