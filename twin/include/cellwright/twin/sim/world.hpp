// World: the simulated cell as the simulation thread sees it. It owns the Scene (mjModel/mjData) and is the only
// thing that touches mjData; the simulation drivers of the robots (sim_driver.hpp) are advanced by it.
//
// WHAT IT DOES
//  - advance(dt) steps the physics a whole number of timesteps. Before every step each SimDriver moves its servo
//    targets along its trajectory; after every step the belts are wrapped (Scene::wrap_belts), contacts are checked
//    for collisions and MuJoCo's warning counters are read. Time is counted in whole steps, so now() is exact.
//  - truth() reads the ground truth the environment model needs: workpiece poses, velocities, what holds them and
//    what they rest on; robot joints, tool pose, finger opening, touch and wrist force/torque.
//  - new_collisions() reports unintended contacts once, when they start (see Collision).
//  - drain_warnings() reports MuJoCo's warnings (contact buffer full, bad accelerations, ...) as text.
//  - The workpiece feed: parts that arrive later wait in a parking row on the floor outside the cell and out of its
//    downward cameras' view (chosen with WorldOptions::parked); feed() puts the next one on a conveyor's entry
//    point, at rest, as a scenario event. It is
//    the only way a part moves without contacts: robots carry parts by friction only.
//  - Part-present sensors: for each conveyor with a sensor (models::ConveyorSpec::sensor, the cell's `sensor:
//    {signal: n}`), signal n of signals() is set after every step (and at construction, and by park()): on while a
//    workpiece that is not parked rests against the stop bar (its front face, along the belt, within 5 mm of `leave`;
//    its centre over the belt; its bottom within 5 mm of the belt's top) and moves slower than the runtime's
//    part-at-rest speed (runtime::TargetOptions::part_at_rest_speed), its velocity averaged over about 0.1 s (a
//    part pressed against the stop chatters), else off. Like a photo-eye at the stop, it says
//    that a part is there, not which one. The sensor owns its signal: anything else setting it is overwritten.
//
// THREADS. One thread (the simulation thread) calls every other member, const or not (now(), truth(), ...);
// scene() and the ids it holds never change and may be read from any thread. The SimDrivers it
// creates are used by their owners (robot-control threads) through the RobotDriver interface, which is thread-safe;
// signals() may be used from any thread. World is neither copyable nor movable (drivers refer to it).
//
// DETERMINISM. Nothing here reads the wall clock, uses randomness or depends on thread timing: drivers are stepped in
// robot order, contacts and collisions are processed in MuJoCo's order, MuJoCo runs single-threaded. Two Worlds made
// from the same cell and driven by the same commands at the same simulation times give bit-identical states.
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/signals.hpp"
#include "cellwright/twin/sim/sim_driver.hpp"

namespace cellwright::twin::sim {

struct WorldOptions {
  SourceLocation where;              // the scenario (or cell) file, for errors about the options
  std::vector<std::string> parked;   // workpieces that start in the parking row, waiting for feed()
  std::size_t signals = 16;          // digital signals of the shared SignalTable
  double location_tolerance = 0.02;  // m: horizontal distance of a part's bottom centre from a location's point ...
  double location_height_tolerance = 0.01;  // ... and vertical distance, for the part to be "at" the location
};

// What a workpiece rests on: the body supporting it from below (the contact with the largest normal force among
// those pushing it up; when no contact pushes it up, e.g. a part wedged against a conveyor's stop by the part behind
// it, chattering a fraction of a millimetre off the belt, the body just under its centre, within 2 mm), or the
// gripper holding it.
enum class SupportKind : std::uint8_t {
  none,       // falling, or only touched from the side
  gripper,    // held: both finger pads of a robot touch it (`robot` says which)
  conveyor,   // on a conveyor's belt, frame or stop (`name`: the conveyor)
  machine,    // on a machine or its fixture (`name`: the machine)
  floor,      // on the floor
  workpiece,  // on another workpiece (`name`: that workpiece)
  robot,      // on a robot's link without being held (`name`: the robot)
  other,      // on other static geometry, e.g. a pedestal (`name`: the MuJoCo geom, else its body)
  parked,     // waiting in the parking row for feed()
};

struct WorkpieceTruth {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();      // the part's centre, world frame
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();   // m/s, world frame
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // rad/s, world frame
  std::optional<std::size_t> held_by;  // index of the robot (scene().robots()) whose two finger pads both touch it
  SupportKind support = SupportKind::none;
  std::string support_name;  // see SupportKind
  std::string location;      // the cell location whose point the part's bottom centre is at (WorldOptions), or ""
  bool upright = false;      // the part's z axis within 10 degrees of the world's z
  bool parked = false;
};

struct RobotTruth {
  std::string name;
  std::vector<double> joints;                              // rad, base to tip
  std::vector<double> joint_velocities;                    // rad/s
  Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();   // tool centre point, world frame
  double finger_opening = 0;                               // m between the finger pads (sum of the finger joints)
  std::array<double, 2> finger_touch{0, 0};                // N on the {left, right} pad's touch sensor
  std::array<bool, 2> finger_contact{false, false};        // touch sensor reads a force
  Eigen::Vector3d wrist_force = Eigen::Vector3d::Zero();   // N, flange frame (MuJoCo's force sensor)
  Eigen::Vector3d wrist_torque = Eigen::Vector3d::Zero();  // N m, flange frame
};

struct ConveyorTruth {
  std::string name;
  double belt_speed = 0;  // m/s, measured
};

struct WorldTruth {
  std::chrono::nanoseconds time{0};
  std::vector<RobotTruth> robots;          // in scene().robots() order
  std::vector<WorkpieceTruth> workpieces;  // in scene().workpieces() order
  std::vector<ConveyorTruth> conveyors;    // in scene().conveyors() order
};

// An unintended contact. Counted: a robot's body touching another robot's body; a robot's body touching the cell's
// static geometry (floor, pedestals, conveyors including belts and stops, machines); an arm link (a robot body that
// is not part of its gripper, i.e. not the flange or below it) touching a workpiece. Not counted: a robot's own
// bodies (not simulated), the gripper touching workpieces (grasping), workpieces touching anything else (resting,
// being put down). A pair of bodies is reported once when it starts touching; it is reported again only after it
// has been apart for more than 100 ms (two bodies pressed together touch and part every few steps: one collision).
struct Collision {
  std::chrono::nanoseconds time{0};
  std::string body1, body2;    // MuJoCo body names ("puma/link3", "melfa/finger_left", "conveyor/input", "world"), in
                               // body id order
  std::string geom1, geom2;    // the geoms of the deepest contact ("floor", "puma/pedestal", "" when unnamed)
  std::string robot1, robot2;  // the robots involved ("" for the cell or a workpiece)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world, of the deepest contact
  double depth = 0;                                    // m of penetration of the deepest contact (>= 0)
};

// Why feed() refused.
enum class FeedStatus : std::uint8_t {
  ok,
  unknown_workpiece,  // no workpiece of that name
  unknown_conveyor,   // no conveyor of that name
  not_parked,         // the workpiece is in the cell already
  occupied,           // another part is still at the conveyor's entry point
};

struct FeedResult {
  FeedStatus status = FeedStatus::ok;
  std::string message;  // when refused: why, with the names and distances
  bool ok() const { return status == FeedStatus::ok; }
};

class World {
 public:
  // Takes the scene (reset to its initial state first) and parks options.parked. Throws InputError naming
  // options.where if a parked name is not a workpiece of the cell, or the cell's timestep is not a whole number of
  // nanoseconds.
  World(Scene scene, WorldOptions options = {});
  World(const World&) = delete;
  World& operator=(const World&) = delete;
  ~World();

  // The cell model and its ids. Any thread.
  const Scene& scene() const { return scene_; }
  // MuJoCo's data, for rendering a snapshot on the simulation thread. Do not step it.
  const mjData* data() const { return scene_.data(); }
  // The same, for a Renderer on the simulation thread (mjv_updateScene takes it mutable and uses its scratch stack;
  // it changes no state a step reads). Do not step it.
  mjData* render_data() { return scene_.data(); }
  const WorldOptions& options() const { return options_; }
  // The digital signals shared by the simulated controllers. Any thread.
  SignalTable& signals() { return signals_; }

  // Creates the simulation driver of robot `robot` (before the threads start). Throws InputError naming
  // options.where when there is no such robot or it has a driver already, and as SimDriver's constructor. The driver
  // lives as long as the World; robots without one hold their servo targets.
  SimDriver& add_sim_driver(std::string_view robot, SimDriverOptions options = {});
  // The driver of a robot, or nullptr.
  SimDriver* driver(std::string_view robot);

  // Steps the simulation by dt (a whole, non-negative number of timesteps; InternalError otherwise): for each step,
  // steps the drivers, then MuJoCo, then wraps the belts, checks collisions and warning counters.
  void advance(std::chrono::nanoseconds dt);
  // Steps the simulation by n timesteps.
  void step(std::int64_t n = 1);

  // Simulation time: exact, counted in steps.
  std::chrono::nanoseconds now() const { return timestep_ * steps_; }
  double time() const { return std::chrono::duration<double>(now()).count(); }
  std::chrono::nanoseconds timestep() const { return timestep_; }
  std::int64_t steps() const { return steps_; }

  // The ground truth now.
  WorldTruth truth() const;

  // Collisions that started since the last call, in the order they started.
  std::vector<Collision> new_collisions();
  // Collision pairs in contact now (body names), for diagnostics.
  std::vector<std::pair<std::string, std::string>> touching_pairs() const;

  // Whether MuJoCo raised warnings not drained yet.
  bool warnings() const { return !warnings_.empty(); }
  // MuJoCo's warnings since the last call, one line each: "t=1.234 s: MuJoCo warning: contact buffer full (raised
  // 3 times; last info 1000)". When MuJoCo reset the simulation after bad accelerations, or its contact or
  // constraint buffer was full (contacts were dropped: the scene's njmax and nconmax are too small for what the cell
  // does), the drivers are put in fault with a message that says which; their commands fail with `hardware`.
  std::vector<std::string> drain_warnings();

  // Puts workpiece `workpiece`, waiting in the parking row, on conveyor `conveyor` at its entry point (`enter`), at
  // rest, upright, turned like the conveyor. Refuses (nothing moves) as FeedStatus says.
  // `offset`, in the conveyor's frame (x along the belt), moves and turns the part from the entry point (a scenario's
  // perturbation); the part must still stand on the belt.
  FeedResult feed(std::string_view workpiece, std::string_view conveyor,
                  const Eigen::Isometry3d& offset = Eigen::Isometry3d::Identity());
  // Moves a workpiece to its place in the parking row, at rest (e.g. a part that has left the output conveyor).
  // Refuses with unknown_workpiece only.
  FeedResult park(std::string_view workpiece);
  // Whether a workpiece waits in the parking row. InternalError if there is no such workpiece.
  bool parked(std::string_view workpiece) const;

  // ---- Fault injection (fault_injector.hpp): the physics made to go wrong on purpose ----
  // Puts a workpiece (parked or not) at `pose` (its centre, world), at rest. Refuses with unknown_workpiece only.
  FeedResult place(std::string_view workpiece, const Eigen::Isometry3d& pose);
  // Moves a workpiece by `delta` (world), keeping its velocity: a part sliding in the fingers. InternalError if there
  // is no such workpiece.
  void shift(std::string_view workpiece, const Eigen::Vector3d& delta);
  // How far the workpiece's bottom (its centre less half its height) is above whatever is straight below its centre
  // (infinity when nothing is). InternalError if there is no such workpiece.
  double clearance_below(std::string_view workpiece) const;
  // Puts obstacle `index` (scene().obstacles()) with its centre at `centre` (world, axis-aligned), or back under the
  // floor with nullopt. Its contacts with robots are collisions (new_collisions).
  void place_obstacle(std::size_t index, const std::optional<Eigen::Vector3d>& centre);

 private:
  struct BodyInfo {
    int robot = -1;        // index of the robot owning the body, -1 if none
    bool gripper = false;  // robot body at or below the flange
    bool finger = false;   // a finger link
    int finger_side = -1;  // 0 left, 1 right
    int workpiece = -1;    // index of the workpiece, -1 if none
    bool fixed = false;    // welded to the world (static geometry)
  };

  void classify_bodies();
  void place_at_rest(std::size_t workpiece, const Eigen::Isometry3d& pose);
  Eigen::Isometry3d parking_pose(std::size_t workpiece) const;
  void check_contacts();
  void check_warnings();
  void update_sensors();  // sets each part-present sensor's signal from the workpieces' poses and speeds
  std::size_t workpiece_index(std::string_view name) const;  // npos when unknown

  Scene scene_;
  WorldOptions options_;
  SignalTable signals_;
  std::chrono::nanoseconds timestep_{0};
  std::int64_t steps_ = 0;
  std::vector<std::unique_ptr<SimDriver>> drivers_;  // by robot index; nullptr when the robot has none
  std::vector<BodyInfo> bodies_;                     // by MuJoCo body id
  std::vector<bool> parked_;                         // by workpiece index
  Eigen::Vector3d parking_origin_ = Eigen::Vector3d::Zero();
  std::set<std::pair<int, int>> touching_;                  // body pairs in contact at the last step
  std::map<std::pair<int, int>, std::int64_t> last_touch_;  // step at which a pair last touched (recent ones)
  std::vector<Collision> collisions_;                       // not yet reported
  std::array<int, mjNWARNING> warning_counts_{};            // MuJoCo's counters at the last check
  std::vector<std::string> warnings_;                       // not yet drained
  struct Sensor {
    const models::ConveyorSpec* conveyor = nullptr;  // in scene_.cell(), which the World owns
    Eigen::Isometry3d world_to_conveyor = Eigen::Isometry3d::Identity();
  };
  std::vector<Sensor> sensors_;                   // the conveyors with a part-present sensor, in the cell's order
  std::vector<Eigen::Vector3d> sensed_velocity_;  // by workpiece: its averaged velocity (update_sensors())
};

// Names for logs: "gripper", "conveyor", ...; "ok", "occupied", ...
std::string_view to_string(SupportKind kind);
std::string_view to_string(FeedStatus status);

}  // namespace cellwright::twin::sim
