// The cell description: what is in the workcell and where (paper section 2: two arms with grippers, an input and
// an output conveyor, a process machine, workpieces, an overhead camera). It is read from a YAML file
// (docs/cell-description.md documents every field), checked completely, and then never changes: the scene builder
// (scene.hpp), the renderer (render.hpp) and robot control all read the same immutable CellDescription.
//
// Units: metres, kilograms, seconds. Angles are degrees in the YAML file and radians in these structures.
// World frame: z up, the floor is the plane z = 0.
//
// Thread safety: the loaders are reentrant (no shared state); a CellDescription may be read from any thread.
#pragma once

#include <Eigen/Geometry>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::models {

// A rigid placement. Rotation is roll about x, then pitch about y, then yaw about z, all about the fixed parent
// axes (R = Rz(yaw) * Ry(pitch) * Rx(roll)), the convention URDF uses.
struct Pose {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();  // radians

  Eigen::Isometry3d transform() const;
  Eigen::Matrix3d rotation() const;
};

// What a real cell cannot exceed (docs/cell-description.md, "Bounds"): a value outside is refused as a typo or a unit
// mistake (millimetres for metres, radians for degrees, grams for kilograms) before it reaches the physics.
namespace bounds {
inline constexpr double kPosition = 100;   // m: every coordinate of a pose or point, within ±100 m of the origin
inline constexpr double kAngle = 360;      // degrees: every angle of a pose and every yaw, within ±360
inline constexpr double kMinSize = 0.001;  // m: the smallest extent of any body (1 mm)
inline constexpr double kMaxSize = 100;    // m: the largest extent of a conveyor or a machine
inline constexpr double kMaxPart = 5;      // m: the largest extent of a workpiece
inline constexpr double kMinMass = 0.001;  // kg: the lightest workpiece (1 g)
inline constexpr double kMaxMass = 1000;   // kg: the heaviest workpiece
inline constexpr double kMaxTime = 86400;  // s: the longest process time (a day)
inline constexpr double kMaxReach = 2;     // m: a grasp or approach height, a hand-over offset
inline constexpr double kOverlap = 0.001;  // m: bodies may touch at the start, not overlap by more than this
}  // namespace bounds

// A robot based above the floor (z > 1 mm) stands on a square pedestal this wide, up to its base (the scene builds it).
inline constexpr double kPedestalSide = 0.3;

enum class DriverKind { kSim, kMovemaster, kVal2 };
enum class Parity { kNone, kEven, kOdd };

// RS-232 line settings of a real robot controller; kept for the drivers, unused by the simulator.
struct SerialSettings {
  std::string port;  // e.g. /dev/ttyS0
  int baud = 9600;
  int data_bits = 8;
  Parity parity = Parity::kNone;
  int stop_bits = 1;
  bool rts_cts = false;
  bool xon_xoff = false;
};

// How a host ends the lines it sends a controller.
enum class LineEnd { kCr, kCrLf, kLf };

// Where a controller's numbers live (docs/real-robots.md, "Commissioning"): the robot's `val2:` / `movemaster:` keys
// world_offset, world_rotation, tool_offset and tool_rotation. The defaults (identity) are the project's assumption
// that the controller's world frame is the URDF's base link and its tool point the project's TCP with the TCP's axes.
struct ControllerFrames {
  // The controller's world frame in the robot's base frame (base_link): metres and a rotation. In the cell file:
  // world_offset in mm, world_rotation in degrees [roll, pitch, yaw] about the fixed axes, R = Rz(yaw)·Ry(pitch)·Rx(roll)
  // (the URDF's convention, as every rpy of the cell description).
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();
  // The controller's tool point (and its axes) in the project's TCP frame: tool_offset (mm), tool_rotation (degrees,
  // as world_rotation). A controller with no tool set reports its flange: tool_offset [0, 0, -l], l the TCP's distance
  // from the flange.
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
};

// The conventions of a VAL II monitor (docs/real-robots.md, "VAL II"), the robot's `val2:` entry; the defaults are the
// page's (assumed) ones, which the val2 driver uses when the entry is left out.
struct Val2Conventions {
  // O, A, T: tool_down (page), plain Z-Y-Z (zyz) or VAL's published one (val: all zero, the hand along -Y, fingers
  // horizontal; val2_protocol.hpp)
  enum class Orientation { kToolDown, kZyz, kVal };
  enum class WhereLayout { kVal2, kAsTwoBlock };  // the page's layout, or Kawasaki AS's two blocks (as)
  enum class Echo { kMaybe, kAlways, kNever };    // whether the monitor echoes the lines it is sent
  Orientation orientation = Orientation::kToolDown;
  LineEnd line_end = LineEnd::kCr;
  std::string prompt = ".";
  WhereLayout where = WhereLayout::kVal2;
  Echo echo = Echo::kMaybe;
  ControllerFrames frames;
};

// The conventions of a Movemaster EX controller (docs/real-robots.md, "Movemaster EX"), the robot's `movemaster:`
// entry; the defaults are the page's, which the movemaster driver uses when the entry is left out.
struct MovemasterConventions {
  enum class Completion { kEr, kPoll };  // a motion's end: the ER answer after it, or WH polling
  LineEnd line_end = LineEnd::kCrLf;
  Completion completion = Completion::kEr;
  char ms_open_letter = 'O';  // the MS letter for an open tool
  // How x,y,z,p,r's angles are read (assumed, docs/real-robots.md "Pose convention"): the pitch at which the hand
  // points straight down (-90, the page's; or 90), and the sense of the roll about the approach axis (+1 right-handed,
  // the page's; -1 the other way).
  double pitch_down_deg = -90;
  int roll_sense = 1;
  ControllerFrames frames;
};

// Which gripper a robot holds (docs/cell-description.md, "Robots as their makers publish them").
enum class GripperKind {
  kOwn,        // the robot's URDF has it: prismatic joints finger_left_joint and finger_right_joint, tool link inside
  kCellwright  // the project's gripper (models/urdf/gripper.urdf, its own model) fixed to the flange link
};

struct RobotSpec {
  std::string name;
  std::filesystem::path urdf;  // absolute; links base_link..tcp, joints joint1..joint6 and two finger joints
  Pose base;                   // base_link in the world
  std::vector<double> home;    // radians, one per arm joint from base_link to tcp, in chain order
  // The robot's park pose (`park:`, degrees in the file), out of the other robots' way: where the task language's
  // `park` sends it. Empty: the cell gives none (a program's `park` for this robot is refused at run time).
  std::vector<double> park;
  // The URDF's own link names: the link placed at `base` (links above it, such as a `world` root fixed to it, are
  // left out), the tool mounting face (the wrist force sensor's frame, where a mounted gripper goes), and the tool
  // centre point, the tip of the robot's kinematic chain. With gripper kCellwright the tool link is the gripper's
  // "tcp".
  std::string base_link = "base_link";
  std::string flange_link = "flange";
  std::string tool_link = "tcp";
  GripperKind gripper = GripperKind::kOwn;
  // Absolute directories holding the packages that package://PACKAGE/... mesh paths name (PACKAGE is a
  // subdirectory of one of them; the first that has it wins).
  std::vector<std::filesystem::path> package_path;
  bool draw_collision = false;  // draw the collision geometry in place of the visual one (meshes: collision)
  double grip_force = 5.0;     // newtons: the most each finger's servo pushes with (so the grip on a part)
  DriverKind driver = DriverKind::kSim;
  std::optional<SerialSettings> serial;  // required for movemaster and val2
  // The controller's conventions, whichever driver the scenario or the command line picks (unused by sim).
  Val2Conventions val2;
  MovemasterConventions movemaster;
  SourceLocation where;
};

// The cell's digital signals, 1..kCellSignals: the wires between the controllers and the sensors' inputs (the
// twin's SignalTable has this many; the Movemaster's bits are assumed to be 1..16).
inline constexpr int kCellSignals = 16;

// An address on the cell's I/O unit (a coil or a discrete input, drivers/digital_io.hpp), 0..65535, and where the
// cell file gives it; address -1: not wired.
struct IoAddress {
  int address = -1;
  SourceLocation where;
  bool wired() const { return address >= 0; }
};

// A belt conveyor. Its frame: origin at the centre of its footprint on the floor, x along the direction of travel.
// The belt's top surface is `height` above the origin and spans x in [-length/2, length/2].
struct ConveyorSpec {
  std::string name;
  Pose pose;
  double length = 0, width = 0, height = 0;
  double speed = 0;   // m/s along +x; the belt runs at this speed from the start of the simulation
  double enter = 0;   // distance from the upstream end where parts are put on the belt
  double leave = 0;   // distance from the upstream end where parts leave it (are picked, or fall off the end)
  bool stop = false;  // a stop bar across the belt at `leave` holds parts there for picking
  // The part-present sensor at the stop (a photo-eye wired to every controller's input `sensor`, 1..16), 0: none. On
  // while a part rests against the stop bar (twin/sim/world.hpp says exactly when).
  int sensor = 0;
  SourceLocation where;
  SourceLocation sensor_where;  // of the `signal` value, for errors about the wiring
  // The robot controllers' output that runs the belt (`run_signal: n`, 1..16), 0: none. A wire of the cell like a
  // sensor's, the other way: the generated robot programs (cell/plan/robot_programs.hpp) run and stop the belt by
  // setting output n, and the emulated cell (cell/sim/emulated_cell.hpp) runs the twin's belt while signal n is on.
  // `twin run` drives the belt through `run_io` instead (device control).
  int run_signal = 0;
  SourceLocation run_signal_where;

  // Devices on the cell's I/O unit (drivers/digital_io.hpp; docs/cell-description.md, "io").
  IoAddress run_io;  // the coil that runs the belt (on: running)
  // An accumulating conveyor stops while a part blocks the photo-eye at its stop bar (and runs again when it is
  // taken), so that a queue of parts rests still instead of sliding against a running belt. Default: true with a stop.
  bool accumulate = false;
  // Side guides (`guides: h`): a rail along each side of the belt, h m above its top (0: none). They keep a queue
  // that a running belt pushes against the stop bar in its lane: pushed from behind, the front parts of a long queue
  // turn and are squeezed out sideways.
  double guides = 0;
  // The photo-eye at the stop bar (`sensor:`): present with a stop; its name (default "<conveyor>_stop", in the
  // cell's one name space) and the discrete input it is wired to.
  bool stop_eye = false;
  std::string stop_eye_name;
  IoAddress stop_eye_io;
  // A photo-eye where parts are put on the belt (`drop_sensor:`, at `enter`): on while a part lies there. Its name
  // (default "<conveyor>_drop") and discrete input.
  bool drop_eye = false;
  std::string drop_eye_name;
  IoAddress drop_eye_io;

  // World position of the point on the belt's top surface at distance s from the upstream end, on the centre line.
  Eigen::Vector3d belt_point(double s) const;
};

// A process machine: a box-shaped body with a fixture plate on top, centred, where a part is put to be processed.
// Its frame: origin at the centre of its footprint on the floor.
struct MachineSpec {
  std::string name;
  Pose pose;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();          // body extents x, y, z
  Eigen::Vector3d fixture_size = Eigen::Vector3d::Zero();  // fixture plate extents x, y, z
  double process_time = 0;                                 // seconds a part spends in the machine
  // The colour a part takes when processed (its cycle done): the change the camera and the video show.
  Eigen::Vector4d processed_rgba{0.55, 0.57, 0.62, 1.0};
  // Its signals on the cell's I/O unit (docs/cell-description.md, "io"). The controller sets `start`
  // (a coil) to start a cycle; the machine answers `busy` (a discrete input) while processing, then `done` until the
  // processed part is taken out.
  IoAddress start_io;
  IoAddress busy_io;
  IoAddress done_io;
  SourceLocation where;

  // Pose of the centre of the fixture plate's top face (the machine's yaw).
  Pose fixture_top() const;
};

// How a gripper approaches a target: from above (tool z axis pointing down) or from the side (tool z axis
// horizontal, pointing from the robot's base towards the target).
enum class Approach { kDown, kSide };

// A named place where a part rests (its bottom centre) and robots must reach it with the gripper pointing down.
struct LocationSpec {
  std::string name;
  Pose pose;                       // world; yaw is the part's (and the fingers') orientation about z
  std::vector<std::string> reach;  // robots that must reach it
  double grasp_height = 0.02;      // tool centre point above the location when grasping
  double approach_height = 0.08;   // extra height of the approach point above the grasp point
  // A stand under it (a scenario's location, docs/scenarios.md): a box from the floor up to the location, this wide
  // along x and y of the location's yaw, centred under it; the scene builds it as static geometry ("stand/<name>").
  // Empty: nothing is built (the location is on something the cell has, or in the air).
  std::optional<Eigen::Vector2d> stand;
  SourceLocation where;
};

struct HandoverGrasp {
  std::string robot;
  Approach approach = Approach::kDown;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // tool centre point relative to the hand-over pose (world axes)
};

// Where one arm hands a part to the other: the part's centre in the world, and how each arm holds it there.
struct HandoverSpec {
  std::string name;
  Pose pose;
  std::vector<HandoverGrasp> grasps;  // one per robot taking part, at least two
  SourceLocation where;
};

enum class Shape { kBox, kCylinder };

struct WorkpieceSpec {
  std::string name;
  Shape shape = Shape::kBox;
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // full extents x, y, z; a cylinder has x = y = its diameter
  double mass = 0;
  Eigen::Vector4d rgba = Eigen::Vector4d::Ones();  // 0..1
  Pose pose;       // initial pose of the part's centre in the world (resolved from `on:` when given)
  std::string on;  // the conveyor or location it was put on, empty if given by pose
  SourceLocation where;
};

// A fixed camera. pose is MuJoCo's camera frame: it looks along its -z axis, image up is its +y axis.
// A real camera (issue 26, docs/vision.md "A real camera") may have two files of its own, named in its entry:
//  - `intrinsics: FILE`, its intrinsics and lens distortion as OpenCV's calibration tools write them (read by vision/:
//    models/ only checks that the file is there); its frames are undistorted into the pinhole of `resolution` and
//    `fovy` before detection;
//  - `calibration: FILE`, its pose in the cell as `twin calibrate` found it (format_camera_calibration below): then
//    `pose` is the calibrated pose, and the entry's own (`pose`, or `position` with `look_at`) is `nominal`.
struct CameraSpec {
  std::string name;
  Pose pose;
  Pose nominal;  // the entry's own pose (the same as `pose` without a calibration)
  int width = 640, height = 480;
  double fovy = 0;  // vertical field of view, radians
  std::filesystem::path intrinsics;   // absolute; empty when not given
  std::filesystem::path calibration;  // absolute; empty when not given
  SourceLocation where;
};

// A camera's calibrated pose as `twin calibrate` writes it: YAML, `camera: NAME`, `pose: {xyz: [...], rpy: [...]}`
// (metres, degrees: the cell description's pose) and `comment` as comment lines at the top.
std::string format_camera_calibration(const std::string& camera, const Eigen::Isometry3d& pose,
                                      const std::string& comment);

// Reads such a file for camera `camera`: its pose. InputError naming the file, line and problem (a missing or
// unknown field, another camera's name, a bad number).
Pose read_camera_calibration(const std::filesystem::path& file, const std::string& camera);

struct LightSpec {
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();  // unit vector
  bool directional = false;
  bool cast_shadow = true;
  Eigen::Vector3d diffuse = Eigen::Vector3d::Constant(0.7);
  SourceLocation where;
};

struct CellDescription {
  std::string name;
  std::filesystem::path source;  // the YAML file (absolute), or the name given to parse_cell
  double timestep = 0.002;       // simulation step, seconds
  std::vector<RobotSpec> robots;
  std::vector<ConveyorSpec> conveyors;
  std::vector<MachineSpec> machines;
  std::optional<HandoverSpec> handover;
  std::vector<WorkpieceSpec> workpieces;
  std::vector<LocationSpec> locations;
  std::vector<CameraSpec> cameras;
  std::vector<LightSpec> lights;

  // Lookups by name; nullptr when there is none.
  const RobotSpec* find_robot(std::string_view name) const;
  const ConveyorSpec* find_conveyor(std::string_view name) const;
  const MachineSpec* find_machine(std::string_view name) const;
  const WorkpieceSpec* find_workpiece(std::string_view name) const;
  const LocationSpec* find_location(std::string_view name) const;
  const CameraSpec* find_camera(std::string_view name) const;
  // Where robots put parts into machine `m`: the location at its fixture's top (`at: M.fixture`), the last one listed
  // when there are several (a scenario's locations come after the cell's, so a scenario may give its own grasp);
  // nullptr when there is none.
  const LocationSpec* fixture_location(const MachineSpec& m) const;
};

// One reachability check: a robot's tool centre point at a target pose, solved with the robot's inverse kinematics.
struct ReachCheck {
  std::string target;  // "location 'input_pick' (grasp)", "location 'input_pick' (approach)", "hand-over 'handover'"
  std::string robot;
  Eigen::Isometry3d tcp_world = Eigen::Isometry3d::Identity();  // the pose asked for
  bool reachable = false;
  std::vector<double> q;  // a joint solution (radians) when reachable
  double distance = 0;    // from the robot's base origin to the target point
  double max_reach = 0;   // of the robot, from its kinematics
  std::string reason;     // why not, when unreachable
  SourceLocation where;   // the location or hand-over in the YAML file
};

// Reads, checks and resolves a cell description file. Relative URDF paths are relative to the file's directory.
// Throws InputError naming the file, line, column and field when: the file is missing or is not YAML; a field is
// missing, unknown, of the wrong type or out of range (negative sizes, colours outside 0..1, ...); a name is used
// twice; a number is outside its bounds (namespace bounds); two bodies overlap at the start (a workpiece inside a
// machine, a machine over a conveyor: message and position name the one listed later and the body it enters, see
// check_overlaps); a reference (a robot in `reach`, a conveyor or location in `on`, an `at` target) names nothing; a URDF is
// missing or unusable; a home configuration does not fit the robot; or a location or the hand-over is out of reach
// of a robot that must reach it (which location, which robot, the distance and the robot's maximum reach).
CellDescription load_cell(const std::filesystem::path& yaml_file);

// As load_cell, from YAML text; `source` names the text in errors and its parent directory resolves relative paths.
CellDescription parse_cell(std::string_view yaml_text, const std::filesystem::path& source);

// The bodies of the cell that overlap at the start by more than bounds::kOverlap: workpieces (boxes, upright
// cylinders), machines (body and fixture plate), conveyors (their frame, up to the belt's top) and robot pedestals,
// each pair once (two parts of one machine are not a pair). Each entry: the later-listed body first, the other, how
// deep they overlap (m), and where the first is in the file. Bodies that touch (a part resting on a belt or fixture) do
// not overlap. Parts on a conveyor's belt are in the conveyor's frame footprint but above it: they do not overlap it.
struct Overlap {
  std::string body;   // "workpiece 'A'"
  std::string other;  // "machine 'mill' (line 40)"
  double depth = 0;
  SourceLocation where;
};
std::vector<Overlap> check_overlaps(const CellDescription& cell);

// Every reachability check the cell asks for: for each location and each robot in its `reach`, the grasp and the
// approach pose (gripper pointing down; the fingers along the location's yaw or turned half a turn); for the
// hand-over, each grasp's pose. Does not throw on unreachable targets: it reports them. Throws InputError when a
// URDF cannot be read.
std::vector<ReachCheck> check_reach(const CellDescription& cell);

// The tool pose (world) a robot based at `robot_base` uses to grasp at `point` with the given approach; `yaw` is
// the rotation of the fingers' closing direction about the world z axis (used for kDown).
Eigen::Isometry3d grasp_pose(const Eigen::Vector3d& point, Approach approach, double yaw,
                             const Eigen::Isometry3d& robot_base);

}  // namespace cellwright::models
