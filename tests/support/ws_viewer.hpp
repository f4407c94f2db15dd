// A live-view viewer for tests (docs/live-view.md): a WebSocket client (websocketpp's, on a thread of its own) that
// connects to ws://127.0.0.1:PORT/ws (or another path, asking for a subprotocol: a Foxglove client), keeps every
// JSON text message and every binary message it receives, and sends texts or binary frames. Its
// websocketpp code stays in ws_viewer.cpp (built as C++17, as serve/ is), so C++20 suites can use it.
//
// Threads: the client's thread receives; every member may be called from the test's thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

namespace cellwright::testing {

class WsViewer {
 public:
  // Connects; a failed test expectation (not an exception) when it cannot within 5 s: connected() says.
  explicit WsViewer(std::uint16_t port);
  // At `path`, asking for `subprotocol` (none when empty).
  WsViewer(std::uint16_t port, const std::string& path, const std::string& subprotocol);
  ~WsViewer();
  WsViewer(const WsViewer&) = delete;
  WsViewer& operator=(const WsViewer&) = delete;

  bool connected() const;
  // The subprotocol the server selected (empty: none).
  std::string subprotocol() const;
  void send(const std::string& text);
  void send_binary(const std::string& bytes);
  // Closes the connection (the server sees the viewer leave) and joins the client's thread. Idempotent.
  void close();

  // The message received (in order) that `match` accepts after the first `skip` it accepts, waiting up to 5 s for it;
  // null JSON if none came.
  nlohmann::json wait_for(const std::function<bool(const nlohmann::json&)>& match, std::size_t skip = 0);
  // The message of `type` after the first `skip` of that type, waiting up to 5 s; null JSON if none came.
  nlohmann::json wait_for(const std::string& type, std::size_t skip = 0);
  // How many messages of `type`, or that `match` accepts, have come so far.
  std::size_t count(const std::string& type);
  std::size_t count(const std::function<bool(const nlohmann::json&)>& match);
  // The binary message (its bytes) that `match` accepts after the first `skip` it accepts, waiting up to 5 s; empty
  // if none came. And how many binary messages `match` accepts so far.
  std::string wait_binary(const std::function<bool(const std::string&)>& match, std::size_t skip = 0);
  std::size_t count_binary(const std::function<bool(const std::string&)>& match);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::testing
