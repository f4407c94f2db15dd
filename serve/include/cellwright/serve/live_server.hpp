// The live view's server (docs/live-view.md): one HTTP + WebSocket endpoint that serves the page's files and the
// robots' models, and carries the live view's messages. It knows nothing of MuJoCo, the twin or the runtime: the
// caller (`twin serve`, cell/live/live.hpp) gives it JSON texts to send and takes the viewers' commands from it.
//
// Protocol (JSON text frames on the WebSocket at "/ws"; every message an object with a "type"):
//   server -> viewer   {"type":"cell",  ...}   the cell (set_cell): sent to each viewer when it connects, and to all
//                                             when it changes (a restart)
//                      {"type":"frame", ...}   the state now (publish): sent at a bounded rate by the caller, and
//                                             dropped for a viewer whose socket has more than
//                                             ServerOptions::max_buffered bytes not yet sent (never queued)
//                      {"type":"error","reason":"..."}  a message of this viewer was refused, and why
//                      anything else the caller sends: to one viewer (send_to) or to all (broadcast), never dropped
//   viewer -> server   {"type":"command","command":"play"|"pause"|"step"|"restart"|"run_to"|"replay", ...}
//                      {"type":"teach", ...}, {"type":"save_location", ...}, {"type":"check"}
//                      (their other fields are the caller's to read: Message::text)
// Anything else from a viewer (not JSON, not an object, another type, an unknown command, a binary frame, a text over
// kMaxMessageBytes) is refused with an "error" message naming the problem; the connection stays open.
//
// The same endpoint speaks the Foxglove WebSocket protocol (https://github.com/foxglove/ws-protocol, docs/spec.md)
// to a client that asks for the subprotocol "foxglove.websocket.v1" (Foxglove, Lichtblick: "Open connection",
// ws://HOST:PORT), on any path. Such a client is not a viewer of the protocol above: it gets none of its messages and
// may send none of them. It gets:
//   {"op":"serverInfo","name" (ServerOptions::name),"capabilities":[],"metadata":{},"sessionId"} when it connects,
//   {"op":"advertise","channels":[...]} the channels (advertise()) when it connects and when they change (after an
//                                       {"op":"unadvertise","channelIds":[...]} of the ones before),
//   binary Message Data (0x01, uint32 subscription id, uint64 timestamp ns, payload; little-endian) on each channel
//       it subscribed to: first the channel's base (set_channel_base) and its latest message, then each message
//       published on it (publish_channel), dropped, as frames are, when its socket is full,
//   {"op":"status","level":2,"message":"..."} when a message of its was refused, and why.
// It may send {"op":"subscribe","subscriptions":[{"id","channelId"}]} and {"op":"unsubscribe","subscriptionIds":[]}.
// The server declares no capability, so any other op (a client publishing, parameters, services), a binary message,
// an unknown channel, a subscription id in use, a second subscription to a channel, or text that is not such an
// object is refused with a status (level 2); unsubscribing a subscription that is not (any more) gets a warning
// (level 1). Each client gets what it is sent in the order it was taken: a channel's base and messages never
// overtake one another.
//
// HTTP: GET "/" is www/index.html; "/<file>" a file of www; "/models/<path>" a file of the models directory (the
// robots' URDFs and meshes). A path with "..", or a file that is not there, is 404. Nothing else is served.
//
// Threads: one thread of its own runs the sockets (asio). Every public member may be called from any thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace cellwright::serve {

// A viewer's command to the run.
enum class CommandKind { kPlay, kPause, kStep, kRestart, kRunTo, kReplay };
const char* to_string(CommandKind kind);

// A viewer's message the server accepted (its type is one of the protocol's).
struct Message {
  std::uint64_t viewer = 0;            // who sent it: LiveServer::send_to answers it (0 from parse_message)
  std::string type;                    // "command", "teach", "save_location" or "check"
  std::optional<CommandKind> command;  // type "command": which
  std::string text;                    // the message as received (a JSON object), for the fields its type has
};

// parse_message's answer: the message, or why it was refused.
struct Refusal {
  std::string reason;
};
using Parsed = std::variant<Message, Refusal>;

// Reads one message from a viewer (the protocol above): its type and, for a command, which one. The other fields
// of a message are read by the caller.
Parsed parse_message(std::string_view text);

inline constexpr std::size_t kMaxMessageBytes = 4096;

struct ServerOptions {
  std::string bind = "127.0.0.1";  // the address listened on: loopback unless the user gives another
  std::uint16_t port = 8029;       // 0: any free port (port() says which)
  std::filesystem::path www;       // the page's files
  std::filesystem::path models;    // served under /models/
  std::size_t max_buffered = 256 * 1024;  // bytes waiting on a viewer's socket above which its frames are dropped
  std::string name = "cellwright";        // the Foxglove serverInfo's name
};

inline constexpr const char* kFoxgloveSubprotocol = "foxglove.websocket.v1";

// A channel of the Foxglove protocol, as its "advertise" message describes it.
struct Channel {
  std::uint32_t id = 0;
  std::string topic;
  std::string encoding = "json";
  std::string schema_name;
  std::string schema;  // the schema's text, in schema_encoding
  std::string schema_encoding = "jsonschema";
};

class LiveServer {
 public:
  // Listens and starts the sockets' thread. Throws InputError naming the address and port when it cannot listen
  // (the port in use, an address that is not this machine's or not an address).
  explicit LiveServer(ServerOptions options);
  // Closes every connection and joins the thread.
  ~LiveServer();
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  std::uint16_t port() const;

  // The "cell" message: kept, sent now to every viewer (followed by the greeting), and to each viewer that connects
  // later.
  void set_cell(std::string json);
  // Messages sent right after the cell: to each viewer that connects from now on, and to all with each set_cell (e.g.
  // a check's result; a viewer that connected before the first cell gets them with it); not sent now.
  void set_greeting(std::vector<std::string> messages);
  // Sends `json` to one viewer (the sender of a Message), or to every viewer; not dropped for a slow viewer (replies
  // are few and small). A viewer gone meanwhile is skipped.
  void send_to(std::uint64_t viewer, const std::string& json);
  void broadcast(const std::string& json);
  // Sends a "frame" message to every viewer that can take it now; the others miss it (counted in dropped()).
  // Never waits for a viewer.
  void publish(std::string json);

  // The oldest message not yet taken, if any; never waits.
  std::optional<Message> poll_message();
  // The oldest message not yet taken, waiting up to `timeout` for one.
  std::optional<Message> wait_message(std::chrono::milliseconds timeout);

  // The Foxglove protocol's channels (see the top). advertise() replaces them: the clients are told of the channels
  // removed or changed (unadvertise: their subscriptions end, with their base and latest) and of the new or changed
  // ones (advertise); a channel that stays as it was keeps its subscriptions. Ids are unique (InputError otherwise).
  void advertise(std::vector<Channel> channels);
  // A channel's base: sent to each client that subscribes from now on, before the channel's latest message, and now
  // to every subscriber (e.g. the whole scene, where later messages carry only what moves). Clears the latest message.
  void set_channel_base(std::uint32_t channel, std::string payload, std::uint64_t time_ns);
  // A message on a channel: kept as its latest, sent to each subscriber that can take it now (the others miss it,
  // counted in Counts::messages_dropped). Never waits. A channel not advertised: nothing is sent.
  void publish_channel(std::uint32_t channel, std::string payload, std::uint64_t time_ns);
  // Subscriptions to `channel` now, over all Foxglove clients.
  std::size_t subscribers(std::uint32_t channel) const;

  // Viewers of the live view's protocol (Foxglove clients are not counted: foxglove_clients()).
  std::size_t viewers() const;
  std::size_t foxglove_clients() const;
  // Viewers that have connected and subscriptions that have been made, since the server started (only grows): a
  // change says someone new watches, who may want the state now.
  std::uint64_t arrivals() const;
  struct Counts {
    std::uint64_t sent = 0;     // frames handed to a viewer's socket
    std::uint64_t dropped = 0;  // frames a slow viewer missed
    std::uint64_t refused = 0;  // viewers' and Foxglove clients' messages refused
    std::uint64_t messages = 0;          // channel messages handed to a Foxglove client's socket
    std::uint64_t messages_dropped = 0;  // channel messages a slow Foxglove client missed
  };
  Counts counts() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Paces frames to at most `hz` per second of wall time: due() is true at the first call and then once `1/hz` has
// passed since the last time it was true.
class FramePacer {
 public:
  explicit FramePacer(double hz);  // hz > 0
  bool due(std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now());

 private:
  std::chrono::steady_clock::duration period_;
  std::optional<std::chrono::steady_clock::time_point> last_;
};

}  // namespace cellwright::serve
