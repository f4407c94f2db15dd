#include "cellwright/runtime/clock.hpp"

#include <algorithm>
#include <cmath>
#include <thread>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

SimDuration VirtualClock::advance(SimDuration dt) {
  CW_CHECK(dt.count() >= 0, "virtual time cannot run backwards (advance by {} ns)", dt.count());
  return SimDuration(ns_.fetch_add(dt.count(), std::memory_order_acq_rel) + dt.count());
}

LockstepScheduler::LockstepScheduler(std::size_t participants, const VirtualClock* clock)
    : LockstepScheduler(
          [participants] {
            std::vector<std::size_t> each(participants);
            for (std::size_t i = 0; i < participants; ++i) each[i] = i;
            return each;
          }(),
          clock) {}

LockstepScheduler::LockstepScheduler(std::vector<std::size_t> threads_of, const VirtualClock* clock)
    : clock_(clock), slots_(threads_of.size()), present_(threads_of.size()) {
  CW_CHECK(!threads_of.empty(), "a lock-step scheduler needs at least one participant");
  for (const std::size_t t : threads_of) threads_ = std::max(threads_, t + 1);
  std::vector<bool> used(threads_, false);
  for (Id id = 0; id < threads_of.size(); ++id) {
    slots_[id].thread = threads_of[id];
    used[threads_of[id]] = true;
  }
  for (std::size_t t = 0; t < threads_; ++t) CW_CHECK(used[t], "lock-step thread {} serves no participant", t);
  cvs_ = std::vector<std::condition_variable>(threads_);
}

template <typename Ready>
bool LockstepScheduler::wait_on(std::unique_lock<std::mutex>& lock, std::size_t thread, Ready ready) {
  ++waiting_;
  cvs_[thread].wait(lock, [&] { return stopped_ || (!idle_ && !held_ && ready()); });
  --waiting_;
  if (stopped_) return false;
  held_ = true;
  return true;
}

bool LockstepScheduler::await_turn(Id id) {
  std::unique_lock lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  CW_CHECK(slots_[id].present, "participant {} awaits a turn after leaving", id);
  CW_CHECK(!(held_ && current_ == id), "participant {} awaits a turn it already holds", id);
  return wait_on(lock, slots_[id].thread, [&] { return current_ == id; });
}

std::optional<LockstepScheduler::Id> LockstepScheduler::await_turn(Thread thread) {
  std::unique_lock lock(mutex_);
  CW_CHECK(thread.index < threads_, "thread {} out of range (scheduler has {})", thread.index, threads_);
  CW_CHECK(std::any_of(slots_.begin(), slots_.end(),
                       [&](const Slot& s) { return s.present && s.thread == thread.index; }),
           "thread {} awaits a turn and every participant of it has left", thread.index);
  CW_CHECK(!(held_ && slots_[current_].thread == thread.index), "thread {} awaits a turn it already holds (of {})",
           thread.index, current_);
  if (!wait_on(lock, thread.index, [&] { return slots_[current_].thread == thread.index; })) return std::nullopt;
  return current_;
}

void LockstepScheduler::yield(Id id, Wake next) {
  std::lock_guard lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  CW_CHECK(held_ && current_ == id, "participant {} yields a turn it does not hold", id);
  CW_CHECK(next.kind() != Wake::Kind::kAt || clock_ != nullptr,
           "participant {} sleeps until a time, and the scheduler has no clock", id);
  slots_[id].wake = next;
  held_ = false;
  ++turns_;
  pass_turn();
}

void LockstepScheduler::notify(Id id) {
  std::lock_guard lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  Slot& s = slots_[id];
  if (!s.present || stopped_) return;
  s.notified = true;
  if (idle_) {
    // Nobody was due; this one is now, and the order resumes from its seat.
    idle_ = false;
    current_ = id;
    s.wake = Wake::next_round();
    s.notified = false;
    ++handoffs_;
    cvs_[s.thread].notify_all();
  }
}

void LockstepScheduler::leave(Id id) {
  std::lock_guard lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  if (!slots_[id].present) return;
  slots_[id].present = false;
  --present_;
  if (current_ == id && !idle_) {
    if (held_) ++turns_;  // a turn ended by leaving still counts as taken
    held_ = false;
    pass_turn();
  }
}

void LockstepScheduler::stop() {
  std::lock_guard lock(mutex_);
  stopped_ = true;
  for (std::condition_variable& cv : cvs_) cv.notify_all();
}

bool LockstepScheduler::due(Id id) const {
  const Slot& s = slots_[id];
  switch (s.wake.kind()) {
    case Wake::Kind::kNextRound:
      return true;
    case Wake::Kind::kAt:
      return s.notified || clock_->now() >= s.wake.time();
    case Wake::Kind::kNotified:
      return s.notified;
  }
  return true;
}

void LockstepScheduler::pass_turn() {
  if (present_ == 0 || stopped_) return;
  const std::size_t n = slots_.size();
  const std::size_t from = slots_[current_].thread;
  Id next = current_;
  // One pass over every seat, ending at current_'s own: the first present participant that is due takes the turn.
  for (std::size_t step = 0; step < n; ++step) {
    next = (next + 1) % n;
    if (next == 0) ++rounds_;
    Slot& s = slots_[next];
    if (!s.present) continue;
    if (!due(next)) {
      ++skipped_;
      continue;
    }
    s.wake = Wake::next_round();
    s.notified = false;
    current_ = next;
    if (s.thread != from) {
      ++handoffs_;
      cvs_[s.thread].notify_all();
    }
    return;
  }
  // Nobody is due, and no turn can run to change that: wait for a notify() from outside (or stop()).
  idle_ = true;
}

std::uint64_t LockstepScheduler::rounds() const {
  std::lock_guard lock(mutex_);
  return rounds_;
}

std::uint64_t LockstepScheduler::turns() const {
  std::lock_guard lock(mutex_);
  return turns_;
}

std::uint64_t LockstepScheduler::skipped() const {
  std::lock_guard lock(mutex_);
  return skipped_;
}

std::uint64_t LockstepScheduler::handoffs() const {
  std::lock_guard lock(mutex_);
  return handoffs_;
}

std::size_t LockstepScheduler::waiting() const {
  std::lock_guard lock(mutex_);
  return waiting_;
}

std::size_t LockstepScheduler::present() const {
  std::lock_guard lock(mutex_);
  return present_;
}

std::size_t LockstepScheduler::thread_of(Id id) const {
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  return slots_[id].thread;
}

bool LockstepScheduler::stopped() const {
  std::lock_guard lock(mutex_);
  return stopped_;
}

LockstepScheduler::Seat::~Seat() {
  if (single_) {
    scheduler_.leave(id_);
    return;
  }
  for (Id id = 0; id < scheduler_.slots_.size(); ++id) {
    if (scheduler_.slots_[id].thread == thread_.index) scheduler_.leave(id);
  }
}

bool LockstepScheduler::Seat::await_turn() {
  if (single_) return scheduler_.await_turn(id_);
  const std::optional<Id> id = scheduler_.await_turn(thread_);
  if (id) id_ = *id;
  return id.has_value();
}

namespace {

RealtimePacer::WallTime steady_wall_time() {
  return {[] { return RealtimePacer::WallClock::now(); },
          [](RealtimePacer::WallClock::time_point t) { std::this_thread::sleep_until(t); }};
}

}  // namespace

RealtimePacer::RealtimePacer(double speed) : RealtimePacer(speed, steady_wall_time()) {}

RealtimePacer::RealtimePacer(double speed, WallTime wall) : speed_(speed), wall_(std::move(wall)) {
  CW_CHECK(std::isfinite(speed) && speed > 0.0, "real-time speed must be finite and positive, got {}", speed);
  CW_CHECK(wall_.now && wall_.sleep_until, "a pacer needs both a clock and a way to sleep");
  anchor(SimDuration(0));
}

void RealtimePacer::anchor(SimDuration sim_now) {
  wall_origin_ = wall_.now();
  sim_origin_ = sim_now;
}

RealtimePacer::WallClock::duration RealtimePacer::pace(SimDuration sim_time) {
  const std::chrono::duration<double, std::nano> scaled(static_cast<double>((sim_time - sim_origin_).count()) / speed_);
  const WallClock::time_point due = wall_origin_ + std::chrono::duration_cast<WallClock::duration>(scaled);
  const WallClock::time_point now = wall_.now();
  if (now >= due) return now - due;
  wall_.sleep_until(due);
  return WallClock::duration::zero();
}

}  // namespace cellwright::runtime
