#include "cellwright/distributed/replica.hpp"

#include <atomic>
#include <cmath>
#include <iostream>
#include <limits>
#include <mutex>

#include <fmt/format.h>

#include "cdr_io.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/distributed/wire.hpp"

namespace cellwright::distributed {
namespace {

using cdr_io::nanoseconds;

// cdr_io's writer with Pose_ and Hold_.
class Out : public cdr_io::Out {
 public:
  using cdr_io::Out::Out;
  void pose(const Eigen::Isometry3d& p) {
    const Eigen::Quaterniond q(p.linear());
    cdr() << p.translation().x() << p.translation().y() << p.translation().z() << q.w() << q.x() << q.y() << q.z();
  }
  void hold(const std::optional<runtime::Hold>& h) {
    cdr() << h.has_value();
    runtime::Hold none;
    const runtime::Hold& v = h ? *h : none;
    text(v.workpiece, kNameBound, "Hold_.workpiece");
    cdr() << static_cast<std::uint8_t>(v.approach == models::Approach::kSide ? 1 : 0) << v.tcp_above_bottom;
    pose(v.in_hand);
  }
};

// cdr_io's reader with Pose_ and Hold_.
class In : public cdr_io::In {
 public:
  using cdr_io::In::In;
  Eigen::Isometry3d pose(const char* field) {
    double v[7];
    for (double& x : v) x = number(field);
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-6) throw WireError(fmt::format("{}: a rotation of norm {}", field, q.norm()));
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() = q.normalized().toRotationMatrix();
    p.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    return p;
  }
  std::optional<runtime::Hold> hold(const char* field) {
    const bool set = get<bool>();
    runtime::Hold h;
    h.workpiece = text(kNameBound, field);
    const auto approach = get<std::uint8_t>();
    if (approach > 1) throw WireError(fmt::format("{}: approach {} (0 down, 1 side)", field, approach));
    h.approach = approach == 1 ? models::Approach::kSide : models::Approach::kDown;
    h.tcp_above_bottom = number(field);
    h.in_hand = pose(field);
    if (!set) return std::nullopt;
    return h;
  }
};

bool same_pose(const std::optional<Eigen::Isometry3d>& a, const std::optional<Eigen::Isometry3d>& b) {
  if (a.has_value() != b.has_value()) return false;
  return !a || a->matrix() == b->matrix();
}

bool same_hold(const std::optional<runtime::Hold>& a, const std::optional<runtime::Hold>& b) {
  if (a.has_value() != b.has_value()) return false;
  return !a || (a->workpiece == b->workpiece && a->approach == b->approach &&
                a->tcp_above_bottom == b->tcp_above_bottom && a->in_hand.matrix() == b->in_hand.matrix());
}

bool same_workpiece(const runtime::WorkpieceState& a, const runtime::WorkpieceState& b) {
  return a.pose.matrix() == b.pose.matrix() && a.velocity == b.velocity && a.motion_known == b.motion_known &&
         a.present == b.present && a.held_by == b.held_by && a.claimed_by == b.claimed_by &&
         a.confidence == b.confidence && a.stamp == b.stamp && a.lost == b.lost && a.lost_reason == b.lost_reason;
}

}  // namespace

std::string model_topic(const std::string& robot) {
  // The robot's name checked as the link's topics check it.
  const std::string command = command_topic(robot);
  return command.substr(0, command.size() - std::string("command").size()) + "model";
}

std::string events_topic(const std::string& robot) {
  const std::string command = command_topic(robot);
  return command.substr(0, command.size() - std::string("command").size()) + "events";
}

std::optional<ModelUpdate> changes(const runtime::EnvironmentModel& before, const runtime::EnvironmentModel& after,
                                   const std::string& robot, std::size_t index) {
  const runtime::RobotState* was = before.find_robot(robot);
  const runtime::RobotState* now = after.find_robot(robot);
  CW_CHECK(was != nullptr && now != nullptr, "robot {} is not in the model", robot);
  ModelUpdate u;
  u.robot = index;
  u.time = after.time;
  bool changed = was->joints != now->joints || !same_hold(was->hold, now->hold) ||
                 !same_hold(was->dropped_hold, now->dropped_hold) || !same_pose(was->tcp, now->tcp) ||
                 !same_pose(was->released_tcp, now->released_tcp);
  CW_CHECK(before.workpieces.size() == after.workpieces.size(), "the model's workpieces changed in number");
  for (std::size_t w = 0; w < after.workpieces.size(); ++w) {
    if (same_workpiece(before.workpieces[w], after.workpieces[w])) continue;
    u.workpieces.push_back(after.workpieces[w]);
    u.workpieces.back().fixed = nullptr;
    changed = true;
  }
  if (!changed) return std::nullopt;
  u.state.name = now->name;
  u.state.joints = now->joints;
  u.state.hold = now->hold;
  u.state.dropped_hold = now->dropped_hold;
  u.state.tcp = now->tcp;
  u.state.released_tcp = now->released_tcp;
  return u;
}

void apply(runtime::EnvironmentModel& model, const ModelUpdate& update) {
  runtime::RobotState* r = model.find_robot(update.state.name);
  if (r == nullptr) throw WireError(fmt::format("an update of robot '{}', which the cell does not have", update.state.name));
  if (r->joints.size() != update.state.joints.size()) {
    throw WireError(fmt::format("an update of robot '{}' with {} joints, which has {}", update.state.name,
                                update.state.joints.size(), r->joints.size()));
  }
  for (const runtime::WorkpieceState& w : update.workpieces) {
    if (model.find_workpiece(w.name) == nullptr) {
      throw WireError(fmt::format("an update of workpiece '{}', which the cell does not have", w.name));
    }
  }
  r->joints = update.state.joints;
  r->hold = update.state.hold;
  r->dropped_hold = update.state.dropped_hold;
  r->tcp = update.state.tcp;
  r->released_tcp = update.state.released_tcp;
  for (const runtime::WorkpieceState& w : update.workpieces) {
    runtime::WorkpieceState* mine = model.find_workpiece(w.name);
    const runtime::CellWorkpiece* fixed = mine->fixed;
    *mine = w;
    mine->fixed = fixed;
  }
}

std::vector<char> encode_model_update(const ModelUpdate& u) {
  if (u.state.joints.size() > kMaxJoints) throw WireError(fmt::format("{} joints, over {}", u.state.joints.size(), kMaxJoints));
  if (u.workpieces.size() > kMaxWorkpieces) {
    throw WireError(fmt::format("{} workpieces, over {}", u.workpieces.size(), kMaxWorkpieces));
  }
  if (u.robot > std::numeric_limits<std::uint32_t>::max()) throw WireError("robot index over 32 bits");
  Out out(max_model_update_size() + 64);
  out.cdr() << static_cast<std::uint32_t>(u.robot) << u.sequence << nanoseconds(u.time);
  out.text(u.state.name, kNameBound, "ModelUpdate_.name");
  out.cdr() << static_cast<std::uint32_t>(u.state.joints.size());
  for (double j : u.state.joints) out.cdr() << j;
  out.hold(u.state.hold);
  out.hold(u.state.dropped_hold);
  for (const auto* p : {&u.state.tcp, &u.state.released_tcp}) {
    out.cdr() << p->has_value();
    out.pose(p->value_or(Eigen::Isometry3d::Identity()));
  }
  out.cdr() << static_cast<std::uint32_t>(u.workpieces.size());
  for (const runtime::WorkpieceState& w : u.workpieces) {
    out.text(w.name, kNameBound, "Workpiece_.name");
    out.pose(w.pose);
    out.cdr() << w.velocity.x() << w.velocity.y() << w.velocity.z() << w.motion_known << w.present;
    out.text(w.held_by, kNameBound, "Workpiece_.held_by");
    out.text(w.claimed_by, kNameBound, "Workpiece_.claimed_by");
    out.cdr() << w.confidence << nanoseconds(w.stamp) << w.lost;
    out.text(w.lost_reason.substr(0, kReasonBound - 1), kReasonBound, "Workpiece_.lost_reason");
  }
  return out.take();
}

ModelUpdate decode_model_update(const std::vector<char>& bytes, std::size_t robot) {
  In in(bytes, kModelUpdateTypeName);
  ModelUpdate u;
  const auto on_wire = in.get<std::uint32_t>();
  if (on_wire != robot) throw WireError(fmt::format("an update of robot {} on robot {}'s topic", on_wire, robot));
  u.robot = robot;
  u.sequence = in.get<std::uint64_t>();
  const auto time = in.get<std::int64_t>();
  if (time < 0) throw WireError(fmt::format("an update at {} ns, before the run began", time));
  u.time = std::chrono::duration_cast<runtime::SimDuration>(std::chrono::nanoseconds(time));
  u.state.name = in.text(kNameBound, "ModelUpdate_.name");
  const auto joints = in.get<std::uint32_t>();
  if (joints > kMaxJoints) throw WireError(fmt::format("{} joints, over the bound of {}", joints, kMaxJoints));
  for (std::uint32_t j = 0; j < joints; ++j) u.state.joints.push_back(in.number("ModelUpdate_.joints"));
  u.state.hold = in.hold("ModelUpdate_.hold");
  u.state.dropped_hold = in.hold("ModelUpdate_.dropped_hold");
  for (auto* p : {&u.state.tcp, &u.state.released_tcp}) {
    const bool set = in.get<bool>();
    const Eigen::Isometry3d pose = in.pose("ModelUpdate_.tcp");
    if (set) *p = pose;
  }
  const auto count = in.get<std::uint32_t>();
  if (count > kMaxWorkpieces) throw WireError(fmt::format("{} workpieces, over the bound of {}", count, kMaxWorkpieces));
  for (std::uint32_t i = 0; i < count; ++i) {
    runtime::WorkpieceState w;
    w.name = in.text(kNameBound, "Workpiece_.name");
    w.pose = in.pose("Workpiece_.pose");
    for (int k = 0; k < 3; ++k) w.velocity[k] = in.number("Workpiece_.velocity");
    w.motion_known = in.get<bool>();
    w.present = in.get<bool>();
    w.held_by = in.text(kNameBound, "Workpiece_.held_by");
    w.claimed_by = in.text(kNameBound, "Workpiece_.claimed_by");
    w.confidence = in.number("Workpiece_.confidence");
    w.stamp = std::chrono::duration_cast<runtime::SimDuration>(std::chrono::nanoseconds(in.get<std::int64_t>()));
    w.lost = in.get<bool>();
    w.lost_reason = in.text(kReasonBound, "Workpiece_.lost_reason");
    u.workpieces.push_back(std::move(w));
  }
  in.end();
  return u;
}

std::size_t max_model_update_size() {
  // Every string at its bound, every sequence full, every field's alignment at its worst: bounded from above.
  const std::size_t pose = 7 * 8;
  const std::size_t name = 4 + kNameBound + 3;
  const std::size_t hold = 1 + name + 1 + 7 + 8 + pose;
  const std::size_t workpiece = name + pose + 3 * 8 + 2 + 2 * name + 8 + 8 + 1 + 4 + kReasonBound + 3 + 8;
  return 4 + 4 + 8 + 8 + 8 + name + 4 + 4 + kMaxJoints * 8 + 2 * (hold + 8) + 2 * (8 + pose) + 4 + 4 +
         kMaxWorkpieces * workpiece;
}

std::vector<char> encode_robot_event(std::size_t robot, std::uint64_t sequence, const std::string& line) {
  if (robot > std::numeric_limits<std::uint32_t>::max()) throw WireError("robot index over 32 bits");
  Out out(max_robot_event_size());
  out.cdr() << static_cast<std::uint32_t>(robot) << sequence;
  out.text(line, kEventLineBound, "RobotEvent_.line");
  return out.take();
}

std::pair<runtime::LogEvent, std::uint64_t> decode_robot_event(const std::vector<char>& bytes, std::size_t robot) {
  In in(bytes, kRobotEventTypeName);
  const auto on_wire = in.get<std::uint32_t>();
  if (on_wire != robot) throw WireError(fmt::format("an event of robot {} on robot {}'s topic", on_wire, robot));
  const auto sequence = in.get<std::uint64_t>();
  const std::string line = in.text(kEventLineBound, "RobotEvent_.line");
  in.end();
  try {
    return {runtime::decode(line, "RobotEvent_.line", 1), sequence};
  } catch (const InputError& e) {
    throw WireError(fmt::format("not an event of the log: {}", e.what()));
  }
}

std::size_t max_robot_event_size() {
  return 4 + 4 + 8 + 4 + kEventLineBound + 3;
}

struct AgentPublisher::Impl {
  std::size_t index;
  std::string robot;
  std::uint64_t updates = 0, events = 0;
  std::mutex event_mutex;  // events may be logged from more than one thread
  RawWriter model, log;
  Impl(Participant& p, const std::string& r, std::size_t i)
      : index(i),
        robot(r),
        model((register_type(p, kModelUpdateTypeName, max_model_update_size()), p), model_topic(r),
              kModelUpdateTypeName),
        log((register_type(p, kRobotEventTypeName, max_robot_event_size()), p), events_topic(r), kRobotEventTypeName) {}
};

AgentPublisher::AgentPublisher(Participant& participant, const std::string& robot, std::size_t index)
    : impl_(new Impl(participant, robot, index)) {}
AgentPublisher::~AgentPublisher() = default;

void AgentPublisher::publish_changes(const runtime::EnvironmentModel& before, const runtime::EnvironmentModel& after,
                                     runtime::SimDuration now) {
  std::optional<ModelUpdate> u = changes(before, after, impl_->robot, impl_->index);
  if (!u) return;
  u->sequence = ++impl_->updates;
  u->time = now;
  if (!impl_->model.write(encode_model_update(*u))) {
    std::cerr << fmt::format("DDS did not take a model update for {}\n", model_topic(impl_->robot));
  }
}

void AgentPublisher::publish_event(const runtime::LogEvent& event) {
  std::string line = runtime::encode(event);
  if (line.size() + 1 > kEventLineBound) line = line.substr(0, kEventLineBound - 1);  // refused on arrival, counted
  std::lock_guard lock(impl_->event_mutex);
  if (!impl_->log.write(encode_robot_event(impl_->index, ++impl_->events, line))) {
    std::cerr << fmt::format("DDS did not take an event for {}\n", events_topic(impl_->robot));
  }
}

bool AgentPublisher::flush(std::chrono::milliseconds timeout) {
  return impl_->model.flush(timeout) && impl_->log.flush(timeout);
}

struct RobotSubscriber::Impl {
  std::size_t index;
  std::string robot;
  std::function<void(const ModelUpdate&)> on_update;
  std::function<void(const runtime::LogEvent&)> on_event;
  mutable std::mutex mutex;
  Refusals refusals;
  std::uint64_t last_update = 0, last_event = 0;
  std::uint64_t updates = 0, events = 0;
  std::unique_ptr<RawReader> model, log;

  void refuse(const std::string& topic, const std::string& why) {
    {
      std::lock_guard lock(mutex);
      ++refusals.count;
      refusals.last = why;
    }
    std::cerr << fmt::format("refused a sample on {}: {}\n", topic, why);
  }
  // Counts a gap in a sequence as a refusal (samples lost); the sample itself is taken. A 1 starts a new agent's
  // stream (an agent that rejoined numbers its samples from 1 again).
  void check_sequence(std::uint64_t& last, std::uint64_t now, const std::string& topic) {
    std::uint64_t was = 0;
    {
      std::lock_guard lock(mutex);
      was = last;
      last = now;
    }
    if (now != was + 1 && now != 1) refuse(topic, fmt::format("sample {} after {}: {} lost", now, was, now > was ? now - was - 1 : 0));
  }
};

RobotSubscriber::RobotSubscriber(Participant& participant, const std::string& robot, std::size_t index,
                                 std::function<void(const ModelUpdate&)> on_update,
                                 std::function<void(const runtime::LogEvent&)> on_event)
    : impl_(new Impl) {
  Impl& im = *impl_;
  im.index = index;
  im.robot = robot;
  im.on_update = std::move(on_update);
  im.on_event = std::move(on_event);
  if (im.on_update) {
    register_type(participant, kModelUpdateTypeName, max_model_update_size());
    im.model = std::make_unique<RawReader>(participant, model_topic(robot), kModelUpdateTypeName,
                                           [&im](const std::vector<char>& b) {
                                             try {
                                               ModelUpdate u = decode_model_update(b, im.index);
                                               im.check_sequence(im.last_update, u.sequence, model_topic(im.robot));
                                               im.on_update(u);
                                               std::lock_guard lock(im.mutex);
                                               ++im.updates;
                                             } catch (const WireError& e) {
                                               im.refuse(model_topic(im.robot), e.what());
                                             }
                                           });
  }
  if (im.on_event) {
    register_type(participant, kRobotEventTypeName, max_robot_event_size());
    im.log = std::make_unique<RawReader>(participant, events_topic(robot), kRobotEventTypeName,
                                         [&im](const std::vector<char>& b) {
                                           try {
                                             auto [event, sequence] = decode_robot_event(b, im.index);
                                             im.check_sequence(im.last_event, sequence, events_topic(im.robot));
                                             im.on_event(event);
                                             std::lock_guard lock(im.mutex);
                                             ++im.events;
                                           } catch (const WireError& e) {
                                             im.refuse(events_topic(im.robot), e.what());
                                           }
                                         });
  }
}

RobotSubscriber::~RobotSubscriber() {
  stop();
}

void RobotSubscriber::start() {
  if (impl_->model) impl_->model->start();
  if (impl_->log) impl_->log->start();
}

void RobotSubscriber::stop() {
  if (impl_->model) impl_->model->stop();
  if (impl_->log) impl_->log->stop();
}

Refusals RobotSubscriber::refusals() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->refusals;
}
std::uint64_t RobotSubscriber::updates() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->updates;
}
std::uint64_t RobotSubscriber::events() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->events;
}

std::unique_ptr<RobotSubscriber> share_into(Participant& participant, const std::string& robot, std::size_t index,
                                            runtime::SharedEnvironment& environment, runtime::EventLog& log) {
  return std::make_unique<RobotSubscriber>(
      participant, robot, index,
      [&environment](const ModelUpdate& u) {
        std::optional<std::string> problem;
        environment.write([&](runtime::EnvironmentModel& m) {
          try {
            apply(m, u);
          } catch (const WireError& e) {
            problem = e.what();
          }
        });
        if (problem) throw WireError(*problem);
      },
      [&log](const runtime::LogEvent& e) { log.log(e); });
}

}  // namespace cellwright::distributed
