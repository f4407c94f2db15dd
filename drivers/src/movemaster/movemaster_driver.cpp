// MovemasterDriver (movemaster_driver.hpp): each job as an exchange of Movemaster EX lines on SerialDriver's link.
#include "cellwright/drivers/movemaster/movemaster_driver.hpp"

#include <fmt/format.h>

#include <cmath>
#include <utility>
#include <variant>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers {

namespace mm = movemaster;

namespace {

using Steady = SerialDriver::Link::Clock;

double ms(std::chrono::nanoseconds d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

void check_option(bool ok, const MovemasterOptions& o, const std::string& problem) {
  if (!ok) throw InputError(o.serial.where, fmt::format("Movemaster EX on {}: {}", o.serial.line.port, problem));
}

}  // namespace

// One job's lines: sends them with the line end, reads answers with deadlines, and turns every way an exchange can
// go wrong into the Outcome that docs/real-robots.md gives it, with a message quoting what was received.
class MovemasterDriver::Exchange {
 public:
  Exchange(Link& link, const MovemasterOptions& options) : link_(link), options_(options) {}

  bool sent_any() const { return sent_any_; }

  static Outcome failed(ErrorCode error, std::string message) {
    Outcome o;
    o.error = error;
    o.message = std::move(message);
    return o;
  }

  // Sends one line; `ER` and `WH` are not counted as what an `ER` answers for.
  Outcome send(const std::string& command) {
    std::string message;
    const PortStatus s = link_.send(command + std::string(mm::line_end_text(options_.line_end)), &message);
    sent_any_ = true;
    if (s == PortStatus::ok) {
      if (command != "ER" && command != "WH") since_er_.push_back(command);
      return {};
    }
    return failed(ErrorCode::connection_lost, fmt::format("the line did not take '{}': {}", command, message));
  }

  // One answer line to `asked`, before `deadline`.
  Outcome read(const std::string& asked, Steady::time_point deadline, std::string* line) {
    const auto waited = deadline - Steady::now();
    std::string message;
    const PortStatus s = link_.read_line(deadline, line, &message);
    if (s == PortStatus::ok) return {};
    if (s == PortStatus::timeout) {
      return failed(ErrorCode::connection_lost,
                    fmt::format("the controller is silent: no answer to '{}' within {:.0f} ms "
                                "(received for this command: {})",
                                asked, ms(waited), received()));
    }
    return failed(ErrorCode::connection_lost, fmt::format("the line dropped while waiting for the answer to '{}': {} "
                                                          "(received for this command: {})",
                                                          asked, message, received()));
  }

  // Sends `ER` and reads its number: none for 0; for any other `RS` goes out (when `reset` is set) and the outcome is
  // hardware (1), unreachable (2) or unknown (a code outside the manual's); an answer that is no number is protocol.
  // With `settle` (at connect), the answer is the last line before `settle` of quiet: see greet().
  Outcome er(Steady::time_point deadline, bool reset = true, std::chrono::nanoseconds settle = {}) {
    const std::string what = since_er_.empty() ? std::string("at connect") : fmt::format("after '{}'", last_sent());
    since_er_.clear();
    if (Outcome o = send("ER"); o.error != ErrorCode::none) return o;
    std::string line;
    if (Outcome o = read("ER", deadline, &line); o.error != ErrorCode::none) return o;
    while (settle.count() > 0) {
      std::string later, message;
      const PortStatus s = link_.read_line(Link::in(settle), &later, &message);
      if (s == PortStatus::timeout) break;
      if (s != PortStatus::ok) return failed(ErrorCode::connection_lost, fmt::format("the line dropped: {}", message));
      line = std::move(later);
    }
    const std::optional<int> answer = mm::parse_er(line);
    if (!answer) {
      return failed(ErrorCode::protocol, fmt::format("the answer to 'ER' {} is '{}', not an error code (received for "
                                                     "this command: {})",
                                                     what, printable(line), received()));
    }
    if (*answer == 0) return {};
    const ErrorCode code = *answer == 1   ? ErrorCode::hardware
                           : *answer == 2 ? ErrorCode::unreachable
                                          : ErrorCode::unknown;
    std::string message =
        code == ErrorCode::hardware ? fmt::format("the controller reports a hardware error: ER answered 1 {}", what)
        : code == ErrorCode::unreachable
            ? fmt::format("the controller cannot do it: ER answered 2 (position or format error) {}", what)
            : fmt::format("the controller reports an error this driver does not know: ER answered {} {}", *answer,
                          what);
    if (reset) {
      if (Outcome o = send("RS"); o.error != ErrorCode::none) return o;
      since_er_.clear();
      message += "; RS sent";
    }
    return failed(code, std::move(message));
  }

  // Sends `WH` and reads the pose it answers.
  Outcome wh(Steady::time_point deadline, mm::Xyzpr* where) {
    if (Outcome o = send("WH"); o.error != ErrorCode::none) return o;
    std::string line;
    if (Outcome o = read("WH", deadline, &line); o.error != ErrorCode::none) return o;
    const std::optional<mm::Xyzpr> v = mm::parse_wh(line);
    if (!v) {
      return failed(ErrorCode::protocol, fmt::format("the answer to 'WH' is '{}', not five numbers x,y,z,p,r (received "
                                                     "for this command: {})",
                                                     printable(line), received()));
    }
    *where = *v;
    return {};
  }

  // Fails when bytes are waiting that nobody asked for (they would be taken for the next answer), or the line
  // dropped.
  Outcome quiet() {
    if (link_.buffer().empty()) {
      std::string message;
      const PortStatus s = link_.receive(Steady::now(), &message);
      if (s == PortStatus::closed || s == PortStatus::error) {
        return failed(ErrorCode::connection_lost, fmt::format("the line dropped: {}", message));
      }
    }
    if (link_.buffer().empty()) return {};
    return failed(ErrorCode::protocol,
                  fmt::format("the controller sent bytes nobody asked for: '{}'", printable(link_.buffer())));
  }

  // Waits `period` with nothing asked, watching the line: none when nothing came.
  Outcome idle(std::chrono::nanoseconds period) {
    std::string message;
    const PortStatus s = link_.receive(Link::in(period), &message);
    if (s == PortStatus::timeout) return {};
    if (s == PortStatus::ok) return quiet();
    return failed(ErrorCode::connection_lost, fmt::format("the line dropped: {}", message));
  }

 private:
  std::string received() const {
    const std::string r = link_.received_text();
    return r.empty() ? std::string("nothing") : fmt::format("'{}'", r);
  }
  std::string last_sent() const {
    std::string s;
    for (const std::string& c : since_er_) s += (s.empty() ? "" : "', '") + c;
    return s;
  }

  Link& link_;
  const MovemasterOptions& options_;
  std::vector<std::string> since_er_;  // the lines sent since the last `ER`, for its messages
  bool sent_any_ = false;
};

MovemasterDriver::MovemasterDriver(MovemasterOptions options) : SerialDriver(options.serial), options_(options) {
  const MovemasterOptions& o = options_;
  check_option(o.ms_open_letter == 'O' || o.ms_open_letter == 'C', o,
               fmt::format("ms_open_letter '{}' is neither O nor C", printable(std::string(1, o.ms_open_letter))));
  check_option(o.linear_slot >= 1 && o.linear_slot <= 629, o,
               fmt::format("linear_slot {} is outside 1..629", o.linear_slot));
  check_option(!o.tool_length_mm || (std::isfinite(*o.tool_length_mm) && *o.tool_length_mm >= 0.0), o,
               fmt::format("tool_length_mm {} is not a length >= 0", o.tool_length_mm.value_or(0.0)));
  check_option(std::isfinite(o.yaw_tolerance_deg) && o.yaw_tolerance_deg >= 0.0 && o.yaw_tolerance_deg < 90.0, o,
               fmt::format("yaw_tolerance_deg {} is outside [0, 90)", o.yaw_tolerance_deg));
  check_option(o.pitch_down_deg == -90.0 || o.pitch_down_deg == 90.0, o,
               fmt::format("pitch_down {} is neither -90 nor 90", o.pitch_down_deg));
  check_option(o.roll_sense == 1 || o.roll_sense == -1, o, fmt::format("roll_sense {} is neither 1 nor -1", o.roll_sense));
  check_option(o.grip_start_time >= 0 && o.grip_start_time <= 99, o,
               fmt::format("grip_start_time {} is outside 0..99 (tenths of a second)", o.grip_start_time));
  check_option(o.joints >= 1, o, "joints must be at least 1");
  check_option(o.max_joint_speed.empty() || o.max_joint_speed.size() == o.joints, o,
               fmt::format("max_joint_speed has {} values for {} joints", o.max_joint_speed.size(), o.joints));
  for (const double v : o.max_joint_speed) {
    check_option(std::isfinite(v) && v > 0.0, o, fmt::format("max_joint_speed {} rad/s is not > 0", v));
  }
  check_option(std::isfinite(o.max_tool_speed) && o.max_tool_speed > 0.0, o,
               fmt::format("max_tool_speed {} m/s is not > 0", o.max_tool_speed));
  check_option(std::isfinite(o.gripper_max_force) && o.gripper_max_force > 0.0, o,
               fmt::format("gripper_max_force {} N is not > 0", o.gripper_max_force));
  const auto positive = [&](std::chrono::nanoseconds d, const char* name) {
    check_option(d.count() > 0, o, fmt::format("{} {} ms is not > 0", name, ms(d)));
  };
  positive(o.poll_period, "poll_period");
  positive(o.longest_motion, "longest_motion");
  positive(o.home_time, "home_time");
  positive(o.serial.reply_timeout, "reply_timeout");
  check_option(o.resync_quiet.count() >= 0, o, fmt::format("resync_quiet {} ms is negative", ms(o.resync_quiet)));
  check_option(o.grip_time.count() >= 0, o, fmt::format("grip_time {} ms is negative", ms(o.grip_time)));
  check_option(o.serial.processing_time.count() >= 0, o,
               fmt::format("processing_time {} ms is negative", ms(o.serial.processing_time)));

  Capabilities caps;
  caps.joints = o.joints;
  caps.joint_control = false;
  caps.cartesian_control = true;
  caps.linear_motion = true;
  caps.full_orientation = false;
  caps.gripper = true;
  caps.gripper_width = false;
  caps.gripper_force = true;
  caps.gripper_max_force = o.gripper_max_force;
  caps.digital_outputs = 0;
  caps.digital_inputs = 0;
  caps.max_joint_speed = o.max_joint_speed;
  caps.max_tool_speed = o.max_tool_speed;
  caps.queue_depth = 2;
  caps.reads_joints = false;
  caps.reads_pose = true;
  caps.reads_while_moving = false;
  // `WH` and its line end; a typical answer of five signed values with one decimal ("+350.0,-150.0,+300.0,-90.0,+0.0",
  // 31 characters) and CR LF.
  caps.read_time = read_time(o.serial, 2 + movemaster::line_end_text(o.line_end).size(), 33);
  caps.prefers_pose = true;
  set_capabilities(std::move(caps));
}

MovemasterDriver::~MovemasterDriver() {
  disconnect();
}

void MovemasterDriver::forget() {
  speed_level_.reset();
  where_.reset();
}

SerialDriver::Outcome MovemasterDriver::greet(Link& link) {
  forget();
  Exchange ex(link, options_);
  const auto reply = options_.serial.reply_timeout;
  // An answer to a question asked before the link was given up (silence, then a reconnect) may still come; the
  // controller answers in order, so it comes before this ER's: the last line before resync_quiet of quiet is ours.
  if (Outcome o = ex.er(Link::in(reply), true, options_.resync_quiet); o.error != ErrorCode::none) return o;
  if (options_.tool_length_mm) {
    if (Outcome o = ex.send(mm::format_tl(*options_.tool_length_mm)); o.error != ErrorCode::none) return o;
    if (Outcome o = ex.er(Link::in(reply)); o.error != ErrorCode::none) return o;
  }
  return {};
}

SerialDriver::Outcome MovemasterDriver::clear_error(Link& link) {
  forget();
  link.discard_input();  // whatever came after the failure is not an answer to what follows
  Exchange ex(link, options_);
  if (Outcome o = ex.send("RS"); o.error != ErrorCode::none) return o;
  Outcome o = ex.er(Link::in(options_.serial.reply_timeout), /*reset=*/false);
  if (o.error == ErrorCode::hardware || o.error == ErrorCode::unreachable) {
    return Exchange::failed(ErrorCode::hardware, fmt::format("RS did not clear the controller's error: {}", o.message));
  }
  return o;
}

std::optional<mm::Xyzpr> MovemasterDriver::last_wh() const {
  std::lock_guard lock(wh_mutex_);
  return last_wh_;
}

SerialDriver::Outcome MovemasterDriver::execute(Link& link, const JobCopy& job) {
  Exchange ex(link, options_);
  const auto reply = options_.serial.reply_timeout;
  Outcome o = ex.quiet();
  if (o.error == ErrorCode::none) {
    switch (job.kind) {
      case JobKind::home:
        o = ex.send("NT");
        if (o.error == ErrorCode::none) o = ex.er(Link::in(options_.home_time + reply));
        where_.reset();  // the nest is no pose the driver knows
        break;
      case JobKind::position: {
        mm::Xyzpr v;
        o = ex.wh(Link::in(reply), &v);
        if (o.error == ErrorCode::none) {
          where_ = v;
          {
            std::lock_guard lock(wh_mutex_);
            last_wh_ = v;
          }
          o.reading.emplace();
          o.reading->tool_pose = options_.frames.from_controller(
              mm::to_pose(mm::with_angle_reading(v, options_.pitch_down_deg, options_.roll_sense)));
        }
        break;
      }
      case JobKind::command:
        CW_CHECK(job.command.has_value(), "command job {} without a command", job.id);
        if (const auto* move_pose = std::get_if<MovePose>(&*job.command)) {
          o = move(ex, *move_pose);
        } else if (const auto* g = std::get_if<Grip>(&*job.command)) {
          o = grip(ex, *g);
        } else {
          // check_command refuses the rest against capabilities(): reaching here is a bug of ours.
          CW_CHECK(false, "the Movemaster driver was given {}", describe(*job.command));
        }
        break;
    }
  }
  if (o.error != ErrorCode::none && ex.sent_any()) forget();
  return o;
}

SerialDriver::Outcome MovemasterDriver::move(Exchange& ex, const MovePose& command) {
  std::string problem;
  std::optional<mm::Xyzpr> target =
      mm::to_xyzpr(options_.frames.to_controller(command.pose), options_.yaw_tolerance_deg, &problem);
  if (!target) return Exchange::failed(ErrorCode::unreachable, problem + "; nothing sent");
  target = mm::with_angle_reading(*target, options_.pitch_down_deg, options_.roll_sense);
  const int level = mm::speed_level(command.speed);
  if (speed_level_ != level) {
    if (Outcome o = ex.send(mm::format_sp(level, options_.acceleration)); o.error != ErrorCode::none) return o;
    speed_level_ = level;
  }
  if (command.path == Path::joint) {
    if (Outcome o = ex.send(mm::format_mp(*target)); o.error != ErrorCode::none) return o;
  } else {
    if (!where_) {  // the intermediate points count the travel: ask where it starts
      mm::Xyzpr start;
      if (Outcome o = ex.wh(Link::in(options_.serial.reply_timeout), &start); o.error != ErrorCode::none) return o;
      where_ = start;
    }
    const char open_letter = options_.ms_open_letter;
    const char letter = grip_closed_ ? (open_letter == 'O' ? 'C' : 'O') : open_letter;
    const int points = mm::intermediate_points(mm::travel_mm(*where_, *target));
    if (Outcome o = ex.send(mm::format_pd(options_.linear_slot, *target)); o.error != ErrorCode::none) return o;
    if (Outcome o = ex.send(mm::format_ms(options_.linear_slot, points, letter)); o.error != ErrorCode::none) {
      return o;
    }
  }
  // The controller's joint speed at level n is (n + 1)/10 of its maximum.
  Outcome o = finish_motion(ex, options_.longest_motion * 10 / (level + 1));
  if (o.error == ErrorCode::none) where_ = *target;
  return o;
}

SerialDriver::Outcome MovemasterDriver::grip(Exchange& ex, const Grip& command) {
  std::chrono::nanoseconds start_time{0};
  if (command.force) {
    const int s = mm::grip_force_level(*command.force, options_.gripper_max_force);
    if (Outcome o = ex.send(mm::format_gp(s, s, options_.grip_start_time)); o.error != ErrorCode::none) return o;
    start_time = std::chrono::milliseconds(100) * options_.grip_start_time;
  }
  const bool close = command.action == Grip::Action::close;
  if (Outcome o = ex.send(close ? "GC" : "GO"); o.error != ErrorCode::none) return o;
  Outcome o = ex.er(Link::in(options_.grip_time + start_time + options_.serial.reply_timeout));
  if (o.error == ErrorCode::none) grip_closed_ = close;
  return o;
}

SerialDriver::Outcome MovemasterDriver::finish_motion(Exchange& ex, std::chrono::nanoseconds expected) {
  const auto reply = options_.serial.reply_timeout;
  const auto deadline = Link::in(expected + reply);
  if (options_.completion == MovemasterOptions::Completion::poll) {
    mm::Xyzpr before;
    if (Outcome o = ex.wh(deadline, &before); o.error != ErrorCode::none) return o;
    for (;;) {
      if (Outcome o = ex.idle(options_.poll_period); o.error != ErrorCode::none) return o;
      mm::Xyzpr now;
      if (Outcome o = ex.wh(Link::in(reply), &now); o.error != ErrorCode::none) return o;
      if (now == before) break;
      if (Steady::now() > deadline) {
        return Exchange::failed(
            ErrorCode::hardware,
            fmt::format("the arm did not come to rest within {:.0f} ms: WH still changes", ms(expected + reply)));
      }
      before = now;
    }
    return ex.er(Link::in(reply));
  }
  return ex.er(deadline);
}

}  // namespace cellwright::drivers
