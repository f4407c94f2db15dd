#include "cellwright/runtime/device_hub.hpp"

#include <fmt/format.h>

#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

namespace {

constexpr double kEyeReach = 0.06;      // m: a model part this close to a photo-eye is the part it sees
constexpr double kFixtureReach = 0.05;  // m: a part this close to a machine's fixture is in the machine

}  // namespace

DeviceHub::DeviceHub(std::vector<IoUnit> units, std::map<std::string, std::string> devices,
                     const task::CompiledProgram& program, MessageQueue<MotionCommand>& inbox,
                     MessageQueue<RobotStatus>& statuses, EventLog& log, const SharedEnvironment& env,
                     RecoveryOptions recovery)
    : units_(std::move(units)),
      program_(program),
      inbox_(inbox),
      statuses_(statuses),
      log_(log),
      env_(env),
      recovery_(std::move(recovery)) {
  // Devices in the units' order (the cell's), each once, whatever the labels.
  std::map<std::string, std::vector<std::string>> labels;  // cell device -> program labels
  for (const auto& [label, cell] : devices) labels[cell].push_back(label);
  for (std::size_t u = 0; u < units_.size(); ++u) {
    CW_CHECK(units_[u].io != nullptr, "I/O unit {} has no DigitalIo", u);
    for (const DeviceWiring& w : units_[u].devices) {
      auto it = labels.find(w.name);
      if (it == labels.end()) continue;
      for (const std::string& label : it->second) {
        CW_CHECK(by_label_.count(label) == 0, "device '{}' is wired on two I/O units", w.name);
        by_label_[label] = devices_.size();
      }
      Device d;
      d.wiring = w;
      d.unit = u;
      d.control = std::make_unique<DeviceControl>(*units_[u].io, std::vector<DeviceWiring>{w});
      devices_.push_back(std::move(d));
    }
  }
  for (const auto& [label, cell] : devices) {
    CW_CHECK(by_label_.count(label) == 1, "program device '{}' (cell device '{}') is wired on no I/O unit", label,
             cell);
  }
}

void DeviceHub::connect() {
  for (const IoUnit& u : units_) {
    if (u.io->is_open()) continue;
    const drivers::IoResult r = u.io->connect();
    if (!r.ok()) {
      throw InputError(SourceLocation{u.io->describe(), 0, 0},
                       fmt::format("the I/O unit {} cannot be reached: {} {}", u.io->describe(),
                                   drivers::to_string(r.status), r.message));
    }
  }
}

void DeviceHub::start(SimDuration now) {
  unit_down_.assign(units_.size(), false);
  // The program's belts start stopped (its net's `C.stopped`), as a PLC's outputs are at power-up: a belt left running
  // by an earlier run or another program would carry a part on before the program runs it.
  for (Device& d : devices_) {
    if (d.wiring.kind != DeviceKind::kConveyor || d.wiring.coil < 0 || unit_down_[d.unit]) continue;
    drivers::DigitalIo& io = *units_[d.unit].io;
    const drivers::IoResult r = io.write_coil(static_cast<std::uint16_t>(d.wiring.coil), false);
    if (!r.ok()) {
      unit_down_[d.unit] = true;
      fault(d, Symptom::io_failed,
            fmt::format("device {}: stopping it at the start (coil {}) on {} failed: {} {}", d.wiring.name,
                        d.wiring.coil, io.describe(), drivers::to_string(r.status), r.message),
            now, false);
    }
  }
  for (Device& d : devices_) {
    if (!stopped_ && !unit_down_[d.unit]) watch(d, now);
  }
}

void DeviceHub::close(bool cell_stopped) {
  for (const Device& d : devices_) {
    if (d.wiring.coil < 0 || !units_[d.unit].io->is_open()) continue;
    // No start left asserted: a machine's next start must be a rising edge (a failed start may have left it on).
    // After a stop, no belt keeps running: a part must not be carried on while nobody tends the cell.
    if (d.wiring.kind == DeviceKind::kMachine || (cell_stopped && d.wiring.kind == DeviceKind::kConveyor)) {
      (void)units_[d.unit].io->write_coil(static_cast<std::uint16_t>(d.wiring.coil), false);
    }
  }
  for (const IoUnit& u : units_) u.io->close();
}

void DeviceHub::step(SimDuration now) {
  // A unit that fails a request is not asked again this turn: its other devices would each wait out the timeout and
  // connect it again.
  unit_down_.assign(units_.size(), false);
  take_commands(now);
  for (Device& d : devices_) {
    if (!stopped_ && !unit_down_[d.unit]) advance(d, now);
  }
  for (Device& d : devices_) {
    if (!stopped_ && !unit_down_[d.unit]) watch(d, now);
  }
}

void DeviceHub::take_commands(SimDuration now) {
  MotionCommand c;
  while (inbox_.try_pop(c) == QueueStatus::ok) {
    CW_CHECK(c.primitive.kind == task::PrimitiveKind::kDevice, "device control was sent '{}'",
             task::to_string(c.primitive));
    auto it = by_label_.find(c.primitive.device);
    CW_CHECK(it != by_label_.end(), "device control was sent a command for device '{}', which it does not have",
             c.primitive.device);
    Device& d = devices_[it->second];
    log_.command_start(now, program_.robots.at(c.robot), c.index, task::to_string(c.primitive), c.primitive.task,
                       c.primitive.motion, fmt::format("{} {}", units_[d.unit].io->describe(), d.wiring.name));
    if (stopped_) {
      answer(c, CommandOutcome::kFailed, "the cell was stopped by a device fault", true, now);
      continue;
    }
    d.queue.push_back(std::move(c));
  }
}

void DeviceHub::advance(Device& d, SimDuration now) {
  if (d.queue.empty()) return;
  MotionCommand& c = d.queue.front();
  if (!d.begun) {
    task::Primitive p = c.primitive;
    p.device = d.wiring.name;  // the control knows the device by its cell name
    d.control->begin(p, now, d.attempts > 0);  // again after a fault: a start may already have been taken
    d.begun = true;
  }
  const DeviceStep s = d.control->poll(now);
  if (s.outcome == DeviceOutcome::kPending) return;
  if (s.outcome == DeviceOutcome::kDone) {
    const MotionCommand done = std::move(c);
    d.queue.pop_front();
    d.begun = false;
    d.attempts = 0;
    answer(done, CommandOutcome::kDone, "", false, now);
    return;
  }
  d.begun = false;
  if (!s.timed_out) unit_down_[d.unit] = true;
  fault(d, s.timed_out ? Symptom::device_timeout : Symptom::io_failed, s.reason, now, true);
}

void DeviceHub::fault(Device& d, Symptom symptom, const std::string& detail, SimDuration now, bool of_command) {
  const MotionCommand* c = !of_command || d.queue.empty() ? nullptr : &d.queue.front();
  const std::string robot = c != nullptr ? program_.robots.at(c->robot) : std::string();
  const int primitive = c != nullptr ? static_cast<int>(c->index) : -1;
  log_.fault_detected(now, robot, primitive, to_string(symptom), detail);
  if (!recovery_.enabled) {
    stopped_ = true;
    if (c != nullptr) {
      answer(*c, CommandOutcome::kFailed, detail, false, now);
    } else {
      statuses_.try_push(RobotStatus{0, RobotStatus::kNoCommand, CommandOutcome::kFailed, detail, false, now});
    }
    return;
  }
  const DecisionTree& tree = recovery_.tree ? *recovery_.tree : DecisionTree::standard();
  const Diagnosis dg = tree.diagnose(symptom, [&](Question q) {
    if (q == Question::retries_left) return d.attempts < recovery_.max_attempts;
    return false;  // the parts' and robots' questions are not about a device
  });
  log_.diagnosis(now, robot, to_string(symptom), dg.cause, to_string(dg.action), dg.path);
  // retry (reset_rehome: a unit has nothing to home) connects the unit again; go_on and wait_clear only do it again.
  // Each is counted, whatever the tree asked, so that a fault that keeps coming ends with the attempts.
  const bool reconnect = dg.action == Action::retry || dg.action == Action::reset_rehome;
  const bool again = reconnect || dg.action == Action::go_on || dg.action == Action::wait_clear;
  if (again && d.attempts < recovery_.max_attempts) {
    ++d.attempts;
    const std::string what = c != nullptr ? "the command is done" : "the state is read";
    if (!reconnect) {
      log_.recovery_end(now, robot, dg.cause, to_string(dg.action), true,
                        fmt::format("{} again (attempt {} of {})", what, d.attempts, recovery_.max_attempts),
                        SimDuration{0});
      return;
    }
    drivers::DigitalIo& io = *units_[d.unit].io;
    io.close();
    const drivers::IoResult r = io.connect();
    if (r.ok()) {
      log_.recovery_end(now, robot, dg.cause, to_string(dg.action), true,
                        fmt::format("{} connected again; {} again (attempt {} of {})", io.describe(), what,
                                    d.attempts, recovery_.max_attempts),
                        SimDuration{0});
      return;  // the head command (if any) begins again next turn
    }
    log_.recovery_end(now, robot, dg.cause, to_string(dg.action), false,
                      fmt::format("{} cannot be connected again: {} {}", io.describe(), drivers::to_string(r.status),
                                  r.message),
                      SimDuration{0});
    // Connecting failed: the unit is gone; the next request fails again and the attempts run out.
    return;
  }
  // stop_cell, and any action that is not about devices (a tree file may say so): the cell is stopped.
  log_.recovery_end(now, robot, dg.cause, to_string(dg.action), false,
                    again ? fmt::format("{} attempts failed: the cell is stopped", d.attempts)
                          : std::string("the cell is stopped"),
                    SimDuration{0});
  stopped_ = true;
  const std::string reason = fmt::format("{}: {}", to_string(symptom), detail);
  if (c != nullptr) {
    answer(*c, CommandOutcome::kFailed, reason, true, now);
  } else {
    statuses_.try_push(RobotStatus{0, RobotStatus::kNoCommand, CommandOutcome::kFailed, reason, true, now});
  }
}

void DeviceHub::answer(const MotionCommand& c, CommandOutcome outcome, const std::string& reason, bool stop_cell,
                       SimDuration now) {
  log_.command_end(now, program_.robots.at(c.robot), c.index, task::to_string(c.primitive),
                   outcome == CommandOutcome::kDone, reason);
  const QueueStatus pushed = statuses_.try_push(RobotStatus{c.robot, c.index, outcome, reason, stop_cell, now});
  CW_CHECK(pushed == QueueStatus::ok || pushed == QueueStatus::closed, "the status queue refused a device status: {}",
           to_string(pushed));
}

void DeviceHub::watch(Device& d, SimDuration now) {
  drivers::DigitalIo& io = *units_[d.unit].io;
  const DeviceWiring& w = d.wiring;
  std::vector<bool> v;
  const auto read = [&](bool coil, int address, const char* what, bool& on) {
    if (address < 0) {
      on = false;
      return true;
    }
    const auto a = static_cast<std::uint16_t>(address);
    const drivers::IoResult r = coil ? io.read_coils(a, 1, v) : io.read_inputs(a, 1, v);
    if (!r.ok()) {
      unit_down_[d.unit] = true;
      fault(d, Symptom::io_failed,
            fmt::format("device {}: reading its {} ({} {}) on {} failed: {} {}", w.name, what, coil ? "coil" : "input",
                        address, io.describe(), drivers::to_string(r.status), r.message),
            now, false);
      return false;
    }
    on = v.at(0);
    return true;
  };
  std::string state;
  std::string workpiece;
  switch (w.kind) {
    case DeviceKind::kMachine: {
      bool busy = false, done = false;
      if (!read(false, w.busy, "busy", busy) || !read(false, w.input, "done", done)) return;
      state = busy ? "busy" : done ? "done" : "idle";
      break;
    }
    case DeviceKind::kConveyor: {
      bool run = false;
      if (!read(true, w.coil, "run", run)) return;
      state = run ? "running" : "stopped";
      break;
    }
    case DeviceKind::kSensor: {
      bool on = false;
      if (!read(false, w.input, "photo-eye", on)) return;
      state = on ? "on" : "off";
      if (units_[d.unit].real && on && !model_has_part_near(w.at)) {
        if (!d.contradicted_since) d.contradicted_since = now;
        if (now - *d.contradicted_since >= recovery_.contradiction_time) {
          d.contradicted_since.reset();
          fault(d, Symptom::device_contradiction,
                fmt::format("photo-eye {} on {} has seen a part for {} s where the environment model has none",
                            w.name, io.describe(), format_sim_time(recovery_.contradiction_time)),
                now, false);
        }
      } else {
        d.contradicted_since.reset();
      }
      break;
    }
  }
  // Read without a fault: with no command pending, the unit's recoveries so far are behind it.
  if (d.queue.empty()) d.attempts = 0;
  // A machine's part is told with its state, once: the model's guess may flicker while a robot carries it.
  if (state == d.state) return;
  d.state = state;
  if (w.kind == DeviceKind::kMachine && state != "idle") workpiece = machine_workpiece(d);
  log_.log(events::Device{now, w.name, to_string(w.kind), state, workpiece});
}

std::string DeviceHub::machine_workpiece(const Device& d) const {
  return env_.read([&](const EnvironmentModel& m) {
    std::string best;
    double best_d = kFixtureReach;
    for (const WorkpieceState& p : m.workpieces) {
      if (!p.present || p.lost || !p.held_by.empty()) continue;
      const Eigen::Vector3d c = p.pose.translation();
      // The part's bottom rests on the fixture's top: compare in the plane, and its height loosely.
      const double dist = (c.head<2>() - d.wiring.at.head<2>()).norm();
      if (dist < best_d && std::abs(c.z() - d.wiring.at.z()) < 0.15) {
        best_d = dist;
        best = p.name;
      }
    }
    return best;
  });
}

bool DeviceHub::model_has_part_near(const Eigen::Vector3d& at) const {
  return env_.read([&](const EnvironmentModel& m) {
    for (const WorkpieceState& p : m.workpieces) {
      if (!p.present || p.lost) continue;
      if ((p.pose.translation().head<2>() - at.head<2>()).norm() < kEyeReach) return true;
    }
    return false;
  });
}

}  // namespace cellwright::runtime
