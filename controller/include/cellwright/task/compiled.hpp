// The output of compiling a task-level program: one robot-independent primitive program per robot (paper section 2:
// move, open, close, signal, wait), with every primitive traced back to the task- and motion-level command it came
// from. This is what the Petri net is generated from (task/to_net.hpp) and what robot control executes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::task {

enum class PrimitiveKind : std::uint8_t { kMove, kOpen, kClose, kSignal, kWait };

// Where a move goes, symbolically; robot control resolves it against the environment model at run time.
enum class TargetKind : std::uint8_t {
  kAbove,     // approach/depart pose above an object (workpiece or location), gripper axis vertical
  kAt,        // grasp/put-down pose at an object
  kHandover,  // the hand-over pose between this robot and `object` (a robot label), holding the workpiece
  kHandApproach,  // approaching the other robot's hand (`object` = that robot) before a Get grasp
  kHandGrasp,     // at the other robot's hand, fingers around the workpiece it presents
  kHome,      // the robot's home pose
};

struct Target {
  TargetKind kind = TargetKind::kHome;
  std::string object;  // workpiece, location or robot label; empty for kHome
};

struct Primitive {
  PrimitiveKind kind = PrimitiveKind::kMove;
  Target target;          // kMove only
  std::string event;      // kSignal / kWait: event (semaphore) name
  std::string workpiece;  // kClose: the workpiece grasped; kOpen: the workpiece released (empty if none)
  // Provenance, for listings and for analysis results told in program terms.
  SourceLocation where;   // the task-level command (or signal/wait/enter/leave statement) in the source
  std::string task;       // task-level command as written, e.g. "Pick A"
  std::string motion;     // motion-level command, e.g. "approach A"
};

struct RobotProgram {
  std::string robot;
  std::vector<Primitive> primitives;
};

// An event object / counting semaphore. Critical regions are semaphores too (initial 1) whose wait/signal pairs
// bracket the region; `region` marks them.
struct Semaphore {
  std::string name;
  std::uint32_t initial = 0;
  bool region = false;
  SourceLocation declared;  // user semaphores/regions: the declaration; inserted events: the command that needs them
  bool inserted = false;    // inserted by the compiler (lock-step barrier or Put/Get hand-over event)
};

// A critical region: for each robot, the half-open primitive index ranges [enter, leave) spent inside it.
struct RegionSpan {
  std::string robot;
  std::size_t begin = 0;  // index of the primitive after the region's wait
  std::size_t end = 0;    // index of the region's signal
};
struct RegionUse {
  std::string name;
  std::vector<RegionSpan> spans;
};

struct CompiledProgram {
  std::string file;
  std::vector<std::string> robots;       // declaration order
  std::vector<std::string> workpieces;
  std::vector<std::string> locations;
  std::vector<RobotProgram> programs;    // one per robot, same order as robots
  std::vector<Semaphore> semaphores;     // user semaphores, regions, and the events the compiler inserted
  std::vector<RegionUse> regions;
};

// "move above(A)", "close A", "signal step2.r1>r2" ...
std::string to_string(const Primitive& p);
const char* to_string(PrimitiveKind k);
std::string to_string(const Target& t);

}  // namespace cellwright::task
