// ModbusServer: a Modbus TCP server that serves any DigitalIo (drivers/digital_io.hpp) as its I/O image: the emulated
// cell I/O (cell_io_emulator.hpp), the twin's I/O for virtual commissioning of a PLC, a MemoryIo in tests. libmodbus
// (3.1.6) listens and frames the answers; the requests are read and framed here, per connection, so that no client
// can hold up another. Written apart from the drivers' Modbus client (drivers/modbus, which emulate/ must not
// include: the walls test), so that each checks the other; both are tested against pymodbus (docs/devices.md).
//
// FUNCTIONS. 1 read coils, 2 read discrete inputs, 5 write single coil, 15 write multiple coils, each passed to the
// backend (15 as one write_coil per coil, in address order, stopping at the first refused). Any other function is
// answered with exception 1 (illegal function). What the backend says becomes the answer:
//   ok                          the normal response
//   exception with a code       that exception (e.g. 2, illegal data address, for an address the backend lacks)
//   timeout                     exception 11 (gateway target device failed to respond)
//   disconnected                exception 10 (gateway path unavailable); the server calls the backend's connect()
//                               before the next request
//   protocol                    exception 4 (server device failure)
// The server connects the backend when it starts listening and whenever a request finds it closed.
// A request malformed for its function (a wrong length, a count of 0 or more than the function allows, a coil value
// other than 0xFF00/0x0000) is answered with exception 3 (illegal data value), a range past address 65535 with
// exception 2, and a request addressed to another unit than the server's with exception 11, without reaching the
// backend. A stream that is not Modbus TCP (a protocol identifier other than 0, a length outside 2..254) closes that
// connection only. A client may send a request in pieces, or several at once: each is answered when complete, in
// order.
//
// TWO WAYS TO RUN, never both at once:
//  - start(): serves on a thread of its own, in real time, until stop() (or the destructor). The backend is then
//    called on that thread only.
//  - serve(wait): the owner serves whatever requests are pending now, between its own steps (the twin answers in
//    virtual time: the I/O image does not change while a request is served; a lock-step owner advances the twin only
//    when a client polls, counting them in the hook). It waits up to `wait` for a first byte or connection to arrive,
//    then serves every request that is complete without waiting further, and returns how many it answered. The
//    backend is called on the owner's thread.
// The hook (set before serving) is called after each answer is sent, on the serving thread, with what was asked and
// answered and the server's own processing time (from the request's last byte read to its answer sent).
//
// ERRORS. The constructor throws InputError (naming `where`, the host and port) when it cannot listen (a port in use,
// a host that does not resolve to a local address). Serving never throws for anything a client or the backend did.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/digital_io.hpp"

struct _modbus;              // libmodbus's context (modbus_t)
struct _modbus_mapping_t;    // libmodbus's register image (modbus_mapping_t)

namespace cellwright::emulate {

struct ModbusServerOptions {
  std::string host = "127.0.0.1";  // the address to listen on: an IPv4 address or a host name ("0.0.0.0": all)
  int port = 0;                    // 0: a free port the system chooses (port() says which); else 1..65535
  int unit = 1;                    // the unit identifier it answers as, 0..255 (Modbus TCP devices often use 255)
  int max_clients = 16;            // further connections are accepted and closed at once
};

// Parses where to listen, `HOST:PORT` (port 0..65535, 0: a free one), into options (the other fields as defaulted).
// Throws InputError naming `where` and the text when it is not that. The host is resolved when the server is made.
ModbusServerOptions parse_listen_address(std::string_view host_port, const SourceLocation& where);

// One request served, for the hook.
struct ServedRequest {
  int client = 0;                      // the connection, numbered 1, 2, ... in the order they were accepted
  int unit = 0;                        // the unit identifier it was addressed to
  int function = 0;                    // the Modbus function code
  std::uint16_t address = 0;           // first address (0 when the function has none)
  std::uint16_t count = 0;             // values asked for or written (0 when the function has none)
  int exception_code = 0;              // 0: a normal answer; else the exception sent
  std::chrono::nanoseconds processing{0};  // from the request's last byte read to its answer sent
};

class ModbusServer {
 public:
  // Listens on options.host:port (libmodbus's modbus_tcp_pi_listen) and connects the backend. The backend must outlive
  // the server; the server is its owner (digital_io.hpp) while it serves.
  ModbusServer(drivers::DigitalIo& backend, ModbusServerOptions options,
               const SourceLocation& where = {"modbus server", 0, 0});
  ~ModbusServer();  // stop(), then closes every connection and the listening socket
  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  int port() const { return port_; }       // the port it listens on
  std::string endpoint() const;            // "127.0.0.1:1502"
  const ModbusServerOptions& options() const { return options_; }

  void set_hook(std::function<void(const ServedRequest&)> hook);

  // Serves what is pending now (see above); returns the number of requests answered. Not while start()ed.
  int serve(std::chrono::nanoseconds wait = std::chrono::nanoseconds(0));

  // Serves on a thread of its own until stop(). stop() is safe from any thread and returns once the thread ended.
  void start();
  void stop();

  // Connections open now, and requests handled so far (counted before each answer is sent, so a client that has its
  // answer is counted); both safe from any thread.
  int clients() const { return open_clients_.load(); }
  long requests() const { return requests_.load(); }

 private:
  struct Client;
  int poll_and_serve(std::chrono::nanoseconds wait);  // wait < 0: until something arrives
  void accept_clients();
  // Reads what `c` has sent; answers every complete request. False when the connection is to be closed.
  bool read_client(Client& c, int& served);
  // Answers one complete frame (MBAP header and PDU). False when the answer could not be sent.
  bool answer(Client& c, const std::uint8_t* frame, std::size_t length);
  int backend_exception(const drivers::IoResult& r);
  void close_client(std::size_t index);

  drivers::DigitalIo& backend_;
  ModbusServerOptions options_;
  _modbus* ctx_ = nullptr;
  _modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  int wake_[2] = {-1, -1};  // stop()'s wake-up, a pipe
  int port_ = 0;
  int next_client_ = 1;
  std::vector<std::unique_ptr<Client>> clients_;
  std::function<void(const ServedRequest&)> hook_;
  std::vector<bool> values_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stopping_{false};
  std::atomic<int> open_clients_{0};
  std::atomic<long> requests_{0};
};

}  // namespace cellwright::emulate
