// The one digital I/O interface. The cell's ancillary equipment (conveyors, the process machine, photo-eyes) is
// wired to an I/O unit: a PLC or a remote-I/O module on Modbus TCP in a real cell, the twin's own I/O image in the
// simulation. The controller writes outputs (coils: run a belt, start the machine's cycle) and reads inputs (discrete
// inputs: a part at a stop, the machine busy, the machine done); nothing above this interface knows which kind of
// unit it talks to. The cell description gives each device's addresses (docs/cell-description.md, "io"); the paper's
// cell ships with this list (unit 1):
//
//   coil 0            input conveyor run          discrete input 0   part at the input conveyor's stop (photo-eye)
//   coil 1            output conveyor run         discrete input 1   part at the output conveyor's drop
//   coil 2            mill cycle start            discrete input 2   mill busy
//                                                 discrete input 3   mill done (a processed part is in the mill)
//
// ADDRESSES are the protocol's 0-based data addresses (Modbus "coil 0" is the PLC programmer's 00001), 0..65535, one
// bit each. A unit answers for the addresses it has; any other is refused with IoStatus::exception and the
// unit's code (Modbus 2, illegal data address).
//
// SYNCHRONOUS, ONE OWNER. Each call is one request and its answer: it returns when the unit has answered, or when
// the unit's response timeout has passed (IoStatus::timeout). The thread that owns the unit is the only caller of
// every method (a Modbus connection is one socket: requests on it cannot overlap); a device-control thread owns its
// unit, and devices that share a unit share that thread. Nothing here sleeps or retries on its own: the caller decides
// what a failure means (docs/faults.md).
//
// LIFECYCLE
//
//   closed --connect() ok--> open --any call failing with disconnected--> closed
//     ^                       |
//     +------- close() -------+
//
//   connect() on an open unit is a no-op returning ok; the other calls on a closed unit return disconnected without
//   touching the network. close() works in every state. A unit that answered with an exception stays open (the
//   request was refused, the link is fine); a timeout leaves it open too (the next request may be answered), a
//   broken link (peer closed, reset, unreachable) closes it, and connect() may be called again to reconnect.
//
// ERRORS OF SETUP vs ERRORS IN CONTROL CYCLES. Creating a unit from a bad address (`modbus:HOST:PORT[/UNIT]` that
// does not parse, a unit outside 0..247) throws cellwright::InputError naming the text and the problem. Every call
// returns an IoResult and never throws for anything the unit or the network did; InternalError (CW_CHECK) is kept for
// the implementation's own bugs (e.g. a count of 0).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cellwright::drivers {

enum class IoStatus {
  ok,
  timeout,       // no answer within the unit's response timeout; the unit stays open
  exception,     // the unit refused the request (IoResult::exception_code: Modbus 1..11); the unit stays open
  disconnected,  // no link (never connected, closed, or it broke during this request); the unit is closed
  protocol,      // an answer that is not a valid reply to the request (wrong length, function, transaction); the
                 // unit is closed, since the stream can no longer be trusted
};

const char* to_string(IoStatus s);

struct IoResult {
  IoStatus status = IoStatus::ok;
  int exception_code = 0;  // with IoStatus::exception: the unit's code (Modbus: 1 illegal function, 2 illegal
                           // data address, 3 illegal data value, 4 server device failure, 6 busy, ...)
  std::string message;     // empty when ok; otherwise names the unit, the request and what happened

  bool ok() const { return status == IoStatus::ok; }
};

// One I/O unit. Implementations: the Modbus TCP client (drivers/modbus/modbus_io.hpp), the twin's I/O image (the
// simulator serves its devices through this), and MemoryIo (a test double, memory_io.hpp).
class DigitalIo {
 public:
  virtual ~DigitalIo() = default;

  // "modbus 127.0.0.1:1502 unit 1", "twin": for messages and the event log.
  virtual std::string describe() const = 0;

  virtual IoResult connect() = 0;
  virtual void close() = 0;
  virtual bool is_open() const = 0;

  // Writes one output (Modbus function 5, write single coil).
  virtual IoResult write_coil(std::uint16_t address, bool value) = 0;
  // Reads `count` outputs from `first` (Modbus function 1, read coils): what the unit's outputs are set to now.
  virtual IoResult read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) = 0;
  // Reads `count` inputs from `first` (Modbus function 2, read discrete inputs). `values` is resized to `count` when
  // the result is ok and left unchanged otherwise.
  virtual IoResult read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) = 0;
};

}  // namespace cellwright::drivers
