// Time for the threaded runtime, in its two modes.
//
// Lock-step mode (the default): a VirtualClock holds simulation time, and a LockstepScheduler makes the runtime's
// participants (simulation, image processing, task control, one per robot) take turns in a fixed order, one at a time:
// every round, participant 0 runs, then 1, ..., then N-1, then round+1 begins. What happens in which order does not
// depend on the OS scheduler or the number of cores, so the same scenario and seed give a byte-identical event log
// anywhere. State touched only inside turns needs no further locking: each handover goes through the scheduler's
// mutex, which orders every turn after the one before. Inside a turn, use only operations that cannot wait for
// another participant (MessageQueue::try_push/try_pop, Event::is_set or wait_for(0)): the other participant cannot
// run until the turn is yielded, so blocking deadlocks.
//
// What a turn costs (why the scheduler has more than one round-robin). Handing the turn to a participant on another
// thread is a mutex and condition-variable wake of that thread and a thread switch: 5-50 us, more than many turns'
// work, and at 4+ turns per 10 ms control period it alone capped a run near 50x real time. Two things cut it, and
// neither changes the order, so neither changes the log:
//  - Event-driven turns. A participant says, as it yields, when it next needs a turn (Wake): at its next place in the
//    order (every round, the default), once the clock reads a given time, or once notified. Until then the turn
//    passes over its seat without running or waking anything. Whether a sleeping participant is due is decided when
//    the turn reaches its seat, from the clock (advanced only inside turns) and from notify() calls (made inside
//    turns), so it is a function of what the earlier turns did: the order stays a function of the inputs only. A
//    participant notified by a turn before its seat in the same round runs in that round (the simulation queues a
//    camera frame, image processing runs right after it); one notified after its seat runs in the next round.
//  - Threads that take several participants' turns. Which thread runs a participant's turns is a deployment choice
//    made when the scheduler is built (one thread each, all on one thread, any grouping); the order is the
//    scheduler's either way. The turn passes between participants of one thread with no wake and no switch: the
//    thread only goes on to its next participant. The runtime puts every participant on the simulation thread by
//    default (RunConfig::lockstep_threads): a period then costs no thread switch at all.
// handoffs() counts the turns passed to another thread (each one a wake and a switch), skipped() the turns passed over.
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
#include <optional>
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

// When a participant next needs a turn, declared as it yields (LockstepScheduler::yield).
class Wake {
 public:
  // At its next place in the order, i.e. every round (the default).
  static Wake next_round() { return Wake(Kind::kNextRound, SimDuration(0)); }
  // At its first place in the order at which the scheduler's clock reads `t` or later, or earlier once notified.
  static Wake at(SimDuration t) { return Wake(Kind::kAt, t); }
  // At its first place in the order after notify() (a notify made before the yield counts).
  static Wake on_notify() { return Wake(Kind::kNotified, SimDuration(0)); }

  enum class Kind { kNextRound, kAt, kNotified };
  Kind kind() const { return kind_; }
  SimDuration time() const { return time_; }  // kAt only

 private:
  Wake(Kind kind, SimDuration time) : kind_(kind), time_(time) {}
  Kind kind_;
  SimDuration time_;
};

// Runs N participants one at a time, in the fixed order 0, 1, ..., N-1, round after round, each on the thread the
// scheduler was built with for it, skipping those that sleep (Wake).
//
// A participant alone on its thread:
//    LockstepScheduler::Seat seat(scheduler, id);      // leaves the rotation when destroyed, even on an exception
//    while (seat.await_turn()) {                        // false once the scheduler is stopped
//      ... one step: non-blocking work only ...
//      seat.yield();                                    // or seat.yield(Wake::on_notify()) etc.
//    }
// A thread that takes the turns of several participants (threads_of[id] == k for each of them):
//    LockstepScheduler::Seat seat(scheduler, LockstepScheduler::Thread{k});
//    while (seat.await_turn()) {                        // seat.id(): whose turn this thread now holds
//      ... that participant's step ...
//      seat.yield();
//    }
// The turn starts with participant 0; every participant starts awake. A participant that has left (or never arrives
// and is removed with leave()) is skipped; the others go on in the same order. If every present participant sleeps
// and none is due (nothing inside a turn can wake one then: no turn runs), the scheduler idles until notify() from
// outside (which then chooses the order: only deterministic if the caller is) or stop(). stop() ends the run: every
// await_turn returns false.
//
// Misuse throws InternalError: an id or thread out of range, yielding a turn not held, awaiting a turn already held,
// awaiting after leaving, a Wake::at without a clock.
//
// Threads: every member may be called from any thread; await_turn/yield are meant for the participant's own thread.
// notify() is deterministic when called inside a turn (the usual case: a participant that has queued a message for
// another).
class LockstepScheduler {
 public:
  using Id = std::size_t;
  // A thread of the scheduler, by index (0 .. threads()-1).
  struct Thread {
    std::size_t index;
  };

  // A scheduler for participants 0..participants-1, all present, each on a thread of its own (participant i on thread
  // i). `clock` (may be null when no participant sleeps until a time) is read to decide when Wake::at is due; it must
  // outlive the scheduler. Throws InternalError if participants is 0.
  explicit LockstepScheduler(std::size_t participants, const VirtualClock* clock = nullptr);
  // A scheduler for participants 0..threads_of.size()-1, participant i on thread threads_of[i]. The threads are
  // numbered 0..T-1 and each serves at least one participant (InternalError otherwise, or if there is none).
  explicit LockstepScheduler(std::vector<std::size_t> threads_of, const VirtualClock* clock = nullptr);
  LockstepScheduler(const LockstepScheduler&) = delete;
  LockstepScheduler& operator=(const LockstepScheduler&) = delete;

  // Blocks until it is `id`'s turn. Returns true when `id` now holds the turn (it must yield() it), false once the
  // scheduler has been stopped (then `id` holds nothing). For a participant alone on its thread: on a thread of
  // several, use await_turn(Thread), which takes whichever of its participants' turns comes.
  [[nodiscard]] bool await_turn(Id id);

  // Blocks until one of `thread`'s participants has the turn; returns it (it now holds the turn and must yield() it),
  // or nothing once the scheduler has been stopped. InternalError if every participant of the thread has left.
  [[nodiscard]] std::optional<Id> await_turn(Thread thread);

  // Ends `id`'s turn and hands it to the next participant in order that is present and due, passing over those that
  // sleep. `next` says when `id` needs its next turn. `id` must hold the turn.
  void yield(Id id, Wake next = Wake::next_round());

  // Wakes `id` for its next place in the order: this round if the turn has not passed its seat yet, else the next.
  // Sticky until that turn (a notify before `id` yields with Wake::on_notify() counts). Any thread; ignored for a
  // participant that has left or after stop().
  void notify(Id id);

  // Takes `id` out of the rotation for good; if it holds or is owed the turn, the turn moves on. Idempotent.
  void leave(Id id);

  // Ends the run: wakes every participant; await_turn returns false from now on. Idempotent.
  void stop();

  // Completed rounds: how many times the turn has passed participant N-1's seat on to participant 0's.
  std::uint64_t rounds() const;

  // Turns taken so far (yielded, or ended by leaving), all participants together.
  std::uint64_t turns() const;

  // Turns passed over: each time the turn reached a present participant that was asleep and not due.
  std::uint64_t skipped() const;

  // Hand-offs: turns handed to a participant on another thread than the one ending a turn (each a wake of that
  // thread, and on one core a thread switch). Turns that stay on one thread are not hand-offs.
  std::uint64_t handoffs() const;

  // Participants blocked in await_turn now (a thread of several counts once). For diagnostics, and for tests that
  // must know threads are parked before they act.
  std::size_t waiting() const;

  // Participants that have not left.
  std::size_t present() const;

  // The threads the scheduler was built with, and which one serves `id`.
  std::size_t threads() const { return threads_; }
  std::size_t thread_of(Id id) const;

  bool stopped() const;

  // RAII membership for one thread: await_turn()/yield() for its participant(s), leave() of each on destruction.
  class Seat {
   public:
    // The thread of participant `id` alone.
    Seat(LockstepScheduler& scheduler, Id id) : scheduler_(scheduler), id_(id), single_(true) {}
    // A thread that serves one or more participants.
    Seat(LockstepScheduler& scheduler, Thread thread) : scheduler_(scheduler), thread_(thread), single_(false) {}
    ~Seat();
    Seat(const Seat&) = delete;
    Seat& operator=(const Seat&) = delete;

    // Waits for the turn of the seat's participant (or one of them); false once stopped.
    [[nodiscard]] bool await_turn();
    // Yields the turn held (see LockstepScheduler::yield).
    void yield(Wake next = Wake::next_round()) { scheduler_.yield(id_, next); }
    // The participant whose turn the seat holds or last held (a single seat: its participant).
    Id id() const { return id_; }

   private:
    LockstepScheduler& scheduler_;
    Id id_ = 0;
    Thread thread_{0};
    bool single_;
  };

 private:
  // Moves the turn from current_ (which has just ended its turn, or left) to the next present participant that is
  // due and wakes its thread if that is another one; idles when none is due. Mutex held.
  void pass_turn();
  // Whether sleeping participant `id` is due now. Mutex held.
  bool due(Id id) const;
  // Waits on `thread`'s condition variable until `ready` or stopped. Mutex held (in `lock`).
  template <typename Ready>
  bool wait_on(std::unique_lock<std::mutex>& lock, std::size_t thread, Ready ready);

  struct Slot {
    bool present = true;
    std::size_t thread = 0;
    Wake wake = Wake::next_round();
    bool notified = false;
  };

  const VirtualClock* clock_;
  mutable std::mutex mutex_;
  std::vector<Slot> slots_;
  std::size_t threads_ = 0;
  std::vector<std::condition_variable> cvs_;  // one per thread
  Id current_ = 0;      // whose turn it is (meaningless when nobody is present or idle_)
  bool held_ = false;   // whether current_ has taken its turn (await_turn returned) and not yielded yet
  bool idle_ = false;   // nobody present was due: the turn waits for a notify()
  bool stopped_ = false;
  std::size_t present_;
  std::size_t waiting_ = 0;
  std::uint64_t rounds_ = 0;
  std::uint64_t turns_ = 0;
  std::uint64_t skipped_ = 0;
  std::uint64_t handoffs_ = 0;
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
