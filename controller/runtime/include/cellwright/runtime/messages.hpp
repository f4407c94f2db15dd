// The messages between the task-control thread and the robot-control threads (paper Fig. 2): a motion-level command
// down, a status up. They travel through MessageQueues (message_queue.hpp); both are plain values.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

// Task control -> robot control: execute primitive `index` of robot `robot`'s program. Only move/open/close are
// sent; signal and wait are net-only and complete as their transition fires.
struct MotionCommand {
  std::size_t robot = 0;               // index into the program's robots (and Net::robots())
  std::size_t index = 0;               // primitive index in that robot's program
  task::Primitive primitive;           // the primitive, with its provenance
  petri::TransitionId transition = 0;  // the transition whose firing started it
  SimDuration sent{0};                 // simulation time it was sent
};

enum class CommandOutcome { kDone, kFailed };

// "done", "failed".
std::string_view to_string(CommandOutcome outcome);

// Robot control -> task control: how a command ended (or that the robot could not be brought up).
struct RobotStatus {
  // An index meaning "no command": the robot failed before any command (its driver could not be homed/activated).
  static constexpr std::size_t kNoCommand = static_cast<std::size_t>(-1);

  std::size_t robot = 0;
  std::size_t index = kNoCommand;  // the primitive the status is about
  CommandOutcome outcome = CommandOutcome::kDone;
  std::string reason;   // kFailed: why, naming the values involved
  bool stop_cell = false;  // kFailed by recovery's stop_cell: the cell is stopped safely (outcome "stopped")
  SimDuration time{0};  // simulation time it ended
};

}  // namespace cellwright::runtime
