// RestingParts: workpieces that lie still on something that does not move are taken out of the physics until
// something could disturb them, the way physics engines let resting bodies sleep (internal to the World).
//
// WHY. A part at rest on a belt or a fixture costs as much of a step as an arm: its geom against the support gives
// four contacts of four constraint rows each (the parts' condim 4), which collision detection, constraint assembly
// and the solver pay for every step although nothing changes. The paper's cell at rest steps in 69 us with its four
// parts on their supports and in 35 us without them (docs/simulation.md, "Resting parts").
//
// THE RULES (after every step, in this order)
//  1. A part asleep is put back where it sleeps: a part lying still where it fell asleep, at rest; a part riding a
//     running belt where the belt has carried it since (its pose then plus the belt's travel along the belt, its
//     velocity the belt's). It collides with nothing (its geom's contype and conaffinity are 0 in the World's own
//     copy of the model, the physics model; the Scene's model, which renderers and the collision sweep use, is never
//     changed), so during a step only gravity moves it, by g h^2 (0.25 mm at 5 ms), and the pose is put back after.
//  2. A part asleep and not parked wakes (its contacts come back; a rider keeps the belt's velocity) when
//     - a geom that moves (a robot's, an obstacle's, a part's that is awake or riding another belt; a part lying
//       still, for a rider) has its bounding sphere within kWakeGap of the part's bounding sphere; geoms move less
//       than half of kWakeGap in the step between two checks (tool speed 0.5 m/s and arm joints at their limits move
//       a link under 10 mm in a 5 ms step), so a finger, a link or a part pushed by one wakes it at least a step
//       before it could touch it; waking spreads the same way to the parts that lie against a part that woke;
//     - lying still: a belt it rested on (one of its contacts' bodies when it fell asleep) is driven or moves;
//     - riding: its belt is no longer driven or runs off its speed; its bounding sphere comes within kWakeGap of the
//       belt's stop bar (or of the end of a belt without one) or of either end, or of static geometry other than its
//       own conveyor's;
//     - wake() is called: the World calls it before it moves a part itself (feed, park, place, shift) and for every
//       part when an obstacle is placed.
//  3. A part awake falls asleep lying still when it is not parked, has moved slower than kStillSpeed (and turned
//     slower than kStillSpin) for kStillTime, touches something, and everything it touches is
//     - static geometry (a body welded to the world that is not an obstacle), or
//     - a belt that is not driven and does not move, or
//     - a part that is asleep or falls asleep in the same step (parts lying against each other sleep together),
//     and no moving geom is near (the test of rule 2). Its support (the contact pushing it up the hardest, as
//     World::truth() chooses it) is kept for truth() while it sleeps.
//     It falls asleep riding when for kStillTime it has moved with a driven belt (its velocity within kStillSpeed of
//     the belt's, turning slower than kStillSpin), touches that belt and nothing else, and nothing of rule 2 is near.
//  4. A parked part is asleep from when it is parked (put_to_sleep) until wake().
//
// What it changes in a run: a sleeping part does not creep or chatter by fractions of a millimetre, and its support
// carries no force. Everything reads the same pose and a zero velocity: the photo-eyes, the machines' rest test, the
// cameras. Determinism holds: the rules read only the simulation state.
//
// THREADS. The World's simulation thread only.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <vector>

#include "cellwright/twin/scene.hpp"

namespace cellwright::twin::sim {

// A contact supports a part when its normal is within 60 degrees of vertical (World::truth(), RestingParts).
inline constexpr double kSupportNormal = 0.5;
// The normal force with which contact `contact` pushes the geom on its side `side` (0: geom1, 1: geom2) upwards; 0
// when its normal is further from vertical or the contact is in the margin gap.
double upward_force(const mjModel* m, const mjData* d, int contact, int side);

class RestingParts {
 public:
  static constexpr double kWakeGap = 0.04;     // m between bounding spheres (rule 2)
  static constexpr double kStillSpeed = 0.002;  // m/s (rule 3)
  static constexpr double kStillSpin = 0.05;   // rad/s (rule 3)
  static constexpr double kStillTime = 0.2;    // s (rule 3)

  // `physics` is the World's copy of the scene's model (it must outlive this); its geoms' collision masks are the
  // only thing changed in it.
  RestingParts(const Scene& scene, mjModel* physics);

  // Rules 1 to 3, after a step. `parked`: by workpiece index.
  void after_step(mjData* d, const std::vector<bool>& parked);
  // Rule 4: asleep now, where it is (the World has just put it at rest in the parking row).
  void put_to_sleep(std::size_t workpiece, const mjData* d);
  // Awake now, its contacts back (nothing moves); a no-op for a part awake.
  void wake(std::size_t workpiece);
  void wake_all();

  bool asleep(std::size_t workpiece) const { return parts_[workpiece].state != State::awake; }
  // Asleep riding a belt (rule 3): the conveyor's index, else -1.
  int riding(std::size_t workpiece) const {
    return parts_[workpiece].state == State::riding ? parts_[workpiece].conveyor : -1;
  }
  // The geom the part rested on hardest when it fell asleep (-1 when none pushed it up, or parked).
  int support_geom(std::size_t workpiece) const { return parts_[workpiece].support_geom; }

 private:
  enum class State : unsigned char { awake, still, riding };
  struct Part {
    State state = State::awake;
    int still_steps = 0;           // consecutive steps slower than kStillSpeed/kStillSpin
    int ride_steps = 0;            // consecutive steps moving with the belt of `ride_belt`
    int ride_belt = -1;            // the conveyor whose belt it moved with at the last step
    std::array<mjtNum, 7> qpos{};  // where it fell asleep
    double travel = 0;             // riding: the belt's travel when it fell asleep
    int conveyor = -1;             // riding: the belt's conveyor
    int support_geom = -1;
    std::vector<int> belts;        // lying still: conveyors whose belts it touched when it fell asleep
  };
  enum class Kind : unsigned char { fixed, moving, belt, part };

  // Whether something that could disturb `workpiece` is near (rule 2's first test), `ignore_parts` aside; `rides`:
  // the conveyor it rides (or is to ride), else -1.
  bool disturbed(const mjData* d, std::size_t workpiece, int rides, const std::vector<char>& ignore_parts) const;
  bool near(const mjData* d, int g1, int g2) const;
  bool belt_still(const mjData* d, std::size_t conveyor) const;
  bool belt_steady(const mjData* d, std::size_t conveyor) const;  // driven, at its speed
  bool ride_clear(const mjData* d, std::size_t workpiece, std::size_t conveyor) const;  // rule 2, riding
  void sleep(std::size_t workpiece, const mjData* d, State state, int support_geom, std::vector<int> belts,
             int conveyor);

  const Scene& scene_;
  mjModel* physics_;
  int still_steps_needed_ = 1;
  std::vector<Part> parts_;          // by workpiece index
  std::vector<Kind> kind_;           // by body id
  std::vector<int> index_;           // by body id: the workpiece or conveyor index for parts and belts, else -1
  std::vector<int> moving_geoms_;    // collidable geoms of robots and obstacles
  std::vector<int> static_geoms_;    // collidable static geoms but the floor's planes
  std::vector<int> geom_conveyor_;   // by geom: the conveyor whose frame, stop or belt it is, else -1
  // By conveyor: the belt's direction of travel (world), its travel so far (unwrapped) and joint position last step.
  std::vector<Eigen::Vector3d> belt_axis_;
  std::vector<Eigen::Vector3d> belt_origin_;  // the belt's upstream end on its centre line (world)
  std::vector<double> travel_;
  std::vector<double> belt_q_;
};

}  // namespace cellwright::twin::sim
