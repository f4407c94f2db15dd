// The live view's run loop (cell/live/live.hpp serve_scenario) served on a free loopback port on a thread of its own,
// for tests that drive it with test viewers (support/ws_viewer.hpp); stopped and joined at the end of the test.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <thread>

#include "cellwright/cell/live/live.hpp"
#include "cellwright/cell/live/replay.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "support/ws_viewer.hpp"

namespace cellwright::cell::live_testing {

using nlohmann::json;
using cellwright::testing::WsViewer;

inline const std::string kExchange = std::string(CW_SOURCE_DIR) + "/scenes/exchange.yaml";

inline bool is_frame(const json& m) { return m.is_object() && m.value("type", "") == "frame"; }

class LiveLoop : public ::testing::Test {
 protected:
  // Serves `scenario` (which must pass the preflight, or fail only its program's check: then it is served as the
  // counterexample's replay, as `twin serve` does), built with `run_options` (lock-step unless they say realtime).
  void start(ServeOptions options = {}, std::size_t max_buffered = 256 * 1024, const std::string& scenario = kExchange,
             RunOptions run_options = {}) {
    scenario_ = std::make_unique<Scenario>(load_scenario(scenario));
    preflight_ = std::make_unique<Preflight>(preflight(*scenario_, &twin_port()));
    if (std::optional<Preflight> replay = counterexample_preflight(*scenario_, *preflight_)) {
      *preflight_ = std::move(*replay);
    } else {
      ASSERT_TRUE(preflight_->ok()) << preflight_->problems.front();
    }
    serve::ServerOptions so;
    so.port = 0;
    so.max_buffered = max_buffered;
    server_ = std::make_unique<serve::LiveServer>(so);
    loop_ = std::thread([this, options, run_options] {
      runs_ = serve_scenario(*scenario_, *preflight_, run_options, *server_, options, stop_);
    });
  }
  void TearDown() override {
    stop_ = true;
    if (loop_.joinable()) loop_.join();
  }
  std::uint16_t port() const { return server_->port(); }
  serve::LiveServer& server() { return *server_; }
  static std::string command(const std::string& c) { return R"({"type":"command","command":")" + c + "\"}"; }

  std::unique_ptr<Scenario> scenario_;
  std::unique_ptr<Preflight> preflight_;
  std::unique_ptr<serve::LiveServer> server_;
  std::atomic<bool> stop_{false};
  std::thread loop_;
  int runs_ = 0;
};

// One run of the exchange scenario, built and not started, for the tests that read its messages.
class ExchangeRun : public ::testing::Test {
 protected:
  void SetUp() override {
    scenario_ = std::make_unique<Scenario>(load_scenario(kExchange));
    preflight_ = std::make_unique<Preflight>(preflight(*scenario_, &twin_port()));
    ASSERT_TRUE(preflight_->ok()) << preflight_->problems.front();
    run_ = std::make_unique<ScenarioRun>(*scenario_, *preflight_, RunOptions{});
  }
  std::unique_ptr<Scenario> scenario_;
  std::unique_ptr<Preflight> preflight_;
  std::unique_ptr<ScenarioRun> run_;
};

}  // namespace cellwright::cell::live_testing
