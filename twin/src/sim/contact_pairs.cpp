// ContactPairs (contact_pairs.hpp): the pairs listed once, selected before each step's collision detection.
#include "cellwright/twin/sim/contact_pairs.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {
namespace {

// Room for rounding in the body test: a geom's world position is its body's plus a rotated offset, each rounded.
constexpr double kRoundingSlack = 1e-9;

bool masks_meet(const mjModel* m, int g1, int g2) {
  return (m->geom_contype[g1] & m->geom_conaffinity[g2]) || (m->geom_contype[g2] & m->geom_conaffinity[g1]);
}

bool is_plane(const mjModel* m, int g) { return m->geom_type[g] == mjGEOM_PLANE || m->geom_type[g] == mjGEOM_HFIELD; }

// A geom pair's contact parameters, mixed from its two geoms as mj_collideGeoms mixes them for a dynamic pair: on
// the geoms ordered by type, by geom priority, else max and the solmix weights.
void mix(const mjModel* m, int a, int b, ContactPairs::Listed& out) {
  const int g1 = m->geom_type[a] > m->geom_type[b] ? b : a;
  const int g2 = g1 == a ? b : a;
  out.margin = std::max(m->geom_margin[g1], m->geom_margin[g2]);
  out.gap = std::max(m->geom_gap[g1], m->geom_gap[g2]);
  if (m->geom_priority[g1] != m->geom_priority[g2]) {
    const int gp = m->geom_priority[g1] > m->geom_priority[g2] ? g1 : g2;
    out.dim = m->geom_condim[gp];
    for (int i = 0; i < 3; ++i) out.friction[2 * i] = m->geom_friction[3 * gp + i];
    std::copy_n(m->geom_solref + mjNREF * gp, mjNREF, out.solref);
    std::copy_n(m->geom_solimp + mjNIMP * gp, mjNIMP, out.solimp);
  } else {
    out.dim = std::max(m->geom_condim[g1], m->geom_condim[g2]);
    for (int i = 0; i < 3; ++i) {
      out.friction[2 * i] = std::max(m->geom_friction[3 * g1 + i], m->geom_friction[3 * g2 + i]);
    }
    const mjtNum s1 = m->geom_solmix[g1], s2 = m->geom_solmix[g2];
    mjtNum w;  // g1's weight
    if (s1 >= mjMINVAL && s2 >= mjMINVAL) {
      w = s1 / (s1 + s2);
    } else if (s1 < mjMINVAL && s2 < mjMINVAL) {
      w = 0.5;
    } else {
      w = s1 < mjMINVAL ? 0.0 : 1.0;
    }
    const mjtNum* r1 = m->geom_solref + mjNREF * g1;
    const mjtNum* r2 = m->geom_solref + mjNREF * g2;
    for (int i = 0; i < mjNREF; ++i) {
      out.solref[i] = r1[0] > 0 && r2[0] > 0 ? w * r1[i] + (1 - w) * r2[i] : std::min(r1[i], r2[i]);
    }
    for (int i = 0; i < mjNIMP; ++i) {  // as mju_scl then mju_addToScl compute it
      out.solimp[i] = m->geom_solimp[mjNIMP * g1 + i] * w;
      out.solimp[i] += m->geom_solimp[mjNIMP * g2 + i] * (1 - w);
    }
  }
  out.friction[1] = out.friction[0];
  out.friction[3] = out.friction[4];
}

// A body's radius about its frame: the largest geom offset plus bounding radius; 0 for a body of one plane, infinite
// for a body with a plane among other geoms (never left out).
double radius_of(const mjModel* m, int b) {
  const int n = m->body_geomnum[b];
  double radius = 0;
  for (int g = m->body_geomadr[b]; g < m->body_geomadr[b] + n; ++g) {
    const double r = is_plane(m, g) ? (n == 1 ? 0.0 : std::numeric_limits<double>::infinity())
                                    : std::hypot(m->geom_pos[3 * g], m->geom_pos[3 * g + 1], m->geom_pos[3 * g + 2]) +
                                          m->geom_rbound[g];
    radius = std::max(radius, r);
  }
  return radius;
}

}  // namespace

ContactPairs::ContactPairs(mjModel* physics) : physics_(physics) {
  const mjModel* m = physics;
  CW_CHECK(m->opt.integrator == mjINT_EULER, "ContactPairs steps with the Euler integrator only, not {}",
           m->opt.integrator);
  CW_CHECK(m->npair == 0, "the physics model has {} predefined pairs; ContactPairs lists its own", m->npair);
  CW_CHECK(m->opt.collision == mjCOL_ALL, "the physics model's collision mode is {}, not MuJoCo's default",
           m->opt.collision);
  CW_CHECK(m->nbody < 0x10000, "{} bodies do not fit a pair signature", m->nbody);

  const bool filter_parent = !(m->opt.disableflags & mjDSBL_FILTERPARENT);
  std::vector<int> excluded(m->exclude_signature, m->exclude_signature + m->nexclude);
  std::sort(excluded.begin(), excluded.end());
  for (int b1 = 0; b1 < m->nbody; ++b1) {
    for (int b2 = b1 + 1; b2 < m->nbody; ++b2) {
      if (m->body_geomnum[b1] == 0 || m->body_geomnum[b2] == 0) continue;
      const int signature = ((b1 + 1) << 16) + (b2 + 1);
      if (std::binary_search(excluded.begin(), excluded.end(), signature)) continue;
      const int weld1 = m->body_weldid[b1], weld2 = m->body_weldid[b2];
      if (weld1 == weld2) continue;
      const int parent1 = m->body_weldid[m->body_parentid[weld1]];
      const int parent2 = m->body_weldid[m->body_parentid[weld2]];
      if (filter_parent && weld1 != 0 && weld2 != 0 && (weld1 == parent2 || weld2 == parent1)) continue;
      BodyPair bp;
      bp.b1 = b1;
      bp.b2 = b2;
      bp.first = listed_.size();
      double margin = 0;
      for (int g1 = m->body_geomadr[b1]; g1 < m->body_geomadr[b1] + m->body_geomnum[b1]; ++g1) {
        for (int g2 = m->body_geomadr[b2]; g2 < m->body_geomadr[b2] + m->body_geomnum[b2]; ++g2) {
          const int t1 = m->geom_type[g1], t2 = m->geom_type[g2];
          if (!masks_meet(m, g1, g2) || !mjCOLLISIONFUNC[std::min(t1, t2)][std::max(t1, t2)]) continue;
          Listed& p = listed_.emplace_back();
          p.geom1 = g1;
          p.geom2 = g2;
          p.signature = signature;
          mix(m, g1, g2, p);
          margin = std::max(margin, p.margin);
        }
      }
      bp.last = listed_.size();
      if (bp.last == bp.first) continue;
      // A body of one plane geom against another (two such have no collision function, so are never listed).
      for (const int body : {b1, b2}) {
        const int g = m->body_geomadr[body];
        if (m->body_geomnum[body] == 1 && is_plane(m, g)) {
          bp.plane = g;
          bp.plane_is_first = body == b1;
        }
      }
      bp.reach = radius_of(m, b1) + radius_of(m, b2) + margin + kRoundingSlack;
      bp.reach2 = bp.reach * bp.reach;
      body_pairs_.push_back(bp);
    }
  }

  const std::size_t n = listed_.size();
  m_dim_.resize(n);
  m_geom1_.resize(n);
  m_geom2_.resize(n);
  m_signature_.resize(n);
  m_solref_.resize(n * mjNREF);
  m_solimp_.resize(n * mjNIMP);
  m_margin_.resize(n);
  m_gap_.resize(n);
  m_friction_.resize(n * 5);
  physics_->pair_dim = m_dim_.data();
  physics_->pair_geom1 = m_geom1_.data();
  physics_->pair_geom2 = m_geom2_.data();
  physics_->pair_signature = m_signature_.data();
  physics_->pair_solref = m_solref_.data();
  physics_->pair_solimp = m_solimp_.data();
  physics_->pair_margin = m_margin_.data();
  physics_->pair_gap = m_gap_.data();
  physics_->pair_friction = m_friction_.data();
  physics_->npair = 0;
  physics_->opt.collision = mjCOL_PAIR;
  select_all();
}

bool ContactPairs::compatible(std::size_t pair) const {
  return masks_meet(physics_, listed_[pair].geom1, listed_[pair].geom2);
}

void ContactPairs::write(std::size_t pair, int slot) {
  const Listed& p = listed_[pair];
  const auto s = static_cast<std::size_t>(slot);
  m_dim_[s] = p.dim;
  m_geom1_[s] = p.geom1;
  m_geom2_[s] = p.geom2;
  m_signature_[s] = p.signature;
  m_margin_[s] = p.margin;
  m_gap_[s] = p.gap;
  std::copy_n(p.solref, mjNREF, &m_solref_[s * mjNREF]);
  std::copy_n(p.solimp, mjNIMP, &m_solimp_[s * mjNIMP]);
  std::copy_n(p.friction, 5, &m_friction_[s * 5]);
}

void ContactPairs::select(const mjData* d) {
  chosen_.clear();
  const mjtNum* xpos = d->xpos;
  for (const BodyPair& bp : body_pairs_) {
    const mjtNum* p1 = xpos + 3 * bp.b1;
    const mjtNum* p2 = xpos + 3 * bp.b2;
    bool near;
    if (bp.plane < 0) {
      const mjtNum dx = p1[0] - p2[0], dy = p1[1] - p2[1], dz = p1[2] - p2[2];
      near = dx * dx + dy * dy + dz * dz <= bp.reach2;
    } else {
      // A plane (a body of one plane geom, radius 0) against a body: mj_collideGeoms rejects each geom of the body
      // whose centre is above the plane by more than its bounding radius and the margin; all of them when the body's
      // frame is above it by more than the body's radius and the margin.
      const mjtNum* at = bp.plane_is_first ? p2 : p1;
      const mjtNum* g = d->geom_xpos + 3 * bp.plane;
      const mjtNum* mat = d->geom_xmat + 9 * bp.plane;  // the plane's normal is its frame's z axis
      near = (at[0] - g[0]) * mat[2] + (at[1] - g[1]) * mat[5] + (at[2] - g[2]) * mat[8] <= bp.reach;
    }
    if (!near) continue;
    for (std::size_t p = bp.first; p < bp.last; ++p) {
      if (compatible(p)) chosen_.push_back(p);
    }
  }
  publish();
}

void ContactPairs::select_all() {
  chosen_.clear();
  for (std::size_t p = 0; p < listed_.size(); ++p) {
    if (compatible(p)) chosen_.push_back(p);
  }
  publish();
}

void ContactPairs::publish() {
  // The model's arrays change only when the choice does (from one step to the next it mostly does not).
  if (chosen_ != published_) {
    for (std::size_t i = 0; i < chosen_.size(); ++i) write(chosen_[i], static_cast<int>(i));
    published_ = chosen_;
  }
  physics_->npair = static_cast<int>(chosen_.size());
}

void ContactPairs::step(mjData* d) {
  const mjModel* m = physics_;
  const auto clock = [] { return mjcb_time ? mjcb_time() : 0; };
  const auto add = [&](int timer, mjtNum since) {
    d->timer[timer].duration += clock() - since;
    d->timer[timer].number++;
  };
  const mjtNum step_start = clock();
  mj_checkPos(m, d);
  mj_checkVel(m, d);
  const mjtNum position_start = clock();
  const auto timed = [&](int timer, auto&& stage) {
    const mjtNum since = clock();
    stage();
    add(timer, since);
  };
  timed(mjTIMER_POS_KINEMATICS, [&] {
    mj_kinematics(m, d);
    mj_comPos(m, d);
    mj_camlight(m, d);
    mj_tendon(m, d);
  });
  timed(mjTIMER_POS_INERTIA, [&] {
    mj_crb(m, d);
    mj_factorM(m, d);
  });
  timed(mjTIMER_POS_COLLISION, [&] {
    select(d);
    mj_collision(m, d);
  });
  timed(mjTIMER_POS_MAKE, [&] {
    mj_makeConstraint(m, d);
    mj_transmission(m, d);
  });
  timed(mjTIMER_POS_PROJECT, [&] { mj_projectConstraint(m, d); });
  add(mjTIMER_POSITION, position_start);
  mj_sensorPos(m, d);  // returns at once while the World disables the sensors
  if (m->opt.enableflags & mjENBL_ENERGY) mj_energyPos(m, d);
  mj_forwardSkip(m, d, mjSTAGE_POS, 0);  // velocity, actuation, acceleration, constraint solver, sensors
  mj_checkAcc(m, d);
  mj_Euler(m, d);
  add(mjTIMER_STEP, step_start);
}

void ContactPairs::forward(mjData* d) {
  select_all();  // the positions are known only after mj_forward's kinematics: every pair
  mj_forward(physics_, d);
}

}  // namespace cellwright::twin::sim
