#include "resting_parts.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::twin::sim {
namespace {

double norm3(const mjtNum* v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

}  // namespace

double upward_force(const mjModel* m, const mjData* d, int contact, int side) {
  const mjContact& con = d->contact[contact];
  if (con.exclude != 0) return 0;  // in the margin gap: no force
  // The contact normal points from geom1 to geom2; turned to point from the other body into the geom on `side`.
  const double up = (side == 0 ? -1.0 : 1.0) * con.frame[2];
  if (up < kSupportNormal) return 0;
  mjtNum force[6];
  mj_contactForce(m, d, contact, force);
  return force[0];
}

RestingParts::RestingParts(const Scene& scene, mjModel* physics) : scene_(scene), physics_(physics) {
  const mjModel* m = scene_.model();
  CW_CHECK(physics_ != nullptr && physics_->ngeom == m->ngeom && physics_->nbody == m->nbody,
           "the physics model is not a copy of the scene's");
  still_steps_needed_ = std::max(1, static_cast<int>(std::ceil(kStillTime / m->opt.timestep - 1e-9)));
  parts_.resize(scene_.workpieces().size());
  kind_.assign(static_cast<std::size_t>(m->nbody), Kind::moving);
  index_.assign(static_cast<std::size_t>(m->nbody), -1);
  geom_conveyor_.assign(static_cast<std::size_t>(m->ngeom), -1);
  for (int b = 0; b < m->nbody; ++b) {
    if (m->body_weldid[b] == 0 && m->body_mocapid[b] < 0) kind_[static_cast<std::size_t>(b)] = Kind::fixed;
  }
  const models::CellDescription& cell = scene_.cell();
  for (std::size_t i = 0; i < scene_.conveyors().size(); ++i) {
    const ConveyorIds& c = scene_.conveyors()[i];
    kind_[static_cast<std::size_t>(c.belt_body)] = Kind::belt;
    index_[static_cast<std::size_t>(c.belt_body)] = static_cast<int>(i);
    for (int g = 0; g < m->ngeom; ++g) {
      if (m->geom_bodyid[g] == c.body || m->geom_bodyid[g] == c.belt_body) {
        geom_conveyor_[static_cast<std::size_t>(g)] = static_cast<int>(i);
      }
    }
    const models::ConveyorSpec& spec = cell.conveyors[i];
    belt_axis_.push_back(spec.pose.rotation().col(0));
    belt_origin_.push_back(spec.belt_point(0.0));
  }
  travel_.assign(scene_.conveyors().size(), 0.0);
  belt_q_.assign(scene_.conveyors().size(), 0.0);
  for (std::size_t w = 0; w < scene_.workpieces().size(); ++w) {
    const WorkpieceIds& ids = scene_.workpieces()[w];
    CW_CHECK(m->body_geomnum[ids.body] == 1 && m->body_geomadr[ids.body] == ids.geom,
             "workpiece '{}' is not one geom on its body", ids.name);
    kind_[static_cast<std::size_t>(ids.body)] = Kind::part;
    index_[static_cast<std::size_t>(ids.body)] = static_cast<int>(w);
  }
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_contype[g] == 0 && m->geom_conaffinity[g] == 0) continue;  // visual only
    const Kind k = kind_[static_cast<std::size_t>(m->geom_bodyid[g])];
    if (k == Kind::moving) moving_geoms_.push_back(g);
    if (k == Kind::fixed && m->geom_type[g] != mjGEOM_PLANE) static_geoms_.push_back(g);
  }
}

bool RestingParts::near(const mjData* d, int g1, int g2) const {
  const mjtNum* a = d->geom_xpos + 3 * g1;
  const mjtNum* b = d->geom_xpos + 3 * g2;
  const double dist = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                (a[2] - b[2]) * (a[2] - b[2]));
  const mjModel* m = scene_.model();
  return dist < m->geom_rbound[g1] + m->geom_rbound[g2] + kWakeGap;
}

bool RestingParts::belt_still(const mjData* d, std::size_t conveyor) const {
  const ConveyorIds& c = scene_.conveyors()[conveyor];
  return d->ctrl[c.belt_actuator] == 0 && std::abs(d->qvel[c.belt_dof_adr]) < kStillSpeed;
}

bool RestingParts::belt_steady(const mjData* d, std::size_t conveyor) const {
  const ConveyorIds& c = scene_.conveyors()[conveyor];
  return c.speed != 0 && d->ctrl[c.belt_actuator] == c.speed &&
         std::abs(d->qvel[c.belt_dof_adr] - c.speed) < kStillSpeed;
}

bool RestingParts::disturbed(const mjData* d, std::size_t workpiece, int rides,
                             const std::vector<char>& ignore_parts) const {
  const int pg = scene_.workpieces()[workpiece].geom;
  if (std::any_of(moving_geoms_.begin(), moving_geoms_.end(), [&](int g) { return near(d, g, pg); })) return true;
  for (std::size_t o = 0; o < parts_.size(); ++o) {
    if (o == workpiece || ignore_parts[o]) continue;
    const Part& q = parts_[o];
    // What moves relative to this part: an awake part; a rider, unless both ride the same belt; for a rider, also a
    // part lying still.
    const bool moves = q.state == State::awake || (q.state == State::riding && q.conveyor != rides) ||
                       (q.state == State::still && rides >= 0);
    if (moves && near(d, scene_.workpieces()[o].geom, pg)) return true;
  }
  return false;
}

bool RestingParts::ride_clear(const mjData* d, std::size_t workpiece, std::size_t conveyor) const {
  const mjModel* m = scene_.model();
  const int pg = scene_.workpieces()[workpiece].geom;
  const models::ConveyorSpec& spec = scene_.cell().conveyors[conveyor];
  const Eigen::Vector3d p = Eigen::Map<const Eigen::Vector3d>(d->geom_xpos + 3 * pg);
  const double s = (p - belt_origin_[conveyor]).dot(belt_axis_[conveyor]);
  const double r = m->geom_rbound[pg] + kWakeGap;
  const double end = spec.stop ? spec.leave : spec.length;
  if (s - r < 0 || s + r > end) return false;
  for (int g : static_geoms_) {
    if (geom_conveyor_[static_cast<std::size_t>(g)] == static_cast<int>(conveyor)) continue;
    if (near(d, g, pg)) return false;
  }
  return true;
}

void RestingParts::sleep(std::size_t workpiece, const mjData* d, State state, int support_geom,
                         std::vector<int> belts, int conveyor) {
  Part& p = parts_[workpiece];
  const WorkpieceIds& ids = scene_.workpieces()[workpiece];
  std::copy(d->qpos + ids.qpos_adr, d->qpos + ids.qpos_adr + 7, p.qpos.begin());
  p.state = state;
  p.support_geom = support_geom;
  p.belts = std::move(belts);
  p.conveyor = conveyor;
  p.travel = conveyor >= 0 ? travel_[static_cast<std::size_t>(conveyor)] : 0.0;
  physics_->geom_contype[ids.geom] = 0;
  physics_->geom_conaffinity[ids.geom] = 0;
}

void RestingParts::put_to_sleep(std::size_t workpiece, const mjData* d) {
  CW_CHECK(workpiece < parts_.size(), "no workpiece {}", workpiece);
  wake(workpiece);
  sleep(workpiece, d, State::still, -1, {}, -1);
}

void RestingParts::wake(std::size_t workpiece) {
  CW_CHECK(workpiece < parts_.size(), "no workpiece {}", workpiece);
  Part& p = parts_[workpiece];
  if (p.state == State::awake) return;
  const int g = scene_.workpieces()[workpiece].geom;
  physics_->geom_contype[g] = scene_.model()->geom_contype[g];
  physics_->geom_conaffinity[g] = scene_.model()->geom_conaffinity[g];
  p.state = State::awake;
  p.still_steps = p.ride_steps = 0;
  p.ride_belt = -1;
  p.support_geom = -1;
  p.conveyor = -1;
  p.belts.clear();
}

void RestingParts::wake_all() {
  for (std::size_t w = 0; w < parts_.size(); ++w) wake(w);
}

void RestingParts::after_step(mjData* d, const std::vector<bool>& parked) {
  const mjModel* m = scene_.model();
  const std::size_t n = parts_.size();
  const std::size_t nc = travel_.size();
  CW_CHECK(parked.size() == n, "{} parked flags for {} workpieces", parked.size(), n);

  // The belts' travel, unwrapped (Scene::wrap_belts moves a belt back by its wrap length).
  for (std::size_t i = 0; i < nc; ++i) {
    const ConveyorIds& c = scene_.conveyors()[i];
    const double q = d->qpos[c.belt_qpos_adr];
    double delta = q - belt_q_[i];
    if (delta > c.wrap / 2) delta -= c.wrap;
    if (delta < -c.wrap / 2) delta += c.wrap;
    travel_[i] += delta;
    belt_q_[i] = q;
  }

  // 1. The sleepers where they sleep.
  for (std::size_t w = 0; w < n; ++w) {
    const Part& p = parts_[w];
    if (p.state == State::awake) continue;
    const WorkpieceIds& ids = scene_.workpieces()[w];
    std::copy(p.qpos.begin(), p.qpos.end(), d->qpos + ids.qpos_adr);
    std::fill(d->qvel + ids.dof_adr, d->qvel + ids.dof_adr + 6, 0.0);
    std::fill(d->qacc_warmstart + ids.dof_adr, d->qacc_warmstart + ids.dof_adr + 6, 0.0);
    if (p.state == State::riding) {
      const auto c = static_cast<std::size_t>(p.conveyor);
      const Eigen::Vector3d moved = (travel_[c] - p.travel) * belt_axis_[c];
      const Eigen::Vector3d v = d->qvel[scene_.conveyors()[c].belt_dof_adr] * belt_axis_[c];
      for (int k = 0; k < 3; ++k) {
        d->qpos[ids.qpos_adr + k] += moved[k];
        d->qvel[ids.dof_adr + k] = v[k];
      }
    }
  }

  // 2. Wake what something could disturb; a part that wakes may wake the parts it lies against.
  const std::vector<char> none(n, 0);
  for (bool woke = true; woke;) {
    woke = false;
    for (std::size_t w = 0; w < n; ++w) {
      const Part& p = parts_[w];
      if (p.state == State::awake || parked[w]) continue;
      bool wake_it = disturbed(d, w, p.state == State::riding ? p.conveyor : -1, none);
      if (p.state == State::still) {
        wake_it = wake_it || std::any_of(p.belts.begin(), p.belts.end(), [&](int c) {
                    return !belt_still(d, static_cast<std::size_t>(c));
                  });
      } else {
        const auto c = static_cast<std::size_t>(p.conveyor);
        wake_it = wake_it || !belt_steady(d, c) || !ride_clear(d, w, c);
      }
      if (wake_it) {
        wake(w);
        woke = true;
      }
    }
  }

  // 3. Who has been still, or moved with a running belt, long enough.
  std::vector<char> still(n, 0), rides(n, 0);
  bool any = false;
  for (std::size_t w = 0; w < n; ++w) {
    Part& p = parts_[w];
    if (p.state != State::awake || parked[w]) continue;
    const mjtNum* v = d->qvel + scene_.workpieces()[w].dof_adr;
    const bool turning = norm3(v + 3) >= kStillSpin;
    p.still_steps = norm3(v) < kStillSpeed && !turning ? p.still_steps + 1 : 0;
    int belt = -1;
    for (std::size_t c = 0; c < nc && !turning && belt < 0; ++c) {
      if (!belt_steady(d, c)) continue;
      const Eigen::Vector3d rel =
          Eigen::Map<const Eigen::Vector3d>(v) - d->qvel[scene_.conveyors()[c].belt_dof_adr] * belt_axis_[c];
      if (rel.norm() < kStillSpeed) belt = static_cast<int>(c);
    }
    p.ride_steps = belt >= 0 && belt == p.ride_belt ? p.ride_steps + 1 : (belt >= 0 ? 1 : 0);
    p.ride_belt = belt;
    still[w] = p.still_steps >= still_steps_needed_ ? 1 : 0;
    rides[w] = p.ride_steps >= still_steps_needed_ ? 1 : 0;
    any = any || still[w] || rides[w];
  }
  if (!any) return;

  // What the candidates touch.
  std::vector<char> touches(n, 0);
  std::vector<int> support(n, -1);
  std::vector<double> support_force(n, 0.0);
  std::vector<std::vector<int>> belts(n);
  std::vector<std::pair<std::size_t, std::size_t>> against;  // (candidate lying still, part it touches)
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    for (int side = 0; side < 2; ++side) {
      const int g = side == 0 ? con.geom1 : con.geom2;
      const int other = side == 0 ? con.geom2 : con.geom1;
      const auto b = static_cast<std::size_t>(m->geom_bodyid[g]);
      const auto ob = static_cast<std::size_t>(m->geom_bodyid[other]);
      if (kind_[b] != Kind::part) continue;
      const auto w = static_cast<std::size_t>(index_[b]);
      if (!still[w] && !rides[w]) continue;
      touches[w] = 1;
      switch (kind_[ob]) {
        case Kind::fixed:
          rides[w] = 0;
          break;
        case Kind::moving:
          still[w] = rides[w] = 0;
          break;
        case Kind::belt:
          if (index_[ob] != parts_[w].ride_belt) rides[w] = 0;
          if (belt_still(d, static_cast<std::size_t>(index_[ob]))) {
            belts[w].push_back(index_[ob]);
          } else {
            still[w] = 0;
          }
          break;
        case Kind::part:
          rides[w] = 0;
          against.emplace_back(w, static_cast<std::size_t>(index_[ob]));
          break;
      }
      const double up = upward_force(m, d, c, side);
      if (up > support_force[w]) {
        support_force[w] = up;
        support[w] = other;
      }
    }
  }
  for (std::size_t w = 0; w < n; ++w) {
    if (!touches[w]) still[w] = rides[w] = 0;
    if (rides[w] && !ride_clear(d, w, static_cast<std::size_t>(parts_[w].ride_belt))) rides[w] = 0;
  }
  // Parts lying against each other sleep together or not at all; nothing moving may be near.
  for (bool changed = true; changed;) {
    changed = false;
    for (const auto& [w, o] : against) {
      if (still[w] && !still[o] && parts_[o].state != State::still) {
        still[w] = 0;
        changed = true;
      }
    }
    for (std::size_t w = 0; w < n; ++w) {
      if (still[w] && disturbed(d, w, -1, still)) {
        still[w] = 0;
        changed = true;
      }
    }
  }
  for (std::size_t w = 0; w < n; ++w) {
    const WorkpieceIds& ids = scene_.workpieces()[w];
    if (still[w]) {
      auto& b = belts[w];
      std::sort(b.begin(), b.end());
      b.erase(std::unique(b.begin(), b.end()), b.end());
      sleep(w, d, State::still, support[w], std::move(b), -1);
      std::fill(d->qvel + ids.dof_adr, d->qvel + ids.dof_adr + 6, 0.0);
    }
  }
  // Riders last: a part that fell asleep lying still near one is something a rider must not meet asleep.
  for (std::size_t w = 0; w < n; ++w) {
    if (!rides[w]) continue;
    const int c = parts_[w].ride_belt;
    std::vector<char> same_belt(n, 0);  // riding off together
    for (std::size_t o = 0; o < n; ++o) same_belt[o] = rides[o] && parts_[o].ride_belt == c;
    if (disturbed(d, w, c, same_belt)) continue;
    const WorkpieceIds& ids = scene_.workpieces()[w];
    sleep(w, d, State::riding, support[w], {}, c);
    const Eigen::Vector3d v = d->qvel[scene_.conveyors()[static_cast<std::size_t>(c)].belt_dof_adr] *
                              belt_axis_[static_cast<std::size_t>(c)];
    for (int k = 0; k < 3; ++k) d->qvel[ids.dof_adr + k] = v[k];
    for (int k = 3; k < 6; ++k) d->qvel[ids.dof_adr + k] = 0.0;
  }
}

}  // namespace cellwright::twin::sim
