// `twin emulate io --listen HOST:PORT [...]`: the paper's cell I/O (emulate/cell_io_emulator.hpp) served on Modbus TCP
// (emulate/modbus_server.hpp) in real time, standing in for a real cell's PLC: run a cell with `twin run ... --device
// NAME=modbus:HOST:PORT` against it. Prints one line when it listens, serves until SIGINT or SIGTERM (exit 0), exit 2
// on bad input. docs/devices.md says what it does.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace cellwright::tools {

struct EmulateIoArgs {
  std::string listen;               // HOST:PORT (port 0: a free one, printed)
  int unit = 1;
  double process_time = 5.0;        // seconds the mill is busy
  double take_out_after = -1;       // seconds from done until it clears; < 0: never
  std::vector<std::string> inputs;  // photo-eye changes, AT:INPUT=VALUE
};

// The options of `emulate io` on the `emulate` subcommand. Each description starts with "io: ": by that the
// subcommand tells them from the robot controllers' options, which `emulate io` refuses.
void add_emulate_io_options(CLI::App* cmd, EmulateIoArgs& args);

// Serves until a signal; `verbose` prints each request served.
int emulate_io(const EmulateIoArgs& args, bool verbose);

}  // namespace cellwright::tools
