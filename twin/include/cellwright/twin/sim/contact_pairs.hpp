// ContactPairs: the World's collision detection without MuJoCo's broadphase. The geom pairs that can ever touch are
// listed once; before each step's collision detection the pairs of bodies too far apart to touch are left out, and
// MuJoCo's own narrow phase (mj_collision in its predefined-pairs mode) tests the rest. The contacts are MuJoCo's
// dynamic mode's, the same values in the same order, so the physics is unchanged (tests/twin/sim/contact_pairs_test.cpp
// steps both side by side and compares the states bit for bit).
//
// WHY. MuJoCo 2.2's broadphase sorts every body's bounding box along the bodies' principal axis on every step (an
// eigen-decomposition and two sorts), pairs a body holding a plane (the floor) with every other body, and then tests
// every geom pair of every overlapping body pair, visual meshes included. On the pipeline that was 116,000 of the
// 480,000 instructions of a step (callgrind), for the few dozen pairs that can touch (docs/simulation.md, "Contact
// pairs").
//
// THE PAIRS. A geom pair is listed when MuJoCo's dynamic mode could test it: both geoms have a collision function for
// their types, their contype/conaffinity masks (the scene's) are compatible, they are on different weld bodies, neither
// weld body is the other's weld parent (unless the model disables the parent filter), and their bodies' pair is not
// excluded. They are in mj_collision's order: body pairs by signature (lower body id first), then the lower body's
// geoms, then the other's. Each pair's contact parameters (condim, margin, gap, friction, solref, solimp) are mixed
// from its geoms as mj_collideGeoms mixes them for a dynamic pair (geom priority, else max and the solmix weights, on
// the geoms ordered by type), so that a contact carries the same numbers.
//
// THE SELECTION (select(), after the step's kinematics, before mj_collision). A body pair is left out when the
// bounding spheres of all its geoms cannot meet: the distance between the bodies' frames exceeds the sum of their
// radii (each the largest, over its geoms, of the geom's offset from the body frame plus its bounding radius) plus the
// pair's largest margin; or, for a plane, when the other body's sphere is above it by more than its radius and the
// margin (mj_collideGeoms's own plane filter, on the body). Otherwise each of its geom pairs whose current masks (the
// physics model's: RestingParts clears a sleeping part's) are compatible is written into the physics model's pair
// arrays, in the listed order. What is left out would have been rejected by mj_collideGeoms's bounding-sphere or plane
// filter, or by its mask test, so the contacts are those of the dynamic mode. select_all() writes every pair whose
// masks are compatible (for an mj_forward outside a step, whose positions are not known before it).
//
// THE MODEL. The physics model (the World's own copy) is switched to predefined pairs (opt.collision = mjCOL_PAIR),
// and its pair arrays (pair_dim ... pair_solimp, npair) are pointed at this object's storage, sized for every listed
// pair: the compiled model has none of its own. MuJoCo 2.2 reads a model's arrays through these pointers only; the
// model's buffer still holds the rest and mj_deleteModel frees it as before. The model must not be copied, saved or
// used after this object is destroyed.
//
// A model with another integrator is refused (CW_CHECK): the World uses Euler (docs/simulation.md).
//
// THREADS. The World's simulation thread only.
#pragma once

#include <mujoco/mujoco.h>

#include <cstddef>
#include <vector>

namespace cellwright::twin::sim {

class ContactPairs {
 public:
  // Lists the pairs of `physics` (see THE PAIRS) and takes over its pair arrays (THE MODEL). `physics` must have no
  // predefined pairs of its own and use MuJoCo's default collision mode; it must outlive this object.
  explicit ContactPairs(mjModel* physics);
  ContactPairs(const ContactPairs&) = delete;
  ContactPairs& operator=(const ContactPairs&) = delete;

  // One step of the physics model on `d`: MuJoCo 2.2.2's mj_step with the Euler integrator, its stages called as
  // mj_step, mj_forward and mj_fwdPosition call them, with select() between the kinematics and the collision
  // detection. MuJoCo's timers (mjData::timer, while mjcb_time is set) are kept as mj_step keeps them.
  void step(mjData* d);
  // mj_forward of the physics model on `d`, every pair written (select_all: the positions are not known before).
  void forward(mjData* d);

  // Writes the pairs whose bodies are near enough in `d` (positions as mj_kinematics left them) into the model.
  void select(const mjData* d);
  // Writes every listed pair whose masks are compatible.
  void select_all();

  std::size_t listed() const { return listed_.size(); }  // every pair that can ever touch
  int selected() const { return physics_->npair; }       // those the last selection kept

  // One listed pair: its geoms (the lower body's first), its bodies' signature and its mixed parameters.
  struct Listed {
    int geom1 = -1, geom2 = -1, signature = 0, dim = 0;
    mjtNum margin = 0, gap = 0, friction[5] = {}, solref[mjNREF] = {}, solimp[mjNIMP] = {};
  };

 private:
  struct BodyPair {
    int b1 = 0, b2 = 0;        // body ids, b1 < b2
    double reach = 0;          // sum of the bodies' radii plus the largest margin of their geom pairs
    double reach2 = 0;         // its square
    int plane = -1;            // the plane geom of one of them when that body holds only it, else -1
    bool plane_is_first = false;  // the plane is b1's
    std::size_t first = 0;     // its geom pairs: [first, last) of the lists below
    std::size_t last = 0;
  };

  void write(std::size_t pair, int slot);
  bool compatible(std::size_t pair) const;
  void publish();  // writes chosen_ into the model's arrays

  mjModel* physics_;
  std::vector<BodyPair> body_pairs_;
  std::vector<Listed> listed_;  // every listed pair, in order
  std::vector<std::size_t> chosen_, published_;  // the pairs of this selection, and those the arrays hold
  // The physics model's pair arrays (what select() writes).
  std::vector<int> m_dim_, m_geom1_, m_geom2_, m_signature_;
  std::vector<mjtNum> m_solref_, m_solimp_, m_margin_, m_gap_, m_friction_;
};

}  // namespace cellwright::twin::sim
