// Collisions found before the run, in the twin's scene (cell/sim/sweep.hpp).
#include "cellwright/cell/sim/sweep.hpp"

#include "cellwright/cell/sim/run.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <tuple>
#include <unordered_set>

#include "cellwright/common/error.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/task/to_net.hpp"
#include "cellwright/twin/scene.hpp"

namespace cellwright::cell {

namespace sim = twin::sim;  // the simulator's World, drivers and plant

using twin::build_scene;
using twin::RobotIds;
using twin::Scene;
using twin::WorkpieceIds;

namespace {

// What a collision geom of the scene stands for.
enum class Owner : std::uint8_t {
  kIgnored,  // visual, a belt, an obstacle of the fault injection
  kStatic,   // the fixed cell
  kRobot,    // a robot's link or finger
  kPart,     // a workpiece
};

struct GeomInfo {
  Owner owner = Owner::kIgnored;
  int index = -1;     // scene robot (kRobot) or workpiece (kPart)
  int mount_of = -1;  // scene robot standing on it (its pedestal), else -1
  std::string name;   // in the cell's words
};

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

std::vector<GeomInfo> classify(const Scene& scene) {
  const mjModel* m = scene.model();
  std::vector<GeomInfo> out(static_cast<std::size_t>(m->ngeom));
  for (int g = 0; g < m->ngeom; ++g) {
    GeomInfo& info = out[static_cast<std::size_t>(g)];
    if (m->geom_contype[g] == 0 && m->geom_conaffinity[g] == 0) continue;
    const char* gname = mj_id2name(m, mjOBJ_GEOM, g);
    const std::string geom = gname != nullptr ? gname : "";
    const int b = m->geom_bodyid[g];
    const char* bname = mj_id2name(m, mjOBJ_BODY, b);
    const std::string body = bname != nullptr ? bname : "";
    info.owner = Owner::kStatic;
    if (twin::is_scenery_body(m, b)) {
      info.name = geom == "floor" ? "the floor" : fmt::format("'{}'", geom);
      for (std::size_t r = 0; r < scene.robots().size(); ++r) {
        if (geom == scene.robots()[r].name + "/pedestal") {
          info.mount_of = static_cast<int>(r);
          info.name = fmt::format("robot '{}''s pedestal", scene.robots()[r].name);
        }
      }
    } else if (starts_with(body, "conveyor/")) {
      const std::string name = body.substr(9);
      if (name.find('/') != std::string::npos) {
        info.owner = Owner::kIgnored;  // the belt: it carries parts, robots meet the frame
        continue;
      }
      const std::string what = geom == body + "/stop" ? "stop bar" : geom == body + "/frame" ? "frame" : geom;
      info.name = fmt::format("conveyor '{}' ({})", name, what);
    } else if (starts_with(body, "machine/")) {
      const std::string name = body.substr(8);
      info.name = fmt::format("machine '{}'{}", name, geom == body + "/fixture" ? " (fixture)" : "");
    } else if (starts_with(body, "obstacle/")) {
      info.owner = Owner::kIgnored;
    } else if (starts_with(body, "workpiece/")) {
      info.owner = Owner::kPart;
      for (std::size_t w = 0; w < scene.workpieces().size(); ++w) {
        if (scene.workpieces()[w].body == b) info.index = static_cast<int>(w);
      }
      CW_CHECK(info.index >= 0, "workpiece body {} not among the scene's workpieces", body);
      info.name = fmt::format("workpiece '{}' (carried)", body.substr(10));
    } else {
      info.name = fmt::format("'{}'", body);
      for (std::size_t r = 0; r < scene.robots().size(); ++r) {
        const std::string prefix = scene.robots()[r].name + "/";
        if (starts_with(body, prefix)) {
          info.owner = Owner::kRobot;
          info.index = static_cast<int>(r);
          info.name = fmt::format("link '{}'", body.substr(prefix.size()));
        }
      }
    }
  }
  return out;
}

// A bounding sphere of one geom in one pose.
struct Sphere {
  Eigen::Vector3d centre;
  double radius = 0;
};

// What one robot does while one place of its chain is marked: the poses it takes (one for anything but a move).
struct Span {
  std::size_t robot = 0;  // program robot
  int scene_robot = -1;
  std::string command, source;
  bool move = false;
  Eigen::VectorXd from, to;
  std::size_t samples = 1;
  int part = -1;  // scene workpiece carried, -1 for none
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();
  double fingers = 0;
  // Per sample: the spheres of the robot's collision geoms and of its part, and their box.
  std::vector<std::vector<Sphere>> spheres;
  std::vector<Eigen::AlignedBox3d> box;
  Eigen::AlignedBox3d all;

  Eigen::VectorXd at(std::size_t i) const {
    if (samples <= 1) return to;
    const double u = static_cast<double>(i) / static_cast<double>(samples - 1);
    return from + u * (to - from);
  }
};

// A copy of the scene's data to pose the arms in: parts parked out of reach, far apart.
class Poser {
 public:
  explicit Poser(const Scene& scene) : scene_(scene), m_(scene.model()), d_(mj_makeData(m_)) {
    CW_CHECK(d_ != nullptr, "mj_makeData failed");
    baseline_.assign(scene.data()->qpos, scene.data()->qpos + m_->nq);
    for (std::size_t w = 0; w < scene.workpieces().size(); ++w) {
      const int adr = scene.workpieces()[w].qpos_adr;
      const double parked[7] = {100.0 + 10.0 * static_cast<double>(w), 100.0, 100.0, 1, 0, 0, 0};
      std::copy(parked, parked + 7, baseline_.begin() + adr);
    }
  }
  Poser(const Poser&) = delete;
  Poser& operator=(const Poser&) = delete;
  ~Poser() { mj_deleteData(d_); }

  const mjData* data() const { return d_; }

  // Poses the spans' robots at their samples (everything else as at the start, parts parked), and computes the
  // contacts when `collide`.
  void pose(const std::vector<std::pair<const Span*, std::size_t>>& at, bool collide) {
    std::copy(baseline_.begin(), baseline_.end(), d_->qpos);
    bool parts = false;
    for (const auto& [span, i] : at) {
      const RobotIds& r = scene_.robots()[static_cast<std::size_t>(span->scene_robot)];
      const Eigen::VectorXd q = span->at(i);
      for (std::size_t j = 0; j < r.qpos_adr.size(); ++j) d_->qpos[r.qpos_adr[j]] = q[static_cast<Eigen::Index>(j)];
      for (int f = 0; f < 2; ++f) d_->qpos[r.finger_qpos_adr[static_cast<std::size_t>(f)]] = span->fingers;
      parts = parts || span->part >= 0;
    }
    mj_kinematics(m_, d_);
    if (parts) {
      std::set<int> placed;
      for (const auto& [span, i] : at) {
        if (span->part < 0 || !placed.insert(span->part).second) continue;  // a part two hands hold: the first's
        const RobotIds& r = scene_.robots()[static_cast<std::size_t>(span->scene_robot)];
        Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();
        tcp.translation() = Eigen::Map<const Eigen::Vector3d>(d_->site_xpos + 3 * r.tcp_site);
        tcp.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d_->site_xmat + 9 * r.tcp_site);
        const Eigen::Isometry3d pose = tcp * span->grip;
        const Eigen::Quaterniond q(pose.linear());
        const int adr = scene_.workpieces()[static_cast<std::size_t>(span->part)].qpos_adr;
        const double v[7] = {
            pose.translation().x(), pose.translation().y(), pose.translation().z(), q.w(), q.x(), q.y(), q.z()};
        std::copy(v, v + 7, d_->qpos + adr);
      }
      mj_kinematics(m_, d_);
    }
    if (collide) mj_collision(m_, d_);
  }

  Sphere sphere(int g) const { return {Eigen::Map<const Eigen::Vector3d>(d_->geom_xpos + 3 * g), m_->geom_rbound[g]}; }
  Eigen::Matrix3d rotation(int g) const {
    return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d_->geom_xmat + 9 * g);
  }

 private:
  const Scene& scene_;
  const mjModel* m_;
  mjData* d_;
  std::vector<double> baseline_;
};

// Whether geom `g` is of the span's robot or of the part it carries.
bool of_span(const GeomInfo& g, const Span& sp) {
  return (g.owner == Owner::kRobot && g.index == sp.scene_robot) || (g.owner == Owner::kPart && g.index == sp.part);
}

// Calls f(mine, other, depth) for each contact of the posed scene deeper than `depth` with a side `mine` on `sp`.
template <typename F>
void each_deep_contact(const mjData* d, double depth, const std::vector<GeomInfo>& geoms, const Span& sp, F&& f) {
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if (con.dist >= -depth) continue;
    const GeomInfo* g1 = &geoms[static_cast<std::size_t>(con.geom1)];
    const GeomInfo* g2 = &geoms[static_cast<std::size_t>(con.geom2)];
    if (!of_span(*g1, sp)) std::swap(g1, g2);
    if (of_span(*g1, sp)) f(*g1, *g2, -con.dist);
  }
}

struct MarkingHash {
  std::size_t operator()(const petri::Marking& m) const {
    std::size_t h = 1469598103934665603ULL;
    for (auto t : m) h = (h ^ static_cast<std::size_t>(t)) * 1099511628211ULL;
    return h;
  }
};

}  // namespace

SweepReport sweep_motions(const Scenario& s, const petri::Net& net, const MotionPlan& plan,
                          const SweepOptions& options) {
  return sweep_motions(build_scene(s.cell), s, net, plan, options);
}

SweepReport sweep_motions(const Scene& scene, const Scenario& s, const petri::Net& net, const MotionPlan& plan,
                          const SweepOptions& options) {
  CW_CHECK(options.resolution > 0 && options.depth >= 0, "sweep resolution {} m, depth {} m", options.resolution,
           options.depth);
  SweepReport report;
  // Robots that overlap at the start: one error, rather than a collision for every command that starts there.
  if (const auto at_start = twin::start_overlaps(scene, options.depth); !at_start.empty()) {
    throw twin::start_overlap_error(at_start);
  }
  const mjModel* m = scene.model();
  std::vector<GeomInfo> geoms = classify(scene);
  Poser poser(scene);
  const std::size_t robots = s.program.robots.size();
  // A cell robot the program does not use stands at home all along: part of the static cell.
  for (GeomInfo& g : geoms) {
    if (g.owner != Owner::kRobot) continue;
    const std::string& name = scene.robots()[static_cast<std::size_t>(g.index)].name;
    const bool used = std::any_of(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.name == name; });
    if (used) continue;
    g.owner = Owner::kStatic;
    g.name = fmt::format("robot '{}' {} (not in the program: at home)", name, g.name);
    g.index = -1;
  }

  // The collision geoms of each scene robot.
  std::vector<std::vector<int>> robot_geoms(scene.robots().size());
  for (int g = 0; g < m->ngeom; ++g) {
    const GeomInfo& info = geoms[static_cast<std::size_t>(g)];
    if (info.owner == Owner::kRobot) robot_geoms[static_cast<std::size_t>(info.index)].push_back(g);
  }
  auto span_geoms = [&](const Span& sp) {
    std::vector<int> out = robot_geoms[static_cast<std::size_t>(sp.scene_robot)];
    if (sp.part >= 0) out.push_back(m->body_geomadr[scene.workpieces()[static_cast<std::size_t>(sp.part)].body]);
    return out;
  };

  // A contact of two bodies: the deepest pair names the collision, the others are listed.
  auto note = [](PredictedCollision& pc, const std::string& body_a, const std::string& body_b, double deep) {
    const std::string pair = fmt::format("{} / {}", body_a, body_b);
    if (deep > pc.depth) {
      pc.depth = deep;
      pc.a.body = body_a;
      pc.b.body = body_b;
    }
    if (std::find(pc.bodies.begin(), pc.bodies.end(), pair) == pc.bodies.end()) pc.bodies.push_back(pair);
  };

  // --- the spans of each robot: start, one per primitive, done ---
  std::vector<std::vector<Span>> spans(robots);
  for (std::size_t r = 0; r < robots; ++r) {
    const std::string& cell_robot = s.robot_of(s.program.robots[r]);
    const RobotIds* ids = scene.find_robot(cell_robot);
    CW_CHECK(ids != nullptr, "robot {} is not in the scene", cell_robot);
    const int scene_robot = static_cast<int>(ids - scene.robots().data());
    const double open = ids->finger_range[1];
    auto fingers_of = [&](const std::optional<double>& closed) {
      return closed ? std::clamp(*closed, ids->finger_range[0], ids->finger_range[1]) : open;
    };
    Eigen::VectorXd cur =
        Eigen::Map<const Eigen::VectorXd>(ids->home.data(), static_cast<Eigen::Index>(ids->home.size()));
    Span state;  // what stands still: where the last move left the arm, with its part and fingers
    state.robot = r;
    state.scene_robot = scene_robot;
    state.fingers = open;
    state.from = state.to = cur;
    auto at_rest = [&](std::string command, std::string source) {
      Span sp = state;
      sp.command = std::move(command);
      sp.source = std::move(source);
      sp.move = false;
      sp.from = sp.to = cur;
      sp.samples = 1;
      return sp;
    };
    spans[r].push_back(at_rest("before its first command", ""));
    const auto& commands = plan.commands[r];
    for (std::size_t k = 0; k < commands.size(); ++k) {
      const PlannedCommand& c = commands[k];
      if (c.kind == task::PrimitiveKind::kMove && !c.goal.empty()) {
        Span sp = state;
        sp.command = c.command;
        sp.source = c.source;
        sp.move = true;
        sp.from = Eigen::Map<const Eigen::VectorXd>(c.from.data(), static_cast<Eigen::Index>(c.from.size()));
        sp.to = Eigen::Map<const Eigen::VectorXd>(c.goal.data(), static_cast<Eigen::Index>(c.goal.size()));
        sp.part = -1;
        if (!c.held.empty()) {
          const WorkpieceIds* w = scene.find_workpiece(c.held);
          CW_CHECK(w != nullptr, "held workpiece {} not in the scene", c.held);
          sp.part = static_cast<int>(w - scene.workpieces().data());
        }
        sp.grip = c.grip;
        sp.fingers = fingers_of(c.closed);
        state.part = sp.part;
        state.grip = sp.grip;
        state.fingers = sp.fingers;
        cur = sp.to;
        spans[r].push_back(std::move(sp));
        continue;
      }
      spans[r].push_back(at_rest(c.command, c.source));
      if (c.kind == task::PrimitiveKind::kOpen) {
        state.part = -1;
        state.fingers = open;
      } else if (c.kind == task::PrimitiveKind::kClose) {
        // From now on the hand holds what the next move carries.
        state.part = -1;
        state.fingers = fingers_of(c.contact.value_or(0.0));
        for (std::size_t n = k + 1; n < commands.size(); ++n) {
          if (commands[n].kind != task::PrimitiveKind::kMove || commands[n].goal.empty()) continue;
          if (!commands[n].held.empty()) {
            state.part = static_cast<int>(scene.find_workpiece(commands[n].held) - scene.workpieces().data());
            state.grip = commands[n].grip;
          }
          break;
        }
      }
    }
    spans[r].push_back(at_rest("after its last command", ""));
  }

  // --- sample every span; sweep the moves against the static cell ---
  struct StaticKey {
    std::size_t robot, span;
    std::string other;
    bool operator<(const StaticKey& o) const {
      return std::tie(robot, span, other) < std::tie(o.robot, o.span, o.other);
    }
  };
  std::map<StaticKey, PredictedCollision> found_static;
  const double depth = options.depth;
  for (std::size_t r = 0; r < robots; ++r) {
    for (std::size_t k = 0; k < spans[r].size(); ++k) {
      Span& sp = spans[r][k];
      const std::vector<int> swept = span_geoms(sp);
      const bool sweep_static = sp.move || k == 0;
      if (sp.move) {
        ++report.motions;
        const double step = (sp.to - sp.from).cwiseAbs().maxCoeff();
        sp.samples = std::max<std::size_t>(2, static_cast<std::size_t>(std::ceil(step / 0.01)) + 1);
      }
      for (int attempt = 0;; ++attempt) {
        sp.spheres.assign(sp.samples, {});
        sp.box.assign(sp.samples, Eigen::AlignedBox3d());
        sp.all.setEmpty();
        std::map<StaticKey, PredictedCollision> hits;
        double worst_step = 0;
        std::vector<Eigen::Vector3d> prev_c;
        std::vector<Eigen::Matrix3d> prev_r;
        for (std::size_t i = 0; i < sp.samples; ++i) {
          poser.pose({{&sp, i}}, sweep_static);
          if (sweep_static) ++report.pose_checks;
          for (std::size_t gi = 0; gi < swept.size(); ++gi) {
            const Sphere sph = poser.sphere(swept[gi]);
            sp.spheres[i].push_back(sph);
            sp.box[i].extend(Eigen::AlignedBox3d(sph.centre - Eigen::Vector3d::Constant(sph.radius),
                                                 sph.centre + Eigen::Vector3d::Constant(sph.radius)));
            const Eigen::Matrix3d rot = poser.rotation(swept[gi]);
            if (i > 0) {
              const double angle = Eigen::Quaterniond(prev_r[gi]).angularDistance(Eigen::Quaterniond(rot));
              worst_step = std::max(worst_step, (sph.centre - prev_c[gi]).norm() + sph.radius * angle);
              prev_c[gi] = sph.centre;
              prev_r[gi] = rot;
            } else {
              prev_c.push_back(sph.centre);
              prev_r.push_back(rot);
            }
          }
          sp.all.extend(sp.box[i]);
          if (!sweep_static) continue;
          each_deep_contact(poser.data(), depth, geoms, sp,
                            [&](const GeomInfo& mine, const GeomInfo& other, double deep) {
                              if (other.owner != Owner::kStatic || other.mount_of == sp.scene_robot)
                                return;  // (its own pedestal)
                              PredictedCollision& pc = hits[{r, k, other.name}];
                              if (pc.a.robot.empty()) {
                                pc.a = {scene.robots()[static_cast<std::size_t>(sp.scene_robot)].name,
                                        mine.name,
                                        sp.command,
                                        sp.source,
                                        i,
                                        sp.samples};
                                pc.b = {"", other.name, "", "", 0, 1};
                              }
                              note(pc, mine.name, other.name, deep);
                            });
        }
        if (worst_step <= options.resolution || attempt >= 4) {
          found_static.insert(hits.begin(), hits.end());
          if (sweep_static) report.samples += sp.samples;
          break;
        }
        sp.samples = static_cast<std::size_t>(
                         std::ceil(static_cast<double>(sp.samples - 1) * worst_step / options.resolution * 1.1)) +
                     1;
      }
    }
  }
  for (auto& [key, pc] : found_static) report.collisions.push_back(std::move(pc));

  // --- which places of two robots the net marks together ---
  std::vector<std::vector<petri::PlaceId>> places(robots);
  for (std::size_t r = 0; r < robots; ++r) {
    const std::string& label = s.program.robots[r];
    auto id = [&](const std::string& pid) {
      auto p = net.find_place(pid);
      CW_CHECK(p.has_value(), "no place {} in the program's net", pid);
      return *p;
    };
    places[r].push_back(id(task::start_place_id(label)));
    for (std::size_t k = 0; k < plan.commands[r].size(); ++k) places[r].push_back(id(task::place_id(label, k)));
    places[r].push_back(id(task::done_place_id(label)));
  }
  std::set<std::tuple<std::size_t, std::size_t, std::size_t, std::size_t>> together;  // (r, span, s, span), r < s
  {
    std::unordered_set<petri::Marking, MarkingHash> seen;
    std::deque<petri::Marking> queue;
    queue.push_back(net.initial_marking());
    seen.insert(queue.front());
    std::vector<std::size_t> where(robots);
    while (!queue.empty() && seen.size() <= options.max_states) {
      const petri::Marking mk = std::move(queue.front());
      queue.pop_front();
      for (std::size_t r = 0; r < robots; ++r) {
        where[r] = places[r].size();
        for (std::size_t k = 0; k < places[r].size(); ++k) {
          if (mk[places[r][k]] > 0) where[r] = k;
        }
        CW_CHECK(where[r] < places[r].size(), "robot {} has no marked place", s.program.robots[r]);
      }
      for (std::size_t r = 0; r < robots; ++r) {
        for (std::size_t q = r + 1; q < robots; ++q) together.insert({r, where[r], q, where[q]});
      }
      for (petri::TransitionId t : petri::enabled(net, mk)) {
        petri::Marking next = petri::fire(net, mk, t);
        if (seen.insert(next).second) queue.push_back(std::move(next));
      }
    }
    report.states = seen.size();
    report.exhaustive = queue.empty();
  }
  if (report.exhaustive) {
    report.concurrency = fmt::format(
        "the net's {} reachable markings: commands of two robots marked in one of them are swept "
        "against each other",
        report.states);
  } else {
    together.clear();
    for (std::size_t r = 0; r < robots; ++r) {
      for (std::size_t q = r + 1; q < robots; ++q) {
        for (std::size_t a = 0; a < spans[r].size(); ++a) {
          for (std::size_t b = 0; b < spans[q].size(); ++b) together.insert({r, a, q, b});
        }
      }
    }
    report.concurrency = fmt::format(
        "the net has more than {} reachable markings: every command of a robot is swept against every command of "
        "each other robot",
        options.max_states);
  }

  // --- concurrent spans of two robots, every pose against every pose ---
  std::map<std::tuple<std::size_t, std::size_t, std::size_t, std::size_t>, PredictedCollision> found_pairs;
  auto overlap = [](const std::vector<Sphere>& x, const std::vector<Sphere>& y) {
    for (const Sphere& p : x) {
      for (const Sphere& q : y) {
        const double reach = p.radius + q.radius;
        if ((p.centre - q.centre).squaredNorm() < reach * reach) return true;
      }
    }
    return false;
  };
  for (const auto& pair : together) {
    // Named copies, not structured bindings: clang before 16 (Debian 12's 14, used for the fuzz build) does not let a
    // lambda capture a structured binding.
    const auto [r, a, q, b] = pair;
    const auto key = pair;
    const Span& sa = spans[r][a];
    const Span& sb = spans[q][b];
    ++report.pairs;
    if (!sa.all.intersects(sb.all)) continue;
    const bool shared = sa.part >= 0 && sa.part == sb.part;  // both hands on one part (a hand-over)
    for (std::size_t i = 0; i < sa.samples; ++i) {
      if (!sa.box[i].intersects(sb.all)) continue;
      for (std::size_t j = 0; j < sb.samples; ++j) {
        if (!sa.box[i].intersects(sb.box[j]) || !overlap(sa.spheres[i], sb.spheres[j])) continue;
        poser.pose({{&sa, i}, {&sb, j}}, true);
        ++report.pose_checks;
        each_deep_contact(poser.data(), depth, geoms, sa,
                          [&](const GeomInfo& mine, const GeomInfo& other, double deep) {
                            if (!of_span(other, sb)) return;
                            if (shared && (mine.owner == Owner::kPart || other.owner == Owner::kPart))
                              return;  // both hands grip it
                            PredictedCollision& pc = found_pairs[key];
                            if (pc.a.robot.empty()) {
                              pc.a = {scene.robots()[static_cast<std::size_t>(sa.scene_robot)].name,
                                      mine.name,
                                      sa.command,
                                      sa.source,
                                      i,
                                      sa.samples};
                              pc.b = {scene.robots()[static_cast<std::size_t>(sb.scene_robot)].name,
                                      other.name,
                                      sb.command,
                                      sb.source,
                                      j,
                                      sb.samples};
                            }
                            note(pc, mine.name, other.name, deep);
                          });
      }
    }
  }
  for (auto& [key, pc] : found_pairs) report.collisions.push_back(std::move(pc));
  return report;
}

std::shared_ptr<const TwinModel> SimulatedTwin::compile(const Scenario& scenario) const {
  return std::make_shared<const TwinModel>(TwinModel{compile_cell(scenario)});
}

SweepReport SimulatedTwin::sweep(const TwinModel& model, const Scenario& scenario, const petri::Net& net,
                                 const MotionPlan& plan, const SweepOptions& options) const {
  return sweep_motions(model.scene, scenario, net, plan, options);
}

Estimate SimulatedTwin::estimate(const Scenario& scenario, const Preflight& preflight) const {
  CW_CHECK(preflight.plan.has_value(), "an estimate of a program the preflight did not plan");
  const std::shared_ptr<const TwinModel> model = preflight.twin != nullptr ? preflight.twin : compile(scenario);
  // The speed of a run's moves: ScenarioRun leaves the runtime's default.
  return estimate_cycle_time(scenario, preflight.net, *preflight.plan,
                             twin_estimate_options(scenario, model->scene, runtime::MotionOptions{}.speed));
}

const TwinPort& twin_port() {
  static const SimulatedTwin twin;
  return twin;
}

}  // namespace cellwright::cell
