// Modbus TCP round trip over loopback: our client (drivers' ModbusIo) against our server (emulate's ModbusServer on
// its own thread, serving the emulated cell I/O), and against pymodbus's server (Debian's python3-pymodbus, the peer
// the tests use: tests/data/modbus/peer.py) for comparison. For each: read_inputs (function 2, the four inputs of the
// paper's cell) and write_coil (function 5), the wall time of each call as its owner sees it, p50 and p99; and our
// server's own processing per request (ModbusServer's hook: from the request's last byte read to its answer sent).
// Reproduce pinned to one CPU (client and server then share it, as on a loaded controller):
//   taskset -c 0 build/tools/modbus_bench [--requests N]
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "../../tests/drivers/modbus/python_peer.hpp"
#include "cellwright/drivers/modbus/modbus_io.hpp"
#include "cellwright/emulate/cell_io_emulator.hpp"
#include "cellwright/emulate/modbus_server.hpp"

namespace {

using namespace cellwright;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5)];
}

struct Figures {
  std::vector<double> read_us, write_us;
  std::string problem;
};

// `n` calls of each kind on a unit connected to 127.0.0.1:port, after a warm-up; the wall time of each, µs.
Figures measure(int port, int n) {
  Figures f;
  drivers::ModbusIo io({"127.0.0.1", port, 1}, {2.0});
  if (const drivers::IoResult r = io.connect(); !r.ok()) {
    f.problem = r.message;
    return f;
  }
  std::vector<bool> v;
  for (int i = 0; i < 200; ++i) io.read_inputs(0, 4, v);
  f.read_us.reserve(static_cast<std::size_t>(n));
  f.write_us.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    const drivers::IoResult r = io.read_inputs(0, 4, v);
    const auto t1 = Clock::now();
    const drivers::IoResult w = io.write_coil(static_cast<std::uint16_t>(i % 2), i % 4 < 2);
    const auto t2 = Clock::now();
    if (!r.ok() || !w.ok()) {
      f.problem = !r.ok() ? r.message : w.message;
      return f;
    }
    f.read_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    f.write_us.push_back(std::chrono::duration<double, std::micro>(t2 - t1).count());
  }
  return f;
}

void row(const char* server, const char* request, const std::vector<double>& us, const std::string& processing) {
  fmt::print("{:<22} {:<12} {:>7} {:>9.1f} {:>9.1f}  {}\n", server, request, us.size(), percentile(us, 0.5),
             percentile(us, 0.99), processing);
}

}  // namespace

int main(int argc, char** argv) {
  int n = 20000;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "--requests") == 0) n = std::max(1, std::atoi(argv[i + 1]));
  }
  fmt::print(
      "modbus_bench: Modbus TCP round trips over loopback, ModbusIo (libmodbus) against our ModbusServer (on its "
      "thread, the emulated cell I/O behind it) and against pymodbus's server; {} calls of each kind. Pin it: taskset "
      "-c 0 build/tools/modbus_bench\n\n",
      n);
  fmt::print("{:<22} {:<12} {:>7} {:>9} {:>9}  {}\n", "server", "request", "calls", "p50 us", "p99 us",
             "server processing p50 / p99 us");

  {
    emulate::CellIoEmulator cell;
    emulate::ModbusServer server(cell, {});
    std::vector<emulate::ServedRequest> served;
    served.reserve(static_cast<std::size_t>(2 * n + 400));
    server.set_hook([&](const emulate::ServedRequest& s) {
      if (served.size() < served.capacity()) served.push_back(s);
    });
    server.start();
    const Figures f = measure(server.port(), n);
    server.stop();
    if (!f.problem.empty()) {
      fmt::print("ModbusServer: {}\n", f.problem);
      return 1;
    }
    std::vector<double> read_proc, write_proc;
    for (std::size_t i = 200; i < served.size(); ++i) {  // past the warm-up
      (served[i].function == 2 ? read_proc : write_proc)
          .push_back(std::chrono::duration<double, std::micro>(served[i].processing).count());
    }
    const auto proc = [](const std::vector<double>& v) {
      return fmt::format("{:.1f} / {:.1f}", percentile(v, 0.5), percentile(v, 0.99));
    };
    row("ModbusServer", "read_inputs", f.read_us, proc(read_proc));
    row("ModbusServer", "write_coil", f.write_us, proc(write_proc));
  }

  if (const std::string why = testing::pymodbus_missing(); !why.empty()) {
    fmt::print("pymodbus: not measured: {}\n", why);
    return 0;
  }
  testing::PythonPeer pymodbus({"server"});
  if (pymodbus.port() <= 0) {
    fmt::print("pymodbus: the server did not start: {}\n", pymodbus.first_line());
    return 1;
  }
  const Figures f = measure(pymodbus.port(), std::min(n, 5000));
  if (!f.problem.empty()) {
    fmt::print("pymodbus: {}\n", f.problem);
    return 1;
  }
  row("pymodbus 3.0.0 server", "read_inputs", f.read_us, "-");
  row("pymodbus 3.0.0 server", "write_coil", f.write_us, "-");
  return 0;
}
