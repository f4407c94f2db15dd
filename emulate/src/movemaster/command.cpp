// Movemaster EX command lines (command.hpp).
#include "movemaster/command.hpp"

#include <fmt/format.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <utility>
#include <vector>

namespace cellwright::emulate::movemaster {

namespace {

struct Mnemonic {
  const char* name;
  Op op;
};

constexpr Mnemonic kMnemonics[] = {
    {"NT", Op::NT}, {"MP", Op::MP}, {"PD", Op::PD}, {"MS", Op::MS}, {"GO", Op::GO}, {"GC", Op::GC}, {"GP", Op::GP},
    {"SP", Op::SP}, {"TL", Op::TL}, {"WH", Op::WH}, {"ER", Op::ER}, {"RS", Op::RS}, {"MO", Op::MO}, {"OB", Op::OB},
    {"TB", Op::TB}, {"GT", Op::GT}, {"ED", Op::ED}, {"RN", Op::RN}, {"NW", Op::NW},
};

bool is_space(char c) {
  return c == ' ' || c == '\t';
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// A field failed: the message says which and why.
struct Failure {
  std::string why;
};

// [+|-] digits [. digits] or [+|-] . digits; nothing else (no exponent, no inf or nan).
double number(std::string_view field, const char* what) {
  std::string_view s = field;
  bool negative = false;
  if (!s.empty() && (s.front() == '+' || s.front() == '-')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  int digits = 0, points = 0;
  for (const char c : s) {
    if (std::isdigit(static_cast<unsigned char>(c))) {
      ++digits;
    } else if (c == '.') {
      ++points;
    } else {
      digits = -1000;  // not a number
      break;
    }
  }
  double v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (digits <= 0 || points > 1 || ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(v)) {
    throw Failure{fmt::format("{} '{}' is not a number", what, field)};
  }
  return negative ? -v : v;
}

int whole(std::string_view field, const char* what, int lowest, int highest) {
  const double v = number(field, what);
  if (v != std::floor(v) || v < lowest || v > highest) {
    throw Failure{fmt::format("{} '{}' is not a whole number from {} to {}", what, field, lowest, highest)};
  }
  return static_cast<int>(v);
}

// One letter of `allowed` (either case), upper-cased.
char letter(std::string_view field, const char* what, std::string_view allowed) {
  if (field.size() == 1) {
    const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(field.front())));
    if (allowed.find(c) != std::string_view::npos) return c;
  }
  throw Failure{fmt::format("{} '{}' is not one of the letters {}", what, field, allowed)};
}

// OB's and TB's bit: ±1–16; a bit without a sign is +.
int bit(std::string_view field) {
  const int v = whole(field, "bit", -kLastBit, kLastBit);
  if (v == 0) throw Failure{fmt::format("bit '{}' is not from 1 to {}, signed", field, kLastBit)};
  return v;
}

Pose5 pose(const std::vector<std::string_view>& f, std::size_t first) {
  return {number(f[first], "x"), number(f[first + 1], "y"), number(f[first + 2], "z"), number(f[first + 3], "pitch"),
          number(f[first + 4], "roll")};
}

}  // namespace

Parsed parse_command(std::string_view line) {
  std::string_view s = trim(line);
  std::string name;
  while (!s.empty() && std::isalpha(static_cast<unsigned char>(s.front()))) {
    name.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(s.front()))));
    s.remove_prefix(1);
  }
  Command c;
  bool known = false;
  for (const Mnemonic& m : kMnemonics) {
    if (name == m.name) {
      c.op = m.op;
      known = true;
    }
  }
  if (!known) return {std::nullopt, fmt::format("unknown command '{}'", name)};

  // The fields: comma-separated, each trimmed; no arguments at all is no fields.
  std::vector<std::string_view> f;
  s = trim(s);
  if (!s.empty()) {
    for (;;) {
      const std::size_t comma = s.find(',');
      f.push_back(trim(s.substr(0, comma)));
      if (comma == std::string_view::npos) break;
      s.remove_prefix(comma + 1);
    }
  }
  const auto count = [&](std::size_t lowest, std::size_t highest) {
    if (f.size() < lowest || f.size() > highest) {
      throw Failure{lowest == highest
                        ? fmt::format("{} takes {} value(s), not {}", name, lowest, f.size())
                        : fmt::format("{} takes {} to {} values, not {}", name, lowest, highest, f.size())};
    }
  };
  try {
    switch (c.op) {
      case Op::NT:
      case Op::GO:
      case Op::GC:
      case Op::WH:
      case Op::ER:
      case Op::RS:
      case Op::ED:
      case Op::NW:
        count(0, 0);
        break;
      case Op::MO:
        count(1, 2);
        c.position = whole(f[0], "position", kFirstPosition, kLastPosition);
        if (f.size() == 2) c.open = letter(f[1], "gripper", "OC") == 'O';
        break;
      case Op::OB:
        count(1, 1);
        c.bit = bit(f[0]);
        break;
      case Op::TB:
        count(2, 2);
        c.bit = bit(f[0]);
        c.line = whole(f[1], "line", kFirstLine, kLastLine);
        break;
      case Op::GT:
        count(1, 1);
        c.line = whole(f[0], "line", kFirstLine, kLastLine);
        break;
      case Op::RN:
        count(0, 1);
        if (f.size() == 1) c.line = whole(f[0], "line", kFirstLine, kLastLine);
        break;
      case Op::MP:
        count(5, 5);
        c.pose = pose(f, 0);
        break;
      case Op::PD:
        count(6, 6);
        c.position = whole(f[0], "position", kFirstPosition, kLastPosition);
        c.pose = pose(f, 1);
        break;
      case Op::MS:
        count(2, 3);
        c.position = whole(f[0], "position", kFirstPosition, kLastPosition);
        c.points = whole(f[1], "intermediate points", 0, 99);
        if (f.size() == 3) c.open = letter(f[2], "gripper", "OC") == 'O';
        break;
      case Op::GP:
        count(3, 3);
        c.grip = {whole(f[0], "starting force", 0, 15), whole(f[1], "retained force", 0, 15),
                  whole(f[2], "starting time", 0, 99)};
        break;
      case Op::SP:
        count(1, 2);
        c.level = whole(f[0], "speed", 0, 9);
        if (f.size() == 2) c.high = letter(f[1], "acceleration", "HL") == 'H';
        break;
      case Op::TL:
        count(1, 1);
        c.tool_length = number(f[0], "tool length");
        if (c.tool_length < 0 || c.tool_length > 300) {
          throw Failure{fmt::format("tool length '{}' is not from 0 to 300 mm", f[0])};
        }
        break;
    }
  } catch (const Failure& failure) {
    return {std::nullopt, failure.why};
  }
  return {std::move(c), {}};
}

}  // namespace cellwright::emulate::movemaster
