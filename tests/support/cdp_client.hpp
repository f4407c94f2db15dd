// A Chrome DevTools Protocol client for tests (the browser test of the live view, tests/browser): one WebSocket to a
// browser's DevTools endpoint (websocketpp's client on a thread of its own), commands sent as {"id","method","params"}
// (and "sessionId" for a page attached with Target.attachToTarget, flatten), each answer matched by its id. Events are
// ignored. Its websocketpp code stays in cdp_client.cpp (built as C++17, as serve/ is).
//
// Threads: the client's thread receives; every member may be called from the test's thread.
#pragma once

#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

namespace cellwright::testing {

class CdpClient {
 public:
  // Connects to `ws_url` (ws://127.0.0.1:PORT/devtools/browser/ID); connected() says whether it could within 5 s.
  explicit CdpClient(const std::string& ws_url);
  ~CdpClient();
  CdpClient(const CdpClient&) = delete;
  CdpClient& operator=(const CdpClient&) = delete;

  bool connected() const;
  // Sends the command and waits up to `timeout` for its answer: the answer's "result", or an object with "error" (the
  // browser's error, or {"message":"timeout"}).
  nlohmann::json call(const std::string& method, const nlohmann::json& params = nlohmann::json::object(),
                      const std::string& session = "", std::chrono::milliseconds timeout = std::chrono::seconds(10));

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::testing
