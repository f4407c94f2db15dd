// The live view's server over loopback: a test client (websocketpp's, on its own thread) connects, receives the cell
// and the frames, sends commands, and is refused garbage; two viewers; a viewer gone mid-run; the HTTP files.
#define ASIO_STANDALONE
#include "cellwright/serve/live_server.hpp"

#include <gtest/gtest.h>

#include <condition_variable>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>
#include <websocketpp/client.hpp>
#include <websocketpp/config/asio_no_tls_client.hpp>

#include "cellwright/common/error.hpp"

namespace cellwright::serve {
namespace {

using namespace std::chrono_literals;
using WsClient = websocketpp::client<websocketpp::config::asio_client>;

// One viewer: connects to ws://127.0.0.1:port/ws and keeps what it receives.
class Viewer {
 public:
  explicit Viewer(std::uint16_t port) {
    client_.clear_access_channels(websocketpp::log::alevel::all);
    client_.clear_error_channels(websocketpp::log::elevel::all);
    client_.init_asio();
    client_.set_open_handler([this](websocketpp::connection_hdl) {
      std::lock_guard lock(mutex_);
      open_ = true;
      cv_.notify_all();
    });
    client_.set_message_handler([this](websocketpp::connection_hdl, WsClient::message_ptr m) {
      std::lock_guard lock(mutex_);
      received_.push_back(nlohmann::json::parse(m->get_payload()));
      cv_.notify_all();
    });
    websocketpp::lib::error_code ec;
    auto con = client_.get_connection("ws://127.0.0.1:" + std::to_string(port) + "/ws", ec);
    EXPECT_FALSE(ec) << ec.message();
    hdl_ = con->get_handle();
    client_.connect(con);
    thread_ = std::thread([this] { client_.run(); });
    std::unique_lock lock(mutex_);
    EXPECT_TRUE(cv_.wait_for(lock, 5s, [this] { return open_; })) << "the viewer could not connect";
  }
  ~Viewer() { close(); }

  void send(const std::string& text, websocketpp::frame::opcode::value op = websocketpp::frame::opcode::text) {
    client_.send(hdl_, text, op);
  }
  void close() {
    if (thread_.joinable()) {
      websocketpp::lib::error_code ec;
      client_.close(hdl_, websocketpp::close::status::normal, "bye", ec);
      thread_.join();
    }
  }
  // Waits until a message of `type` beyond the first `skip` of that type has come; returns it (null JSON if none in
  // 5 s).
  nlohmann::json wait_for(const std::string& type, std::size_t skip = 0) {
    std::unique_lock lock(mutex_);
    nlohmann::json found;
    cv_.wait_for(lock, 5s, [&] {
      std::size_t n = 0;
      for (const auto& m : received_) {
        if (m["type"] == type && n++ == skip) {
          found = m;
          return true;
        }
      }
      return false;
    });
    return found;
  }
  std::size_t count(const std::string& type) {
    std::lock_guard lock(mutex_);
    std::size_t n = 0;
    for (const auto& m : received_) n += m["type"] == type ? 1 : 0;
    return n;
  }

 private:
  WsClient client_;
  websocketpp::connection_hdl hdl_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = false;
  std::vector<nlohmann::json> received_;
};

// Waits until the server counts `n` viewers (a closed connection is noticed on the server's thread).
bool wait_viewers(const LiveServer& server, std::size_t n) {
  for (int i = 0; i < 500; ++i) {
    if (server.viewers() == n) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

ServerOptions loopback_any_port() {
  ServerOptions o;
  o.port = 0;
  return o;
}

TEST(ParseCommand, AcceptsTheFourCommands) {
  EXPECT_EQ(std::get<CommandKind>(parse_command(R"({"type":"command","command":"play"})")), CommandKind::kPlay);
  EXPECT_EQ(std::get<CommandKind>(parse_command(R"({"type":"command","command":"pause"})")), CommandKind::kPause);
  EXPECT_EQ(std::get<CommandKind>(parse_command(R"({"command":"step","type":"command"})")), CommandKind::kStep);
  EXPECT_EQ(std::get<CommandKind>(parse_command(R"({"type":"command","command":"restart"})")), CommandKind::kRestart);
}

TEST(ParseCommand, RefusesWithAReason) {
  auto reason = [](std::string_view t) { return std::get<Refusal>(parse_command(t)).reason; };
  EXPECT_EQ(reason("{not json"), "not JSON");
  EXPECT_EQ(reason("[1,2]"), "not a JSON object");
  EXPECT_EQ(reason(R"({"command":"play"})"), "no \"type\" (a string)");
  EXPECT_EQ(reason(R"({"type":"jog"})"), "unknown type 'jog' (a viewer sends \"command\")");
  EXPECT_EQ(reason(R"({"type":"command"})"), "a command needs \"command\" (a string)");
  EXPECT_EQ(reason(R"({"type":"command","command":"fly"})"), "unknown command 'fly' (play, pause, step or restart)");
  EXPECT_NE(reason(std::string(kMaxMessageBytes + 1, ' ')).find("more than"), std::string::npos);
}

TEST(FramePacer, LetsThroughAtMostTheRate) {
  FramePacer pacer(30);
  const auto t0 = std::chrono::steady_clock::time_point() + 1h;
  EXPECT_TRUE(pacer.due(t0));
  EXPECT_FALSE(pacer.due(t0 + 10ms));
  EXPECT_FALSE(pacer.due(t0 + 33ms));
  EXPECT_TRUE(pacer.due(t0 + 34ms));
  EXPECT_FALSE(pacer.due(t0 + 50ms));
}

TEST(LiveServer, AViewerGetsTheCellThenFramesAndItsCommandsArrive) {
  LiveServer server(loopback_any_port());
  ASSERT_NE(server.port(), 0);
  server.set_cell(R"({"type":"cell","name":"demo"})");
  Viewer v(server.port());
  EXPECT_EQ(v.wait_for("cell")["name"], "demo");
  ASSERT_TRUE(wait_viewers(server, 1));
  server.publish(R"({"type":"frame","t":0.5})");
  EXPECT_EQ(v.wait_for("frame")["t"], 0.5);

  v.send(R"({"type":"command","command":"step"})");
  v.send(R"({"type":"command","command":"pause"})");
  EXPECT_EQ(server.wait_command(5s), CommandKind::kStep);
  EXPECT_EQ(server.wait_command(5s), CommandKind::kPause);
  EXPECT_EQ(server.poll_command(), std::nullopt);
}

TEST(LiveServer, GarbageIsRefusedAndTheConnectionStays) {
  LiveServer server(loopback_any_port());
  Viewer v(server.port());
  v.send("hello");
  EXPECT_EQ(v.wait_for("error")["reason"], "not JSON");
  v.send(R"({"type":"command","command":"fly"})");
  EXPECT_EQ(v.wait_for("error", 1)["reason"], "unknown command 'fly' (play, pause, step or restart)");
  v.send("\x01\x02", websocketpp::frame::opcode::binary);
  EXPECT_EQ(v.wait_for("error", 2)["reason"], "a binary message (commands are JSON text)");
  EXPECT_EQ(server.counts().refused, 3u);
  // Still connected: a good command after the bad ones arrives, and nothing refused was taken as a command.
  v.send(R"({"type":"command","command":"play"})");
  EXPECT_EQ(server.wait_command(5s), CommandKind::kPlay);
  EXPECT_EQ(server.poll_command(), std::nullopt);
}

TEST(LiveServer, TwoViewersBothGetEveryFrameAndOneLeavingCostsTheOtherNothing) {
  LiveServer server(loopback_any_port());
  server.set_cell(R"({"type":"cell","name":"two"})");
  Viewer a(server.port());
  Viewer b(server.port());
  ASSERT_TRUE(wait_viewers(server, 2));
  EXPECT_EQ(a.wait_for("cell")["name"], "two");
  EXPECT_EQ(b.wait_for("cell")["name"], "two");
  server.publish(R"({"type":"frame","n":1})");
  EXPECT_EQ(a.wait_for("frame")["n"], 1);
  EXPECT_EQ(b.wait_for("frame")["n"], 1);

  a.close();  // mid-run
  ASSERT_TRUE(wait_viewers(server, 1));
  for (int n = 2; n <= 20; ++n) server.publish(fmt::format(R"({{"type":"frame","n":{}}})", n));
  EXPECT_EQ(b.wait_for("frame", 19)["n"], 20);
  EXPECT_EQ(a.count("frame"), 1u);
  EXPECT_EQ(server.counts().dropped, 0u);
  // A restart's new cell reaches the viewer still there.
  server.set_cell(R"({"type":"cell","name":"again"})");
  EXPECT_EQ(b.wait_for("cell", 1)["name"], "again");
}

TEST(LiveServer, FramesToAViewerThatDoesNotReadAreDroppedNotQueued) {
  ServerOptions o = loopback_any_port();
  o.max_buffered = 64 * 1024;
  LiveServer server(o);
  // A raw TCP client that does the WebSocket handshake and then never reads: its socket fills up.
  asio::io_context io;
  asio::ip::tcp::socket sock(io);
  sock.connect({asio::ip::make_address("127.0.0.1"), server.port()});
  const std::string hello =
      "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  asio::write(sock, asio::buffer(hello));
  ASSERT_TRUE(wait_viewers(server, 1));
  const std::string frame = R"({"type":"frame","pad":")" + std::string(16 * 1024, 'x') + "\"}";
  // 64 MB offered: far more than the socket buffers of both ends hold; publish never waits for the viewer.
  for (int i = 0; i < 4096; ++i) server.publish(frame);
  const LiveServer::Counts c = server.counts();
  EXPECT_GT(c.dropped, 0u);
  EXPECT_EQ(c.sent + c.dropped, 4096u);
}

TEST(LiveServer, ServesThePageAndTheModelsAndNothingElse) {
  const auto dir = std::filesystem::temp_directory_path() / ("cw-serve-test-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "www");
  std::filesystem::create_directories(dir / "models" / "puma");
  std::ofstream(dir / "www" / "index.html") << "<html>live</html>";
  std::ofstream(dir / "models" / "puma" / "puma.urdf") << "<robot name='puma'/>";
  std::ofstream(dir / "secret.txt") << "no";
  ServerOptions o = loopback_any_port();
  o.www = dir / "www";
  o.models = dir / "models";
  LiveServer server(o);
  auto get = [&](const std::string& path) {
    asio::io_context io;
    asio::ip::tcp::socket sock(io);
    sock.connect({asio::ip::make_address("127.0.0.1"), server.port()});
    asio::write(sock, asio::buffer("GET " + path + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"));
    std::string reply;
    asio::error_code ec;
    char buf[4096];
    for (;;) {
      const std::size_t n = sock.read_some(asio::buffer(buf), ec);
      reply.append(buf, n);
      if (ec) break;
    }
    return reply;
  };
  const std::string index = get("/");
  EXPECT_NE(index.find("200"), std::string::npos) << index;
  EXPECT_NE(index.find("<html>live</html>"), std::string::npos);
  EXPECT_NE(get("/models/puma/puma.urdf").find("<robot name='puma'/>"), std::string::npos);
  EXPECT_NE(get("/../secret.txt").find("404"), std::string::npos);
  EXPECT_NE(get("/models/../../secret.txt").find("404"), std::string::npos);
  EXPECT_NE(get("/nothing.js").find("404"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(LiveServer, AnAddressThatIsNotOneIsAnInputError) {
  ServerOptions o = loopback_any_port();
  o.bind = "not-an-address";
  EXPECT_THROW(LiveServer{o}, InputError);
}

}  // namespace
}  // namespace cellwright::serve
