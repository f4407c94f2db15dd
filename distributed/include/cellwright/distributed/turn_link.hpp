// Lock-step across processes (docs/distributed.md, "Lock-step with agents"): a robot's turns taken by its robot control
// in an agent process, over DDS, with the run's twin (and its drivers) in the run's process. The messages are
// turn_wire.hpp's; this is their transport and the two ends' logic.
//
//   run's process (twin run --agents remote, lock-step)        agent process (twin agent, robot on the twin)
//   Runtime ── robot r's turn ── TurnLink ── rt/cellwright/<r>/turn ──> TurnAgent ── RobotControl
//                                  │       <── rt/cellwright/<r>/call ──          │
//                     the twin's driver of r  <── its calls ── StandInDriver ─────┘
//
// THE RUN'S END (TurnLink, a runtime::RemoteLink that takes turns): in the robot's turn it sends the turn (its time,
// the commands task control queued since the last turn, the whole environment model), answers every driver call of the
// agent's step on the robot's driver in this process, in order, and when the agent says the step is done logs its
// events, pushes its statuses and writes back the model it left (turn_wire.hpp says why this is what one process
// does). The run's thread blocks meanwhile (a lock-step run waits for each turn anyway).
//
// THE AGENT'S END (TurnAgent): builds the same RobotControl the runtime would (the scenario's cell, program, binding
// and motion options, the run's perception), in front of a StandInDriver whose every call is a DriverCall answered by
// the run's process. It steps only when told to: no clock, no thread of its own besides Fast DDS's.
//
// Meeting: the agent says hello (a TurnCall kDone of turn 0, with its settings: turn_settings()) every 50 ms from when
// both its endpoints match the run's until the first turn comes; the run's end waits (wait_for_agent) for a hello and
// for its turn writer to match the agent's reader: a sample written to a reader that has not matched yet is lost (a
// volatile topic), and these checks make both directions matched on both sides before the first turn. A hello whose
// settings differ from the run's (another perception, control period, program) is refused, naming both, and the
// agent is then not taken as present.
//
// Liveliness: as the other topics (DdsOptions::lease). A turn whose agent loses its liveliness or its endpoints, or
// gives no answer for `TurnOptions::answer_timeout`, ends the run failed (InternalError naming the robot and what was
// seen); the agent, when the run's process loses its liveliness or leaves, or sends the end, stops serving.
//
// Threads: TurnLink's take_turn on the run's turn thread; its listener hands samples over on Fast DDS's thread.
// TurnAgent::serve on one thread (samples handed over from Fast DDS's); request_stop from any thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "cellwright/distributed/link.hpp"
#include "cellwright/models/cell.hpp"
#include "cellwright/runtime/runtime.hpp"
#include "cellwright/task/compiled.hpp"

namespace cellwright::distributed {

// What both ends must agree on for the agent's robot control to be the one the run would have built: the program
// (its file and robots), the robot, the control period and the perception. A line of text, compared whole.
std::string turn_settings(const task::CompiledProgram& program, const std::string& robot, runtime::SimDuration period,
                          runtime::Perception perception);

struct TurnOptions {
  // How long one message of a turn may take before the agent is taken as lost even with its liveliness holding (a
  // hung agent). A turn's messages take well under a millisecond.
  std::chrono::milliseconds answer_timeout{10000};
};

// The run's end of one remote robot in lock-step.
class TurnLink final : public runtime::RemoteLink {
 public:
  // `robot`: the cell robot (the topics'), `index` its program index, `settings` this run's turn_settings(). The
  // participant, the program and both queues must outlive the link.
  TurnLink(Participant& participant, std::string robot, std::size_t index, const task::CompiledProgram& program,
           std::string settings, runtime::MessageQueue<runtime::MotionCommand>& commands,
           runtime::MessageQueue<runtime::RobotStatus>& statuses, TurnOptions options = {});
  ~TurnLink() override;
  TurnLink(const TurnLink&) = delete;
  TurnLink& operator=(const TurnLink&) = delete;

  // Whether the agent said hello with this run's settings and both topics match; waits at most `timeout` for it.
  bool wait_for_agent(std::chrono::milliseconds timeout) const;
  // Why the last hello was refused ("" if none was).
  std::string refused_hello() const;

  void start() override;
  // Tells the agent the run is over (once; later calls do nothing).
  void stop() override;
  runtime::LinkState state() const override;
  void share(runtime::SharedEnvironment& environment, runtime::EventLog& log) override;
  bool takes_turns() const override { return true; }
  void take_turn(runtime::SimDuration now, drivers::RobotDriver& driver) override;

  const std::string& robot() const;
  Refusals refusals() const;
  // Turns taken and driver calls answered so far.
  std::uint64_t turns() const;
  std::uint64_t calls() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// The run's side of a lock-step cell whose robots (some or all) are agents: RunConfig::attach_remote making
// TurnLinks, and the wait for their agents (InputError naming the robots whose agent did not come, the domain and how to
// start one, or why a hello was refused).
class TurnCell {
 public:
  explicit TurnCell(Participant& participant, TurnOptions options = {})
      : participant_(participant), options_(options) {}
  // The links of a run of `program` (which must outlive them) with this control period and perception.
  runtime::AttachRemote attach(const task::CompiledProgram& program, runtime::SimDuration period,
                               runtime::Perception perception);
  void wait_for_agents(std::chrono::milliseconds timeout) const;
  const std::vector<TurnLink*>& links() const { return links_; }

 private:
  Participant& participant_;
  TurnOptions options_;
  std::vector<TurnLink*> links_;
};

struct TurnAgentConfig {
  task::CompiledProgram program;
  models::CellDescription cell;
  runtime::Binding binding;
  std::string robot;  // cell robot name
  runtime::MotionOptions motion;  // the scenario's (track_held_parts is set from `perception`, as the runtime does)
  runtime::SimDuration period = std::chrono::milliseconds(10);
  runtime::Perception perception = runtime::Perception::kTruth;
  std::ostream* log_stream = nullptr;  // the agent's events are also written here (JSONL), if set
  TurnOptions options;
};

struct TurnAgentSummary {
  bool run_came = false;
  bool ended_by_stop = false;  // request_stop()
  bool run_ended = false;      // the run sent its end (not lost)
  std::uint64_t turns = 0;
  std::uint64_t calls = 0;     // driver calls made
  Refusals refusals;
  std::string phase;           // robot control's phase at the end
  std::string error;           // why serving ended early (the run lost, a refused sample), "" if it did not
};

// The agent's end: one robot's control taking its turns for a lock-step run elsewhere.
class TurnAgent {
 public:
  // InputError when `robot` is not a cell robot bound in the program (naming the program's robots), or the binding is
  // wrong. Creates the DDS endpoints.
  TurnAgent(Participant& participant, TurnAgentConfig config);
  ~TurnAgent();
  TurnAgent(const TurnAgent&) = delete;
  TurnAgent& operator=(const TurnAgent&) = delete;

  const std::string& label() const;
  std::size_t index() const;
  // Serves one run: says hello until the first turn (InputError when none came within `wait`, naming the domain),
  // then takes turns until the run's end, the run's loss or request_stop().
  TurnAgentSummary serve(std::chrono::milliseconds wait);
  void request_stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellwright::distributed
