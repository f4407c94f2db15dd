// The cycle-time estimate made before a run: the program's Petri net timed with the durations of its commands and
// simulated at earliest firing times (timed_net.hpp), all robots concurrent, waits resolved at the times of their
// signals. It predicts a lock-step run on the twin; docs/scenarios.md compares it with measured runs.
//
// First the motion plan (plan_motions, computed once by the preflight and passed on), which follows the program in the order one untimed run of the net gives: each
// move's target is resolved as robot control resolves it (runtime::resolve_target on an environment model that
// follows the program: parts held move with the hand and keep the approach they were grasped with, parts put down
// rest where they were put, parts on a conveyor are picked at its stop, a hand that has just let go of a part departs
// straight up from where it let go) and solved with the robot's inverse kinematics from its previous joints (the
// solution within the limits closest to them). A coordinated block's moves are resolved as robot control resolves
// them, with the same function (runtime::resolve_segment_target, segment_target.hpp): each arm's own end of the
// workpiece before the grasp, the master's tool translated while carrying, the follower's target the master's
// composed with the grasp transform measured from the two arms' planned tools once both hold it; the master's move
// of a segment is planned before the follower's. Preflight refuses a program with a move the plan cannot make. A
// loop's body is planned on its first pass; a move the loop then runs again from elsewhere (its first move, from
// where the body's end left the arm) is timed as the repeats make it, the first pass too (PlannedCommand::again_from).
//
// Then the command durations, per robot primitive, as the simulated controller (sim/sim_driver.hpp) ends them:
//  - move: a joint move (robot control sends joint targets to a simulation driver): sim::move_duration, the quintic
//    profile's peak within max_joint_speed x speed, at least min_move_time; a straight line (a coordinated segment's
//    move but the first approach, sent as MovePose linear): the driver's own waypoints and least duration
//    (sim::straight_line, sim::least_move_duration, move_timing.hpp: the joints along the line, and the tool within
//    max_tool_speed x speed);
//  - a coordinated segment (docs/runtime.md "Coordinated blocks"): a move takes the agreed duration, the longer of the
//    two arms' least durations, on both arms; every segment command (a grip too) starts late by the rendezvous: each
//    robot posts in its turn of the round the segment was started in, the follower only once the master has, and
//    both submit in the round after the later post: one period when the master's turn comes first in the round
//    (robots take their turns in program order), two when it comes after;
//  - open/close: the finger ramp (sim/grip_timing.hpp) from where the last grip left it: an open to fully open, a
//    close to fully closed or, on a part, until the fingers press it (the part's width across the fingers from the
//    plan), then the rest window; in a loop's body, from where the body's end left the ramp, as the loop's repeats
//    find it (the first pass is timed so too);
//  - signal/wait (and a loop's end): 0 (a wait lasts until its signal, which the timed net resolves);
//  - lock-step turns: the driver starts a command at the physics step after the round it was sent in and ends it at
//    a physics step; robot control sees that in the next round, a move's position read-back takes one more round,
//    and task control fires the next transition in the round after the command's end. So a command lasts from its
//    firing to the next one: its physical time rounded up to the physics step and then to the control period, plus
//    two periods (a move three).
//  - before its first command each robot homes (min_move_time at home speed, the fingers opening) and activates.
// A named part that arrives on a conveyor (fed, or carried to the stop from where it starts) holds back the move that
// goes to pick it until it has arrived, at the belt's speed.
// Parts of a workpiece class that the feed brings (`workpiece part from IN`) are the feed's, in a net of its own
// joined to the program's (estimate_cycle_time): the i-th part fed is put on the belt at max(its feed time, the time
// a body became free) and can be picked once it has ridden to the stop; each firing of a move that takes a new part of
// the class (the first move to it) takes the next part there. In a shift (more parts than bodies) a body becomes free
// when the part it made has ridden the exit conveyor from where the open let go of it (the fingers' ramp passing its
// faces) to where the world takes it out (sim/belt_exit.hpp), at the belt's speed, at the end of the control period
// the world parks it in; the feed puts it on the belt in the next period.
// Parts of a class relayed over a belt (MotionPlan::QueueBelt: one robot lets them go on a belt between robots, another
// takes them at its stop) queue there: the belt accumulates, so while a part waits at the stop the belt stands and the
// next part stays where it was let go of; it rides to the stop once the part before it is lifted off. So the take of
// the next part waits for both the part's own ride from its open and a ride from the lift of the part before it (the
// queue's net, estimate_cycle_time): exact for a part let go of while the part before it waits at the stop or after
// it was lifted; a part let go of while the one before it still rides would come up sooner than the estimate has it.
// The lift is taken from the start of the move that lifts the part (the belt restarts once it is 5 mm up, about a
// tenth of a second later).
// Not modelled: parts queueing on the feed's belt (a fed part is taken to reach the stop at its own ride's end; on an
// accumulating belt the queue stands while a part waits at the stop, so a part comes up the rest of its ride after
// the lift of the part before it: in the shipped scenes the part is there before the arm comes back for it),
// the frames a camera needs to see a part (perception vision), the few control periods a part pressed against a stop
// bar may take to come to rest. Feed times are taken as they are, not rounded to the control period (exact when the
// feed's start and period are whole periods, as in the shipped scenes). The bodies of a shift are not told apart:
// each rides in as long as the longest of them. The finger ramp of a close is taken to be over by the next open (it
// is over 1.5 s after the close began, and an arm moves in between).
//
// Thread safety: pure functions; any thread may call them.
#pragma once

#include <Eigen/Geometry>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/petri/net.hpp"
#include "cellwright/runtime/environment_model.hpp"
#include "cellwright/task/compiled.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/timed_net.hpp"

namespace cellwright::cell {

// One primitive of the program as the motion plan follows it.
struct PlannedCommand {
  std::string robot;  // program label
  std::string cell;   // cell robot
  std::size_t primitive = 0;
  task::PrimitiveKind kind = task::PrimitiveKind::kMove;
  std::string command;   // "move above(A)"
  std::string source;    // the task-level command it belongs to: "exchange.task:10:14 'Place B'"
  bool reached = false;  // the untimed run of the net reached it
  // Moves only:
  std::vector<double> from, goal;  // joints before and after (goal empty when the move cannot be made)
  // A move in a loop's body that the loop runs again from elsewhere: the joints it then starts from (where the body's
  // end left the arm); empty when every pass starts from `from`. The goal is the first pass's.
  std::vector<double> again_from;
  std::string target;              // the resolved target ("above B: tool at (...)"), or "" when unresolved
  // A straight line of the tool (a coordinated segment's move but the first approach): its goal in the base frame.
  std::optional<Eigen::Isometry3d> line_to;
  std::string problem;             // why the move cannot be made, "" when it can
  // The part the hand carries during the move (cell workpiece, "" for none) and its pose in the tool (tcp) frame;
  // `closed`: the last grip before the move closed the fingers, to half the part's width across them (m) or, on
  // nothing, fully (0); nullopt when they are open (as homing leaves them).
  std::string held;
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();
  std::optional<double> closed;
  // Open and close only: half the width of the part across the fingers (m), where they close on it or let go of it;
  // nullopt when the plan puts no part between them (a grip that names none). For a part of a class relayed over a
  // belt (no body in the plan, see queue_belts): the width of the body last let go of on that belt.
  std::optional<double> contact;
};

// A part that has to arrive before a robot can go to it: `transition` starts the first move to it.
struct ArrivalGate {
  petri::TransitionId transition = 0;
  std::string workpiece;  // cell name
  double ready = 0;       // s: when it is at the stop, at rest
  std::string conveyor;   // the conveyor it rides to its stop (or end)
};

// A body of a shift delivered: the open that lets go of a fed body over an exit conveyor (every conveyor but the
// feed's; the world takes the part out at the conveyor's exit point, sim/belt_exit.hpp, and feeds its body again).
struct Delivery {
  petri::TransitionId transition = 0;  // starts the open
  std::size_t robot = 0;               // program robot index
  std::size_t primitive = 0;           // of the open
  std::string conveyor;                // the exit conveyor
  double distance = 0;                 // m along the belt from where the part is let go to the exit point
  double ride = 0;                     // s: the distance at the belt's speed
};

struct MotionPlan {
  std::vector<std::vector<PlannedCommand>> commands;  // per program robot, per primitive
  std::vector<ArrivalGate> gates;                     // named parts
  // Transitions that start the first move to a new part of a class the feed brings: each firing takes the next part
  // fed (see the top).
  std::vector<petri::TransitionId> feed_takes;
  // Every move that takes a new part of a class from the class's location (`workpiece part from LOC`; not a Get's,
  // which takes the giver's part): the part arrives there, fed, carried by a belt or put down by another robot, and
  // the robot programs must know it is there before the move (robot_programs.hpp). `fed`: one of feed_takes.
  struct ClassTake {
    petri::TransitionId transition = 0;
    std::string label;     // the program's class
    std::string location;  // the cell location it is taken from
    bool fed = false;
  };
  std::vector<ClassTake> class_takes;
  // The first move to a named part after an open let go of it on a running belt, which carries it on: the plan puts
  // the part where the belt stops it (its stop bar, or its end), at rest; the estimate does not time the ride, and
  // the robot programs refuse it (robot_programs.hpp).
  struct BeltRide {
    petri::TransitionId transition = 0;
    std::string workpiece;  // cell workpiece
    std::string conveyor;   // the belt it was let go of on
    std::string put;        // the open's task-level command: "prog.task:5:3 'Place OUT'"
  };
  std::vector<BeltRide> belt_rides;
  double feed_ride = 0;  // s a fed part rides from the feed's entry point to the stop (the longest of the bodies')
  // A belt between robots that parts of a class ride (a relay over a belt, scenes/relay_belt.task: one robot lets
  // them go on it, another takes them at its stop bar; the class's location is at the stop of a running belt that is
  // not the feed's). Its parts queue: the belt stands while a part waits at the stop (it accumulates), so a part let
  // go of behind it rides to the stop once that part is lifted off it (see estimate_cycle_time).
  struct QueueBelt {
    std::string conveyor;
    std::vector<petri::TransitionId> puts;   // start an open that lets go of a part of the class on the belt
    std::vector<petri::TransitionId> takes;  // start the first move to a new part of the class (at the stop)
    std::vector<petri::TransitionId> lifts;  // start the move that lifts a part of the class off the stop
    double ride = 0;  // s from where a part is let go of to the stop, at the belt's speed (the longest of the puts')
  };
  std::vector<QueueBelt> queue_belts;  // only belts with puts, takes and lifts
  std::vector<Delivery> deliveries;  // a shift's opens that deliver a body (empty unless the feed recycles)
  // One line per move that cannot be made: the robot, the command, its source and why.
  std::vector<std::string> problems() const;
};

// The running belt (speed > 0) whose top surface holds `point` (within 1 cm of it), or nullptr: a part let go of
// there rides on.
const models::ConveyorSpec* running_belt_under(const models::CellDescription& cell, const Eigen::Vector3d& point);

// Follows one untimed run of the net (petri::choose over everything enabled) and plans every move as robot control
// will make it (see the top): parts ride conveyors to their stop, are held, handed over, put down and, in a shift,
// delivered. Moves whose
// target cannot be resolved or has no inverse-kinematics solution within the joint limits are reported in
// PlannedCommand::problem (the robot then stays where it was). Throws InputError if a URDF cannot be read.
// The one function that computes the plan: the preflight calls it once per scenario (targets: the scenario's
// handover_clearance) and keeps it (Preflight::plan); the sweep, the estimate, the robot programs, the dry run and
// the run take it from there.
MotionPlan plan_motions(const Scenario& scenario, const petri::Net& net, const runtime::TargetOptions& targets);

// How fast one robot's controller executes commands (the simulated controller's settings).
struct RobotTiming {
  std::vector<double> max_joint_speed;  // rad/s per arm joint at speed 1
  double speed = 0.5;                   // fraction of max_joint_speed the moves use
  double min_move_time = 0.2;           // s, the shortest motion
  double max_tool_speed = 0.5;          // m/s of the tool on a straight line at speed 1
  double linear_step = 0.005;           // m between a straight line's waypoints ...
  double max_waypoint_step = 0.25;      // rad: ... and the largest joint step between them (move_timing.hpp)
  models::IkOptions ik;                 // how the driver solves the waypoints
  double finger_speed = 0.05;           // m/s of each finger's ramp at its peak
  double finger_open = 0.04;            // m: each finger's position fully open ...
  double finger_closed = 0.0;           // ... and fully closed
  double finger_squeeze = 0.002;        // m: grip force / finger stiffness, the ramp's lead when the fingers press
  double release_clearance = 0.005;     // m each finger opens beyond a part it lets go of (SimDriverOptions)
};

struct EstimateOptions {
  std::map<std::string, RobotTiming> robots;  // by cell robot name; every program robot needs one
  double control_period = 0.01;               // s: the lock-step round (scenario options.control_period)
  double physics_step = 0.002;                // s: the simulation's timestep (the cell's timestep)
};

// One primitive's estimated duration and what it is based on.
struct CommandEstimate {
  std::string robot;  // program label
  std::size_t primitive = 0;
  std::string command;  // "move above(A)"
  double motion = 0;    // s the driver takes (its physical part, before the lock-step turns are added)
  double seconds = 0;   // s from the firing that starts it to the firing after it (what the timed net uses)
  std::string basis;    // "joint move, largest step 1.234 rad (joint 2)", "close on a part ...", "net only"
};

struct Estimate {
  std::vector<CommandEstimate> commands;  // every primitive of every robot, program order
  std::vector<double> place_duration;     // per place of the timed net
  // The program's net with the arrival places added and, for a program that takes parts of a class the feed brings,
  // the feed's net (places and transitions "feed.*", see estimate_cycle_time).
  petri::Net timed_net;
  TimedRun run;
  // When the last robot is done: the last firing of one of the program's transitions (`net`'s: run.finish, but for
  // the feed's net, which goes on delivering the last parts after the program's end).
  double cycle_time = 0;
  std::vector<std::string> notes;  // targets that could not be resolved (their moves count min_move_time)
};

// Estimates the cycle time of the scenario's program, whose net is `net` (task::to_net of the program), from its
// motion plan `plan` (plan_motions of that net: the preflight's, Preflight::plan; nothing is planned here). Throws
// InternalError when a program robot has no timing in `options` (or one of the wrong size), the plan is not of this
// program (its robots or primitives), or a period or step is not > 0.
//
// The feed's net, for a program with feed takes (each place's duration in brackets; p = the control period):
//  - feed.first [start] --feed.begin--> feed.slot [0] + feed.clock [period], feed.clock --feed.tick--> feed.clock +
//    feed.slot: a slot at each feed time, feed.begin and feed.tick each taking one of the `count` tokens of
//    feed.due [0];
//  - feed.slot + feed.free [0] (a token per body) --feed.feed--> feed.part [feed_ride rounded up to p]: a part at the
//    stop, taken by every feed take (an input arc of its transition);
//  - in a shift, per delivery d: its open's transition --> feed.leaving.d [from the open's start to the end of the
//    period in which the part, let go of, has ridden to the exit point] --feed.delivered.d--> feed.free.
// The queue's net, per relay belt B (MotionPlan::queue_belts; r = the ride from where a part is let go of to the
// stop, rounded up to p):
//  - each put (the open that lets go of a part on B) --> queue.B.put [r], each lift (the move that lifts a part off
//    the stop) --> queue.B.clear [r] (one token at the start); each take (the first move to the next part at the
//    stop) takes one token of each: the part arrives r after the later of its put and the lift before it.
Estimate estimate_cycle_time(const Scenario& scenario, const petri::Net& net, const MotionPlan& plan,
                             const EstimateOptions& options);

}  // namespace cellwright::cell
