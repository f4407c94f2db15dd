// The digital I/O wiring of the simulated cell: one table of binary signals shared by every simulated controller,
// as if each robot's outputs were wired to the other robots' inputs with the same number. A SimDriver's SetOutput(n)
// sets signal n; its WaitInput(n) waits for signal n. Outside code (a simulated machine, a test) may set and read
// signals too. All signals are off at the start.
//
// Determinism: SimDrivers read and write the table only while the World advances them (on the simulation thread, in
// robot order, once per physics step), so in lock-step runs the order of signal changes is fixed.
//
// Threads: every member may be called from any thread; each call is one short critical section.
#pragma once

#include <cstddef>
#include <mutex>
#include <vector>

namespace cellwright::twin::sim {

class SignalTable {
 public:
  // Signals 1..count. Throws InternalError if count is 0.
  explicit SignalTable(std::size_t count);
  SignalTable(const SignalTable&) = delete;
  SignalTable& operator=(const SignalTable&) = delete;

  std::size_t size() const { return count_; }
  // Sets or clears signal `channel` (1..size(); InternalError outside).
  void set(int channel, bool on);
  // The level of signal `channel` (1..size(); InternalError outside).
  bool get(int channel) const;
  // All levels, signal 1 first.
  std::vector<bool> levels() const;

 private:
  std::size_t index(int channel) const;

  const std::size_t count_;
  mutable std::mutex mutex_;
  std::vector<bool> levels_;
};

}  // namespace cellwright::twin::sim
