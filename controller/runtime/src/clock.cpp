#include "cellwright/runtime/clock.hpp"

#include <cmath>
#include <thread>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

SimDuration VirtualClock::advance(SimDuration dt) {
  CW_CHECK(dt.count() >= 0, "virtual time cannot run backwards (advance by {} ns)", dt.count());
  return SimDuration(ns_.fetch_add(dt.count(), std::memory_order_acq_rel) + dt.count());
}

LockstepScheduler::LockstepScheduler(std::size_t participants) : slots_(participants), present_(participants) {
  CW_CHECK(participants > 0, "a lock-step scheduler needs at least one participant");
}

bool LockstepScheduler::await_turn(Id id) {
  std::unique_lock lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  CW_CHECK(slots_[id].present, "participant {} awaits a turn after leaving", id);
  CW_CHECK(!(held_ && current_ == id), "participant {} awaits a turn it already holds", id);
  ++waiting_;
  slots_[id].cv.wait(lock, [&] { return stopped_ || (current_ == id && !held_); });
  --waiting_;
  if (stopped_) return false;
  held_ = true;
  return true;
}

void LockstepScheduler::yield(Id id) {
  std::lock_guard lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  CW_CHECK(held_ && current_ == id, "participant {} yields a turn it does not hold", id);
  held_ = false;
  ++turns_;
  pass_turn();
}

void LockstepScheduler::leave(Id id) {
  std::lock_guard lock(mutex_);
  CW_CHECK(id < slots_.size(), "participant {} out of range (scheduler has {})", id, slots_.size());
  if (!slots_[id].present) return;
  slots_[id].present = false;
  --present_;
  if (current_ == id) {
    if (held_) ++turns_;  // a turn ended by leaving still counts as taken
    held_ = false;
    pass_turn();
  }
}

void LockstepScheduler::stop() {
  std::lock_guard lock(mutex_);
  stopped_ = true;
  for (Slot& s : slots_) s.cv.notify_all();
}

void LockstepScheduler::pass_turn() {
  if (present_ == 0) return;
  const std::size_t n = slots_.size();
  Id next = current_;
  do {
    next = (next + 1) % n;
    if (next == 0) ++rounds_;
  } while (!slots_[next].present);
  current_ = next;
  slots_[current_].cv.notify_all();
}

std::uint64_t LockstepScheduler::rounds() const {
  std::lock_guard lock(mutex_);
  return rounds_;
}

std::uint64_t LockstepScheduler::turns() const {
  std::lock_guard lock(mutex_);
  return turns_;
}

std::size_t LockstepScheduler::waiting() const {
  std::lock_guard lock(mutex_);
  return waiting_;
}

std::size_t LockstepScheduler::present() const {
  std::lock_guard lock(mutex_);
  return present_;
}

bool LockstepScheduler::stopped() const {
  std::lock_guard lock(mutex_);
  return stopped_;
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
