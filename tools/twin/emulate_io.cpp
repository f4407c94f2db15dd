#include "emulate_io.hpp"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cstdio>

#include "cellwright/common/error.hpp"
#include "cellwright/emulate/cell_io_emulator.hpp"
#include "cellwright/emulate/modbus_server.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

void add_emulate_io_options(CLI::App* cmd, EmulateIoArgs& args) {
  cmd->add_option("--listen", args.listen,
                  "io: HOST:PORT to serve the cell's I/O on, Modbus TCP (e.g. 127.0.0.1:1502; port 0: a free one)");
  cmd->add_option("--unit", args.unit, "io: the Modbus unit identifier it answers as (default 1)")
      ->check(CLI::Range(0, 255));
  cmd->add_option("--process-time", args.process_time, "io: seconds the mill is busy after a start (default 5)");
  cmd->add_option("--take-out-after", args.take_out_after,
                  "io: seconds from the mill's done to the part taken out (done clears); default: never");
  cmd->add_option("--input", args.inputs,
                  "io: a photo-eye's change AT:INPUT=VALUE, e.g. 2.5:0=1 (input 0 on at 2.5 s; repeatable)");
}

int emulate_io(const EmulateIoArgs& args, bool verbose) {
  const SourceLocation listen_at{"--listen", 0, 0};
  if (args.listen.empty()) throw InputError(listen_at, "emulate io needs --listen HOST:PORT");
  emulate::ModbusServerOptions server = emulate::parse_listen_address(args.listen, listen_at);
  server.unit = args.unit;
  emulate::CellIoEmulatorOptions cell;
  cell.process_time = args.process_time;
  cell.take_out_after = args.take_out_after;
  for (const std::string& i : args.inputs) cell.script.push_back(emulate::parse_input_change(i, {"--input", 0, 0}));
  emulate::CellIoEmulator io(std::move(cell), {"twin emulate io", 0, 0});
  emulate::ModbusServer modbus(io, server, listen_at);
  if (verbose) {
    modbus.set_hook([](const emulate::ServedRequest& s) {
      std::printf("client %d: function %d, %u value(s) from %u: %s\n", s.client, s.function, s.count, s.address,
                  s.exception_code == 0 ? "ok" : fmt::format("exception {}", s.exception_code).c_str());
      std::fflush(stdout);
    });
  }
  std::printf("emulating the cell's I/O on Modbus TCP at %s, unit %d (mill: busy %g s, part taken out %s); Ctrl-C "
              "to stop\n",
              modbus.endpoint().c_str(), args.unit, args.process_time,
              args.take_out_after < 0 ? "never" : fmt::format("after {} s", args.take_out_after).c_str());
  std::fflush(stdout);
  std::atomic<bool> stop{false};
  // Served on the worker in the owner's way, so that the stop is seen within one wait.
  run_until_signal(
      [&] {
        while (!stop) modbus.serve(std::chrono::milliseconds(200));
      },
      [&] { stop = true; });
  return 0;
}

}  // namespace cellwright::tools
