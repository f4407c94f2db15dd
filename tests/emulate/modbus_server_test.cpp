// ModbusServer, our Modbus TCP server, against pymodbus's client (not our code: tests/data/modbus/peer.py) and raw
// sockets over loopback: every function, refused addresses and functions, the backend's failures, garbage and a
// request sent in pieces by one client while another keeps working, a client dropping, and the owner's mode that
// serves pending requests between its steps and counts them in the hook.
#include "cellwright/emulate/modbus_server.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "cellwright/drivers/memory_io.hpp"
#include "drivers/modbus/python_peer.hpp"

namespace cellwright::emulate {
namespace {

using drivers::IoStatus;
using drivers::MemoryIo;
using testing::PythonPeer;
using namespace std::chrono_literals;

// A raw TCP client: bytes in, bytes out, no Modbus of its own.
class RawClient {
 public:
  explicit RawClient(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~RawClient() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool connected() const { return connected_; }
  void send(const std::vector<std::uint8_t>& bytes) {
    ASSERT_EQ(::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL), static_cast<ssize_t>(bytes.size()));
  }
  // Reads until `n` bytes came, the peer closed, or 10 s passed.
  std::vector<std::uint8_t> receive(std::size_t n) {
    std::vector<std::uint8_t> got;
    const auto until = std::chrono::steady_clock::now() + 10s;
    while (got.size() < n && std::chrono::steady_clock::now() < until) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      std::uint8_t buf[512];
      const ssize_t k = ::recv(fd_, buf, std::min(sizeof buf, n - got.size()), 0);
      if (k <= 0) {
        closed_ = true;
        break;
      }
      got.insert(got.end(), buf, buf + k);
    }
    return got;
  }
  // True once the server has closed this connection (end of file within 10 s).
  bool closed_by_server() {
    receive(1 << 20);
    return closed_;
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
  bool closed_ = false;
};

// A Modbus TCP frame: transaction `tid`, unit 1, the PDU given.
std::vector<std::uint8_t> frame(int tid, std::vector<std::uint8_t> pdu, int unit = 1) {
  const std::size_t len = pdu.size() + 1;
  std::vector<std::uint8_t> f{static_cast<std::uint8_t>(tid >> 8), static_cast<std::uint8_t>(tid), 0, 0,
                              static_cast<std::uint8_t>(len >> 8), static_cast<std::uint8_t>(len),
                              static_cast<std::uint8_t>(unit)};
  f.insert(f.end(), pdu.begin(), pdu.end());
  return f;
}

class ModbusServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (const std::string why = testing::pymodbus_missing(); !why.empty()) GTEST_SKIP() << why;
    backend_.set_input(0, true);
    backend_.set_input(2, true);
    backend_.set_input(3, true);
    server_ = std::make_unique<ModbusServer>(backend_, ModbusServerOptions{});
  }
  // A pymodbus client connected to the server (running on its thread, unless the test serves it itself).
  std::unique_ptr<PythonPeer> client(int unit = 1) {
    auto c = std::make_unique<PythonPeer>(
        std::vector<std::string>{"client", std::to_string(server_->port()), std::to_string(unit)});
    return c;
  }
  MemoryIo backend_{8, 8, "backend"};
  std::unique_ptr<ModbusServer> server_;
};

TEST_F(ModbusServerTest, ServesEveryFunctionFromItsBackend) {
  server_->start();
  auto c = client();
  ASSERT_EQ(c->first_line(), "ready");
  EXPECT_EQ(c->ask("read_inputs 0 8"), "ok 1 0 1 1 0 0 0 0");
  EXPECT_EQ(c->ask("read_inputs 2 2"), "ok 1 1");
  EXPECT_EQ(c->ask("write_coil 3 1"), "ok");
  EXPECT_TRUE(backend_.coil(3));
  EXPECT_EQ(c->ask("write_coils 4 1,0,1"), "ok");
  EXPECT_TRUE(backend_.coil(4));
  EXPECT_FALSE(backend_.coil(5));
  EXPECT_TRUE(backend_.coil(6));
  EXPECT_EQ(c->ask("read_coils 0 8"), "ok 0 0 0 1 1 0 1 0");
  EXPECT_EQ(c->ask("write_coil 3 0"), "ok");
  EXPECT_FALSE(backend_.coil(3));
  EXPECT_EQ(server_->requests(), 6);
}

TEST_F(ModbusServerTest, AnAddressTheBackendLacksAndAnotherFunctionAreRefused) {
  server_->start();
  auto c = client();
  EXPECT_EQ(c->ask("read_inputs 6 4"), "exception 2");
  EXPECT_EQ(c->ask("read_coils 8 1"), "exception 2");
  EXPECT_EQ(c->ask("write_coil 9 1"), "exception 2");
  EXPECT_EQ(c->ask("write_coils 7 1,1"), "exception 2");
  EXPECT_TRUE(backend_.coil(7)) << "function 15 writes coil by coil and stops at the first refused";
  EXPECT_EQ(c->ask("read_holding 0 2"), "exception 1");
  EXPECT_EQ(c->ask("read_inputs 0 1"), "ok 1") << "the connection is fine after refusals";
}

TEST_F(ModbusServerTest, TheBackendsFailuresBecomeExceptionsAndItIsReconnected) {
  server_->start();
  auto c = client();
  backend_.fail_next(IoStatus::exception, 4);
  EXPECT_EQ(c->ask("read_inputs 0 1"), "exception 4");
  backend_.fail_next(IoStatus::timeout);
  EXPECT_EQ(c->ask("read_inputs 0 1"), "exception 11");
  backend_.fail_next(IoStatus::disconnected);
  EXPECT_EQ(c->ask("write_coil 0 1"), "exception 10");
  EXPECT_FALSE(backend_.is_open());
  EXPECT_EQ(c->ask("write_coil 0 1"), "ok") << "the server connects the backend again";
  EXPECT_TRUE(backend_.coil(0));
}

TEST_F(ModbusServerTest, ARequestToAnotherUnitIsRefusedWithoutReachingTheBackend) {
  server_->start();
  auto c = client(5);
  EXPECT_EQ(c->ask("write_coil 0 1"), "exception 11");
  EXPECT_FALSE(backend_.coil(0));
  EXPECT_EQ(backend_.requests(), 0);
}

TEST_F(ModbusServerTest, GarbageFromOneClientClosesOnlyItsConnection) {
  server_->start();
  auto good = client();
  EXPECT_EQ(good->ask("read_inputs 0 2"), "ok 1 0");
  RawClient junk(server_->port());
  ASSERT_TRUE(junk.connected());
  junk.send({'G', 'E', 'T', ' ', '/', ' ', 'H', 'T', 'T', 'P', '/', '1', '.', '0', '\r', '\n', '\r', '\n'});
  EXPECT_TRUE(junk.closed_by_server());
  EXPECT_EQ(good->ask("read_inputs 0 2"), "ok 1 0");
  EXPECT_EQ(good->ask("write_coil 1 1"), "ok");
}

TEST_F(ModbusServerTest, ARequestInPiecesWaitsForItsRestWhileAnotherClientIsServed) {
  server_->start();
  auto good = client();
  RawClient slow(server_->port());
  const std::vector<std::uint8_t> request = frame(0x1234, {0x02, 0x00, 0x00, 0x00, 0x04});  // read inputs 0..3
  slow.send({request.begin(), request.begin() + 4});
  EXPECT_EQ(good->ask("read_inputs 0 4"), "ok 1 0 1 1");
  EXPECT_EQ(good->ask("write_coil 2 1"), "ok");
  slow.send({request.begin() + 4, request.end()});
  EXPECT_EQ(slow.receive(10), (std::vector<std::uint8_t>{0x12, 0x34, 0, 0, 0, 4, 1, 0x02, 0x01, 0b1101}));
  // Two requests in one send are answered in order; a coil value other than on/off is an illegal value.
  std::vector<std::uint8_t> two = frame(1, {0x05, 0x00, 0x01, 0x12, 0x34});
  const std::vector<std::uint8_t> second = frame(2, {0x01, 0x00, 0x01, 0x00, 0x02});  // read coils 1..2
  two.insert(two.end(), second.begin(), second.end());
  slow.send(two);
  EXPECT_EQ(slow.receive(9 + 10), (std::vector<std::uint8_t>{0, 1, 0, 0, 0, 3, 1, 0x85, 3,  //
                                                              0, 2, 0, 0, 0, 4, 1, 0x01, 1, 0b10}));
}

TEST_F(ModbusServerTest, AClientThatDropsCostsTheOthersNothing) {
  server_->start();
  auto good = client();
  for (int i = 0; i < 3; ++i) {
    RawClient quitter(server_->port());
    quitter.send(frame(7, {0x02, 0x00, 0x00, 0x00, 0x08}));
    quitter.close();  // before its answer could be read
    EXPECT_EQ(good->ask("read_inputs 0 2"), "ok 1 0");
  }
  RawClient half(server_->port());
  half.send({0x00, 0x01, 0x00});
  half.close();
  EXPECT_EQ(good->ask("read_coils 0 2"), "ok 0 0");
}

TEST_F(ModbusServerTest, TheOwnerServesPendingRequestsBetweenItsStepsAndTheHookCountsThem) {
  std::vector<ServedRequest> served;
  server_->set_hook([&](const ServedRequest& s) { served.push_back(s); });
  EXPECT_EQ(server_->serve(), 0) << "nothing pending";
  auto c = client();
  // The owner's loop: a step of its own, then whatever the client asked meanwhile.
  const auto ask = [&](const std::string& command) {
    c->send(command);
    for (int steps = 0; steps < 400; ++steps) {
      if (std::string reply = c->line(0ms); !reply.empty()) return reply;
      server_->serve(50ms);
    }
    return std::string("no answer");
  };
  // The client connects while nobody serves: its connect completes in the kernel's backlog.
  ASSERT_EQ(c->first_line(), "ready");
  EXPECT_EQ(ask("read_inputs 1 3"), "ok 0 1 1");
  EXPECT_EQ(ask("write_coil 5 1"), "ok");
  EXPECT_EQ(ask("read_coils 9 1"), "exception 2");
  ASSERT_EQ(served.size(), 3u);
  EXPECT_EQ(served[0].client, 1);
  EXPECT_EQ(served[0].unit, 1);
  EXPECT_EQ(served[0].function, 2);
  EXPECT_EQ(served[0].address, 1);
  EXPECT_EQ(served[0].count, 3);
  EXPECT_EQ(served[0].exception_code, 0);
  EXPECT_EQ(served[1].function, 5);
  EXPECT_EQ(served[1].address, 5);
  EXPECT_EQ(served[1].count, 1);
  EXPECT_EQ(served[2].function, 1);
  EXPECT_EQ(served[2].exception_code, 2);
  EXPECT_EQ(server_->clients(), 1);
  EXPECT_EQ(server_->requests(), 3);
  EXPECT_TRUE(backend_.coil(5));
}

TEST(ModbusServer, APortInUseIsAnInputErrorNamingIt) {
  MemoryIo a(1, 1), b(1, 1);
  ModbusServer first(a, {});
  try {
    ModbusServerOptions o;
    o.port = first.port();
    ModbusServer second(b, o, {"--listen", 0, 0});
    ADD_FAILURE() << "two servers on one port";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1:" + std::to_string(first.port())),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace cellwright::emulate
