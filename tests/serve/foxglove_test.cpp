// The live view's server speaking the Foxglove WebSocket protocol (live_server.hpp, "Foxglove") over loopback, to a
// test client that asks for the subprotocol as Foxglove does: serverInfo and advertise on connecting, subscriptions
// and their Message Data (base, latest, then each message), refusals as status messages, channels that change, and
// the wall between these clients and the page's viewers. (tests/foxglove runs Foxglove's own client against twin
// serve.)
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/serve/foxglove_schemas.hpp"
#include "cellwright/serve/live_server.hpp"
#include "support/foxglove_data.hpp"
#include "support/ws_viewer.hpp"

namespace cellwright::serve {
namespace {

using namespace std::chrono_literals;
using Client = cellwright::testing::WsViewer;
using nlohmann::json;

using Data = cellwright::testing::MessageData;
constexpr auto decode = cellwright::testing::decode_message_data;

auto any_data = [](const std::string& b) { return decode(b).has_value(); };

std::vector<Channel> two_channels() {
  Channel a;
  a.id = 1;
  a.topic = "/a";
  a.schema_name = "foxglove.SceneUpdate";
  a.schema = std::string(foxglove_schema(a.schema_name));
  Channel b;
  b.id = 7;
  b.topic = "/b";
  b.schema_name = "test.B";
  b.schema = R"({"type":"object"})";
  return {a, b};
}

ServerOptions loopback_any_port() {
  ServerOptions o;
  o.port = 0;
  o.name = "test server";
  return o;
}

bool wait_until(const std::function<bool()>& f) {
  for (int i = 0; i < 500; ++i) {
    if (f()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

auto op_is(const std::string& op) {
  return [op](const json& m) { return m.is_object() && m.value("op", "") == op; };
}

TEST(FoxgloveSchemas, TheBuildCarriesSceneUpdateFromFoxglovesPackage) {
  const json s = json::parse(foxglove_schema("foxglove.SceneUpdate"));
  EXPECT_EQ(s["title"], "foxglove.SceneUpdate");
  EXPECT_TRUE(s["properties"].contains("entities"));
  EXPECT_TRUE(s["properties"].contains("deletions"));
  EXPECT_TRUE(foxglove_schema("foxglove.Nothing").empty());
}

TEST(Foxglove, AClientGetsServerInfoAndTheChannelsAndNoneOfThePagesMessages) {
  LiveServer server(loopback_any_port());
  server.advertise(two_channels());
  server.set_cell(R"({"type":"cell"})");
  Client fox(server.port(), "/", kFoxgloveSubprotocol);
  ASSERT_TRUE(fox.connected());
  EXPECT_EQ(fox.subprotocol(), "foxglove.websocket.v1");
  const json info = fox.wait_for(op_is("serverInfo"));
  ASSERT_FALSE(info.is_null());
  EXPECT_EQ(info["name"], "test server");
  EXPECT_EQ(info["capabilities"], json::array());
  EXPECT_TRUE(info["sessionId"].is_string());
  const json ad = fox.wait_for(op_is("advertise"));
  ASSERT_EQ(ad["channels"].size(), 2u);
  EXPECT_EQ(ad["channels"][0]["id"], 1);
  EXPECT_EQ(ad["channels"][0]["topic"], "/a");
  EXPECT_EQ(ad["channels"][0]["encoding"], "json");
  EXPECT_EQ(ad["channels"][0]["schemaName"], "foxglove.SceneUpdate");
  EXPECT_EQ(ad["channels"][0]["schemaEncoding"], "jsonschema");
  EXPECT_EQ(json::parse(ad["channels"][0]["schema"].get<std::string>())["title"], "foxglove.SceneUpdate");
  EXPECT_EQ(ad["channels"][1]["id"], 7);
  // Not a viewer of the page's protocol: not counted, no cell, no frame.
  EXPECT_TRUE(wait_until([&] { return server.foxglove_clients() == 1; }));
  EXPECT_EQ(server.viewers(), 0u);
  server.publish(R"({"type":"frame"})");
  server.broadcast(R"({"type":"saved"})");
  Client page(server.port());
  EXPECT_FALSE(page.wait_for("cell").is_null());
  EXPECT_EQ(fox.count("cell") + fox.count("frame") + fox.count("saved"), 0u);
  // A page's viewer asking for no subprotocol is not given one, and gets no advertise.
  EXPECT_EQ(page.subprotocol(), "");
  EXPECT_EQ(page.count(op_is("advertise")), 0u);
}

TEST(Foxglove, ASubscriberGetsTheBaseTheLatestThenEachMessageUntilItUnsubscribes) {
  LiveServer server(loopback_any_port());
  server.advertise(two_channels());
  server.set_channel_base(1, "base", 100);
  server.publish_channel(1, "latest", 200);  // nobody subscribed: kept, sent to nobody
  server.publish_channel(7, "on b", 250);
  Client fox(server.port(), "/", kFoxgloveSubprotocol);
  ASSERT_FALSE(fox.wait_for(op_is("advertise")).is_null());
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":42,"channelId":1}]})");
  ASSERT_TRUE(wait_until([&] { return server.subscribers(1) == 1; }));
  const std::optional<Data> base = decode(fox.wait_binary(any_data, 0));
  const std::optional<Data> latest = decode(fox.wait_binary(any_data, 1));
  ASSERT_TRUE(base && latest);
  EXPECT_EQ(base->subscription, 42u);
  EXPECT_EQ(base->time_ns, 100u);
  EXPECT_EQ(base->payload, "base");
  EXPECT_EQ(latest->payload, "latest");
  EXPECT_EQ(latest->time_ns, 200u);
  server.publish_channel(1, "next", 0x0102030405060708ULL);
  const std::optional<Data> next = decode(fox.wait_binary(any_data, 2));  // nullopt if it never came
  ASSERT_TRUE(next);
  EXPECT_EQ(next->payload, "next");
  EXPECT_EQ(next->time_ns, 0x0102030405060708ULL);  // little-endian, all eight bytes
  // A new base goes to the subscriber at once, and replaces the latest for those who come later.
  server.set_channel_base(1, "base 2", 300);
  const std::optional<Data> base2 = decode(fox.wait_binary(any_data, 3));
  ASSERT_TRUE(base2);
  EXPECT_EQ(base2->payload, "base 2");
  fox.send(R"({"op":"unsubscribe","subscriptionIds":[42]})");
  ASSERT_TRUE(wait_until([&] { return server.subscribers(1) == 0; }));
  server.publish_channel(1, "after", 400);
  Client other(server.port(), "/ws", kFoxgloveSubprotocol);  // any path
  other.send(R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":1,"channelId":7}]})");
  // Sent in order: subscription 0's base and latest, then subscription 1's latest.
  const std::optional<Data> third = decode(other.wait_binary(any_data, 2));
  const std::optional<Data> first = decode(other.wait_binary(any_data, 0));
  const std::optional<Data> second = decode(other.wait_binary(any_data, 1));
  ASSERT_TRUE(first && second && third);
  EXPECT_EQ(third->payload, "on b");
  EXPECT_EQ(third->subscription, 1u);
  EXPECT_EQ(first->payload, "base 2");
  EXPECT_EQ(second->payload, "after");
  EXPECT_EQ(second->subscription, 0u);
  EXPECT_EQ(other.count_binary(any_data), 3u);
  EXPECT_EQ(fox.count_binary(any_data), 4u);  // nothing after it unsubscribed
  EXPECT_EQ(server.counts().messages, 1u);    // "next"; the rest went out on subscribing
}

TEST(Foxglove, MessagesItCannotTakeAreRefusedWithAStatusAndTheClientStays) {
  LiveServer server(loopback_any_port());
  server.advertise(two_channels());
  Client fox(server.port(), "/", kFoxgloveSubprotocol);
  ASSERT_FALSE(fox.wait_for(op_is("advertise")).is_null());
  auto status = [&](std::size_t skip) { return fox.wait_for(op_is("status"), skip); };
  fox.send("{not json");
  EXPECT_EQ(status(0)["message"], "not a JSON object");
  EXPECT_EQ(status(0)["level"], 2);
  fox.send(R"({"subscriptions":[]})");
  EXPECT_EQ(status(1)["message"], "no \"op\" (a string)");
  fox.send(R"({"op":"advertise","channels":[{"id":1,"topic":"/x","encoding":"json","schemaName":"X"}]})");
  EXPECT_NE(status(2)["message"].get<std::string>().find("op 'advertise' is not supported"), std::string::npos);
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":99}]})");
  EXPECT_EQ(status(3)["message"], "subscription 1: no channel 99 is advertised");
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})");
  EXPECT_NE(status(4)["message"].get<std::string>().find("unsigned 32-bit"), std::string::npos);
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":5,"channelId":1}]})");
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":5,"channelId":7}]})");
  EXPECT_EQ(status(5)["message"], "subscription id 5 is in use (unsubscribe it first)");
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":6,"channelId":1}]})");  // one subscription a channel
  EXPECT_EQ(status(6)["message"],
            "subscription 6: this client has a subscription to channel 1 already (one a channel)");
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":4294967297,"channelId":7}]})");  // 2^32 + 1
  EXPECT_NE(status(7)["message"].get<std::string>().find("unsigned 32-bit"), std::string::npos);
  fox.send_binary(std::string("\x01\x01\x00\x00\x00{}", 7));
  EXPECT_NE(status(8)["message"].get<std::string>().find("a binary message"), std::string::npos);
  fox.send(R"({"type":"command","command":"play"})");  // the page's protocol is not this client's
  EXPECT_EQ(status(9)["message"], "no \"op\" (a string)");
  // Unsubscribing what is not subscribed is a warning, not an error (Foxglove unsubscribes channels unadvertised).
  fox.send(R"({"op":"unsubscribe","subscriptionIds":[6]})");
  EXPECT_EQ(status(10)["message"], "no subscription 6 (any more)");
  EXPECT_EQ(status(10)["level"], 1);
  for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(status(i)["level"], 2) << i;
  EXPECT_FALSE(server.poll_message().has_value());
  EXPECT_EQ(server.counts().refused, 10u);
  // Still connected, its one good subscription working.
  EXPECT_EQ(server.subscribers(1), 1u);
  server.publish_channel(1, "still here", 1);
  const std::optional<Data> here = decode(fox.wait_binary(any_data));
  ASSERT_TRUE(here);
  EXPECT_EQ(here->payload, "still here");
}

TEST(Foxglove, ChannelsThatChangeAreUnadvertisedAndTheirSubscriptionsEnd) {
  LiveServer server(loopback_any_port());
  server.advertise(two_channels());
  Client fox(server.port(), "/", kFoxgloveSubprotocol);
  ASSERT_FALSE(fox.wait_for(op_is("advertise")).is_null());
  fox.send(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1},{"id":2,"channelId":7}]})");
  ASSERT_TRUE(wait_until([&] { return server.subscribers(1) + server.subscribers(7) == 2; }));
  // Channel 7 goes: only it is unadvertised, and only its subscription ends; nothing new is advertised.
  std::vector<Channel> one = two_channels();
  one.pop_back();
  server.advertise(one);
  EXPECT_EQ(fox.wait_for(op_is("unadvertise"))["channelIds"], json::array({7}));
  EXPECT_EQ(server.subscribers(7), 0u);
  EXPECT_EQ(server.subscribers(1), 1u);
  server.publish_channel(7, "nobody", 1);  // not advertised: not sent, not kept
  // Channel 1 changes under its id (another topic): unadvertised, advertised again, its subscription ended.
  one[0].topic = "/a2";
  server.advertise(one);
  EXPECT_EQ(fox.wait_for(op_is("unadvertise"), 1)["channelIds"], json::array({1}));
  const json again = fox.wait_for(op_is("advertise"), 1);
  ASSERT_EQ(again["channels"].size(), 1u);
  EXPECT_EQ(again["channels"][0]["topic"], "/a2");
  EXPECT_EQ(server.subscribers(1), 0u);
  EXPECT_EQ(fox.count(op_is("advertise")), 2u);  // on connecting, and the changed channel
  std::vector<Channel> twice = two_channels();
  twice[1].id = 1;
  EXPECT_THROW(server.advertise(twice), InputError);
}

TEST(Foxglove, AClientThatLeavesCostsNothingAndIsForgotten) {
  LiveServer server(loopback_any_port());
  server.advertise(two_channels());
  {
    Client fox(server.port(), "/", kFoxgloveSubprotocol);
    fox.send(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1}]})");
    ASSERT_TRUE(wait_until([&] { return server.subscribers(1) == 1; }));
  }
  EXPECT_TRUE(wait_until([&] { return server.foxglove_clients() == 0 && server.subscribers(1) == 0; }));
  server.publish_channel(1, "x", 1);
  EXPECT_EQ(server.counts().messages, 0u);
}

}  // namespace
}  // namespace cellwright::serve
