// `twin serve` as a user runs it: the exchange scenario served on a free port, a viewer over loopback receives the
// cell, steps the run and sees its firings advance; the page over HTTP; loopback only unless --bind says otherwise.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "support/ws_viewer.hpp"
#include "twin_cli.hpp"

namespace cellwright::testing {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

const std::string kBanner = "serving the live view on http://127.0.0.1:";

// The port `twin serve --port 0` printed.
std::uint16_t served_port(const std::string& output) {
  const auto at = output.find(kBanner);
  if (at == std::string::npos) return 0;
  return static_cast<std::uint16_t>(std::stoi(output.substr(at + kBanner.size())));
}

// A TCP connection to addr:port (-1 if refused).
int connect_to(in_addr addr, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(port);
  sa.sin_addr = addr;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

std::string http_get(std::uint16_t port, const std::string& path) {
  in_addr lo{};
  lo.s_addr = htonl(INADDR_LOOPBACK);
  const int fd = connect_to(lo, port);
  if (fd < 0) return "";
  const std::string req = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (::write(fd, req.data(), req.size()) != static_cast<ssize_t>(req.size())) return "";
  std::string reply;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) reply.append(buf, static_cast<std::size_t>(n));
  ::close(fd);
  return reply;
}

// The local IPv4 addresses of `port`'s listening sockets, from /proc/net/tcp ("0100007F" is 127.0.0.1).
std::vector<std::string> listening_on(std::uint16_t port) {
  std::ifstream in("/proc/net/tcp");
  std::string line;
  std::getline(in, line);  // the header
  std::vector<std::string> out;
  char hex_port[8];
  std::snprintf(hex_port, sizeof hex_port, "%04X", port);
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string slot, local, remote, state;
    s >> slot >> local >> remote >> state;
    if (state == "0A" && local.substr(local.find(':') + 1) == hex_port) out.push_back(local.substr(0, local.find(':')));
  }
  return out;
}

TEST(TwinServe, AViewerStepsTheExchangeScenarioAndTheFiringsAdvance) {
  BackgroundTwin twin({"serve", source_path("scenes/exchange.yaml"), "--port", "0"});
  ASSERT_TRUE(twin.wait_for(kBanner, 60s)) << twin.output();
  ASSERT_TRUE(twin.wait_for("/ (Ctrl-C stops)", 5s)) << twin.output();
  const std::uint16_t port = served_port(twin.output());
  ASSERT_NE(port, 0) << twin.output();
  // The same endpoint for Foxglove, said in the banner.
  EXPECT_NE(twin.output().find("and Foxglove on ws://127.0.0.1:" + std::to_string(port) + "/"), std::string::npos)
      << twin.output();

  WsViewer v(port);
  const json cell = v.wait_for("cell");
  ASSERT_TRUE(cell.is_object()) << twin.output();
  EXPECT_EQ(cell["scenario"], "exchange.yaml");
  EXPECT_FALSE(cell["robots"].empty());
  const json start = v.wait_for("frame");
  ASSERT_TRUE(start.is_object());
  EXPECT_EQ(start["firings"], 0);
  EXPECT_EQ(start["state"], "paused");
  v.send(R"({"type":"command","command":"step"})");
  const json f = v.wait_for([](const json& m) { return m.value("type", "") == "frame" && m["firings"] > 0; });
  ASSERT_TRUE(f.is_object()) << "no frame after a step";
  EXPECT_FALSE(f["fired"].empty());
  // A bad message is refused to this page with the reason; the run is unharmed.
  v.send("step please");
  EXPECT_EQ(v.wait_for("error")["reason"], "not JSON");

  // The page and the robots' models over HTTP.
  const std::string page = http_get(port, "/");
  EXPECT_EQ(page.rfind("HTTP/1.1 200", 0), 0u) << page.substr(0, 200);
  EXPECT_NE(page.find("<html"), std::string::npos);
  const std::string urdf = http_get(port, cell["robots"][0]["urdf"].get<std::string>());
  EXPECT_EQ(urdf.rfind("HTTP/1.1 200", 0), 0u) << urdf.substr(0, 200);
  EXPECT_NE(urdf.find("<robot"), std::string::npos);

  v.close();
  EXPECT_EQ(twin.stop(SIGINT), 130) << twin.output();
}

TEST(TwinServe, ListensOnLoopbackOnlyUnlessBindSaysOtherwise) {
  BackgroundTwin twin({"serve", source_path("scenes/exchange.yaml"), "--port", "0"});
  ASSERT_TRUE(twin.wait_for("/ (Ctrl-C stops)", 60s)) << twin.output();
  const std::uint16_t port = served_port(twin.output());
  ASSERT_NE(port, 0);
  EXPECT_EQ(listening_on(port), std::vector<std::string>{"0100007F"}) << "listening elsewhere than 127.0.0.1";
  // From this machine's other addresses (if it has any), nobody gets in.
  ifaddrs* ifs = nullptr;
  ASSERT_EQ(::getifaddrs(&ifs), 0);
  for (ifaddrs* i = ifs; i; i = i->ifa_next) {
    if (!i->ifa_addr || i->ifa_addr->sa_family != AF_INET) continue;
    const in_addr a = reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr;
    if ((ntohl(a.s_addr) >> 24) == 127) continue;
    const int fd = connect_to(a, port);
    EXPECT_LT(fd, 0) << "reached through " << inet_ntoa(a);
    if (fd >= 0) ::close(fd);
  }
  ::freeifaddrs(ifs);
  EXPECT_EQ(twin.stop(SIGTERM), 130);
}

// A program that fails the check is served as its counterexample's replay (not refused); other refusals still exit 2.
TEST(TwinServe, AProgramThatFailsTheCheckIsServedAsItsCounterexamplesReplay) {
  TwinCli cli("cw-serve-replay");
  const std::filesystem::path scenario = cli.dir() / "deadlock.yaml";
  std::ofstream(scenario) << "cell: " << source_path("scenes/cell.yaml") << "\nprogram: "
                          << source_path("scenes/deadlock.task") << "\nrobots: {r1: puma, r2: melfa}\n";
  BackgroundTwin twin({"serve", scenario.string(), "--port", "0"});
  ASSERT_TRUE(twin.wait_for("/ (Ctrl-C stops)", 60s)) << twin.output();
  EXPECT_NE(twin.output().find("fails the check: serving its counterexample's replay"), std::string::npos)
      << twin.output();
  WsViewer v(served_port(twin.output()));
  ASSERT_TRUE(v.wait_for("cell").is_object()) << twin.output();
  const json check = v.wait_for("check");
  ASSERT_TRUE(check.is_object()) << "no check on connect";
  EXPECT_EQ(check["ok"], false);
  EXPECT_EQ(check["property"], "deadlock");
  v.send(R"({"type":"command","command":"play"})");
  const json end = v.wait_for([](const json& m) { return m.value("type", "") == "frame" && m["state"] == "ended"; });
  ASSERT_TRUE(end.is_object());
  EXPECT_EQ(end["replay"], true);
  EXPECT_EQ(end["replay_index"], check["counterexample"].size());
  EXPECT_NE(end["reason"].get<std::string>().find("deadlock"), std::string::npos) << end.dump();
  v.close();
  EXPECT_EQ(twin.stop(SIGINT), 130) << twin.output();

  // A robot the cell does not have: refused before anything listens.
  std::ofstream(scenario) << "cell: " << source_path("scenes/cell.yaml") << "\nprogram: "
                          << source_path("scenes/deadlock.task") << "\nrobots: {r1: puma, r2: kuka}\n";
  const Outcome bad = cli.run("serve " + shell_quote(scenario.string()) + " --port 0");
  EXPECT_EQ(bad.status, 2) << bad.err;
  EXPECT_NE(bad.err.find("kuka"), std::string::npos) << bad.err;
}

// --realtime: the run goes paced by the wall clock from the start with --play, its frames "playing" with the time
// rising, and pause holds it; --speed without --realtime is refused.
TEST(TwinServe, RealTimePlaysFromTheStartAndPauses) {
  BackgroundTwin twin({"serve", source_path("scenes/exchange.yaml"), "--port", "0", "--realtime", "--speed", "4",
                       "--play"});
  ASSERT_TRUE(twin.wait_for("/ (Ctrl-C stops)", 60s)) << twin.output();
  EXPECT_NE(twin.output().find("real time at speed 4, serving"), std::string::npos) << twin.output();
  WsViewer v(served_port(twin.output()));
  const auto frame_at = [](double t) {
    return [t](const json& m) { return m.value("type", "") == "frame" && m["state"] == "playing" && m["t"] > t; };
  };
  const json early = v.wait_for(frame_at(0.1));
  ASSERT_TRUE(early.is_object()) << twin.output();
  const json later = v.wait_for(frame_at(early["t"].get<double>() + 0.5));
  ASSERT_TRUE(later.is_object()) << "the time did not rise as the run went";
  v.send(R"({"type":"command","command":"pause"})");
  const json held = v.wait_for([](const json& m) { return m.value("type", "") == "frame" && m["state"] != "playing"; });
  ASSERT_TRUE(held.is_object());
  EXPECT_EQ(held["state"], "paused");
  v.close();
  EXPECT_EQ(twin.stop(SIGINT), 130) << twin.output();

  TwinCli cli("cw-serve-cli");
  const Outcome speed = cli.run("serve " + shell_quote(source_path("scenes/exchange.yaml")) + " --speed 2 --port 0");
  EXPECT_EQ(speed.status, 2) << speed.err;
  EXPECT_NE(speed.err.find("--speed"), std::string::npos) << speed.err;
  EXPECT_NE(speed.err.find("add --realtime"), std::string::npos) << speed.err;
}

TEST(TwinServe, AnAddressItCannotListenOnIsRefusedWithTheReason) {
  TwinCli cli("cw-serve-cli");
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const Outcome bad = cli.run("serve " + scenario + " --bind not-an-address --port 0");
  EXPECT_EQ(bad.status, 2) << bad.err;
  EXPECT_NE(bad.err.find("'not-an-address' is not an IP address"), std::string::npos) << bad.err;
  // 203.0.113.77 (TEST-NET-3, RFC 5737, documentation only) is no address of this machine.
  const Outcome elsewhere = cli.run("serve " + scenario + " --bind 203.0.113.77 --port 0");
  EXPECT_EQ(elsewhere.status, 2) << elsewhere.err;
  EXPECT_NE(elsewhere.err.find("203.0.113.77:0"), std::string::npos) << elsewhere.err;
  EXPECT_NE(elsewhere.err.find("cannot listen"), std::string::npos) << elsewhere.err;
  const Outcome port = cli.run("serve " + scenario + " --port 70000");
  EXPECT_EQ(port.status, 2) << port.err;
  EXPECT_NE(port.err.find("70000 is not a TCP port"), std::string::npos) << port.err;
}

}  // namespace
}  // namespace cellwright::testing
