#define ASIO_STANDALONE
#include "support/cdp_client.hpp"

#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>
#include <websocketpp/client.hpp>
#include <websocketpp/config/asio_no_tls_client.hpp>

namespace cellwright::testing {

using WsClient = websocketpp::client<websocketpp::config::asio_client>;
using nlohmann::json;

struct CdpClient::Impl {
  WsClient client;
  websocketpp::connection_hdl hdl;
  std::thread thread;
  mutable std::mutex mutex;
  std::condition_variable cv;
  bool open = false;
  int next_id = 1;
  std::map<int, json> answers;
};

CdpClient::CdpClient(const std::string& ws_url) : impl_(std::make_unique<Impl>()) {
  Impl& i = *impl_;
  i.client.clear_access_channels(websocketpp::log::alevel::all);
  i.client.clear_error_channels(websocketpp::log::elevel::all);
  i.client.init_asio();
  // Screenshots come back base64 in one message: far more than websocketpp's default 32 MB is never needed, but
  // more than a small limit is.
  i.client.set_max_message_size(64 * 1024 * 1024);
  i.client.set_open_handler([&i](websocketpp::connection_hdl) {
    std::lock_guard lock(i.mutex);
    i.open = true;
    i.cv.notify_all();
  });
  i.client.set_message_handler([&i](websocketpp::connection_hdl, WsClient::message_ptr m) {
    json j = json::parse(m->get_payload(), nullptr, false);
    if (!j.is_object() || !j.contains("id") || !j["id"].is_number_integer()) return;  // an event
    const int id = j["id"].get<int>();
    std::lock_guard lock(i.mutex);
    i.answers[id] = std::move(j);
    i.cv.notify_all();
  });
  websocketpp::lib::error_code ec;
  auto con = i.client.get_connection(ws_url, ec);
  if (ec) return;
  i.hdl = con->get_handle();
  i.client.connect(con);
  i.thread = std::thread([&i] { i.client.run(); });
  std::unique_lock lock(i.mutex);
  i.cv.wait_for(lock, std::chrono::seconds(5), [&i] { return i.open; });
}

CdpClient::~CdpClient() {
  Impl& i = *impl_;
  if (!i.thread.joinable()) return;
  websocketpp::lib::error_code ec;
  i.client.close(i.hdl, websocketpp::close::status::normal, "bye", ec);
  if (ec) i.client.stop();
  i.thread.join();
}

bool CdpClient::connected() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->open;
}

json CdpClient::call(const std::string& method, const json& params, const std::string& session,
                     std::chrono::milliseconds timeout) {
  Impl& i = *impl_;
  int id = 0;
  {
    std::lock_guard lock(i.mutex);
    if (!i.open) return json{{"error", {{"message", "not connected"}}}};
    id = i.next_id++;
  }
  json msg = {{"id", id}, {"method", method}, {"params", params}};
  if (!session.empty()) msg["sessionId"] = session;
  websocketpp::lib::error_code ec;
  i.client.send(i.hdl, msg.dump(), websocketpp::frame::opcode::text, ec);
  if (ec) return json{{"error", {{"message", ec.message()}}}};
  std::unique_lock lock(i.mutex);
  if (!i.cv.wait_for(lock, timeout, [&] { return i.answers.count(id) > 0; })) {
    return json{{"error", {{"message", "timeout: no answer to " + method}}}};
  }
  json answer = std::move(i.answers[id]);
  i.answers.erase(id);
  if (answer.contains("error")) return json{{"error", answer["error"]}};
  return answer.value("result", json::object());
}

}  // namespace cellwright::testing
