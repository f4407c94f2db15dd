// The output of compiling a task-level program: one robot-independent primitive program per robot (paper section 2:
// move, open, close, signal, wait), with every primitive traced back to the task- and motion-level command it came
// from. This is what the Petri net is generated from (task/to_net.hpp) and what robot control executes.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::task {

// kLoop closes the body of a `repeat N ... end` block (RobotProgram::loops): it never goes to a robot and takes no
// time; after it the robot goes back to the body's first primitive (again) or on to the next one (exit).
// kDevice is an action of a device (a machine, a conveyor, a sensor) that a robot's program orders: it goes to device
// control (runtime/device_control.hpp), not to the robot, and the robot's program goes on when it is done.
enum class PrimitiveKind : std::uint8_t { kMove, kOpen, kClose, kSignal, kWait, kLoop, kDevice };

// What a kDevice primitive does (docs/task-language.md, "Devices"):
enum class DeviceOp : std::uint8_t {
  kStart,       // machine: set its start coil, see busy, clear start (the cycle has begun)
  kAwaitDone,   // machine: wait until its done input is on (the cycle has finished)
  kRun,         // conveyor: set its run coil
  kStop,        // conveyor: clear its run coil
  kAccumulate,  // conveyor: set its run coil; the belt stops itself while its stop eye is blocked
  kAwaitOn,     // sensor: wait until its input is on (a part is there)
};

// "start", "await done", "run", "stop", "accumulate", "await on".
const char* to_string(DeviceOp op);

// Where a move goes, symbolically; robot control resolves it against the environment model at run time.
enum class TargetKind : std::uint8_t {
  kAbove,     // approach/depart pose above an object (workpiece or location), gripper axis vertical
  kAt,        // grasp/put-down pose at an object
  kHandover,  // the hand-over pose between this robot and `object` (a robot label), holding the workpiece
  kHandApproach,  // approaching the other robot's hand (`object` = that robot) before a Get grasp
  kHandGrasp,     // at the other robot's hand, fingers around the workpiece it presents
  kHome,      // the robot's home pose
  kPark,      // the robot's park pose (the cell description's `park:`), out of the other robots' way
};

struct Target {
  TargetKind kind = TargetKind::kHome;
  std::string object;  // workpiece, location or robot label; empty for kHome
};

// A segment of a coordinated block (compiled.hpp CoordinatedUse; docs/task-language.md "Coordinated motion"): one
// move or gripper action that the block's two robots do together, starting and stopping together. Both robots'
// primitives of a segment carry the master's symbolic target; the master goes there, the follower to the master's
// target composed with the fixed grasp transform between the two grasp points on the workpiece.
struct Segment {
  std::string block;     // the coordinated block's name
  int index = 0;         // 1-based, in the block's order
  int count = 0;         // segments in the block
  std::string master;    // the robot whose target it is
  std::string follower;  // the robot that follows it
};

struct Primitive {
  PrimitiveKind kind = PrimitiveKind::kMove;
  Target target;          // kMove only
  std::string event;      // kSignal / kWait: event (semaphore) name
  std::string workpiece;  // kClose: the workpiece grasped; kOpen: the workpiece released (empty if none)
  int loop = -1;          // kLoop: index into RobotProgram::loops of the loop it closes; -1 for the other kinds
  std::string device;     // kDevice: the machine, conveyor or sensor
  DeviceOp op = DeviceOp::kStart;  // kDevice: what it does
  std::optional<Segment> segment;  // kMove/kOpen/kClose of a coordinated block: which segment; nullopt otherwise
  // Provenance, for listings and for analysis results told in program terms.
  SourceLocation where;   // the task-level command (or signal/wait/enter/leave statement) in the source
  std::string task;       // task-level command as written, e.g. "Pick A"
  std::string motion;     // motion-level command, e.g. "approach A"
};

// One `repeat N ... end` block as one robot runs it. Primitives [begin, end) are the body; primitive `end` is the
// kLoop primitive that closes it. Reaching it, the robot goes back to `begin` (again) or on to end + 1 (exit).
//
// Who decides: a loop in the steps table is run by every robot of the table; the first column (the leader) decides,
// after the barrier that ends the body's last line, and tells each other table robot (a follower, column order) by
// an inserted event, `loopL.LEADER>FOLLOWER.again` or `loopL.LEADER>FOLLOWER.exit` (L: the source line of `repeat`).
// A follower's kLoop primitive waits for one of its two events. In a sequence the robot is its own leader and has no
// followers, unless its loop names partners (`repeat N with R2 ...`, LoopBlock::partners): the loops of those
// sequences are one loop, named after the leader's `repeat` line, whose leader is the group's robot declared first
// (`robot` order) and whose followers are the others in that order. Such a loop is `paced`: with no barrier before
// the decision, the leader could otherwise decide twice before a follower has taken the first decision, and a
// follower would find again and exit both signalled. So each follower, taking a decision, signals
// `loopL.FOLLOWER>LEADER.taken` (initially 1), and the leader's again and exit each take one from every follower:
// the leader is at most one iteration ahead of each follower. The count is not in the Petri net: the net lets the
// leader choose freely (so its check holds for any number of iterations, and costs the same for 3 or 3,000); task
// control counts and chooses at run time.
struct Loop {
  std::string name;          // "loopL", L the line of `repeat`; the prefix of its inserted events
  SourceLocation where;      // the `repeat` keyword
  std::uint32_t count = 1;   // iterations (at least 1)
  std::size_t begin = 0;     // first primitive of the body
  std::size_t end = 0;       // index of the kLoop primitive (begin <= end)
  std::string leader;        // the robot that decides (this robot, in a sequence or as the table's first column)
  std::vector<std::string> followers;  // leader only: the robots it tells, in column order; empty for a follower
  bool paced = false;        // a loop of cooperating sequences: the `taken` events pace the leader (above)
};

// The events of a loop's decision: "loopL.r1>r2.again", "loopL.r1>r2.exit".
std::string loop_again_event(const Loop& loop, const std::string& follower);
std::string loop_exit_event(const Loop& loop, const std::string& follower);
// A paced loop's acknowledgement: "loopL.r2>r1.taken" (follower r2 has taken leader r1's last decision).
std::string loop_taken_event(const Loop& loop, const std::string& follower);

struct RobotProgram {
  std::string robot;
  std::vector<Primitive> primitives;
  std::vector<Loop> loops;  // in program order; loops do not nest
};

// An event object / counting semaphore. Critical regions are semaphores too (initial 1) whose wait/signal pairs
// bracket the region; `region` marks them.
struct Semaphore {
  std::string name;
  std::uint32_t initial = 0;
  bool region = false;
  SourceLocation declared;  // user semaphores/regions: the declaration; inserted events: the command that needs them
  bool inserted = false;    // inserted by the compiler (lock-step barrier or Put/Get hand-over event)
  // A device's state (inserted too, `inserted` false): the device's name; its places are "M.idle" (initial 1),
  // "M.loaded", "M.busy", "M.done" for a machine M, "C.stopped" (initial 1) and "C.running" for a conveyor C. Empty
  // for the others.
  std::string device{};
};

// A device's state event, "mill.idle".
std::string device_state_event(const std::string& device, const char* state);

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

// A workpiece class (`workpiece part from IN`): not one workpiece but whichever arrives at location `from`. At run
// time each Pick of the class by a robot takes the next part that has arrived there and that nobody else has taken,
// and the name means that part in the robot's commands until it lets go of it (the taker of a hand-over takes the
// giver's part with it).
struct WorkpieceClass {
  std::string name;
  std::string from;     // a location label of the program
  SourceLocation where;  // the name in the declaration
};

// A photo-eye and the conveyor whose parts it sees.
struct SensorDecl {
  std::string name;
  std::string conveyor;
};

// A coordinated block as compiled: its robots, what they carry, its segments, and where each robot runs it.
// The block's synchronisation is by inserted events: before each segment k, and after the last (k = count + 1,
// written "end"), each robot signals `NAME.sK.SELF>OTHER` and waits for `NAME.sK.OTHER>SELF` (a barrier pair), so that
// in the Petri net neither robot can begin a segment, or leave the block, without the other; a block only one of them
// reaches deadlocks there, and `twin check` refuses it with the firing sequence.
struct CoordinatedUse {
  std::string name;
  SourceLocation where;  // the `coordinated` statement's name
  std::string master, follower;
  std::string workpiece;              // the named workpiece the block picks
  std::vector<std::string> segments;  // each segment's motion-level command ("approach beam"), in order
  struct Run {
    std::string robot;
    SourceLocation where;   // the robot's `coordinate NAME` command
    std::size_t begin = 0;  // its first primitive for the block (the first barrier)
    std::size_t end = 0;    // one past its last (the last barrier's wait)
  };
  std::vector<Run> runs;  // in compilation order; a robot that never runs the block has none
};

// The barrier events of a coordinated block: before segment k (1-based; k = count + 1 after the last), from robot
// `from` to robot `to`: "carry.s3.left>right", "carry.end.left>right".
std::string segment_event(const std::string& block, int k, int count, const std::string& from, const std::string& to);

struct CompiledProgram {
  std::string file;
  std::vector<std::string> robots;       // declaration order
  std::vector<std::string> workpieces;   // named workpieces only (declaration order); classes are in `classes`
  std::vector<WorkpieceClass> classes;   // declaration order
  std::vector<std::string> locations;
  std::vector<std::string> machines;     // declaration order
  std::vector<std::string> conveyors;    // declaration order
  std::vector<SensorDecl> sensors;       // declaration order
  std::vector<RobotProgram> programs;    // one per robot, same order as robots
  std::vector<Semaphore> semaphores;     // user semaphores, regions, and the events the compiler inserted
  std::vector<RegionUse> regions;
  std::vector<CoordinatedUse> coordinated;  // declaration order
};

// Whether the program declares a machine, conveyor or sensor named `name`.
bool declares_device(const CompiledProgram& program, const std::string& name);

// The class named `name`, or nullptr if it is a named workpiece (or not declared).
const WorkpieceClass* find_class(const CompiledProgram& program, const std::string& name);

// "move above(A)", "close A", "signal step2.r1>r2", "loop loop7" ...
std::string to_string(const Primitive& p);
const char* to_string(PrimitiveKind k);
std::string to_string(const Target& t);

}  // namespace cellwright::task
