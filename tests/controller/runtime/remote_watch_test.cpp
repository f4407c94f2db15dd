// The runtime's watch over a remote robot's link (remote_watch.hpp): a lost agent as a link_lost fault diagnosed by
// the decision tree, the cell stopped or a new agent taken on. Driven step by step with a link whose state the test
// sets (no DDS, no threads: the simulated time is what the test passes to step()). The DDS link in other processes is
// tested in tests/distributed/link_test.cpp.
#include "cellwright/runtime/remote_watch.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace cellwright::runtime {
namespace {

using std::chrono::milliseconds;
using ::testing::HasSubstr;

class SetLink : public RemoteLink {
 public:
  void start() override {}
  void stop() override {}
  LinkState state() const override { return now; }
  bool resend() override {
    ++resends;
    return now.present && now.in_flight >= 0;
  }
  LinkState now;
  int resends = 0;
};

struct Watched {
  explicit Watched(SimDuration rejoin_wait = SimDuration{0}, RecoveryOptions options = {})
      : recovery(std::move(options)), watch(1, "r2", "melfa", link, statuses, log, recovery, rejoin_wait) {
    link.now.session = 7;
  }
  // The agent lost, with primitive `primitive` in flight (-1: idle).
  void lose(int primitive) {
    link.now.present = false;
    ++link.now.losses;
    link.now.lost_detail = "no sign of life";
    link.now.in_flight = primitive;
  }
  std::vector<nlohmann::json> events(const std::string& type) const {
    std::vector<nlohmann::json> out;
    for (const auto& l : log.lines()) {
      auto j = nlohmann::json::parse(l);
      if (j["type"] == type) out.push_back(j);
    }
    return out;
  }
  RobotStatus status() {
    RobotStatus s;
    EXPECT_EQ(statuses.try_pop(s), QueueStatus::ok);
    return s;
  }

  SetLink link;
  MessageQueue<RobotStatus> statuses{8};
  EventLog log;
  RecoveryOptions recovery;
  RemoteWatch watch;
};

TEST(RemoteWatch, AnAgentLostWithACommandInFlightIsALinkLostFaultAndStopsTheCellWhenNoRejoinIsWaitedFor) {
  Watched w;
  EXPECT_FALSE(w.watch.step(milliseconds(10)));
  w.lose(3);
  EXPECT_TRUE(w.watch.step(milliseconds(20)));
  const auto faults = w.events("fault_detected");
  ASSERT_EQ(faults.size(), 1u);
  EXPECT_EQ(faults[0]["robot"], "r2");
  EXPECT_EQ(faults[0]["primitive"], 3);
  EXPECT_EQ(faults[0]["symptom"], "link_lost");
  EXPECT_EQ(faults[0]["detail"], "the agent of melfa was lost with primitive 3 in hand: no sign of life");
  const auto diagnoses = w.events("diagnosis");
  ASSERT_EQ(diagnoses.size(), 1u);
  EXPECT_EQ(diagnoses[0]["action"], "reset_rehome");  // the standard tree, a retry left
  const RobotStatus s = w.status();
  EXPECT_EQ(s.robot, 1u);
  EXPECT_EQ(s.index, RobotStatus::kNoCommand);
  EXPECT_EQ(s.outcome, CommandOutcome::kFailed);
  EXPECT_TRUE(s.stop_cell);
  EXPECT_THAT(s.reason, HasSubstr("link_dropped: the agent of melfa was lost with primitive 3 in hand"));
  EXPECT_THAT(s.reason, HasSubstr("the run's rejoin wait is 0"));
  EXPECT_EQ(w.events("recovery_end").at(0)["ok"], false);
  EXPECT_EQ(w.watch.phase(), RemoteWatch::Phase::kStopped);
  w.link.now.present = true;  // nothing more once stopped
  EXPECT_FALSE(w.watch.step(milliseconds(30)));
  EXPECT_EQ(w.log.lines().size(), 3u);
}

TEST(RemoteWatch, AnAgentLostWhileIdleIsNoFaultUntilItHasWork) {
  Watched w;
  w.lose(-1);
  EXPECT_FALSE(w.watch.step(milliseconds(10)));
  EXPECT_TRUE(w.log.lines().empty());
  w.link.now.in_flight = 4;  // a command sent to no agent
  EXPECT_TRUE(w.watch.step(milliseconds(20)));
  EXPECT_EQ(w.events("fault_detected").at(0)["primitive"], 4);
}

TEST(RemoteWatch, OutOfRetriesTheTreeStopsTheCellAndWithoutRecoveryTheRunFails) {
  RecoveryOptions none_left;
  none_left.max_attempts = 0;
  Watched w(std::chrono::seconds(10), none_left);
  w.lose(2);
  EXPECT_TRUE(w.watch.step(milliseconds(10)));
  EXPECT_EQ(w.events("diagnosis").at(0)["cause"], "link_down");
  EXPECT_THAT(w.status().reason, HasSubstr("link_down: the agent of melfa was lost"));

  RecoveryOptions off;
  off.enabled = false;
  Watched f(std::chrono::seconds(10), off);
  f.lose(2);
  EXPECT_TRUE(f.watch.step(milliseconds(10)));
  EXPECT_TRUE(f.events("diagnosis").empty());
  const RobotStatus s = f.status();
  EXPECT_FALSE(s.stop_cell);  // a failed run
  EXPECT_EQ(s.reason, "the agent of melfa was lost with primitive 2 in hand: no sign of life");
}

TEST(RemoteWatch, ANewAgentWithinTheRejoinWaitIsSentTheInterruptedCommandAgain) {
  Watched w(std::chrono::seconds(5));
  EXPECT_FALSE(w.watch.step(milliseconds(10)));
  w.lose(3);
  EXPECT_FALSE(w.watch.step(milliseconds(20)));  // waiting
  EXPECT_EQ(w.watch.phase(), RemoteWatch::Phase::kWaiting);
  EXPECT_FALSE(w.watch.step(milliseconds(1000)));
  w.link.now.present = true;
  w.link.now.session = 8;
  EXPECT_FALSE(w.watch.step(milliseconds(1010)));
  EXPECT_EQ(w.link.resends, 1);
  EXPECT_EQ(w.watch.phase(), RemoteWatch::Phase::kUp);
  const auto ends = w.events("recovery_end");
  ASSERT_EQ(ends.size(), 1u);
  EXPECT_EQ(ends[0]["ok"], true);
  EXPECT_THAT(ends[0]["detail"].get<std::string>(), HasSubstr("a new agent of melfa (session 8)"));
  EXPECT_EQ(w.statuses.size(), 0u);
  // Lost again later: a second fault, counted towards retries_left.
  w.lose(5);
  EXPECT_FALSE(w.watch.step(milliseconds(2000)));
  EXPECT_EQ(w.events("fault_detected").size(), 2u);
}

TEST(RemoteWatch, TheSameAgentHeardAgainIsSentNothingAgain) {
  Watched w(std::chrono::seconds(5));
  EXPECT_FALSE(w.watch.step(milliseconds(10)));
  w.lose(3);
  EXPECT_FALSE(w.watch.step(milliseconds(20)));
  w.link.now.present = true;  // session 7 still
  EXPECT_FALSE(w.watch.step(milliseconds(30)));
  EXPECT_EQ(w.link.resends, 0);
  EXPECT_THAT(w.events("recovery_end").at(0)["detail"].get<std::string>(), HasSubstr("the same session"));
}

TEST(RemoteWatch, ALoadedArmIsNotTakenOnByANewAgentAndNoAgentByTheDeadlineStopsTheCell) {
  Watched w(std::chrono::seconds(5));
  EXPECT_FALSE(w.watch.step(milliseconds(10)));
  w.lose(3);
  w.link.now.holding = "A";
  EXPECT_FALSE(w.watch.step(milliseconds(20)));
  w.link.now.present = true;
  w.link.now.session = 9;
  EXPECT_TRUE(w.watch.step(milliseconds(30)));
  EXPECT_EQ(w.link.resends, 0);
  EXPECT_THAT(w.status().reason, HasSubstr("melfa holds A: re-homing would carry it"));

  Watched late(std::chrono::seconds(5));
  EXPECT_FALSE(late.watch.step(milliseconds(10)));
  late.lose(3);
  EXPECT_FALSE(late.watch.step(milliseconds(20)));
  EXPECT_FALSE(late.watch.step(milliseconds(5010)));
  EXPECT_TRUE(late.watch.step(milliseconds(5020)));
  EXPECT_THAT(late.status().reason, HasSubstr("no agent came back within 5.0000 s"));
}

}  // namespace
}  // namespace cellwright::runtime
