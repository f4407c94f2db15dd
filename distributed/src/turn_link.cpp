#include "cellwright/distributed/turn_link.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <iostream>
#include <mutex>
#include <optional>

#include "cellwright/common/error.hpp"
#include "cellwright/distributed/replica.hpp"
#include "cellwright/distributed/turn_wire.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/runtime/event_log.hpp"
#include "cellwright/runtime/log_event.hpp"
#include "cellwright/runtime/robot_control.hpp"

namespace cellwright::distributed {

namespace {

constexpr std::chrono::milliseconds kHelloEvery{50};
constexpr std::chrono::milliseconds kSlice{20};  // how often a waiting end looks at its peer's liveliness

// Samples of one topic as they arrive (Fast DDS's thread), taken by one consumer thread, with the liveliness of the
// writers they come from.
class Inbox {
 public:
  void push(const std::vector<char>& bytes) {
    {
      std::lock_guard lock(mutex_);
      samples_.push_back(bytes);
    }
    changed_.notify_all();
  }
  void alive(int count) {
    {
      std::lock_guard lock(mutex_);
      alive_ = count;
      if (count > 0) seen_alive_ = true;
    }
    changed_.notify_all();
  }
  // The next sample, waiting at most `slice`; nullopt when none came.
  std::optional<std::vector<char>> next(std::chrono::milliseconds slice) {
    std::unique_lock lock(mutex_);
    if (!changed_.wait_for(lock, slice, [&] { return !samples_.empty(); })) return std::nullopt;
    std::vector<char> b = std::move(samples_.front());
    samples_.pop_front();
    return b;
  }
  // Whether a writer was alive and none is any more (its liveliness lapsed).
  bool lapsed() const {
    std::lock_guard lock(mutex_);
    return seen_alive_ && alive_ == 0;
  }
  void wake() { changed_.notify_all(); }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::vector<char>> samples_;
  int alive_ = 0;
  bool seen_alive_ = false;
};

// The agent is gone, or said something this end cannot take: the link is lost for good (TurnLink::state()).
struct LinkLost {
  std::string detail;
};

std::string seconds_text(std::chrono::milliseconds d) {
  return fmt::format("{:.3g} s", static_cast<double>(d.count()) / 1000.0);
}

// A driver call answered on `driver`, as the call would be in this process.
DriverResult answer(drivers::RobotDriver& driver, const DriverCall& call) {
  DriverResult r;
  r.op = call.op;
  switch (call.op) {
    case DriverOp::capabilities: r.capabilities = driver.capabilities(); break;
    case DriverOp::state: r.state = driver.state(); break;
    case DriverOp::connect: r.error = driver.connect(); break;
    case DriverOp::disconnect: driver.disconnect(); break;
    case DriverOp::home: r.submitted = driver.home(); break;
    case DriverOp::activate: r.error = driver.activate(); break;
    case DriverOp::stop: driver.stop(); break;
    case DriverOp::reset: r.error = driver.reset(); break;
    case DriverOp::submit: r.submitted = driver.submit(call.command); break;
    case DriverOp::request_position: r.submitted = driver.request_position(); break;
    case DriverOp::poll: r.status = driver.poll(call.id); break;
    case DriverOp::last_position: r.position = driver.last_position(); break;
    case DriverOp::grip_sense: r.grip = driver.grip_sense(); break;
    case DriverOp::least_duration: r.least = driver.least_duration(call.command); break;
  }
  return r;
}

}  // namespace

std::string turn_settings(const task::CompiledProgram& program, const std::string& robot, runtime::SimDuration period,
                          runtime::Perception perception) {
  std::string robots;
  for (const std::string& r : program.robots) robots += (robots.empty() ? "" : ",") + r;
  return fmt::format("program {} (robots {}), robot {}, control period {} ns, perception {}", program.file, robots,
                     robot, period.count(), runtime::to_string(perception));
}

// ---- the run's end ----

struct TurnLink::Impl {
  Participant& participant;
  std::string robot;
  std::size_t index;
  const task::CompiledProgram& program;
  std::string settings;
  runtime::MessageQueue<runtime::MotionCommand>& commands;
  runtime::MessageQueue<runtime::RobotStatus>& statuses;
  TurnOptions options;
  runtime::SharedEnvironment* env = nullptr;
  runtime::EventLog* log = nullptr;
  std::optional<runtime::EnvironmentModel> cell_model;  // a copy of the run's model: its geometry, its names
  Inbox inbox;
  std::unique_ptr<RawWriter> writer;
  std::unique_ptr<RawReader> reader;

  mutable std::mutex mutex;  // the fields below
  bool hello = false;
  std::string refused_hello;
  Refusals refusals;
  bool ended = false;
  std::uint64_t sent = 0;  // sequence numbers of what this end sent
  SequenceCheck received;
  std::uint64_t turn = 0;
  std::uint64_t calls = 0;
  bool lost = false;
  std::string lost_detail;
  int in_flight = -1;  // the primitive sent to the agent and not answered

  Impl(Participant& p, std::string r, std::size_t i, const task::CompiledProgram& prog, std::string s,
       runtime::MessageQueue<runtime::MotionCommand>& c, runtime::MessageQueue<runtime::RobotStatus>& st,
       TurnOptions o)
      : participant(p), robot(std::move(r)), index(i), program(prog), settings(std::move(s)), commands(c),
        statuses(st), options(o) {
    register_type(p, kTurnTypeName, max_turn_size());
    register_type(p, kTurnCallTypeName, max_turn_call_size());
    writer = std::make_unique<RawWriter>(p, turn_topic(robot), kTurnTypeName);
    reader = std::make_unique<RawReader>(
        p, call_topic(robot), kTurnCallTypeName, [this](const std::vector<char>& b) { inbox.push(b); },
        [this](int alive) { inbox.alive(alive); });
    reader->start();
  }

  void send(TurnMessage m) {
    m.robot = index;
    m.sequence = ++sent;
    if (!writer->write(encode_turn(m))) throw LinkLost{"DDS did not take a turn message for it"};
  }

  // Takes the hellos that came (before the run's model is shared, nothing can be decoded: they wait).
  void take_hellos(std::chrono::milliseconds slice) {
    if (!cell_model) return;
    while (std::optional<std::vector<char>> b = inbox.next(slice)) {
      slice = std::chrono::milliseconds(0);
      try {
        TurnCall c = decode_turn_call(*b, index, *cell_model);
        if (c.kind != TurnCall::Kind::kDone || c.turn != 0) {
          refuse(fmt::format("a {} of turn {} before the first turn", c.kind == TurnCall::Kind::kCall ? "call" : "done",
                             c.turn));
          continue;
        }
        std::lock_guard lock(mutex);
        if (c.settings == settings) {
          hello = true;
        } else {
          refused_hello = fmt::format("its agent runs '{}', this run '{}'", c.settings, settings);
        }
      } catch (const WireError& e) {
        refuse(e.what());
      }
    }
  }

  void refuse(const std::string& why) {
    std::lock_guard lock(mutex);
    ++refusals.count;
    refusals.last = why;
    std::cerr << fmt::format("refused a sample on {}: {}\n", call_topic(robot), why);
  }

  // The agent's next message of this turn; LinkLost when it is lost, silent or says what cannot be taken.
  TurnCall next_of_turn() {
    const auto deadline = std::chrono::steady_clock::now() + options.answer_timeout;
    for (;;) {
      std::optional<std::vector<char>> b = inbox.next(kSlice);
      if (!b) {
        if (inbox.lapsed() || reader->writers() == 0) {
          throw LinkLost{fmt::format("no sign of life from it in turn {} for the lease of {}, or it left (the process "
                                     "killed, its host down or the network cut)",
                                     turn, seconds_text(participant.lease()))};
        }
        if (std::chrono::steady_clock::now() > deadline) {
          throw LinkLost{fmt::format("it gave no answer in turn {} for {}", turn,
                                     seconds_text(options.answer_timeout))};
        }
        continue;
      }
      TurnCall c;
      try {
        c = decode_turn_call(*b, index, *cell_model);
      } catch (const WireError& e) {
        // In the middle of a turn a refused message is one the agent's step waits for an answer to, or one that would
        // have changed the run: the turn cannot be finished as one process would have.
        refuse(e.what());
        throw LinkLost{fmt::format("it sent a message that does not decode in turn {}: {}", turn, e.what())};
      }
      if (c.kind == TurnCall::Kind::kDone && c.turn == 0) continue;  // a late hello
      try {
        std::lock_guard lock(mutex);
        received.accept(c.sequence, "turn call");
      } catch (const WireError& e) {
        refuse(e.what());
        throw LinkLost{e.what()};
      }
      if (c.turn != turn) throw LinkLost{fmt::format("it answered for turn {} in turn {}", c.turn, turn)};
      return c;
    }
  }
};

TurnLink::TurnLink(Participant& participant, std::string robot, std::size_t index, const task::CompiledProgram& program,
                   std::string settings, runtime::MessageQueue<runtime::MotionCommand>& commands,
                   runtime::MessageQueue<runtime::RobotStatus>& statuses, TurnOptions options)
    : impl_(new Impl(participant, std::move(robot), index, program, std::move(settings), commands, statuses,
                     options)) {}

TurnLink::~TurnLink() {
  impl_->reader->stop();
}

bool TurnLink::wait_for_agent(std::chrono::milliseconds timeout) const {
  Impl& im = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    im.take_hellos(kSlice);
    {
      std::lock_guard lock(im.mutex);
      if (im.hello && im.writer->wait_for_reader(std::chrono::milliseconds(0))) return true;
    }
    if (std::chrono::steady_clock::now() >= deadline) return false;
    if (!im.cell_model) std::this_thread::sleep_for(kSlice);  // nothing shared yet: nothing to decode with
  }
}

std::string TurnLink::refused_hello() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->refused_hello;
}

void TurnLink::start() {}

void TurnLink::stop() {
  Impl& im = *impl_;
  {
    std::lock_guard lock(im.mutex);
    if (im.ended) return;
    im.ended = true;
    if (!im.hello) return;  // no agent to tell
  }
  TurnMessage end;
  end.kind = TurnMessage::Kind::kEnd;
  end.turn = im.turn;
  try {
    im.send(std::move(end));
    (void)im.writer->flush(std::chrono::milliseconds(1000));
  } catch (const LinkLost& e) {
    std::cerr << fmt::format("robot {}: the run's end was not sent to its agent: {}\n", im.robot, e.detail);
  }
}

runtime::LinkState TurnLink::state() const {
  std::lock_guard lock(impl_->mutex);
  runtime::LinkState s;
  s.present = !impl_->lost;
  s.session = 1;
  s.losses = impl_->lost ? 1 : 0;
  s.lost_detail = impl_->lost_detail;
  s.in_flight = impl_->in_flight;
  return s;
}

void TurnLink::share(runtime::SharedEnvironment& environment, runtime::EventLog& log) {
  impl_->env = &environment;
  impl_->log = &log;
  impl_->cell_model = environment.read([](const runtime::EnvironmentModel& m) { return m; });
}

void TurnLink::take_turn(runtime::SimDuration now, drivers::RobotDriver& driver) {
  Impl& im = *impl_;
  CW_CHECK(im.env != nullptr, "robot {}: a turn before the run's model was shared", im.robot);
  TurnMessage t;
  t.kind = TurnMessage::Kind::kTurn;
  // The commands task control queued: sent with this turn, or, to an agent that was lost, in flight for good (the
  // runtime's watch makes that the link_lost fault: an agent lost while idle has lost nothing until it is sent one).
  runtime::MotionCommand c;
  while (im.commands.try_pop(c) == runtime::QueueStatus::ok) {
    {
      std::lock_guard lock(im.mutex);
      im.in_flight = static_cast<int>(c.index);
    }
    t.commands.push_back(std::move(c));
  }
  {
    std::lock_guard lock(im.mutex);
    if (im.lost) return;  // for good
    t.turn = ++im.turn;
  }
  t.now = now;
  t.model = im.env->read([](const runtime::EnvironmentModel& m) { return m; });
  try {
    im.send(std::move(t));
    for (;;) {
      TurnCall m = im.next_of_turn();
      if (m.kind == TurnCall::Kind::kCall) {
        TurnMessage r;
        r.kind = TurnMessage::Kind::kResult;
        r.turn = m.turn;
        r.result = answer(driver, m.call);
        {
          std::lock_guard lock(im.mutex);
          ++im.calls;
        }
        im.send(std::move(r));
        continue;
      }
      // Done: what one process would have had at the end of the step, in its order: the events as they were logged,
      // the statuses as they were queued, the model as the step left it.
      for (const std::string& line : m.events) im.log->log(runtime::decode(line, call_topic(im.robot), 0));
      for (runtime::RobotStatus& s : m.statuses) {
        {
          std::lock_guard lock(im.mutex);
          if (im.in_flight == static_cast<int>(s.index)) im.in_flight = -1;
        }
        if (im.statuses.push(std::move(s)) != runtime::QueueStatus::ok) break;  // closed: the run is ending
      }
      im.env->write([&](runtime::EnvironmentModel& model) { model = std::move(m.model); });
      if (!m.error.empty()) {
        throw InternalError(fmt::format("robot {}: its agent's robot control failed in turn {}: {}", im.robot, m.turn,
                                        m.error));
      }
      return;
    }
  } catch (const LinkLost& lost) {
    std::lock_guard lock(im.mutex);
    im.lost = true;
    im.lost_detail = lost.detail;
  }
}

const std::string& TurnLink::robot() const {
  return impl_->robot;
}
Refusals TurnLink::refusals() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->refusals;
}
std::uint64_t TurnLink::turns() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->turn;
}
std::uint64_t TurnLink::calls() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->calls;
}

runtime::AttachRemote TurnCell::attach(const task::CompiledProgram& program, runtime::SimDuration period,
                                       runtime::Perception perception) {
  return [this, &program, period, perception](std::size_t index, const std::string& cell,
                                              runtime::MessageQueue<runtime::MotionCommand>& c,
                                              runtime::MessageQueue<runtime::RobotStatus>& s)
             -> std::unique_ptr<runtime::RemoteLink> {
    auto link = std::make_unique<TurnLink>(participant_, cell, index, program,
                                           turn_settings(program, cell, period, perception), c, s, options_);
    links_.push_back(link.get());
    return link;
  };
}

void TurnCell::wait_for_agents(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::vector<std::string> missing, refused;
  for (TurnLink* l : links_) {
    const auto left = std::max(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   deadline - std::chrono::steady_clock::now()),
                               std::chrono::milliseconds(0));
    if (l->wait_for_agent(left)) continue;
    missing.push_back(l->robot());
    if (const std::string why = l->refused_hello(); !why.empty()) refused.push_back(l->robot() + ": " + why);
  }
  if (missing.empty()) return;
  std::vector<std::string> how;
  for (const std::string& r : missing) how.push_back(fmt::format("twin agent SCENARIO --robot {} --domain {}", r,
                                                                 participant_.domain()));
  std::string text = fmt::format(
      "no agent for {} on DDS domain {} within {} (a lock-step run with the twin): start one per robot, the robot on "
      "the twin's driver (no --driver): {}",
      fmt::join(missing, ", "), participant_.domain(), seconds_text(timeout), fmt::join(how, "; "));
  if (!refused.empty()) text += fmt::format("; refused: {}", fmt::join(refused, "; "));
  throw InputError(SourceLocation{fmt::format("DDS domain {}", participant_.domain())}, text);
}

// ---- the agent's end ----


namespace {

// The agent's robot control's driver: every call is a DriverCall answered by the run's process (its twin's driver).
class StandInDriver final : public drivers::RobotDriver {
 public:
  explicit StandInDriver(std::function<DriverResult(const DriverCall&)> call) : call_(std::move(call)) {}
  const drivers::Capabilities& capabilities() const override {
    if (!capabilities_) capabilities_ = call_({DriverOp::capabilities, {}, 0}).capabilities;  // fixed: asked once
    return *capabilities_;
  }
  drivers::DriverState state() const override { return call_({DriverOp::state, {}, 0}).state; }
  drivers::ErrorCode connect() override { return call_({DriverOp::connect, {}, 0}).error; }
  void disconnect() override { (void)call_({DriverOp::disconnect, {}, 0}); }
  drivers::Submitted home() override { return call_({DriverOp::home, {}, 0}).submitted; }
  drivers::ErrorCode activate() override { return call_({DriverOp::activate, {}, 0}).error; }
  void stop() override { (void)call_({DriverOp::stop, {}, 0}); }
  drivers::ErrorCode reset() override { return call_({DriverOp::reset, {}, 0}).error; }
  drivers::Submitted submit(const drivers::Command& command) override {
    return call_({DriverOp::submit, command, 0}).submitted;
  }
  drivers::Submitted request_position() override { return call_({DriverOp::request_position, {}, 0}).submitted; }
  drivers::CommandStatus poll(drivers::CommandId id) const override { return call_({DriverOp::poll, {}, id}).status; }
  std::optional<drivers::PositionReading> last_position() const override {
    return call_({DriverOp::last_position, {}, 0}).position;
  }
  void set_notifier(std::function<void()>) override {}  // lock-step: nothing is notified
  void set_clock(Clock) override {}                      // the run's process stamps read-backs on its clock
  std::optional<drivers::GripSense> grip_sense() const override { return call_({DriverOp::grip_sense, {}, 0}).grip; }
  std::optional<double> least_duration(const drivers::Command& command) const override {
    return call_({DriverOp::least_duration, command, 0}).least;
  }

 private:
  std::function<DriverResult(const DriverCall&)> call_;
  mutable std::optional<drivers::Capabilities> capabilities_;
};

// Serving ends (the run's end, its loss, a stop): unwinds a step waiting for an answer.
struct ServingEnds {
  std::string why;
  bool run_ended = false;
};

}  // namespace

struct TurnAgent::Impl {
  Participant& participant;
  TurnAgentConfig config;
  std::size_t index = 0;
  std::string label;
  runtime::NameMap names;
  runtime::SharedEnvironment env;
  runtime::EnvironmentModel cell_model;
  runtime::EventLog log;
  runtime::MessageQueue<runtime::MotionCommand> inbox{64};
  runtime::MessageQueue<runtime::RobotStatus> statuses{64};
  std::vector<std::string> turn_events;  // what the step logged, as lines
  Inbox in;
  std::unique_ptr<RawWriter> writer;
  std::unique_ptr<RawReader> reader;
  std::unique_ptr<StandInDriver> driver;
  std::unique_ptr<runtime::RobotControl> control;
  std::atomic<bool> stop{false};
  std::uint64_t sent = 0;
  SequenceCheck received;
  std::uint64_t turn = 0;
  TurnAgentSummary summary;

  Impl(Participant& p, TurnAgentConfig c)
      : participant(p),
        config(std::move(c)),
        env(runtime::make_environment_model(config.cell)),
        cell_model(env.read([](const runtime::EnvironmentModel& m) { return m; })),
        log(config.log_stream) {}

  void send(TurnCall m) {
    m.robot = index;
    m.sequence = m.kind == TurnCall::Kind::kDone && m.turn == 0 ? 0 : ++sent;
    if (!writer->write(encode_turn_call(m))) throw ServingEnds{"DDS did not take a message for the run"};
  }

  // The run's next message; ServingEnds when it ended, was lost or the agent was stopped.
  TurnMessage next(std::chrono::steady_clock::time_point deadline) {
    for (;;) {
      if (stop) throw ServingEnds{"stopped"};
      std::optional<std::vector<char>> b = in.next(kSlice);
      if (!b) {
        if (in.lapsed()) throw ServingEnds{"the run's process was lost (no sign of life for the liveliness lease)"};
        if (turn > 0 && reader->writers() == 0) throw ServingEnds{"the run's process left"};
        if (std::chrono::steady_clock::now() > deadline) throw ServingEnds{"the run gave no answer in time"};
        continue;
      }
      TurnMessage m;
      try {
        m = decode_turn(*b, index, config.program, cell_model);
        received.accept(m.sequence, "turn message");
      } catch (const WireError& e) {
        ++summary.refusals.count;
        summary.refusals.last = e.what();
        std::cerr << fmt::format("refused a sample on {}: {}\n", turn_topic(config.robot), e.what());
        if (turn > 0) throw ServingEnds{fmt::format("a refused message in turn {}: {}", turn, e.what())};
        continue;
      }
      if (m.kind == TurnMessage::Kind::kEnd) throw ServingEnds{"", true};
      return m;
    }
  }

  DriverResult call(const DriverCall& c) {
    TurnCall m;
    m.kind = TurnCall::Kind::kCall;
    m.turn = turn;
    m.call = c;
    send(std::move(m));
    ++summary.calls;
    TurnMessage r = next(std::chrono::steady_clock::now() + config.options.answer_timeout);
    if (r.kind != TurnMessage::Kind::kResult || r.turn != turn || r.result.op != c.op) {
      throw ServingEnds{fmt::format("the run answered a {} call of turn {} with something else", to_string(c.op),
                                    turn)};
    }
    return r.result;
  }

  void take(TurnMessage t) {
    turn = t.turn;
    ++summary.turns;
    env.write([&](runtime::EnvironmentModel& m) { m = std::move(t.model); });
    for (runtime::MotionCommand& c : t.commands) {
      CW_CHECK(inbox.try_push(std::move(c)) == runtime::QueueStatus::ok, "robot {}: its inbox is full", config.robot);
    }
    TurnCall done;
    done.kind = TurnCall::Kind::kDone;
    done.turn = turn;
    turn_events.clear();
    try {
      if (turn == 1) control->connect();  // as the runtime does before the first turn (the run's driver: connected)
      control->step(t.now);
    } catch (const ServingEnds&) {
      throw;
    } catch (const std::exception& e) {
      done.error = e.what();
    }
    done.events = std::move(turn_events);
    runtime::RobotStatus s;
    while (statuses.try_pop(s) == runtime::QueueStatus::ok) done.statuses.push_back(std::move(s));
    done.model = env.read([](const runtime::EnvironmentModel& m) { return m; });
    send(std::move(done));
  }
};

TurnAgent::TurnAgent(Participant& participant, TurnAgentConfig config) : impl_(new Impl(participant, std::move(config))) {
  Impl& im = *impl_;
  const TurnAgentConfig& c = im.config;
  const models::RobotSpec* spec = c.cell.find_robot(c.robot);
  std::vector<std::string> bound;
  for (const auto& [label, entry] : c.binding.robots) bound.push_back(fmt::format("{} ({})", entry.name, label));
  if (spec == nullptr) {
    throw InputError(SourceLocation{"--robot"},
                     fmt::format("'{}' is not a robot of cell '{}' (the program's robots: {})", c.robot, c.cell.name,
                                 fmt::join(bound, ", ")));
  }
  runtime::RunConfig rc;
  rc.program = c.program;
  rc.cell = c.cell;
  rc.binding = c.binding;
  for (const auto& [label, entry] : c.binding.robots) rc.remote_robots.push_back(entry.name);
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
  for (const task::Primitive& p : c.program.programs[im.index].primitives) {
    if (!p.segment) continue;
    throw InputError(p.where, fmt::format("robot {} ({}) would be an agent, and this command is part of a coordinated "
                                          "block, whose robots meet in one process: run it with --agents local",
                                          im.label, c.robot));
  }
  register_type(participant, kTurnTypeName, max_turn_size());
  register_type(participant, kTurnCallTypeName, max_turn_call_size());
  im.writer = std::make_unique<RawWriter>(participant, call_topic(c.robot), kTurnCallTypeName);
  im.reader = std::make_unique<RawReader>(
      participant, turn_topic(c.robot), kTurnTypeName, [&im](const std::vector<char>& b) { im.in.push(b); },
      [&im](int alive) { im.in.alive(alive); });
  im.log.add_observer([&im](const runtime::LogEvent& e) { im.turn_events.push_back(runtime::encode(e)); });
  im.driver = std::make_unique<StandInDriver>([&im](const DriverCall& call) { return im.call(call); });
  runtime::MotionOptions motion = c.motion;
  motion.track_held_parts = c.perception != runtime::Perception::kTruth;  // as the runtime sets it
  im.control = std::make_unique<runtime::RobotControl>(im.index, im.label, c.robot, *im.driver,
                                                       models::robot_chain(*spec), spec->grip_force, im.names, im.env,
                                                       im.inbox, im.statuses, im.log, motion, false, nullptr);
}

TurnAgent::~TurnAgent() {
  impl_->reader->stop();
}

const std::string& TurnAgent::label() const {
  return impl_->label;
}
std::size_t TurnAgent::index() const {
  return impl_->index;
}

TurnAgentSummary TurnAgent::serve(std::chrono::milliseconds wait) {
  Impl& im = *impl_;
  const TurnAgentConfig& c = im.config;
  im.reader->start();
  const std::string settings = turn_settings(c.program, c.robot, c.period, c.perception);
  // Hello until the first turn: only once this end's reader sees the run's writer (a turn written before would be
  // lost), and again every kHelloEvery (a hello written before the run's reader saw this writer is lost).
  const auto deadline = std::chrono::steady_clock::now() + wait;
  std::optional<TurnMessage> first;
  bool run_seen = false;  // a run's writer matched: its leaving before the first turn is its loss
  while (!first) {
    if (im.stop) {
      im.summary.ended_by_stop = true;
      return im.summary;
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      throw InputError(SourceLocation{fmt::format("DDS domain {}", im.participant.domain())},
                       fmt::format("no lock-step run came for robot {} within {} (twin run SCENARIO --agents remote "
                                   "--domain {})",
                                   c.robot, seconds_text(wait), im.participant.domain()));
    }
    if (im.reader->writers() > 0) {
      run_seen = true;
    } else if (run_seen || im.in.lapsed()) {
      im.summary.error = "the run's process was lost before its first turn";
      return im.summary;
    }
    if (im.reader->writers() > 0 && im.writer->wait_for_reader(std::chrono::milliseconds(0))) {
      TurnCall hello;
      hello.kind = TurnCall::Kind::kDone;
      hello.turn = 0;
      hello.settings = settings;
      hello.model = im.env.read([](const runtime::EnvironmentModel& m) { return m; });
      try {
        im.send(std::move(hello));
      } catch (const ServingEnds& e) {
        im.summary.error = e.why;
        return im.summary;
      }
    }
    try {
      first = im.next(std::chrono::steady_clock::now() + kHelloEvery);
    } catch (const ServingEnds& e) {
      if (e.run_ended || e.why == "stopped") {
        im.summary.run_ended = e.run_ended;
        im.summary.ended_by_stop = !e.run_ended;
        return im.summary;
      }
      // no answer within kHelloEvery: hello again
    }
  }
  im.summary.run_came = true;
  try {
    if (first->kind != TurnMessage::Kind::kTurn || first->turn != 1) {
      throw ServingEnds{"the run's first message was not its first turn"};
    }
    im.take(std::move(*first));
    for (;;) {
      // Between turns the run's process steps the others: no time limit but its liveliness.
      TurnMessage t = im.next(std::chrono::steady_clock::time_point::max());
      if (t.kind != TurnMessage::Kind::kTurn || t.turn != im.turn + 1) {
        throw ServingEnds{fmt::format("the run sent turn {} ({}) after turn {}", t.turn,
                                      t.kind == TurnMessage::Kind::kTurn ? "a turn" : "a result", im.turn)};
      }
      im.take(std::move(t));
    }
  } catch (const ServingEnds& e) {
    im.summary.run_ended = e.run_ended;
    im.summary.ended_by_stop = e.why == "stopped";
    if (!e.run_ended && !im.summary.ended_by_stop) im.summary.error = e.why;
  }
  im.summary.phase = runtime::to_string(im.control->phase());
  return im.summary;
}

void TurnAgent::request_stop() {
  impl_->stop = true;
  impl_->in.wake();
}

}  // namespace cellwright::distributed
