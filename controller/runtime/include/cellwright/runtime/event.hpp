// Event: the paper's event object (section 4): "when a thread waits on a nonsignaled event object, the thread blocks
// until another thread sets the object". The image-processing thread sets one after each environment-model update
// to wake the task-control thread.
//
// Two kinds, as Win32 events:
//  - manual reset: set() releases every waiter, present and future, until reset() is called.
//  - auto reset: each set() releases exactly one waiter, and the event is unsignalled again as that waiter returns.
//    With nobody waiting, the event stays signalled until the next wait consumes it. The signal is a flag, not a
//    counter: two set() calls with no wait in between release one waiter, not two.
//
// Threads: every member may be called from any thread, concurrently.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>

namespace cellwright::runtime {

class Event {
 public:
  enum class Kind { manual_reset, auto_reset };

  explicit Event(Kind kind, bool initially_set = false) : kind_(kind), signalled_(initially_set) {}
  Event(const Event&) = delete;
  Event& operator=(const Event&) = delete;

  // Signals the event: a manual-reset event wakes every waiter; an auto-reset event wakes one.
  void set() {
    {
      std::lock_guard lock(mutex_);
      signalled_ = true;
    }
    if (kind_ == Kind::manual_reset) {
      cv_.notify_all();
    } else {
      cv_.notify_one();
    }
  }

  // Makes the event unsignalled. (Auto-reset events rarely need it: a released wait resets them.)
  void reset() {
    std::lock_guard lock(mutex_);
    signalled_ = false;
  }

  // Blocks until the event is signalled. An auto-reset event is unsignalled again when this returns.
  void wait() {
    std::unique_lock lock(mutex_);
    ++waiters_;
    cv_.wait(lock, [&] { return signalled_; });
    --waiters_;
    consume();
  }

  // Blocks until the event is signalled or `timeout` has passed (steady clock). Returns true if it was signalled
  // (consuming the signal of an auto-reset event), false on timeout. A zero timeout just tests and consumes.
  template <typename Rep, typename Period>
  bool wait_for(std::chrono::duration<Rep, Period> timeout) {
    std::unique_lock lock(mutex_);
    ++waiters_;
    const bool got = cv_.wait_for(lock, timeout, [&] { return signalled_; });
    --waiters_;
    if (got) consume();
    return got;
  }

  // Whether the event is signalled now; does not consume the signal.
  bool is_set() const {
    std::lock_guard lock(mutex_);
    return signalled_;
  }

  // Threads blocked in wait()/wait_for() now. For diagnostics and for tests that must know a thread is blocked
  // before they act (a handshake, instead of sleeping and hoping).
  std::size_t waiters() const {
    std::lock_guard lock(mutex_);
    return waiters_;
  }

  Kind kind() const { return kind_; }

 private:
  void consume() {
    if (kind_ == Kind::auto_reset) signalled_ = false;
  }

  const Kind kind_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool signalled_;
  std::size_t waiters_ = 0;
};

}  // namespace cellwright::runtime
