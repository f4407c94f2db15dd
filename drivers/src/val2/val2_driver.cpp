// Val2Driver (val2_driver.hpp): the VAL II monitor over SerialDriver's line.
#include "cellwright/drivers/val2/val2_driver.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <variant>

namespace cellwright::drivers {

namespace {

using SteadyClock = SerialPort::Clock;
using Outcome = SerialDriver::Outcome;
using std::chrono::nanoseconds;

// An unfinished line longer than this is garbage (the WHERE lines, the longest, are under 100 bytes).
constexpr std::size_t kMaxLine = 512;

std::string_view line_end_text(Val2LineEnd end) {
  switch (end) {
    case Val2LineEnd::cr:
      return "\r";
    case Val2LineEnd::crlf:
      return "\r\n";
    case Val2LineEnd::lf:
      return "\n";
  }
  return "\r";
}

bool printable_byte(char ch) {
  const auto c = static_cast<unsigned char>(ch);
  return c == '\t' || (c >= 0x20 && c < 0x7f);
}

// A byte that may stand in an unfinished line: printable, a line end's CR, or a bell (dropped when the line ends).
bool pending_byte(char ch) {
  return ch == '\r' || ch == '\a' || printable_byte(ch);
}

// A line's text without the spaces and tabs around it.
std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string seconds_text(nanoseconds d) {
  return fmt::format("{:.3f} s", std::chrono::duration<double>(d).count());
}

Outcome failure(ErrorCode error, std::string message) {
  Outcome o;
  o.error = error;
  o.message = std::move(message);
  return o;
}

nanoseconds seconds(double s) {
  return std::chrono::duration_cast<nanoseconds>(std::chrono::duration<double>(s));
}

}  // namespace

SerialOptions val2_serial_defaults() {
  SerialOptions o;
  o.line.baud = 9600;
  o.line.data_bits = 8;
  o.line.parity = Parity::none;
  o.line.stop_bits = 1;
  o.line.rts_cts = false;
  o.line.xon_xoff = false;
  return o;
}

// One job's exchanges with the monitor, on the communication thread (or connect()'s, for the greeting).
class Val2Driver::Session {
 public:
  Session(Link& link, const Val2Options& options, State& state) : link_(link), options_(options), state_(state) {}

  // Sends `text` and reads the answer up to the prompt (see await()).
  Outcome command(const std::string& text, nanoseconds budget, ErrorCode on_silence = ErrorCode::protocol,
                  val2::WhereParser* where = nullptr) {
    if (Outcome o = unasked(text); o.error != ErrorCode::none) return o;
    if (Outcome o = send(text); o.error != ErrorCode::none) return o;
    return await(text, options_.echo != Val2Echo::never, budget, on_silence, where);
  }

  // RESYNC (val2_driver.hpp): an empty line, then a prompt followed by quiet; whatever comes before it is skipped.
  // `failed` is the error when the monitor does not answer.
  Outcome resync(ErrorCode failed) {
    state_ = State{};
    link_.discard_input();
    if (Outcome o = send(""); o.error != ErrorCode::none) return o;
    const auto deadline = Link::in(options_.serial.reply_timeout);
    std::string& buffer = link_.buffer();
    bool prompt = false;
    std::string message;
    for (;;) {
      if (const std::size_t end = buffer.find_last_of("\r\n"); end != std::string::npos) buffer.erase(0, end + 1);
      if (val2::is_prompt(buffer, options_.prompt)) {
        prompt = true;
        buffer.clear();
      } else if (buffer.size() > kMaxLine) {
        buffer.clear();  // no prompt in there
      }
      const auto until = prompt ? std::min(deadline, Link::in(options_.resync_quiet)) : deadline;
      const PortStatus s = link_.receive(until, &message);
      if (s == PortStatus::timeout) {
        if (prompt) return {};
        return failure(failed, fmt::format("the monitor gave no prompt within {} of an empty line (received '{}')",
                                           seconds_text(options_.serial.reply_timeout), link_.received_text()));
      }
      if (s != PortStatus::ok) return dropped("an empty line", s, message);
      prompt = false;  // more came after it: the prompt is the last one, if any
    }
  }

  // The prompt a DO WAIT given up on still owes: waits for it before `next` goes out.
  Outcome settle_owed(std::string_view next) {
    const std::string owed = *state_.owed_prompt;
    Outcome o = await(owed, false, options_.serial.reply_timeout, ErrorCode::timeout, nullptr);
    if (o.error == ErrorCode::timeout) {
      o.message = fmt::format("{} not sent: the monitor has not finished '{}' (no prompt within {})", next, owed,
                              seconds_text(options_.serial.reply_timeout));
      return o;
    }
    state_.owed_prompt.reset();
    return o;
  }

  Outcome home() {
    Outcome o = command("DO READY", options_.home_timeout);
    forget_position();
    return o;
  }

  Outcome where() {
    val2::WhereParser parser(options_.where_layout);
    Outcome o = command("WHERE", options_.serial.reply_timeout, ErrorCode::protocol, &parser);
    if (o.error != ErrorCode::none) return o;
    PositionReading reading = val2::to_position_reading(*parser.reading(), options_.orientation);
    reading.tool_pose = options_.frames.from_controller(*reading.tool_pose);
    state_.where_world = parser.reading()->world;
    state_.joints = reading.joints;
    state_.pose = reading.tool_pose;
    o.reading = std::move(reading);
    return o;
  }

  Outcome run(const MoveJoints& c) {
    const int percent = speed_percent(c.speed);
    if (Outcome o = speed(percent); o.error != ErrorCode::none) return o;
    double duration = worst_duration();
    if (state_.joints && state_.joints->size() == c.positions.size()) {
      duration = 0.0;
      for (std::size_t i = 0; i < c.positions.size(); ++i) {
        duration = std::max(duration, std::abs(c.positions[i] - (*state_.joints)[i]) / options_.max_joint_speed[i]);
      }
    }
    Outcome o = command("DO MOVE " + val2::ppoint_text(c.positions), motion_budget(duration, percent));
    forget_position();
    if (o.error == ErrorCode::none) state_.joints = c.positions;
    return o;
  }

  Outcome run(const MovePose& c) {
    const int percent = speed_percent(c.speed);
    if (Outcome o = speed(percent); o.error != ErrorCode::none) return o;
    const bool linear = c.path == Path::linear;
    double duration = worst_duration();
    if (linear && state_.pose) {
      const double distance = (c.pose.translation() - state_.pose->translation()).norm();
      const double turn = Eigen::AngleAxisd(state_.pose->linear().transpose() * c.pose.linear()).angle();
      const double wrist = *std::min_element(options_.max_joint_speed.begin() + 3, options_.max_joint_speed.end());
      duration = std::max(distance / options_.max_tool_speed, turn / wrist);
    }
    const std::string text = std::string(linear ? "DO MOVES " : "DO MOVE ") +
                             val2::trans_text(val2::to_location(options_.frames.to_controller(c.pose), options_.orientation));
    Outcome o = command(text, motion_budget(duration, percent));
    forget_position();
    if (o.error == ErrorCode::none) state_.pose = c.pose;
    return o;
  }

  Outcome run(const Grip& c) {
    return command(c.action == Grip::Action::open ? "DO OPENI" : "DO CLOSEI", options_.serial.reply_timeout);
  }

  Outcome run(const SetOutput& c) {
    return command(fmt::format("DO SIGNAL {}", c.on ? c.channel : -c.channel), options_.serial.reply_timeout);
  }

  Outcome run(const WaitInput& c) {
    const int signal = 1000 + c.channel;
    const std::string text = fmt::format("DO WAIT SIG({})", c.on ? signal : -signal);
    const nanoseconds budget = c.timeout > nanoseconds::zero() ? c.timeout : options_.input_wait_limit;
    Outcome o = command(text, budget, ErrorCode::timeout);
    if (o.error == ErrorCode::timeout) {
      state_.owed_prompt = text;
      o.message = fmt::format("{}: input {} did not turn {} within {}{}", text, c.channel, c.on ? "on" : "off",
                              seconds_text(budget), c.timeout > nanoseconds::zero() ? "" : " (input_wait_limit)");
    }
    return o;
  }

 private:
  static int speed_percent(double speed) { return std::clamp(static_cast<int>(std::lround(speed * 100.0)), 1, 100); }

  // The slowest joint's whole travel at SPEED 100, s: the bound when the motion's start is not known.
  double worst_duration() const {
    double d = 0.0;
    for (std::size_t i = 0; i < options_.joint_travel.size(); ++i) {
      d = std::max(d, options_.joint_travel[i] / options_.max_joint_speed[i]);
    }
    return d;
  }

  nanoseconds motion_budget(double duration_at_full_speed, int percent) const {
    return seconds(duration_at_full_speed * 100.0 / percent) + options_.motion_margin;
  }

  void forget_position() {
    state_.joints.reset();
    state_.pose.reset();
  }

  Outcome speed(int percent) {
    if (state_.speed_percent == percent) return {};
    state_.speed_percent.reset();  // unknown until the monitor took it
    Outcome o = command(fmt::format("SPEED {}", percent), options_.serial.reply_timeout);
    if (o.error == ErrorCode::none) state_.speed_percent = percent;
    return o;
  }

  // Bytes that came after the last prompt, before `text` goes out: the monitor spoke on its own. `text` is not sent.
  Outcome unasked(const std::string& text) {
    std::string message;
    if (link_.buffer().empty()) {
      const PortStatus s = link_.receive(SteadyClock::now(), &message);
      if (s == PortStatus::closed || s == PortStatus::error) return dropped(text, s, message);
    }
    const std::string& bytes = link_.buffer();
    if (bytes.empty()) return {};
    const std::string said_text = val2::without_bells(bytes);
    const ErrorCode said = trim(said_text).starts_with('*') ? val2::classify_error(said_text) : ErrorCode::protocol;
    const bool fault = said == ErrorCode::hardware || said == ErrorCode::unknown;
    return failure(fault ? said : ErrorCode::protocol,
                   fmt::format("{} not sent: the controller sent '{}' unasked", text, printable(bytes)));
  }

  Outcome send(const std::string& text) {
    std::string message;
    const PortStatus s = link_.send(text + std::string(line_end_text(options_.line_end)), &message);
    if (s == PortStatus::ok) return {};
    const std::string what = text.empty() ? std::string("an empty line") : text;
    if (s == PortStatus::timeout) {
      return failure(ErrorCode::protocol, fmt::format("{}: the line took no bytes for {} ({})", what,
                                                      seconds_text(options_.serial.reply_timeout), message));
    }
    return dropped(what, s, message);
  }

  // Reads the monitor's answer to `sent` up to the prompt, `budget` from now: an echoed copy of `sent` first (if
  // `echo`), blank lines, error lines, and for WHERE the lines `where` takes. Silence past the budget is `on_silence`
  // (protocol, or timeout for DO WAIT), unless some answer had begun (then protocol).
  Outcome await(const std::string& sent, bool echo, nanoseconds budget, ErrorCode on_silence,
                val2::WhereParser* where) {
    auto deadline = Link::in(budget);
    std::string& buffer = link_.buffer();
    std::optional<std::string> error_line;
    std::string message;
    for (;;) {
      // A line ends at CR LF, CR or LF: the empty line between a CR and its LF is skipped as every blank line is.
      for (std::size_t end = buffer.find_first_of("\r\n"); end != std::string::npos;
           end = buffer.find_first_of("\r\n")) {
        const std::string raw = buffer.substr(0, end);
        buffer.erase(0, end + 1);
        const std::string line = val2::without_bells(raw);
        if (!std::all_of(line.begin(), line.end(), printable_byte)) return garbage(sent, raw);
        const std::string_view text = trim(line);
        if (text.empty()) continue;
        if (echo) {
          echo = false;
          if (text == sent) continue;
          if (options_.echo == Val2Echo::always) return garbage(sent, raw);
        }
        if (text.front() == '*') {
          if (!error_line) {
            error_line = std::string(text);
            deadline = Link::in(options_.serial.reply_timeout);  // the prompt follows an error
          }
          continue;
        }
        if (!error_line && where != nullptr && where->feed(line)) continue;
        return garbage(sent, raw);
      }
      if (val2::is_prompt(buffer, options_.prompt)) {
        // A number line of WHERE may begin with '.': then more follows at once.
        if (!error_line && where != nullptr && !where->finished()) {
          const PortStatus s = link_.receive(std::min(deadline, Link::in(options_.prompt_settle)), &message);
          if (s == PortStatus::ok) continue;
          if (s != PortStatus::timeout) return dropped(sent, s, message);
        }
        buffer.clear();
        return answered(sent, error_line, where);
      }
      const bool bad = !std::all_of(buffer.begin(), buffer.end(), pending_byte);
      if (bad || buffer.size() > kMaxLine) return garbage(sent, buffer);
      const PortStatus s = link_.receive(deadline, &message);
      if (s == PortStatus::timeout) return silent(sent, budget, error_line, on_silence);
      if (s != PortStatus::ok) return dropped(sent, s, message);
    }
  }

  Outcome answered(const std::string& sent, const std::optional<std::string>& error_line,
                   const val2::WhereParser* where) {
    if (error_line) {
      return failure(val2::classify_error(*error_line),
                     fmt::format("{}: the controller answered '{}'", sent, printable(*error_line)));
    }
    if (where != nullptr && !where->complete()) {
      return failure(ErrorCode::protocol, fmt::format("{}: the answer lacks {} (received '{}')", sent, where->missing(),
                                                      link_.received_text()));
    }
    return {};
  }

  Outcome silent(const std::string& sent, nanoseconds budget, const std::optional<std::string>& error_line,
                 ErrorCode on_silence) {
    if (error_line) {
      return failure(ErrorCode::protocol,
                     fmt::format("{}: the controller answered '{}' and then gave no prompt within {}", sent,
                                 printable(*error_line), seconds_text(options_.serial.reply_timeout)));
    }
    const ErrorCode e = link_.buffer().empty() ? on_silence : ErrorCode::protocol;
    return failure(
        e, fmt::format("{}: no prompt within {} (received '{}')", sent, seconds_text(budget), link_.received_text()));
  }

  Outcome garbage(const std::string& sent, std::string_view bytes) {
    return failure(ErrorCode::protocol, fmt::format("{}: the controller's answer could not be understood: '{}' "
                                                    "(received '{}')",
                                                    sent, printable(bytes), link_.received_text()));
  }

  static Outcome dropped(std::string_view what, PortStatus s, const std::string& message) {
    return failure(ErrorCode::connection_lost, fmt::format("{}: the link dropped{}: {}", what,
                                                           s == PortStatus::error ? " (port error)" : "", message));
  }

  Link& link_;
  const Val2Options& options_;
  State& state_;
};

// ---- Val2Driver ---------------------------------------------------------------------------------------------------

namespace {

void check_six(const SerialOptions& serial, const char* name, const std::vector<double>& values) {
  const bool ok = values.size() == 6 &&
                  std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v) && v > 0.0; });
  if (!ok) {
    throw InputError(serial.where, fmt::format("VAL II driver on {}: {} needs six positive values, not [{}]",
                                               serial.line.port, name, fmt::join(values, ", ")));
  }
}

const Val2Options& checked(const Val2Options& o) {
  check_six(o.serial, "max_joint_speed", o.max_joint_speed);
  check_six(o.serial, "joint_travel", o.joint_travel);
  const bool prompt_ok =
      !o.prompt.empty() && std::all_of(o.prompt.begin(), o.prompt.end(), [](char c) { return c > 0x20 && c < 0x7f; });
  if (!prompt_ok) {
    std::string shown;
    for (const char c : o.prompt) shown += printable_byte(c) ? std::string(1, c) : fmt::format("\\x{:02x}", c);
    throw InputError(o.serial.where, fmt::format("VAL II driver on {}: the prompt must be printable characters "
                                                 "without spaces, not '{}'",
                                                 o.serial.line.port, shown));
  }
  if (!(std::isfinite(o.max_tool_speed) && o.max_tool_speed > 0.0)) {
    throw InputError(o.serial.where, fmt::format("VAL II driver on {}: max_tool_speed must be positive, not {}",
                                                 o.serial.line.port, o.max_tool_speed));
  }
  const std::pair<const char*, nanoseconds> durations[] = {{"processing_time", o.serial.processing_time},
                                                           {"reply_timeout", o.serial.reply_timeout},
                                                           {"motion_margin", o.motion_margin},
                                                           {"home_timeout", o.home_timeout},
                                                           {"input_wait_limit", o.input_wait_limit},
                                                           {"prompt_settle", o.prompt_settle},
                                                           {"resync_quiet", o.resync_quiet}};
  for (const auto& [name, d] : durations) {
    if (d < nanoseconds::zero()) {
      throw InputError(o.serial.where,
                       fmt::format("VAL II driver on {}: {} is negative ({} ns)", o.serial.line.port, name, d.count()));
    }
  }
  return o;
}

// The bytes of `WHERE` and its line end.
std::size_t where_request_bytes(const Val2Options& o) {
  return 5 + (o.line_end == Val2LineEnd::crlf ? 2 : 1);
}

// A typical answer to `WHERE` (Capabilities::read_time), with the columns of docs/real-robots.md: the echo (`WHERE` CR
// LF), then for the VAL II layout a header of seven columns (76 characters), the seven world values (76) and the six
// joints (65), for the AS layout four lines of six columns (60 each), each line with CR LF, and the prompt.
std::size_t where_answer_bytes(const Val2Options& o) {
  const std::size_t echo = o.echo == Val2Echo::never ? 0 : 7;
  const std::size_t lines =
      o.where_layout == val2::WhereLayout::as_two_block ? 4 * (60 + 2) : (76 + 2) + (76 + 2) + (65 + 2);
  return echo + lines + o.prompt.size();
}

}  // namespace

Val2Driver::Val2Driver(Val2Options options) : SerialDriver(checked(options).serial), options_(std::move(options)) {
  Capabilities c;
  c.joints = 6;
  c.joint_control = true;
  c.cartesian_control = true;
  c.linear_motion = true;
  c.full_orientation = true;
  c.prefers_pose = true;
  c.gripper = true;
  c.digital_outputs = 32;
  c.digital_inputs = 32;
  c.max_joint_speed = options_.max_joint_speed;
  c.max_tool_speed = options_.max_tool_speed;
  c.queue_depth = 2;
  c.reads_joints = true;
  c.reads_pose = true;
  c.reads_while_moving = false;
  c.read_time = read_time(options_.serial, where_request_bytes(options_), where_answer_bytes(options_));
  set_capabilities(std::move(c));
}

std::optional<val2::Location> Val2Driver::last_location() const {
  std::lock_guard lock(location_mutex_);
  return last_location_;
}

Val2Driver::~Val2Driver() {
  disconnect();
}

SerialDriver::Outcome Val2Driver::greet(Link& link) {
  return Session(link, options_, state_).resync(ErrorCode::connection_lost);
}

SerialDriver::Outcome Val2Driver::clear_error(Link& link) {
  return Session(link, options_, state_).resync(ErrorCode::protocol);
}

SerialDriver::Outcome Val2Driver::execute(Link& link, const JobCopy& job) {
  Session session(link, options_, state_);
  if (state_.owed_prompt) {
    const std::string next = job.kind == JobKind::home       ? std::string("home")
                             : job.kind == JobKind::position ? std::string("position")
                                                             : describe(*job.command);
    if (Outcome o = session.settle_owed(next); o.error != ErrorCode::none) return o;
  }
  switch (job.kind) {
    case JobKind::home:
      return session.home();
    case JobKind::position: {
      Outcome o = session.where();
      if (o.error == ErrorCode::none && state_.where_world) {
        std::lock_guard lock(location_mutex_);
        last_location_ = state_.where_world;
      }
      return o;
    }
    case JobKind::command:
      break;
  }
  return std::visit([&](const auto& command) { return session.run(command); }, *job.command);
}

}  // namespace cellwright::drivers
