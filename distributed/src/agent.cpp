#include "cellwright/distributed/agent.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <optional>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/distributed/wire.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/runtime/event.hpp"
#include "cellwright/runtime/event_log.hpp"

namespace cellwright::distributed {

struct RobotAgent::Impl {
  Participant& participant;
  AgentConfig config;
  std::size_t index = 0;
  std::string label;
  runtime::NameMap names;
  runtime::SharedEnvironment env;
  runtime::EventLog log;
  runtime::MessageQueue<runtime::MotionCommand> from_wire{64};  // what the endpoint took, before robot control has it
  runtime::MessageQueue<runtime::MotionCommand> inbox{64};
  runtime::MessageQueue<runtime::RobotStatus> statuses{64};
  std::unique_ptr<AgentPublisher> publisher;
  std::unique_ptr<AgentEndpoint> endpoint;
  std::vector<std::unique_ptr<RobotSubscriber>> others;
  std::unique_ptr<runtime::RobotControl> control;
  runtime::Event wake{runtime::Event::Kind::auto_reset};
  std::atomic<bool> stop{false};
  // Other robots' updates, taken on Fast DDS's thread, applied on the agent's between steps.
  std::mutex pending_mutex;
  std::vector<ModelUpdate> pending;

  Impl(Participant& p, AgentConfig c)
      : participant(p),
        config(std::move(c)),
        env(runtime::make_environment_model(config.cell)),
        log(config.log_stream) {}
};

RobotAgent::RobotAgent(Participant& participant, AgentConfig config) : impl_(new Impl(participant, std::move(config))) {
  Impl& im = *impl_;
  const AgentConfig& c = im.config;
  CW_CHECK(c.driver != nullptr, "an agent without a driver");
  CW_CHECK(c.period.count() > 0 && c.speed > 0, "an agent's period and speed must be positive");
  const models::RobotSpec* spec = c.cell.find_robot(c.robot);
  std::vector<std::string> bound;
  for (const auto& [label, entry] : c.binding.robots) bound.push_back(fmt::format("{} ({})", entry.name, label));
  if (spec == nullptr) {
    throw InputError(SourceLocation{"--robot"},
                     fmt::format("'{}' is not a robot of cell '{}' (the program's robots: {})", c.robot, c.cell.name,
                                 fmt::join(bound, ", ")));
  }
  // The binding checked as the runtime checks it, this robot on its driver and the others elsewhere.
  runtime::RunConfig rc;
  rc.program = c.program;
  rc.cell = c.cell;
  rc.binding = c.binding;
  rc.drivers[c.robot] = c.driver;
  for (const auto& [label, entry] : c.binding.robots) {
    if (entry.name != c.robot) rc.remote_robots.push_back(entry.name);
  }
  im.names = runtime::resolve_names(rc);
  bool found = false;
  for (std::size_t r = 0; r < c.program.robots.size(); ++r) {
    if (im.names.robots.at(c.program.robots[r]) == c.robot) {
      im.index = r;
      im.label = c.program.robots[r];
      found = true;
    }
  }
  if (!found) {
    throw InputError(SourceLocation{"--robot"}, fmt::format("robot '{}' has nothing to do in program {} (its robots: {})",
                                                            c.robot, c.program.file, fmt::join(bound, ", ")));
  }
  im.publisher = std::make_unique<AgentPublisher>(participant, c.robot, im.index);
  im.log.add_observer([&im](const runtime::LogEvent& e) { im.publisher->publish_event(e); });
  im.endpoint = std::make_unique<AgentEndpoint>(participant, c.robot, im.index, im.config.program, im.from_wire,
                                                im.statuses);
  for (std::size_t r = 0; r < c.program.robots.size(); ++r) {
    if (r == im.index) continue;
    im.others.push_back(std::make_unique<RobotSubscriber>(
        participant, im.names.robots.at(c.program.robots[r]), r,
        [&im](const ModelUpdate& u) {
          {
            std::lock_guard lock(im.pending_mutex);
            im.pending.push_back(u);
          }
          im.wake.set();
        },
        nullptr));
  }
  runtime::MotionOptions motion = c.motion;
  motion.track_held_parts = true;  // Perception::kCad: nothing measures a held part
  im.control = std::make_unique<runtime::RobotControl>(im.index, im.label, c.robot, *c.driver,
                                                       models::robot_chain(*spec), spec->grip_force, im.names, im.env,
                                                       im.inbox, im.statuses, im.log, motion, true, nullptr);
}

RobotAgent::~RobotAgent() {
  if (impl_->endpoint) impl_->endpoint->stop();
  for (auto& o : impl_->others) o->stop();
  impl_->config.driver->set_notifier({});
  impl_->config.driver->set_clock({});
}

const std::string& RobotAgent::label() const {
  return impl_->label;
}
std::size_t RobotAgent::index() const {
  return impl_->index;
}

void RobotAgent::request_stop() {
  impl_->stop = true;
  impl_->wake.set();
}

AgentSummary RobotAgent::serve(std::chrono::milliseconds wait) {
  Impl& im = *impl_;
  AgentSummary summary;
  im.control->connect();  // InputError: the driver's configuration cannot work
  for (auto& o : im.others) o->start();
  im.endpoint->start();
  const int domain = im.participant.domain();
  // Task control: its endpoints matched, then its first command (which starts the clock).
  const auto deadline = std::chrono::steady_clock::now() + wait;
  while (!im.stop && !im.endpoint->task_control_present() && std::chrono::steady_clock::now() < deadline) {
    (void)im.endpoint->wait_for_task_control(std::chrono::milliseconds(50));
  }
  if (im.stop) {
    summary.ended_by_stop = true;
    return summary;
  }
  if (!im.endpoint->task_control_present()) {
    throw InputError(SourceLocation{fmt::format("DDS domain {}", domain)},
                     fmt::format("no task control for robot {} on DDS domain {} within {:.1f} s (start it with twin "
                                 "run SCENARIO --agents remote --domain {})",
                                 im.config.robot, domain, static_cast<double>(wait.count()) / 1000.0, domain));
  }
  summary.task_control_came = true;
  runtime::MotionCommand first;
  bool have_first = false;
  while (!im.stop && im.endpoint->task_control_present()) {
    if (im.from_wire.pop_for(first, std::chrono::milliseconds(20)) == runtime::QueueStatus::ok) {
      have_first = true;
      break;
    }
  }
  if (!have_first) {
    summary.ended_by_stop = im.stop;
    if (!im.stop) summary.task_control_lost = im.endpoint->task_control_lost(std::chrono::milliseconds(500));
    if (!summary.task_control_lost.empty()) im.control->halt();  // at rest, but halted all the same
    summary.refusals = im.endpoint->refusals();
    return summary;
  }
  const runtime::SimDuration origin = first.sent;
  const auto wall_origin = std::chrono::steady_clock::now();
  const double speed = im.config.speed;
  const auto clock = [origin, wall_origin, speed] {
    const auto wall = std::chrono::steady_clock::now() - wall_origin;
    return origin + std::chrono::duration_cast<runtime::SimDuration>(
                        std::chrono::duration<double, std::nano>(
                            std::chrono::duration<double, std::nano>(wall).count() * speed));
  };
  drivers::RobotDriver& driver = *im.config.driver;
  driver.set_clock([clock] { return std::chrono::duration_cast<std::chrono::nanoseconds>(clock()); });
  driver.set_notifier([&im] { im.wake.set(); });
  im.inbox.push(std::move(first));
  ++summary.commands;
  const auto wall_period = std::chrono::duration_cast<std::chrono::nanoseconds>(
      std::chrono::duration<double, std::nano>(std::chrono::duration<double, std::nano>(im.config.period).count() /
                                               speed));
  const std::vector<std::string> self{im.config.robot};
  std::uint64_t applied = 0;
  while (!im.stop) {
    (void)im.wake.wait_for(wall_period);
    const runtime::SimDuration now = clock();
    runtime::MotionCommand c;
    while (im.from_wire.try_pop(c) == runtime::QueueStatus::ok) {
      im.inbox.push(std::move(c));
      ++summary.commands;
    }
    std::vector<ModelUpdate> updates;
    {
      std::lock_guard lock(im.pending_mutex);
      updates.swap(im.pending);
    }
    const runtime::SensorReadings readings = runtime::read_sensors(im.config.sensors, self, now);
    runtime::EnvironmentModel before;
    im.env.write([&](runtime::EnvironmentModel& m) {
      for (const ModelUpdate& u : updates) {
        try {
          apply(m, u);
          ++applied;
        } catch (const WireError& e) {
          std::fprintf(stderr, "refused a model update of robot %zu: %s\n", u.robot, e.what());
        }
      }
      runtime::apply_readings(m, readings, runtime::Perception::kCad);
      before = m;
    });
    im.control->step(now);
    im.publisher->publish_changes(before, im.env.snapshot(), now);
    if (!im.endpoint->task_control_present()) break;  // its process ended, or was lost
  }
  summary.ended_by_stop = im.stop;
  im.control->halt();
  if (!im.stop) summary.task_control_lost = im.endpoint->task_control_lost(std::chrono::milliseconds(500));
  // What is left to send is written; a lost task control will acknowledge nothing, so it is not waited for.
  const auto ack_wait = summary.task_control_lost.empty() ? std::chrono::milliseconds(2000)
                                                          : std::chrono::milliseconds(100);
  (void)im.endpoint->flush(ack_wait);
  (void)im.publisher->flush(ack_wait);
  driver.set_notifier({});
  driver.set_clock({});
  summary.updates_applied = applied;
  summary.refusals = im.endpoint->refusals();
  for (const auto& o : im.others) {
    const Refusals r = o->refusals();
    summary.refusals.count += r.count;
    if (!r.last.empty()) summary.refusals.last = r.last;
  }
  summary.phase = runtime::to_string(im.control->phase());
  return summary;
}

}  // namespace cellwright::distributed
