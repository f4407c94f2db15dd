// World: the simulated cell as the simulation thread sees it. It owns the Scene (mjModel/mjData) and is the only
// thing that touches mjData; the simulation drivers of the robots (sim_driver.hpp) are advanced by it.
//
// WHAT IT DOES
//  - advance(dt) steps the physics a whole number of timesteps. Before every step each SimDriver moves its servo
//    targets along its trajectory; after every step the belts are wrapped (Scene::wrap_belts), contacts are checked
//    for collisions and MuJoCo's warning counters are read. Time is counted in whole steps, so now() is exact.
//    MuJoCo's sensors (touch, wrist force/torque) are computed on the last step of each call, and on the steps after
//    which a driver reads its fingers' touch: mjData's sensor values are always those of the last step when anyone
//    reads them (SimDriver::step says when it will).
//  - truth() reads the ground truth the environment model needs: workpiece poses, velocities, what holds them and
//    what they rest on; robot joints, tool pose, finger opening, touch and wrist force/torque.
//  - new_collisions() reports unintended contacts once, when they start (see Collision).
//  - drain_warnings() reports MuJoCo's warnings (contact buffer full, bad accelerations, ...) as text.
//  - The workpiece feed: parts that arrive later wait in a parking row on the floor outside the cell and out of its
//    downward cameras' view (chosen with WorldOptions::parked); feed() puts the next one on a conveyor's entry
//    point, at rest, as a scenario event. It is
//    the only way a part moves without contacts: robots carry parts by friction only.
//  - Part-present sensors: for each conveyor with a stop eye (models::ConveyorSpec::stop_eye, the cell's `sensor:`),
//    the eye, and signal n of signals() when it is wired to one (`sensor: {signal: n}`), are set after every step (and
//    at construction, and by feed(), park() and place()): on while a
//    workpiece that is not parked rests against the stop bar (its front face, along the belt, within 5 mm of `leave`;
//    its centre over the belt; its bottom within 5 mm of the belt's top) and moves slower than the runtime's
//    part-at-rest speed (runtime::TargetOptions::part_at_rest_speed), its velocity averaged over about 0.1 s (a
//    part pressed against the stop chatters), else off. Like a photo-eye at the stop, it says
//    that a part is there, not which one. The sensor owns its signal: anything else setting it is overwritten.
//
// RESTING PARTS (twin/src/sim/resting_parts.hpp; docs/simulation.md, "Resting parts"): a part that has been still
// for 0.2 s on static geometry or a stopped belt (or on parts that rest with it), with no moving geom near, sleeps:
// it leaves the physics (no contacts; the World steps its own copy of the scene's model, in which the part's geom
// collides with nothing) and stays exactly where it lies, at rest, keeping the support it rested on for truth(). It
// wakes, at rest where it slept, when a robot's or an awake part's geom comes within 4 cm (bounding spheres), the belt
// under it runs, an obstacle is placed, or the World moves it (feed, park, place, shift). Parked parts sleep.
// asleep() says which.
//
// DEVICES (docs/simulation.md, "Devices"): the conveyors, their photo-eyes and the machines, as a real cell's I/O unit
// sees them (TwinIo, twin_io.hpp, serves them as a DigitalIo). Their state is updated after every step (and at
// construction, feed(), park() and place()) and read by devices().
//  - Photo-eyes. The stop eye of a conveyor with a `sensor` (models::ConveyorSpec::stop_eye) is the part-present
//    sensor above (it drives its signal when it has one). The drop eye (`drop_sensor`) is on while a part that is not
//    parked lies across the point `enter` (the part's extent along the belt covers it; its centre over the belt; its
//    bottom within 5 mm of the belt's top), moving or not, like a beam across the belt.
//  - Belts. A belt runs at its speed while its run command is on (set_belt_run(); on at the start, so that a cell
//    without device commands runs as it always did) and, on an accumulating conveyor (ConveyorSpec::accumulate), no
//    part blocks the stop eye's beam: it stops (drive 0) when a part on the belt reaches the stop bar (its front face
//    within 0.5 mm of it), so that the queue behind rests instead of sliding on a moving belt, and runs again once no
//    part on the belt is within 5 mm of the bar (the part was taken; the hysteresis keeps a part that eases back from
//    the bar once the belt no longer presses it from restarting the belt). The eye's output (the signal, the
//    discrete input) is the settled part of the rule above. A stopped belt carries nothing. The belt's drive is set
//    after every step from the parts' poses of that step.
//  - Machines: the cycle idle -> loaded -> busy -> done -> (unloaded) idle. `loaded`: a part that is not parked rests
//    on the fixture (its bottom centre over the fixture plate's top, within 5 mm of it, averaged speed under the
//    part-at-rest speed); a part that no longer lies on it (the same test without the speed) has left. A rising edge
//    of the start command (set_machine_start(), from false to true; edges between two steps are not lost) while
//    `loaded` starts the cycle: `busy` for process_time, counted in whole steps of simulated time; then the part is
//    processed (processed(): for good; its colour becomes the machine's processed_rgba in every rendering, through
//    mjData::userdata, scene.hpp) and the machine is `done` until that part leaves the fixture, which is the unload:
//    the machine goes back to `idle` (MachineDevice::unloads counts them). A start while the machine is not `loaded`
//    (empty, busy or done) is IGNORED: nothing happens, the edge is consumed. A part taken off while `busy` aborts
//    the cycle unprocessed (back to `idle`).
//
// THREADS. One thread (the simulation thread) calls every other member, const or not (now(), truth(), ...);
// scene() and the ids it holds never change and may be read from any thread. The SimDrivers it
// creates are used by their owners (robot-control threads) through the RobotDriver interface, which is thread-safe;
// signals(), set_belt_run(), set_machine_start(), belt_run(), machine_start() and devices() may be used from any
// thread (a device-control thread serving the I/O image): commands take effect at the next step, devices() gives
// the state as of the last step. World is neither copyable nor movable (drivers refer to it).
//
// DETERMINISM. Nothing here reads the wall clock, uses randomness or depends on thread timing: drivers are stepped in
// robot order, contacts and collisions are processed in MuJoCo's order, MuJoCo runs single-threaded. Two Worlds made
// from the same cell and driven by the same commands at the same simulation times give bit-identical states.
#pragma once

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
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

class RestingParts;
class ContactPairs;

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
  // Every such robot, in robot order (two for a part carried together, docs/runtime.md "Coordinated blocks"); held_by
  // is the first of them.
  std::vector<std::size_t> holders;
  bool held_by_robot(std::size_t robot) const {
    return std::find(holders.begin(), holders.end(), robot) != holders.end();
  }
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

// The devices as the I/O image sees them (see the top), for the rig to log and TwinIo to serve.
struct ConveyorDevice {
  std::string name;
  bool run = true;         // the run command (the coil)
  bool running = true;     // the belt is driven at its speed now (run, and not held by accumulation)
  bool stop_eye = false;   // the photo-eye at the stop bar (false when the conveyor has none)
  bool drop_eye = false;   // the photo-eye at `enter` (false when the conveyor has none)
  bool operator==(const ConveyorDevice&) const = default;
};

enum class MachineState : std::uint8_t {
  idle,    // no part on the fixture (or one the machine has processed was taken: the unload)
  loaded,  // a part rests on the fixture
  busy,    // processing the part, for the machine's process_time
  done,    // the processed part is still on the fixture
};

struct MachineDevice {
  std::string name;
  bool start = false;                // the start command (the coil)
  MachineState state = MachineState::idle;
  std::string part;                  // the part on the fixture (loaded, busy, done), else ""
  std::chrono::nanoseconds busy_left{0};  // busy: the process time still to run
  int cycles = 0;                    // cycles done (parts processed)
  int unloads = 0;                   // processed parts taken off the fixture
  bool busy() const { return state == MachineState::busy; }
  bool done() const { return state == MachineState::done; }
  bool operator==(const MachineDevice&) const = default;
};

struct DeviceStates {
  std::chrono::nanoseconds time{0};      // the simulation time of the step they are from
  std::vector<ConveyorDevice> conveyors;  // in the cell's order
  std::vector<MachineDevice> machines;    // in the cell's order
  std::vector<std::string> processed;     // the workpieces processed so far, in the order they were done
  bool operator==(const DeviceStates&) const = default;
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
  // Whether a workpiece is asleep: at rest on something still and out of the physics until something could disturb
  // it (see RESTING PARTS at the top). InternalError if there is no such workpiece.
  bool asleep(std::string_view workpiece) const;

  // ---- Devices (see the top). Any thread. ----
  // The run command of conveyor `conveyor` (index in the cell's conveyors; InternalError outside): on, the belt runs
  // (unless it accumulates against a blocked stop eye); off, it stops. From the next step.
  void set_belt_run(std::size_t conveyor, bool run);
  bool belt_run(std::size_t conveyor) const;
  // The start command of machine `machine` (index in the cell's machines; InternalError outside). A change from off
  // to on is a start, acted on at the next step (and ignored unless the machine is loaded).
  void set_machine_start(std::size_t machine, bool on);
  bool machine_start(std::size_t machine) const;
  // The devices' state as of the last step (or construction, feed(), park(), place()).
  DeviceStates devices() const;
  // Whether a workpiece has been processed by a machine. InternalError if there is no such workpiece.
  bool processed(std::string_view workpiece) const;

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
  // After a step (stepped) or a part moved without one: the photo-eyes (and the stop eyes' signals), the machines,
  // the belts' drive; publishes the devices if they changed.
  void update_devices(bool stepped);
  void update_sensors();  // the photo-eyes, from the workpieces' poses and speeds; the stop eyes' signals
  void apply_commands();  // before a step: takes the device commands given since the last one
  void drive_belts();     // sets each belt's drive from its run command and, accumulating, its stop eye
  void update_machines(bool stepped);
  bool on_fixture(std::size_t machine, std::size_t workpiece) const;  // the part lies on the fixture plate
  void paint_processed(std::size_t workpiece, const Eigen::Vector4d& rgba);
  std::size_t workpiece_index(std::string_view name) const;  // npos when unknown

  Scene scene_;
  // The model the World steps: a copy of the scene's, in which RestingParts switches sleeping parts' contacts off
  // (the scene's model, read by renderers and the collision sweep, never changes).
  std::unique_ptr<mjModel, void (*)(mjModel*)> physics_;
  std::unique_ptr<ContactPairs> pairs_;  // declared before resting_: both take the physics model's masks
  std::unique_ptr<RestingParts> resting_;
  bool sensors_fresh_ = true;  // mjData's sensor values are from the last step (see step())
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
  std::size_t stop_eyes_ = 0;                     // conveyors with a stop eye
  std::vector<Eigen::Vector3d> sensed_velocity_;  // by workpiece: its averaged velocity (update_sensors())
  std::vector<Eigen::Isometry3d> world_to_conveyor_;  // by conveyor
  std::vector<Eigen::Isometry3d> world_to_fixture_;   // by machine: the frame of the fixture plate's top centre
  std::vector<std::int64_t> busy_steps_;              // by machine: busy steps still to run
  std::vector<int> taken_edges_;                      // by machine: starts taken by apply_commands() for this step
  std::vector<bool> held_;                            // by conveyor: accumulation holds the belt (see the top)
  std::vector<bool> processed_;                       // by workpiece
  DeviceStates state_;                                // the simulation thread's, updated every step
  // The commands and the published state, shared with any thread under device_mutex_.
  mutable std::mutex device_mutex_;
  std::vector<bool> belt_run_;        // by conveyor, the run command
  std::vector<bool> machine_start_;   // by machine, the start command
  std::vector<int> start_edges_;      // by machine, rising edges of start not yet taken by a step
  DeviceStates published_;            // devices() returns this (its time: published_time_)
  std::atomic<bool> commands_changed_{true};
  std::atomic<std::int64_t> published_time_{0};  // ns: the step the published state is from
};

// Names for logs: "gripper", "conveyor", ...; "ok", "occupied", ...
std::string_view to_string(SupportKind kind);
std::string_view to_string(FeedStatus status);
std::string_view to_string(MachineState state);  // "idle", "loaded", "busy", "done"

}  // namespace cellwright::twin::sim
