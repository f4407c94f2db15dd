// Collisions found before the run, in the twin's scene (cell/sim/sweep.hpp).
#include "cellwright/cell/sim/sweep.hpp"

#include "cellwright/cell/sim/run.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <deque>
#include <iterator>
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

std::vector<GeomInfo> classify(const Scene& scene) {
  using Kind = twin::GeomRole::Kind;
  std::vector<GeomInfo> out(static_cast<std::size_t>(scene.model()->ngeom));
  for (int g = 0; g < scene.model()->ngeom; ++g) {
    const twin::GeomRole role = twin::geom_role(scene, g);
    GeomInfo& info = out[static_cast<std::size_t>(g)];
    info.index = role.index;
    info.mount_of = role.mount_of;
    info.name = role.name;
    switch (role.kind) {
      case Kind::none:
      case Kind::belt:  // it carries parts; robots meet its frame
      case Kind::obstacle:
        info.owner = Owner::kIgnored;
        break;
      case Kind::fixed:
        info.owner = Owner::kStatic;
        break;
      case Kind::robot:
        info.owner = Owner::kRobot;
        break;
      case Kind::workpiece:
        info.owner = Owner::kPart;
        info.name += " (carried)";
        break;
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
  // Its geoms that contacts are counted on (of_span: the robot's collision geoms and its part's), and per sample where
  // MuJoCo's kinematics put them (geom_xpos, geom_xmat, sample after sample): the contacts are found on these.
  std::vector<int> touch;
  std::vector<mjtNum> xpos, xmat;

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

  // Poses the span's robot at sample i (everything else as at the start, parts parked, its part in its hand): MuJoCo's
  // kinematics, no collision detection.
  void pose(const Span& span, std::size_t i) {
    std::copy(baseline_.begin(), baseline_.end(), d_->qpos);
    const RobotIds& r = scene_.robots()[static_cast<std::size_t>(span.scene_robot)];
    const Eigen::VectorXd q = span.at(i);
    for (std::size_t j = 0; j < r.qpos_adr.size(); ++j) d_->qpos[r.qpos_adr[j]] = q[static_cast<Eigen::Index>(j)];
    for (int f = 0; f < 2; ++f) d_->qpos[r.finger_qpos_adr[static_cast<std::size_t>(f)]] = span.fingers;
    mj_kinematics(m_, d_);
    if (span.part >= 0) {
      Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();
      tcp.translation() = Eigen::Map<const Eigen::Vector3d>(d_->site_xpos + 3 * r.tcp_site);
      tcp.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d_->site_xmat + 9 * r.tcp_site);
      const Eigen::Isometry3d pose = tcp * span.grip;
      const Eigen::Quaterniond rot(pose.linear());
      const double v[7] = {
          pose.translation().x(), pose.translation().y(), pose.translation().z(), rot.w(), rot.x(), rot.y(), rot.z()};
      twin::place_free_body(m_, d_, scene_.workpieces()[static_cast<std::size_t>(span.part)].body, v);
    }
  }

  // Keeps where the last pose() put the span's `touch` geoms as its sample i.
  void record(Span& span, std::size_t i) const {
    const std::size_t n = span.touch.size();
    for (std::size_t k = 0; k < n; ++k) {
      const int g = span.touch[k];
      std::copy(d_->geom_xpos + 3 * g, d_->geom_xpos + 3 * g + 3, span.xpos.begin() + 3 * (i * n + k));
      std::copy(d_->geom_xmat + 9 * g, d_->geom_xmat + 9 * g + 9, span.xmat.begin() + 9 * (i * n + k));
    }
  }

  // Puts the span's `touch` geoms where its sample i had them, the other geoms staying where the last pose() left
  // them (the static cell's never move): the data for the narrow phase (Contacts).
  void place(const Span& span, std::size_t i) {
    const std::size_t n = span.touch.size();
    for (std::size_t k = 0; k < n; ++k) {
      const int g = span.touch[k];
      std::copy_n(span.xpos.begin() + 3 * (i * n + k), 3, d_->geom_xpos + 3 * g);
      std::copy_n(span.xmat.begin() + 9 * (i * n + k), 9, d_->geom_xmat + 9 * g);
    }
  }

  mjData* data() { return d_; }

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

// Calls f(mine, other, depth) if the contact of geoms g1 and g2 at distance `dist` is deeper than `depth` and has a side
// `mine` on `sp`.
template <typename F>
void if_deep(int g1, int g2, mjtNum dist, double depth, const std::vector<GeomInfo>& geoms, const Span& sp, F&& f) {
  if (dist >= -depth) return;
  const GeomInfo* a = &geoms[static_cast<std::size_t>(g1)];
  const GeomInfo* b = &geoms[static_cast<std::size_t>(g2)];
  if (!of_span(*a, sp)) std::swap(a, b);
  if (of_span(*a, sp)) f(*a, *b, -dist);
}

// MuJoCo's collision detection (mj_collision) on chosen pairs of geoms only: the pairs it would test (its filters that
// depend on the model alone, made once: contype/conaffinity, same or parent weld body, <exclude>d body pairs, no
// collision function), tested as mj_collideGeoms tests them (its bounding-sphere and plane filters, the pair's
// collision function with the larger margin, box-box duplicates dropped), in the order mj_collision gives its
// contacts (body pairs by id, then the lower body's geoms, then the higher's). The contacts of these pairs are
// therefore mj_collision's, bit for bit (same geom poses, same functions, same order); what it is spared is every
// other pair of the scene (the static cell against itself, the robots at home, the parked parts) and the broad phase.
// Two differences, neither in a pose the shipped cells reach: mj_collision keeps at most the scene's nconmax
// contacts in all (these pairs alone are never cut short), and its broad phase (boxes in float) might drop a pair
// that only grazes, never one deeper than a sweep's depth.
class Contacts {
 public:
  struct Pair {
    int g1 = -1, g2 = -1;  // ordered by geom type, as mj_collideGeoms orders them
    mjtNum margin = 0;
    mjfCollision test = nullptr;
    std::uint64_t order = 0;  // mj_collision's: body pair, then geom pair
  };

  explicit Contacts(const mjModel* m) : m_(m) {
    CW_CHECK(m->npair == 0, "the sweep does not model explicit contact pairs (the scene has {})", m->npair);
    enabled_ = !(m->opt.disableflags & (mjDSBL_CONSTRAINT | mjDSBL_CONTACT)) && m->nconmax > 0 && m->nbody >= 2 &&
               m->opt.collision != mjCOL_PAIR;
    excluded_.assign(m->exclude_signature, m->exclude_signature + m->nexclude);
    std::sort(excluded_.begin(), excluded_.end());
  }

  // The pairs of a geom of `a` and a geom of `b` (distinct) that mj_collision tests, in its order.
  std::vector<Pair> pairs(const std::vector<int>& a, const std::vector<int>& b) const {
    std::vector<Pair> out;
    if (!enabled_) return out;
    const int* bodyid = m_->geom_bodyid;
    for (int x : a) {
      for (int y : b) {
        if (x == y) continue;
        int lo = x, hi = y;  // mj_collision's order: the geom of the lower body first
        if (bodyid[lo] > bodyid[hi]) std::swap(lo, hi);
        const int b1 = bodyid[lo], b2 = bodyid[hi];
        if (b1 == b2) continue;  // one body: mj_collision never pairs it with itself
        const int signature = ((b1 + 1) << 16) + (b2 + 1);
        if (std::binary_search(excluded_.begin(), excluded_.end(), signature)) continue;
        Pair p;
        p.g1 = lo;
        p.g2 = hi;
        if (m_->geom_type[p.g1] > m_->geom_type[p.g2]) std::swap(p.g1, p.g2);
        p.test = mjCOLLISIONFUNC[m_->geom_type[p.g1]][m_->geom_type[p.g2]];
        if (p.test == nullptr) continue;
        if (mjcb_contactfilter == nullptr && filtered(p.g1, p.g2)) continue;
        p.margin = std::max(m_->geom_margin[p.g1], m_->geom_margin[p.g2]);
        if (m_->opt.enableflags & mjENBL_OVERRIDE) p.margin = m_->opt.o_margin;
        p.order = (static_cast<std::uint64_t>(signature) << 32) |
                  (static_cast<std::uint64_t>(lo - m_->body_geomadr[b1]) << 16) |
                  static_cast<std::uint64_t>(hi - m_->body_geomadr[b2]);
        out.push_back(p);
      }
    }
    std::sort(out.begin(), out.end(), [](const Pair& p, const Pair& q) { return p.order < q.order; });
    out.erase(std::unique(out.begin(), out.end(), [](const Pair& p, const Pair& q) { return p.order == q.order; }),
              out.end());
    return out;
  }

  // Tests the pairs on `d`'s geom poses and calls f(geom1, geom2, dist) for each contact, in mj_collision's order.
  template <typename F>
  void collide(mjData* d, const std::vector<Pair>& pairs, F&& f) const {
    mjContact con[mjMAXCONPAIR];
    for (const Pair& p : pairs) {
      const int g1 = p.g1, g2 = p.g2;
      if (mjcb_contactfilter != nullptr && mjcb_contactfilter(m_, d, g1, g2)) continue;
      const mjtNum r1 = m_->geom_rbound[g1], r2 = m_->geom_rbound[g2];
      if (r1 > 0 && r2 > 0 && mju_dist3(d->geom_xpos + 3 * g1, d->geom_xpos + 3 * g2) > r1 + r2 + p.margin) continue;
      if (m_->geom_type[g1] == mjGEOM_PLANE && r2 > 0 && above_plane(d, g1, g2) > p.margin + r2) continue;
      if (m_->geom_type[g2] == mjGEOM_PLANE && r1 > 0 && above_plane(d, g2, g1) > p.margin + r1) continue;
      int n = p.test(m_, d, con, g1, g2, p.margin);
      CW_CHECK(n <= mjMAXCONPAIR, "{} contacts from one pair of geoms", n);
      if (m_->geom_type[g1] == mjGEOM_BOX && m_->geom_type[g2] == mjGEOM_BOX) n = drop_repeated(con, n);
      for (int c = 0; c < n; ++c) f(g1, g2, con[c].dist);
    }
  }

 private:
  // mj_contactFilter's tests, with its arguments as mj_collideGeoms gives them.
  bool filtered(int g1, int g2) const {
    const int w1 = m_->body_weldid[m_->geom_bodyid[g1]], w2 = m_->body_weldid[m_->geom_bodyid[g2]];
    if (!(m_->geom_contype[g1] & m_->geom_conaffinity[g2]) && !(m_->geom_contype[g2] & m_->geom_conaffinity[g1])) {
      return true;
    }
    if (w1 == w2) return true;
    const bool parent = !(m_->opt.disableflags & mjDSBL_FILTERPARENT) && w1 != 0 && w2 != 0;
    return parent && (w1 == m_->body_weldid[m_->body_parentid[w2]] || w2 == m_->body_weldid[m_->body_parentid[w1]]);
  }
  // How far geom g's centre is above plane geom `plane`, as mj_collideGeoms measures it.
  static mjtNum above_plane(const mjData* d, int plane, int g) {
    const mjtNum* mat = d->geom_xmat + 9 * plane;
    const mjtNum normal[3] = {mat[2], mat[5], mat[8]};
    mjtNum dif[3];
    mju_sub3(dif, d->geom_xpos + 3 * g, d->geom_xpos + 3 * plane);
    return mju_dot3(dif, normal);
  }
  // Box-box contacts at one point: the later kept, as mj_collideGeoms keeps them.
  static int drop_repeated(mjContact* con, int n) {
    bool bad[mjMAXCONPAIR] = {};
    for (int i = 0; i + 1 < n; ++i) {
      for (int j = i + 1; j < n; ++j) {
        if (con[i].pos[0] == con[j].pos[0] && con[i].pos[1] == con[j].pos[1] && con[i].pos[2] == con[j].pos[2]) {
          bad[i] = true;
          break;
        }
      }
    }
    int kept = 0;
    for (int j = 0; j < n; ++j) {
      if (bad[j]) continue;
      if (kept < j) con[kept] = con[j];
      ++kept;
    }
    return kept;
  }

  const mjModel* m_;
  bool enabled_ = true;
  std::vector<int> excluded_;
};

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

  // The pairs of geoms whose contacts count (MuJoCo's narrow phase on these only, Contacts), made once per robot and
  // part carried: a span's against the static cell but its robot's pedestal, and two spans' against each other (with
  // a part both hold left out: both grip it).
  const Contacts contacts(m);
  std::vector<int> fixed;
  for (int g = 0; g < m->ngeom; ++g) {
    if (geoms[static_cast<std::size_t>(g)].owner == Owner::kStatic) fixed.push_back(g);
  }
  std::map<std::pair<int, int>, std::vector<Contacts::Pair>> static_cache;
  auto static_pairs = [&](const Span& sp) -> const std::vector<Contacts::Pair>& {
    auto [it, made] = static_cache.try_emplace({sp.scene_robot, sp.part});
    if (made) {
      std::vector<int> others;
      for (int g : fixed) {
        if (geoms[static_cast<std::size_t>(g)].mount_of != sp.scene_robot) others.push_back(g);
      }
      it->second = contacts.pairs(sp.touch, others);
    }
    return it->second;
  };
  std::map<std::tuple<int, int, int, int>, std::vector<Contacts::Pair>> pair_cache;
  auto pair_pairs = [&](const Span& sa, const Span& sb, bool shared) -> const std::vector<Contacts::Pair>& {
    auto [it, made] = pair_cache.try_emplace({sa.scene_robot, sa.part, sb.scene_robot, sb.part});
    if (made) {
      auto gripped = [&](int g) { return shared && geoms[static_cast<std::size_t>(g)].owner == Owner::kPart; };
      std::vector<int> x, y;
      std::copy_if(sa.touch.begin(), sa.touch.end(), std::back_inserter(x), [&](int g) { return !gripped(g); });
      std::copy_if(sb.touch.begin(), sb.touch.end(), std::back_inserter(y), [&](int g) { return !gripped(g); });
      it->second = contacts.pairs(x, y);
    }
    return it->second;
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
      sp.touch.clear();
      for (int g = 0; g < m->ngeom; ++g) {
        if (of_span(geoms[static_cast<std::size_t>(g)], sp)) sp.touch.push_back(g);
      }
      // Sample; refine the sampling until no point moves more than the resolution between two samples. Only the
      // kinematics: the contacts are looked for on the samples kept.
      for (int attempt = 0;; ++attempt) {
        sp.spheres.assign(sp.samples, {});
        sp.box.assign(sp.samples, Eigen::AlignedBox3d());
        sp.all.setEmpty();
        sp.xpos.assign(3 * sp.samples * sp.touch.size(), 0);
        sp.xmat.assign(9 * sp.samples * sp.touch.size(), 0);
        double worst_step = 0;
        std::vector<Eigen::Vector3d> prev_c;
        std::vector<Eigen::Matrix3d> prev_r;
        for (std::size_t i = 0; i < sp.samples; ++i) {
          poser.pose(sp, i);
          poser.record(sp, i);
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
        }
        if (worst_step <= options.resolution || attempt >= 4) break;
        sp.samples = static_cast<std::size_t>(
                         std::ceil(static_cast<double>(sp.samples - 1) * worst_step / options.resolution * 1.1)) +
                     1;
      }
      if (!sweep_static) continue;
      // Each sample against the static cell but the robot's own pedestal (its mount).
      const std::vector<Contacts::Pair>& against = static_pairs(sp);
      for (std::size_t i = 0; i < sp.samples; ++i) {
        poser.place(sp, i);
        ++report.pose_checks;
        contacts.collide(poser.data(), against, [&](int g1, int g2, mjtNum dist) {
          if_deep(g1, g2, dist, depth, geoms, sp, [&](const GeomInfo& mine, const GeomInfo& other, double deep) {
            if (other.owner != Owner::kStatic || other.mount_of == sp.scene_robot) return;  // (its own pedestal)
            PredictedCollision& pc = found_static[{r, k, other.name}];
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
        });
      }
      report.samples += sp.samples;
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
    const std::vector<Contacts::Pair>& between = pair_pairs(sa, sb, shared);
    for (std::size_t i = 0; i < sa.samples; ++i) {
      if (!sa.box[i].intersects(sb.all)) continue;
      for (std::size_t j = 0; j < sb.samples; ++j) {
        if (!sa.box[i].intersects(sb.box[j]) || !overlap(sa.spheres[i], sb.spheres[j])) continue;
        poser.place(sa, i);
        poser.place(sb, j);
        ++report.pose_checks;
        contacts.collide(poser.data(), between, [&](int g1, int g2, mjtNum dist) {
          if_deep(g1, g2, dist, depth, geoms, sa, [&](const GeomInfo& mine, const GeomInfo& other, double deep) {
            if (!of_span(other, sb)) return;
            if (shared && (mine.owner == Owner::kPart || other.owner == Owner::kPart)) return;  // both hands grip it
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
