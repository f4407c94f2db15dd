#include "cellwright/runtime/runtime.hpp"
#include "cellwright/runtime/remote_watch.hpp"
#include "cellwright/models/robot_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <set>
#include <thread>

#include "cellwright/runtime/clock.hpp"
#include "cellwright/runtime/device_hub.hpp"
#include "cellwright/runtime/event.hpp"
#include "cellwright/runtime/message_queue.hpp"

namespace cellwright::runtime {

const char* to_string(Mode mode) {
  return mode == Mode::kLockstep ? "lockstep" : "realtime";
}

const char* to_string(Outcome outcome) {
  switch (outcome) {
    case Outcome::kFinished:
      return "finished";
    case Outcome::kFailed:
      return "failed";
    case Outcome::kStopped:
      return "stopped";
    case Outcome::kTimeout:
      return "timeout";
  }
  return "?";
}

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? std::string("none") : s;
}

template <typename Specs>
std::vector<std::string> names_of(const Specs& specs) {
  std::vector<std::string> out;
  for (const auto& s : specs) out.push_back(s.name);
  return out;
}

bool has_grasp(const models::CellDescription& cell, const std::string& robot) {
  if (!cell.handover) return false;
  return std::any_of(cell.handover->grasps.begin(), cell.handover->grasps.end(),
                     [&](const models::HandoverGrasp& g) { return g.robot == robot; });
}

// Checks the binding against the program and the cell; returns the label -> cell name maps.
NameMap check_binding(const RunConfig& c) {
  NameMap names;
  const Binding& b = c.binding;
  std::map<std::string, std::string> used;  // cell robot -> label
  for (const std::string& label : c.program.robots) {
    auto it = b.robots.find(label);
    if (it == b.robots.end()) {
      throw InputError(b.where, fmt::format("program robot '{}' is not bound to a robot of the cell (cell robots: {})",
                                            label, joined(names_of(c.cell.robots))));
    }
    const auto& [name, where] = it->second;
    if (c.cell.find_robot(name) == nullptr) {
      throw InputError(where, fmt::format("program robot '{}' is bound to '{}', which is not a robot of the cell "
                                          "(cell robots: {})",
                                          label, name, joined(names_of(c.cell.robots))));
    }
    if (auto [u, fresh] = used.emplace(name, label); !fresh) {
      throw InputError(
          where, fmt::format("program robots '{}' and '{}' are both bound to cell robot '{}'", u->second, label, name));
    }
    auto d = c.drivers.find(name);
    const bool remote = std::find(c.remote_robots.begin(), c.remote_robots.end(), name) != c.remote_robots.end();
    if (!remote && (d == c.drivers.end() || d->second == nullptr)) {
      throw InputError(where, fmt::format("cell robot '{}' (program robot '{}') has no driver", name, label));
    }
    names.robots[label] = name;
  }
  for (const auto& [label, entry] : b.robots) {
    if (std::find(c.program.robots.begin(), c.program.robots.end(), label) == c.program.robots.end()) {
      throw InputError(entry.where, fmt::format("'{}' is not a robot of the program (program robots: {})", label,
                                                joined(c.program.robots)));
    }
  }
  const auto object = [&](const std::string& label, bool workpiece) {
    auto it = b.objects.find(label);
    const std::string name = it == b.objects.end() ? label : it->second.name;
    const SourceLocation where = it == b.objects.end() ? b.where : it->second.where;
    const bool found = workpiece ? c.cell.find_workpiece(name) != nullptr : c.cell.find_location(name) != nullptr;
    if (!found) {
      const char* kind = workpiece ? "workpiece" : "location";
      const std::vector<std::string> known = workpiece ? names_of(c.cell.workpieces) : names_of(c.cell.locations);
      throw InputError(where, it == b.objects.end()
                                  ? fmt::format("program {} '{}' is not a {} of the cell and is not bound to one "
                                                "(cell {}s: {})",
                                                kind, label, kind, kind, joined(known))
                                  : fmt::format("program {} '{}' is bound to '{}', which is not a {} of the cell "
                                                "(cell {}s: {})",
                                                kind, label, name, kind, kind, joined(known)));
    }
    names.objects[label] = name;
  };
  for (const auto& w : c.program.workpieces) object(w, true);
  for (const auto& l : c.program.locations) object(l, false);
  for (const task::WorkpieceClass& w : c.program.classes) names.classes[w.name] = names.objects.at(w.from);
  for (const auto& [label, entry] : b.objects) {
    if (names.objects.count(label) == 0 && !task::declares_device(c.program, label)) {
      throw InputError(entry.where,
                       fmt::format("'{}' is not a workpiece or location of the program (workpieces: {}; locations: {})",
                                   label, joined(c.program.workpieces), joined(c.program.locations)));
    }
  }
  // Hand-over targets need the cell's hand-over and a grasp there for the robots involved.
  for (std::size_t r = 0; r < c.program.programs.size(); ++r) {
    const std::string& label = c.program.robots[r];
    for (const task::Primitive& p : c.program.programs[r].primitives) {
      if (p.kind != task::PrimitiveKind::kMove) continue;
      const task::TargetKind k = p.target.kind;
      if (k != task::TargetKind::kHandover && k != task::TargetKind::kHandApproach &&
          k != task::TargetKind::kHandGrasp) {
        continue;
      }
      if (!c.cell.handover) {
        throw InputError(p.where, fmt::format("robot {}: '{}' needs a hand-over, and cell '{}' has none", label,
                                              task::to_string(p), c.cell.name));
      }
      for (const std::string& who : {label, p.target.object}) {
        auto it = names.robots.find(who);
        CW_CHECK(it != names.robots.end(), "target robot '{}' of '{}' is not a program robot", who, task::to_string(p));
        if (!has_grasp(c.cell, it->second)) {
          throw InputError(p.where, fmt::format("robot {}: '{}' needs a grasp for cell robot '{}' at hand-over '{}', "
                                                "which has none",
                                                label, task::to_string(p), it->second, c.cell.handover->name));
        }
      }
    }
  }
  return names;
}

// The cell device a program device label is bound to (the binding's objects, else the same name).
std::pair<std::string, SourceLocation> bound_device(const Binding& b, const std::string& label) {
  auto it = b.objects.find(label);
  return it == b.objects.end() ? std::pair{label, b.where} : std::pair{it->second.name, it->second.where};
}

// Checks the program's devices against the cell and the I/O units (runtime.hpp, the input errors); returns program
// device label -> cell device name, and adds each machine's fixture location to `names.objects` (a robot's `Place M`
// goes there). Fills in the limits of the units' devices that have none (RecoveryOptions).
std::map<std::string, std::string> check_devices(RunConfig& c, NameMap& names) {
  std::map<std::string, std::string> devices;
  const task::CompiledProgram& p = c.program;
  const auto wired = [&](const std::string& cell, const std::string& label, const SourceLocation& where) {
    for (const IoUnit& u : c.io_units) {
      for (const DeviceWiring& w : u.devices) {
        if (w.name == cell) return;
      }
    }
    // A machine needs all three of its addresses; say which are missing when some are given.
    std::vector<std::string> missing;
    if (const models::MachineSpec* m = c.cell.find_machine(cell)) {
      if (m->start_io.address < 0) missing.push_back("start");
      if (m->busy_io.address < 0) missing.push_back("busy");
      if (m->done_io.address < 0) missing.push_back("done");
      if (missing.size() < 3) {
        throw InputError(m->where, fmt::format("program device '{}' (cell machine '{}') is on no I/O unit: the cell "
                                               "description's `io` of machine '{}' lacks {}, and device control "
                                               "needs start, busy and done (docs/cell-description.md, \"io\")",
                                               label, cell, cell, joined(missing)));
      }
    }
    throw InputError(where, fmt::format("program device '{}' (cell device '{}') is on no I/O unit: the cell "
                                        "description gives it no `io` addresses, so device control cannot drive it "
                                        "(docs/cell-description.md, \"io\")",
                                        label, cell));
  };
  for (const std::string& label : p.machines) {
    const auto [cell, where] = bound_device(c.binding, label);
    const models::MachineSpec* m = c.cell.find_machine(cell);
    if (m == nullptr) {
      throw InputError(where, fmt::format("program machine '{}' is {}not a machine of the cell (cell machines: {})",
                                          label, cell == label ? "" : fmt::format("bound to '{}', which is ", cell),
                                          joined(names_of(c.cell.machines))));
    }
    // Its fixture: the location at the fixture's top (`at: M.fixture` in the cell description).
    const models::LocationSpec* at = c.cell.fixture_location(*m);
    const std::string fixture = at != nullptr ? at->name : std::string();
    if (fixture.empty()) {
      throw InputError(m->where, fmt::format("machine '{}' has no location at its fixture, where robots put parts "
                                             "into it: add one to the cell's locations, e.g. `- {{name: {}_fixture, "
                                             "at: {}.fixture, reach: [ROBOT]}}`",
                                             cell, cell, cell));
    }
    names.objects[label] = fixture;
    wired(cell, label, where);
    devices[label] = cell;
  }
  for (const std::string& label : p.conveyors) {
    const auto [cell, where] = bound_device(c.binding, label);
    if (c.cell.find_conveyor(cell) == nullptr) {
      throw InputError(where, fmt::format("program conveyor '{}' is {}not a conveyor of the cell (cell conveyors: {})",
                                          label, cell == label ? "" : fmt::format("bound to '{}', which is ", cell),
                                          joined(names_of(c.cell.conveyors))));
    }
    wired(cell, label, where);
    devices[label] = cell;
  }
  for (const task::SensorDecl& s : p.sensors) {
    const auto [cell, where] = bound_device(c.binding, s.name);
    const std::string belt = devices.count(s.conveyor) ? devices.at(s.conveyor) : s.conveyor;
    std::vector<std::string> eyes;
    bool found = false;
    for (const auto& cv : c.cell.conveyors) {
      if (cv.stop_eye) eyes.push_back(cv.stop_eye_name);
      if (cv.drop_eye) eyes.push_back(cv.drop_eye_name);
      if ((cv.stop_eye && cv.stop_eye_name == cell) || (cv.drop_eye && cv.drop_eye_name == cell)) {
        found = true;
        if (cv.name != belt) {
          throw InputError(where, fmt::format("program sensor '{}' is on conveyor '{}' (cell conveyor '{}'), and "
                                              "cell sensor '{}' watches conveyor '{}'",
                                              s.name, s.conveyor, belt, cell, cv.name));
        }
      }
    }
    if (!found) {
      throw InputError(where, fmt::format("program sensor '{}' is {}not a photo-eye of the cell (cell photo-eyes: {})",
                                          s.name, cell == s.name ? "" : fmt::format("bound to '{}', which is ", cell),
                                          joined(eyes)));
    }
    wired(cell, s.name, where);
    devices[s.name] = cell;
  }
  const RecoveryOptions& r = c.motion.recovery;
  for (IoUnit& u : c.io_units) {
    CW_CHECK(u.io != nullptr, "an I/O unit has no DigitalIo");
    for (DeviceWiring& w : u.devices) {
      if (w.limit.count() > 0) continue;
      if (w.kind == DeviceKind::kSensor) w.limit = r.sensor_wait;
      if (w.kind != DeviceKind::kMachine) continue;
      if (const models::MachineSpec* m = c.cell.find_machine(w.name)) {
        w.limit = std::chrono::duration_cast<SimDuration>(
                      std::chrono::duration<double>(m->process_time * r.machine_time_factor)) +
                  r.machine_time_margin;
      }
    }
  }
  return devices;
}

}  // namespace

struct Runtime::Impl {
  Impl(RunConfig& c, EventLog& l) : cfg(c), log(l), env(make_environment_model(c.cell)), statuses(64) {}

  RunConfig& cfg;
  EventLog& log;
  NameMap names;
  std::vector<std::string> cells;        // per program robot
  std::vector<std::string> cell_robots;  // every cell robot, in the cell's order (the sensors are read so)
  SharedEnvironment env;
  Coordination coordination;  // the robots' rendezvous for coordinated blocks (coordination.hpp)
  std::vector<std::unique_ptr<MessageQueue<MotionCommand>>> inboxes;
  MessageQueue<RobotStatus> statuses;
  std::unique_ptr<TaskControl> task;
  // Device control (the program has device commands): its inbox and its work.
  MessageQueue<MotionCommand> device_inbox{64};
  std::unique_ptr<DeviceHub> devices;
  Event device_wake{Event::Kind::auto_reset};
  std::vector<std::unique_ptr<RobotControl>> robots;  // nullptr for a remote robot
  std::vector<std::unique_ptr<RemoteLink>> remote;    // per program robot: its link, for a remote robot
  std::vector<std::unique_ptr<RemoteWatch>> lockstep_watches;  // lock-step: each remote robot's link watch
  VirtualClock clock;
  // Vision (Perception::kVision): frames from the simulation thread to the image-processing thread.
  MessageQueue<Frame> frames{2};
  std::unique_ptr<ImageProcessing> vision;
  SimDuration next_frame{0};
  std::unique_ptr<LockstepScheduler> scheduler;
  std::vector<std::thread> threads;
  bool started = false;

  // Published by task control after each of its steps, read by the simulation thread (real-time: concurrently).
  std::atomic<int> task_state{static_cast<int>(TaskControl::State::kRunning)};
  std::atomic<std::int64_t> finished_at_ns{-1};
  std::atomic<std::uint64_t> task_firings{0};

  // Real-time mode.
  std::atomic<bool> stopping{false};
  Event task_wake{Event::Kind::auto_reset};
  std::vector<std::unique_ptr<Event>> robot_wake;

  // When the run started on the wall clock, moved on by the time parked between steps (simulation thread).
  std::chrono::steady_clock::time_point wall_start;

  // A stop asked for from outside (Runtime::request_stop).
  std::atomic<bool> stop_requested{false};
  std::mutex stop_mutex;
  std::string stop_reason;

  // The end, as the simulation thread decided it.
  Outcome outcome = Outcome::kTimeout;
  std::string reason;
  std::vector<Collision> collisions;
  std::size_t detections_seen = 0;  // fault_detected lines the simulation thread has logged the physical state after
  std::vector<SimDuration> next_observation;  // per observer
  bool observed_robots = false;  // some observer wants task and robot control's views
  // Whether task and robot control copy their views after each step (observed_robots, or real time: wait_held()).
  bool publish_views = false;
  // Task control's view and robot control's (this process's robots, program order) after their last step, for the
  // observers and a held real-time run (their participants write, the simulation thread and the caller read).
  std::mutex observed_mutex;
  TaskView observed_task;
  std::vector<RobotControlView> observed_controls;
  std::vector<std::size_t> control_slot;  // per program robot: its index in observed_controls (remote: none, npos)
  std::vector<std::string> fired_since_go;  // real time: the transitions fired since the last go() (the last 1000)

  // Stepping (lock-step): the simulation thread parks at the start of its turn after a period with firings.
  std::mutex m;
  std::condition_variable cv;
  bool step_mode = false;
  std::optional<SimDuration> pause_at;  // step(until): also park once the clock has reached this
  bool paused = false;
  bool resume = false;
  bool hold_now = false;  // real time: hold() asked to park at the next period
  bool abort = false;
  bool ended = false;
  std::uint64_t firings_seen = 0;
  std::uint64_t pauses = 0;
  std::exception_ptr error;

  std::optional<RunResult> result;

  void record_error() {
    std::lock_guard lock(m);
    if (!error) error = std::current_exception();
  }
  void end_all() {
    stopping = true;
    if (scheduler) scheduler->stop();
    frames.close();
    task_wake.set();
    device_wake.set();
    for (auto& e : robot_wake) e->set();
    std::lock_guard lock(m);
    abort = true;
    ended = true;
    cv.notify_all();
  }
  void announce_end() {
    std::lock_guard lock(m);
    ended = true;
    cv.notify_all();
  }

  // Parks after a period with firings when stepping, at the time step(until)/go() gave, or (real time) when hold()
  // asked. Returns false when the run is aborted; `*parked_out` says whether it parked.
  bool maybe_pause(bool* parked_out = nullptr) {
    std::unique_lock lock(m);
    if (!step_mode && !pause_at && !hold_now) return !abort;
    const std::uint64_t f = task_firings.load();
    const bool at_time = pause_at && clock.now() >= *pause_at;
    const bool at_firing = step_mode && f > firings_seen;
    if (!at_firing && !at_time && !hold_now) return !abort;
    firings_seen = f;
    pause_at.reset();
    hold_now = false;
    paused = true;
    ++pauses;
    const auto parked = std::chrono::steady_clock::now();
    cv.notify_all();
    // A real-time run held may be asked to stop meanwhile (the simulation turn then ends it); a lock-step one parked
    // goes on only when the caller steps again, since the caller reads the plant meanwhile.
    const bool realtime = cfg.mode == Mode::kRealtime;
    cv.wait(lock, [&] { return resume || abort || (realtime && stop_requested.load()); });
    wall_start += std::chrono::steady_clock::now() - parked;  // parked time is not run time
    resume = false;
    paused = false;
    if (parked_out) *parked_out = true;
    return !abort;
  }

  // The simulation's turn: decide the end, else advance one period. Returns false when the run ends.
  bool sim_turn() {
    const SimDuration now = clock.now();
    const auto state = static_cast<TaskControl::State>(task_state.load());
    if (state == TaskControl::State::kFailed) {
      outcome = Outcome::kFailed;
      return false;
    }
    if (state == TaskControl::State::kStopped) {
      outcome = Outcome::kStopped;
      return false;
    }
    if (stop_requested.load()) {
      outcome = Outcome::kStopped;
      std::lock_guard lock(stop_mutex);
      reason = stop_reason;
      return false;
    }
    if (state == TaskControl::State::kFinished && now >= SimDuration(finished_at_ns.load()) + cfg.limits.settle) {
      outcome = Outcome::kFinished;
      return false;
    }
    if (now >= cfg.limits.sim_time) {
      outcome = Outcome::kTimeout;
      reason = fmt::format("the simulation time limit of {} s was reached before the program finished",
                           format_sim_time(cfg.limits.sim_time));
      return false;
    }
    if (cfg.limits.wall_time.count() > 0 && std::chrono::steady_clock::now() - wall_start >= cfg.limits.wall_time) {
      outcome = Outcome::kTimeout;
      reason = fmt::format(
          "the wall time limit of {:g} s was reached at simulation time {} s, before the program "
          "finished",
          std::chrono::duration<double>(cfg.limits.wall_time).count(), format_sim_time(now));
      return false;
    }
    const SimDuration t = now + cfg.period;
    // No simulation: the robots' drivers run on their own; this thread keeps the clock and reads the sensors.
    if (cfg.plant != nullptr) cfg.plant->advance(cfg.period);
    const SensorReadings readings = read_sensors(cfg.sensors, cell_robots, t);
    env.write([&](EnvironmentModel& e) { apply_readings(e, readings, cfg.perception); });
    if (cfg.plant == nullptr) {
      clock.advance(cfg.period);
    } else {
      for (Collision& c : cfg.plant->new_collisions()) {
        log.collision(t, c.a, c.b, c.depth);
        collisions.push_back(std::move(c));
      }
      for (const Arrival& a : cfg.plant->new_arrivals()) {
        if (a.left) {
          log.workpiece_left(t, a.workpiece, a.where);
        } else {
          log.workpiece_arrived(t, a.workpiece, a.where);
        }
      }
      // A detection since the previous period: the plant's physical state with it, for the report to judge it by.
      if (const std::size_t d = log.detections(); d != detections_seen) {
        detections_seen = d;
        const Truth truth = cfg.plant->truth();
        std::vector<EventLog::Held> held;
        for (const RobotTruth& r : truth.robots) {
          if (r.between_fingers) held.push_back({r.name, *r.between_fingers});
        }
        log.physical(t, held, truth.obstacles.size());
      }
      clock.advance(cfg.period);  // after the model is written, so a reader at time t sees t's truth (real-time)
    }
    if (vision && t >= next_frame) {
      // Rendered here (after the clock has moved to t, so that the image thread never sees a frame from its future):
      // the simulation thread owns the physics state the camera shows, and the rendering context.
      Frame f;
      f.time = t;
      std::string why;
      std::optional<Image> image = cfg.camera != nullptr ? cfg.camera->capture(t, &why)
                                                         : cfg.plant->capture(vision->options().camera, &why);
      if (image) {
        f.image = std::move(*image);
      } else {
        f.problem = why;
      }
      // Real-time: image processing may lag; a frame it has no room for is dropped (the next one is newer anyway).
      // Lock-step: image processing sleeps until told, and takes this frame in this period, right after this turn.
      if (frames.try_push(std::move(f)) == QueueStatus::ok && scheduler) scheduler->notify(vision_seat());
      next_frame += vision->options().period;
    } else if (!vision && cfg.camera_frames && cfg.on_frame && cfg.plant != nullptr && t >= next_frame) {
      // Plain camera frames (no vision): handed over here, on the thread that rendered them; a failed capture is
      // skipped (no one acts on these frames).
      if (std::optional<Image> image = cfg.plant->capture(cfg.camera_frames->camera, nullptr)) {
        cfg.on_frame(VisionFrame{t, std::move(*image), Sightings{}, {}});
      }
      next_frame += cfg.camera_frames->period;
    }
    for (std::size_t k = 0; k < cfg.observers.size(); ++k) {
      const RunObserver& o = cfg.observers[k];
      if (o.every.count() <= 0 || !o.observe || t < next_observation[k]) continue;
      std::lock_guard lock(observed_mutex);
      const auto observing = std::chrono::steady_clock::now();
      o.observe(Observation{t, task_firings.load(), observed_task.robots, env, observed_task, observed_controls});
      // Time spent observing (a video's encoder catching up) is not run time: a run ends on its wall-time limit
      // where it would without the observer, so that the event log is the same with and without.
      wall_start += std::chrono::steady_clock::now() - observing;
      while (next_observation[k] <= t) next_observation[k] += o.every;  // multiples of `every`: fixed times
    }
    return true;
  }

  void task_step() {
    const TaskControl::State s = task->step(clock.now());
    // The view first: the simulation thread that sees the new firings count (and holds there) finds it published.
    if (publish_views) {
      TaskView v = task->view();
      std::lock_guard lock(observed_mutex);
      if (cfg.mode == Mode::kRealtime) {
        fired_since_go.insert(fired_since_go.end(), v.last_fired.begin(), v.last_fired.end());
        if (fired_since_go.size() > 1000) {
          fired_since_go.erase(fired_since_go.begin(), fired_since_go.end() - 1000);
        }
      }
      observed_task = std::move(v);
    }
    task_firings = task->firings();
    if (s == TaskControl::State::kFinished && finished_at_ns.load() < 0) {
      finished_at_ns = task->finished_at()->count();
    }
    task_state = static_cast<int>(s);
  }

  // Robot control r's step, and its view published after it when someone reads it.
  void robot_step(std::size_t r, SimDuration now) {
    robots[r]->step(now);
    if (publish_views) {
      RobotControlView v = robots[r]->view();
      std::lock_guard lock(observed_mutex);
      observed_controls[control_slot[r]] = std::move(v);
    }
  }

  // The state step() and wait_held() answer, from the objects themselves: at the end (threads joined) or in lock-step
  // (parked: no other thread runs).
  StepState state_now() {
    StepState s;
    s.time = result ? result->end_time : clock.now();
    s.task = task->view();
    for (const auto& r : robots) {
      if (r) s.robots.push_back(r->view());
    }
    if (result) {
      s.ended = true;
      s.result = result;
    }
    return s;
  }

  // Lock-step: one thread's loop. It takes the turns of the participants the scheduler put on it (by default all).
  void run_lockstep(std::size_t thread) {
    LockstepScheduler::Seat seat(*scheduler, LockstepScheduler::Thread{thread});
    try {
      while (seat.await_turn()) {
        if (seat.id() == 0) {
          if (!maybe_pause() || !sim_turn()) {
            scheduler->stop();
            announce_end();
            break;
          }
          seat.yield();
        } else {
          seat.yield(take_turn(seat.id()));
        }
      }
    } catch (...) {
      record_error();
      end_all();
    }
    // The run is over (or this thread failed and ended it): halt the robots this thread served, then free the
    // plant's thread resources on the thread that stepped it.
    for (std::size_t r = 0; r < robots.size(); ++r) {
      if (scheduler->thread_of(first_robot_seat() + r) != thread) continue;
      try {
        if (robots[r]) {
          robots[r]->halt();
        } else {
          cfg.drivers.at(cells[r])->stop();  // a remote robot's halt (RobotControl::halt): its driver is here
        }
      } catch (...) {
        record_error();
        end_all();
      }
    }
    if (scheduler->thread_of(0) == thread) release_plant();
  }

  // Lock-step: the turn of participant p (not the simulation), and when it next needs one.
  Wake take_turn(std::size_t p) {
    const SimDuration now = clock.now();
    const bool skip = cfg.lockstep_skip_idle;
    if (vision && p == vision_seat()) {
      vision->step(now);
      return skip ? Wake::on_notify() : Wake::next_round();  // the simulation notifies it with each frame
    }
    if (p == task_seat()) {
      task_step();
      // It has nothing to do until a robot reports (that robot's turn notifies it: it runs next period, as it always
      // did, the robots coming after it) unless its wait watchdog is armed: that is a time, so it looks every period.
      return skip && !task_watches_time() ? Wake::on_notify() : Wake::next_round();
    }
    if (devices && p == device_seat()) {
      devices->step(now);
      if (statuses.size() > 0) scheduler->notify(task_seat());
      return Wake::next_round();  // every period it reads the devices' states and polls what it waits for
    }
    const std::size_t r = p - first_robot_seat();
    if (robots[r]) {
      robot_step(r, now);
    } else {
      // Its robot control's step, in its agent. A lost agent is a link_lost fault, as in real time (remote_watch.hpp),
      // found in this turn; no new agent can take over a lock-step run's robot control (its state went with it).
      remote[r]->take_turn(now, *cfg.drivers.at(cells[r]));
      (void)lockstep_watches[r]->step(now);
    }
    if (statuses.size() > 0) scheduler->notify(task_seat());
    return Wake::next_round();  // every period it reads where its arm is and watches its grip and the safety layer
  }

  // Whether task control's step depends on time now, not only on statuses: recovery's watchdog on a robot waiting
  // for an event (TaskControl::step, 4). Anything else in its step happens only after a status arrives. Keep this in
  // step with TaskControl::step: a turn skipped that had something to do changes the run (the runtime tests compare
  // the log with and without skipping).
  bool task_watches_time() const {
    return cfg.motion.recovery.enabled && task->state() == TaskControl::State::kRunning && task->any_waiting();
  }

  // Seats (lock-step turns): simulation, image processing (with vision), task control, device control (with
  // devices), robots.
  std::size_t vision_seat() const { return 1; }
  std::size_t task_seat() const { return vision ? 2 : 1; }
  std::size_t device_seat() const { return task_seat() + 1; }
  std::size_t first_robot_seat() const { return task_seat() + (devices ? 2 : 1); }
  std::size_t participants() const { return first_robot_seat() + robots.size(); }

  std::chrono::steady_clock::duration wall_period() const {
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double, std::nano>(static_cast<double>(cfg.period.count()) / cfg.realtime_speed));
  }

  void run_realtime(std::size_t participant) {
    try {
      if (participant == 0) {
        RealtimePacer pacer(cfg.realtime_speed);
        pacer.anchor(clock.now());
        while (!stopping) {
          bool parked = false;
          if (!maybe_pause(&parked)) break;
          if (parked) pacer.anchor(clock.now());  // no catching up on the hold
          pacer.pace(clock.now() + cfg.period);
          if (!sim_turn()) break;
        }
        release_plant();
        end_all();
      } else if (vision && participant == vision_seat()) {
        while (!stopping) {
          Frame f;
          if (frames.pop_for(f, wall_period() * 10) != QueueStatus::ok) continue;
          vision->process(f, clock.now());
          // The model changed: whoever waits for a part looks again now.
          task_wake.set();
          for (auto& e : robot_wake) e->set();
        }
      } else if (participant == task_seat()) {
        while (!stopping) {
          // Woken by a status; at least once a period, for the time accounting.
          (void)task_wake.wait_for(wall_period());
          if (stopping) break;
          task_step();
          for (std::size_t r = 0; r < robots.size(); ++r) {
            if (inboxes[r]->size() > 0) robot_wake[r]->set();
          }
          if (device_inbox.size() > 0) device_wake.set();
        }
      } else if (devices && participant == device_seat()) {
        while (!stopping) {
          // Woken by a command; at least once a period, to poll what it waits for and read the devices' states.
          (void)device_wake.wait_for(wall_period());
          if (stopping) break;
          devices->step(clock.now());
          if (statuses.size() > 0) task_wake.set();
        }
      } else {
        const std::size_t r = participant - first_robot_seat();
        if (!robots[r]) {
          // Remote: its robot control is an agent's, its queues carried by its link; this thread watches the link.
          RemoteWatch watch(r, cfg.program.robots[r], cells[r], *remote[r], statuses, log, cfg.motion.recovery,
                            cfg.rejoin_wait);
          while (!stopping) {
            (void)robot_wake[r]->wait_for(wall_period());
            if (stopping) break;
            if (watch.step(clock.now())) task_wake.set();
          }
          return;
        }
        while (!stopping) {
          // Woken by a command or the driver's notifier; at least once a period, to watch sensor conditions.
          (void)robot_wake[r]->wait_for(wall_period());
          if (stopping) break;
          robot_step(r, clock.now());
          if (statuses.size() > 0) task_wake.set();
        }
        robots[r]->halt();
      }
    } catch (...) {
      if (participant == 0) release_plant();
      record_error();
      end_all();
    }
  }

  // The drivers outlive the run: they must not call into it any more.
  // The driver of program robot r in this process: a local robot's, and in lock-step a remote one's (its agent calls
  // it in its turns); nullptr for a remote robot in real time (its driver is its agent's).
  drivers::RobotDriver* driver_here(std::size_t r) const {
    if (!robots[r] && cfg.mode == Mode::kRealtime) return nullptr;
    return cfg.drivers.at(cells[r]);
  }

  void detach_drivers() {
    for (std::size_t r = 0; r < cells.size(); ++r) {
      drivers::RobotDriver* d = driver_here(r);
      if (d == nullptr) continue;
      d->set_notifier({});
      d->set_clock({});
    }
  }

  void release_plant() {
    if (cfg.plant != nullptr) cfg.plant->release_thread_resources();
    if (cfg.camera != nullptr) cfg.camera->release_thread_resources();
  }
};

NameMap resolve_names(const RunConfig& config) {
  return check_binding(config);
}

Runtime::Runtime(RunConfig config) : config_(std::move(config)), log_(std::make_unique<EventLog>(config_.log_stream,
                                        config_.keep_log ? EventLog::Keep::kLines : EventLog::Keep::kNothing)) {
  CW_CHECK(config_.period.count() > 0, "the control period must be positive, got {} ns", config_.period.count());
  CW_CHECK(config_.realtime_speed > 0.0, "real-time speed must be positive, got {}", config_.realtime_speed);
  CW_CHECK(config_.net.robots() == config_.program.robots, "the net was not made from the program");
  for (const auto& observer : config_.event_observers) log_->add_observer(observer);
  impl_ = std::make_unique<Impl>(config_, *log_);
  Impl& im = *impl_;
  im.names = check_binding(config_);
  for (const models::RobotSpec& r : config_.cell.robots) im.cell_robots.push_back(r.name);
  const auto check_sensors = [&](const auto& sensors) {
    for (const auto& entry : sensors) {
      CW_CHECK(config_.cell.find_robot(entry.first) != nullptr, "a sensor is wired for '{}', which is not a cell robot",
               entry.first);
    }
  };
  check_sensors(config_.sensors.grip);
  check_sensors(config_.sensors.force);

  std::vector<MessageQueue<MotionCommand>*> inbox_ptrs;
  for (std::size_t r = 0; r < config_.program.robots.size(); ++r) {
    im.inboxes.push_back(std::make_unique<MessageQueue<MotionCommand>>(4));
    inbox_ptrs.push_back(im.inboxes.back().get());
    im.robot_wake.push_back(std::make_unique<Event>(Event::Kind::auto_reset));
  }
  if (config_.perception == Perception::kVision) {
    CW_CHECK(config_.vision.has_value() && config_.detector != nullptr &&
                 (config_.plant != nullptr || config_.camera != nullptr),
             "vision perception needs a camera, a detector and a frame source or a plant that renders the camera");
    im.vision = std::make_unique<ImageProcessing>(*config_.detector, im.env, im.frames, *log_, *config_.vision,
                                                  config_.on_frame, config_.motion.recovery);
    // Until the camera has seen them, parts are not known to be in the cell (a fed part may not have arrived): their
    // poses stay the cell description's, unconfirmed, nothing known of their motion.
    im.env.write([](EnvironmentModel& m) {
      for (WorkpieceState& w : m.workpieces) {
        w.present = false;
        w.confidence = 0;
        w.motion_known = false;
      }
    });
  }
  config_.motion.track_held_parts = config_.perception != Perception::kTruth;
  std::map<std::string, std::string> devices = check_devices(config_, im.names);
  const bool has_devices = std::any_of(config_.program.programs.begin(), config_.program.programs.end(), [](const auto& p) {
    return std::any_of(p.primitives.begin(), p.primitives.end(),
                       [](const task::Primitive& q) { return q.kind == task::PrimitiveKind::kDevice; });
  });
  if (has_devices || !devices.empty()) {
    im.devices = std::make_unique<DeviceHub>(config_.io_units, std::move(devices), config_.program, im.device_inbox,
                                             im.statuses, *log_, im.env, config_.motion.recovery);
  }
  im.task = std::make_unique<TaskControl>(config_.net, config_.program, inbox_ptrs, im.statuses, *log_,
                                          config_.motion.recovery, config_.signal_filter,
                                          im.devices ? &im.device_inbox : nullptr);
  if (!config_.firing_order.empty()) im.task->follow(config_.firing_order);
  for (const std::string& cell : config_.remote_robots) {
    const bool in_program = std::any_of(im.names.robots.begin(), im.names.robots.end(),
                                        [&](const auto& entry) { return entry.second == cell; });
    if (!in_program) {
      throw InputError(config_.binding.where, fmt::format("remote robot '{}' is not a robot of the program", cell));
    }
    if (config_.mode != Mode::kRealtime) {
      const auto d = config_.drivers.find(cell);
      if (d == config_.drivers.end() || d->second == nullptr) {
        throw InputError(config_.binding.where,
                         fmt::format("robot '{}' is remote in a lock-step run, which needs its driver here (the "
                                     "twin's: its agent's robot control calls it in its turns)",
                                     cell));
      }
    }
    CW_CHECK(static_cast<bool>(config_.attach_remote), "remote robots but nothing to attach them");
  }
  for (std::size_t r = 0; r < config_.program.robots.size(); ++r) {
    const std::string& label = config_.program.robots[r];
    const std::string& cell = im.names.robots.at(label);
    const models::RobotSpec& spec = *config_.cell.find_robot(cell);
    im.cells.push_back(cell);
    const bool remote =
        std::find(config_.remote_robots.begin(), config_.remote_robots.end(), cell) != config_.remote_robots.end();
    if (remote) {
      // A coordinated block's robots meet on a board in this process's memory (coordination.hpp).
      for (const task::Primitive& p : config_.program.programs[r].primitives) {
        if (!p.segment) continue;
        throw InputError(p.where, fmt::format("robot {} ({}) is remote, and this command is part of a coordinated "
                                              "block, whose robots meet in one process: run the robots of a "
                                              "coordinated block in one process (--agents local)",
                                              label, cell));
      }
    }
    im.remote.push_back(remote ? config_.attach_remote(r, cell, *im.inboxes[r], im.statuses) : nullptr);
    if (remote) {
      if (config_.mode != Mode::kRealtime && !im.remote.back()->takes_turns()) {
        throw InputError(config_.binding.where,
                         fmt::format("robot '{}' is remote and its link carries no lock-step turns: run it in real "
                                     "time",
                                     cell));
      }
      im.remote.back()->share(im.env, *log_);
      im.robots.push_back(nullptr);
      continue;
    }
    im.robots.push_back(std::make_unique<RobotControl>(
        r, label, cell, *config_.drivers.at(cell), models::robot_chain(spec), spec.grip_force,
        im.names, im.env, *im.inboxes[r], im.statuses, *log_, config_.motion, config_.mode == Mode::kRealtime,
        &im.coordination));
  }
}

Runtime::~Runtime() {
  if (impl_ && impl_->started) {
    impl_->end_all();
    for (auto& t : impl_->threads) {
      if (t.joinable()) t.join();
    }
    impl_->detach_drivers();
  }
  if (impl_) {
    for (auto& link : impl_->remote) {
      if (link) link->stop();
    }
  }
}

RunResult Runtime::run() {
  Impl& im = *impl_;
  if (im.result) return *im.result;
  if (!im.started) {
    start();
  } else {
    std::lock_guard lock(im.m);
    im.step_mode = false;
    im.resume = true;
    im.paused = false;
    im.cv.notify_all();
  }
  return finish();
}

StepState Runtime::step(std::optional<SimDuration> until) {
  Impl& im = *impl_;
  if (config_.mode == Mode::kRealtime) {
    go(HoldAt{true, until});
    return *wait_held(std::chrono::steady_clock::duration::max());
  }
  if (!im.result) {
    {
      std::lock_guard lock(im.m);
      im.step_mode = true;
      im.pause_at = until;
    }
    if (!im.started) {
      start();
    } else {
      std::lock_guard lock(im.m);
      im.resume = true;
      im.paused = false;  // cleared here, so the wait below waits for the next pause, not the one just ended
      im.cv.notify_all();
    }
    {
      std::unique_lock lock(im.m);
      im.cv.wait(lock, [&] { return im.paused || im.ended; });
    }
    if (!im.paused) finish();
  }
  // Ended, or parked: the simulation thread holds the turn and waits (any other lock-step thread waits for its turn).
  return im.state_now();
}

void Runtime::go(HoldAt at) {
  Impl& im = *impl_;
  CW_CHECK(config_.mode == Mode::kRealtime, "go() lets a real-time run go; a lock-step one steps");
  if (im.result) return;
  {
    std::lock_guard lock(im.m);
    if (im.ended) return;
    im.step_mode = at.firing;
    im.pause_at = at.time;
    im.hold_now = false;
    // A firing counts from now. The count is the published view's, read with the list it clears: task control
    // publishes its view (appending to the list) before it stores task_firings, so a firing either is in this count
    // or is appended after the clear, and raises task_firings above it.
    std::lock_guard views(im.observed_mutex);
    im.firings_seen = im.observed_task.firings;
    im.fired_since_go.clear();
    if (im.paused) {
      im.resume = true;
      im.paused = false;  // cleared here, so that wait_held() waits for the next hold, not the one just ended
      im.cv.notify_all();
    }
  }
  if (!im.started) start();
}

void Runtime::hold() {
  Impl& im = *impl_;
  CW_CHECK(config_.mode == Mode::kRealtime, "hold() holds a real-time run; a lock-step one is parked between steps");
  std::lock_guard lock(im.m);
  if (im.started && !im.paused && !im.ended) im.hold_now = true;
}

std::optional<StepState> Runtime::wait_held(std::chrono::steady_clock::duration wait) {
  Impl& im = *impl_;
  CW_CHECK(config_.mode == Mode::kRealtime, "wait_held() waits for a real-time run; a lock-step one steps");
  CW_CHECK(im.started, "wait_held() before the run was let go (go())");
  if (!im.result) {
    {
      std::unique_lock lock(im.m);
      const auto done = [&] { return im.paused || im.ended; };
      if (wait == std::chrono::steady_clock::duration::max()) {
        im.cv.wait(lock, done);
      } else if (!im.cv.wait_for(lock, wait, done)) {
        return std::nullopt;
      }
      if (im.paused) {
        // Held: task and robot control still run (at the frozen time), so their views are the copies they publish.
        StepState s;
        s.time = im.clock.now();
        std::lock_guard views(im.observed_mutex);
        s.task = im.observed_task;
        s.task.last_fired = im.fired_since_go;
        s.robots = im.observed_controls;
        return s;
      }
    }
    finish();
  }
  return im.state_now();
}

void Runtime::start() {
  Impl& im = *impl_;
  std::vector<EventLog::RobotName> names;
  for (std::size_t r = 0; r < config_.program.robots.size(); ++r) {
    names.push_back({config_.program.robots[r], im.cells[r]});
  }
  for (std::size_t r = 0; r < im.robots.size(); ++r) {
    if (im.robots[r]) {
      im.robots[r]->connect();  // InputError here: no thread has started
    } else if (drivers::RobotDriver* d = im.driver_here(r); d != nullptr &&
                                                              d->state() == drivers::DriverState::disconnected) {
      // A remote robot's in lock-step, connected here as its robot control would (RobotControl::connect).
      const drivers::ErrorCode e = d->connect();
      CW_CHECK(e == drivers::ErrorCode::none, "robot {}: connect() refused: {}", im.cells[r], drivers::to_string(e));
    }
  }
  if (im.devices) im.devices->connect();
  // Position read-backs are stamped on the runtime's clock.
  for (std::size_t r = 0; r < im.robots.size(); ++r) {
    if (drivers::RobotDriver* d = im.driver_here(r)) d->set_clock([&clock = im.clock] { return clock.now(); });
  }
  for (auto& link : im.remote) {
    if (link) link->start();
  }
  if (config_.mode == Mode::kLockstep) {
    im.lockstep_watches.resize(im.remote.size());
    for (std::size_t r = 0; r < im.remote.size(); ++r) {
      if (!im.remote[r]) continue;
      im.lockstep_watches[r] = std::make_unique<RemoteWatch>(r, config_.program.robots[r], im.cells[r], *im.remote[r],
                                                             im.statuses, *log_, config_.motion.recovery,
                                                             SimDuration{0});
    }
  }
  if (config_.mode == Mode::kRealtime) {
    for (std::size_t r = 0; r < im.robots.size(); ++r) {
      if (!im.robots[r]) continue;
      Event* wake = im.robot_wake[r].get();
      config_.drivers.at(im.cells[r])->set_notifier([wake] { wake->set(); });
    }
  }
  log_->run_start(im.clock.now(), config_.program.file, config_.cell.name, to_string(config_.mode), config_.period,
                  names);
  if (im.devices) im.devices->start(im.clock.now());  // every device's state from the start (no thread runs yet)
  im.next_observation.assign(config_.observers.size(), SimDuration{0});
  for (const RunObserver& o : config_.observers) im.observed_robots = im.observed_robots || o.robots;
  im.publish_views = im.observed_robots || config_.mode == Mode::kRealtime;
  im.control_slot.assign(im.robots.size(), static_cast<std::size_t>(-1));
  im.observed_controls.clear();
  for (std::size_t r = 0; r < im.robots.size(); ++r) {
    if (!im.robots[r]) continue;
    im.control_slot[r] = im.observed_controls.size();
    im.observed_controls.push_back(im.robots[r]->view());  // the first observation's, before any step
  }
  im.observed_task = im.task->view();
  const std::size_t participants = im.participants();
  im.started = true;
  im.wall_start = std::chrono::steady_clock::now();
  if (config_.mode == Mode::kLockstep) {
    std::vector<std::size_t> threads_of(participants, 0);  // kShared: every participant on the simulation thread
    if (config_.lockstep_threads == LockstepThreads::kOwn) {
      for (std::size_t p = 0; p < participants; ++p) threads_of[p] = p;
    }
    im.scheduler = std::make_unique<LockstepScheduler>(std::move(threads_of), &im.clock);
    for (std::size_t t = 0; t < im.scheduler->threads(); ++t) im.threads.emplace_back([&im, t] { im.run_lockstep(t); });
  } else {
    for (std::size_t p = 0; p < participants; ++p) im.threads.emplace_back([&im, p] { im.run_realtime(p); });
  }
}

void Runtime::set_lockstep(LockstepThreads threads, bool skip_idle) {
  CW_CHECK(!impl_->started, "the lock-step turns are chosen before the run starts");
  config_.lockstep_threads = threads;
  config_.lockstep_skip_idle = skip_idle;
}

void Runtime::request_stop(const std::string& reason) {
  Impl& im = *impl_;
  {
    std::lock_guard lock(im.stop_mutex);
    if (im.stop_requested.load()) return;
    im.stop_reason = reason;
  }
  im.stop_requested = true;
  // Parked between steps: let the simulation turn see it. A real-time run held goes on to its end now (so that
  // wait_held() waits for the end, not the hold just ended); a lock-step one at the caller's next step.
  std::lock_guard lock(im.m);
  if (config_.mode == Mode::kRealtime) im.paused = false;
  im.cv.notify_all();
}

RunResult Runtime::finish() {
  Impl& im = *impl_;
  for (auto& t : im.threads) {
    if (t.joinable()) t.join();
  }
  for (auto& link : im.remote) {
    if (link) link->stop();
  }
  if (im.error) std::rethrow_exception(im.error);
  if (im.result) return *im.result;
  im.detach_drivers();
  // Its thread has ended: no machine's start is left on, and after a stop no belt runs.
  if (im.devices) im.devices->close(im.outcome != Outcome::kFinished);
  RunResult r;
  r.end_time = im.clock.now();
  im.task->account_until(r.end_time);
  r.outcome = im.outcome;
  r.reason = im.outcome == Outcome::kFailed || (im.outcome == Outcome::kStopped && im.reason.empty())
                 ? im.task->reason()
                 : im.reason;
  r.finished_at = im.task->finished_at();
  r.final_marking = im.task->marking();
  r.firings = im.task->firings();
  for (std::size_t i = 0; i < im.robots.size(); ++i) {
    r.robots.push_back({config_.program.robots[i], im.cells[i], im.task->activity_time()[i]});
  }
  r.collisions = im.collisions;
  r.environment = im.env.snapshot();
  if (im.scheduler) {
    r.lockstep = {im.scheduler->rounds(), im.scheduler->turns(), im.scheduler->skipped(), im.scheduler->handoffs(),
                  im.pauses};
  }
  if (r.outcome == Outcome::kStopped) log_->cell_stopped(r.end_time, r.reason);
  log_->run_end(r.end_time, to_string(r.outcome), r.reason, r.firings);
  im.result = r;
  return r;
}

}  // namespace cellwright::runtime
