// A remote robot control's lock-step turn on the wire (turn_wire.hpp). Plain CDR (XCDR1 little-endian, the
// encapsulation header 00 01 00 00 first), every type @final, every string and sequence bounded. A union is written as
// CDR writes one: its discriminator, then the member it selects (nothing for a case without one).
//
//   module cellwright { module msg { module dds_ {
//     // An Isometry3d, bit for bit: its rotation matrix column by column, then its translation. (Not replica.hpp's
//     // quaternion Pose_: a rotation made from a quaternion is not the matrix it was made of, and the run's twin and
//     // the agent must compute with the same bits for their event logs to be the same bytes.)
//     @final struct Frame_ { double r[9]; double t[3]; };
//     @final struct Vector_ { double x, y, z; };
//     @final struct Hold_ { string<128> workpiece; uint8 approach;   // 0 down, 1 side
//                           double tcp_above_bottom; Frame_ in_hand; };
//     @final struct GripReading_ { boolean on_part; string<128> part; };
//     @final struct Robot_ {              // RobotState but `fixed`
//       string<128> name; sequence<double, 16> joints;
//       boolean has_hold; Hold_ hold; boolean has_dropped_hold; Hold_ dropped_hold;
//       boolean has_tcp; Frame_ tcp; boolean has_released_tcp; Frame_ released_tcp;
//       boolean has_grip; GripReading_ grip; boolean has_wrist_force; Vector_ wrist_force;
//     };                                  // (an unset optional's value is written as its default, read, not kept)
//     @final struct Workpiece_ {          // WorkpieceState but `fixed`
//       string<128> name; Frame_ pose; Vector_ velocity; boolean motion_known, present;
//       string<128> held_by, claimed_by; double confidence; int64 stamp_ns; boolean lost; string<8192> lost_reason;
//     };
//     @final struct Obstacle_ { string<128> name; Vector_ centre, size; };
//     @final struct Model_ {              // EnvironmentModel's changing state: the geometry is the receiver's own
//       int64 time_ns; sequence<Robot_, 16> robots; sequence<Workpiece_, 64> workpieces;
//       sequence<Obstacle_, 64> obstacles;
//     };
//     @final struct Command_ {            // a MotionCommand, as RobotCommand_ (wire.hpp) without its sequence
//       uint32 robot; uint32 index; uint32 transition; int64 sent_ns; string<256> primitive;
//     };
//     @final struct Status_ {             // a RobotStatus, as RobotStatus_ without its stamp (a reason is not cut)
//       uint32 robot; int64 index;        // -1: kNoCommand
//       uint8 outcome; boolean stop_cell; string<8192> reason; int64 time_ns;  // outcome 0 done, 1 failed
//     };
//     @final struct MoveJoints_ { sequence<double, 16> positions; double speed;
//                                 boolean has_duration; double duration; };
//     @final struct MovePose_ { Frame_ pose; uint8 path;  // 0 joint, 1 linear
//                               double speed; boolean has_duration; double duration; };
//     @final struct Grip_ { uint8 action;  // 0 open, 1 close
//                           boolean has_width; double width; boolean has_force; double force; };
//     @final struct SetOutput_ { int32 channel; boolean on; };
//     @final struct WaitInput_ { int32 channel; boolean on; int64 timeout_ns; };
//     union DriverCommand_ switch (uint8) {  // the discriminator: drivers::Command's index() (the variant's order)
//       case 0: MoveJoints_ move_joints; case 1: MovePose_ move_pose; case 2: Grip_ grip;
//       case 3: SetOutput_ set_output; case 4: WaitInput_ wait_input;
//     };
//     // DriverOp: 0 capabilities, 1 state, 2 connect, 3 disconnect, 4 home, 5 activate, 6 stop, 7 reset, 8 submit,
//     // 9 request_position, 10 poll, 11 last_position, 12 grip_sense, 13 least_duration.
//     union DriverCall_ switch (uint8) {          // the discriminator: the DriverOp
//       case 8: case 13: DriverCommand_ command;  // submit, least_duration
//       case 10: uint64 id;                        // poll
//     };                                           // the other ops carry nothing
//     @final struct Capabilities_ {
//       uint32 joints; boolean joint_control, cartesian_control, linear_motion, full_orientation, gripper,
//       gripper_width, gripper_force; double gripper_max_width, gripper_max_force; uint32 digital_outputs,
//       digital_inputs; sequence<double, 16> max_joint_speed; double max_tool_speed; uint32 queue_depth;
//       boolean reads_joints, reads_pose, reads_while_moving; int64 read_time_ns; boolean prefers_pose, senses_grip,
//       timed_motion;
//     };
//     @final struct Submitted_ { uint64 id; uint8 error; string<1024> message; };  // the message cut to fit
//     @final struct CommandStatus_ { uint64 id; uint8 phase; uint8 error; string<1024> message; };  // likewise
//     @final struct PositionReading_ { uint64 request; int64 stamp_ns; sequence<double, 16> joints;
//                                      boolean has_tool_pose; Frame_ tool_pose; };
//     // ErrorCode 0 none .. 12 unknown_command, DriverState 0 disconnected .. 5 fault, CommandPhase 0 pending .. 3
//     // failed, GripSense 0 open, 1 closed_empty, 2 closed_on_part: their enums' order (robot_driver.hpp).
//     @final struct LastPosition_ { boolean has; PositionReading_ reading; };
//     @final struct GripSense_ { boolean has; uint8 sense; };
//     @final struct LeastDuration_ { boolean has; double seconds; };
//     union DriverResult_ switch (uint8) {       // the discriminator: the DriverOp; only its answer travels
//       case 0: Capabilities_ capabilities;
//       case 1: uint8 state;
//       case 2: case 5: case 7: uint8 error;         // connect, activate, reset
//       case 4: case 8: case 9: Submitted_ submitted;  // home, submit, request_position
//       case 10: CommandStatus_ status;              // poll
//       case 11: LastPosition_ position;
//       case 12: GripSense_ grip;
//       case 13: LeastDuration_ least;
//     };                                             // 3 disconnect, 6 stop: nothing
//     @final struct TurnStart_ { int64 now_ns; sequence<Command_, 8> commands; Model_ model; };
//     union TurnBody_ switch (uint8) { case 0: TurnStart_ turn; case 1: DriverResult_ result; };  // 2: the end
//     @final struct Turn_ { uint32 robot; uint64 sequence; uint64 turn; TurnBody_ body; };
//     @final struct TurnDone_ {
//       sequence<string<8192>, 64> events;  // each event's log line (log_event.hpp)
//       sequence<Status_, 16> statuses; Model_ model;
//       string<8192> error;                 // "" none; a longer text is cut to fit
//       string<1024> settings;              // turn 0 (the agent's hello): turn_link.hpp's turn_settings(); else ""
//     };
//     union TurnCallBody_ switch (uint8) { case 0: DriverCall_ call; case 1: TurnDone_ done; };
//     @final struct TurnCall_ { uint32 robot; uint64 sequence; uint64 turn; TurnCallBody_ body; };
//   }; }; };
//
// Doubles travel as their bits. The model's are refused when not finite (and a rotation that is not one, beyond
// 1e-6); a command's and a driver's answer's are carried as they are (the driver, or the robot control, judges them
// as it would in one process).
#include "cellwright/distributed/turn_wire.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>

#include <fmt/format.h>

#include "cdr_io.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/distributed/link.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/runtime/log_event.hpp"

namespace cellwright::distributed {
namespace {

using cdr_io::from_ns;
using cdr_io::nanoseconds;
using cdr_io::narrow_index;

// Reasons, lost reasons, an agent's error: as long as an event line may be (a reason is logged in one).
constexpr std::size_t kTextBound = kEventLineBound;
constexpr std::size_t kSettingsBound = 1024;
constexpr std::uint8_t kLastDriverOp = static_cast<std::uint8_t>(DriverOp::least_duration);
constexpr std::uint8_t kLastErrorCode = static_cast<std::uint8_t>(drivers::ErrorCode::unknown_command);
constexpr std::uint8_t kLastDriverState = static_cast<std::uint8_t>(drivers::DriverState::fault);
constexpr std::uint8_t kLastPhase = static_cast<std::uint8_t>(drivers::CommandPhase::failed);
constexpr std::uint8_t kLastGripSense = static_cast<std::uint8_t>(drivers::GripSense::closed_on_part);

// An enum's value off the wire, refused above `last` (its enum's last value), naming `field` and `names`.
template <typename E>
E enum_of(std::uint8_t value, std::uint8_t last, const char* field, const char* names) {
  if (value > last) throw WireError(fmt::format("{}: {} is none of {}", field, value, names));
  return static_cast<E>(value);
}

const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();

void check_count(std::size_t n, std::size_t bound, const char* what) {
  if (n > bound) throw WireError(fmt::format("{} {}, over the bound of {}", n, what, bound));
}

// ---- Writing ----

class Out : public cdr_io::Out {
 public:
  using cdr_io::Out::Out;

  void frame(const Eigen::Isometry3d& p) {
    const Eigen::Matrix3d r = p.linear();
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) cdr() << r(k, c);
    }
    vector(p.translation());
  }
  void vector(const Eigen::Vector3d& v) { cdr() << v.x() << v.y() << v.z(); }
  void doubles(const std::vector<double>& values, std::size_t bound, const char* what) {
    check_count(values.size(), bound, what);
    cdr() << static_cast<std::uint32_t>(values.size());
    for (double v : values) cdr() << v;
  }
  // An optional: whether it is set, then its value, or `none` when it is not.
  template <typename T, typename Write>
  void optional(const std::optional<T>& value, const T& none, Write write) {
    cdr() << value.has_value();
    write(value ? *value : none);
  }
  void hold(const runtime::Hold& h) {
    text(h.workpiece, kNameBound, "Hold_.workpiece");
    cdr() << static_cast<std::uint8_t>(h.approach == models::Approach::kSide ? 1 : 0) << h.tcp_above_bottom;
    frame(h.in_hand);
  }
  void model(const runtime::EnvironmentModel& m);
  void command(const drivers::Command& c);
  void result(const DriverResult& r);
  void cut(const std::string& s, std::size_t bound, const char* field) { text(s.substr(0, bound - 1), bound, field); }
};

void Out::model(const runtime::EnvironmentModel& m) {
  check_count(m.robots.size(), kMaxRobots, "robots in the model");
  check_count(m.workpieces.size(), kMaxWorkpieces, "workpieces in the model");
  check_count(m.obstacles.size(), kMaxObstacles, "obstacles in the model");
  cdr() << nanoseconds(m.time) << static_cast<std::uint32_t>(m.robots.size());
  for (const runtime::RobotState& r : m.robots) {
    text(r.name, kNameBound, "Robot_.name");
    doubles(r.joints, kMaxJoints, "joints");
    optional(r.hold, runtime::Hold{}, [&](const runtime::Hold& h) { hold(h); });
    optional(r.dropped_hold, runtime::Hold{}, [&](const runtime::Hold& h) { hold(h); });
    optional(r.tcp, kIdentity, [&](const Eigen::Isometry3d& p) { frame(p); });
    optional(r.released_tcp, kIdentity, [&](const Eigen::Isometry3d& p) { frame(p); });
    optional(r.grip, runtime::GripReading{}, [&](const runtime::GripReading& g) {
      cdr() << g.on_part;
      text(g.part, kNameBound, "GripReading_.part");
    });
    cdr() << r.wrist_force.has_value();
    vector(r.wrist_force.value_or(Eigen::Vector3d::Zero()));
  }
  cdr() << static_cast<std::uint32_t>(m.workpieces.size());
  for (const runtime::WorkpieceState& w : m.workpieces) {
    text(w.name, kNameBound, "Workpiece_.name");
    frame(w.pose);
    vector(w.velocity);
    cdr() << w.motion_known << w.present;
    text(w.held_by, kNameBound, "Workpiece_.held_by");
    text(w.claimed_by, kNameBound, "Workpiece_.claimed_by");
    cdr() << w.confidence << nanoseconds(w.stamp) << w.lost;
    text(w.lost_reason, kTextBound, "Workpiece_.lost_reason");
  }
  cdr() << static_cast<std::uint32_t>(m.obstacles.size());
  for (const runtime::ObstacleState& o : m.obstacles) {
    text(o.name, kNameBound, "Obstacle_.name");
    vector(o.centre);
    vector(o.size);
  }
}

void Out::command(const drivers::Command& c) {
  cdr() << static_cast<std::uint8_t>(c.index());
  auto maybe = [&](const std::optional<double>& d) { cdr() << d.has_value() << d.value_or(0.0); };
  if (const auto* m = std::get_if<drivers::MoveJoints>(&c)) {
    doubles(m->positions, kMaxJoints, "MoveJoints positions");
    cdr() << m->speed;
    maybe(m->duration);
  } else if (const auto* p = std::get_if<drivers::MovePose>(&c)) {
    frame(p->pose);
    cdr() << static_cast<std::uint8_t>(p->path) << p->speed;
    maybe(p->duration);
  } else if (const auto* g = std::get_if<drivers::Grip>(&c)) {
    cdr() << static_cast<std::uint8_t>(g->action);
    maybe(g->width);
    maybe(g->force);
  } else if (const auto* s = std::get_if<drivers::SetOutput>(&c)) {
    cdr() << static_cast<std::int32_t>(s->channel) << s->on;
  } else {
    const auto& w = std::get<drivers::WaitInput>(c);
    cdr() << static_cast<std::int32_t>(w.channel) << w.on << static_cast<std::int64_t>(w.timeout.count());
  }
}

void Out::result(const DriverResult& r) {
  cdr() << static_cast<std::uint8_t>(r.op);
  switch (r.op) {
    case DriverOp::capabilities: {
      const drivers::Capabilities& c = r.capabilities;
      cdr() << narrow_index(c.joints, "Capabilities joints") << c.joint_control << c.cartesian_control
            << c.linear_motion << c.full_orientation << c.gripper << c.gripper_width << c.gripper_force
            << c.gripper_max_width << c.gripper_max_force << narrow_index(c.digital_outputs, "digital outputs")
            << narrow_index(c.digital_inputs, "digital inputs");
      doubles(c.max_joint_speed, kMaxJoints, "max joint speeds");
      cdr() << c.max_tool_speed << narrow_index(c.queue_depth, "queue depth") << c.reads_joints << c.reads_pose
            << c.reads_while_moving << static_cast<std::int64_t>(c.read_time.count()) << c.prefers_pose << c.senses_grip
            << c.timed_motion;
      break;
    }
    case DriverOp::state:
      cdr() << static_cast<std::uint8_t>(r.state);
      break;
    case DriverOp::connect:
    case DriverOp::activate:
    case DriverOp::reset:
      cdr() << static_cast<std::uint8_t>(r.error);
      break;
    case DriverOp::home:
    case DriverOp::submit:
    case DriverOp::request_position:
      cdr() << r.submitted.id << static_cast<std::uint8_t>(r.submitted.error);
      cut(r.submitted.message, kMessageBound, "Submitted_.message");
      break;
    case DriverOp::poll:
      cdr() << r.status.id << static_cast<std::uint8_t>(r.status.phase) << static_cast<std::uint8_t>(r.status.error);
      cut(r.status.message, kMessageBound, "CommandStatus_.message");
      break;
    case DriverOp::last_position:
      optional(r.position, drivers::PositionReading{}, [&](const drivers::PositionReading& p) {
        cdr() << p.request << static_cast<std::int64_t>(p.stamp.count());
        doubles(p.joints, kMaxJoints, "read-back joints");
        optional(p.tool_pose, kIdentity, [&](const Eigen::Isometry3d& pose) { frame(pose); });
      });
      break;
    case DriverOp::grip_sense:
      optional(r.grip, drivers::GripSense::open, [&](drivers::GripSense g) { cdr() << static_cast<std::uint8_t>(g); });
      break;
    case DriverOp::least_duration:
      optional(r.least, 0.0, [&](double s) { cdr() << s; });
      break;
    case DriverOp::disconnect:
    case DriverOp::stop:
      break;
  }
}

// ---- Reading ----

class In : public cdr_io::In {
 public:
  using cdr_io::In::In;

  // A frame as it was; `field` set: a model's, refused when not finite or not a rotation.
  Eigen::Isometry3d frame(const char* field = nullptr) {
    double v[12];
    for (double& x : v) x = field != nullptr ? number(field) : get<double>();
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    Eigen::Matrix3d r;
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) r(k, c) = v[3 * c + k];
    }
    if (field != nullptr) {
      const double off = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
      if (off > 1e-6 || r.determinant() < 0) {
        throw WireError(
            fmt::format("{}: no rotation (R^T R off the identity by {}, det {})", field, off, r.determinant()));
      }
    }
    p.linear() = r;
    p.translation() = Eigen::Vector3d(v[9], v[10], v[11]);
    return p;
  }
  Eigen::Vector3d vector(const char* field = nullptr) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v[k] = field != nullptr ? number(field) : get<double>();
    return v;
  }
  std::vector<double> doubles(std::size_t bound, const char* field, bool finite) {
    const std::uint32_t n = count(bound, field);
    std::vector<double> values(n);
    for (double& v : values) v = finite ? number(field) : get<double>();
    return values;
  }
  template <typename T, typename Read>
  std::optional<T> optional(Read read) {
    const bool set = get<bool>();
    T value = read();
    if (!set) return std::nullopt;
    return value;
  }
  runtime::Hold hold(const char* field) {
    runtime::Hold h;
    h.workpiece = text(kNameBound, field);
    h.approach = enum_of<std::uint8_t>(get<std::uint8_t>(), 1, field, "0 down, 1 side") == 1 ? models::Approach::kSide
                                                                                             : models::Approach::kDown;
    h.tcp_above_bottom = number(field);
    h.in_hand = frame(field);
    return h;
  }
  runtime::EnvironmentModel model(const runtime::EnvironmentModel& cell_model);
  drivers::Command command();
  DriverResult result();
};

// "a, b, c"
template <typename T>
std::string names_of(const std::vector<T>& items) {
  std::string s;
  for (const T& i : items) s += (s.empty() ? "" : ", ") + i.name;
  return "[" + s + "]";
}

template <typename T>
void check_names(const std::vector<T>& wire, const std::vector<T>& cell, const char* what) {
  bool same = wire.size() == cell.size();
  for (std::size_t i = 0; same && i < wire.size(); ++i) same = wire[i].name == cell[i].name;
  if (!same) {
    throw WireError(fmt::format("the model's {} are {} on the wire, {} in this cell (by name, in its order)", what,
                                names_of(wire), names_of(cell)));
  }
}

runtime::EnvironmentModel In::model(const runtime::EnvironmentModel& cell_model) {
  runtime::EnvironmentModel m = cell_model;
  const auto time = get<std::int64_t>();
  if (time < 0) throw WireError(fmt::format("a model at {} ns, before the run began", time));
  m.time = from_ns(time);
  std::vector<runtime::RobotState> robots(count(kMaxRobots, "Model_.robots"));
  for (runtime::RobotState& r : robots) {
    r.name = text(kNameBound, "Robot_.name");
    r.joints = doubles(kMaxJoints, "Robot_.joints", true);
    r.hold = optional<runtime::Hold>([&] { return hold("Robot_.hold"); });
    r.dropped_hold = optional<runtime::Hold>([&] { return hold("Robot_.dropped_hold"); });
    r.tcp = optional<Eigen::Isometry3d>([&] { return frame("Robot_.tcp"); });
    r.released_tcp = optional<Eigen::Isometry3d>([&] { return frame("Robot_.released_tcp"); });
    r.grip = optional<runtime::GripReading>([&] {
      runtime::GripReading g;
      g.on_part = get<bool>();
      g.part = text(kNameBound, "GripReading_.part");
      return g;
    });
    r.wrist_force = optional<Eigen::Vector3d>([&] { return vector("Robot_.wrist_force"); });
  }
  check_names(robots, m.robots, "robots");
  for (std::size_t i = 0; i < robots.size(); ++i) {
    runtime::RobotState& mine = m.robots[i];
    robots[i].fixed = mine.fixed;
    mine = std::move(robots[i]);
  }
  std::vector<runtime::WorkpieceState> workpieces(count(kMaxWorkpieces, "Model_.workpieces"));
  for (runtime::WorkpieceState& w : workpieces) {
    w.name = text(kNameBound, "Workpiece_.name");
    w.pose = frame("Workpiece_.pose");
    w.velocity = vector("Workpiece_.velocity");
    w.motion_known = get<bool>();
    w.present = get<bool>();
    w.held_by = text(kNameBound, "Workpiece_.held_by");
    w.claimed_by = text(kNameBound, "Workpiece_.claimed_by");
    w.confidence = number("Workpiece_.confidence");
    w.stamp = from_ns(get<std::int64_t>());
    w.lost = get<bool>();
    w.lost_reason = text(kTextBound, "Workpiece_.lost_reason");
  }
  check_names(workpieces, m.workpieces, "workpieces");
  for (std::size_t i = 0; i < workpieces.size(); ++i) {
    runtime::WorkpieceState& mine = m.workpieces[i];
    workpieces[i].fixed = mine.fixed;
    mine = std::move(workpieces[i]);
  }
  m.obstacles.assign(count(kMaxObstacles, "Model_.obstacles"), {});
  for (runtime::ObstacleState& o : m.obstacles) {
    o.name = text(kNameBound, "Obstacle_.name");
    o.centre = vector("Obstacle_.centre");
    o.size = vector("Obstacle_.size");
  }
  return m;
}

drivers::Command In::command() {
  const auto which = get<std::uint8_t>();
  auto maybe = [&] { return optional<double>([&] { return get<double>(); }); };
  switch (which) {
    case 0: {
      drivers::MoveJoints m;
      m.positions = doubles(kMaxJoints, "MoveJoints_.positions", false);
      m.speed = get<double>();
      m.duration = maybe();
      return m;
    }
    case 1: {
      drivers::MovePose p;
      p.pose = frame();
      p.path = enum_of<drivers::Path>(get<std::uint8_t>(), 1, "MovePose_.path", "0 joint, 1 linear");
      p.speed = get<double>();
      p.duration = maybe();
      return p;
    }
    case 2: {
      drivers::Grip g;
      g.action = enum_of<drivers::Grip::Action>(get<std::uint8_t>(), 1, "Grip_.action", "0 open, 1 close");
      g.width = maybe();
      g.force = maybe();
      return g;
    }
    case 3: {
      drivers::SetOutput s;
      s.channel = get<std::int32_t>();
      s.on = get<bool>();
      return s;
    }
    case 4: {
      drivers::WaitInput w;
      w.channel = get<std::int32_t>();
      w.on = get<bool>();
      w.timeout = std::chrono::nanoseconds(get<std::int64_t>());
      return w;
    }
    default:
      throw WireError(fmt::format("DriverCommand_: alternative {} (0 move_joints .. 4 wait_input)", which));
  }
}

DriverResult In::result() {
  DriverResult r;
  r.op = enum_of<DriverOp>(get<std::uint8_t>(), kLastDriverOp, "DriverResult_.op", "the 14 driver calls");
  auto error = [&](const char* field) {
    return enum_of<drivers::ErrorCode>(get<std::uint8_t>(), kLastErrorCode, field, "the ErrorCodes 0..12");
  };
  switch (r.op) {
    case DriverOp::capabilities: {
      drivers::Capabilities& c = r.capabilities;
      c.joints = get<std::uint32_t>();
      for (bool* b : {&c.joint_control, &c.cartesian_control, &c.linear_motion, &c.full_orientation, &c.gripper,
                      &c.gripper_width, &c.gripper_force}) {
        *b = get<bool>();
      }
      c.gripper_max_width = get<double>();
      c.gripper_max_force = get<double>();
      c.digital_outputs = get<std::uint32_t>();
      c.digital_inputs = get<std::uint32_t>();
      c.max_joint_speed = doubles(kMaxJoints, "Capabilities_.max_joint_speed", false);
      c.max_tool_speed = get<double>();
      c.queue_depth = get<std::uint32_t>();
      c.reads_joints = get<bool>();
      c.reads_pose = get<bool>();
      c.reads_while_moving = get<bool>();
      c.read_time = std::chrono::nanoseconds(get<std::int64_t>());
      c.prefers_pose = get<bool>();
      c.senses_grip = get<bool>();
      c.timed_motion = get<bool>();
      break;
    }
    case DriverOp::state:
      r.state = enum_of<drivers::DriverState>(get<std::uint8_t>(), kLastDriverState, "DriverResult_.state",
                                              "the DriverStates 0..5");
      break;
    case DriverOp::connect:
    case DriverOp::activate:
    case DriverOp::reset:
      r.error = error("DriverResult_.error");
      break;
    case DriverOp::home:
    case DriverOp::submit:
    case DriverOp::request_position:
      r.submitted.id = get<std::uint64_t>();
      r.submitted.error = error("Submitted_.error");
      r.submitted.message = text(kMessageBound, "Submitted_.message");
      break;
    case DriverOp::poll:
      r.status.id = get<std::uint64_t>();
      r.status.phase = enum_of<drivers::CommandPhase>(get<std::uint8_t>(), kLastPhase, "CommandStatus_.phase",
                                                      "the CommandPhases 0..3");
      r.status.error = error("CommandStatus_.error");
      r.status.message = text(kMessageBound, "CommandStatus_.message");
      break;
    case DriverOp::last_position:
      r.position = optional<drivers::PositionReading>([&] {
        drivers::PositionReading p;
        p.request = get<std::uint64_t>();
        p.stamp = std::chrono::nanoseconds(get<std::int64_t>());
        p.joints = doubles(kMaxJoints, "PositionReading_.joints", false);
        p.tool_pose = optional<Eigen::Isometry3d>([&] { return frame(); });
        return p;
      });
      break;
    case DriverOp::grip_sense:
      r.grip = optional<drivers::GripSense>([&] {
        return enum_of<drivers::GripSense>(get<std::uint8_t>(), kLastGripSense, "DriverResult_.grip",
                                           "0 open, 1 closed_empty, 2 closed_on_part");
      });
      break;
    case DriverOp::least_duration:
      r.least = optional<double>([&] { return get<double>(); });
      break;
    case DriverOp::disconnect:
    case DriverOp::stop:
      break;
  }
  return r;
}

bool carries_command(DriverOp op) {
  return op == DriverOp::submit || op == DriverOp::least_duration;
}

// The header every message starts with: robot, sequence, turn, kind.
void put_header(Out& out, std::size_t robot, std::uint64_t sequence, std::uint64_t turn, std::uint8_t kind) {
  out.cdr() << narrow_index(robot, "robot index") << sequence << turn << kind;
}

template <typename Message>
std::uint8_t get_header(In& in, Message& m, std::size_t robot, const char* what, std::uint8_t last_kind,
                        const char* kinds) {
  const auto on_wire = in.get<std::uint32_t>();
  if (on_wire != robot) throw WireError(fmt::format("{} of robot {} on robot {}'s topic", what, on_wire, robot));
  m.robot = robot;
  m.sequence = in.get<std::uint64_t>();
  m.turn = in.get<std::uint64_t>();
  const auto kind = in.get<std::uint8_t>();
  enum_of<std::uint8_t>(kind, last_kind, what, kinds);
  return kind;
}

// The largest sample of each kind: every sequence full, every string at its bound, every optional set (a longer
// field never ends the sample earlier: CDR's alignment only rounds positions up).
runtime::EnvironmentModel largest_model() {
  runtime::EnvironmentModel m;
  const std::string name(kNameBound - 1, 'n');
  runtime::Hold hold;
  hold.workpiece = name;
  runtime::RobotState r;
  r.name = name;
  r.joints.assign(kMaxJoints, 0.0);
  r.hold = r.dropped_hold = hold;
  r.tcp = r.released_tcp = Eigen::Isometry3d::Identity();
  r.grip = runtime::GripReading::of(name);
  r.wrist_force = Eigen::Vector3d::Zero();
  m.robots.assign(kMaxRobots, r);
  runtime::WorkpieceState w;
  w.name = w.held_by = w.claimed_by = name;
  w.lost_reason.assign(kTextBound - 1, 'r');
  m.workpieces.assign(kMaxWorkpieces, w);
  m.obstacles.assign(kMaxObstacles, runtime::ObstacleState{name, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
  return m;
}

std::vector<DriverResult> largest_results() {
  std::vector<DriverResult> results;
  for (std::uint8_t op = 0; op <= kLastDriverOp; ++op) {
    DriverResult r;
    r.op = static_cast<DriverOp>(op);
    r.capabilities.max_joint_speed.assign(kMaxJoints, 1.0);
    r.submitted.message.assign(kMessageBound - 1, 'm');
    r.status.message.assign(kMessageBound - 1, 'm');
    r.position = drivers::PositionReading{1, {}, std::vector<double>(kMaxJoints, 0.0), Eigen::Isometry3d::Identity()};
    r.grip = drivers::GripSense::open;
    r.least = 1.0;
    results.push_back(r);
  }
  return results;
}

std::vector<drivers::Command> largest_commands() {
  drivers::MoveJoints joints;
  joints.positions.assign(kMaxJoints, 0.0);
  joints.duration = 1.0;
  drivers::MovePose pose;
  pose.duration = 1.0;
  return {joints, pose, drivers::Grip{drivers::Grip::Action::close, 0.01, 1.0}, drivers::SetOutput{},
          drivers::WaitInput{}};
}

}  // namespace

std::string turn_topic(const std::string& robot) {
  const std::string command = command_topic(robot);  // the robot's name checked as the link's topics check it
  return command.substr(0, command.size() - std::string("command").size()) + "turn";
}

std::string call_topic(const std::string& robot) {
  const std::string command = command_topic(robot);
  return command.substr(0, command.size() - std::string("command").size()) + "call";
}

const char* to_string(DriverOp op) {
  switch (op) {
    case DriverOp::capabilities:
      return "capabilities";
    case DriverOp::state:
      return "state";
    case DriverOp::connect:
      return "connect";
    case DriverOp::disconnect:
      return "disconnect";
    case DriverOp::home:
      return "home";
    case DriverOp::activate:
      return "activate";
    case DriverOp::stop:
      return "stop";
    case DriverOp::reset:
      return "reset";
    case DriverOp::submit:
      return "submit";
    case DriverOp::request_position:
      return "request_position";
    case DriverOp::poll:
      return "poll";
    case DriverOp::last_position:
      return "last_position";
    case DriverOp::grip_sense:
      return "grip_sense";
    case DriverOp::least_duration:
      return "least_duration";
  }
  return "?";
}

// Room for a message with a model of a few robots and a dozen workpieces at once; more is made as it is needed.
constexpr std::size_t kModelRoom = 16384;

std::vector<char> encode_turn(const TurnMessage& message) {
  return cdr_io::encode_growing<Out>(message.kind == TurnMessage::Kind::kTurn ? kModelRoom : 256, [&](Out& out) {
    put_header(out, message.robot, message.sequence, message.turn, static_cast<std::uint8_t>(message.kind));
    switch (message.kind) {
      case TurnMessage::Kind::kTurn:
        check_count(message.commands.size(), kMaxTurnCommands, "commands in a turn");
        out.cdr() << nanoseconds(message.now) << static_cast<std::uint32_t>(message.commands.size());
        for (const runtime::MotionCommand& c : message.commands) {
          const cdr_io::CommandFields f = cdr_io::command_fields(c);
          out.cdr() << f.robot << f.index << f.transition << f.sent_ns;
          out.text(f.primitive, kPrimitiveTextBound, "Command_.primitive");
        }
        out.model(message.model);
        break;
      case TurnMessage::Kind::kResult:
        out.result(message.result);
        break;
      case TurnMessage::Kind::kEnd:
        break;
    }
  });
}

std::vector<char> encode_turn_call(const TurnCall& message) {
  return cdr_io::encode_growing<Out>(message.kind == TurnCall::Kind::kDone ? kModelRoom : 256, [&](Out& out) {
    put_header(out, message.robot, message.sequence, message.turn, static_cast<std::uint8_t>(message.kind));
    if (message.kind == TurnCall::Kind::kCall) {
      const DriverCall& call = message.call;
      out.cdr() << static_cast<std::uint8_t>(call.op);
      if (carries_command(call.op)) out.command(call.command);
      if (call.op == DriverOp::poll) out.cdr() << call.id;
      return;
    }
    check_count(message.events.size(), kMaxTurnEvents, "events in a turn");
    check_count(message.statuses.size(), kMaxTurnStatuses, "statuses in a turn");
    out.cdr() << static_cast<std::uint32_t>(message.events.size());
    for (const std::string& line : message.events) out.text(line, kEventLineBound, "TurnDone_.events");
    out.cdr() << static_cast<std::uint32_t>(message.statuses.size());
    for (const runtime::RobotStatus& s : message.statuses) {
      const cdr_io::StatusFields f = cdr_io::status_fields(s);
      out.cdr() << f.robot << f.index << f.outcome << f.stop_cell;
      out.text(f.reason, kTextBound, "Status_.reason");
      out.cdr() << f.time_ns;
    }
    out.model(message.model);
    out.cut(message.error, kTextBound, "TurnDone_.error");
    out.text(message.settings, kSettingsBound, "TurnDone_.settings");
  });
}

TurnMessage decode_turn(const std::vector<char>& bytes, std::size_t robot, const task::CompiledProgram& program,
                        const runtime::EnvironmentModel& cell_model) {
  In in(bytes, kTurnTypeName);
  TurnMessage m;
  m.kind = static_cast<TurnMessage::Kind>(get_header(in, m, robot, "a turn", 2, "0 turn, 1 result, 2 end"));
  switch (m.kind) {
    case TurnMessage::Kind::kTurn: {
      const auto now = in.get<std::int64_t>();
      if (now < 0) throw WireError(fmt::format("a turn at {} ns, before the run began", now));
      m.now = from_ns(now);
      const std::uint32_t n = in.count(kMaxTurnCommands, "TurnStart_.commands");
      for (std::uint32_t i = 0; i < n; ++i) {
        cdr_io::CommandFields f;
        f.robot = in.get<std::uint32_t>();
        f.index = in.get<std::uint32_t>();
        f.transition = in.get<std::uint32_t>();
        f.sent_ns = in.get<std::int64_t>();
        f.primitive = in.text(kPrimitiveTextBound, "Command_.primitive");
        m.commands.push_back(cdr_io::command_from_fields(f, program, robot));
      }
      m.model = in.model(cell_model);
      break;
    }
    case TurnMessage::Kind::kResult:
      m.result = in.result();
      break;
    case TurnMessage::Kind::kEnd:
      break;
  }
  in.end();
  return m;
}

TurnCall decode_turn_call(const std::vector<char>& bytes, std::size_t robot,
                          const runtime::EnvironmentModel& cell_model) {
  In in(bytes, kTurnCallTypeName);
  TurnCall m;
  m.kind = static_cast<TurnCall::Kind>(get_header(in, m, robot, "a turn's call", 1, "0 call, 1 done"));
  if (m.kind == TurnCall::Kind::kCall) {
    DriverCall& call = m.call;
    call.op = enum_of<DriverOp>(in.get<std::uint8_t>(), kLastDriverOp, "DriverCall_.op", "the 14 driver calls");
    if (carries_command(call.op)) call.command = in.command();
    if (call.op == DriverOp::poll) call.id = in.get<std::uint64_t>();
    in.end();
    return m;
  }
  m.events.resize(in.count(kMaxTurnEvents, "TurnDone_.events"));
  for (std::size_t i = 0; i < m.events.size(); ++i) {
    m.events[i] = in.text(kEventLineBound, "TurnDone_.events");
    try {
      runtime::decode(m.events[i], "TurnDone_.events", static_cast<int>(i + 1));
    } catch (const InputError& e) {
      throw WireError(fmt::format("event {} of the turn is no event of the log: {}", i + 1, e.what()));
    }
  }
  const std::uint32_t n = in.count(kMaxTurnStatuses, "TurnDone_.statuses");
  for (std::uint32_t i = 0; i < n; ++i) {
    cdr_io::StatusFields f;
    f.robot = in.get<std::uint32_t>();
    f.index = in.get<std::int64_t>();
    f.outcome = in.get<std::uint8_t>();
    f.stop_cell = in.get<bool>();
    f.reason = in.text(kTextBound, "Status_.reason");
    f.time_ns = in.get<std::int64_t>();
    m.statuses.push_back(cdr_io::status_from_fields(std::move(f), robot));
  }
  m.model = in.model(cell_model);
  m.error = in.text(kTextBound, "TurnDone_.error");
  m.settings = in.text(kSettingsBound, "TurnDone_.settings");
  in.end();
  return m;
}

std::size_t max_turn_size() {
  static const std::size_t size = [] {
    TurnMessage m;
    std::size_t most = 0;
    for (const DriverResult& r : largest_results()) {
      m.kind = TurnMessage::Kind::kResult;
      m.result = r;
      most = std::max(most, encode_turn(m).size());
    }
    m.kind = TurnMessage::Kind::kTurn;
    m.model = largest_model();
    runtime::MotionCommand c;
    c.primitive.kind = task::PrimitiveKind::kSignal;
    c.primitive.event.assign(kPrimitiveTextBound, 'e');  // its text is cut to the bound
    m.commands.assign(kMaxTurnCommands, c);
    return std::max(most, encode_turn(m).size());
  }();
  return size;
}

std::size_t max_turn_call_size() {
  static const std::size_t size = [] {
    TurnCall m;
    std::size_t most = 0;
    for (const drivers::Command& c : largest_commands()) {
      for (DriverOp op : {DriverOp::submit, DriverOp::least_duration}) {
        m.call.op = op;
        m.call.command = c;
        most = std::max(most, encode_turn_call(m).size());
      }
    }
    m.kind = TurnCall::Kind::kDone;
    m.events.assign(kMaxTurnEvents, std::string(kEventLineBound - 1, 'l'));
    runtime::RobotStatus s;
    s.index = 0;
    s.reason.assign(kTextBound - 1, 'r');
    m.statuses.assign(kMaxTurnStatuses, s);
    m.model = largest_model();
    m.error.assign(kTextBound - 1, 'e');
    m.settings.assign(kSettingsBound - 1, 's');
    return std::max(most, encode_turn_call(m).size());
  }();
  return size;
}

}  // namespace cellwright::distributed
