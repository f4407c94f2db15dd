// The environment model (paper section 3, Fig. 2): positions and orientations of the robots, workpieces, locations,
// conveyors and machines, the workpieces' shapes, sizes and grasp information, and which robot holds what. It is
// pre-coded from the cell description (the paper's off-line CAD data), updated every control period from the
// simulation's ground truth, and corrected by vision (issue 5) through correct().
//
// EnvironmentModel is a plain value; the runtime shares one as SharedEnvironment (a Guarded<>, guarded.hpp). Copy out
// what you need in a short read() and work on the copy.
//
// Target resolution (resolve_target) turns a primitive's symbolic move target into tool poses for one robot:
//  - above(X) / at(X), X a workpiece: at = the part's grasp point, the tool centre point `grasp_height` above the
//    part's bottom centre, gripper pointing down, fingers closing on the part's faces: along the part's own yaw (or
//    half a turn round), or, when the part rests at a cell location (its bottom within
//    TargetOptions::at_location_tolerance of it), along the face direction (of four, for a box) nearest that
//    location's yaw;
//    above = the same raised by `approach_height`. grasp/approach heights are those of that location, else the
//    LocationSpec defaults (0.02 m / 0.08 m).
//    A part that is absent, held by another robot, or still moving (faster than part_at_rest_speed) is not ready:
//    the robot waits for it (Resolution::kWait).
//  - above(X) / at(X), X a location: at = the location's grasp point (grasp_height above it); when the robot holds a
//    part, the tool goes where it puts the part's bottom on the location (the hold's height above the part bottom)
//    with the approach it holds the part with (down, or from the side: then with the tool axis horizontal, pointing
//    away from the robot's base if it can, else turned about the vertical in 30 degree steps, least turned preferred);
//    above = at raised by approach_height. Except when the robot holds nothing, opened its hand on a part within
//    at_location_tolerance of the location and its tool is still there: above is then that tool pose raised by
//    approach_height, orientation
//    kept, so that it departs straight up between the part and whatever it stands on (a hand that put a part down
//    from the side would otherwise sweep its fingers through the surface, turning to point down).
//  - handover(R): the giver presents the part at the hand-over pose: its tool goes to hand-over pose + its grasp's
//    offset (HandoverSpec), with its grasp's approach and the hand-over's yaw.
//  - hand_grasp(P): the taker's tool at the part P presents (its centre, from the model, when P holds one; else the
//    hand-over pose) + the taker's grasp offset, with the taker's approach.
//  - hand_approach(P): the hand-over pose + the taker's offset, backed off `handover_clearance` along the tool's
//    approach axis; where the arm cannot reach that, the same pose lowered by `handover_clearance` instead (the open
//    fingers straddle the part from below, clear of the giver's hand above), then backed off half as far.
//  - home: the robot's home joints.
// Poses are offered as alternatives (the fingers turned half a turn about the approach axis give the same grasp);
// robot control takes the reachable one closest to the current joints.
//
// Threads: all free functions are pure and may be called from any thread on values they own.
#pragma once

#include <Eigen/Geometry>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/guarded.hpp"
#include "cellwright/runtime/plant.hpp"
#include "cellwright/runtime/sensors.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::runtime {

// ---- The cell's fixed geometry: made once from the cell description, never changed, shared by every copy ----

struct CellRobot {
  std::string name;
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();  // base_link in the world
  std::vector<double> home;                                // radians
  std::vector<double> park;                                // radians; empty: the cell gives no park pose
};

struct CellWorkpiece {
  std::string name;
  models::Shape shape = models::Shape::kBox;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // full extents
};

struct CellLocation {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // the part's bottom centre when it rests there
  double grasp_height = 0.02;
  double approach_height = 0.08;
};

struct CellConveyor {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // footprint centre on the floor
  double length = 0, width = 0, height = 0, speed = 0;
};

struct CellMachine {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // footprint centre on the floor
  Eigen::Isometry3d fixture_top = Eigen::Isometry3d::Identity();
};

// What of the cell never changes during a run: the robots' bases and homes, the workpieces' shapes and sizes, the
// locations with their grasp heights, the conveyors, the machines and the hand-over with its grasps. Immutable once
// made (make_environment_model makes it), held by shared pointer: copying a model copies only its changing state.
struct CellGeometry {
  std::vector<CellRobot> robots;
  std::vector<CellWorkpiece> workpieces;
  std::vector<CellLocation> locations;
  std::vector<CellConveyor> conveyors;
  std::vector<CellMachine> machines;
  std::optional<models::HandoverSpec> handover;

  // Lookups by cell name; nullptr when there is none.
  const CellLocation* find_location(std::string_view name) const;
};

// ---- What changes: poses, motion, presence, holds, confidences (guarded by the runtime) ----

struct WorkpieceState {
  std::string name;
  const CellWorkpiece* fixed = nullptr;  // its geometry, in the model's CellGeometry (shared, lives as long as it)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // centre, world
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      // m/s, world
  // Whether `velocity` is known: false for a part vision has seen once only (it may be riding a belt); such a part
  // is not ready to be grasped.
  bool motion_known = true;
  bool present = true;    // in the cell now
  std::string held_by;    // cell robot holding it, empty if none (set by robot control on close/open)
  // Cell robot that has taken it as the part of a workpiece class it is about to pick or is carrying (robot
  // control's NameMap::classes), empty if none: no other robot binds a class to it meanwhile.
  std::string claimed_by;
  double confidence = 1;  // 1 for the CAD data and the simulation's truth; vision's confidence after correct()
  SimDuration stamp{0};   // simulation time the pose was measured at
  // Declared lost by robot control's recovery (set_aside, docs/faults.md): every command about it is skipped from
  // then on. `pose` is where it was last seen; `lost_reason` says why.
  bool lost = false;
  std::string lost_reason;

  models::Shape shape() const { return fixed->shape; }
  const Eigen::Vector3d& size() const { return fixed->size; }  // full extents (cell description)
};

// Whether the part stands upright (its axis within 15 degrees of vertical): a grasp from above fits it.
inline bool stands_upright(const WorkpieceState& w) {
  return w.pose.linear().col(2).z() > std::cos(15.0 * M_PI / 180.0);
}

// How a robot holds the part it has grasped: recorded by robot control when a close succeeds.
struct Hold {
  std::string workpiece;
  models::Approach approach = models::Approach::kDown;
  double tcp_above_bottom = 0;  // tool centre point height above the part's bottom when it closed (m)
  // The part's centre in the tool frame when it closed (from the model's estimate then): where the part is while held,
  // when nothing measures it (Perception::kVision, kCad).
  Eigen::Isometry3d in_hand = Eigen::Isometry3d::Identity();
};

struct RobotState {
  std::string name;
  const CellRobot* fixed = nullptr;  // its base and home, in the model's CellGeometry
  // Current arm joints, from the robot's driver (robot control writes each position read-back); the home joints
  // until the first one.
  std::vector<double> joints;
  std::optional<Hold> hold;  // what it holds, if anything
  // The hold it had on a part that it lost while carrying it (grip_lost), until it grips again or the part is
  // declared lost: a re-grasp of that part, standing upright, held from above before and at a height within it, takes
  // it at the same height above its bottom, the hold the rest of the program expects (a hand-over's other arm closes
  // below it).
  std::optional<Hold> dropped_hold;
  // The tool centre point (world), from the last position read-back (joints, or the tool pose a Cartesian controller
  // reports); nullopt before the first.
  std::optional<Eigen::Isometry3d> tcp;
  // The tool pose (world) where it last opened its hand on a part; cleared when it closes again. Departing from a
  // put-down lifts the open hand straight up from there (see above(X) at the top).
  std::optional<Eigen::Isometry3d> released_tcp;
  // The grip sensor (sensors.hpp): what is between the finger pads, nullopt when nothing senses it (no grip sensor
  // wired, or it cannot tell now). Written from the robot's grip sensor every period.
  std::optional<GripReading> grip;
  // The wrist force sensor (N, world frame), from the robot's force sensor every period; nullopt when there is none.
  std::optional<Eigen::Vector3d> wrist_force;

  const Eigen::Isometry3d& base() const { return fixed->base; }  // base_link in the world
  const std::vector<double>& home() const { return fixed->home; }
  const std::vector<double>& park() const { return fixed->park; }
};

// An object the safety sensor sees that is not in the cell model (runtime::Obstacle), as of the last period.
struct ObstacleState {
  std::string name;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
};

struct EnvironmentModel {
  std::shared_ptr<const CellGeometry> geometry;  // fixed, shared by every copy of this model
  SimDuration time{0};                           // simulation time of the last update from truth
  std::vector<RobotState> robots;
  std::vector<WorkpieceState> workpieces;
  std::vector<ObstacleState> obstacles;  // from the safety sensor every period (every perception)

  // Lookups by cell name; nullptr when there is none.
  const RobotState* find_robot(std::string_view name) const;
  RobotState* find_robot(std::string_view name);
  const WorkpieceState* find_workpiece(std::string_view name) const;
  WorkpieceState* find_workpiece(std::string_view name);
  const CellLocation* find_location(std::string_view name) const { return geometry->find_location(name); }
};

using SharedEnvironment = Guarded<EnvironmentModel>;

// The model pre-coded from the cell description: every robot at home holding nothing, every workpiece at its initial
// pose, present, held by nobody.
EnvironmentModel make_environment_model(const models::CellDescription& cell);

// Where the model's knowledge of the workpieces comes from.
//  kTruth   the simulation's ground truth, every control period: a perfect sensor (the default; for checking task
//           logic without perception in the way).
//  kVision  the camera: the image-processing thread corrects the model (correct()); a part is absent until the camera
//           has seen it (the runtime starts every part absent), present from then on; while held it moves with the
//           hand.
//  kCad     the cell description only (the paper's off-line CAD data; "vision off"): the cell's presence sensors (a
//           light barrier at each conveyor entry and location, the belts' encoders) tell whether a part is there and
//           whether it moves, never where exactly: a part at rest within kCadSensorRadius of a location is taken to
//           stand at that location's nominal pose. While held it moves with the hand.
// The robots' joints never come from the sensors: robot control reads them from the drivers. The grip sensors do.
enum class Perception { kTruth, kVision, kCad };

// "truth", "vision", "cad".
const char* to_string(Perception perception);

inline constexpr double kCadSensorRadius = 0.1;  // m
inline constexpr double kCadRestSpeed = 0.005;   // m/s: slower, a part is at rest for the presence sensors

// What the simulation thread read from the wired sensors (sensors.hpp) in one period, at `time`.
struct SensorReadings {
  struct Robot {
    std::string name;  // cell robot
    std::optional<GripReading> grip;  // nullopt: no grip sensor, or it cannot tell now
    std::optional<Eigen::Vector3d> wrist_force;
  };
  SimDuration time{0};
  std::optional<std::vector<PartReading>> parts;  // nullopt: no part sensor
  std::vector<Obstacle> obstacles;                // the safety sensor's (none without one)
  std::vector<Robot> robots;                      // every cell robot, in the cell's order
};

// Reads every sensor of `sensors` once, in the port's order (sensors.hpp): parts, safety, then each of `robots`'
// grip and force. A robot with no sensor of a kind reads nullopt.
SensorReadings read_sensors(Sensors& sensors, const std::vector<std::string>& robots, SimDuration time);

// Writes the sensor readings into the model, as `perception` allows (see Perception): time, grip sensors, wrist forces
// and the safety sensor's obstacles always; with a part sensor, workpiece poses, velocities and presence for kTruth (a
// part held by a robot keeps its held_by; confidence becomes 1 and the stamp the readings' time); presence, velocity
// and the nominal pose of the location a resting part stands at for kCad; nothing of the workpieces for kVision.
// Entries naming nothing in the model are ignored (a sensor may know more bodies than the model).
void apply_readings(EnvironmentModel& model, const SensorReadings& readings, Perception perception = Perception::kTruth);

// Vision's entry point (issue 5): the workpiece was seen at `pose` (its centre, world) with `confidence` in [0, 1],
// in an image taken `age` before model.time. Updates the pose and confidence, stamps it model.time - age, and marks
// it present. A part held by a robot is left alone (the hand hides it; the hold is authoritative). Returns false,
// changing nothing, when there is no such workpiece, it is held, the confidence is outside [0, 1] or not finite, or
// the age is negative.
// `velocity` is the part's measured velocity, nullopt when it could not be measured (seen once): then
// motion_known becomes false.
bool correct(EnvironmentModel& model, std::string_view workpiece, const Eigen::Isometry3d& pose, double confidence,
             SimDuration age, const std::optional<Eigen::Vector3d>& velocity = Eigen::Vector3d::Zero());

// Tunables of target resolution.
struct TargetOptions {
  double handover_clearance = 0.08;   // m: hand_approach backs off this far from the hand-over grasp
  double part_at_rest_speed = 0.005;  // m/s: a part moving faster is not ready to be grasped
  // m: a part this close to a location's point rests "at" it. Generous: a part a conveyor brings to its stop bar
  // stands within a few centimetres of the pick location, and must be taken with the location's heights and finger
  // direction (clear of the bar) wherever vision finds it there.
  double at_location_tolerance = 0.1;
};

// The result of resolving a move target for one robot.
struct MotionTarget {
  enum class Resolution {
    kOk,    // go to one of `poses` (or to `joints`)
    kWait,  // not ready yet (a part still moving or absent): try again later; `reason` says why
    kFail,  // cannot be resolved (names nothing usable): the command fails with `reason`
  };
  Resolution resolution = Resolution::kFail;
  std::vector<double> joints;            // set for home: go to these joints
  std::vector<Eigen::Isometry3d> poses;  // tool centre point poses in the world
  // Preference of each pose (same size as poses; lower is better): robot control goes to a reachable pose of the
  // best rank, and among those to the one closest to the current joints.
  std::vector<int> rank;
  std::string description;  // e.g. "above A: tool at (0.550, -0.550, 0.630)"
  std::string reason;       // kWait/kFail: why
};

// Resolves `target` for robot `robot` (cell name). target.object must already be bound to a cell name: a workpiece
// or location for above/at, a cell robot for handover/hand_approach/hand_grasp. See the rules at the top.
MotionTarget resolve_target(const EnvironmentModel& model, const std::string& robot, const task::Target& target,
                            const TargetOptions& options = {});

}  // namespace cellwright::runtime
