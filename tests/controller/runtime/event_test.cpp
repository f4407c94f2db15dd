#include "cellwright/runtime/event.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "controller/runtime/handshake.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::eventually;
using cellwright::testing::ThreadGroup;
using namespace std::chrono_literals;

TEST(RuntimeEvent, StartsAsRequested) {
  EXPECT_FALSE(Event(Event::Kind::manual_reset).is_set());
  EXPECT_TRUE(Event(Event::Kind::manual_reset, true).is_set());
  Event e(Event::Kind::auto_reset, true);
  EXPECT_TRUE(e.wait_for(0ms));
  EXPECT_FALSE(e.is_set());
}

TEST(RuntimeEvent, ManualResetReleasesEveryWaiterAndStaysSetUntilReset) {
  Event e(Event::Kind::manual_reset);
  constexpr int kWaiters = 4;
  std::atomic<int> released{0};
  ThreadGroup waiters([&] {
    while (released < kWaiters) {
      e.set();
      std::this_thread::yield();
    }
  });
  for (int i = 0; i < kWaiters; ++i) {
    waiters.spawn([&] {
      e.wait();
      ++released;
    });
  }
  ASSERT_TRUE(eventually([&] { return e.waiters() == kWaiters; }));
  EXPECT_EQ(released, 0);
  e.set();
  waiters.join();
  EXPECT_EQ(released, kWaiters);
  EXPECT_TRUE(e.is_set());
  EXPECT_TRUE(e.wait_for(0ms));  // still set: later waits pass too
  e.reset();
  EXPECT_FALSE(e.is_set());
  EXPECT_FALSE(e.wait_for(0ms));
}

// Each set() of an auto-reset event lets exactly one of the blocked waiters through. Between sets the state is
// stable (the signal is consumed, the rest stay blocked), so the counts are checked exactly, not raced.
TEST(RuntimeEvent, AutoResetWakesExactlyOneWaiterPerSet) {
  Event e(Event::Kind::auto_reset);
  constexpr int kWaiters = 5;
  std::atomic<int> released{0};
  ThreadGroup waiters([&] {
    while (released < kWaiters) {
      e.set();
      std::this_thread::yield();
    }
  });
  for (int i = 0; i < kWaiters; ++i) {
    waiters.spawn([&] {
      e.wait();
      ++released;
    });
  }
  ASSERT_TRUE(eventually([&] { return e.waiters() == kWaiters; }));
  for (int k = 1; k <= kWaiters; ++k) {
    e.set();
    ASSERT_TRUE(eventually([&] { return released == k; })) << "set " << k << " released nobody";
    EXPECT_FALSE(e.is_set()) << "the released waiter must consume the signal";
    EXPECT_EQ(e.waiters(), static_cast<std::size_t>(kWaiters - k));
    EXPECT_EQ(released, k) << "set " << k << " released more than one waiter";
  }
  waiters.join();
}

TEST(RuntimeEvent, AutoResetKeepsASignalNobodyWaitedForUntilTheNextWait) {
  Event e(Event::Kind::auto_reset);
  e.set();
  EXPECT_TRUE(e.is_set());
  EXPECT_TRUE(e.wait_for(0ms));
  EXPECT_FALSE(e.wait_for(0ms));
}

TEST(RuntimeEvent, AutoResetSignalsDoNotAccumulate) {
  Event e(Event::Kind::auto_reset);
  e.set();
  e.set();
  EXPECT_TRUE(e.wait_for(0ms));
  EXPECT_FALSE(e.wait_for(0ms)) << "two sets with no wait between must release one wait, as a Win32 event";
}

TEST(RuntimeEvent, ResetWithdrawsAPendingSignal) {
  Event e(Event::Kind::auto_reset);
  e.set();
  e.reset();
  EXPECT_FALSE(e.wait_for(0ms));
}

TEST(RuntimeEvent, WaitForTimesOutWhenNobodySets) {
  Event e(Event::Kind::manual_reset);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(e.wait_for(2ms));
  EXPECT_GE(std::chrono::steady_clock::now() - start, 2ms);
  EXPECT_EQ(e.waiters(), 0u);
}

TEST(RuntimeEvent, WaitForReturnsTrueWhenSetWhileWaiting) {
  Event e(Event::Kind::auto_reset);
  bool got = false;
  ThreadGroup waiter([&] { e.set(); });
  waiter.spawn([&] { got = e.wait_for(std::chrono::hours(1)); });
  ASSERT_TRUE(eventually([&] { return e.waiters() == 1; }));
  e.set();
  waiter.join();
  EXPECT_TRUE(got);
  EXPECT_FALSE(e.is_set());
}

}  // namespace
}  // namespace cellwright::runtime
