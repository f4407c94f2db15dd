// The live view's server: websocketpp on standalone asio (docs/live-view.md says why these).
#define ASIO_STANDALONE
#include "cellwright/serve/live_server.hpp"

#include <fmt/format.h>

#include <condition_variable>
#include <fstream>
#include <nlohmann/json.hpp>
#include <map>
#include <set>
#include <sstream>
#include <thread>
#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

#include "cellwright/common/error.hpp"

namespace cellwright::serve {

const char* to_string(CommandKind kind) {
  switch (kind) {
    case CommandKind::kPlay: return "play";
    case CommandKind::kPause: return "pause";
    case CommandKind::kStep: return "step";
    case CommandKind::kRestart: return "restart";
    case CommandKind::kRunTo: return "run_to";
    case CommandKind::kReplay: return "replay";
  }
  return "?";
}

Parsed parse_message(std::string_view text) {
  if (text.size() > kMaxMessageBytes) {
    return Refusal{fmt::format("message of {} bytes, more than the {} a message may have", text.size(), kMaxMessageBytes)};
  }
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Refusal{"not JSON"};
  if (!j.is_object()) return Refusal{"not a JSON object"};
  const auto type = j.find("type");
  if (type == j.end() || !type->is_string()) return Refusal{"no \"type\" (a string)"};
  Message m;
  m.type = type->get<std::string>();
  m.text = std::string(text);
  if (m.type == "teach" || m.type == "save_location" || m.type == "check") return m;
  if (m.type != "command") {
    return Refusal{fmt::format("unknown type '{}' (a viewer sends \"command\", \"teach\", \"save_location\" or "
                               "\"check\")",
                               m.type)};
  }
  const auto cmd = j.find("command");
  if (cmd == j.end() || !cmd->is_string()) return Refusal{"a command needs \"command\" (a string)"};
  const std::string c = cmd->get<std::string>();
  for (CommandKind k : {CommandKind::kPlay, CommandKind::kPause, CommandKind::kStep, CommandKind::kRestart,
                        CommandKind::kRunTo, CommandKind::kReplay}) {
    if (c == to_string(k)) {
      m.command = k;
      return m;
    }
  }
  return Refusal{fmt::format("unknown command '{}' (play, pause, step, restart, run_to or replay)", c)};
}

FramePacer::FramePacer(double hz)
    : period_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(1.0 / hz))) {}

bool FramePacer::due(std::chrono::steady_clock::time_point now) {
  if (last_ && now - *last_ < period_) return false;
  last_ = now;
  return true;
}

namespace {

using WsServer = websocketpp::server<websocketpp::config::asio>;
using Handle = websocketpp::connection_hdl;

const char* content_type(const std::filesystem::path& p) {
  const std::string ext = p.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json") return "application/json";
  if (ext == ".urdf" || ext == ".xml") return "application/xml";
  if (ext == ".png") return "image/png";
  return "application/octet-stream";  // meshes (STL, DAE, OBJ) and the rest
}

// The file under `root` that `rel` (a URL path without its leading '/') names, or empty if it names none: no "..",
// no absolute path, a regular file.
std::filesystem::path file_under(const std::filesystem::path& root, std::string_view rel) {
  if (root.empty() || rel.empty()) return {};
  const std::filesystem::path p(rel);
  for (const auto& part : p) {
    if (part == ".." || part == ".") return {};
  }
  if (p.is_absolute()) return {};
  std::filesystem::path f = root / p;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(f, ec)) return {};
  return f;
}

}  // namespace

struct LiveServer::Impl {
  ServerOptions options;
  WsServer ws;
  std::thread thread;
  std::uint16_t port = 0;

  mutable std::mutex mutex;  // guards what follows
  std::set<Handle, std::owner_less<Handle>> viewers;
  std::map<Handle, std::uint64_t, std::owner_less<Handle>> ids;  // each viewer's number (Message::viewer)
  std::map<std::uint64_t, Handle> by_id;
  std::uint64_t next_id = 1;
  std::string cell;
  std::vector<std::string> greeting;
  std::deque<Message> commands;
  std::condition_variable command_ready;
  Counts counts;

  void send_text(Handle h, const std::string& text) {
    websocketpp::lib::error_code ec;
    ws.send(h, text, websocketpp::frame::opcode::text, ec);  // a viewer gone meanwhile: nothing to do
  }

  void on_http(Handle h) {
    WsServer::connection_ptr con = ws.get_con_from_hdl(h);
    std::string path = con->get_resource();
    if (const auto q = path.find('?'); q != std::string::npos) path.resize(q);
    std::filesystem::path file;
    if (path == "/" || path == "/index.html") {
      file = file_under(options.www, "index.html");
    } else if (path.rfind("/models/", 0) == 0) {
      file = file_under(options.models, std::string_view(path).substr(8));
    } else if (path.size() > 1) {
      file = file_under(options.www, std::string_view(path).substr(1));
    }
    std::ifstream in(file, std::ios::binary);
    if (file.empty() || !in) {
      con->set_status(websocketpp::http::status_code::not_found);
      con->set_body(fmt::format("not found: {}\n", path));
      return;
    }
    std::ostringstream body;
    body << in.rdbuf();
    con->set_status(websocketpp::http::status_code::ok);
    con->append_header("Content-Type", content_type(file));
    con->append_header("Cache-Control", "no-store");
    con->set_body(body.str());
  }

  void on_open(Handle h) {
    std::string c;
    std::vector<std::string> after;
    {
      std::lock_guard lock(mutex);
      viewers.insert(h);
      const std::uint64_t id = next_id++;
      ids[h] = id;
      by_id[id] = h;
      c = cell;
      after = greeting;
    }
    if (!c.empty()) send_text(h, c);
    for (const std::string& m : after) send_text(h, m);
  }

  void on_close(Handle h) {
    std::lock_guard lock(mutex);
    viewers.erase(h);
    if (const auto it = ids.find(h); it != ids.end()) {
      by_id.erase(it->second);
      ids.erase(it);
    }
  }

  void on_message(Handle h, const WsServer::message_ptr& msg) {
    Parsed parsed = msg->get_opcode() == websocketpp::frame::opcode::text
                        ? parse_message(msg->get_payload())
                        : Parsed(Refusal{"a binary message (messages are JSON text)"});
    if (const auto* r = std::get_if<Refusal>(&parsed)) {
      {
        std::lock_guard lock(mutex);
        ++counts.refused;
      }
      send_text(h, nlohmann::json{{"type", "error"}, {"reason", r->reason}}.dump());
      return;
    }
    {
      std::lock_guard lock(mutex);
      Message& m = std::get<Message>(parsed);
      const auto it = ids.find(h);
      m.viewer = it == ids.end() ? 0 : it->second;
      commands.push_back(std::move(m));
    }
    command_ready.notify_all();
  }
};

LiveServer::LiveServer(ServerOptions options) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.options = std::move(options);
  const std::string where = fmt::format("{}:{}", im.options.bind, im.options.port);
  im.ws.clear_access_channels(websocketpp::log::alevel::all);
  im.ws.clear_error_channels(websocketpp::log::elevel::all);
  im.ws.set_max_message_size(kMaxMessageBytes + 1);  // a longer message closes that connection (1009)
  websocketpp::lib::error_code ec;
  im.ws.init_asio(ec);
  if (ec) throw InputError({where, 0, 0}, fmt::format("cannot start the server: {}", ec.message()));
  im.ws.set_reuse_addr(true);
  im.ws.set_http_handler([&im](Handle h) { im.on_http(h); });
  im.ws.set_open_handler([&im](Handle h) { im.on_open(h); });
  im.ws.set_close_handler([&im](Handle h) { im.on_close(h); });
  im.ws.set_fail_handler([&im](Handle h) { im.on_close(h); });
  im.ws.set_message_handler([&im](Handle h, WsServer::message_ptr m) { im.on_message(h, m); });
  asio::error_code aec;
  const asio::ip::address addr = asio::ip::make_address(im.options.bind, aec);
  if (aec) throw InputError({"--bind", 0, 0}, fmt::format("'{}' is not an IP address", im.options.bind));
  im.ws.listen(asio::ip::tcp::endpoint(addr, im.options.port), ec);
  if (ec) throw InputError({where, 0, 0}, fmt::format("cannot listen: {}", ec.message()));
  im.port = im.ws.get_local_endpoint(aec).port();
  im.ws.start_accept(ec);
  if (ec) throw InputError({where, 0, 0}, fmt::format("cannot accept connections: {}", ec.message()));
  im.thread = std::thread([&im] { im.ws.run(); });
}

LiveServer::~LiveServer() {
  Impl& im = *impl_;
  websocketpp::lib::error_code ec;
  im.ws.stop_listening(ec);
  std::set<Handle, std::owner_less<Handle>> open;
  {
    std::lock_guard lock(im.mutex);
    open = im.viewers;
  }
  for (const Handle& h : open) im.ws.close(h, websocketpp::close::status::going_away, "the server stops", ec);
  im.ws.stop();
  if (im.thread.joinable()) im.thread.join();
}

std::uint16_t LiveServer::port() const { return impl_->port; }

void LiveServer::set_cell(std::string json) {
  std::vector<std::string> after;
  {
    std::lock_guard lock(impl_->mutex);
    impl_->cell = json;
    after = impl_->greeting;
  }
  broadcast(json);
  // The greeting goes right after the cell, also to a viewer that connected before there was one.
  for (const std::string& m : after) broadcast(m);
}

void LiveServer::publish(std::string json) {
  Impl& im = *impl_;
  std::set<Handle, std::owner_less<Handle>> open;
  {
    std::lock_guard lock(im.mutex);
    open = im.viewers;
  }
  std::uint64_t sent = 0, dropped = 0;
  for (const Handle& h : open) {
    websocketpp::lib::error_code ec;
    WsServer::connection_ptr con = im.ws.get_con_from_hdl(h, ec);
    if (ec || !con) continue;  // gone meanwhile
    if (con->get_buffered_amount() > im.options.max_buffered) {
      ++dropped;
      continue;
    }
    con->send(json, websocketpp::frame::opcode::text);
    ++sent;
  }
  std::lock_guard lock(im.mutex);
  im.counts.sent += sent;
  im.counts.dropped += dropped;
}

std::optional<Message> LiveServer::poll_message() {
  std::lock_guard lock(impl_->mutex);
  if (impl_->commands.empty()) return std::nullopt;
  Message m = std::move(impl_->commands.front());
  impl_->commands.pop_front();
  return m;
}

std::optional<Message> LiveServer::wait_message(std::chrono::milliseconds timeout) {
  std::unique_lock lock(impl_->mutex);
  if (!impl_->command_ready.wait_for(lock, timeout, [this] { return !impl_->commands.empty(); })) return std::nullopt;
  Message m = std::move(impl_->commands.front());
  impl_->commands.pop_front();
  return m;
}

void LiveServer::set_greeting(std::vector<std::string> messages) {
  std::lock_guard lock(impl_->mutex);
  impl_->greeting = std::move(messages);
}

void LiveServer::send_to(std::uint64_t viewer, const std::string& json) {
  Handle h;
  {
    std::lock_guard lock(impl_->mutex);
    const auto it = impl_->by_id.find(viewer);
    if (it == impl_->by_id.end()) return;
    h = it->second;
  }
  impl_->send_text(h, json);
}

void LiveServer::broadcast(const std::string& json) {
  std::set<Handle, std::owner_less<Handle>> open;
  {
    std::lock_guard lock(impl_->mutex);
    open = impl_->viewers;
  }
  for (const Handle& h : open) impl_->send_text(h, json);
}

std::size_t LiveServer::viewers() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->viewers.size();
}

LiveServer::Counts LiveServer::counts() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->counts;
}

}  // namespace cellwright::serve
