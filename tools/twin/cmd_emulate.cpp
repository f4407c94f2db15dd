// `twin emulate movemaster|val2 --link PATH [...]`: a robot controller emulator on a pseudo-terminal, with the
// project's kinematics behind it; `twin emulate --scenario SCENARIO --robot ROBOT=LANGUAGE:LINK ...`: the controllers
// of a cell, each driving the twin's MuJoCo arm, and/or `--io modbus:HOST:PORT[/UNIT] [--lockstep [--scan S]]`: the
// twin's I/O served to a PLC in virtual time (virtual commissioning: cell/sim/emulated_cell.hpp, docs/devices.md).
// Runs until SIGINT or SIGTERM; exit 0 then,
// 2 on bad input. docs/real-robots.md says what each emulator speaks and how it can be told to misbehave.
// A twin built for real robots only (CW_SIM=OFF) has the first form (the emulators need no MuJoCo), not --scenario.
// `twin emulate io --listen HOST:PORT`: the cell's I/O on Modbus TCP (emulate_io.hpp).
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/emulate/kinematic_arm.hpp"
#include "cellwright/emulate/misbehaviour.hpp"
#include "cellwright/emulate/movemaster_emulator.hpp"
#include "cellwright/emulate/val2_emulator.hpp"
#include "cellwright/models/kinematics.hpp"
#include "commands.hpp"
#include "emulate_io.hpp"
#include "until_signal.hpp"
#if CW_SIM
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sim/emulated_cell.hpp"
#else
#include "simulator.hpp"
#endif

namespace cellwright::tools {

namespace {

// Joins a thread however the scope is left.
struct Joined {
  std::thread thread;
  ~Joined() {
    if (thread.joinable()) thread.join();
  }
};

std::vector<double> degrees_to_radians(const std::vector<double>& deg) {
  std::vector<double> out;
  for (const double d : deg) out.push_back(d * M_PI / 180.0);
  return out;
}

// A frame from --*-offset (mm) and --*-rotation (degrees, R = Rz(yaw)·Ry(pitch)·Rx(roll)); each empty: none.
Eigen::Isometry3d frame_of(const std::vector<double>& offset_mm, const std::vector<double>& rpy_deg) {
  Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
  if (offset_mm.size() == 3) f.translation() = Eigen::Vector3d(offset_mm[0], offset_mm[1], offset_mm[2]) / 1000.0;
  if (rpy_deg.size() == 3) {
    const std::vector<double> r = degrees_to_radians(rpy_deg);
    f.linear() = (Eigen::AngleAxisd(r[2], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r[1], Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(r[0], Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
  }
  return f;
}

}  // namespace

void add_emulate(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand(
      "emulate",
      "Emulate robot controllers on pseudo-terminals: one controller with the project's kinematics "
      "(`emulate movemaster|val2 --link PATH`), or a cell's controllers driving the twin's arms (`emulate --scenario "
      "SCENARIO --robot ROBOT=movemaster:LINK ...`), with the twin's I/O on Modbus TCP for a PLC (`--io "
      "modbus:HOST:PORT`, alone or with --robot); or the cell's I/O alone (`emulate io --listen HOST:PORT`). "
      "Runs until Ctrl-C or SIGTERM; exit 0, or 2 on bad input.");
  struct Args {
    std::string language;
    std::string link;
    std::string urdf;
    std::vector<double> home_deg;
    double time_scale = 1.0;
    double speed = 1.0;
    std::string scenario;
    std::vector<std::string> robots;
    std::string twin_io;  // --io modbus:HOST:PORT[/UNIT]
    bool lockstep = false;
    double scan = 0.01;
    std::uint64_t seed = 1;
    std::vector<std::string> misbehave;
    bool no_echo = false;
    bool verbose = false;
    std::string orientation = "tool_down";
    std::vector<double> world_offset, world_rotation, tool_offset, tool_rotation;
    double pitch_down = -90;
    int roll_sense = 1;
    int pace = 0;
    EmulateIoArgs io;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("language", args->language,
                  "the controller to emulate alone: movemaster or val2; or io, the cell's I/O on Modbus TCP")
      ->check(CLI::IsMember({"movemaster", "val2", "io"}));
  cmd->add_option("--link", args->link, "where to publish the pseudo-terminal (a symbolic link), e.g. /tmp/melfa");
  cmd->add_option("--urdf", args->urdf,
                  "the arm (default: models/urdf/melfa_rve2.urdf for movemaster, puma560.urdf for val2)");
  cmd->add_option("--home", args->home_deg, "home joints in degrees (default: zero, within the limits)")
      ->delimiter(',');
  cmd->add_option("--time-scale", args->time_scale, "motions take this times their time (default 1)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--scenario", args->scenario, "emulate the controllers of this scenario's cell, on the twin's arms");
  cmd->add_option("--speed", args->speed,
                  "with --scenario: the twin's arms move this many times faster than real time (default 1), for a "
                  "twin run --realtime --speed X against them")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--robot", args->robots, "with --scenario: ROBOT=movemaster:LINK or ROBOT=val2:LINK (repeatable)");
  cmd->add_option("--io", args->twin_io,
                  "with --scenario: serve the twin's I/O (the cell's coils and discrete inputs) on Modbus TCP at "
                  "modbus:HOST:PORT[/UNIT] (port 0: a free one, printed), answering between simulation steps");
  cmd->add_flag("--lockstep", args->lockstep,
                "with --io alone: the twin advances only when the client reads the discrete inputs, by --scan of "
                "simulated time each, so the same requests get the same replies run to run");
  cmd->add_option("--scan", args->scan,
                  "with --lockstep: seconds of simulated time per read of the discrete inputs (default 0.01; a "
                  "whole number of the cell's timesteps)");
  cmd->add_option("--seed", args->seed, "seed of the random misbehaviours");
  cmd->add_option("--misbehave", args->misbehave,
                  "KIND@LINE or KIND~PROBABILITY (late: late@LINE:SECONDS); with --scenario ROBOT:KIND@LINE; "
                  "KIND: error (er1), unreachable (er2), garbage, silent, drop, late (repeatable)");
  cmd->add_option("--pace", args->pace,
                  "one controller alone: pace the pseudo-terminal as a serial line at this baud rate (e.g. 9600; "
                  "Movemaster 11 bits a character, VAL II 10), for figures of the line's use")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--no-echo", args->no_echo, "VAL II: do not echo what is received");
  cmd->add_flag("--verbose", args->verbose, "print every line received and answered");
  // The controller's conventions (docs/real-robots.md, "Commissioning"), as a robot's cell entry gives them.
  cmd->add_option("--orientation", args->orientation, "VAL II: how O, A, T read: tool_down (default) or val")
      ->check(CLI::IsMember({"tool_down", "val"}));
  const auto triple = [&](const char* name, std::vector<double>& v, const char* what) {
    cmd->add_option(name, v, what)->delimiter(',')->expected(3);
  };
  triple("--world-offset", args->world_offset, "X,Y,Z mm: the controller's world frame in the arm's base frame");
  triple("--world-rotation", args->world_rotation, "ROLL,PITCH,YAW degrees: its rotation (Rz·Ry·Rx, fixed axes)");
  triple("--tool-offset", args->tool_offset, "X,Y,Z mm: the controller's tool point in the arm's TCP frame");
  triple("--tool-rotation", args->tool_rotation, "ROLL,PITCH,YAW degrees: its axes in the TCP's");
  cmd->add_option("--pitch-down", args->pitch_down, "Movemaster: the pitch at which the hand points down: -90 or 90");
  cmd->add_option("--roll-sense", args->roll_sense, "Movemaster: 1 (roll right-handed about the approach) or -1");
  add_emulate_io_options(cmd, args->io);
  cmd->callback([run, args, cmd] {
    *run = [args, cmd] {
      const SourceLocation cli{"twin emulate", 0, 0};
      const bool io = args->language == "io";
      for (const char* name : {"--listen", "--unit", "--process-time", "--take-out-after", "--input"}) {
        if (!io && cmd->count(name) > 0) throw InputError(cli, fmt::format("{} is for `twin emulate io`", name));
      }
      if (io) {
        for (const CLI::Option* o : cmd->get_options()) {
          const std::string name = o->get_name();  // "--link"; the positional's name has no dashes
          const bool robots = name.rfind("--", 0) == 0 && name != "--verbose" && name != "--help" &&
                              o->get_description().rfind("io: ", 0) != 0;
          if (robots && o->count() > 0) {
            throw InputError(cli, fmt::format("{} is for a robot controller or --scenario, not `twin emulate io`",
                                              name));
          }
        }
        return emulate_io(args->io, args->verbose);
      }
      std::mutex print_mutex;
      const auto print = [&print_mutex](std::string_view line) {
        std::lock_guard lock(print_mutex);
        std::fprintf(stdout, "%.*s\n", static_cast<int>(line.size()), line.data());
        std::fflush(stdout);
      };
      for (const char* name : {"--orientation", "--world-offset", "--world-rotation", "--tool-offset",
                               "--tool-rotation", "--pitch-down", "--roll-sense"}) {
        if (!args->scenario.empty() && cmd->count(name) > 0) {
          throw InputError(cli, fmt::format("{} is for one controller alone; with --scenario the controllers follow "
                                            "the page's conventions",
                                            name));
        }
      }
      for (const char* name : {"--io", "--lockstep", "--scan"}) {
        if (args->scenario.empty() && cmd->count(name) > 0) {
          throw InputError(cli, fmt::format("{} is for --scenario (the twin's I/O)", name));
        }
      }
      if (!args->scenario.empty()) {
#if !CW_SIM
        needs_simulator("twin emulate --scenario (the controllers on the twin's arms)");
#else
        if (!args->language.empty() || !args->link.empty() || args->pace != 0) {
          throw InputError(cli,
                           "--scenario emulates the cell's controllers given by --robot; a language, --link and "
                           "--pace are for one controller alone");
        }
        if (args->lockstep && args->twin_io.empty()) throw InputError(cli, "--lockstep is for the I/O: add --io");
        if (args->robots.empty() && args->twin_io.empty()) {
          throw InputError(cli, "--scenario needs at least one --robot ROBOT=LANGUAGE:LINK, or --io modbus:HOST:PORT");
        }
        if (args->lockstep && !args->robots.empty()) {
          throw InputError(cli, "--lockstep serves the I/O alone: the robot controllers' serial lines run on the "
                                "wall clock (leave out --robot, or leave out --lockstep)");
        }
        if (args->lockstep && cmd->count("--speed") > 0) {
          throw InputError(cli, "--speed is for the paced twin; with --lockstep the client's reads set the pace");
        }
        if (!args->lockstep && cmd->count("--scan") > 0) throw InputError(cli, "--scan is for --lockstep");
        if (args->lockstep && !(args->scan > 0 && args->scan <= 3600)) {
          throw InputError({"--scan", 0, 0}, fmt::format("the scan must be within (0, 3600] seconds, got {}",
                                                          args->scan));
        }
        std::optional<emulate::ModbusServerOptions> served_io;
        if (!args->twin_io.empty()) served_io = cell::parse_served_io(args->twin_io, {"--io", 0, 0});
        const cell::Scenario s = cell::load_scenario(args->scenario);
        std::vector<cell::EmulatedController> controllers;
        for (const std::string& r : args->robots) {
          controllers.push_back(cell::parse_emulated_controller(r, {"--robot", 0, 0}));
        }
        for (const std::string& m : args->misbehave) {
          const std::size_t colon = m.find(':');
          bool placed = false;
          for (auto& c : controllers) {
            if (colon != std::string::npos && m.substr(0, colon) == c.robot) {
              c.misbehaviours.push_back(emulate::parse_misbehaviour(m.substr(colon + 1)));
              placed = true;
            }
          }
          if (!placed) {
            throw InputError({"--misbehave", 0, 0}, fmt::format("'{}': with --scenario, write ROBOT:KIND@LINE for "
                                                                "one of the emulated robots",
                                                                m));
          }
        }
        cell::EmulatedCellOptions options;
        options.seed = args->seed;
        options.echo = !args->no_echo;
        options.speed = args->speed;
        options.io = served_io;
        if (args->lockstep) {
          options.lockstep = std::chrono::round<std::chrono::nanoseconds>(std::chrono::duration<double>(args->scan));
        }
        if (args->verbose) options.log = print;
        std::string names;
        for (const auto& c : controllers) {
          names += fmt::format("{}{} ({}) at {}", names.empty() ? "" : ", ", c.robot,
                               cell::to_string(c.language), c.link.string());
        }
        std::unique_ptr<cell::EmulatedCell> emulated;
        options.on_ready = [&] {
          std::string what = names;
          if (served_io) {
            what += fmt::format("{}the twin's I/O on Modbus TCP at {}, unit {} ({})", what.empty() ? "" : "; ",
                                emulated->io_endpoint(), served_io->unit,
                                args->lockstep ? fmt::format("lock-step: {} s of simulated time per read of the "
                                                             "discrete inputs",
                                                             args->scan)
                                               : fmt::format("paced at {}x real time", args->speed));
          }
          print(fmt::format("emulating {}; Ctrl-C to stop", what));
        };
        emulated = std::make_unique<cell::EmulatedCell>(s, std::move(controllers), std::move(options), cli);
        cell::EmulatedCell& cell = *emulated;
        run_until_signal([&] { cell.run(); }, [&] { cell.stop(); });
        for (const cell::FinalPose& p : cell.final_poses()) {
          if (!p.present) continue;
          const Eigen::Vector3d x = p.pose.translation();
          print(fmt::format("{} at ({:.3f}, {:.3f}, {:.3f}){}", p.name, x.x(), x.y(), x.z(),
                            p.held_by.empty() ? "" : fmt::format(", held by {}", p.held_by)));
        }
        return 0;
#endif  // CW_SIM
      }

      if (cmd->count("--speed") > 0) {
        throw InputError(cli, "--speed is for --scenario (the twin's arms); one controller alone takes --time-scale");
      }
      if (args->language.empty()) throw InputError(cli, "say which controller: movemaster or val2 (or --scenario)");
      if (args->link.empty()) throw InputError(cli, "--link PATH is needed: where to publish the pseudo-terminal");
      const bool movemaster = args->language == "movemaster";
      const std::string urdf = args->urdf.empty() ? std::string(models::models_dir()) +
                                                        (movemaster ? "/urdf/melfa_rve2.urdf" : "/urdf/puma560.urdf")
                                                  : args->urdf;
      emulate::KinematicArmOptions arm_options;
      arm_options.home = degrees_to_radians(args->home_deg);
      arm_options.time_scale = args->time_scale;
      emulate::KinematicArm arm(models::KinematicChain::from_urdf_file(urdf), arm_options);
      std::vector<emulate::Misbehaviour> misbehaviours;
      for (const std::string& m : args->misbehave) misbehaviours.push_back(emulate::parse_misbehaviour(m));
      const std::string ready = fmt::format("emulating a {} controller at {} ({}); Ctrl-C to stop",
                                            movemaster ? "Movemaster EX" : "VAL II", args->link, urdf);
      if (movemaster) {
        emulate::MovemasterEmulatorOptions o;
        o.seed = args->seed;
        o.misbehaviours = std::move(misbehaviours);
        o.pace = {args->pace, 11};
        if (args->verbose) o.log = print;
        o.world = frame_of(args->world_offset, args->world_rotation);
        o.tool = frame_of(args->tool_offset, args->tool_rotation);
        o.pitch_down_deg = args->pitch_down;
        o.roll_sense = args->roll_sense;
        emulate::MovemasterEmulator e(arm, std::move(o));
        Joined announce{std::thread([&] {
          if (e.wait_published(1, std::chrono::seconds(10))) print(ready);
        })};
        run_until_signal([&] { e.serve(args->link); }, [&] { e.stop(); });
      } else {
        emulate::Val2EmulatorOptions o;
        o.seed = args->seed;
        o.misbehaviours = std::move(misbehaviours);
        o.echo = !args->no_echo;
        o.pace = {args->pace, 10};
        if (args->verbose) o.log = print;
        o.world = frame_of(args->world_offset, args->world_rotation);
        o.tool = frame_of(args->tool_offset, args->tool_rotation);
        if (args->orientation == "val") o.orientation = emulate::Val2EmulatorOptions::Orientation::val;
        emulate::Val2Emulator e(arm, std::move(o));
        Joined announce{std::thread([&] {
          if (e.wait_published(1, std::chrono::seconds(10))) print(ready);
        })};
        run_until_signal([&] { e.serve(args->link); }, [&] { e.stop(); });
      }
      return 0;
    };
  });
}

}  // namespace cellwright::tools
