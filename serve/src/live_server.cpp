// The live view's server: websocketpp on standalone asio (docs/live-view.md says why these).
#define ASIO_STANDALONE
#include "cellwright/serve/live_server.hpp"

#include <fmt/format.h>

#include <condition_variable>
#include <algorithm>
#include <fstream>
#include <limits>
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

// The Foxglove protocol's Message Data: opcode 0x01, the subscription id (uint32) and the timestamp (uint64, ns),
// little-endian, then the payload.
std::string message_data(std::uint32_t subscription, std::uint64_t time_ns, const std::string& payload) {
  std::string out;
  out.reserve(13 + payload.size());
  out.push_back('\x01');
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((subscription >> (8 * i)) & 0xFF));
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((time_ns >> (8 * i)) & 0xFF));
  out += payload;
  return out;
}

}  // namespace

struct LiveServer::Impl {
  ServerOptions options;
  WsServer ws;
  std::thread thread;
  std::uint16_t port = 0;

  // Held across taking what to send to Foxglove clients and handing it to their sockets (on_open, subscribe,
  // advertise, set_channel_base, publish_channel), so that each client gets them in the order they were taken: never
  // a channel's older base or message after a newer one. Taken before `mutex`, never while holding it.
  std::mutex send_order;
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
  std::uint64_t arrivals = 0;  // viewers that connected and subscriptions made, so far
  // The Foxglove protocol: its clients (not in `viewers`) and each one's subscriptions (id -> channel id).
  std::map<Handle, std::map<std::uint32_t, std::uint32_t>, std::owner_less<Handle>> fox;
  std::vector<Channel> channels;
  struct Stamped {
    std::uint64_t time_ns = 0;
    std::string payload;
  };
  std::map<std::uint32_t, Stamped> base, latest;  // by channel id
  std::string session = std::to_string(
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());

  void send_text(Handle h, const std::string& text) {
    websocketpp::lib::error_code ec;
    ws.send(h, text, websocketpp::frame::opcode::text, ec);  // a viewer gone meanwhile: nothing to do
  }

  void send_binary(Handle h, const std::string& bytes) {
    websocketpp::lib::error_code ec;
    ws.send(h, bytes, websocketpp::frame::opcode::binary, ec);
  }

  // A message that may be dropped (a frame, a channel message): handed to h's socket unless more than
  // options.max_buffered bytes wait there unsent. Never waits.
  enum class Handed { kSent, kDropped, kGone };
  Handed send_unless_full(Handle h, const std::string& bytes, websocketpp::frame::opcode::value opcode) {
    websocketpp::lib::error_code ec;
    WsServer::connection_ptr con = ws.get_con_from_hdl(h, ec);
    if (ec || !con) return Handed::kGone;
    if (con->get_buffered_amount() > options.max_buffered) return Handed::kDropped;
    con->send(bytes, opcode);
    return Handed::kSent;
  }

  // Every Foxglove subscription to `channel`: its client and id. Under `mutex`.
  std::vector<std::pair<Handle, std::uint32_t>> subscriptions_to(std::uint32_t channel) const {
    std::vector<std::pair<Handle, std::uint32_t>> to;
    for (const auto& [h, subs] : fox) {
      for (const auto& [id, c] : subs) {
        if (c == channel) to.emplace_back(h, id);
      }
    }
    return to;
  }

  static std::string status_json(int level, const std::string& message) {
    return nlohmann::json{{"op", "status"}, {"level", level}, {"message", message}}.dump();
  }

  bool has_channel(std::uint32_t id) const {
    return std::any_of(channels.begin(), channels.end(), [id](const Channel& c) { return c.id == id; });
  }

  static std::string advertise_json(const std::vector<Channel>& list_of) {
    nlohmann::json list = nlohmann::json::array();
    for (const Channel& c : list_of) {
      list.push_back({{"id", c.id},
                      {"topic", c.topic},
                      {"encoding", c.encoding},
                      {"schemaName", c.schema_name},
                      {"schema", c.schema},
                      {"schemaEncoding", c.schema_encoding}});
    }
    return nlohmann::json{{"op", "advertise"}, {"channels", list}}.dump();
  }

  void refuse_fox(Handle h, const std::string& reason) {
    {
      std::lock_guard lock(mutex);
      ++counts.refused;
    }
    send_text(h, status_json(2, reason));
  }

  // A Foxglove client's message: subscribe and unsubscribe; anything else refused with a status.
  void on_fox_message(Handle h, const WsServer::message_ptr& msg) {
    if (msg->get_opcode() != websocketpp::frame::opcode::text) {
      return refuse_fox(h, "a binary message: this server takes no client data (it declares no capability)");
    }
    const nlohmann::json j = nlohmann::json::parse(msg->get_payload(), nullptr, false);
    if (j.is_discarded() || !j.is_object()) return refuse_fox(h, "not a JSON object");
    const auto op = j.find("op");
    if (op == j.end() || !op->is_string()) return refuse_fox(h, "no \"op\" (a string)");
    auto is_u32 = [](const nlohmann::json& v) {
      return v.is_number_unsigned() && v.get<std::uint64_t>() <= std::numeric_limits<std::uint32_t>::max();
    };
    if (*op == "subscribe") {
      const auto subs = j.find("subscriptions");
      if (subs == j.end() || !subs->is_array()) return refuse_fox(h, "subscribe needs \"subscriptions\" (an array)");
      for (const nlohmann::json& s : *subs) {
        if (!s.is_object() || !s.contains("id") || !s.contains("channelId") || !is_u32(s["id"]) ||
            !is_u32(s["channelId"])) {
          refuse_fox(h, fmt::format("a subscription is {{\"id\", \"channelId\"}} (unsigned 32-bit), not {}",
                                    s.dump()));
          continue;
        }
        const auto id = s["id"].get<std::uint32_t>();
        const auto channel = s["channelId"].get<std::uint32_t>();
        std::vector<std::string> first;  // the channel's base and latest, to this subscription
        std::string problem;
        std::lock_guard order(send_order);
        {
          std::lock_guard lock(mutex);
          auto it = fox.find(h);
          if (it == fox.end()) return;  // gone meanwhile
          if (!has_channel(channel)) {
            problem = fmt::format("subscription {}: no channel {} is advertised", id, channel);
          } else if (it->second.count(id)) {
            problem = fmt::format("subscription id {} is in use (unsubscribe it first)", id);
          } else if (std::any_of(it->second.begin(), it->second.end(),
                                 [channel](const auto& sub) { return sub.second == channel; })) {
            problem = fmt::format("subscription {}: this client has a subscription to channel {} already (one a "
                                  "channel)",
                                  id, channel);
          } else {
            it->second[id] = channel;
            ++arrivals;
            for (const auto* kept : {&base, &latest}) {
              if (const auto k = kept->find(channel); k != kept->end()) {
                first.push_back(message_data(id, k->second.time_ns, k->second.payload));
              }
            }
          }
        }
        if (!problem.empty()) {
          refuse_fox(h, problem);
          continue;
        }
        for (const std::string& m : first) send_binary(h, m);
      }
      return;
    }
    if (*op == "unsubscribe") {
      const auto sub_ids = j.find("subscriptionIds");
      if (sub_ids == j.end() || !sub_ids->is_array()) {
        return refuse_fox(h, "unsubscribe needs \"subscriptionIds\" (an array)");
      }
      for (const nlohmann::json& v : *sub_ids) {
        if (!is_u32(v)) {
          refuse_fox(h, fmt::format("a subscription id is an unsigned 32-bit number, not {}", v.dump()));
          continue;
        }
        bool known = false;
        {
          std::lock_guard lock(mutex);
          auto it = fox.find(h);
          if (it == fox.end()) return;
          known = it->second.erase(v.get<std::uint32_t>()) > 0;
        }
        // Not an error: the subscriptions of a channel unadvertised end with it, and a client may unsubscribe them
        // after (Foxglove does).
        if (!known) {
          send_text(h, status_json(1, fmt::format("no subscription {} (any more)", v.dump())));
        }
      }
      return;
    }
    refuse_fox(h, fmt::format("op '{}' is not supported: this server declares no capability (it streams its "
                              "channels, and takes subscribe and unsubscribe)",
                              op->get<std::string>()));
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

  // The handshake: a client that asks for the Foxglove subprotocol gets it.
  bool on_validate(Handle h) {
    WsServer::connection_ptr con = ws.get_con_from_hdl(h);
    for (const std::string& p : con->get_requested_subprotocols()) {
      if (p == kFoxgloveSubprotocol) {
        con->select_subprotocol(p);
        break;
      }
    }
    return true;
  }

  void on_open(Handle h) {
    websocketpp::lib::error_code ec;
    WsServer::connection_ptr con = ws.get_con_from_hdl(h, ec);
    if (!ec && con && con->get_subprotocol() == kFoxgloveSubprotocol) {
      std::string advertised;
      std::lock_guard order(send_order);  // serverInfo, then the channels as they are now
      {
        std::lock_guard lock(mutex);
        fox[h];
        advertised = advertise_json(channels);
      }
      send_text(h, nlohmann::json{{"op", "serverInfo"},
                                  {"name", options.name},
                                  {"capabilities", nlohmann::json::array()},
                                  {"metadata", nlohmann::json::object()},
                                  {"sessionId", session}}
                       .dump());
      send_text(h, advertised);
      return;
    }
    std::string c;
    std::vector<std::string> after;
    {
      std::lock_guard lock(mutex);
      viewers.insert(h);
      const std::uint64_t id = next_id++;
      ++arrivals;
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
    fox.erase(h);
    viewers.erase(h);
    if (const auto it = ids.find(h); it != ids.end()) {
      by_id.erase(it->second);
      ids.erase(it);
    }
  }

  void on_message(Handle h, const WsServer::message_ptr& msg) {
    bool is_fox = false;
    {
      std::lock_guard lock(mutex);
      is_fox = fox.count(h) > 0;
    }
    if (is_fox) return on_fox_message(h, msg);
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
  im.ws.set_validate_handler([&im](Handle h) { return im.on_validate(h); });
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
    for (const auto& f : im.fox) open.insert(f.first);
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
    const Impl::Handed handed = im.send_unless_full(h, json, websocketpp::frame::opcode::text);
    sent += handed == Impl::Handed::kSent ? 1 : 0;
    dropped += handed == Impl::Handed::kDropped ? 1 : 0;
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

void LiveServer::advertise(std::vector<Channel> channels) {
  Impl& im = *impl_;
  for (std::size_t i = 0; i < channels.size(); ++i) {
    for (std::size_t k = 0; k < i; ++k) {
      if (channels[i].id == channels[k].id) {
        throw InputError({channels[i].topic, 0, 0},
                         fmt::format("channel id {} is also {}'s", channels[i].id, channels[k].topic));
      }
    }
  }
  auto same = [](const Channel& a, const Channel& b) {
    return a.id == b.id && a.topic == b.topic && a.encoding == b.encoding && a.schema_name == b.schema_name &&
           a.schema == b.schema && a.schema_encoding == b.schema_encoding;
  };
  auto in = [&same](const std::vector<Channel>& list, const Channel& c) {
    return std::any_of(list.begin(), list.end(), [&](const Channel& o) { return same(o, c); });
  };
  std::lock_guard order(im.send_order);
  std::vector<Handle> clients;
  nlohmann::json gone = nlohmann::json::array();  // removed, or changed under the same id
  std::vector<Channel> added;                     // new, or changed
  {
    std::lock_guard lock(im.mutex);
    for (const Channel& c : im.channels) {
      if (!in(channels, c)) gone.push_back(c.id);
    }
    for (const Channel& c : channels) {
      if (!in(im.channels, c)) added.push_back(c);
    }
    im.channels = std::move(channels);
    auto ended = [&gone](std::uint32_t id) { return std::find(gone.begin(), gone.end(), id) != gone.end(); };
    for (auto& [h, subs] : im.fox) {
      clients.push_back(h);
      for (auto it = subs.begin(); it != subs.end();) it = ended(it->second) ? subs.erase(it) : std::next(it);
    }
    for (auto* kept : {&im.base, &im.latest}) {
      for (auto it = kept->begin(); it != kept->end();) it = ended(it->first) ? kept->erase(it) : std::next(it);
    }
  }
  const std::string unadvertise = nlohmann::json{{"op", "unadvertise"}, {"channelIds", gone}}.dump();
  const std::string advertised = Impl::advertise_json(added);
  for (const Handle& h : clients) {
    if (!gone.empty()) im.send_text(h, unadvertise);
    if (!added.empty()) im.send_text(h, advertised);
  }
}

void LiveServer::set_channel_base(std::uint32_t channel, std::string payload, std::uint64_t time_ns) {
  Impl& im = *impl_;
  std::vector<std::pair<Handle, std::uint32_t>> to;
  std::lock_guard order(im.send_order);
  {
    std::lock_guard lock(im.mutex);
    if (!im.has_channel(channel)) return;
    im.latest.erase(channel);
    to = im.subscriptions_to(channel);
    im.base[channel] = {time_ns, payload};
  }
  for (const auto& [h, id] : to) im.send_binary(h, message_data(id, time_ns, payload));
}

void LiveServer::publish_channel(std::uint32_t channel, std::string payload, std::uint64_t time_ns) {
  Impl& im = *impl_;
  std::vector<std::pair<Handle, std::uint32_t>> to;
  std::lock_guard order(im.send_order);
  {
    std::lock_guard lock(im.mutex);
    if (!im.has_channel(channel)) return;
    to = im.subscriptions_to(channel);
    im.latest[channel] = {time_ns, payload};  // before sending: a client subscribing meanwhile gets it too
  }
  std::uint64_t sent = 0, dropped = 0;
  for (const auto& [h, id] : to) {
    const Impl::Handed handed =
        im.send_unless_full(h, message_data(id, time_ns, payload), websocketpp::frame::opcode::binary);
    sent += handed == Impl::Handed::kSent ? 1 : 0;
    dropped += handed == Impl::Handed::kDropped ? 1 : 0;
  }
  std::lock_guard lock(im.mutex);
  im.counts.messages += sent;
  im.counts.messages_dropped += dropped;
}

std::size_t LiveServer::subscribers(std::uint32_t channel) const {
  std::lock_guard lock(impl_->mutex);
  return impl_->subscriptions_to(channel).size();
}

std::uint64_t LiveServer::arrivals() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->arrivals;
}

std::size_t LiveServer::foxglove_clients() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->fox.size();
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
