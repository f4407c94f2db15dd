// `twin emulate io`: the cell's I/O served on Modbus TCP, as a user starts it, driven by pymodbus's client (not our
// code): it says where it listens, runs the mill's handshake, stops cleanly on SIGTERM, and refuses bad input.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <regex>
#include <string>

#include "drivers/modbus/python_peer.hpp"
#include "tools/twin_cli.hpp"

namespace {

using cellwright::testing::BackgroundTwin;
using cellwright::testing::PythonPeer;
using cellwright::testing::TwinCli;
using namespace std::chrono_literals;

TEST(EmulateIoCli, ServesTheMillsHandshakeOnTheAnnouncedPortUntilStopped) {
  if (const std::string why = cellwright::testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  // No process time and no take-out: the mill is done as soon as it starts, and stays done.
  BackgroundTwin twin({"emulate", "io", "--listen", "127.0.0.1:0", "--process-time", "0", "--input", "0:1=1"});
  ASSERT_TRUE(twin.wait_for("Ctrl-C to stop\n", 20s)) << twin.output();
  std::smatch m;
  const std::string out = twin.output();
  ASSERT_TRUE(std::regex_search(out, m, std::regex("on Modbus TCP at 127\\.0\\.0\\.1:([0-9]+), unit 1"))) << out;
  PythonPeer plc({"client", m[1].str()});
  ASSERT_EQ(plc.first_line(), "ready");
  EXPECT_EQ(plc.ask("read_inputs 0 4"), "ok 0 1 0 0");
  EXPECT_EQ(plc.ask("write_coil 0 1"), "ok");
  EXPECT_EQ(plc.ask("write_coil 2 1"), "ok");
  EXPECT_EQ(plc.ask("read_inputs 0 4"), "ok 0 1 0 1");
  EXPECT_EQ(plc.ask("read_coils 0 3"), "ok 1 0 1");
  EXPECT_EQ(plc.ask("read_inputs 4 1"), "exception 2");
  EXPECT_EQ(twin.stop(), 0) << twin.output();
}

TEST(EmulateIoCli, BadInputIsRefusedWithExit2NamingIt) {
  TwinCli cli("emulate-io");
  const struct {
    const char* args;
    const char* message;
  } cases[] = {
      {"emulate io", "emulate io needs --listen HOST:PORT"},
      {"emulate io --listen 127.0.0.1", "'127.0.0.1' is not HOST:PORT"},
      {"emulate io --listen 127.0.0.1:0 --input 1:3=1", "--input: error: '1:3=1': the input '3' is not 0 or 1"},
      {"emulate io --listen 127.0.0.1:0 --process-time -1", "process time must be a number of seconds >= 0, got -1"},
      {"emulate io --listen 127.0.0.1:0 --link /tmp/x", "--link is for a robot controller"},
      {"emulate movemaster --link /tmp/x --listen 127.0.0.1:0", "--listen is for `twin emulate io`"},
  };
  for (const auto& c : cases) {
    const auto r = cli.run(c.args);
    EXPECT_EQ(r.status, 2) << c.args;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << ": " << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args << ": " << r.out;
  }
}

}  // namespace
