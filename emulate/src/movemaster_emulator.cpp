// MovemasterEmulator (movemaster_emulator.hpp): lines from the LinePort, one misbehaviour decision each, parsed
// (movemaster/command.hpp) and run by the Executor (movemaster/executor.hpp).
#include "cellwright/emulate/movemaster_emulator.hpp"

#include <fmt/format.h>

#include <cmath>
#include <utility>

#include "cellwright/common/error.hpp"
#include "movemaster/command.hpp"
#include "movemaster/executor.hpp"
#include "movemaster/program.hpp"

namespace cellwright::emulate {

namespace {

constexpr std::size_t kMaxLine = 256;

// The bytes of a line as text for the log: printable ASCII as it is, anything else as \xNN.
std::string printable(std::string_view bytes) {
  std::string s;
  for (const char c : bytes) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      s.push_back(c);
    } else {
      s += fmt::format("\\x{:02x}", u);
    }
  }
  return s;
}

bool blank(std::string_view text) {
  return text.find_first_not_of(" \t") == std::string_view::npos;
}

}  // namespace

MovemasterEmulator::MovemasterEmulator(EmulatedArm& arm, MovemasterEmulatorOptions options)
    : arm_(arm),
      options_(std::move(options)),
      plan_(options_.misbehaviours, options_.seed),
      port_(kMaxLine, options_.pace) {
  const SourceLocation where{"<movemaster emulator>", 0, 0};
  if (options_.speed_level < 0 || options_.speed_level > 9) {
    throw InputError(where, fmt::format("speed level {} is not 0 to 9", options_.speed_level));
  }
  if (options_.reply_line_end != "\r\n" && options_.reply_line_end != "\n") {
    throw InputError(where, fmt::format("answers end with CR LF or LF, not '{}'", printable(options_.reply_line_end)));
  }
  if (!std::isfinite(options_.nominal_tool_length_mm)) {
    throw InputError(where, "the nominal tool length is not a number");
  }
  if (options_.reconnect_delay.count() < 0) throw InputError(where, "the reconnect delay is negative");
  if (options_.pitch_down_deg != -90 && options_.pitch_down_deg != 90) {
    throw InputError(where, fmt::format("pitch_down {} is neither -90 nor 90", options_.pitch_down_deg));
  }
  if (options_.roll_sense != 1 && options_.roll_sense != -1) {
    throw InputError(where, fmt::format("roll_sense {} is neither 1 nor -1", options_.roll_sense));
  }
  executor_ = std::make_unique<movemaster::Executor>(
      arm_, options_.nominal_tool_length_mm, options_.speed_level,
      movemaster::Conventions{options_.world, options_.tool, options_.pitch_down_deg > 0, options_.roll_sense < 0});
  program_ = std::make_unique<movemaster::Program>();
}

MovemasterEmulator::~MovemasterEmulator() = default;

void MovemasterEmulator::serve(const std::filesystem::path& link) {
  if (port_.stopped()) return;
  port_.publish(link);
  log(fmt::format("serving {} ({})", link.string(), port_.slave_path()));
  while (const std::optional<ReceivedLine> line = port_.next_line()) {
    if (!serve_line(*line, link)) break;
  }
  port_.hang_up();
}

bool MovemasterEmulator::serve_line(const ReceivedLine& line, const std::filesystem::path& link) {
  using movemaster::Executor;
  if (blank(line.text) && !line.overlong) return true;
  const std::optional<Misbehaviour> m = plan_.next_line(line.text);
  tally([&](Stats& s) {
    ++s.lines;
    if (m) ++s.misbehaviours[static_cast<std::size_t>(m->kind)];
  });
  if (options_.log) {
    log(fmt::format("< {}{}", printable(line.text), line.overlong ? "... (overlong)" : ""));
    if (m) log(fmt::format("misbehaving on line {}: {}", plan_.lines(), to_string(m->kind)));
  }
  const MisbehaviourKind kind = m ? m->kind : MisbehaviourKind::error;
  if (m && kind == MisbehaviourKind::drop) {
    port_.hang_up();
    if (!port_.wait(options_.reconnect_delay)) return false;
    port_.publish(link);
    log(fmt::format("serving {} again ({})", link.string(), port_.slave_path()));
    return true;
  }
  if (m && kind == MisbehaviourKind::silent) return true;

  if (!line.overlong && movemaster::Program::is_program_line(line.text)) return store_line(line.text, m);

  const movemaster::Parsed parsed =
      line.overlong ? movemaster::Parsed{std::nullopt, fmt::format("longer than {} bytes", kMaxLine)}
                    : movemaster::parse_command(line.text);
  const bool refused = m && (kind == MisbehaviourKind::error || kind == MisbehaviourKind::unreachable ||
                             kind == MisbehaviourKind::unknown);
  if (refused) {
    executor_->raise(kind == MisbehaviourKind::error     ? movemaster::kHardwareError
                     : kind == MisbehaviourKind::unknown ? movemaster::kUnlistedError
                                                         : movemaster::kPositionError);
  }
  movemaster::Executed done;
  if (!parsed.command) {
    executor_->raise(movemaster::kPositionError);
    tally([](Stats& s) { ++s.format_errors; });
    log(fmt::format("format error: {}", parsed.error));
  } else if (!refused || Executor::is_query(parsed.command->op)) {
    done = movemaster::Program::handles(parsed.command->op)
               ? program_->direct(*parsed.command, *executor_, arm_, options_.on_program_line)
               : executor_->execute(*parsed.command);
    if (done.interrupted) return false;
    const bool er = parsed.command->op == movemaster::Op::ER;
    tally([&](Stats& s) {
      if (!done.ignored) ++s.executed;
      if (er && done.reply && done.reply->front() >= '0' && done.reply->front() <= '2') {
        ++s.er_answers[static_cast<std::size_t>(done.reply->front() - '0')];
      }
    });
    if (done.ignored) log("ignored: halted by a hardware error until RS");
    if (!done.error.empty()) log(fmt::format("error {}: {}", executor_->error(), done.error));
  }
  if (m && kind == MisbehaviourKind::late && !port_.wait(m->delay)) return false;
  const bool garble = m && kind == MisbehaviourKind::garbage;
  if (done.reply) {
    const bool garbled = garble || garble_next_answer_;
    garble_next_answer_ = false;
    return answer(std::move(*done.reply), garbled);
  }
  if (garble) garble_next_answer_ = true;
  return true;
}

bool MovemasterEmulator::store_line(std::string_view text, const std::optional<Misbehaviour>& m) {
  const MisbehaviourKind kind = m ? m->kind : MisbehaviourKind::error;
  if (m && (kind == MisbehaviourKind::error || kind == MisbehaviourKind::unreachable ||
            kind == MisbehaviourKind::unknown)) {
    executor_->raise(kind == MisbehaviourKind::error     ? movemaster::kHardwareError
                     : kind == MisbehaviourKind::unknown ? movemaster::kUnlistedError
                                                         : movemaster::kPositionError);
  } else if (const std::optional<std::string> why = program_->store(text)) {
    executor_->raise(movemaster::kPositionError);
    tally([](Stats& s) { ++s.format_errors; });
    log(fmt::format("format error: {}", *why));
  }
  if (m && kind == MisbehaviourKind::late && !port_.wait(m->delay)) return false;
  if (m && kind == MisbehaviourKind::garbage) garble_next_answer_ = true;
  return true;
}

bool MovemasterEmulator::answer(std::string text, bool garble) {
  if (garble) text = kGarbage;
  log(fmt::format("> {}", printable(text)));
  text += options_.reply_line_end;
  return port_.write(text);
}

void MovemasterEmulator::log(std::string_view text) const {
  if (options_.log) options_.log(text);
}

void MovemasterEmulator::stop() {
  port_.stop();
  arm_.interrupt();
}

bool MovemasterEmulator::wait_published(std::uint64_t count, std::chrono::nanoseconds timeout) const {
  return port_.wait_published(count, timeout);
}

MovemasterEmulator::Stats MovemasterEmulator::stats() const {
  Stats s;
  {
    std::lock_guard lock(stats_mutex_);
    s = stats_;
  }
  s.publications = port_.publications();
  return s;
}

}  // namespace cellwright::emulate
