// The live view's server over loopback: a test client (support/ws_viewer.hpp) connects, receives the cell
// and the frames, sends commands, and is refused garbage; two viewers; a viewer gone mid-run; the HTTP files.
#define ASIO_STANDALONE
#include "cellwright/serve/live_server.hpp"

#include <gtest/gtest.h>

#include <asio.hpp>
#include <fmt/format.h>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "cellwright/common/error.hpp"
#include "support/ws_viewer.hpp"

namespace cellwright::serve {
namespace {

using namespace std::chrono_literals;
using Viewer = cellwright::testing::WsViewer;

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

std::optional<CommandKind> command_of(const Parsed& p) { return std::get<Message>(p).command; }

TEST(ParseMessage, AcceptsTheCommands) {
  EXPECT_EQ(command_of(parse_message(R"({"type":"command","command":"play"})")), CommandKind::kPlay);
  EXPECT_EQ(command_of(parse_message(R"({"type":"command","command":"pause"})")), CommandKind::kPause);
  EXPECT_EQ(command_of(parse_message(R"({"command":"step","type":"command"})")), CommandKind::kStep);
  EXPECT_EQ(command_of(parse_message(R"({"type":"command","command":"restart"})")), CommandKind::kRestart);
  EXPECT_EQ(command_of(parse_message(R"({"type":"command","command":"run_to","line":3})")), CommandKind::kRunTo);
  EXPECT_EQ(command_of(parse_message(R"({"type":"command","command":"replay"})")), CommandKind::kReplay);
}

TEST(ParseMessage, TakesTeachSaveAndCheckWithTheirText) {
  const std::string teach = R"({"type":"teach","robot":"puma","action":"begin"})";
  const Message m = std::get<Message>(parse_message(teach));
  EXPECT_EQ(m.type, "teach");
  EXPECT_EQ(m.command, std::nullopt);
  EXPECT_EQ(m.text, teach);
  EXPECT_EQ(std::get<Message>(parse_message(R"({"type":"save_location","robot":"puma","name":"x"})")).type,
            "save_location");
  EXPECT_EQ(std::get<Message>(parse_message(R"({"type":"check"})")).type, "check");
}

TEST(ParseMessage, RefusesWithAReason) {
  auto reason = [](std::string_view t) { return std::get<Refusal>(parse_message(t)).reason; };
  EXPECT_EQ(reason("{not json"), "not JSON");
  EXPECT_EQ(reason("[1,2]"), "not a JSON object");
  EXPECT_EQ(reason(R"({"command":"play"})"), "no \"type\" (a string)");
  EXPECT_EQ(reason(R"({"type":"jog"})"),
            "unknown type 'jog' (a viewer sends \"command\", \"teach\", \"save_location\" or \"check\")");
  EXPECT_EQ(reason(R"({"type":"command"})"), "a command needs \"command\" (a string)");
  EXPECT_EQ(reason(R"({"type":"command","command":"fly"})"),
            "unknown command 'fly' (play, pause, step, restart, run_to or replay)");
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
  const std::optional<Message> step = server.wait_message(5s);
  ASSERT_TRUE(step.has_value());
  EXPECT_EQ(step->command, CommandKind::kStep);
  EXPECT_EQ(server.wait_message(5s)->command, CommandKind::kPause);
  EXPECT_FALSE(server.poll_message().has_value());
  // Answers go to the sender alone; broadcasts to every viewer.
  Viewer other(server.port());
  ASSERT_TRUE(wait_viewers(server, 2));
  server.send_to(step->viewer, R"({"type":"error","reason":"yours"})");
  server.broadcast(R"({"type":"saved","name":"all"})");
  EXPECT_EQ(v.wait_for("error")["reason"], "yours");
  EXPECT_EQ(v.wait_for("saved")["name"], "all");
  EXPECT_EQ(other.wait_for("saved")["name"], "all");
  EXPECT_EQ(other.count("error"), 0u);
}

TEST(LiveServer, GarbageIsRefusedAndTheConnectionStays) {
  LiveServer server(loopback_any_port());
  Viewer v(server.port());
  v.send("hello");
  EXPECT_EQ(v.wait_for("error")["reason"], "not JSON");
  v.send(R"({"type":"command","command":"fly"})");
  EXPECT_EQ(v.wait_for("error", 1)["reason"], "unknown command 'fly' (play, pause, step, restart, run_to or replay)");
  v.send_binary("\x01\x02");
  EXPECT_EQ(v.wait_for("error", 2)["reason"], "a binary message (messages are JSON text)");
  EXPECT_EQ(server.counts().refused, 3u);
  // Still connected: a good command after the bad ones arrives, and nothing refused was taken as a command.
  v.send(R"({"type":"command","command":"play"})");
  EXPECT_EQ(server.wait_message(5s)->command, CommandKind::kPlay);
  EXPECT_FALSE(server.poll_message().has_value());
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
  // A greeting goes to each viewer that connects after it is set, right after the cell; not to those there already.
  server.set_greeting({R"({"type":"check","ok":false})"});
  Viewer c(server.port());
  ASSERT_TRUE(c.wait_for("check").is_object());
  EXPECT_EQ(c.count("cell"), 1u);
  EXPECT_EQ(b.count("check"), 0u);
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
