#include "cellwright/runtime/message_queue.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <latch>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "controller/runtime/handshake.hpp"

namespace cellwright::runtime {
namespace {

using cellwright::testing::eventually;
using cellwright::testing::ThreadGroup;
using namespace std::chrono_literals;

TEST(RuntimeMessageQueue, DeliversInFifoOrder) {
  MessageQueue<int> q(3);
  EXPECT_EQ(q.capacity(), 3u);
  for (int i = 1; i <= 3; ++i) ASSERT_EQ(q.push(i), QueueStatus::ok);
  EXPECT_EQ(q.size(), 3u);
  for (int i = 1; i <= 3; ++i) {
    auto v = q.pop();
    ASSERT_TRUE(v.has_value());
    EXPECT_EQ(*v, i);
  }
  EXPECT_EQ(q.size(), 0u);
}

TEST(RuntimeMessageQueue, TryOperationsReportFullAndEmptyWithoutBlocking) {
  MessageQueue<int> q(1);
  int out = -1;
  EXPECT_EQ(q.try_pop(out), QueueStatus::empty);
  EXPECT_EQ(out, -1);
  EXPECT_EQ(q.try_push(7), QueueStatus::ok);
  EXPECT_EQ(q.try_push(8), QueueStatus::full);
  EXPECT_EQ(q.size(), 1u);
  EXPECT_EQ(q.try_pop(out), QueueStatus::ok);
  EXPECT_EQ(out, 7);
}

TEST(RuntimeMessageQueue, FailedPushLeavesAMoveOnlyItemWithTheCaller) {
  MessageQueue<std::unique_ptr<int>> q(1);
  ASSERT_EQ(q.try_push(std::make_unique<int>(1)), QueueStatus::ok);
  auto item = std::make_unique<int>(2);
  EXPECT_EQ(q.try_push(std::move(item)), QueueStatus::full);
  ASSERT_NE(item, nullptr);  // not consumed by the failed push
  q.close();
  EXPECT_EQ(q.push(std::move(item)), QueueStatus::closed);
  ASSERT_NE(item, nullptr);
  EXPECT_EQ(*item, 2);
  auto first = q.pop();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(**first, 1);
}

TEST(RuntimeMessageQueue, PushBlocksWhileFullUntilAnItemIsPopped) {
  MessageQueue<int> q(1);
  ASSERT_EQ(q.push(1), QueueStatus::ok);
  std::atomic<bool> pushed{false};
  ThreadGroup producer([&] { q.close(); });
  producer.spawn([&] {
    EXPECT_EQ(q.push(2), QueueStatus::ok);
    pushed = true;
  });
  // The producer must park inside push(); had push() not blocked, it would have finished instead.
  ASSERT_TRUE(eventually([&] { return q.waiting_pushers() == 1 || pushed; }));
  EXPECT_FALSE(pushed) << "push() returned on a full queue";
  EXPECT_EQ(q.size(), 1u);
  EXPECT_EQ(q.pop(), 1);  // makes room: the producer gets through
  producer.join();
  EXPECT_TRUE(pushed);
  EXPECT_EQ(q.pop(), 2);
}

TEST(RuntimeMessageQueue, PopBlocksWhileEmptyUntilAnItemIsPushed) {
  MessageQueue<int> q(2);
  std::atomic<bool> popped{false};
  std::optional<int> got;
  ThreadGroup consumer([&] { q.close(); });
  consumer.spawn([&] {
    got = q.pop();
    popped = true;
  });
  ASSERT_TRUE(eventually([&] { return q.waiting_poppers() == 1 || popped; }));
  EXPECT_FALSE(popped) << "pop() returned on an empty queue";
  ASSERT_EQ(q.push(42), QueueStatus::ok);
  consumer.join();
  EXPECT_EQ(got, 42);
}

TEST(RuntimeMessageQueue, PopForTimesOutOnAnEmptyQueue) {
  MessageQueue<int> q(1);
  int out = -1;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(q.pop_for(out, 2ms), QueueStatus::timeout);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 2ms);
  EXPECT_EQ(out, -1);
  ASSERT_EQ(q.push(5), QueueStatus::ok);
  EXPECT_EQ(q.pop_for(out, 0ms), QueueStatus::ok);
  EXPECT_EQ(out, 5);
}

TEST(RuntimeMessageQueue, PopForWakesWhenAnItemArrives) {
  MessageQueue<int> q(1);
  QueueStatus status = QueueStatus::timeout;
  int out = -1;
  ThreadGroup consumer([&] { q.close(); });
  consumer.spawn([&] { status = q.pop_for(out, std::chrono::hours(1)); });
  ASSERT_TRUE(eventually([&] { return q.waiting_poppers() == 1; }));
  ASSERT_EQ(q.push(9), QueueStatus::ok);
  consumer.join();
  EXPECT_EQ(status, QueueStatus::ok);
  EXPECT_EQ(out, 9);
}

TEST(RuntimeMessageQueue, CloseWakesEveryBlockedPopper) {
  MessageQueue<int> q(4);
  constexpr int kConsumers = 3;
  std::atomic<int> saw_closed{0};
  ThreadGroup consumers([&] { q.close(); });
  for (int i = 0; i < kConsumers; ++i) {
    consumers.spawn([&] {
      if (!q.pop().has_value()) ++saw_closed;
    });
  }
  ASSERT_TRUE(eventually([&] { return q.waiting_poppers() == kConsumers; }));
  q.close();
  consumers.join();
  EXPECT_EQ(saw_closed, kConsumers);
}

TEST(RuntimeMessageQueue, CloseWakesABlockedPusherWhoseItemIsRefused) {
  MessageQueue<int> q(1);
  ASSERT_EQ(q.push(1), QueueStatus::ok);
  QueueStatus status = QueueStatus::ok;
  ThreadGroup producer([&] { q.close(); });
  producer.spawn([&] { status = q.push(2); });
  ASSERT_TRUE(eventually([&] { return q.waiting_pushers() == 1; }));
  q.close();
  producer.join();
  EXPECT_EQ(status, QueueStatus::closed);
  EXPECT_EQ(q.size(), 1u);  // only the item queued before close
}

TEST(RuntimeMessageQueue, PopsDrainAClosedQueueThenReportClosed) {
  MessageQueue<int> q(3);
  for (int i = 0; i < 3; ++i) ASSERT_EQ(q.push(i), QueueStatus::ok);
  q.close();
  q.close();  // idempotent
  EXPECT_TRUE(q.closed());
  EXPECT_EQ(q.push(99), QueueStatus::closed);
  EXPECT_EQ(q.try_push(99), QueueStatus::closed);
  int out = -1;
  EXPECT_EQ(q.pop(), 0);
  EXPECT_EQ(q.try_pop(out), QueueStatus::ok);
  EXPECT_EQ(out, 1);
  EXPECT_EQ(q.pop_for(out, 0ms), QueueStatus::ok);
  EXPECT_EQ(out, 2);
  EXPECT_EQ(q.pop(), std::nullopt);
  EXPECT_EQ(q.try_pop(out), QueueStatus::closed);
  EXPECT_EQ(q.pop_for(out, 1h), QueueStatus::closed);  // returns at once: nothing can arrive any more
}

TEST(RuntimeMessageQueue, ZeroCapacityIsABug) {
  EXPECT_THROW(MessageQueue<int>(0), InternalError);
}

// Several producers and consumers through a small queue: every item arrives exactly once, and a consumer sees each
// producer's items in the order they were pushed.
TEST(RuntimeMessageQueue, ManyProducersAndConsumersDeliverEveryItemExactlyOnce) {
  for (const std::uint32_t seed : {1u, 2u, 3u, 20240611u}) {
    SCOPED_TRACE(seed);
    std::mt19937 rng(seed);
    const int producers = std::uniform_int_distribution<int>(2, 5)(rng);
    const int consumers = std::uniform_int_distribution<int>(2, 5)(rng);
    std::vector<int> counts(producers);
    for (int& c : counts) c = std::uniform_int_distribution<int>(200, 2000)(rng);

    MessageQueue<std::uint64_t> q(std::uniform_int_distribution<std::size_t>(1, 8)(rng));
    std::vector<std::vector<std::uint64_t>> received(consumers);
    std::latch start(producers + consumers);
    std::vector<std::thread> threads;
    for (int c = 0; c < consumers; ++c) {
      threads.emplace_back([&, c] {
        start.arrive_and_wait();
        while (auto item = q.pop()) received[c].push_back(*item);
      });
    }
    std::vector<std::thread> producer_threads;
    for (int p = 0; p < producers; ++p) {
      producer_threads.emplace_back([&, p] {
        start.arrive_and_wait();
        for (int i = 0; i < counts[p]; ++i) {
          ASSERT_EQ(q.push((static_cast<std::uint64_t>(p) << 32) | static_cast<std::uint64_t>(i)), QueueStatus::ok);
        }
      });
    }
    for (auto& t : producer_threads) t.join();
    q.close();
    for (auto& t : threads) t.join();

    std::vector<std::vector<int>> seen(producers);
    for (const auto& mine : received) {
      std::vector<int> last(producers, -1);
      for (const std::uint64_t item : mine) {
        const auto p = static_cast<int>(item >> 32);
        const auto i = static_cast<int>(item & 0xffffffffu);
        ASSERT_LT(p, producers);
        EXPECT_GT(i, last[p]) << "a consumer saw producer " << p << "'s items out of order";
        last[p] = i;
        seen[p].push_back(i);
      }
    }
    for (int p = 0; p < producers; ++p) {
      std::sort(seen[p].begin(), seen[p].end());
      ASSERT_EQ(seen[p].size(), static_cast<std::size_t>(counts[p])) << "producer " << p;
      for (int i = 0; i < counts[p]; ++i) ASSERT_EQ(seen[p][i], i) << "producer " << p;
    }
  }
}

}  // namespace
}  // namespace cellwright::runtime
