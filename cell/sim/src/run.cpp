// One run of a scenario on the simulated cell (run.hpp).
#include "cellwright/cell/sim/run.hpp"

#include <malloc.h>

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/twin/render.hpp"
#include "cellwright/cell/commissioning.hpp"
#include "cellwright/cell/real_drivers.hpp"
#include "cellwright/cell/run_wiring.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/twin/scene.hpp"
#include "cellwright/twin/sim/fault_injector.hpp"
#include "cellwright/twin/sim/world_plant.hpp"
#include "cellwright/drivers/mirrored_io.hpp"
#include "cellwright/drivers/modbus/modbus_io.hpp"
#include "cellwright/vision/camera_model.hpp"
#include "cellwright/vision/cell_detector.hpp"
#include "cellwright/vision/detector.hpp"
#include "cellwright/models/robot_model.hpp"

namespace cellwright::cell {

namespace {

runtime::SimDuration seconds(double s) {
  return std::chrono::duration_cast<runtime::SimDuration>(std::chrono::duration<double>(s));
}

// The driver faults of robot `robot` as a FaultyDriver's plan (docs/faults.md): `command: move` counts joint and pose
// moves together, `grip` opens and closes. Empty when it has none.
drivers::FaultPlan driver_plan(const Scenario& s, const std::string& robot) {
  drivers::FaultPlan plan;
  for (const FaultSpec& f : s.faults) {
    if (!is_driver_fault(f.kind) || f.robot != robot) continue;
    drivers::KindsRule rule;
    rule.kinds = f.command == FaultCommand::move
                     ? std::vector<drivers::CommandKind>{drivers::CommandKind::move_joints, drivers::CommandKind::move_pose}
                     : std::vector<drivers::CommandKind>{drivers::CommandKind::grip};
    rule.nth = f.n;
    switch (f.kind) {
      case FaultKind::timeout:
        rule.fault.never_completes = true;
        break;
      case FaultKind::garbage:
        rule.fault.error = drivers::ErrorCode::protocol;
        rule.fault.message = "garbage reply: the controller answered with bytes that are no reply";
        break;
      case FaultKind::hardware:
        rule.fault.error = drivers::ErrorCode::hardware;
        rule.fault.message = "ER 1: the controller reports a hardware error";
        break;
      case FaultKind::position:
        rule.fault.error = drivers::ErrorCode::unreachable;
        rule.fault.message = "ER 2: the controller refuses the position";
        break;
      default:
        rule.fault.error = drivers::ErrorCode::connection_lost;
        rule.fault.message = "the serial link to the controller dropped";
        break;
    }
    plan.kinds_rules.push_back(std::move(rule));
  }
  plan.seed = s.seed;
  return plan;
}

}  // namespace

twin::Scene compile_cell(const Scenario& s) {
  // The world as it really is: perturbed parts stand elsewhere than the cell description says.
  const std::map<std::string, Eigen::Isometry3d> offsets =
      s.perturb ? draw_perturbation(*s.perturb, s.seed) : std::map<std::string, Eigen::Isometry3d>{};
  models::CellDescription real = s.cell;
  for (models::WorkpieceSpec& w : real.workpieces) {
    const auto it = offsets.find(w.name);
    if (it == offsets.end() || (s.feed && s.feed->feeds(w.name))) continue;
    const Eigen::Isometry3d moved = w.pose.transform() * it->second;
    w.pose.xyz = moved.translation();
    w.pose.rpy.z() += std::atan2(it->second.linear()(1, 0), it->second.linear()(0, 0));
  }
  return twin::build_scene(real, sim::FaultInjector::scene_options(s.faults));
}

CellWorld make_cell_world(const Scenario& s, const twin::Scene* compiled) {
  sim::WorldOptions world_options;
  world_options.where = {s.source.string(), 0, 0};
  if (s.feed) world_options.parked = s.feed->workpieces;
  const std::map<std::string, Eigen::Isometry3d> offsets =
      s.perturb ? draw_perturbation(*s.perturb, s.seed) : std::map<std::string, Eigen::Isometry3d>{};
  CellWorld out;
  out.world = std::make_unique<sim::World>(compiled != nullptr ? compiled->share() : compile_cell(s), world_options);
  if (s.feed) {
    for (std::size_t i = 0; i < s.feed->count; ++i) {
      const auto it = offsets.find(s.feed->workpiece_at(i));
      out.feed.push_back({seconds(s.feed->arrival(i)), s.feed->workpiece_at(i), s.feed->conveyor,
                          it == offsets.end() || i >= s.feed->workpieces.size() ? Eigen::Isometry3d::Identity()
                                                                                : it->second});
    }
  }
  return out;
}


sim::SimDriverOptions sim_driver_options(const Scenario& s, const std::string& robot) {
  sim::SimDriverOptions o;
  for (const DriverChoice& d : s.drivers) {
    if (d.robot == robot) o.where = d.where;
  }
  return o;
}

EstimateOptions twin_estimate_options(const Scenario& s, const twin::Scene& scene, double motion_speed) {
  EstimateOptions out;
  out.control_period = s.options.control_period;
  out.physics_step = s.cell.timestep;
  for (const Binding& b : s.robots) {
    const sim::SimDriverOptions driver = sim_driver_options(s, b.name);
    const twin::RobotIds* ids = scene.find_robot(b.name);
    CW_CHECK(ids != nullptr, "robot {} is not in the scene", b.name);
    const models::RobotSpec& spec = scene.cell().robots.at(static_cast<std::size_t>(ids - scene.robots().data()));
    RobotTiming timing;
    timing.max_joint_speed = sim::sim_joint_speeds(spec, models::robot_chain(spec), driver);
    timing.speed = motion_speed;
    timing.min_move_time = driver.min_move_time;
    timing.max_tool_speed = driver.max_tool_speed;
    timing.linear_step = driver.linear_step;
    timing.max_waypoint_step = driver.max_waypoint_step;
    timing.ik = driver.ik;
    timing.finger_speed = driver.finger_speed;
    timing.release_clearance = driver.release_clearance;
    timing.finger_closed = ids->finger_range[0];
    timing.finger_open = ids->finger_range[1];
    // The fingers' servo stiffness (N/m) in the scene: the grip force is reached this far behind the ramp.
    const double finger_stiffness = scene.model()->actuator_gainprm[ids->finger_actuator[0] * mjNGAIN];
    timing.finger_squeeze = spec.grip_force / finger_stiffness;
    out.robots[b.name] = timing;
  }
  return out;
}

namespace {

// The real camera of `texts` (RunOptions::cameras), opened, or none; InputError when it cannot stand in for the twin's.
std::unique_ptr<vision::CameraSource> open_real_camera(const Scenario& s, const std::vector<std::string>& texts,
                                                       runtime::Perception perception, bool realtime) {
  if (texts.empty()) return nullptr;
  const SourceLocation where{"--camera", 0, 0};
  if (texts.size() > 1) {
    throw InputError(where, fmt::format("{} cameras given, and vision looks through one", texts.size()));
  }
  const vision::CameraText text = vision::parse_camera_text(texts.front(), where);
  const models::CameraSpec* camera = s.cell.find_camera(text.camera);
  if (camera == nullptr) {
    throw InputError(where, fmt::format("'{}': the cell {} has no camera '{}'", text.text, s.cell.source.string(),
                                        text.camera));
  }
  if (perception != runtime::Perception::kVision) {
    throw InputError(where, fmt::format("'{}': a camera's frames are for vision, and this run's perception is {}",
                                        text.text, runtime::to_string(perception)));
  }
  const std::string looks_through = s.vision ? s.vision->camera : s.cell.cameras.front().name;
  if (text.camera != looks_through) {
    throw InputError(where, fmt::format("'{}': vision looks through camera '{}', not '{}'", text.text, looks_through,
                                        text.camera));
  }
  if (text.kind == vision::CameraText::Kind::kDevice && !realtime) {
    throw InputError(where, fmt::format("'{}': a live camera runs at its own pace, and this run is lock-step: add "
                                        "--realtime (or give a recording, file:...)",
                                        text.text));
  }
  for (const FaultSpec& f : s.faults) {
    if (needs_vision(f.kind)) {
      throw InputError(f.where, fmt::format("a {} fault is injected into the twin's camera, and '{}' puts a real "
                                            "camera in its place",
                                            to_string(f.kind), text.text));
    }
  }
  return std::make_unique<vision::CameraSource>(text, *camera);
}

}  // namespace

ScenarioRun::ScenarioRun(const Scenario& s, const Preflight& pre, RunOptions options)
    : scenario_(s),
      realtime_(options.realtime.value_or(s.options.realtime)),
      perception_(options.perception.value_or(s.perception)) {
  refuse_lockstep_with_real_drivers(s, realtime_);
  for (const FaultSpec& f : s.faults) {
    if (needs_vision(f.kind) && perception_ != runtime::Perception::kVision) {
      throw InputError(f.where, fmt::format("a {} fault needs perception vision (the camera), and this run's "
                                            "perception is {}",
                                            to_string(f.kind), runtime::to_string(perception_)));
    }
  }
  CW_CHECK(pre.plan.has_value(), "a run of a program the preflight did not plan");
  camera_ = open_real_camera(s, options.cameras, perception_, realtime_);
  CellWorld cell = make_cell_world(s, pre.twin != nullptr ? &pre.twin->scene : nullptr);
  world_ = std::move(cell.world);

  runtime::RunConfig config = scenario_run_config(s, pre.net);

  // A simulation driver for each robot the program uses.
  std::vector<std::string> mirrored;  // the real robots: their grip sensed on the real side where it can tell
  std::vector<sim::ReplicaMirror::Copy> followed;  // the agents' robots: copies following their replicated states
  for (const std::string& robot : options.followed) {
    CW_CHECK(std::any_of(s.robots.begin(), s.robots.end(), [&](const Binding& b) { return b.name == robot; }),
             "robot '{}' is followed in the twin but is no robot of the program", robot);
  }
  if (!options.followed.empty() && !realtime_) {
    throw InputError({"--agents", 0, 0}, "robots on agents' real drivers are followed in the twin in real time only: "
                                         "run with --realtime");
  }
  if (!options.followed.empty() && !s.faults.empty()) {
    throw InputError(s.faults.front().where,
                     fmt::format("the scenario injects faults into the twin and its drivers, and robot {}'s robot "
                                 "control runs in its agent, on its real driver, which no fault here can reach: "
                                 "leave the faults out of a run with --agents remote",
                                 options.followed.front()));
  }
  for (const Binding& b : s.robots) {
    sim::SimDriver& driver = world_->add_sim_driver(b.name, sim_driver_options(s, b.name));
    if (std::find(options.followed.begin(), options.followed.end(), b.name) != options.followed.end()) {
      // Its robot control and driver are its agent's: nothing here drives the copy but the mirror.
      followed.push_back({b.name, &driver, driver.kinematics(), s.cell.find_robot(b.name)->home});
      continue;
    }
    config.drivers[b.name] = &driver;
    const DriverChoice* choice = nullptr;
    for (const DriverChoice& d : s.drivers) {
      if (d.robot == b.name) choice = &d;
    }
    if (choice != nullptr && choice->real()) {
      std::unique_ptr<drivers::SerialDriver> real = make_real_driver(*choice, *s.cell.find_robot(b.name));
      connect_real_driver(*real, *choice);
      bring_up_checked(*real, *choice, *s.cell.find_robot(b.name));  // homes, reads and cross-checks: refuses here
      mirrors_.push_back(std::make_unique<sim::MirroredDriver>(b.name, std::move(real), driver, driver.kinematics()));
      config.drivers[b.name] = mirrors_.back().get();
      mirrored.push_back(b.name);
    } else if (drivers::FaultPlan plan = driver_plan(s, b.name); !plan.kinds_rules.empty()) {
      // The controller's and the link's faults: each reported, as it is chosen on the robot's thread, through the plant.
      plan.on_injection = [this, robot = b.name](drivers::CommandId id, const drivers::Command& command,
                                                 const drivers::Fault& fault) {
        const std::string kind =
            fault.never_completes ? std::string("timeout")
            : fault.error == drivers::ErrorCode::protocol        ? std::string("garbage")
            : fault.error == drivers::ErrorCode::hardware        ? std::string("hardware")
            : fault.error == drivers::ErrorCode::unreachable     ? std::string("position")
                                                                 : std::string("link_lost");
        world_plant_->report_fault(
            {kind, robot, "",
             fmt::format("command {} ({}): {}", id, drivers::describe(command),
                         fault.never_completes ? std::string("the controller never answers") : fault.message)});
      };
      faulty_.push_back(std::make_unique<drivers::FaultyDriver>(driver, std::move(plan)));
      config.drivers[b.name] = faulty_.back().get();
    }
  }

  auto plant = std::make_unique<sim::WorldPlant>(*world_, std::move(cell.feed), s.faults, s.seed);
  world_plant_ = plant.get();
  {
    // The carries the twin measures: the workpieces the coordinated blocks pick.
    std::vector<std::string> carried;
    for (const task::CoordinatedUse& b : s.program.coordinated) carried.push_back(s.workpiece_of(b.workpiece));
    plant->measure_carries_of(std::move(carried));
  }
  if (s.feed && s.feed->recycles()) {
    // A shift: parts leave the cell at the end of every conveyor but the feed's, and their bodies are fed again.
    std::vector<std::string> exits;
    for (const models::ConveyorSpec* c : s.feed->exits(s.cell)) exits.push_back(c->name);
    plant->recycle_at(std::move(exits));
  }
  if (s.perturb) {
    // The scenario's perturbation misplaces parts on purpose (the controller's model does not know it): logged as
    // such, so that its detection is matched to it and not taken for a false alarm.
    for (const auto& [name, offset] : draw_perturbation(*s.perturb, s.seed)) {
      world_plant_->report_fault(
          {"misplace", "", name,
           fmt::format("the scenario's perturbation: workpiece '{}' moved by ({:.3f}, {:.3f}) m in its own frame and "
                       "turned by {:.1f} degrees",
                       name, offset.translation().x(), offset.translation().y(),
                       std::atan2(offset.linear()(1, 0), offset.linear()(0, 0)) * 180.0 / M_PI)});
    }
  }
  plant_ = std::move(plant);
  followed_ = options.followed;
  followed_via_ = options.followed_via;
  if (!followed.empty()) {
    replica_mirror_ = std::make_unique<sim::ReplicaMirror>(std::move(followed));
    replica_mirror_->start();  // the copies come up as the World steps
  }
  // The twin's sensors; a real robot's grip from its own driver where that can tell (MirroredDriver::grip_sense()),
  // else from its copy in the twin.
  config.sensors = world_plant_->sensors();
  for (const std::string& robot : mirrored) {
    config.sensors.grip[robot] = runtime::grip_sensor_for(*config.drivers.at(robot), config.sensors.grip[robot],
                                                          grip_sensors_);
  }
  // Lost signals: dropped on the signal path and logged here (the runtime knows nothing of injected faults).
  std::vector<std::uint64_t> lost;
  for (const FaultSpec& f : s.faults) {
    if (f.kind == FaultKind::lost_signal) lost.push_back(f.n);
  }
  if (!lost.empty()) {
    config.signal_filter = [this, lost](const runtime::SignalSent& sig) {
      if (std::find(lost.begin(), lost.end(), sig.count) == lost.end()) return true;
      runtime_->log().fault_injected(sig.time, "lost_signal", "", "",
                                     fmt::format("signal {} of {} (the {}th signal fired) is lost", sig.event,
                                                 sig.robot, sig.count));
      return false;
    };
  }
  // The preflight's plan, timed as the drivers above will take it.
  estimate_ = estimate_cycle_time(s, pre.net, *pre.plan, twin_estimate_options(s, world_->scene(), config.motion.speed));

  config.plant = plant_.get();
  config.mode = realtime_ ? runtime::Mode::kRealtime : runtime::Mode::kLockstep;
  config.realtime_speed = options.speed;
  config.perception = perception_;
  if (perception_ == runtime::Perception::kVision) {
    // The scenario's camera (checked when it was loaded), else, when --perception asks for vision, the cell's first.
    VisionSettings v = s.vision.value_or(VisionSettings{});
    if (!s.vision) {
      if (s.cell.cameras.empty()) {
        throw InputError({s.source.string(), 0, 0}, "perception vision needs a camera, and the cell has none");
      }
      v.camera = s.cell.cameras.front().name;
    }
    const models::CameraSpec* camera = s.cell.find_camera(v.camera);
    CW_CHECK(camera != nullptr, "the vision camera '{}' is not in the cell", v.camera);
    config.vision = runtime::VisionOptions{v.camera, seconds(v.period)};
    config.detector = std::make_shared<const vision::CellDetector>(
        std::make_shared<const vision::Detector>(s.cell, vision::CameraModel(*camera)));
    if (std::any_of(s.faults.begin(), s.faults.end(),
                    [](const FaultSpec& f) { return f.kind == FaultKind::detection_noise; })) {
      sim::WorldPlant* frames = world_plant_;
      config.detector = std::make_shared<const sim::NoisyDetector>(config.detector, s.faults, s.seed,
                                                                   [frames] { return frames->last_capture(); });
    }
    config.on_frame = std::move(options.on_frame);
    config.camera = camera_.get();
  } else if (options.on_frame) {
    // Plain frames of the camera vision would look through, at its period: for a person to look at, not acted on.
    const VisionSettings v = s.vision.value_or(VisionSettings{});
    const std::string camera = s.vision ? v.camera : s.cell.cameras.empty() ? std::string() : s.cell.cameras[0].name;
    if (camera.empty()) throw InputError({s.source.string(), 0, 0}, "saving camera frames needs a camera, and the cell has none");
    config.camera_frames = runtime::VisionOptions{camera, seconds(v.period)};
    config.on_frame = std::move(options.on_frame);
  }
  // The event log first: it makes the output directory, where the video may go (-o DIR --video DIR/run.mp4).
  if (!options.events_file.empty()) {
    streamed_ = std::make_unique<StreamedLog>(std::move(options.events_file));
    config.log_stream = &streamed_->stream();
    config.keep_log = false;
  }
  if (options.on_progress) {
    config.observers.push_back(progress_observer(options.progress_every, std::move(options.on_progress)));
  }
  if (options.video) {
    video_file_ = options.video->path;
    try {
      video_ = std::make_unique<twin::VideoRecorder>(world_->scene().model(), std::move(*options.video));
    } catch (...) {  // refused before anything ran: leave nothing behind
      if (streamed_) streamed_->remove();
      throw;
    }
    // The video watches the run: an observer of the runtime's, which knows nothing of videos. A program with
    // devices also shows the twin's devices, under the robots (a run without them looks as it did).
    const bool devices = !s.program.machines.empty() || !s.program.conveyors.empty() || !s.program.sensors.empty();
    config.observers.push_back({video_->frame_period(), true, [this, devices](const runtime::Observation& o) {
                                  std::vector<std::string> lines;
                                  for (const runtime::RobotView& r : o.robots) {
                                    lines.push_back(r.done ? fmt::format("{}: done", r.robot)
                                                           : fmt::format("{}: {} {}", r.robot,
                                                                         runtime::to_string(r.activity), r.command));
                                  }
                                  if (devices) {
                                    for (std::string& l : twin::device_lines(world_->devices())) {
                                      lines.push_back(std::move(l));
                                    }
                                  }
                                  // copies positions: the World is untouched
                                  if (video_) video_->record(world_->data(), o.time, std::move(lines));
                                }});
  }
  wire_devices(config);
  if (options.configure) options.configure(config);
  runtime_ = std::make_unique<runtime::Runtime>(std::move(config));
  world_plant_->log_injections_to(&runtime_->log());
}

void ScenarioRun::wire_devices(runtime::RunConfig& config) {
  twin_io_ = std::make_unique<sim::TwinIo>(*world_);
  // The twin's unit first, with every device not on real I/O (the scenario loader checked every choice against the
  // cell and the program).
  std::vector<runtime::IoUnit> units{runtime::IoUnit{twin_io_.get(), false, {}}};
  for (const runtime::DeviceWiring& w : cell_devices(scenario_.cell)) {
    const DeviceChoice* choice = find_device_choice(scenario_, w.name);
    if (choice == nullptr || !choice->real()) {
      units.front().devices.push_back(w);
    } else if (!realtime_) {
      throw InputError(choice->where, fmt::format("device '{}' is on real I/O (modbus {}): a real device runs on the "
                                                  "wall clock and cannot wait for the simulation's steps; run with "
                                                  "--realtime",
                                                  w.name, choice->modbus->str()));
    }
  }
  // Each real unit mirrored into the twin's I/O image (its coils, written and read, shown by the twin's devices).
  for (RealIoUnit& u : real_io_units(scenario_)) {
    (void)twin_io_->connect();  // the mirror writes into it
    auto mirror = std::make_unique<drivers::MirroredIo>(
        std::make_unique<drivers::ModbusIo>(u.address, drivers::ModbusIoOptions{}, u.where), *twin_io_);
    for (const runtime::DeviceWiring& w : u.devices) mirror->mirror_coil(w.coil);
    real_io_.push_back(std::move(mirror));
    units.push_back(runtime::IoUnit{real_io_.back().get(), true, std::move(u.devices)});
  }
  config.io_units = std::move(units);
}

ScenarioRun::~ScenarioRun() {
  runtime_.reset();  // joins the threads before the plant and the World they use go
}

std::vector<FinalPose> final_poses_of(const sim::World& world) {
  std::vector<FinalPose> out;
  const sim::WorldTruth truth = world.truth();
  for (const sim::WorkpieceTruth& w : truth.workpieces) {
    FinalPose f;
    f.name = w.name;
    f.pose = w.pose;
    f.present = !w.parked;
    if (w.held_by) f.held_by = world.scene().robots().at(*w.held_by).name;
    out.push_back(std::move(f));
  }
  return out;
}

bool ScenarioRun::settle_followers(runtime::SimDuration most) {
  if (!replica_mirror_) return true;
  // The runtime has ended: nothing else steps the World now. The copies' commands advance with it, their notifiers
  // waking the mirror's thread, which gives them the next action.
  constexpr std::chrono::milliseconds kStep{10};
  bool done = replica_mirror_->idle();
  for (runtime::SimDuration t{0}; !done && t < most; t += kStep) {
    world_->advance(kStep);
    done = replica_mirror_->idle();
  }
  replica_mirror_->stop();
  return done;
}

std::vector<FinalPose> ScenarioRun::final_poses() const {
  return final_poses_of(*world_);
}

Report ScenarioRun::report() const {
  // What this run used: the scenario's drivers and faults (the command line's already in it), its perception.
  RunSetup setup = setup_of(scenario_);
  setup.perception = runtime::to_string(perception_);
  for (DriverUse& d : setup.drivers) {
    if (std::find(followed_.begin(), followed_.end(), d.robot) != followed_.end()) {
      d = DriverUse{d.robot, "agent", followed_via_, false};  // its copy here followed the agent's robot
    }
  }
  if (!streamed_) {
    return make_report(scenario_, runtime::decode_log(runtime_->log().text(), kEventsFile), final_poses(),
                       estimate_.cycle_time, kEventsFile, std::move(setup));
  }
  return streamed_->report(runtime_->log(), scenario_, final_poses(), estimate_.cycle_time, std::move(setup));
}

void ScenarioRun::write_outputs(const std::filesystem::path& dir, const Report& report, const cv::Mat& final_image) {
  std::optional<std::filesystem::path> video;  // for the page: the file beside it, by its path relative to `dir`
  if (!video_file_.empty()) {
    video = std::filesystem::absolute(video_file_).lexically_relative(std::filesystem::absolute(dir));
  }
  make_output_directory(dir);
  if (!streamed_) {
    write_file_atomically(dir / kEventsFile, runtime_->log().text());
  } else {
    streamed_->move_into(dir, runtime_->log());
  }
  write_report_outputs(dir, scenario_, report, final_image, video);
}

cv::Mat ScenarioRun::snapshot(int width, int height) const {
  // Render a copy: the renderer's scene update needs a mutable mjData, and the World's stays untouched.
  const mjModel* model = world_->scene().model();
  std::unique_ptr<mjData, void (*)(mjData*)> copy(mj_makeData(model), mj_deleteData);
  mj_copyData(copy.get(), model, world_->data());
  // Give the heap that the run's threads freed (the camera's renderer, released when the simulation thread ended)
  // back to the system before this renderer takes its own: 18 MB less at the run's peak with a camera.
  malloc_trim(0);
  twin::Renderer renderer(model, width, height);
  cv::Mat image = renderer.render_overview(copy.get(), width, height);
  // The workpieces the verdict is about, named where they ended up (the poses the report judges).
  const vision::CameraModel camera = twin::overview_camera_model(model, copy.get(), width, height);
  const std::vector<FinalPose> finals = final_poses();
  for (const Expectation& e : scenario_.expect) {
    const auto f = std::find_if(finals.begin(), finals.end(), [&](const FinalPose& p) { return p.name == e.workpiece; });
    if (f == finals.end() || !f->present) continue;
    const std::optional<cv::Point2d> px = camera.project(f->pose.translation());
    if (!px) continue;
    const cv::Point at(static_cast<int>(std::lround(px->x)), static_cast<int>(std::lround(px->y)));
    if (at.x < 0 || at.y < 0 || at.x >= width || at.y >= height) continue;
    const std::string text = fmt::format("{} ({})", e.workpiece, e.place);
    int base = 0;
    const cv::Size sz = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, &base);
    const cv::Point corner(std::min(at.x + 8, width - sz.width - 4), std::max(at.y - 10, sz.height + 4));
    cv::circle(image, at, 5, {0, 0, 0}, 2, cv::LINE_AA);
    cv::line(image, at, corner + cv::Point(0, -sz.height / 2), {0, 0, 0}, 1, cv::LINE_AA);
    cv::rectangle(image, corner + cv::Point(-2, -sz.height - 3), corner + cv::Point(sz.width + 2, base + 1),
                  {255, 255, 255}, cv::FILLED);
    cv::putText(image, text, corner, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0}, 1, cv::LINE_AA);
  }
  return image;
}

std::filesystem::path ScenarioRun::finish_video(const Report& report) {
  if (!video_) return {};
  const std::string verdict =
      report.ok() ? fmt::format("PASS: {} in {:.2f} s", report.outcome, report.end_time)
                  : fmt::format("FAIL: {}{}", report.outcome,
                                report.failures.empty() ? "" : fmt::format(" ({} failures)", report.failures.size()));
  std::unique_ptr<twin::VideoRecorder> video = std::move(video_);
  video->finish(world_->data(), std::chrono::duration_cast<runtime::SimDuration>(
                                    std::chrono::duration<double>(report.end_time)),
                verdict, report.ok());
  return video->options().path;
}

}  // namespace cellwright::cell
