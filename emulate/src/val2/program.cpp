// VAL II's stored programs and locations (program.hpp).
#include "val2/program.hpp"

#include <fmt/format.h>

#include <cctype>
#include <charconv>
#include <cmath>

namespace cellwright::emulate::val2 {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string upper(std::string_view s) {
  std::string u(s);
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return u;
}

// Splits at spaces and tabs.
std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  for (;;) {
    s = trim(s);
    if (s.empty()) return out;
    const std::size_t end = s.find_first_of(" \t");
    out.push_back(s.substr(0, end));
    if (end == std::string_view::npos) return out;
    s.remove_prefix(end);
  }
}

// A location or program name: a letter, then letters, digits, '.' and '_'.
bool is_name(std::string_view s) {
  if (s.empty() || !std::isalpha(static_cast<unsigned char>(s.front()))) return false;
  for (const char c : s) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_') return false;
  }
  return true;
}

bool number(std::string_view s, double& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() && std::isfinite(v);
}

Outcome print(std::string line) {
  Outcome o;
  o.lines.push_back(std::move(line));
  return o;
}

}  // namespace

std::optional<Outcome> Programs::take(std::string_view line, Executor& executor,
                                      const std::function<void(int)>& on_step) {
  const std::string_view text = trim(line);
  const std::vector<std::string_view> w = words(text);
  const std::string first = w.empty() ? std::string() : upper(w[0]);
  if (mode_ != Mode::monitor && first == ".END") {
    const Mode was = mode_;
    mode_ = Mode::monitor;
    if (was == Mode::program) {
      if (defining_failed_) return print("*Program not stored*");
      programs_[defining_] = std::move(steps_);
    }
    return Outcome{};
  }
  if (mode_ == Mode::program) {
    if (const std::optional<std::string> error = define_step(text)) {
      defining_failed_ = true;
      return print(*error);
    }
    return Outcome{};
  }
  if (mode_ == Mode::locations) {
    std::array<double, 6> v{};
    bool ok = w.size() == 7 && is_name(w[0]);
    for (std::size_t i = 0; ok && i < 6; ++i) ok = number(w[i + 1], v[i]);
    if (!ok) return print(std::string(kInvalidArgument));
    locations_[upper(w[0])] = v;
    return Outcome{};
  }
  if (first == ".PROGRAM" || first == ".LOCATIONS") {
    if (first == ".LOCATIONS") {
      if (w.size() != 1) return print(std::string(kSyntaxError));
      mode_ = Mode::locations;
      return Outcome{};
    }
    if (w.size() != 2 || !is_name(w[1])) return print(std::string(kSyntaxError));
    mode_ = Mode::program;
    defining_ = upper(w[1]);
    steps_.clear();
    defining_failed_ = false;
    return Outcome{};
  }
  // EXECUTE and its abbreviations (EX, EXE, ...: E alone is also EDIT's).
  if (first.size() >= 2 && std::string_view("EXECUTE").starts_with(first)) {
    if (w.size() != 2 || !is_name(w[1])) return print(std::string(kInvalidArgument));
    return run(upper(w[1]), executor, on_step);
  }
  return std::nullopt;
}

std::optional<std::string> Programs::define_step(std::string_view text) {
  Step step;
  step.text = std::string(text);
  if (text.empty() || text.front() == ';') {
    step.comment = true;
    steps_.push_back(std::move(step));
    return std::nullopt;
  }
  const std::vector<std::string_view> w = words(text);
  const std::string first = upper(w[0]);
  if ((first == "MOVE" || first == "MOVES") && w.size() == 2 && is_name(w[1]) && upper(w[1]) != "TRANS" &&
      text.find('(') == std::string_view::npos) {
    step.instruction.op = first == "MOVE" ? Op::move : Op::moves;
    step.location_name = upper(w[1]);
    steps_.push_back(std::move(step));
    return std::nullopt;
  }
  Parsed parsed = parse_instruction(text);
  if (!parsed.ok()) return parsed.error;
  step.instruction = std::move(parsed.instruction);
  steps_.push_back(std::move(step));
  return std::nullopt;
}

Outcome Programs::run(const std::string& name, Executor& executor, const std::function<void(int)>& on_step) {
  const auto it = programs_.find(name);
  if (it == programs_.end()) return print("*Undefined program*");
  const std::vector<Step>& steps = it->second;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const int number = static_cast<int>(i) + 1;
    if (on_step) on_step(number);
    const Step& step = steps[i];
    if (step.comment) continue;
    Instruction in = step.instruction;
    if (!step.location_name.empty()) {
      const auto loc = locations_.find(step.location_name);
      if (loc == locations_.end()) {
        Outcome o = print("*Undefined location*");
        o.lines.push_back(fmt::format("Program stopped at step {}", number));
        return o;
      }
      in.location.kind = Location::Kind::trans;
      in.location.values = loc->second;
    }
    Outcome out = executor.execute(in);
    if (out.interrupted) return out;
    for (const std::string& l : out.lines) {
      if (l.starts_with('*')) {
        out.lines.push_back(fmt::format("Program stopped at step {}", number));
        return out;
      }
    }
  }
  return print("Program completed");
}

}  // namespace cellwright::emulate::val2
