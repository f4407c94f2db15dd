#include "cellwright/twin/sim/signals.hpp"

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {

SignalTable::SignalTable(std::size_t count) : count_(count), levels_(count, false) {
  CW_CHECK(count > 0, "a signal table needs at least one signal");
}

std::size_t SignalTable::index(int channel) const {
  CW_CHECK(channel >= 1 && static_cast<std::size_t>(channel) <= count_, "signal {} outside 1..{}", channel, count_);
  return static_cast<std::size_t>(channel - 1);
}

void SignalTable::set(int channel, bool on) {
  const std::size_t i = index(channel);
  std::lock_guard lock(mutex_);
  levels_[i] = on;
}

bool SignalTable::get(int channel) const {
  const std::size_t i = index(channel);
  std::lock_guard lock(mutex_);
  return levels_[i];
}

std::vector<bool> SignalTable::levels() const {
  std::lock_guard lock(mutex_);
  return levels_;
}

}  // namespace cellwright::twin::sim
