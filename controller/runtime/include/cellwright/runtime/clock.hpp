// Time for the threaded runtime, in its two modes.
//
// Lock-step mode (the default): a VirtualClock holds simulation time, and a LockstepScheduler makes the runtime's
// threads (simulation, image processing, task control, one per robot) take turns in a fixed order, one at a time:
// every round, participant 0 runs, then 1, ..., then N-1, then round+1 begins. Each thread still blocks and wakes as
// in the paper, but what happens in which order no longer depends on the OS scheduler or the number of cores, so
// the same scenario and seed give a byte-identical event log anywhere. State touched only inside turns needs no
// further locking: each handover goes through the scheduler's mutex, which orders every turn after the one before.
// Inside a turn, use only operations that cannot wait for another participant (MessageQueue::try_push/try_pop,
// Event::is_set or wait_for(0)): the other participant cannot run until the turn is yielded, so blocking deadlocks.
//
// Real-time mode (--realtime): the same threads run freely and the simulation thread calls RealtimePacer::pace()
// before each step, so simulation time follows the wall clock (sleeping there is the feature, not a race cover).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <vector>

namespace cellwright::runtime {

// Simulation time in nanoseconds since the start of the run.
using SimDuration = std::chrono::nanoseconds;

// The runtime's simulation time. Only the simulation participant advances it (inside its lock-step turn, or before
// each step in real-time mode); any thread may read it. Starts at 0.
class VirtualClock {
 public:
  // The current simulation time. Any thread.
  SimDuration now() const { return SimDuration(ns_.load(std::memory_order_acquire)); }

  // Moves time forward by `dt` and returns the new time. Throws InternalError if dt is negative (time never runs
  // backwards). The simulation participant only.
  SimDuration advance(SimDuration dt);

 private:
  std::atomic<std::int64_t> ns_{0};
};

// Runs N participant threads one at a time, in the fixed order 0, 1, ..., N-1, round after round.
//
// A participant's loop:
//    LockstepScheduler::Seat seat(scheduler, id);      // leaves the rotation when destroyed, even on an exception
//    while (seat.await_turn()) {                        // false once the scheduler is stopped
//      ... one step: non-blocking work only ...
//      seat.yield();                                    // hands the turn to the next participant
//    }
// The turn starts with participant 0. A participant that has left (or never arrives and is removed with leave())
// is skipped; the others go on in the same order. stop() ends the run: every await_turn returns false.
//
// Misuse throws InternalError: an id out of range, yielding a turn not held, awaiting a turn already held, or
// awaiting after leaving.
//
// Threads: every member may be called from any thread; await_turn/yield are meant for the participant's own thread.
class LockstepScheduler {
 public:
  using Id = std::size_t;

  // A scheduler for participants 0..participants-1, all present. Throws InternalError if participants is 0.
  explicit LockstepScheduler(std::size_t participants);
  LockstepScheduler(const LockstepScheduler&) = delete;
  LockstepScheduler& operator=(const LockstepScheduler&) = delete;

  // Blocks until it is `id`'s turn. Returns true when `id` now holds the turn (it must yield() it), false once the
  // scheduler has been stopped (then `id` holds nothing).
  [[nodiscard]] bool await_turn(Id id);

  // Ends `id`'s turn and hands it to the next present participant in order. `id` must hold the turn.
  void yield(Id id);

  // Takes `id` out of the rotation for good; if it holds or is owed the turn, the turn moves on. Idempotent.
  void leave(Id id);

  // Ends the run: wakes every participant; await_turn returns false from now on. Idempotent.
  void stop();

  // Completed rounds: how many times the turn has wrapped from the last present participant to the first.
  std::uint64_t rounds() const;

  // Turns yielded so far, all participants together.
  std::uint64_t turns() const;

  // Participants blocked in await_turn now. For diagnostics, and for tests that must know threads are parked before
  // they act.
  std::size_t waiting() const;

  // Participants that have not left.
  std::size_t present() const;

  bool stopped() const;

  // RAII membership for one participant thread: await_turn()/yield() for its id, leave() on destruction.
  class Seat {
   public:
    Seat(LockstepScheduler& scheduler, Id id) : scheduler_(scheduler), id_(id) {}
    ~Seat() { scheduler_.leave(id_); }
    Seat(const Seat&) = delete;
    Seat& operator=(const Seat&) = delete;

    [[nodiscard]] bool await_turn() { return scheduler_.await_turn(id_); }
    void yield() { scheduler_.yield(id_); }
    Id id() const { return id_; }

   private:
    LockstepScheduler& scheduler_;
    Id id_;
  };

 private:
  // Moves the turn from current_ to the next present participant (mutex held) and wakes it.
  void pass_turn();

  struct Slot {
    bool present = true;
    std::condition_variable cv;
  };

  mutable std::mutex mutex_;
  std::vector<Slot> slots_;
  Id current_ = 0;     // whose turn it is (meaningless when nobody is present)
  bool held_ = false;  // whether current_ has taken its turn (await_turn returned) and not yielded yet
  bool stopped_ = false;
  std::size_t present_;
  std::size_t waiting_ = 0;
  std::uint64_t rounds_ = 0;
  std::uint64_t turns_ = 0;
};

// Paces simulation time to the wall clock for real-time mode: pace(t) sleeps until the wall-clock instant that
// corresponds to simulation time t, at `speed` times real time (2.0 = twice as fast as the wall clock).
class RealtimePacer {
 public:
  using WallClock = std::chrono::steady_clock;
  // Where the pacer reads and waits for wall-clock time: the real steady clock, or a fake one in tests.
  struct WallTime {
    std::function<WallClock::time_point()> now;
    std::function<void(WallClock::time_point)> sleep_until;
  };

  // A pacer on the real steady clock, anchored now at simulation time 0. Throws InternalError unless speed is
  // finite and > 0 (the command line validates the user's value).
  explicit RealtimePacer(double speed = 1.0);
  // The same on the given wall time (tests).
  RealtimePacer(double speed, WallTime wall);

  // Re-anchors: simulation time `sim_now` corresponds to the wall-clock instant now. Call it when the run starts or
  // resumes after a pause, so that the pacer does not try to catch up on the pause.
  void anchor(SimDuration sim_now);

  // Sleeps until the wall-clock instant of simulation time `sim_time`, unless it has already passed. Returns how late
  // the caller already was (zero when it had to wait): the runtime reports it when the simulation cannot keep up.
  WallClock::duration pace(SimDuration sim_time);

  double speed() const { return speed_; }

 private:
  double speed_;
  WallTime wall_;
  WallClock::time_point wall_origin_;
  SimDuration sim_origin_{0};
};

}  // namespace cellwright::runtime
