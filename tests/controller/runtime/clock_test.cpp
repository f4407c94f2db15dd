#include "cellwright/runtime/clock.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <latch>
#include <limits>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/runtime/event.hpp"
#include "controller/runtime/handshake.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::eventually;
using cellwright::testing::ThreadGroup;
using namespace std::chrono_literals;

TEST(RuntimeVirtualClock, StartsAtZeroAndOnlyMovesForward) {
  VirtualClock clock;
  EXPECT_EQ(clock.now(), SimDuration(0));
  EXPECT_EQ(clock.advance(2ms), SimDuration(2ms));
  EXPECT_EQ(clock.advance(SimDuration(0)), SimDuration(2ms));
  EXPECT_EQ(clock.advance(500us), SimDuration(2500us));
  EXPECT_EQ(clock.now(), SimDuration(2500us));
  EXPECT_THROW(clock.advance(SimDuration(-1)), InternalError);
  EXPECT_EQ(clock.now(), SimDuration(2500us));
}

// One thread may play every participant in turn: it never blocks, because each await_turn is for the participant
// whose turn it is. This pins down the bookkeeping without threads.
TEST(RuntimeLockstep, HandsTheTurnOnInIdOrderAndCountsRounds) {
  LockstepScheduler s(3);
  EXPECT_EQ(s.present(), 3u);
  for (std::uint64_t round = 0; round < 2; ++round) {
    for (LockstepScheduler::Id id = 0; id < 3; ++id) {
      EXPECT_EQ(s.rounds(), round);
      ASSERT_TRUE(s.await_turn(id));
      s.yield(id);
    }
  }
  EXPECT_EQ(s.rounds(), 2u);
  EXPECT_EQ(s.turns(), 6u);
}

TEST(RuntimeLockstep, SkipsParticipantsThatLeft) {
  LockstepScheduler s(3);
  s.leave(1);
  s.leave(1);  // idempotent
  EXPECT_EQ(s.present(), 2u);
  for (int round = 0; round < 2; ++round) {
    ASSERT_TRUE(s.await_turn(0));
    s.yield(0);
    ASSERT_TRUE(s.await_turn(2));  // 1 is skipped: 2 is next
    s.yield(2);
  }
  EXPECT_EQ(s.rounds(), 2u);
  // The holder leaving passes the turn on.
  ASSERT_TRUE(s.await_turn(0));
  s.leave(0);
  ASSERT_TRUE(s.await_turn(2));
  s.yield(2);
  ASSERT_TRUE(s.await_turn(2));  // alone now: every turn is 2's
  s.yield(2);
}

TEST(RuntimeLockstep, MisuseIsReportedNotIgnored) {
  EXPECT_THROW(LockstepScheduler(0), InternalError);
  LockstepScheduler s(2);
  EXPECT_THROW(s.yield(0), InternalError);             // not holding the turn yet
  EXPECT_THROW((void)s.await_turn(2), InternalError);  // no such participant
  ASSERT_TRUE(s.await_turn(0));
  EXPECT_THROW((void)s.await_turn(0), InternalError);  // already holding it
  EXPECT_THROW(s.yield(1), InternalError);             // 1 does not hold the turn
  s.yield(0);
  s.leave(1);
  EXPECT_THROW((void)s.await_turn(1), InternalError);  // left
  EXPECT_THROW(s.leave(7), InternalError);
}

TEST(RuntimeLockstep, StopReleasesEveryParkedParticipant) {
  LockstepScheduler s(3);
  std::vector<int> results(3, -1);
  ThreadGroup threads([&] { s.stop(); });
  for (LockstepScheduler::Id id = 1; id < 3; ++id) {
    threads.spawn([&, id] { results[id] = s.await_turn(id) ? 1 : 0; });
  }
  ASSERT_TRUE(eventually([&] { return s.waiting() == 2; }));  // both parked: it is 0's turn
  s.stop();
  s.stop();  // idempotent
  threads.join();
  EXPECT_EQ(results[1], 0);
  EXPECT_EQ(results[2], 0);
  EXPECT_TRUE(s.stopped());
  EXPECT_FALSE(s.await_turn(0));
}

// The shared workload of the determinism tests: each step reads and changes shared state and logs the result, so the
// log records the exact order in which the participants ran.
struct SharedLog {
  std::string text;
  std::uint64_t value = 1;
  void step(std::size_t id, int turn) {
    value = value * 6364136223846793005ULL + id + 1;
    text += fmt::format("turn {} participant {} value {:016x}\n", turn, id, value);
  }
};

// The log of the fixed order: every participant once per round, in id order.
std::string expected_log(std::size_t participants, int rounds) {
  SharedLog log;
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t id = 0; id < participants; ++id) log.step(id, r);
  }
  return log.text;
}

// Runs `participants` threads for `rounds` turns each under a scheduler, all released together by a latch.
std::string run_under_scheduler(std::size_t participants, int rounds) {
  LockstepScheduler scheduler(participants);
  SharedLog log;  // touched only inside turns: the scheduler orders them, no other lock needed
  std::latch go(static_cast<std::ptrdiff_t>(participants));
  std::vector<std::thread> threads;
  for (std::size_t id = 0; id < participants; ++id) {
    threads.emplace_back([&, id] {
      LockstepScheduler::Seat seat(scheduler, id);
      go.arrive_and_wait();
      for (int turn = 0; turn < rounds && seat.await_turn(); ++turn) {
        log.step(id, turn);
        seat.yield();
      }
    });
  }
  for (auto& t : threads) t.join();
  return log.text;
}

TEST(RuntimeLockstep, SharedLogIsByteIdenticalOverFiftyRuns) {
  constexpr std::size_t kParticipants = 4;
  constexpr int kRounds = 200;
  const std::string expected = expected_log(kParticipants, kRounds);
  for (int run = 0; run < 50; ++run) {
    ASSERT_EQ(run_under_scheduler(kParticipants, kRounds), expected) << "run " << run;
  }
}

// Threads that arrive in the worst order (last participant first, participant 0 last) still run in id order.
TEST(RuntimeLockstep, OrderIsEnforcedWhateverOrderTheThreadsArriveIn) {
  constexpr std::size_t kParticipants = 4;
  constexpr int kRounds = 5;
  LockstepScheduler scheduler(kParticipants);
  SharedLog log;
  ThreadGroup threads([&] { scheduler.stop(); });
  for (std::size_t k = 0; k < kParticipants; ++k) {
    const std::size_t id = kParticipants - 1 - k;
    threads.spawn([&, id] {
      LockstepScheduler::Seat seat(scheduler, id);
      for (int turn = 0; turn < kRounds && seat.await_turn(); ++turn) {
        log.step(id, turn);
        seat.yield();
      }
    });
    if (id != 0) {  // every later participant is parked before the next (lower) one even starts
      ASSERT_TRUE(eventually([&] { return scheduler.waiting() == k + 1; }));
    }
  }
  threads.join();
  EXPECT_EQ(log.text, expected_log(kParticipants, kRounds));
}

// The control for the two tests above: without the scheduler the same workload, with the threads arriving in that
// worst order, gives another log, so the comparison with expected_log() does detect a wrong order.
TEST(RuntimeLockstep, BypassingTheSchedulerChangesTheLog) {
  constexpr std::size_t kParticipants = 4;
  constexpr int kRounds = 5;
  SharedLog log;
  for (std::size_t k = 0; k < kParticipants; ++k) {
    const std::size_t id = kParticipants - 1 - k;
    std::thread t([&, id] {
      for (int turn = 0; turn < kRounds; ++turn) log.step(id, turn);
    });
    t.join();
  }
  EXPECT_NE(log.text, expected_log(kParticipants, kRounds));
}

TEST(RuntimeLockstep, AParticipantThatLeavesIsSkippedByTheOthers) {
  constexpr int kRounds = 6;
  constexpr int kLeavesAfter = 2;
  LockstepScheduler scheduler(3);
  SharedLog log;
  std::vector<std::thread> threads;
  for (std::size_t id = 0; id < 3; ++id) {
    threads.emplace_back([&, id] {
      LockstepScheduler::Seat seat(scheduler, id);
      const int turns = id == 1 ? kLeavesAfter : kRounds;
      for (int turn = 0; turn < turns && seat.await_turn(); ++turn) {
        log.step(id, turn);
        seat.yield();
      }
    });
  }
  for (auto& t : threads) t.join();
  SharedLog expected;
  for (int r = 0; r < kRounds; ++r) {
    expected.step(0, r);
    if (r < kLeavesAfter) expected.step(1, r);
    expected.step(2, r);
  }
  EXPECT_EQ(log.text, expected.text);
}

TEST(RuntimeLockstep, AParticipantThatThrowsLeavesAndTheOthersCarryOn) {
  constexpr int kRounds = 5;
  LockstepScheduler scheduler(3);
  SharedLog log;
  bool threw = false;
  std::vector<std::thread> threads;
  for (std::size_t id = 0; id < 3; ++id) {
    threads.emplace_back([&, id] {
      try {
        LockstepScheduler::Seat seat(scheduler, id);
        for (int turn = 0; turn < kRounds && seat.await_turn(); ++turn) {
          if (id == 1 && turn == 3) throw std::runtime_error("robot thread failed");  // while holding the turn
          log.step(id, turn);
          seat.yield();
        }
      } catch (const std::runtime_error&) {
        threw = true;  // written before the Seat left, read after join
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_TRUE(threw);
  SharedLog expected;
  for (int r = 0; r < kRounds; ++r) {
    expected.step(0, r);
    if (r < 3) expected.step(1, r);
    expected.step(2, r);
  }
  EXPECT_EQ(log.text, expected.text);
}

// The runtime's shape in miniature: the simulation participant advances virtual time 2 ms a turn, the image
// participant updates every 400 ms of virtual time and sets an event, the task participant reacts to the event in the
// same round. The log is fixed by virtual time alone.
std::string run_miniature_cell() {
  constexpr SimDuration kStep = 2ms;
  constexpr SimDuration kImagePeriod = 400ms;
  constexpr SimDuration kEnd = 2s;
  LockstepScheduler scheduler(3);
  VirtualClock clock;
  Event model_updated(Event::Kind::auto_reset);
  std::string log;
  std::thread simulation([&] {
    LockstepScheduler::Seat seat(scheduler, 0);
    while (seat.await_turn()) {
      if (clock.now() >= kEnd) {
        scheduler.stop();
        break;
      }
      clock.advance(kStep);
      seat.yield();
    }
  });
  std::thread image([&] {
    LockstepScheduler::Seat seat(scheduler, 1);
    SimDuration due = kImagePeriod;
    while (seat.await_turn()) {
      if (clock.now() >= due) {
        log += fmt::format("{} image: model updated\n", clock.now().count());
        due += kImagePeriod;
        model_updated.set();
      }
      seat.yield();
    }
  });
  std::thread task([&] {
    LockstepScheduler::Seat seat(scheduler, 2);
    while (seat.await_turn()) {
      if (model_updated.wait_for(0ms)) log += fmt::format("{} task: woke\n", clock.now().count());
      seat.yield();
    }
  });
  simulation.join();
  image.join();
  task.join();
  return log;
}

TEST(RuntimeLockstep, VirtualTimeDrivesPeriodicThreadsDeterministically) {
  std::string expected;
  for (SimDuration t = 400ms; t <= 2s; t += 400ms) {
    expected += fmt::format("{} image: model updated\n{} task: woke\n", t.count(), t.count());
  }
  for (int run = 0; run < 20; ++run) ASSERT_EQ(run_miniature_cell(), expected) << "run " << run;
}

// ---- Event-driven turns and threads that take several participants' turns ----

// A small script over 4 participants, run by whatever threads `threads_of` says. Participant 0 is the clock: it
// advances 10 ms a turn and stops the run at 60 ms. 1 sleeps 25 ms after each turn. 2 sleeps until notified and, when
// it runs, notifies 3. 3 runs every round and notifies 2 at 30 ms. Returns "id@ms" per turn taken, in order.
struct ScriptRun {
  std::string order;
  std::uint64_t skipped = 0, handoffs = 0, turns = 0, rounds = 0;
};

ScriptRun run_script(std::vector<std::size_t> threads_of) {
  VirtualClock clock;
  LockstepScheduler scheduler(threads_of, &clock);
  ScriptRun out;
  const auto turn = [&](LockstepScheduler::Id id) -> std::optional<Wake> {  // nothing: the run ends
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(clock.now()).count();
    out.order += fmt::format("{}@{} ", id, ms);
    switch (id) {
      case 0:
        if (clock.now() >= 60ms) return std::nullopt;
        clock.advance(10ms);
        return Wake::next_round();
      case 1:
        return Wake::at(clock.now() + 25ms);
      case 2:
        scheduler.notify(3);
        return Wake::on_notify();
      default:
        if (clock.now() == 30ms) scheduler.notify(2);
        return Wake::next_round();
    }
  };
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < scheduler.threads(); ++t) {
    threads.emplace_back([&, t] {
      LockstepScheduler::Seat seat(scheduler, LockstepScheduler::Thread{t});
      while (seat.await_turn()) {
        const std::optional<Wake> next = turn(seat.id());
        if (!next) {
          scheduler.stop();
          break;
        }
        seat.yield(*next);
      }
    });
  }
  for (auto& t : threads) t.join();
  out.skipped = scheduler.skipped();
  out.handoffs = scheduler.handoffs();
  out.turns = scheduler.turns();
  out.rounds = scheduler.rounds();
  return out;
}

// What the script must do, worked out by hand: 1 runs at 10 ms, then not before 35 ms (so at 40 ms), then not
// before 65 ms (never); 2 runs at 10 ms (every participant starts awake), then only when 3 has notified it at 30 ms:
// 3's seat is after 2's, so in the next round (40 ms); 3 every round.
const char* const kScriptOrder =
    "0@0 1@10 2@10 3@10 "
    "0@10 3@20 "
    "0@20 3@30 "
    "0@30 1@40 2@40 3@40 "
    "0@40 3@50 "
    "0@50 3@60 "
    "0@60 ";

TEST(RuntimeLockstep, ASleeperIsNotWokenBeforeItsTimeAndANotifiedOneRunsInTheFixedOrder) {
  const ScriptRun one = run_script({0, 0, 0, 0});
  EXPECT_EQ(one.order, kScriptOrder);
  // Passed over: 1 and 2 each in the rounds at 20, 30, 50 and 60 ms.
  EXPECT_EQ(one.skipped, 8u);
  EXPECT_EQ(one.handoffs, 0u);  // one thread: the turn never leaves it
  EXPECT_EQ(one.rounds, 6u);
}

TEST(RuntimeLockstep, TheOrderIsTheSameWhicheverThreadsTakeTheTurns) {
  for (int run = 0; run < 20; ++run) {
    const ScriptRun each = run_script({0, 1, 2, 3});
    const ScriptRun mixed = run_script({0, 0, 1, 1});
    ASSERT_EQ(each.order, kScriptOrder) << "run " << run;
    ASSERT_EQ(mixed.order, kScriptOrder) << "run " << run;
    ASSERT_EQ(each.skipped, 8u);
    // A thread each: every turn but the last (0's at 60 ms, which ends the run) is handed to another thread.
    ASSERT_EQ(each.handoffs + 1, each.turns);
    ASSERT_LT(mixed.handoffs, each.handoffs);
  }
}

TEST(RuntimeLockstep, ANotifyBeforeTheSleepCountsAndOneAfterTheSeatWaitsForTheNextRound) {
  VirtualClock clock;
  LockstepScheduler s(std::vector<std::size_t>{0, 0}, &clock);
  LockstepScheduler::Seat seat(s, LockstepScheduler::Thread{0});
  // Yields the turn held, waits for the next and says whose it is.
  const auto pass = [&](Wake next) {
    seat.yield(next);
    EXPECT_TRUE(seat.await_turn());
    return seat.id();
  };
  ASSERT_TRUE(seat.await_turn());
  ASSERT_EQ(seat.id(), 0u);
  s.notify(1);  // before 1 sleeps: sticky
  ASSERT_EQ(pass(Wake::next_round()), 1u);
  EXPECT_EQ(pass(Wake::on_notify()), 0u);  // the earlier notify woke this turn of 1's, not the next: 1 sleeps now
  EXPECT_EQ(pass(Wake::next_round()), 0u);  // 1 passed over
  EXPECT_EQ(s.skipped(), 1u);
  EXPECT_EQ(s.rounds(), 2u);
  s.notify(1);
  EXPECT_EQ(pass(Wake::next_round()), 1u);
  EXPECT_EQ(pass(Wake::at(1s)), 0u);  // a sleeper until a time is also woken early by a notify
  s.notify(1);
  EXPECT_EQ(pass(Wake::next_round()), 1u);
  EXPECT_EQ(clock.now(), SimDuration(0));
  seat.yield();
}

TEST(RuntimeLockstep, WithEveryoneAsleepTheSchedulerIdlesUntilANotifyOrStop) {
  VirtualClock clock;
  LockstepScheduler s(std::vector<std::size_t>{0, 1, 0}, &clock);
  std::vector<std::string> ran;
  std::mutex ran_mutex;
  ThreadGroup threads([&] { s.stop(); });
  for (std::size_t t = 0; t < 2; ++t) {
    threads.spawn([&, t] {
      LockstepScheduler::Seat seat(s, LockstepScheduler::Thread{t});
      while (seat.await_turn()) {
        {
          std::lock_guard lock(ran_mutex);
          ran.push_back(fmt::format("{}", seat.id()));
        }
        seat.yield(Wake::on_notify());
      }
    });
  }
  ASSERT_TRUE(eventually([&] { return s.waiting() == 2 && s.turns() == 3; }));  // one round, then all asleep
  EXPECT_EQ(s.skipped(), 3u);
  s.notify(2);  // from outside: 2 takes the turn, then all sleep again
  ASSERT_TRUE(eventually([&] { return s.waiting() == 2 && s.turns() == 4; }));
  s.stop();  // wakes the sleepers' threads: await_turn returns false
  threads.join();
  EXPECT_EQ(ran, (std::vector<std::string>{"0", "1", "2", "2"}));
}

TEST(RuntimeLockstep, StopReleasesAThreadOfSeveralAndSleepers) {
  LockstepScheduler s(std::vector<std::size_t>{0, 1, 1});
  std::optional<LockstepScheduler::Id> got{7};
  ThreadGroup threads([&] { s.stop(); });
  threads.spawn([&] { got = s.await_turn(LockstepScheduler::Thread{1}); });
  ASSERT_TRUE(eventually([&] { return s.waiting() == 1; }));  // it is 0's turn: thread 1 is parked
  s.stop();
  threads.join();
  EXPECT_FALSE(got.has_value());
  EXPECT_FALSE(s.await_turn(LockstepScheduler::Thread{0}).has_value());
}

TEST(RuntimeLockstep, MisuseOfThreadsAndWakesIsReported) {
  EXPECT_THROW(LockstepScheduler(std::vector<std::size_t>{}), InternalError);
  EXPECT_THROW(LockstepScheduler(std::vector<std::size_t>{0, 2}), InternalError);  // thread 1 serves nobody
  LockstepScheduler s(std::vector<std::size_t>{0, 0, 1});  // no clock
  EXPECT_EQ(s.threads(), 2u);
  EXPECT_EQ(s.thread_of(2), 1u);
  EXPECT_THROW((void)s.await_turn(LockstepScheduler::Thread{2}), InternalError);
  EXPECT_THROW(s.notify(3), InternalError);
  ASSERT_EQ(s.await_turn(LockstepScheduler::Thread{0}), std::optional<LockstepScheduler::Id>(0));
  EXPECT_THROW((void)s.await_turn(LockstepScheduler::Thread{0}), InternalError);  // already holds it
  EXPECT_THROW(s.yield(0, Wake::at(1s)), InternalError);                          // no clock to wake it by
  s.yield(0);
  s.leave(2);
  EXPECT_THROW((void)s.await_turn(LockstepScheduler::Thread{1}), InternalError);  // all of thread 1 left
}

// A wall clock that moves only when the pacer sleeps, or when the test says so.
struct FakeWall {
  RealtimePacer::WallClock::time_point now{std::chrono::seconds(1000)};
  std::vector<RealtimePacer::WallClock::time_point> sleeps;
  RealtimePacer::WallTime hooks() {
    return {[this] { return now; },
            [this](RealtimePacer::WallClock::time_point t) {
              sleeps.push_back(t);
              now = t;
            }};
  }
};

TEST(RuntimePacer, SleepsUntilTheWallTimeOfEachSimulationTime) {
  FakeWall wall;
  const auto t0 = wall.now;
  RealtimePacer pacer(1.0, wall.hooks());
  EXPECT_EQ(pacer.pace(10ms), RealtimePacer::WallClock::duration::zero());
  EXPECT_EQ(pacer.pace(25ms), RealtimePacer::WallClock::duration::zero());
  EXPECT_EQ(wall.sleeps, (std::vector{t0 + 10ms, t0 + 25ms}));
}

TEST(RuntimePacer, ReportsHowLateTheCallerIsWithoutSleeping) {
  FakeWall wall;
  const auto t0 = wall.now;
  RealtimePacer pacer(1.0, wall.hooks());
  wall.now = t0 + 30ms;  // a step took too long
  EXPECT_EQ(pacer.pace(20ms), std::chrono::duration_cast<RealtimePacer::WallClock::duration>(10ms));
  EXPECT_TRUE(wall.sleeps.empty());
}

TEST(RuntimePacer, SpeedScalesWallTime) {
  FakeWall wall;
  const auto t0 = wall.now;
  RealtimePacer fast(2.0, wall.hooks());
  (void)fast.pace(10ms);
  RealtimePacer slow(0.5, wall.hooks());  // anchored at t0 + 5ms
  (void)slow.pace(10ms);
  EXPECT_EQ(wall.sleeps, (std::vector{t0 + 5ms, t0 + 25ms}));
  EXPECT_EQ(fast.speed(), 2.0);
}

TEST(RuntimePacer, AnchorRestartsPacingFromTheCurrentSimulationTime) {
  FakeWall wall;
  RealtimePacer pacer(1.0, wall.hooks());
  wall.now += 10s;  // paused for ten seconds
  const auto resumed = wall.now;
  pacer.anchor(3s);
  EXPECT_EQ(pacer.pace(3s + 40ms), RealtimePacer::WallClock::duration::zero());
  EXPECT_EQ(wall.sleeps, (std::vector{resumed + 40ms}));
}

TEST(RuntimePacer, RejectsSpeedsThatCannotPace) {
  EXPECT_THROW(RealtimePacer(0.0), InternalError);
  EXPECT_THROW(RealtimePacer(-1.0), InternalError);
  EXPECT_THROW(RealtimePacer(std::numeric_limits<double>::infinity()), InternalError);
  EXPECT_THROW(RealtimePacer(std::numeric_limits<double>::quiet_NaN()), InternalError);
}

TEST(RuntimePacer, OnTheRealClockSimulationTimeNeverRunsAheadOfWallTime) {
  const auto start = std::chrono::steady_clock::now();
  RealtimePacer pacer(1.0);
  for (int i = 1; i <= 3; ++i) {
    (void)pacer.pace(SimDuration(i * 1ms));
    EXPECT_GE(std::chrono::steady_clock::now() - start, i * 1ms);
  }
}

}  // namespace
}  // namespace cellwright::runtime
