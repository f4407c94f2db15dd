// Guarded<T>: state shared between threads behind one mutex, the paper's "critical section object" (section 4).
// The environment model lives in one: the image-processing thread writes it every 400 ms, the task-control and
// robot-control threads read it.
//
// Access goes only through short callbacks run with the mutex held:
//    model.write([&](EnvironmentModel& m) { m.parts[id].pose = seen; });
//    auto pose = model.read([&](const EnvironmentModel& m) { return m.parts.at(id).pose; });
// Callbacks must be short and must not block (no queue pushes/pops, no event waits, no I/O, no sleeping): every
// other thread touching the state waits for them. They must not touch the same Guarded again: that would deadlock,
// so it is detected and throws InternalError instead. Copy out what you need (or take a snapshot()) and work on the
// copy outside.
//
// Threads: every member may be called from any thread, concurrently. An exception thrown by a callback releases the
// mutex and propagates to the caller; a write that throws still counts as a write in version().
#pragma once

#include <atomic>
#include <concepts>
#include <cstdint>
#include <mutex>
#include <thread>
#include <type_traits>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

template <typename T>
class Guarded {
 public:
  // Constructs the guarded value in place from `args`.
  template <typename... Args>
  requires std::constructible_from<T, Args&&...>
  explicit Guarded(Args&&... args) : value_(std::forward<Args>(args)...) {}
  Guarded(const Guarded&) = delete;
  Guarded& operator=(const Guarded&) = delete;

  // Runs fn(const T&) under the mutex and returns a copy of what it returns (never a reference into the state, which
  // would outlive the lock). Throws InternalError if called from inside a callback on this same object.
  template <typename F>
  requires std::is_invocable_v<F&, const T&>
  auto read(F&& fn) const {
    Section section(*this);
    return fn(std::as_const(value_));
  }

  // Runs fn(T&) under the mutex, bumps version(), and returns a copy of what fn returns. Throws InternalError if
  // called from inside a callback on this same object.
  template <typename F>
  requires std::is_invocable_v<F&, T&>
  auto write(F&& fn) {
    Section section(*this);
    version_.fetch_add(1, std::memory_order_relaxed);
    return fn(value_);
  }

  // A copy of the value, taken under the mutex.
  T snapshot() const {
    Section section(*this);
    return value_;
  }

  // How many write() calls have begun so far. A reader that remembers it can tell whether the state changed since
  // (e.g. whether the environment model has been updated since the last planning step).
  std::uint64_t version() const { return version_.load(std::memory_order_relaxed); }

 private:
  // Holds the mutex for one callback and records the holder, so that a nested call from the same thread fails loudly
  // instead of deadlocking.
  class Section {
   public:
    explicit Section(const Guarded& g) : g_(g) {
      CW_CHECK(g_.holder_.load(std::memory_order_relaxed) != std::this_thread::get_id(),
               "Guarded accessed again from inside one of its own callbacks (that would deadlock)");
      g_.mutex_.lock();
      g_.holder_.store(std::this_thread::get_id(), std::memory_order_relaxed);
    }
    ~Section() {
      g_.holder_.store(std::thread::id(), std::memory_order_relaxed);
      g_.mutex_.unlock();
    }
    Section(const Section&) = delete;
    Section& operator=(const Section&) = delete;

   private:
    const Guarded& g_;
  };

  mutable std::mutex mutex_;
  // The thread inside a callback now, or a default id. Only the holder itself can observe its own id here, which is
  // all the re-entry check needs.
  mutable std::atomic<std::thread::id> holder_{};
  std::atomic<std::uint64_t> version_{0};
  T value_;
};

}  // namespace cellwright::runtime
