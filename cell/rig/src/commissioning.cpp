// Commissioning a real controller's conventions: the bring-up cross-check and the suggested settings
// (commissioning.hpp).
#include "cellwright/cell/commissioning.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <numbers>

#include "cellwright/cell/real_drivers.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/val2/val2_driver.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::cell {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Each frame is fitted as its origin and the points this far along its axes (m): a degree off is 1.7 mm there.
constexpr double kLever = 0.1;
// Fits whose residuals differ by less than this (mm) fit alike: the smaller world rotation decides.
constexpr double kAlike = 1.0;

// A number of a setting: at most two decimals, no "-0".
std::string num(double v) {
  const double r = std::round(v * 100.0) / 100.0;
  return fmt::format("{:g}", r == 0 ? 0.0 : r);
}

std::string triple(const Eigen::Vector3d& v) {
  return fmt::format("[{}, {}, {}]", num(v.x()), num(v.y()), num(v.z()));
}

// [roll, pitch, yaw] degrees of `r` = Rz(yaw)·Ry(pitch)·Rx(roll), the cell description's rpy.
Eigen::Vector3d rpy_degrees(const Eigen::Matrix3d& r) {
  const Eigen::Vector3d ypr = r.eulerAngles(2, 1, 0);
  Eigen::Vector3d rpy(ypr[2], ypr[1], ypr[0]);
  // eulerAngles keeps the first angle in [0, π]: the equivalent set with the smallest angles reads best.
  const Eigen::Vector3d other(rpy[0] + std::numbers::pi, std::numbers::pi - rpy[1], rpy[2] + std::numbers::pi);
  const auto wrap = [](double a) { return std::remainder(a, 2 * std::numbers::pi); };
  Eigen::Vector3d a(wrap(rpy[0]), wrap(rpy[1]), wrap(rpy[2]));
  Eigen::Vector3d b(wrap(other[0]), wrap(other[1]), wrap(other[2]));
  return (b.cwiseAbs().sum() < a.cwiseAbs().sum() ? b : a) / kDeg;
}

std::vector<double> joints_of(const models::RobotSpec& robot, const ReadBack& r) {
  return r.reading.joints.empty() ? robot.home : r.reading.joints;
}

Eigen::Isometry3d forward(const models::KinematicChain& chain, const std::vector<double>& q) {
  return chain.forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
}

// One way of reading the controller's numbers.
struct Reading {
  std::optional<drivers::val2::Orientation> orientation;  // VAL II
  double pitch_down = -90;                                // Movemaster
  int roll_sense = 1;
};

std::vector<Reading> readings_of(models::DriverKind kind) {
  if (kind == models::DriverKind::kVal2) {
    return {{drivers::val2::Orientation::tool_down, -90, 1},
            {drivers::val2::Orientation::zyz, -90, 1},
            {drivers::val2::Orientation::val, -90, 1}};
  }
  return {{std::nullopt, -90, 1}, {std::nullopt, 90, 1}, {std::nullopt, -90, -1}, {std::nullopt, 90, -1}};
}

// The controller's tool frame in its world, as `reading` reads the raw numbers; nullopt without raw numbers.
std::optional<Eigen::Isometry3d> controller_frame(const ReadBack& r, const Reading& reading) {
  if (const auto* l = std::get_if<drivers::val2::Location>(&r.raw)) {
    return drivers::val2::to_pose(*l, reading.orientation.value_or(drivers::val2::Orientation::tool_down));
  }
  if (const auto* v = std::get_if<drivers::movemaster::Xyzpr>(&r.raw)) {
    return drivers::movemaster::to_pose(drivers::movemaster::with_angle_reading(*v, reading.pitch_down,
                                                                                reading.roll_sense));
  }
  return std::nullopt;
}

void add_frame_points(const Eigen::Isometry3d& f, std::vector<Eigen::Vector3d>& points) {
  points.push_back(f.translation());
  for (int k = 0; k < 3; ++k) points.push_back(f.translation() + kLever * f.linear().col(k));
}

struct Fit {
  Reading reading;
  Eigen::Isometry3d world = Eigen::Isometry3d::Identity();
  double residual_mm = 0;
  double turn_deg = 0;  // the world frame's rotation
};

const models::ControllerFrames& frames_of(const models::RobotSpec& robot, models::DriverKind kind) {
  return kind == models::DriverKind::kVal2 ? robot.val2.frames : robot.movemaster.frames;
}

}  // namespace

ReadBack read_back_of(const drivers::SerialDriver& driver) {
  ReadBack r;
  if (const auto p = driver.last_position()) r.reading = *p;
  if (const auto* v = dynamic_cast<const drivers::Val2Driver*>(&driver)) {
    if (const auto l = v->last_location()) r.raw = *l;
  } else if (const auto* m = dynamic_cast<const drivers::MovemasterDriver*>(&driver)) {
    if (const auto w = m->last_wh()) r.raw = *w;
  }
  return r;
}

Suggestion suggest_settings(const models::RobotSpec& robot, models::DriverKind kind,
                            const std::vector<ReadBack>& samples) {
  Suggestion s;
  const models::KinematicChain chain = models::robot_chain(robot);
  const Eigen::Isometry3d tool = frames_of(robot, kind).tool;
  std::optional<Fit> best;
  for (const Reading& reading : readings_of(kind)) {
    std::vector<Eigen::Vector3d> from, to;
    for (const ReadBack& r : samples) {
      const std::optional<Eigen::Isometry3d> c = controller_frame(r, reading);
      if (!c) continue;
      add_frame_points(*c, from);
      add_frame_points(forward(chain, joints_of(robot, r)) * tool, to);
    }
    if (from.empty()) return s;
    Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(from.size())), dst(3, static_cast<Eigen::Index>(to.size()));
    for (std::size_t i = 0; i < from.size(); ++i) {
      src.col(static_cast<Eigen::Index>(i)) = from[i];
      dst.col(static_cast<Eigen::Index>(i)) = to[i];
    }
    Fit fit;
    fit.reading = reading;
    fit.world.matrix() = Eigen::umeyama(src, dst, false);
    for (Eigen::Index i = 0; i < src.cols(); ++i) {
      fit.residual_mm = std::max(fit.residual_mm, (fit.world * Eigen::Vector3d(src.col(i)) - dst.col(i)).norm() * 1e3);
    }
    fit.turn_deg = Eigen::AngleAxisd(fit.world.linear()).angle() / kDeg;
    const bool better = !best || fit.residual_mm < best->residual_mm - kAlike ||
                        (fit.residual_mm < best->residual_mm + kAlike && fit.turn_deg < best->turn_deg);
    if (better) best = fit;
  }
  if (!best) return s;
  s.residual_mm = best->residual_mm;
  std::vector<std::string> keys;
  if (kind == models::DriverKind::kVal2) {
    const char* names[] = {"tool_down", "zyz", "val"};
    keys.push_back(fmt::format("orientation: {}", names[static_cast<int>(*best->reading.orientation)]));
  } else {
    if (best->reading.pitch_down > 0) keys.emplace_back("pitch_down: 90");
    if (best->reading.roll_sense < 0) keys.emplace_back("roll: left_hand");
  }
  keys.push_back(fmt::format("world_offset: {}", triple(best->world.translation() * 1e3)));
  if (best->turn_deg > 0.01) keys.push_back(fmt::format("world_rotation: {}", triple(rpy_degrees(best->world.linear()))));
  if (!tool.matrix().isIdentity(0)) {
    keys.push_back(fmt::format("tool_offset: {}", triple(tool.translation() * 1e3)));
    keys.push_back(fmt::format("tool_rotation: {}", triple(rpy_degrees(tool.linear()))));
  }
  std::string joined;
  for (const std::string& k : keys) joined += fmt::format("{}{}", joined.empty() ? "" : ", ", k);
  s.yaml = fmt::format("{}: {{{}}}", kind == models::DriverKind::kVal2 ? "val2" : "movemaster", joined);
  if (samples.size() < 2) {
    s.limitations = "one reading cannot tell a tool offset from a world offset: the tool transform was kept as set";
  }
  return s;
}

CrossCheck cross_check(const models::RobotSpec& robot, models::DriverKind kind, const ReadBack& home) {
  CrossCheck c;
  const models::KinematicChain chain = models::robot_chain(robot);
  const std::vector<double>& q = home.reading.joints;
  const std::string entry = kind == models::DriverKind::kVal2 ? "val2" : "movemaster";
  const auto degrees = [](const std::vector<double>& v) {
    std::string s;
    for (const double x : v) s += fmt::format("{}{}", s.empty() ? "" : ", ", num(x / kDeg));
    return "[" + s + "]";
  };
  if (!q.empty() && q.size() != robot.home.size()) {
    c.problems.push_back(fmt::format("the controller reads {} joints, and the cell's home has {}", q.size(),
                                     robot.home.size()));
    return c;
  }
  if (!q.empty()) {
    std::size_t worst = 0;
    double off = 0.0;
    for (std::size_t j = 0; j < q.size(); ++j) {
      if (std::abs(q[j] - robot.home[j]) > off) {
        off = std::abs(q[j] - robot.home[j]);
        worst = j;
      }
    }
    if (off / kDeg > kJointTolerance) {
      c.problems.push_back(fmt::format(
          "after homing the controller reads joints {} deg, and the cell's home is {} deg (joint {} is {} deg off, "
          "more than {} deg): its READY is not the cell's home, or it counts its joints otherwise; set the robot's "
          "home: to the controller's READY",
          degrees(q), degrees(robot.home), worst + 1, num(off / kDeg), num(kJointTolerance)));
    }
  } else {
    c.notes.push_back(fmt::format("the controller reads no joints: its pose was compared with the kinematics of the "
                                  "cell's home {} deg, so a {} that is not the home shows as a pose difference too",
                                  degrees(robot.home), kind == models::DriverKind::kVal2 ? "READY" : "nest (NT)"));
  }
  if (!home.reading.tool_pose) {
    c.notes.emplace_back("the controller reads no pose: its frames could not be checked");
    return c;
  }
  const std::vector<double> joints = joints_of(robot, home);
  if (joints.size() != chain.dof()) {
    c.problems.push_back(fmt::format("the controller reads {} joints and the robot has {}", joints.size(), chain.dof()));
    return c;
  }
  const Eigen::Isometry3d expected = forward(chain, joints);
  const Eigen::Isometry3d& read = *home.reading.tool_pose;
  const Eigen::Vector3d offset = (read.translation() - expected.translation()) * 1e3;
  const Eigen::AngleAxisd turn(read.linear() * expected.linear().transpose());
  if (offset.norm() <= kPositionTolerance && turn.angle() / kDeg <= kRotationTolerance) return c;
  std::string fix;
  const Suggestion s = suggest_settings(robot, kind, {home});
  if (!s.yaml.empty()) {
    fix = fmt::format("; set {} in the robot's cell entry ({} mm left over)", s.yaml, num(s.residual_mm));
  }
  c.problems.push_back(fmt::format(
      "the pose the controller reads back is {} mm (offset {} mm in the base frame) and {} deg (about the axis {}) "
      "from the project's kinematics of {} (tolerances {} mm, {} deg): the controller's world frame, tool point or "
      "orientation reading is not what the robot's {}: entry says{} (docs/real-robots.md, \"Commissioning\"; "
      "`twin commission` proposes the settings)",
      num(offset.norm()), triple(offset), num(turn.angle() / kDeg), triple(turn.axis()),
      q.empty() ? "the cell's home joints" : "the joints it reads back", num(kPositionTolerance),
      num(kRotationTolerance), entry, fix));
  return c;
}

drivers::CommandStatus wait_for_command(drivers::RobotDriver& driver, drivers::CommandId id,
                                        std::chrono::nanoseconds timeout) {
  std::mutex mutex;
  std::condition_variable cv;
  std::uint64_t events = 0;
  driver.set_notifier([&] {
    {
      std::lock_guard lock(mutex);
      ++events;
    }
    cv.notify_all();
  });
  const auto until = std::chrono::steady_clock::now() + timeout;
  drivers::CommandStatus st;
  for (;;) {
    std::uint64_t seen = 0;
    {
      std::lock_guard lock(mutex);
      seen = events;
    }
    st = driver.poll(id);
    if (st.phase == drivers::CommandPhase::done || st.phase == drivers::CommandPhase::failed) break;
    std::unique_lock lock(mutex);
    if (!cv.wait_until(lock, until, [&] { return events != seen; })) {
      st.message = "no answer in time";
      break;
    }
  }
  driver.set_notifier({});
  return st;
}

namespace {

std::string failed(const char* step, const drivers::CommandStatus& st) {
  return fmt::format("{} did not finish: {} {}", step, drivers::to_string(st.phase),
                     st.phase == drivers::CommandPhase::failed
                         ? fmt::format("({}: {})", drivers::to_string(st.error), st.message)
                         : st.message);
}

}  // namespace

std::optional<ReadBack> home_and_read(drivers::SerialDriver& driver, std::chrono::nanoseconds home_timeout,
                                      std::chrono::nanoseconds read_timeout, std::string* problem) {
  const drivers::Submitted home = driver.home();
  drivers::CommandStatus st = home.accepted() ? wait_for_command(driver, home.id, home_timeout)
                                              : drivers::CommandStatus{0, drivers::CommandPhase::failed, home.error,
                                                                       home.message};
  if (st.phase != drivers::CommandPhase::done) {
    *problem = failed("homing", st);
    return std::nullopt;
  }
  const drivers::Submitted read = driver.request_position();
  st = read.accepted() ? wait_for_command(driver, read.id, read_timeout)
                       : drivers::CommandStatus{0, drivers::CommandPhase::failed, read.error, read.message};
  if (st.phase != drivers::CommandPhase::done) {
    *problem = failed("reading the position", st);
    return std::nullopt;
  }
  return read_back_of(driver);
}

void bring_up_checked(drivers::SerialDriver& driver, const DriverChoice& choice, const models::RobotSpec& robot) {
  std::string problem;
  const std::optional<ReadBack> home =
      home_and_read(driver, std::chrono::seconds(60), std::chrono::seconds(5), &problem);
  std::vector<std::string> problems;
  if (!home) {
    problems.push_back(problem);
  } else {
    problems = cross_check(robot, choice.kind, *home).problems;
  }
  if (problems.empty()) return;
  std::string all;
  for (const std::string& p : problems) all += fmt::format("{}{}", all.empty() ? "" : "; and ", p);
  driver.disconnect();
  throw InputError(choice.where, fmt::format("robot '{}' on the {} driver, refused at bring-up before anything moved "
                                             "but homing: {}",
                                             choice.robot, to_string(choice.kind), all));
}

bool Commissioning::ok() const {
  for (const CommissionedRobot& r : robots) {
    if (!r.problem.empty() || !r.home) return false;
    if (!r.check.ok() && (r.suggestion.yaml.empty() || r.suggestion.residual_mm > kPositionTolerance)) return false;
  }
  return true;
}

Commissioning commission(const Scenario& s) {
  Commissioning out;
  for (const Binding& b : s.robots) {
    const auto choice = std::find_if(s.drivers.begin(), s.drivers.end(),
                                     [&](const DriverChoice& d) { return d.robot == b.name && d.real(); });
    if (choice == s.drivers.end()) continue;
    const models::RobotSpec& spec = *s.cell.find_robot(b.name);
    CommissionedRobot r;
    r.label = b.label;
    r.robot = b.name;
    r.driver = fmt::format("{} {}", to_string(choice->kind), choice->serial->port);
    r.entry = spec.where;
    std::unique_ptr<drivers::SerialDriver> driver = make_real_driver(*choice, spec);
    connect_real_driver(*driver, *choice);
    r.home = home_and_read(*driver, std::chrono::seconds(60), std::chrono::seconds(5), &r.problem);
    driver->disconnect();
    if (r.home) {
      r.check = cross_check(spec, choice->kind, *r.home);
      r.suggestion = suggest_settings(spec, choice->kind, {*r.home});
    }
    out.robots.push_back(std::move(r));
  }
  return out;
}

std::string format_commissioning(const Commissioning& c) {
  std::string out;
  for (const CommissionedRobot& r : c.robots) {
    out += fmt::format("{} ({}) on {}\n", r.label, r.robot, r.driver);
    if (!r.problem.empty()) out += fmt::format("  PROBLEM: {}\n", r.problem);
    if (!r.home) continue;
    if (const auto* l = std::get_if<drivers::val2::Location>(&r.home->raw)) {
      out += fmt::format("  WHERE after homing: X Y Z {} {} {} mm, O A T {} {} {} deg\n", num(l->x), num(l->y),
                         num(l->z), num(l->o), num(l->a), num(l->t));
    } else if (const auto* v = std::get_if<drivers::movemaster::Xyzpr>(&r.home->raw)) {
      out += fmt::format("  WH after homing: {}\n", drivers::movemaster::format_mp(*v).substr(3));
    }
    for (const std::string& n : r.check.notes) out += fmt::format("  not checked: {}\n", n);
    if (r.check.ok()) {
      out += "  the read-back agrees with the robot's settings: nothing to change\n";
      continue;
    }
    for (const std::string& p : r.check.problems) out += fmt::format("  disagrees: {}\n", p);
    if (r.suggestion.yaml.empty()) continue;
    out += fmt::format("  proposed settings (the robot's entry at {}; merge with its {} keys):\n    {}\n",
                       r.entry.str(), r.suggestion.yaml.substr(0, r.suggestion.yaml.find(':')), r.suggestion.yaml);
    out += fmt::format("  fit: {} mm left over{}\n", num(r.suggestion.residual_mm),
                       r.suggestion.limitations.empty() ? "" : "; " + r.suggestion.limitations);
  }
  out += c.ok() ? "commission: done; nothing was moved but homing\n"
                : "commission: problems above; nothing was moved but homing\n";
  return out;
}

}  // namespace cellwright::cell
