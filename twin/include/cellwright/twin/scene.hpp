// The MuJoCo scene of a cell: one MJCF model of the whole cell built from a CellDescription, compiled to an
// mjModel, with the ids robot control and the renderer need.
//
// What the scene holds (docs/cell-description.md, "The simulated cell", says why each choice was made):
//  - each robot's URDF links (from its base link down, with the gripper mounted on its flange when the cell asks,
//    models/robot_model.hpp) as bodies named "<robot>/<link>" with the URDF's inertials (links without one: mass
//    from their collision geometry) and geoms (meshes converted where MuJoCo cannot read them: mesh_import.hpp), its
//    joints as hinge/slide joints "<robot>/<joint>" with their ranges; a position servo per joint and finger
//    (actuator named like the joint); a wrist force/torque sensor at the flange ("<robot>/wrist_force",
//    "<robot>/wrist_torque"), finger position sensors ("<robot>/finger_left_pos", ...), touch sensors on the finger
//    pads ("<robot>/finger_left_touch", ...), arm joint position sensors ("<robot>/joint1_pos", ...) and a site
//    "<robot>/tcp". A robot based above the floor stands on a pedestal.
//  - each conveyor as a static frame with a belt body "conveyor/<name>/belt" that slides along the conveyor and is
//    driven at the belt speed by a velocity actuator "conveyor/<name>/belt"; parts are carried by the friction of
//    their contact with the moving belt. The belt is longer than the conveyor and is moved back by one period
//    (wrap_belts) whenever it has run that far, which leaves its flat top, and whatever rests on it, unchanged.
//  - each machine as a static body "machine/<name>" with its fixture plate; each workpiece as a free body
//    "workpiece/<name>"; cameras and lights as described; sites "location/<name>" and "handover/<name>" (hidden).
//
// Fixed model and changing state: the compiled mjModel is never changed once built, and Scenes made with share() use
// the one model (compiled once) each with its own mjData. A colour that changes during a run (a part a machine has
// processed, world.hpp) is therefore state: it travels in mjData::userdata (kColourSlot numbers per workpiece, in
// workpieces() order: {geom id + 1, or 0 for no change; r; g; b; a}), which every copy of the state carries
// (mj_copyData, the video's frames), and the Renderer paints it over the model's colour (render.hpp).
//
// Threads: a Scene and its mjData belong to one thread at a time (MuJoCo's mjData is not thread-safe); Scenes that
// share a model may be used by different threads. The functions here install no MuJoCo error or warning handlers:
// that is the application's choice.
#pragma once

#include <mujoco/mujoco.h>

#include <array>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/models/cell.hpp"

namespace cellwright::twin {

// MuJoCo ids of one robot. Arrays of two are {left, right} fingers.
struct RobotIds {
  std::string name;
  std::vector<std::string> joints;  // MuJoCo names of the arm joints, base to tip ("puma/joint1", ...)
  std::vector<int> joint, qpos_adr, dof_adr, actuator, joint_pos_sensor;  // per arm joint, same order
  std::array<int, 2> finger_joint{}, finger_qpos_adr{}, finger_dof_adr{}, finger_actuator{};
  std::array<int, 2> finger_pos_sensor{}, finger_touch_sensor{};
  std::array<double, 2> finger_range{};  // finger joint travel {closed, open} (metres, same for both fingers)
  int wrist_force_sensor = -1, wrist_torque_sensor = -1;  // 3 values each: force (N) and torque (N m) on the flange
  int tcp_site = -1, wrist_site = -1;
  int base_body = -1, flange_body = -1;
  std::vector<double> home;  // radians, per arm joint
};

// Numbers of mjData::userdata per workpiece: a colour that replaces the model's (see the top).
inline constexpr int kColourSlot = 5;

struct ConveyorIds {
  std::string name;
  int body = -1, belt_body = -1, belt_joint = -1, belt_qpos_adr = -1, belt_dof_adr = -1, belt_actuator = -1;
  double speed = 0;  // the belt speed the description asks for, m/s
  double wrap = 0;   // belt travel after which wrap_belts moves it back
};

struct MachineIds {
  std::string name;
  int body = -1;
  int fixture_geom = -1;
};

struct WorkpieceIds {
  std::string name;
  int body = -1, joint = -1, qpos_adr = -1, dof_adr = -1, geom = -1;
};

// An obstacle of the fault injection (docs/faults.md, kind obstacle): a box moved by the simulation (a MuJoCo mocap
// body "obstacle/<i>", from 1), not part of the cell. It collides with robots and parts. It waits 1 m under the floor
// (static and mocap geoms never collide, and no camera sees through the floor) until it is put in the cell.
struct ObstacleIds {
  std::string name;  // "obstacle/1", ...
  int body = -1, mocap = -1, geom = -1;
  double size = 0;  // m, the cube's side
};

// A flat coloured box fixed in the world that the cameras see and nothing touches (a calibration target's board and
// squares, for `twin calibrate`'s tests: vision/calibration.hpp).
struct Plate {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // its centre, world
  Eigen::Vector3d size = Eigen::Vector3d::Zero();          // full extents, m
  Eigen::Vector4d rgba = Eigen::Vector4d::Ones();
};

// What a scene holds besides the cell: the obstacles the scenario's faults may put in the cell, by size (m), and
// plates.
struct SceneOptions {
  std::vector<double> obstacles;
  std::vector<Plate> plates;
};

class Scene {
 public:
  Scene(Scene&&) noexcept;
  Scene& operator=(Scene&&) noexcept;
  ~Scene();

  const mjModel* model() const { return model_.get(); }
  // Another Scene of this compiled model (shared, not compiled again) with its own mjData, in the initial state
  // (reset()).
  Scene share() const;
  mjData* data() { return data_.get(); }
  const mjData* data() const { return data_.get(); }
  const models::CellDescription& cell() const { return cell_; }
  const std::string& mjcf() const { return mjcf_; }

  const std::vector<RobotIds>& robots() const { return robots_; }
  const std::vector<ConveyorIds>& conveyors() const { return conveyors_; }
  const std::vector<MachineIds>& machines() const { return machines_; }
  const std::vector<WorkpieceIds>& workpieces() const { return workpieces_; }
  const std::vector<ObstacleIds>& obstacles() const { return obstacles_; }
  // Lookups by name; nullptr when there is none.
  const RobotIds* find_robot(std::string_view name) const;
  const ConveyorIds* find_conveyor(std::string_view name) const;
  const WorkpieceIds* find_workpiece(std::string_view name) const;
  // MuJoCo id of the camera with this name, -1 if there is none.
  int camera_id(std::string_view name) const;

  // Puts the cell in its described initial state: robots at home with open grippers and servo targets there,
  // workpieces at their initial poses at rest, belts at their speed; time 0; then mj_forward.
  void reset();
  // Advances the simulation by n steps of the model's timestep, wrapping the belts after each step.
  void step(int n = 1);
  // Moves each belt back by its wrap distance once it has run that far. Call after every mj_step on this scene's
  // model when stepping without step(); `data` must have been made for this scene's model.
  void wrap_belts(mjData* data) const;

 private:
  friend Scene build_scene(const models::CellDescription& cell, const SceneOptions& options);

  // Writes MJCF text (e.g. Scene::mjcf(), for MuJoCo's viewer or for debugging) atomically: to a temporary file in
  // the same directory, then renamed over `path`. Throws InputError naming the path if it cannot be written.
  void write_mjcf(const std::string& mjcf, const std::filesystem::path& path);
  Scene() = default;

  struct DataDeleter {
    void operator()(mjData* d) const { mj_deleteData(d); }
  };

  models::CellDescription cell_;
  std::string mjcf_;
  std::shared_ptr<const mjModel> model_;  // shared by the Scenes share() makes
  std::unique_ptr<mjData, DataDeleter> data_;
  std::vector<RobotIds> robots_;
  std::vector<ConveyorIds> conveyors_;
  std::vector<MachineIds> machines_;
  std::vector<WorkpieceIds> workpieces_;
  std::vector<ObstacleIds> obstacles_;
};

// The cell's fixed scenery (the floor, robots' pedestals, the stands of locations, plates) is not on MuJoCo's world
// body: each such geom is in a fixed body of its own named kSceneryPrefix + the geom's name ("scenery/floor",
// "scenery/melfa/pedestal"), so that the broadphase pairs it only with what comes near it. Code that asks "is this
// geom part of the fixed scenery?" asks is_scenery_body of the geom's body (true for the world body too).
inline constexpr std::string_view kSceneryPrefix = "scenery/";
bool is_scenery_body(const mjModel* m, int body);

// What a geom of the scene stands for, named in the cell's words: the one naming of the scene's geoms that the
// start-overlap check (start_overlaps) and the collision sweep (cell/sim/sweep.hpp) report with.
struct GeomRole {
  enum class Kind : unsigned char {
    none,       // collides with nothing (a visual geom)
    fixed,      // the fixed cell: the scenery, a conveyor's frame, stop bar or guides, a machine
    belt,       // a conveyor's moving belt (it carries parts; robots meet its frame)
    robot,      // a robot's link or finger
    workpiece,  // a part
    obstacle,   // an obstacle of the fault injection
  };
  Kind kind = Kind::none;
  int index = -1;     // the robot (scene().robots()) or workpiece (scene().workpieces()), else -1
  int mount_of = -1;  // the robot standing on it (its pedestal), else -1
  // "the floor", "the stand of location 'S'", "robot 'melfa''s pedestal", "conveyor 'input' (stop bar)",
  // "machine 'mill' (fixture)", "link 'link3'", "workpiece 'A'"; "" for none, belt and obstacle.
  std::string name;
};
GeomRole geom_role(const Scene& scene, int geom);

// Puts free body `body` (a part: a free joint, child of the world) at `pose` (x y z qw qx qy qz) in d: writes its
// qpos and the positions and orientations mj_kinematics derives from them (the body's frame, its inertial frame, its
// geoms' and sites' frames), the same bits as mj_kinematics gives (MuJoCo 2.2: the quaternion normalised in qpos,
// then again as the body's), and nothing else: the rest of d stays as it was. For a pose of one body after a
// whole-model kinematics pass (the sweep's carried part), at a fraction of a second pass. InternalError if `body` is
// not such a body.
void place_free_body(const mjModel* m, mjData* d, int body, const double pose[7]);

// The MJCF text of the whole cell. Reads each robot's URDF (boxes, cylinders, spheres and meshes) and the gripper
// mounted on it. Throws InputError naming the URDF's file and line when it cannot be read or lacks what the scene
// needs (the cell's base, flange and tool links; prismatic joints finger_left_joint and finger_right_joint, in the
// URDF or the mounted gripper), when a mesh's package is unknown, its file missing or unreadable (mesh_import.hpp).
// With links that have no mass it compiles the scene once with MuJoCo to tune the servos (and throws as
// build_scene).
std::string scene_mjcf(const models::CellDescription& cell, const SceneOptions& options = {});

// Builds the MJCF, compiles it in memory (MuJoCo's virtual file system: nothing is written to disk but converted
// meshes, mesh_import.hpp) and returns
// the scene, reset to its initial state. Throws InputError as scene_mjcf, or naming the cell file with MuJoCo's
// message if MuJoCo rejects the model.
Scene build_scene(const models::CellDescription& cell, const SceneOptions& options = {});

// Writes MJCF text (e.g. Scene::mjcf(), for MuJoCo's viewer or for debugging) atomically: to a temporary file in
// the same directory, then renamed over `path`. Throws InputError naming the path if it cannot be written.
void write_mjcf(const std::string& mjcf, const std::filesystem::path& path);

// A robot that overlaps something at the start, in the cell's initial state (Scene::reset: every robot at home):
// another robot, or the fixed cell (the floor, a conveyor's frame or stop bar, a machine, another robot's pedestal).
// Not counted: a robot against its own pedestal, parts (a run's physics judges those: a part may start in a hand)
// and the fault injection's obstacles (under the floor until a fault puts them in). Such a cell cannot run: every
// motion of either robot would start in collision.
struct StartOverlap {
  std::string robot;        // the robot, as the cell names it
  std::string body;         // its body in contact: "link 'link3'"
  std::string other_robot;  // the other robot; "" when `other` is of the fixed cell
  std::string other;        // "link 'link2'", "the floor", "conveyor 'input' (frame)", "machine 'mill'",
                            // "robot 'melfa''s pedestal"
  double depth = 0;         // m, the deepest contact between the two
  SourceLocation where;        // the robot's entry in the cell file
  SourceLocation other_where;  // the other robot's; empty for the fixed cell
  // "robot 'puma''s link 'link3' and robot 'melfa''s link 'link2' overlap by 25 mm"
  std::string text() const;
};

// The overlaps at the start deeper than `depth` (m), one per pair of a robot and another robot or a fixed object
// (the deepest of their contacts), in the order of the cell's robots. `scene` as build_scene returns it (reset).
// The default depth is the plan's collision sweep's (cell/sweep.hpp SweepOptions::depth): shallower is touching.
std::vector<StartOverlap> start_overlaps(const Scene& scene, double depth = 0.002);

// The one error for `overlaps` (not empty), at the first one's robot entry in the cell file: "at the start, with
// every robot at home: <text of each, '; '>; move a robot's base or change its home (the robots' entries: <file:line
// of each robot named>)".
InputError start_overlap_error(const std::vector<StartOverlap>& overlaps);

}  // namespace cellwright::twin
