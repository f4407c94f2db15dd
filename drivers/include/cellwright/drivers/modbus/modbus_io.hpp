// ModbusIo: an I/O unit on Modbus TCP (a PLC, a remote-I/O module), the DigitalIo of a real cell. A client of
// libmodbus (Debian's libmodbus 3.1.6), one TCP connection, one request at a time, exactly as digital_io.hpp says;
// docs/devices.md lists the cell's I/O and what was tested against what.
//
// THE ADDRESS TEXT. `modbus:HOST:PORT[/UNIT]`, as `twin run --device NAME=...` and the scenario take it:
//   HOST   an IPv4 address (127.0.0.1) or a host name (plc-1.cell.local: letters, digits, '-' and '.'); IPv6 is not
//          taken (write a host name that resolves to it)
//   PORT   1..65535 (Modbus's own is 502)
//   UNIT   the unit identifier, 0..247, default 1 (most TCP devices ignore it; a gateway to serial devices routes by it)
// parse_modbus_address() throws InputError naming `where`, the text and what is wrong with it. The host name is
// resolved at connect(), not while parsing.
//
// REQUESTS. write_coil is function 5, read_coils 1, read_inputs 2. The calls follow the DigitalIo contract; here is
// what each libmodbus outcome becomes:
//   an exception response (codes 1..11)                      IoStatus::exception with the code; the unit stays open
//   no complete answer within the response timeout            IoStatus::timeout; the unit stays open (a late answer
//                                                              already there is discarded before the next request;
//                                                              one that comes during it is a protocol error)
//   peer closed or reset, refused, unreachable, not connected  IoStatus::disconnected; the unit is closed
//   an answer that is not a reply to the request (another     IoStatus::protocol; the unit is closed
//   transaction or function, a wrong length or byte count, an
//   exception code outside 1..11)
// The response timeout bounds the whole answer (its first byte and every later one) and the TCP connect: no call
// waits longer than it, and none retries. A request for 0 values, more than 2000, or past address 65535 is the
// caller's bug (CW_CHECK), never sent.
//
// Messages name the unit, the request and what happened, e.g. "modbus 127.0.0.1:1502 unit 1: read discrete inputs
// 0..3: exception 2 (illegal data address)".
//
// Threads: not synchronised; the owner thread (digital_io.hpp) is the only caller.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/digital_io.hpp"

struct _modbus;  // libmodbus's context (modbus_t), kept out of the interface

namespace cellwright::drivers {

struct ModbusAddress {
  std::string host;
  int port = 502;
  int unit = 1;

  // "127.0.0.1:1502 unit 1"
  std::string str() const;
};

// Parses `modbus:HOST:PORT[/UNIT]`. Throws InputError(where, ...) naming the text and the problem.
ModbusAddress parse_modbus_address(std::string_view text, const SourceLocation& where);

struct ModbusIoOptions {
  double response_timeout = 0.5;  // seconds, > 0: how long a request (and a connect) waits for the answer
};

class ModbusIo final : public DigitalIo {
 public:
  // A closed unit; nothing is sent until connect(). Throws InputError (naming `where`) for a response timeout that is
  // not a positive finite number of seconds up to an hour.
  ModbusIo(ModbusAddress address, ModbusIoOptions options = {}, const SourceLocation& where = {"modbus", 0, 0});
  ~ModbusIo() override;
  ModbusIo(const ModbusIo&) = delete;
  ModbusIo& operator=(const ModbusIo&) = delete;

  // "modbus 127.0.0.1:1502 unit 1"
  std::string describe() const override;
  // Resolves the host and opens the connection (within the response timeout). A host that does not resolve, a refused
  // or unanswered connection: disconnected, the message saying which.
  IoResult connect() override;
  void close() override;
  bool is_open() const override;
  IoResult write_coil(std::uint16_t address, bool value) override;
  IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;
  IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) override;

  const ModbusAddress& address() const { return address_; }

 private:
  // Runs one request (`send` calls libmodbus and returns its result), mapping a failure as the header says.
  template <typename Send>
  IoResult request(const std::string& what, Send&& send);
  IoResult read_bits(bool inputs, std::uint16_t first, std::uint16_t count, std::vector<bool>& values);

  ModbusAddress address_;
  ModbusIoOptions options_;
  _modbus* ctx_ = nullptr;
  bool open_ = false;
  bool stale_ = false;  // the last request timed out: its answer may still come, and is flushed first
  std::vector<std::uint8_t> bits_;
};

}  // namespace cellwright::drivers
