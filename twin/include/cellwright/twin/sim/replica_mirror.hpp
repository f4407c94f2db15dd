// ReplicaMirror: the twin's copies of robots whose robot control runs in another process (an agent on its real
// driver, docs/distributed.md), made to follow what those robot controls write into their environment models: each
// robot's measured position (joints, or the tool pose a Cartesian controller reports) and what its hand holds. In one
// process a real robot's copy is given every command as the real one is (MirroredDriver); an agent's commands to its
// driver never leave its process, so the copy follows the replicated state instead (distributed/replica.hpp's model
// updates), as the agent publishes it.
//
// HOW THE COPIES FOLLOW. Each state pushed (push(), in the order the agent published it) is turned into what the copy
// must do to get there from the previous state, in that order:
//   - a move, when the position changed by more than the tolerances: MoveJoints to the new joints, or to the tool
//     pose's inverse kinematics seeded with the copy's last target (the configuration nearest to where it stands);
//   - a grip, when the hold changed: close on taking a workpiece, open on letting one go (both when it took another).
// A copy does its actions one at a time, each when the last is done, at full speed (it follows the real robot's last
// measured position, so it runs one motion behind it; full speed keeps that lag short). The hand-over rule keeps the
// cross-robot order the program had: an open that lets go of workpiece W waits while another copy still has a close
// on W to do (the real arms closed before they opened; the copies may be behind by different amounts), so a part
// handed over in the real cell is handed over in the twin rather than dropped.
// More than kMaxBehind moves waiting: the older moves are dropped (the copy goes straight to the newer positions);
// grips are never dropped.
//
// The copies' failures (a pose without IK solution, a refused or failed command, a copy in fault) never reach the
// agents: the action is dropped and counted (counts()), and the next state corrects the copy.
//
// LIFECYCLE. start() brings every copy up (connect, home, activate, as a robot control does) on the mirror's own
// thread, which owns the copies from then on (their RobotDriver calls are its only), and starts following; push()
// before start() is kept. stop() (and the destructor) stops the thread and the copies where they stand. idle() says
// whether every copy is up with nothing left to do: after the run, the World is stepped until then (the copies catch
// up with the last states) by whoever steps it.
//
// THREADS. push() from any thread (DDS's listener threads); counts() and idle() from any thread. The copies are
// stepped by the simulation thread as every SimDriver; their notifiers wake the mirror's thread.
#pragma once

#include <Eigen/Geometry>

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"
#include "cellwright/models/kinematics.hpp"

namespace cellwright::twin::sim {

// What an agent's robot control last wrote of its robot (its environment model's RobotState, as replicated).
struct ReplicaState {
  std::vector<double> joints;                     // measured joints (empty, or the home joints, when it reads poses)
  std::optional<Eigen::Isometry3d> tool_in_base;  // the measured tool pose in the robot's base frame, if any
  std::optional<std::string> holding;             // the workpiece its hand holds, if any
};

class ReplicaMirror {
 public:
  struct Copy {
    std::string robot;                       // its name in the cell
    drivers::RobotDriver* driver = nullptr;  // the World's SimDriver of that robot (not owned)
    models::KinematicChain chain;  // its kinematics (base_link to tool), for tool poses
    std::vector<double> home;      // where it stands at first (radians)
  };
  struct Counts {
    int states = 0;  // states pushed
    int moves = 0;   // moves and grips the copies were given
    int grips = 0;
    int misses = 0;   // what a copy could not do (no IK solution, refused, failed), and moves dropped behind
    int waits = 0;    // opens held back by the hand-over rule
  };
  static constexpr double kJointTolerance = 0.01;  // rad
  static constexpr double kToolTolerance = 0.002;  // m
  static constexpr std::size_t kMaxBehind = 16;

  // Throws InternalError for a copy without a driver, or whose driver does not take its chain's joints.
  explicit ReplicaMirror(std::vector<Copy> copies);
  ~ReplicaMirror();
  ReplicaMirror(const ReplicaMirror&) = delete;
  ReplicaMirror& operator=(const ReplicaMirror&) = delete;

  // The copy of `robot`'s index, or nullopt when it has none here.
  std::optional<std::size_t> index_of(const std::string& robot) const;
  // The newest state of copy `index`'s robot, published after the last one pushed.
  void push(std::size_t index, ReplicaState state);
  void start();
  void stop();
  bool idle() const;
  Counts counts() const;

 private:
  struct Action {
    enum class Kind { move, close, open } kind = Kind::move;
    std::vector<double> joints;  // a move's
    std::string workpiece;       // a grip's
    bool held_back = false;      // an open the hand-over rule has held back (counted once)
  };
  struct Follower {
    explicit Follower(Copy c) : copy(std::move(c)) {}
    Copy copy;
    std::optional<ReplicaState> last;  // the last state pushed
    std::vector<double> target;        // the joints of the last move given (or home)
    std::deque<Action> todo;
    std::optional<Action> running;
    drivers::CommandId running_id = 0;
    drivers::CommandId home_id = 0;
    bool up = false;
  };
  void loop();
  // One pass over the copies (the mirror's thread, mutex held): bring-up, finished commands, the next actions.
  void advance(std::unique_lock<std::mutex>& lock);
  bool closing_elsewhere(std::size_t index, const std::string& workpiece) const;
  void to_actions(Follower& f, const ReplicaState& state);

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<Follower> followers_;
  Counts counts_;
  bool started_ = false;
  bool stopping_ = false;
  bool poke_ = false;  // something changed since the last pass
  std::thread thread_;
};

}  // namespace cellwright::twin::sim
