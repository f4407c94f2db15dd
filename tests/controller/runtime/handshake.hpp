// Test helpers for threaded tests.
//  - eventually(): wait for another thread to reach an observable state (blocked in a queue, waiting on an event,
//    parked in the scheduler) before acting. It polls the condition, yielding the CPU; it never sleeps a guessed
//    time. A watchdog turns a hang (a broken implementation) into a test failure instead of a stuck test run.
//  - ThreadGroup: threads that are always joined, even when an assertion fails half-way: its destructor first runs
//    a `release` action (close the queue, stop the scheduler, ...) that unblocks them, so a failing test reports its
//    failure instead of aborting on a joinable std::thread or hanging in join().
#pragma once

#include <chrono>
#include <functional>
#include <thread>
#include <utility>
#include <vector>

namespace cellwright::testing {

// Returns true as soon as cond() holds; false if it still does not hold after `watchdog` (the caller asserts).
template <typename Cond>
[[nodiscard]] bool eventually(Cond cond, std::chrono::seconds watchdog = std::chrono::seconds(20)) {
  const auto give_up = std::chrono::steady_clock::now() + watchdog;
  while (!cond()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::yield();
  }
  return true;
}

class ThreadGroup {
 public:
  explicit ThreadGroup(std::function<void()> release = [] {}) : release_(std::move(release)) {}
  ThreadGroup(const ThreadGroup&) = delete;
  ThreadGroup& operator=(const ThreadGroup&) = delete;
  ~ThreadGroup() {
    bool running = false;
    for (auto& t : threads_) running = running || t.joinable();
    if (running) release_();
    join();
  }

  template <typename F>
  void spawn(F&& f) {
    threads_.emplace_back(std::forward<F>(f));
  }

  // Joins every thread (the normal end of a test).
  void join() {
    for (auto& t : threads_) {
      if (t.joinable()) t.join();
    }
  }

 private:
  std::function<void()> release_;
  std::vector<std::thread> threads_;
};

}  // namespace cellwright::testing
