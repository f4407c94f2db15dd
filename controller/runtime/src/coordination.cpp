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

void Coordination::set_grasp(const std::string& block, const Eigen::Isometry3d& grasp) {
  std::lock_guard lock(m_);
  carries_[block].grasp = grasp;
}

std::optional<Eigen::Isometry3d> Coordination::grasp(const std::string& block) const {
  std::lock_guard lock(m_);
  const auto it = carries_.find(block);
  return it == carries_.end() ? std::nullopt : it->second.grasp;
}

bool Coordination::claim_watch(const std::string& block, SimDuration now) {
  std::lock_guard lock(m_);
  CarryWatch& w = carries_[block];
  if (w.watched && *w.watched >= now) return false;
  w.watched = now;
  return true;
}

void Coordination::stop(const std::string& block, const std::string& reason) {
  std::lock_guard lock(m_);
  stops_.emplace(block, reason);
}

std::optional<std::string> Coordination::stopped(const std::string& block) const {
  std::lock_guard lock(m_);
  const auto it = stops_.find(block);
  if (it == stops_.end()) return std::nullopt;
  return it->second;
}

void Coordination::forget_carry(const std::string& block) {
  std::lock_guard lock(m_);
  carries_.erase(block);
}

}  // namespace cellwright::runtime
