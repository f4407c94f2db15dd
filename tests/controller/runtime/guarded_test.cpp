#include "cellwright/runtime/guarded.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <latch>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cellwright::runtime {
namespace {

struct Pair {
  long a = 0;
  long b = 0;  // always -a outside a write
};

TEST(RuntimeGuarded, ConstructsInPlaceAndReturnsCallbackResults) {
  Guarded<std::string> g(3, 'x');
  EXPECT_EQ(g.read([](const std::string& s) { return s.size(); }), 3u);
  EXPECT_EQ(g.write([](std::string& s) {
    s += "y";
    return s;
  }),
            "xxxy");
  EXPECT_EQ(g.snapshot(), "xxxy");
}

TEST(RuntimeGuarded, ReadReturnsACopyNotAReferenceIntoTheState) {
  Guarded<std::string> g("before");
  auto copy = g.read([](const std::string& s) -> const std::string& { return s; });
  g.write([](std::string& s) { s = "after"; });
  EXPECT_EQ(copy, "before");
}

TEST(RuntimeGuarded, SnapshotIsAnIndependentCopy) {
  Guarded<std::vector<int>> g(std::vector<int>{1, 2, 3});
  auto snap = g.snapshot();
  snap.push_back(4);
  g.write([](std::vector<int>& v) { v[0] = 10; });
  EXPECT_EQ(snap, (std::vector<int>{1, 2, 3, 4}));
  EXPECT_EQ(g.snapshot(), (std::vector<int>{10, 2, 3}));
}

TEST(RuntimeGuarded, ConcurrentWritesAreNeverLost) {
  Guarded<long> g(0L);
  constexpr int kThreads = 4;
  constexpr int kWrites = 20000;
  std::latch start(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&] {
      start.arrive_and_wait();
      for (int i = 0; i < kWrites; ++i) g.write([](long& v) { ++v; });
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(g.snapshot(), long{kThreads} * kWrites);
  EXPECT_EQ(g.version(), std::uint64_t{kThreads} * kWrites);
}

TEST(RuntimeGuarded, ReadersNeverSeeAHalfDoneWrite) {
  Guarded<Pair> g;
  constexpr int kWrites = 20000;
  std::atomic<bool> done{false};
  std::atomic<long> torn{0};
  std::atomic<long> reads{0};
  std::atomic<long> written{0};
  std::latch start(3);
  std::thread writer([&] {
    start.arrive_and_wait();
    // At least kWrites, and on until the readers have read while it wrote (on a loaded machine they may start late).
    long k = 0;
    while (k < kWrites || reads.load() < 1000) {
      ++k;
      g.write([k](Pair& p) {
        p.a = k;
        p.b = -k;
      });
    }
    written = k;
    done = true;
  });
  std::vector<std::thread> readers;
  for (int r = 0; r < 2; ++r) {
    readers.emplace_back([&] {
      start.arrive_and_wait();
      while (!done) {
        if (g.read([](const Pair& p) { return p.a + p.b; }) != 0) ++torn;
        const Pair snap = g.snapshot();
        if (snap.a + snap.b != 0) ++torn;
        ++reads;
      }
    });
  }
  writer.join();
  for (auto& t : readers) t.join();
  EXPECT_EQ(torn, 0);
  EXPECT_GE(reads, 1000);
  EXPECT_EQ(g.snapshot().a, written.load());
}

TEST(RuntimeGuarded, NestedAccessFromACallbackThrowsInsteadOfDeadlocking) {
  Guarded<int> g(1);
  EXPECT_THROW(g.read([&](const int&) { return g.snapshot(); }), InternalError);
  EXPECT_THROW(g.write([&](int&) { g.write([](int& v) { v = 5; }); }), InternalError);
  EXPECT_THROW(g.read([&](const int&) { return g.read([](const int& v) { return v; }); }), InternalError);
  // The failed calls released the mutex: the object is still usable, and the nested write never happened.
  EXPECT_EQ(g.snapshot(), 1);
}

TEST(RuntimeGuarded, AnotherGuardedMayBeUsedInsideACallback) {
  Guarded<int> a(1);
  Guarded<int> b(2);
  EXPECT_EQ(a.read([&](const int& x) { return x + b.snapshot(); }), 3);
}

TEST(RuntimeGuarded, ACallbackThatThrowsReleasesTheMutex) {
  Guarded<int> g(0);
  EXPECT_THROW(g.write([](int& v) {
    v = 3;
    throw std::runtime_error("callback failed");
  }),
               std::runtime_error);
  EXPECT_EQ(g.version(), 1u);
  std::thread other([&] { g.write([](int& v) { v += 1; }); });  // would hang if the mutex were still held
  other.join();
  EXPECT_EQ(g.snapshot(), 4);
}

}  // namespace
}  // namespace cellwright::runtime
