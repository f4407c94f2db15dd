// The dry run for hardware bring-up (dry_run.hpp).
#include "cellwright/cell/dry_run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "cellwright/drivers/movemaster/movemaster_driver.hpp"
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/cell/estimate.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/real_drivers.hpp"
#include "cellwright/cell/run_wiring.hpp"
#include "cellwright/drivers/modbus/modbus_io.hpp"

namespace cellwright::cell {

bool DryRunReport::ok() const {
  for (const DryRobot& r : robots) {
    if (!r.real) continue;
    if (!r.problem.empty() || !r.homed || !r.position || !r.check.ok()) return false;
    for (const DryTarget& t : r.targets) {
      if (!t.problem.empty()) return false;
    }
  }
  return std::all_of(devices.begin(), devices.end(), [](const DryDevice& d) { return d.problem.empty(); });
}

namespace {

// Reads every input of each device on real I/O (and a conveyor's run coil) from its unit; writes nothing.
std::vector<DryDevice> check_devices(const Scenario& s) {
  std::vector<DryDevice> out;
  std::map<std::string, std::unique_ptr<drivers::ModbusIo>> units;  // by endpoint, connected once
  for (const runtime::DeviceWiring& w : cell_devices(s.cell)) {
    const DeviceChoice* choice = find_device_choice(s, w.name);
    if (choice == nullptr || !choice->real()) continue;
    DryDevice d;
    d.device = w.name;
    auto& io = units[choice->modbus->str()];
    if (!io) {
      io = std::make_unique<drivers::ModbusIo>(*choice->modbus, drivers::ModbusIoOptions{}, choice->where);
      if (const drivers::IoResult r = io->connect(); !r.ok()) d.problem = fmt::format("cannot reach it: {}", r.message);
    } else if (!io->is_open()) {
      d.problem = "cannot reach it (see above)";
    }
    d.unit = io->describe();
    const auto read_one = [&](const char* what, int address, bool coil) {
      if (address < 0 || !d.problem.empty()) return;
      std::vector<bool> v;
      const auto a = static_cast<std::uint16_t>(address);
      const drivers::IoResult r = coil ? io->read_coils(a, 1, v) : io->read_inputs(a, 1, v);
      if (!r.ok()) {
        d.problem = r.message;
        return;
      }
      d.reads.push_back({fmt::format("{} ({} {})", what, coil ? "coil" : "input", address), v.at(0)});
    };
    switch (w.kind) {
      case runtime::DeviceKind::kMachine:
        read_one("busy", w.busy, false);
        read_one("done", w.input, false);
        break;
      case runtime::DeviceKind::kConveyor:
        read_one("run", w.coil, true);
        break;
      case runtime::DeviceKind::kSensor:
        read_one("part seen", w.input, false);
        break;
    }
    out.push_back(std::move(d));
  }
  for (auto& [endpoint, io] : units) io->close();
  return out;
}

}  // namespace

DryRunReport dry_run(const Scenario& s, const Preflight& pre, const DryRunOptions& options) {
  DryRunReport report;
  CW_CHECK(pre.plan.has_value(), "a dry run of a program the preflight did not plan");
  const MotionPlan& plan = *pre.plan;
  for (std::size_t i = 0; i < s.robots.size(); ++i) {
    const Binding& b = s.robots[i];
    DryRobot r;
    r.label = b.label;
    r.robot = b.name;
    const DriverChoice* choice = nullptr;
    for (const DriverChoice& d : s.drivers) {
      if (d.robot == b.name) choice = &d;
    }
    r.real = choice != nullptr && choice->real();
    r.driver = r.real ? fmt::format("{} {}", to_string(choice->kind), choice->serial->port) : "sim";
    if (!r.real) {
      report.robots.push_back(std::move(r));
      continue;
    }
    const models::RobotSpec& spec = *s.cell.find_robot(b.name);
    std::unique_ptr<drivers::SerialDriver> driver = make_real_driver(*choice, spec);
    connect_real_driver(*driver, *choice);
    if (const std::optional<ReadBack> home =
            home_and_read(*driver, options.home_timeout, options.read_timeout, &r.problem)) {
      r.homed = true;
      r.position = home->reading;
      r.check = cross_check(spec, choice->kind, *home);
    } else {
      r.homed = driver->state() == drivers::DriverState::homed;
    }
    driver->disconnect();

    // Every target of the program for this robot.
    const models::KinematicChain chain = models::robot_chain(spec);
    const auto* movemaster = dynamic_cast<const drivers::MovemasterDriver*>(driver.get());
    for (const PlannedCommand& c : plan.commands[i]) {
      if (c.kind != task::PrimitiveKind::kMove || !c.reached) continue;
      DryTarget t;
      t.command = c.command;
      t.source = c.source;
      if (!c.problem.empty() || c.goal.size() != chain.dof()) {
        t.problem = c.problem.empty() ? "no joint goal" : c.problem;
        r.targets.push_back(std::move(t));
        continue;
      }
      const Eigen::Isometry3d pose =
          chain.forward(Eigen::Map<const Eigen::VectorXd>(c.goal.data(), static_cast<Eigen::Index>(c.goal.size())));
      if (movemaster != nullptr) {
        std::string why;
        const auto v = drivers::movemaster::to_xyzpr(pose, movemaster->options().yaw_tolerance_deg, &why);
        if (v) {
          t.controller = drivers::movemaster::format_mp(*v);
        } else {
          t.problem = fmt::format("the Movemaster cannot be told this pose: {}", why);
        }
      } else {
        const Eigen::Vector3d p = pose.translation() * 1000.0;
        t.controller = fmt::format("tool at ({:.1f}, {:.1f}, {:.1f}) mm", p.x(), p.y(), p.z());
      }
      r.targets.push_back(std::move(t));
    }
    report.robots.push_back(std::move(r));
  }
  report.devices = check_devices(s);
  return report;
}

std::string format_dry_run(const DryRunReport& report) {
  std::string out;
  for (const DryRobot& r : report.robots) {
    out += fmt::format("{} ({}) on {}\n", r.label, r.robot, r.driver);
    if (!r.real) {
      out += "  simulated: nothing to check on hardware\n";
      continue;
    }
    out += fmt::format("  homed: {}\n", r.homed ? "yes" : "no");
    if (r.position && r.position->tool_pose) {
      const Eigen::Vector3d p = r.position->tool_pose->translation() * 1000.0;
      out += fmt::format("  position after homing: tool at ({:.1f}, {:.1f}, {:.1f}) mm\n", p.x(), p.y(), p.z());
    } else if (r.position && !r.position->joints.empty()) {
      std::string q;
      for (const double v : r.position->joints) q += fmt::format("{}{:.2f}", q.empty() ? "" : ", ", v * 180 / M_PI);
      out += fmt::format("  position after homing: joints [{}] deg\n", q);
    }
    if (!r.problem.empty()) out += fmt::format("  PROBLEM: {}\n", r.problem);
    for (const std::string& p : r.check.problems) out += fmt::format("  CROSS-CHECK FAILED: {}\n", p);
    for (const std::string& n : r.check.notes) out += fmt::format("  not checked: {}\n", n);
    for (const DryTarget& t : r.targets) {
      out += fmt::format("  {} {:<24} {}  {}\n", t.problem.empty() ? "ok  " : "FAIL", t.command,
                         t.problem.empty() ? t.controller : t.problem, t.source);
    }
  }
  for (const DryDevice& d : report.devices) {
    out += fmt::format("{} on {}\n", d.device, d.unit);
    for (const DryDevice::Read& r : d.reads) out += fmt::format("  read {}: {}\n", r.what, r.value ? "on" : "off");
    if (!d.problem.empty()) out += fmt::format("  PROBLEM: device {} on {}: {}\n", d.device, d.unit, d.problem);
  }
  const std::string devices = report.devices.empty() ? "" : ", and every device's unit answered";
  const std::string untouched = report.devices.empty() ? "" : "; no output was written";
  out += report.ok() ? fmt::format("dry run: every target can be reached and expressed, and the read-backs agree with "
                                   "the kinematics and the home{}; nothing was moved but homing{}\n",
                                   devices, untouched)
                     : fmt::format("dry run: problems above; nothing was moved but homing{}\n", untouched);
  return out;
}

}  // namespace cellwright::cell
