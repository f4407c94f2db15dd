// MessageQueue<T>: the paper's message queue between threads (section 4): "when a thread attempts to write to a full
// queue or read from an empty queue, it is blocked". The task-control thread sends motion-level commands to each
// robot-control thread through one; robot-control threads report completion back through another.
//
// Semantics
//  - Bounded FIFO of at most capacity() items; one mutex, two condition variables (not full / not empty).
//  - push() blocks while the queue is full; pop() blocks while it is empty. try_push()/try_pop() never block;
//    pop_for() blocks at most for a given time.
//  - close() ends the queue's life: every blocked caller wakes; pushes fail with QueueStatus::closed from then on;
//    pops still deliver the items already queued, and report closed once the queue is drained. close() is
//    idempotent. This is how a runtime shuts its threads down without leaving one blocked forever.
//  - A push that fails never consumes its argument: the caller still owns the item (it matters for move-only T).
//
// Threads: every member may be called from any thread, concurrently. In lock-step mode (clock.hpp) a participant
// must not block inside its turn while another participant needs the turn to unblock it: use try_push/try_pop there.
#pragma once

#include <chrono>
#include <concepts>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <string_view>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

// Outcome of a queue operation. Each operation documents which of these it returns.
enum class QueueStatus {
  ok,       // the item was pushed or popped
  full,     // try_push: no room, nothing pushed
  empty,    // try_pop: nothing queued, nothing popped
  timeout,  // pop_for: nothing arrived in time
  closed,   // push*: the queue is closed; pop*: the queue is closed and drained
};

// "ok", "full", "empty", "timeout", "closed".
constexpr std::string_view to_string(QueueStatus s) {
  switch (s) {
    case QueueStatus::ok:
      return "ok";
    case QueueStatus::full:
      return "full";
    case QueueStatus::empty:
      return "empty";
    case QueueStatus::timeout:
      return "timeout";
    case QueueStatus::closed:
      return "closed";
  }
  return "?";
}

template <typename T>
class MessageQueue {
 public:
  // A queue holding at most `capacity` items. Throws InternalError if capacity is 0 (nothing could ever pass).
  explicit MessageQueue(std::size_t capacity) : capacity_(capacity) {
    CW_CHECK(capacity > 0, "a message queue needs a capacity of at least 1");
  }
  MessageQueue(const MessageQueue&) = delete;
  MessageQueue& operator=(const MessageQueue&) = delete;

  // Appends `item`, blocking while the queue is full. Returns ok, or closed if the queue is or becomes closed
  // before room appears (then `item` is left untouched).
  template <typename U = T>
  requires std::constructible_from<T, U&&> QueueStatus push(U&& item) {
    std::unique_lock lock(mutex_);
    ++waiting_pushers_;
    not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    --waiting_pushers_;
    if (closed_) return QueueStatus::closed;
    items_.emplace_back(std::forward<U>(item));
    lock.unlock();
    not_empty_.notify_one();
    return QueueStatus::ok;
  }

  // Appends `item` if there is room, without blocking. Returns ok, full or closed (item untouched unless ok).
  template <typename U = T>
  requires std::constructible_from<T, U&&> QueueStatus try_push(U&& item) {
    std::unique_lock lock(mutex_);
    if (closed_) return QueueStatus::closed;
    if (items_.size() >= capacity_) return QueueStatus::full;
    items_.emplace_back(std::forward<U>(item));
    lock.unlock();
    not_empty_.notify_one();
    return QueueStatus::ok;
  }

  // Removes and returns the oldest item, blocking while the queue is empty and open. Returns nullopt only when the
  // queue is closed and drained, so `while (auto m = q.pop()) handle(*m);` consumes everything ever pushed.
  std::optional<T> pop() {
    std::unique_lock lock(mutex_);
    ++waiting_poppers_;
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    --waiting_poppers_;
    return take(lock);
  }

  // Moves the oldest item into `out` if there is one, without blocking. Returns ok, empty, or closed (closed and
  // drained); `out` is assigned only on ok.
  QueueStatus try_pop(T& out) {
    std::unique_lock lock(mutex_);
    return take_into(lock, out, QueueStatus::empty);
  }

  // Like pop(), but waits at most `timeout` (steady clock). Returns ok, timeout, or closed (closed and drained);
  // `out` is assigned only on ok.
  template <typename Rep, typename Period>
  QueueStatus pop_for(T& out, std::chrono::duration<Rep, Period> timeout) {
    std::unique_lock lock(mutex_);
    ++waiting_poppers_;
    not_empty_.wait_for(lock, timeout, [&] { return closed_ || !items_.empty(); });
    --waiting_poppers_;
    return take_into(lock, out, QueueStatus::timeout);
  }

  // Closes the queue and wakes every blocked push and pop. Idempotent.
  void close() {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
  }

  // Whether close() has been called.
  bool closed() const {
    std::lock_guard lock(mutex_);
    return closed_;
  }

  // Items queued now (a snapshot: other threads may change it at once).
  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return items_.size();
  }

  std::size_t capacity() const { return capacity_; }

  // Threads blocked in push() / in pop() or pop_for() now. For diagnostics, and for tests that must know a thread is
  // blocked before they act (a handshake, instead of sleeping and hoping).
  std::size_t waiting_pushers() const {
    std::lock_guard lock(mutex_);
    return waiting_pushers_;
  }
  std::size_t waiting_poppers() const {
    std::lock_guard lock(mutex_);
    return waiting_poppers_;
  }

 private:
  // Pops the front under `lock` (held), then releases the lock and wakes one pusher.
  std::optional<T> take(std::unique_lock<std::mutex>& lock) {
    if (items_.empty()) return std::nullopt;  // closed and drained
    std::optional<T> item(std::move(items_.front()));
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }

  QueueStatus take_into(std::unique_lock<std::mutex>& lock, T& out, QueueStatus when_empty) {
    if (items_.empty()) return closed_ ? QueueStatus::closed : when_empty;
    out = std::move(items_.front());
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return QueueStatus::ok;
  }

  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_full_;
  std::condition_variable not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
  std::size_t waiting_pushers_ = 0;
  std::size_t waiting_poppers_ = 0;
};

}  // namespace cellwright::runtime
