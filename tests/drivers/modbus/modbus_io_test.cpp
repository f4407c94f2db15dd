// ModbusIo, our libmodbus client, against Modbus peers that are not ours (tests/data/modbus/peer.py: pymodbus's TCP
// server, a server answering junk, one never answering) over loopback: every call, the exception codes, a dropped
// connection and the reconnect, garbage, no server, no answer. And the address text.
#include "cellwright/drivers/modbus/modbus_io.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <memory>
#include <string>
#include <vector>

#include "drivers/modbus/python_peer.hpp"

namespace cellwright::drivers {
namespace {

using testing::PythonPeer;
using testing::pymodbus_missing;

// ---- The address text ---------------------------------------------------------------------------------------------

TEST(ModbusAddress, ParsesHostPortAndUnitWithUnitOneByDefault) {
  const ModbusAddress a = parse_modbus_address("modbus:192.168.0.10:502/7", {"--device", 0, 0});
  EXPECT_EQ(a.host, "192.168.0.10");
  EXPECT_EQ(a.port, 502);
  EXPECT_EQ(a.unit, 7);
  const ModbusAddress b = parse_modbus_address("modbus:plc-1.cell.local:1502", {"--device", 0, 0});
  EXPECT_EQ(b.host, "plc-1.cell.local");
  EXPECT_EQ(b.port, 1502);
  EXPECT_EQ(b.unit, 1);
  EXPECT_EQ(parse_modbus_address("modbus:localhost:65535/0", {}).unit, 0);
  EXPECT_EQ(b.str(), "plc-1.cell.local:1502 unit 1");
}

TEST(ModbusAddress, BadTextIsAnInputErrorNamingTheTextAndTheProblem) {
  const struct {
    const char* text;
    const char* problem;
  } cases[] = {
      {"tcp:127.0.0.1:502", "does not start with 'modbus:'"},
      {"modbus:127.0.0.1", "port is missing"},
      {"modbus:127.0.0.1:0", "the port '0' is not a number within 1..65535"},
      {"modbus:127.0.0.1:65536", "the port '65536'"},
      {"modbus:127.0.0.1:50x", "the port '50x'"},
      {"modbus:127.0.0.1:502/248", "the unit '248' is not a number within 0..247"},
      {"modbus:127.0.0.1:502/", "the unit ''"},
      {"modbus:127.0.0.1:502/-1", "the unit '-1'"},
      {"modbus:::1:502", "IPv6"},
      {"modbus:[::1]:502", "IPv6"},
      {"modbus::502", "the host is empty"},
      {"modbus:256.0.0.1:502", "'256.0.0.1' is not an IPv4 address"},
      {"modbus:10.0.1:502", "'10.0.1' is not an IPv4 address"},
      {"modbus:plc_1:502", "'_' is not a letter, digit"},
      {"modbus:-plc:502", "starts or ends with '-'"},
      {"modbus:plc..cell:502", "is empty"},
  };
  for (const auto& c : cases) {
    try {
      parse_modbus_address(c.text, {"scene.yaml", 12, 3});
      ADD_FAILURE() << c.text << " was taken";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("scene.yaml:12:3"), std::string::npos) << what;
      EXPECT_NE(what.find(std::string("'") + c.text + "'"), std::string::npos) << what;
      EXPECT_NE(what.find(c.problem), std::string::npos) << c.text << ": " << what;
    }
  }
}

TEST(ModbusIo, AResponseTimeoutThatIsNotPositiveIsAnInputError) {
  for (const double t : {0.0, -1.0, 1e9}) {
    EXPECT_THROW(ModbusIo({"127.0.0.1", 502, 1}, {t}), InputError) << t;
  }
}

// ---- Against peers --------------------------------------------------------------------------------------------------

// A loopback port on which nothing listens (bound, then released).
int unused_port() {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
  ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(s);
  return ntohs(a.sin_port);
}

class ModbusIoPeer : public ::testing::Test {
 protected:
  void SetUp() override {
    if (const std::string why = pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
  }
  // A unit connected to a peer started in `mode`.
  std::unique_ptr<ModbusIo> start(const char* mode, double timeout = 2.0) {
    peer_ = std::make_unique<PythonPeer>(std::vector<std::string>{mode});
    EXPECT_GT(peer_->port(), 0) << "the peer did not start: " << peer_->first_line();
    auto io = std::make_unique<ModbusIo>(ModbusAddress{"127.0.0.1", peer_->port(), 1}, ModbusIoOptions{timeout});
    const IoResult r = io->connect();
    EXPECT_TRUE(r.ok()) << r.message;
    return io;
  }
  std::unique_ptr<PythonPeer> peer_;
};

TEST_F(ModbusIoPeer, ReadsInputsAndCoilsAndWritesACoilThePeerHolds) {
  auto io = start("server");
  EXPECT_EQ(io->describe(), "modbus 127.0.0.1:" + std::to_string(peer_->port()) + " unit 1");
  std::vector<bool> v;
  IoResult r = io->read_inputs(0, 8, v);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(v, (std::vector<bool>{true, false, true, true, false, false, true, false}));
  r = io->read_inputs(2, 2, v);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(v, (std::vector<bool>{true, true}));
  ASSERT_TRUE(io->read_coils(0, 3, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{true, false, true}));

  r = io->write_coil(1, true);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(peer_->ask("coil 1"), "coil 1 1");
  ASSERT_TRUE(io->write_coil(0, false).ok());
  EXPECT_EQ(peer_->ask("coil 0"), "coil 0 0");
  ASSERT_TRUE(io->read_coils(0, 3, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{false, true, true}));

  ASSERT_EQ(peer_->ask("input 5 1"), "ok");
  ASSERT_TRUE(io->read_inputs(5, 1, v).ok());
  EXPECT_EQ(v, std::vector<bool>{true});
}

TEST_F(ModbusIoPeer, EveryExceptionCodeIsReportedWithItsCodeAndTheUnitStaysOpen) {
  auto io = start("server");
  std::vector<bool> v{true};
  for (const int code : {1, 2, 3, 4}) {
    for (int call = 0; call < 3; ++call) {
      ASSERT_EQ(peer_->ask("exception " + std::to_string(code)), "ok");
      const IoResult r = call == 0   ? io->read_inputs(0, 4, v)
                         : call == 1 ? io->read_coils(0, 2, v)
                                     : io->write_coil(2, false);
      EXPECT_EQ(r.status, IoStatus::exception) << code << "/" << call << ": " << r.message;
      EXPECT_EQ(r.exception_code, code) << r.message;
      EXPECT_NE(r.message.find("exception " + std::to_string(code)), std::string::npos) << r.message;
      EXPECT_TRUE(io->is_open());
    }
  }
  EXPECT_EQ(v, std::vector<bool>{true}) << "values are left alone on a failure";
  ASSERT_TRUE(io->read_inputs(0, 1, v).ok()) << "the link is fine after exceptions";
  EXPECT_EQ(v, std::vector<bool>{true});
}

TEST_F(ModbusIoPeer, AnAddressThePeerDoesNotHaveIsIllegalDataAddress) {
  auto io = start("server");
  std::vector<bool> v;
  const IoResult r = io->read_inputs(14, 4, v);  // the peer has inputs 0..15
  EXPECT_EQ(r.status, IoStatus::exception);
  EXPECT_EQ(r.exception_code, 2);
  EXPECT_NE(r.message.find("read discrete inputs 14..17: exception 2 (illegal data address)"), std::string::npos)
      << r.message;
  EXPECT_EQ(io->write_coil(16, true).exception_code, 2);
}

TEST_F(ModbusIoPeer, ADroppedConnectionClosesTheUnitAndConnectReconnects) {
  auto io = start("server");
  std::vector<bool> v;
  ASSERT_EQ(peer_->ask("drop"), "ok");
  IoResult r = io->read_inputs(0, 2, v);
  EXPECT_EQ(r.status, IoStatus::disconnected) << r.message;
  EXPECT_FALSE(io->is_open());
  EXPECT_NE(r.message.find("closed"), std::string::npos) << r.message;

  ASSERT_EQ(peer_->ask("requests"), "requests 1");
  r = io->write_coil(0, true);
  EXPECT_EQ(r.status, IoStatus::disconnected);
  EXPECT_NE(r.message.find("not connected"), std::string::npos) << r.message;
  EXPECT_EQ(peer_->ask("requests"), "requests 1") << "a closed unit touches no network";

  r = io->connect();
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_TRUE(io->is_open());
  r = io->read_inputs(0, 2, v);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(v, (std::vector<bool>{true, false}));
  EXPECT_TRUE(io->connect().ok()) << "connect on an open unit is a no-op";
  EXPECT_EQ(peer_->ask("requests"), "requests 2");
}

TEST_F(ModbusIoPeer, AJunkAnswerIsAProtocolErrorAndClosesTheUnit) {
  auto io = start("junk");
  std::vector<bool> v{false};
  IoResult r = io->read_inputs(0, 4, v);
  EXPECT_EQ(r.status, IoStatus::protocol) << r.message;
  EXPECT_FALSE(io->is_open());
  EXPECT_EQ(v, std::vector<bool>{false});
  ASSERT_TRUE(io->connect().ok());
  r = io->write_coil(0, true);
  EXPECT_EQ(r.status, IoStatus::protocol) << r.message;
  EXPECT_NE(r.message.find("write coil 0 on: not a valid answer"), std::string::npos) << r.message;
}

TEST_F(ModbusIoPeer, AServerThatNeverAnswersTimesOutAndTheUnitStaysOpen) {
  auto io = start("silent", 0.2);
  std::vector<bool> v;
  for (int i = 0; i < 2; ++i) {
    const IoResult r = io->read_inputs(0, 4, v);
    EXPECT_EQ(r.status, IoStatus::timeout) << r.message;
    EXPECT_NE(r.message.find("no answer within 0.2 s"), std::string::npos) << r.message;
    EXPECT_TRUE(io->is_open());
  }
  EXPECT_EQ(io->write_coil(1, true).status, IoStatus::timeout);
}

TEST_F(ModbusIoPeer, ALateAnswerIsDiscardedAndTheNextRequestGetsItsOwn) {
  peer_ = std::make_unique<PythonPeer>(std::vector<std::string>{"late", "0.5"});
  ASSERT_GT(peer_->port(), 0) << peer_->first_line();
  ModbusIo io({"127.0.0.1", peer_->port(), 1}, {0.2});
  ASSERT_TRUE(io.connect().ok());
  std::vector<bool> v;
  EXPECT_EQ(io.read_coils(0, 4, v).status, IoStatus::timeout);
  ASSERT_EQ(peer_->line(), "late answer sent");  // it waits in our socket now
  const IoResult r = io.write_coil(3, true);
  EXPECT_TRUE(r.ok()) << "the late answer (to another request) was taken for this one: " << r.message;
  EXPECT_TRUE(io.is_open());
  ASSERT_TRUE(io.read_inputs(0, 4, v).ok());
  EXPECT_EQ(v, (std::vector<bool>{true, false, true, true}));
}

TEST(ModbusIo, NoServerIsDisconnectedAndEveryCallSaysNotConnected) {
  ModbusIo io({"127.0.0.1", unused_port(), 1});
  IoResult r = io.connect();
  EXPECT_EQ(r.status, IoStatus::disconnected);
  EXPECT_NE(r.message.find("connect: Connection refused"), std::string::npos) << r.message;
  EXPECT_FALSE(io.is_open());
  std::vector<bool> v;
  EXPECT_EQ(io.read_inputs(0, 1, v).status, IoStatus::disconnected);
  EXPECT_EQ(io.read_coils(0, 1, v).status, IoStatus::disconnected);
  EXPECT_EQ(io.write_coil(0, true).status, IoStatus::disconnected);
  io.close();  // works in every state
  EXPECT_FALSE(io.is_open());
}

TEST(ModbusIo, ARequestForNoValuesIsTheCallersBug) {
  ModbusIo io({"127.0.0.1", 502, 1});
  std::vector<bool> v;
  EXPECT_THROW(io.read_inputs(0, 0, v), InternalError);
  EXPECT_THROW(io.read_coils(65535, 2, v), InternalError);
}

}  // namespace
}  // namespace cellwright::drivers
