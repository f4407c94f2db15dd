// A remote robot control's lock-step turn on the wire (distributed/turn_wire.hpp): every field of every message comes
// back as it was sent, doubles bit for bit (the run's event log must be the same bytes whichever process ran the
// robot control), and bytes that are not a message of this robot, this program and this cell are refused with a
// reason, never a crash.
#include "cellwright/distributed/turn_wire.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <functional>
#include <random>

#include "cellwright/distributed/replica.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "cellwright/task/compile.hpp"

namespace cellwright::distributed {
namespace {

constexpr std::size_t kDriverOps = static_cast<std::size_t>(DriverOp::least_duration) + 1;

// The program and the cell of scenes/exchange.yaml (exchange.task on cell.yaml): r1 is the PUMA, r2 the MELFA.
struct Exchange {
  task::CompiledProgram program = task::compile_file(std::string(CW_SOURCE_DIR) + "/scenes/exchange.task");
  runtime::EnvironmentModel cell =
      runtime::make_environment_model(models::load_cell(std::string(CW_SOURCE_DIR) + "/scenes/cell.yaml"));
};

const Exchange& exchange() {
  static const Exchange e;
  return e;
}

// ---- Seeded random values: every bit pattern of a double, every optional set and unset ----

class Random {
 public:
  explicit Random(std::uint32_t seed) : engine_(seed) {}
  std::uint64_t bits() { return (std::uint64_t{engine_()} << 32) | engine_(); }
  std::size_t below(std::size_t n) { return static_cast<std::size_t>(bits() % n); }
  bool coin() { return below(2) == 1; }
  // Any double: NaNs, infinities, subnormals and -0 included.
  double any() { return std::bit_cast<double>(bits()); }
  double finite() {
    for (;;) {
      const double v = any();
      if (std::isfinite(v)) return v;
    }
  }
  std::int64_t non_negative() { return static_cast<std::int64_t>(bits() >> 1); }
  // A string of 0..bound-1 bytes (no NUL), now and then at its bound.
  std::string text(std::size_t bound, bool printable = false) {
    const std::size_t n = below(8) == 0 ? bound - 1 : below(std::min<std::size_t>(bound, 40));
    std::string s(n, ' ');
    for (char& c : s) c = static_cast<char>(printable ? 32 + below(95) : 1 + below(255));
    return s;
  }
  Eigen::Vector3d vector(bool finite_only) {
    return {finite_only ? finite() : any(), finite_only ? finite() : any(), finite_only ? finite() : any()};
  }
  // A rigid transform (its rotation from a random quaternion) or, `finite_only` false, any twelve doubles.
  Eigen::Isometry3d frame(bool rotation) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    if (rotation) {
      std::normal_distribution<double> normal;
      Eigen::Quaterniond q(normal(engine_), normal(engine_), normal(engine_), normal(engine_));
      p.linear() = q.normalized().toRotationMatrix();
    } else {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) p.matrix()(r, c) = any();
      }
    }
    p.translation() = vector(rotation);
    return p;
  }
  std::vector<double> doubles(std::size_t bound, bool finite_only) {
    std::vector<double> v(below(bound + 1));
    for (double& x : v) x = finite_only ? finite() : any();
    return v;
  }
  template <typename T>
  std::optional<T> maybe(const std::function<T()>& make) {
    if (coin()) return std::nullopt;
    return make();
  }
  std::mt19937& engine() { return engine_; }

 private:
  std::mt19937 engine_;
};

runtime::Hold random_hold(Random& r) {
  runtime::Hold h;
  h.workpiece = r.text(kNameBound);
  h.approach = r.coin() ? models::Approach::kSide : models::Approach::kDown;
  h.tcp_above_bottom = r.finite();
  h.in_hand = r.frame(true);
  return h;
}

// The cell's model with every changing field drawn at random.
runtime::EnvironmentModel random_model(Random& r) {
  runtime::EnvironmentModel m = exchange().cell;
  m.time = std::chrono::nanoseconds(r.non_negative());
  for (runtime::RobotState& s : m.robots) {
    s.joints = r.doubles(kMaxJoints, true);
    s.hold = r.maybe<runtime::Hold>([&] { return random_hold(r); });
    s.dropped_hold = r.maybe<runtime::Hold>([&] { return random_hold(r); });
    s.tcp = r.maybe<Eigen::Isometry3d>([&] { return r.frame(true); });
    s.released_tcp = r.maybe<Eigen::Isometry3d>([&] { return r.frame(true); });
    s.grip = r.maybe<runtime::GripReading>([&] { return runtime::GripReading{r.coin(), r.text(kNameBound)}; });
    s.wrist_force = r.maybe<Eigen::Vector3d>([&] { return r.vector(true); });
  }
  for (runtime::WorkpieceState& w : m.workpieces) {
    w.pose = r.frame(true);
    w.velocity = r.vector(true);
    w.motion_known = r.coin();
    w.present = r.coin();
    w.held_by = r.text(kNameBound);
    w.claimed_by = r.text(kNameBound);
    w.confidence = r.finite();
    w.stamp = std::chrono::nanoseconds(static_cast<std::int64_t>(r.bits()));  // vision's stamp may precede the run
    w.lost = r.coin();
    w.lost_reason = r.text(kEventLineBound);
  }
  m.obstacles.resize(r.below(8) == 0 ? kMaxObstacles : r.below(4));
  for (runtime::ObstacleState& o : m.obstacles) {
    o.name = r.text(kNameBound);
    o.centre = r.vector(true);
    o.size = r.vector(true);
  }
  return m;
}

drivers::Command random_command(Random& r, std::size_t alternative) {
  auto maybe = [&] { return r.maybe<double>([&] { return r.any(); }); };
  switch (alternative) {
    case 0:
      return drivers::MoveJoints{r.doubles(kMaxJoints, false), r.any(), maybe()};
    case 1:
      return drivers::MovePose{r.frame(r.coin()), r.coin() ? drivers::Path::linear : drivers::Path::joint, r.any(),
                               maybe()};
    case 2:
      return drivers::Grip{r.coin() ? drivers::Grip::Action::open : drivers::Grip::Action::close, maybe(), maybe()};
    case 3:
      return drivers::SetOutput{static_cast<int>(static_cast<std::int32_t>(r.bits())), r.coin()};
    default:
      return drivers::WaitInput{static_cast<int>(static_cast<std::int32_t>(r.bits())), r.coin(),
                                std::chrono::nanoseconds(static_cast<std::int64_t>(r.bits()))};
  }
}

// Every field of the result drawn (the op's is the one that travels).
DriverResult random_result(Random& r, DriverOp op) {
  DriverResult d;
  d.op = op;
  drivers::Capabilities& c = d.capabilities;
  c.joints = r.bits() >> 32;
  for (bool* b : {&c.joint_control, &c.cartesian_control, &c.linear_motion, &c.full_orientation, &c.gripper,
                  &c.gripper_width, &c.gripper_force, &c.reads_joints, &c.reads_pose, &c.reads_while_moving,
                  &c.prefers_pose, &c.senses_grip, &c.timed_motion}) {
    *b = r.coin();
  }
  c.gripper_max_width = r.any();
  c.gripper_max_force = r.any();
  c.digital_outputs = r.bits() >> 32;
  c.digital_inputs = r.bits() >> 32;
  c.max_joint_speed = r.doubles(kMaxJoints, false);
  c.max_tool_speed = r.any();
  c.queue_depth = r.bits() >> 32;
  c.read_time = std::chrono::nanoseconds(static_cast<std::int64_t>(r.bits()));
  d.state = static_cast<drivers::DriverState>(r.below(6));
  d.error = static_cast<drivers::ErrorCode>(r.below(13));
  d.submitted = {r.bits(), static_cast<drivers::ErrorCode>(r.below(13)), r.text(kMessageBound)};
  d.status = {r.bits(), static_cast<drivers::CommandPhase>(r.below(4)), static_cast<drivers::ErrorCode>(r.below(13)),
              r.text(kMessageBound)};
  d.position = r.maybe<drivers::PositionReading>([&] {
    return drivers::PositionReading{r.bits(), std::chrono::nanoseconds(static_cast<std::int64_t>(r.bits())),
                                    r.doubles(kMaxJoints, false),
                                    r.maybe<Eigen::Isometry3d>([&] { return r.frame(r.coin()); })};
  });
  d.grip = r.maybe<drivers::GripSense>([&] { return static_cast<drivers::GripSense>(r.below(3)); });
  d.least = r.maybe<double>([&] { return r.any(); });
  return d;
}

runtime::MotionCommand random_motion(Random& r, std::size_t robot) {
  const auto& primitives = exchange().program.programs[robot].primitives;
  runtime::MotionCommand c;
  c.robot = robot;
  c.index = r.below(primitives.size());
  c.primitive = primitives[c.index];
  c.transition = static_cast<petri::TransitionId>(r.bits() >> 32);
  c.sent = std::chrono::nanoseconds(r.non_negative());
  return c;
}

// A line of the log: a command's start or end, or a sensor event, with random text.
std::string random_event(Random& r) {
  const runtime::SimDuration t(r.non_negative() >> 8);
  switch (r.below(3)) {
    case 0:
      return runtime::encode(runtime::events::CommandStart{t, r.text(kNameBound, true), r.below(1000),
                                                           r.text(200, true), r.text(40, true), r.text(40, true),
                                                           r.text(300, true)});
    case 1:
      return runtime::encode(runtime::events::CommandEnd{t, r.text(kNameBound, true), r.below(1000), r.text(200, true),
                                                         r.coin(), r.text(2000, true)});
    default:
      return runtime::encode(
          runtime::events::Sensor{t, r.text(40, true), r.below(1000), "gripped", r.text(kNameBound, true)});
  }
}

runtime::RobotStatus random_status(Random& r, std::size_t robot) {
  runtime::RobotStatus s;
  s.robot = robot;
  s.index = r.below(4) == 0 ? runtime::RobotStatus::kNoCommand : static_cast<std::size_t>(r.bits() >> 32);
  s.outcome = r.coin() ? runtime::CommandOutcome::kDone : runtime::CommandOutcome::kFailed;
  s.reason = r.text(kEventLineBound);
  s.stop_cell = r.coin();
  s.time = std::chrono::nanoseconds(r.non_negative());
  return s;
}

// ---- Field-by-field equality, doubles by their bits ----

std::uint64_t bits(double v) {
  return std::bit_cast<std::uint64_t>(v);
}

void expect_same(const Eigen::Isometry3d& got, const Eigen::Isometry3d& sent, const std::string& what) {
  EXPECT_EQ(std::memcmp(got.matrix().data(), sent.matrix().data(), 16 * sizeof(double)), 0) << what;
}

void expect_same(const Eigen::Vector3d& got, const Eigen::Vector3d& sent, const std::string& what) {
  EXPECT_EQ(std::memcmp(got.data(), sent.data(), 3 * sizeof(double)), 0) << what;
}

void expect_same(const std::vector<double>& got, const std::vector<double>& sent, const std::string& what) {
  ASSERT_EQ(got.size(), sent.size()) << what;
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(bits(got[i]), bits(sent[i])) << what << "[" << i << "]";
}

void expect_same(const std::optional<double>& got, const std::optional<double>& sent, const std::string& what) {
  ASSERT_EQ(got.has_value(), sent.has_value()) << what;
  if (got) {
    EXPECT_EQ(bits(*got), bits(*sent)) << what;
  }
}

void expect_same(const std::optional<runtime::Hold>& got, const std::optional<runtime::Hold>& sent,
                 const std::string& what) {
  ASSERT_EQ(got.has_value(), sent.has_value()) << what;
  if (!got) return;
  EXPECT_EQ(got->workpiece, sent->workpiece) << what;
  EXPECT_EQ(got->approach, sent->approach) << what;
  EXPECT_EQ(bits(got->tcp_above_bottom), bits(sent->tcp_above_bottom)) << what;
  expect_same(got->in_hand, sent->in_hand, what + ".in_hand");
}

void expect_same(const std::optional<Eigen::Isometry3d>& got, const std::optional<Eigen::Isometry3d>& sent,
                 const std::string& what) {
  ASSERT_EQ(got.has_value(), sent.has_value()) << what;
  if (got) expect_same(*got, *sent, what);
}

// `got` decoded against the cell's model: its geometry is the cell model's own.
void expect_same_model(const runtime::EnvironmentModel& got, const runtime::EnvironmentModel& sent) {
  const runtime::EnvironmentModel& cell = exchange().cell;
  EXPECT_EQ(got.geometry, cell.geometry);
  EXPECT_EQ(got.time, sent.time);
  ASSERT_EQ(got.robots.size(), sent.robots.size());
  for (std::size_t i = 0; i < got.robots.size(); ++i) {
    const runtime::RobotState& g = got.robots[i];
    const runtime::RobotState& s = sent.robots[i];
    const std::string what = "robot " + s.name;
    EXPECT_EQ(g.name, s.name);
    EXPECT_EQ(g.fixed, cell.robots[i].fixed) << what;
    expect_same(g.joints, s.joints, what + " joints");
    expect_same(g.hold, s.hold, what + " hold");
    expect_same(g.dropped_hold, s.dropped_hold, what + " dropped_hold");
    expect_same(g.tcp, s.tcp, what + " tcp");
    expect_same(g.released_tcp, s.released_tcp, what + " released_tcp");
    EXPECT_EQ(g.grip, s.grip) << what;
    ASSERT_EQ(g.wrist_force.has_value(), s.wrist_force.has_value()) << what;
    if (g.wrist_force) expect_same(*g.wrist_force, *s.wrist_force, what + " wrist_force");
  }
  ASSERT_EQ(got.workpieces.size(), sent.workpieces.size());
  for (std::size_t i = 0; i < got.workpieces.size(); ++i) {
    const runtime::WorkpieceState& g = got.workpieces[i];
    const runtime::WorkpieceState& s = sent.workpieces[i];
    const std::string what = "workpiece " + s.name;
    EXPECT_EQ(g.name, s.name);
    EXPECT_EQ(g.fixed, cell.workpieces[i].fixed) << what;
    expect_same(g.pose, s.pose, what + " pose");
    expect_same(g.velocity, s.velocity, what + " velocity");
    EXPECT_EQ(g.motion_known, s.motion_known) << what;
    EXPECT_EQ(g.present, s.present) << what;
    EXPECT_EQ(g.held_by, s.held_by) << what;
    EXPECT_EQ(g.claimed_by, s.claimed_by) << what;
    EXPECT_EQ(bits(g.confidence), bits(s.confidence)) << what;
    EXPECT_EQ(g.stamp, s.stamp) << what;
    EXPECT_EQ(g.lost, s.lost) << what;
    EXPECT_EQ(g.lost_reason, s.lost_reason) << what;
  }
  ASSERT_EQ(got.obstacles.size(), sent.obstacles.size());
  for (std::size_t i = 0; i < got.obstacles.size(); ++i) {
    EXPECT_EQ(got.obstacles[i].name, sent.obstacles[i].name);
    expect_same(got.obstacles[i].centre, sent.obstacles[i].centre, "obstacle centre");
    expect_same(got.obstacles[i].size, sent.obstacles[i].size, "obstacle size");
  }
}

void expect_same_command(const drivers::Command& got, const drivers::Command& sent) {
  ASSERT_EQ(got.index(), sent.index());
  if (const auto* joints = std::get_if<drivers::MoveJoints>(&sent)) {
    const auto& g = std::get<drivers::MoveJoints>(got);
    expect_same(g.positions, joints->positions, "positions");
    EXPECT_EQ(bits(g.speed), bits(joints->speed));
    expect_same(g.duration, joints->duration, "duration");
  } else if (const auto* pose = std::get_if<drivers::MovePose>(&sent)) {
    const auto& g = std::get<drivers::MovePose>(got);
    expect_same(g.pose, pose->pose, "pose");
    EXPECT_EQ(g.path, pose->path);
    EXPECT_EQ(bits(g.speed), bits(pose->speed));
    expect_same(g.duration, pose->duration, "duration");
  } else if (const auto* grip = std::get_if<drivers::Grip>(&sent)) {
    const auto& g = std::get<drivers::Grip>(got);
    EXPECT_EQ(g.action, grip->action);
    expect_same(g.width, grip->width, "width");
    expect_same(g.force, grip->force, "force");
  } else if (const auto* output = std::get_if<drivers::SetOutput>(&sent)) {
    const auto& g = std::get<drivers::SetOutput>(got);
    EXPECT_EQ(g.channel, output->channel);
    EXPECT_EQ(g.on, output->on);
  } else {
    const auto& g = std::get<drivers::WaitInput>(got);
    const auto& w = std::get<drivers::WaitInput>(sent);
    EXPECT_EQ(g.channel, w.channel);
    EXPECT_EQ(g.on, w.on);
    EXPECT_EQ(g.timeout, w.timeout);
  }
}

// The op's field as sent; every other field as a default DriverResult has it (not sent).
void expect_same_result(const DriverResult& got, const DriverResult& sent) {
  const DriverResult none;
  ASSERT_EQ(got.op, sent.op);
  const DriverOp op = sent.op;
  const bool capabilities = op == DriverOp::capabilities;
  const drivers::Capabilities& g = got.capabilities;
  const drivers::Capabilities& s = capabilities ? sent.capabilities : none.capabilities;
  EXPECT_EQ(g.joints, s.joints);
  EXPECT_EQ(g.joint_control, s.joint_control);
  EXPECT_EQ(g.cartesian_control, s.cartesian_control);
  EXPECT_EQ(g.linear_motion, s.linear_motion);
  EXPECT_EQ(g.full_orientation, s.full_orientation);
  EXPECT_EQ(g.gripper, s.gripper);
  EXPECT_EQ(g.gripper_width, s.gripper_width);
  EXPECT_EQ(g.gripper_force, s.gripper_force);
  EXPECT_EQ(bits(g.gripper_max_width), bits(s.gripper_max_width));
  EXPECT_EQ(bits(g.gripper_max_force), bits(s.gripper_max_force));
  EXPECT_EQ(g.digital_outputs, s.digital_outputs);
  EXPECT_EQ(g.digital_inputs, s.digital_inputs);
  expect_same(g.max_joint_speed, s.max_joint_speed, "max_joint_speed");
  EXPECT_EQ(bits(g.max_tool_speed), bits(s.max_tool_speed));
  EXPECT_EQ(g.queue_depth, s.queue_depth);
  EXPECT_EQ(g.reads_joints, s.reads_joints);
  EXPECT_EQ(g.reads_pose, s.reads_pose);
  EXPECT_EQ(g.reads_while_moving, s.reads_while_moving);
  EXPECT_EQ(g.read_time, s.read_time);
  EXPECT_EQ(g.prefers_pose, s.prefers_pose);
  EXPECT_EQ(g.senses_grip, s.senses_grip);
  EXPECT_EQ(g.timed_motion, s.timed_motion);
  EXPECT_EQ(got.state, op == DriverOp::state ? sent.state : none.state);
  const bool error = op == DriverOp::connect || op == DriverOp::activate || op == DriverOp::reset;
  EXPECT_EQ(got.error, error ? sent.error : none.error);
  const bool submitted = op == DriverOp::home || op == DriverOp::submit || op == DriverOp::request_position;
  const drivers::Submitted& sub = submitted ? sent.submitted : none.submitted;
  EXPECT_EQ(got.submitted.id, sub.id);
  EXPECT_EQ(got.submitted.error, sub.error);
  EXPECT_EQ(got.submitted.message, sub.message);
  const drivers::CommandStatus& st = op == DriverOp::poll ? sent.status : none.status;
  EXPECT_EQ(got.status.id, st.id);
  EXPECT_EQ(got.status.phase, st.phase);
  EXPECT_EQ(got.status.error, st.error);
  EXPECT_EQ(got.status.message, st.message);
  const auto& pos = op == DriverOp::last_position ? sent.position : none.position;
  ASSERT_EQ(got.position.has_value(), pos.has_value());
  if (pos) {
    EXPECT_EQ(got.position->request, pos->request);
    EXPECT_EQ(got.position->stamp, pos->stamp);
    expect_same(got.position->joints, pos->joints, "read-back joints");
    expect_same(got.position->tool_pose, pos->tool_pose, "read-back tool pose");
  }
  EXPECT_EQ(got.grip, op == DriverOp::grip_sense ? sent.grip : none.grip);
  expect_same(got.least, op == DriverOp::least_duration ? sent.least : none.least, "least");
}

void expect_same_motion(const runtime::MotionCommand& got, const runtime::MotionCommand& sent) {
  EXPECT_EQ(got.robot, sent.robot);
  EXPECT_EQ(got.index, sent.index);
  EXPECT_EQ(got.transition, sent.transition);
  EXPECT_EQ(got.sent, sent.sent);
  EXPECT_EQ(task::to_string(got.primitive), task::to_string(sent.primitive));
  EXPECT_EQ(got.primitive.where.line, sent.primitive.where.line);
}

TurnMessage random_turn(Random& r, TurnMessage::Kind kind, std::size_t robot) {
  TurnMessage m;
  m.kind = kind;
  m.robot = robot;
  m.sequence = r.bits();
  m.turn = r.bits();
  if (kind == TurnMessage::Kind::kTurn) {
    m.now = std::chrono::nanoseconds(r.non_negative());
    m.commands.resize(r.below(kMaxTurnCommands + 1));
    for (auto& c : m.commands) c = random_motion(r, robot);
    m.model = random_model(r);
  } else if (kind == TurnMessage::Kind::kResult) {
    m.result = random_result(r, static_cast<DriverOp>(r.below(kDriverOps)));
  }
  return m;
}

TurnCall random_call(Random& r, TurnCall::Kind kind, std::size_t robot) {
  TurnCall m;
  m.kind = kind;
  m.robot = robot;
  m.sequence = r.bits();
  m.turn = r.bits();
  if (kind == TurnCall::Kind::kCall) {
    m.call.op = static_cast<DriverOp>(r.below(kDriverOps));
    if (m.call.op == DriverOp::submit || m.call.op == DriverOp::least_duration) {
      m.call.command = random_command(r, r.below(5));
    }
    if (m.call.op == DriverOp::poll) m.call.id = r.bits();
  } else {
    m.events.resize(r.below(8) == 0 ? kMaxTurnEvents : r.below(6));
    for (auto& e : m.events) e = random_event(r);
    m.statuses.resize(r.below(8) == 0 ? kMaxTurnStatuses : r.below(3));
    for (auto& s : m.statuses) s = random_status(r, robot);
    m.model = random_model(r);
    m.error = r.coin() ? std::string() : r.text(kEventLineBound);
    m.settings = r.coin() ? std::string() : r.text(1024);
  }
  return m;
}

TurnMessage decode_turn_of(const std::vector<char>& bytes, std::size_t robot) {
  return decode_turn(bytes, robot, exchange().program, exchange().cell);
}

TurnCall decode_call_of(const std::vector<char>& bytes, std::size_t robot) {
  return decode_turn_call(bytes, robot, exchange().cell);
}

// ---- Round trips ----

TEST(TurnWire, SeededRandomTurnsComeBackFieldByFieldBitForBit) {
  Random r(28);
  for (auto kind : {TurnMessage::Kind::kTurn, TurnMessage::Kind::kResult, TurnMessage::Kind::kEnd}) {
    for (int n = 0; n < 200; ++n) {
      SCOPED_TRACE(::testing::Message() << "kind " << static_cast<int>(kind) << " sample " << n);
      const std::size_t robot = r.below(2);
      const TurnMessage sent = random_turn(r, kind, robot);
      const std::vector<char> bytes = encode_turn(sent);
      ASSERT_LE(bytes.size(), max_turn_size());
      ASSERT_EQ(std::string(bytes.data(), 4), std::string("\0\1\0\0", 4));  // XCDR1 little-endian
      const TurnMessage got = decode_turn_of(bytes, robot);
      EXPECT_EQ(encode_turn(got), bytes);  // the same message, the same bytes (its padding too)
      EXPECT_EQ(got.kind, sent.kind);
      EXPECT_EQ(got.robot, robot);
      EXPECT_EQ(got.sequence, sent.sequence);
      EXPECT_EQ(got.turn, sent.turn);
      if (kind == TurnMessage::Kind::kTurn) {
        EXPECT_EQ(got.now, sent.now);
        ASSERT_EQ(got.commands.size(), sent.commands.size());
        for (std::size_t i = 0; i < got.commands.size(); ++i) expect_same_motion(got.commands[i], sent.commands[i]);
        expect_same_model(got.model, sent.model);
      } else if (kind == TurnMessage::Kind::kResult) {
        expect_same_result(got.result, sent.result);
      }
    }
  }
}

TEST(TurnWire, SeededRandomCallsComeBackFieldByFieldBitForBit) {
  Random r(29);
  for (auto kind : {TurnCall::Kind::kCall, TurnCall::Kind::kDone}) {
    for (int n = 0; n < 200; ++n) {
      SCOPED_TRACE(::testing::Message() << "kind " << static_cast<int>(kind) << " sample " << n);
      const std::size_t robot = r.below(2);
      const TurnCall sent = random_call(r, kind, robot);
      const std::vector<char> bytes = encode_turn_call(sent);
      ASSERT_LE(bytes.size(), max_turn_call_size());
      ASSERT_EQ(std::string(bytes.data(), 4), std::string("\0\1\0\0", 4));
      const TurnCall got = decode_call_of(bytes, robot);
      EXPECT_EQ(encode_turn_call(got), bytes);
      EXPECT_EQ(got.kind, sent.kind);
      EXPECT_EQ(got.robot, robot);
      EXPECT_EQ(got.sequence, sent.sequence);
      EXPECT_EQ(got.turn, sent.turn);
      if (kind == TurnCall::Kind::kCall) {
        EXPECT_EQ(got.call.op, sent.call.op);
        EXPECT_EQ(got.call.id, sent.call.id);
        expect_same_command(got.call.command, sent.call.command);
      } else {
        EXPECT_EQ(got.events, sent.events);
        ASSERT_EQ(got.statuses.size(), sent.statuses.size());
        for (std::size_t i = 0; i < got.statuses.size(); ++i) {
          EXPECT_EQ(got.statuses[i].robot, sent.statuses[i].robot);
          EXPECT_EQ(got.statuses[i].index, sent.statuses[i].index);
          EXPECT_EQ(got.statuses[i].outcome, sent.statuses[i].outcome);
          EXPECT_EQ(got.statuses[i].reason, sent.statuses[i].reason);
          EXPECT_EQ(got.statuses[i].stop_cell, sent.statuses[i].stop_cell);
          EXPECT_EQ(got.statuses[i].time, sent.statuses[i].time);
        }
        expect_same_model(got.model, sent.model);
        EXPECT_EQ(got.error, sent.error);
        EXPECT_EQ(got.settings, sent.settings);
      }
    }
  }
}

TEST(TurnWire, EveryDriverCallAndEachOfItsAnswersComeBack) {
  Random r(30);
  for (std::size_t op = 0; op < kDriverOps; ++op) {
    SCOPED_TRACE(to_string(static_cast<DriverOp>(op)));
    for (int n = 0; n < 20; ++n) {
      TurnMessage answer;
      answer.kind = TurnMessage::Kind::kResult;
      answer.result = random_result(r, static_cast<DriverOp>(op));
      expect_same_result(decode_turn_of(encode_turn(answer), 0).result, answer.result);
    }
    for (std::size_t alternative = 0; alternative < 5; ++alternative) {
      TurnCall call;
      call.call.op = static_cast<DriverOp>(op);
      call.call.command = random_command(r, alternative);
      call.call.id = 77;
      const DriverCall got = decode_call_of(encode_turn_call(call), 0).call;
      EXPECT_EQ(got.op, call.call.op);
      const bool command = call.call.op == DriverOp::submit || call.call.op == DriverOp::least_duration;
      expect_same_command(got.command, command ? call.call.command : drivers::Command{});
      EXPECT_EQ(got.id, call.call.op == DriverOp::poll ? 77u : 0u);
    }
  }
  // Messages too long for their field are cut, the rest of the answer intact.
  TurnMessage answer;
  answer.kind = TurnMessage::Kind::kResult;
  answer.result.op = DriverOp::poll;
  answer.result.status = {9, drivers::CommandPhase::failed, drivers::ErrorCode::hardware, std::string(5000, 'x')};
  const DriverResult got = decode_turn_of(encode_turn(answer), 0).result;
  EXPECT_EQ(got.status.message, std::string(kMessageBound - 1, 'x'));
  EXPECT_EQ(got.status.error, drivers::ErrorCode::hardware);
  EXPECT_STREQ(to_string(DriverOp::request_position), "request_position");
  EXPECT_EQ(turn_topic("puma"), "rt/cellwright/puma/turn");
  EXPECT_EQ(call_topic("puma"), "rt/cellwright/puma/call");
}

// ---- Refusals ----

// What decoding `bytes` as robot 0's says; "" when it decodes.
std::string refusal(const std::vector<char>& bytes, bool call) {
  try {
    if (call) {
      (void)decode_call_of(bytes, 0);
    } else {
      (void)decode_turn_of(bytes, 0);
    }
  } catch (const WireError& e) {
    return e.what();
  }
  return "";
}

// The model with its long texts shortened and a few obstacles: every truncation of a sample is decoded, so samples
// are kept to a few kilobytes.
void shorten(runtime::EnvironmentModel& m) {
  for (runtime::WorkpieceState& w : m.workpieces) w.lost_reason.resize(std::min<std::size_t>(w.lost_reason.size(), 9));
  m.obstacles.resize(std::min<std::size_t>(m.obstacles.size(), 2));
}

// One sample of each kind, each driver op's answer and each command's alternative, every optional set somewhere.
std::vector<std::vector<char>> samples_of_every_kind(bool call) {
  Random r(31);
  std::vector<std::vector<char>> samples;
  if (call) {
    TurnCall done = random_call(r, TurnCall::Kind::kDone, 0);
    shorten(done.model);
    done.events.resize(2, random_event(r));
    done.statuses.assign(2, random_status(r, 0));
    for (runtime::RobotStatus& s : done.statuses) s.reason.resize(std::min<std::size_t>(s.reason.size(), 9));
    done.error = "it threw";
    samples.push_back(encode_turn_call(done));
    TurnCall c;
    for (std::size_t op = 0; op < kDriverOps; ++op) {
      c.call.op = static_cast<DriverOp>(op);
      c.call.id = r.bits();
      for (std::size_t a = 0; a < 5; ++a) {
        c.call.command = random_command(r, a);
        samples.push_back(encode_turn_call(c));
      }
    }
  } else {
    for (int n = 0; n < 2; ++n) {
      TurnMessage turn = random_turn(r, TurnMessage::Kind::kTurn, 0);
      shorten(turn.model);
      samples.push_back(encode_turn(turn));
    }
    samples.push_back(encode_turn(random_turn(r, TurnMessage::Kind::kEnd, 0)));
    TurnMessage result;
    result.kind = TurnMessage::Kind::kResult;
    for (std::size_t op = 0; op < kDriverOps; ++op) {
      for (int n = 0; n < 2; ++n) {
        result.result = random_result(r, static_cast<DriverOp>(op));
        samples.push_back(encode_turn(result));
      }
    }
  }
  return samples;
}

TEST(TurnWire, EveryTruncationOfAValidSampleIsRefusedAndSoIsWhatFollowsIt) {
  for (bool call : {false, true}) {
    for (const std::vector<char>& bytes : samples_of_every_kind(call)) {
      ASSERT_EQ(refusal(bytes, call), "");
      for (std::size_t cut = 0; cut < bytes.size(); ++cut) {
        EXPECT_NE(refusal(std::vector<char>(bytes.begin(), bytes.begin() + static_cast<long>(cut)), call), "")
            << "cut at " << cut << " of " << bytes.size();
      }
      std::vector<char> longer = bytes;
      longer.resize(bytes.size() + 4, '\0');
      EXPECT_NE(refusal(longer, call).find("bytes after the message"), std::string::npos);
    }
  }
}

TEST(TurnWire, RandomBytesAreRefused) {
  Random r(32);
  for (int n = 0; n < 500; ++n) {
    std::vector<char> garbage(r.below(600));
    for (char& c : garbage) c = static_cast<char>(r.bits());
    if (garbage.size() >= 8 && r.coin()) {
      // A CDR little-endian header and robot 0: the body is what must be refused.
      const char head[8] = {0, 1, 0, 0, 0, 0, 0, 0};
      std::copy(head, head + 8, garbage.begin());
    }
    EXPECT_NE(refusal(garbage, false), "") << n;
    EXPECT_NE(refusal(garbage, true), "") << n;
  }
}

// The first byte where two encodings differ (the field the two messages differ in).
std::size_t first_difference(const std::vector<char>& a, const std::vector<char>& b) {
  std::size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  return i;
}

// `bytes` with byte `at` set to `value`: what decoding it says.
std::string refusal_with(std::vector<char> bytes, std::size_t at, std::uint8_t value, bool call) {
  bytes.at(at) = static_cast<char>(value);
  return refusal(bytes, call);
}

TEST(TurnWire, AnEnumOutOfRangeIsRefusedEachEnum) {
  // Turn_'s kind: an end and a result differ first in it.
  TurnMessage end, result;
  end.kind = TurnMessage::Kind::kEnd;
  result.kind = TurnMessage::Kind::kResult;
  const std::size_t kind = first_difference(encode_turn(end), encode_turn(result));
  EXPECT_NE(refusal_with(encode_turn(end), kind, 3, false).find("0 turn, 1 result, 2 end"), std::string::npos);
  TurnCall call, done;
  done.kind = TurnCall::Kind::kDone;
  done.model = exchange().cell;
  EXPECT_NE(refusal_with(encode_turn_call(call), kind, 2, true).find("0 call, 1 done"), std::string::npos);

  // DriverCall_'s op, DriverCommand_'s alternative, MovePose_'s path, Grip_'s action.
  call.call.op = DriverOp::state;
  EXPECT_NE(refusal_with(encode_turn_call(call), kind + 1, 14, true).find("DriverCall_.op"), std::string::npos);
  call.call.op = DriverOp::submit;
  call.call.command = drivers::SetOutput{3, true};
  EXPECT_NE(refusal_with(encode_turn_call(call), kind + 2, 5, true).find("DriverCommand_"), std::string::npos);
  auto refused_where = [&](drivers::Command a, drivers::Command b, std::uint8_t value) {
    TurnCall x, y;
    x.call.op = y.call.op = DriverOp::submit;
    x.call.command = a;
    y.call.command = b;
    const std::vector<char> bytes = encode_turn_call(x);
    return refusal_with(bytes, first_difference(bytes, encode_turn_call(y)), value, true);
  };
  EXPECT_NE(refused_where(drivers::MovePose{},
                          drivers::MovePose{Eigen::Isometry3d::Identity(), drivers::Path::linear, 1.0, std::nullopt}, 2)
                .find("MovePose_.path"),
            std::string::npos);
  EXPECT_NE(refused_where(drivers::Grip{drivers::Grip::Action::open, std::nullopt, std::nullopt},
                          drivers::Grip{drivers::Grip::Action::close, std::nullopt, std::nullopt}, 2)
                .find("Grip_.action"),
            std::string::npos);
  // A boolean that is neither 0 nor 1.
  EXPECT_NE(refused_where(drivers::SetOutput{1, false}, drivers::SetOutput{1, true}, 2), "");

  // DriverResult_'s op and its enums: the state, an error code (alone, in Submitted_, in CommandStatus_), a phase,
  // a grip sense.
  auto refused_answer = [&](DriverResult a, DriverResult b, std::uint8_t value) {
    TurnMessage x, y;
    x.kind = y.kind = TurnMessage::Kind::kResult;
    x.result = a;
    y.result = b;
    const std::vector<char> bytes = encode_turn(x);
    return refusal_with(bytes, first_difference(bytes, encode_turn(y)), value, false);
  };
  DriverResult a, b;
  a.op = DriverOp::capabilities;
  b.op = DriverOp::state;
  EXPECT_NE(refused_answer(a, b, 14).find("DriverResult_.op"), std::string::npos);
  a.op = b.op = DriverOp::state;
  b.state = drivers::DriverState::fault;
  EXPECT_NE(refused_answer(a, b, 6).find("DriverResult_.state"), std::string::npos);
  a.op = b.op = DriverOp::connect;
  b.error = drivers::ErrorCode::busy;
  EXPECT_NE(refused_answer(a, b, 13).find("DriverResult_.error"), std::string::npos);
  a.op = b.op = DriverOp::submit;
  b.submitted.error = drivers::ErrorCode::busy;
  EXPECT_NE(refused_answer(a, b, 13).find("Submitted_.error"), std::string::npos);
  a.op = b.op = DriverOp::poll;
  b.status.phase = drivers::CommandPhase::done;
  EXPECT_NE(refused_answer(a, b, 4).find("CommandStatus_.phase"), std::string::npos);
  b.status.phase = drivers::CommandPhase::pending;
  b.status.error = drivers::ErrorCode::busy;
  EXPECT_NE(refused_answer(a, b, 13).find("CommandStatus_.error"), std::string::npos);
  a.op = b.op = DriverOp::grip_sense;
  a.grip = drivers::GripSense::open;
  b.grip = drivers::GripSense::closed_on_part;
  EXPECT_NE(refused_answer(a, b, 3).find("DriverResult_.grip"), std::string::npos);

  // A hold's approach in the model, a status's outcome.
  TurnCall side = done;
  runtime::Hold hold;
  hold.workpiece = "A";
  done.model.robots[0].hold = hold;
  hold.approach = models::Approach::kSide;
  side.model.robots[0].hold = hold;
  const std::vector<char> down_bytes = encode_turn_call(done);
  EXPECT_NE(
      refusal_with(down_bytes, first_difference(down_bytes, encode_turn_call(side)), 2, true).find("0 down, 1 side"),
      std::string::npos);
  TurnCall failed = done;
  done.statuses.push_back(runtime::RobotStatus{});
  failed.statuses.push_back(runtime::RobotStatus{});
  failed.statuses[0].outcome = runtime::CommandOutcome::kFailed;
  const std::vector<char> ok_bytes = encode_turn_call(done);
  EXPECT_NE(refusal_with(ok_bytes, first_difference(ok_bytes, encode_turn_call(failed)), 2, true).find("outcome 2"),
            std::string::npos);
}

TEST(TurnWire, StringsWithoutTheirNulOrOverTheirBoundAreRefused) {
  TurnCall done;
  done.kind = TurnCall::Kind::kDone;
  done.model = exchange().cell;
  done.settings = "abc";  // the last field: its length, then a b c NUL
  std::vector<char> bytes = encode_turn_call(done);
  ASSERT_EQ(refusal(bytes, true), "");
  std::vector<char> no_nul = bytes;
  no_nul.back() = 'x';
  EXPECT_NE(refusal(no_nul, true).find("TurnDone_.settings: a misplaced NUL"), std::string::npos);
  std::vector<char> inner_nul = bytes;
  inner_nul[inner_nul.size() - 3] = '\0';
  EXPECT_NE(refusal(inner_nul, true).find("misplaced NUL"), std::string::npos);
  // Over its bound: the length says 1025 bytes, and they are there.
  std::vector<char> over(bytes.begin(), bytes.end() - 8);
  const std::uint32_t length = 1024 + 1;
  over.insert(over.end(), reinterpret_cast<const char*>(&length), reinterpret_cast<const char*>(&length) + 4);
  over.insert(over.end(), length - 1, 'x');
  over.push_back('\0');
  EXPECT_NE(refusal(over, true).find("TurnDone_.settings: a string of 1025 bytes with its NUL (1..1024)"),
            std::string::npos);
  // The encoder: an error is cut to fit (the run fails with it anyway); a name, a line, a reason is not.
  done.error.assign(20000, 'e');
  EXPECT_EQ(decode_call_of(encode_turn_call(done), 0).error, std::string(kEventLineBound - 1, 'e'));
  done.error.clear();
  TurnCall long_name = done;
  long_name.model.robots[0].name.assign(kNameBound, 'p');
  EXPECT_THROW(encode_turn_call(long_name), WireError);
  TurnCall long_line = done;
  long_line.events.assign(1, std::string(kEventLineBound, '{'));
  EXPECT_THROW(encode_turn_call(long_line), WireError);
  TurnCall long_reason = done;
  long_reason.statuses.assign(1, runtime::RobotStatus{});
  long_reason.statuses[0].reason.assign(kEventLineBound, 'r');
  EXPECT_THROW(encode_turn_call(long_reason), WireError);
  TurnCall long_lost = done;
  long_lost.model.workpieces[0].lost_reason.assign(kEventLineBound, 'r');
  EXPECT_THROW(encode_turn_call(long_lost), WireError);
}

TEST(TurnWire, AnotherRobotsSampleIsRefused) {
  Random r(33);
  EXPECT_NE(
      refusal(encode_turn(random_turn(r, TurnMessage::Kind::kEnd, 1)), false).find("a turn of robot 1 on robot 0"),
      std::string::npos);
  EXPECT_NE(refusal(encode_turn_call(random_call(r, TurnCall::Kind::kCall, 1)), true).find("of robot 1 on robot 0"),
            std::string::npos);
  // Inside a sample of this robot: another robot's command, another robot's status.
  TurnMessage turn = random_turn(r, TurnMessage::Kind::kTurn, 0);
  turn.commands.assign(1, random_motion(r, 1));
  EXPECT_NE(refusal(encode_turn(turn), false).find("a command for robot 1 on robot 0's topic"), std::string::npos);
  TurnCall done = random_call(r, TurnCall::Kind::kDone, 0);
  done.statuses.assign(1, random_status(r, 1));
  EXPECT_NE(refusal(encode_turn_call(done), true).find("a status of robot 1 on robot 0's topic"), std::string::npos);
}

TEST(TurnWire, AModelThatIsNotTheCellsByNameAndOrderIsRefusedNamingThem) {
  const runtime::EnvironmentModel& cell = exchange().cell;
  ASSERT_GE(cell.robots.size(), 2u);
  ASSERT_GE(cell.workpieces.size(), 1u);
  TurnMessage turn;
  turn.kind = TurnMessage::Kind::kTurn;
  auto refused = [&](const runtime::EnvironmentModel& m) {
    turn.model = m;
    const std::string turn_says = refusal(encode_turn(turn), false);
    TurnCall done;
    done.kind = TurnCall::Kind::kDone;
    done.model = m;
    EXPECT_EQ(refusal(encode_turn_call(done), true), turn_says);
    return turn_says;
  };
  EXPECT_EQ(refused(cell), "");
  runtime::EnvironmentModel renamed = cell;
  renamed.robots[1].name = "kuka";
  EXPECT_NE(refused(renamed).find("robots are [puma, kuka] on the wire, [puma, melfa] in this cell"), std::string::npos)
      << refused(renamed);
  runtime::EnvironmentModel missing = cell;
  missing.robots.pop_back();
  EXPECT_NE(refused(missing).find("robots are [puma] on the wire"), std::string::npos);
  runtime::EnvironmentModel reordered = cell;
  std::swap(reordered.robots[0], reordered.robots[1]);
  EXPECT_NE(refused(reordered).find("[melfa, puma] on the wire"), std::string::npos);

  const std::string first = cell.workpieces[0].name;
  runtime::EnvironmentModel part_renamed = cell;
  part_renamed.workpieces[0].name = "Z";
  EXPECT_NE(refused(part_renamed).find("workpieces are [Z"), std::string::npos);
  runtime::EnvironmentModel part_missing = cell;
  part_missing.workpieces.erase(part_missing.workpieces.begin());
  EXPECT_NE(refused(part_missing).find("the model's workpieces are"), std::string::npos);
  runtime::EnvironmentModel part_added = cell;
  part_added.workpieces.push_back(cell.workpieces[0]);
  EXPECT_NE(refused(part_added).find("the model's workpieces are"), std::string::npos);
  if (cell.workpieces.size() >= 2) {
    runtime::EnvironmentModel part_reordered = cell;
    std::swap(part_reordered.workpieces[0], part_reordered.workpieces[1]);
    EXPECT_NE(refused(part_reordered).find("the model's workpieces are"), std::string::npos);
  }
  // Values no model has: a number that is not finite, a rotation that is none, a time before the run.
  runtime::EnvironmentModel nan = cell;
  nan.workpieces[0].confidence = std::nan("");
  EXPECT_NE(refused(nan).find("Workpiece_.confidence"), std::string::npos);
  runtime::EnvironmentModel skewed = cell;
  skewed.robots[0].tcp = Eigen::Isometry3d::Identity();
  skewed.robots[0].tcp->matrix()(0, 1) = 0.1;
  EXPECT_NE(refused(skewed).find("Robot_.tcp: no rotation"), std::string::npos);
  runtime::EnvironmentModel early = cell;
  early.time = std::chrono::nanoseconds(-1);
  EXPECT_NE(refused(early).find("before the run began"), std::string::npos);
}

TEST(TurnWire, ACommandThatIsNotTheProgramsPrimitiveIsRefused) {
  const auto& primitives = exchange().program.programs[0].primitives;
  std::size_t i = 0;
  while (i + 1 < primitives.size() && task::to_string(primitives[i]) == task::to_string(primitives[i + 1])) ++i;
  ASSERT_LT(i + 1, primitives.size());
  TurnMessage turn;
  turn.kind = TurnMessage::Kind::kTurn;
  turn.model = exchange().cell;
  runtime::MotionCommand c;
  c.index = i;
  c.primitive = primitives[i + 1];  // another primitive's text at index i
  turn.commands.assign(1, c);
  EXPECT_NE(refusal(encode_turn(turn), false).find("on the wire (another program?)"), std::string::npos);
  turn.commands[0].index = primitives.size();
  EXPECT_NE(refusal(encode_turn(turn), false).find("its program has"), std::string::npos);
  turn.commands[0].index = i;
  turn.commands[0].primitive = primitives[i];
  EXPECT_EQ(refusal(encode_turn(turn), false), "");
  turn.now = std::chrono::nanoseconds(-5);
  EXPECT_NE(refusal(encode_turn(turn), false).find("a turn at -5 ns"), std::string::npos);
}

TEST(TurnWire, AnEventLineThatIsNoEventOfTheLogIsRefused) {
  Random r(34);
  TurnCall done;
  done.kind = TurnCall::Kind::kDone;
  done.model = exchange().cell;
  done.events = {random_event(r), random_event(r)};
  EXPECT_EQ(refusal(encode_turn_call(done), true), "");
  for (const char* line : {"not json", "{\"t\":1,\"type\":\"nonsense\"}", "{\"t\":1.0,\"type\":\"command_end\"}", ""}) {
    done.events[1] = line;
    EXPECT_NE(refusal(encode_turn_call(done), true).find("event 2 of the turn is no event of the log"),
              std::string::npos)
        << line;
  }
}

TEST(TurnWire, CountsOverTheirBoundsAreNotEncodedNorDecoded) {
  const runtime::EnvironmentModel& cell = exchange().cell;
  TurnMessage turn;
  turn.kind = TurnMessage::Kind::kTurn;
  turn.model = cell;
  auto turn_throws = [&](const std::function<void(TurnMessage&)>& change) {
    TurnMessage m = turn;
    change(m);
    EXPECT_THROW(encode_turn(m), WireError);
  };
  turn_throws([](TurnMessage& m) { m.model.robots.resize(kMaxRobots + 1, m.model.robots[0]); });
  turn_throws([](TurnMessage& m) { m.model.workpieces.resize(kMaxWorkpieces + 1, m.model.workpieces[0]); });
  turn_throws([](TurnMessage& m) { m.model.obstacles.resize(kMaxObstacles + 1); });
  turn_throws([](TurnMessage& m) { m.model.robots[0].joints.resize(kMaxJoints + 1); });
  turn_throws([](TurnMessage& m) { m.commands.resize(kMaxTurnCommands + 1); });
  turn_throws([](TurnMessage& m) {
    m.kind = TurnMessage::Kind::kResult;
    m.result.op = DriverOp::capabilities;
    m.result.capabilities.max_joint_speed.resize(kMaxJoints + 1);
  });
  turn_throws([](TurnMessage& m) {
    m.kind = TurnMessage::Kind::kResult;
    m.result.op = DriverOp::last_position;
    m.result.position = drivers::PositionReading{};
    m.result.position->joints.resize(kMaxJoints + 1);
  });
  TurnCall done;
  done.kind = TurnCall::Kind::kDone;
  done.model = cell;
  TurnCall many = done;
  many.events.assign(kMaxTurnEvents + 1, "{}");
  EXPECT_THROW(encode_turn_call(many), WireError);
  many = done;
  many.statuses.resize(kMaxTurnStatuses + 1);
  EXPECT_THROW(encode_turn_call(many), WireError);
  TurnCall submit;
  submit.call.op = DriverOp::submit;
  submit.call.command = drivers::MoveJoints{std::vector<double>(kMaxJoints + 1, 0.0), 1.0, std::nullopt};
  EXPECT_THROW(encode_turn_call(submit), WireError);

  // On the wire: a count over its bound is refused before anything is read of it. The counts sit where a sample with
  // none and one with one differ first.
  auto count_refused = [](std::vector<char> bytes, std::size_t at, std::uint32_t n, bool call) {
    std::memcpy(bytes.data() + at, &n, 4);
    return refusal(bytes, call);
  };
  TurnMessage one = turn;
  one.commands.assign(1, runtime::MotionCommand{0, 0, exchange().program.programs[0].primitives[0], 0, {}});
  const std::vector<char> none_bytes = encode_turn(turn);
  const std::size_t commands_at = first_difference(none_bytes, encode_turn(one));
  EXPECT_NE(count_refused(none_bytes, commands_at, kMaxTurnCommands + 1, false).find("9 elements, over the bound of 8"),
            std::string::npos)
      << count_refused(none_bytes, commands_at, kMaxTurnCommands + 1, false) << " at " << commands_at;
  TurnCall with_event = done;
  with_event.events.assign(1, "{}");
  const std::vector<char> no_events = encode_turn_call(done);
  const std::size_t events_at = first_difference(no_events, encode_turn_call(with_event));
  EXPECT_NE(count_refused(no_events, events_at, 1000000, true).find("TurnDone_.events: 1000000 elements"),
            std::string::npos)
      << count_refused(no_events, events_at, 1000000, true) << " at " << events_at;
}

// ---- Sizes ----

TEST(TurnWire, ASampleAtEveryBoundFitsTheLargestSize) {
  // Every sequence full, every string at its bound, every optional set.
  const std::string name(kNameBound - 1, 'n');
  runtime::EnvironmentModel m;
  runtime::RobotState robot;
  robot.name = name;
  robot.joints.assign(kMaxJoints, 1.5);
  runtime::Hold hold{name, models::Approach::kSide, 0.1, Eigen::Isometry3d::Identity()};
  robot.hold = robot.dropped_hold = hold;
  robot.tcp = robot.released_tcp = Eigen::Isometry3d::Identity();
  robot.grip = runtime::GripReading::of(name);
  robot.wrist_force = Eigen::Vector3d(1, 2, 3);
  m.robots.assign(kMaxRobots, robot);
  runtime::WorkpieceState part;
  part.name = part.held_by = part.claimed_by = name;
  part.lost_reason.assign(kEventLineBound - 1, 'l');
  m.workpieces.assign(kMaxWorkpieces, part);
  m.obstacles.assign(kMaxObstacles, runtime::ObstacleState{name, Eigen::Vector3d::Ones(), Eigen::Vector3d::Ones()});

  TurnMessage turn;
  turn.model = m;
  runtime::MotionCommand command;
  command.primitive.kind = task::PrimitiveKind::kSignal;
  command.primitive.event.assign(2 * kPrimitiveTextBound, 'e');
  turn.commands.assign(kMaxTurnCommands, command);
  const std::size_t largest_turn = encode_turn(turn).size();
  EXPECT_EQ(largest_turn, max_turn_size());  // the turn with the largest model is the largest Turn_
  Random r(35);
  TurnMessage answer;
  answer.kind = TurnMessage::Kind::kResult;
  for (std::size_t op = 0; op < kDriverOps; ++op) {
    answer.result = random_result(r, static_cast<DriverOp>(op));
    answer.result.capabilities.max_joint_speed.assign(kMaxJoints, 2.0);
    answer.result.submitted.message.assign(kMessageBound + 10, 'm');
    answer.result.status.message.assign(kMessageBound + 10, 'm');
    answer.result.position =
        drivers::PositionReading{1, {}, std::vector<double>(kMaxJoints), Eigen::Isometry3d::Identity()};
    EXPECT_LE(encode_turn(answer).size(), max_turn_size()) << op;
  }

  TurnCall done;
  done.kind = TurnCall::Kind::kDone;
  done.model = m;
  done.events.assign(kMaxTurnEvents, std::string(kEventLineBound - 1, 'x'));
  runtime::RobotStatus status;
  status.index = 12;
  status.reason.assign(kEventLineBound - 1, 'r');
  done.statuses.assign(kMaxTurnStatuses, status);
  done.error.assign(3 * kEventLineBound, 'e');
  done.settings.assign(1023, 's');  // string<1024>
  EXPECT_EQ(encode_turn_call(done).size(), max_turn_call_size());
  done.settings.assign(1024, 's');
  EXPECT_THROW((void)encode_turn_call(done), WireError);  // over its bound: refused, never cut
  TurnCall call;
  for (std::size_t op = 0; op < kDriverOps; ++op) {
    for (std::size_t alternative = 0; alternative < 5; ++alternative) {
      call.call.op = static_cast<DriverOp>(op);
      call.call.command = random_command(r, alternative);
      if (auto* joints = std::get_if<drivers::MoveJoints>(&call.call.command)) joints->positions.resize(kMaxJoints);
      EXPECT_LE(encode_turn_call(call).size(), max_turn_call_size());
    }
  }
  // Smaller than the DDS types' sizes would make them useless: a few hundred KB to a little over a MB.
  EXPECT_LT(max_turn_call_size(), std::size_t{2} << 20);
}

}  // namespace
}  // namespace cellwright::distributed
