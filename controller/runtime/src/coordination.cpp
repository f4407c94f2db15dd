#include "cellwright/runtime/coordination.hpp"

#include <algorithm>

namespace cellwright::runtime {

void Coordination::post(const std::string& block, std::uint64_t n, bool master, SegmentPost post) {
  std::lock_guard lock(m_);
  entries_[{block, n}].posts[master ? 0 : 1] = std::move(post);
}

std::optional<SegmentPost> Coordination::master_post(const std::string& block, std::uint64_t n) const {
  std::lock_guard lock(m_);
  const auto it = entries_.find({block, n});
  if (it == entries_.end()) return std::nullopt;
  return it->second.posts[0];
}

std::optional<double> Coordination::agreed(const std::string& block, std::uint64_t n, SimDuration now) const {
  std::lock_guard lock(m_);
  const auto it = entries_.find({block, n});
  if (it == entries_.end() || !it->second.posts[0] || !it->second.posts[1]) return std::nullopt;
  const SegmentPost& a = *it->second.posts[0];
  const SegmentPost& b = *it->second.posts[1];
  if (now <= std::max(a.posted, b.posted)) return std::nullopt;
  return std::max(a.least, b.least);
}

void Coordination::taken(const std::string& block, std::uint64_t n, bool master) {
  std::lock_guard lock(m_);
  const auto it = entries_.find({block, n});
  if (it == entries_.end()) return;
  it->second.taken[master ? 0 : 1] = true;
  if (it->second.taken[0] && it->second.taken[1]) entries_.erase(it);
}

}  // namespace cellwright::runtime
