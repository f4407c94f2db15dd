#define ASIO_STANDALONE
#include "support/ws_viewer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>
#include <websocketpp/client.hpp>
#include <websocketpp/config/asio_no_tls_client.hpp>

namespace cellwright::testing {

using WsClient = websocketpp::client<websocketpp::config::asio_client>;
using namespace std::chrono_literals;

struct WsViewer::Impl {
  WsClient client;
  websocketpp::connection_hdl hdl;
  std::thread thread;
  mutable std::mutex mutex;
  std::condition_variable cv;
  bool open = false;
  std::vector<nlohmann::json> received;
  std::vector<std::string> binaries;
  std::string subprotocol;
};

WsViewer::WsViewer(std::uint16_t port) : WsViewer(port, "/ws", "") {}

WsViewer::WsViewer(std::uint16_t port, const std::string& path, const std::string& subprotocol)
    : impl_(std::make_unique<Impl>()) {
  Impl& i = *impl_;
  i.client.clear_access_channels(websocketpp::log::alevel::all);
  i.client.clear_error_channels(websocketpp::log::elevel::all);
  i.client.init_asio();
  i.client.set_open_handler([&i](websocketpp::connection_hdl h) {
    websocketpp::lib::error_code ec;
    const auto con = i.client.get_con_from_hdl(h, ec);
    std::lock_guard lock(i.mutex);
    if (!ec && con) i.subprotocol = con->get_response_header("Sec-WebSocket-Protocol");  // the server's choice
    i.open = true;
    i.cv.notify_all();
  });
  i.client.set_message_handler([&i](websocketpp::connection_hdl, WsClient::message_ptr m) {
    if (m->get_opcode() == websocketpp::frame::opcode::binary) {
      std::lock_guard lock(i.mutex);
      i.binaries.push_back(m->get_payload());
      i.cv.notify_all();
      return;
    }
    nlohmann::json j = nlohmann::json::parse(m->get_payload(), nullptr, false);
    std::lock_guard lock(i.mutex);
    i.received.push_back(std::move(j));
    i.cv.notify_all();
  });
  websocketpp::lib::error_code ec;
  auto con = i.client.get_connection("ws://127.0.0.1:" + std::to_string(port) + path, ec);
  EXPECT_FALSE(ec) << ec.message();
  if (ec) return;
  if (!subprotocol.empty()) con->add_subprotocol(subprotocol);
  i.hdl = con->get_handle();
  i.client.connect(con);
  i.thread = std::thread([&i] { i.client.run(); });
  std::unique_lock lock(i.mutex);
  EXPECT_TRUE(i.cv.wait_for(lock, 5s, [&i] { return i.open; })) << "the viewer could not connect to port " << port;
}

WsViewer::~WsViewer() { close(); }

std::string WsViewer::subprotocol() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->subprotocol;
}

bool WsViewer::connected() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->open;
}

void WsViewer::send(const std::string& text) {
  websocketpp::lib::error_code ec;
  impl_->client.send(impl_->hdl, text, websocketpp::frame::opcode::text, ec);
  EXPECT_FALSE(ec) << ec.message();
}

void WsViewer::send_binary(const std::string& bytes) {
  websocketpp::lib::error_code ec;
  impl_->client.send(impl_->hdl, bytes, websocketpp::frame::opcode::binary, ec);
  EXPECT_FALSE(ec) << ec.message();
}

void WsViewer::close() {
  Impl& i = *impl_;
  if (!i.thread.joinable()) return;
  websocketpp::lib::error_code ec;
  i.client.close(i.hdl, websocketpp::close::status::normal, "bye", ec);
  if (ec) i.client.stop();  // not open (any more): nothing to say goodbye on
  i.thread.join();
}

namespace {

// The message of `list` (guarded by `mutex`, told of by `cv`) that `match` accepts after the first `skip` it accepts,
// waiting up to 5 s for it; T() if none came.
template <class T, class Match>
T wait_in(std::mutex& mutex, std::condition_variable& cv, const std::vector<T>& list, const Match& match,
          std::size_t skip) {
  std::unique_lock lock(mutex);
  T found{};
  cv.wait_for(lock, 5s, [&] {
    std::size_t n = 0;
    for (const T& m : list) {
      if (match(m) && n++ == skip) {
        found = m;
        return true;
      }
    }
    return false;
  });
  return found;
}

}  // namespace

nlohmann::json WsViewer::wait_for(const std::function<bool(const nlohmann::json&)>& match, std::size_t skip) {
  return wait_in(impl_->mutex, impl_->cv, impl_->received, match, skip);
}

std::string WsViewer::wait_binary(const std::function<bool(const std::string&)>& match, std::size_t skip) {
  return wait_in(impl_->mutex, impl_->cv, impl_->binaries, match, skip);
}

nlohmann::json WsViewer::wait_for(const std::string& type, std::size_t skip) {
  return wait_for([&](const nlohmann::json& m) { return m.is_object() && m.value("type", "") == type; }, skip);
}

std::size_t WsViewer::count(const std::string& type) {
  return count([&](const nlohmann::json& m) { return m.is_object() && m.value("type", "") == type; });
}

std::size_t WsViewer::count(const std::function<bool(const nlohmann::json&)>& match) {
  std::lock_guard lock(impl_->mutex);
  return static_cast<std::size_t>(std::count_if(impl_->received.begin(), impl_->received.end(), match));
}

std::size_t WsViewer::count_binary(const std::function<bool(const std::string&)>& match) {
  std::lock_guard lock(impl_->mutex);
  return static_cast<std::size_t>(std::count_if(impl_->binaries.begin(), impl_->binaries.end(), match));
}

}  // namespace cellwright::testing
