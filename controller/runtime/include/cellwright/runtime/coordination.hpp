// Coordination: the rendezvous of the two robots of a coordinated block (docs/task-language.md, "Coordinated motion";
// docs/runtime.md, "Coordinated blocks"), segment by segment. The Petri net's barrier pairs already make both robots
// begin a segment's command together; this board makes them execute it together: the master posts its segment's tool
// target (a move's, in the world) and its least time; the follower, which needs the master's target to compute its
// own (the master's target composed with the grasp transform), posts its least time; once both have posted, and from
// the turn after the later post on, each submits its command with the agreed duration, the longer of the two least
// times (the slower segment sets the time for both, as ABB MultiMove's synchronised moves do). In lock-step both
// robots therefore submit in the same period, whatever their order of turns.
//
// Segments are keyed by the block's name and the occurrence: the n-th segment of that block the robot executes,
// counted by each robot from 0 (both execute the same segments in the same order: the net enforces it).
//
// The carry's safety watch (docs/runtime.md, "Coordinated blocks"; RobotControl::watch_carry): while both robots
// hold the workpiece, the first of the two to take its turn in a control period checks the pair for both
// (claim_watch), from the grasp transform the follower measured (set_grasp) and what the controller senses of both;
// a trip is recorded here (stop) and the other robot, seeing it (stopped) in its own turn, stops too: in lock-step
// in the same period. forget_carry() clears a block's carry when its last segment is submitted.
//
// Threads: any robot-control thread; every call takes the board's own mutex, briefly. No call blocks or waits for the
// other robot: a robot whose partner has not posted yet asks again on its next turn.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "cellwright/runtime/clock.hpp"

namespace cellwright::runtime {

// What one robot posts for a segment.
struct SegmentPost {
  std::optional<Eigen::Isometry3d> target;  // the master's tool target (world) for a move; nullopt for a grip
  double least = 0;                         // seconds: the least time of its command (RobotDriver::least_duration)
  SimDuration posted{0};                    // when it was posted
};

class Coordination {
 public:
  // Posts robot `master ? master : follower`'s part of segment (block, n). Posting twice replaces the first post.
  void post(const std::string& block, std::uint64_t n, bool master, SegmentPost post);
  // The master's post of segment (block, n), if it has posted.
  std::optional<SegmentPost> master_post(const std::string& block, std::uint64_t n) const;
  // The agreed duration of segment (block, n) (the longer least time) once both robots have posted and `now` is
  // later than both posts; nullopt before.
  std::optional<double> agreed(const std::string& block, std::uint64_t n, SimDuration now) const;
  // Robot `master ? master : follower` has submitted its command of segment (block, n): once both have, the segment
  // is forgotten.
  void taken(const std::string& block, std::uint64_t n, bool master);

  // The follower's grasp transform of `block` (master tool -> follower tool, measured once both hold the workpiece);
  // nullopt before.
  void set_grasp(const std::string& block, const Eigen::Isometry3d& grasp);
  std::optional<Eigen::Isometry3d> grasp(const std::string& block) const;
  // True for the first call for `block` at time `now` (later times count anew): that robot checks the pair.
  bool claim_watch(const std::string& block, SimDuration now);
  // The carry of `block` must stop: `reason` says why (the first reason recorded stays).
  void stop(const std::string& block, const std::string& reason);
  // Why the carry of `block` was stopped; nullopt while it was not.
  std::optional<std::string> stopped(const std::string& block) const;
  // The block's carry is over: its grasp and watch are forgotten (a stop stays).
  void forget_carry(const std::string& block);

 private:
  struct CarryWatch {
    std::optional<Eigen::Isometry3d> grasp;
    std::optional<SimDuration> watched;  // the last period a robot claimed
  };
  std::map<std::string, CarryWatch> carries_;
  std::map<std::string, std::string> stops_;
  struct Entry {
    std::optional<SegmentPost> posts[2];  // [0] master, [1] follower
    bool taken[2] = {false, false};
  };
  mutable std::mutex m_;
  std::map<std::pair<std::string, std::uint64_t>, Entry> entries_;
};

}  // namespace cellwright::runtime
