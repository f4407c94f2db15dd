// Misbehaviour specs and the seeded plan (misbehaviour.hpp).
#include "cellwright/emulate/misbehaviour.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

#include "cellwright/common/error.hpp"

namespace cellwright::emulate {

namespace {

struct KindName {
  const char* name;
  MisbehaviourKind kind;
};

constexpr KindName kKinds[] = {
    {"error", MisbehaviourKind::error},
    {"er1", MisbehaviourKind::error},
    {"unreachable", MisbehaviourKind::unreachable},
    {"er2", MisbehaviourKind::unreachable},
    {"garbage", MisbehaviourKind::garbage},
    {"silent", MisbehaviourKind::silent},
    {"drop", MisbehaviourKind::drop},
    {"late", MisbehaviourKind::late},
    {"unknown", MisbehaviourKind::unknown},
};

// Upper case, blanks left out: how a line and a misbehaviour's command are compared.
std::string normalised(std::string_view text) {
  std::string out;
  for (const char c : text) {
    if (c == ' ' || c == '\t') continue;
    out += (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c;
  }
  return out;
}

bool parse_number(const std::string& text, double* out) {
  if (text.empty()) return false;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, *out);
  return ec == std::errc() && ptr == end && std::isfinite(*out);
}

}  // namespace

const char* to_string(MisbehaviourKind kind) {
  for (const KindName& k : kKinds) {
    if (k.kind == kind) return k.name;
  }
  return "?";
}

Misbehaviour parse_misbehaviour(const std::string& spec, const std::string& option) {
  const SourceLocation where{option, 0, 0};
  const auto bad = [&](const std::string& why) {
    return InputError(where, fmt::format("'{}': {} (write KIND@LINE, KIND@COMMAND#N or KIND~PROBABILITY, and "
                                         "late@LINE:SECONDS; KIND is error, er1, unreachable, er2, garbage, silent, "
                                         "drop, late or unknown)",
                                         spec, why));
  };
  const std::size_t sep = spec.find_first_of("@~");
  if (sep == std::string::npos) throw bad("no @ or ~");
  const std::string name = spec.substr(0, sep);
  Misbehaviour m;
  bool known = false;
  for (const KindName& k : kKinds) {
    if (name == k.name) {
      m.kind = k.kind;
      known = true;
    }
  }
  if (!known) throw bad(fmt::format("unknown kind '{}'", name));
  std::string rest = spec.substr(sep + 1);
  const std::size_t colon = rest.find(':');
  if (m.kind == MisbehaviourKind::late) {
    if (colon == std::string::npos) throw bad("late needs a delay, e.g. late@4:1.5");
    double s = 0;
    if (!parse_number(rest.substr(colon + 1), &s) || s <= 0 || s > 3600) {
      throw bad(fmt::format("the delay '{}' is not a number of seconds in (0, 3600]", rest.substr(colon + 1)));
    }
    m.delay = std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(s * 1e9)));
    rest = rest.substr(0, colon);
  } else if (colon != std::string::npos) {
    throw bad("only late takes a delay");
  }
  if (const std::size_t hash = rest.find('#'); spec[sep] == '@' && hash != std::string::npos) {
    m.command = normalised(rest.substr(0, hash));
    if (m.command.empty()) throw bad("no command before #");
    for (const char c : m.command) {
      if (c < 0x21 || c > 0x7e || c == '@' || c == '~' || c == '#') {
        throw bad(fmt::format("the command '{}' is not printable text", rest.substr(0, hash)));
      }
    }
    rest = rest.substr(hash + 1);
  }
  double v = 0;
  if (!parse_number(rest, &v)) throw bad(fmt::format("'{}' is not a number", rest));
  if (spec[sep] == '@') {
    if (v < 1 || v != std::floor(v) || v > 1e15) throw bad(fmt::format("line {} is not a whole number >= 1", rest));
    m.at_line = static_cast<std::uint64_t>(v);
  } else {
    if (!(v > 0 && v <= 1)) throw bad(fmt::format("the probability {} is not in (0, 1]", rest));
    m.probability = v;
  }
  return m;
}

std::string to_string(const Misbehaviour& m) {
  std::string s = m.at_line == 0      ? fmt::format("{}~{:.6f}", to_string(m.kind), m.probability)
                  : m.command.empty() ? fmt::format("{}@{}", to_string(m.kind), m.at_line)
                                      : fmt::format("{}@{}#{}", to_string(m.kind), m.command, m.at_line);
  if (m.kind == MisbehaviourKind::late) {
    s += fmt::format(":{:.6f}", std::chrono::duration<double>(m.delay).count());
  }
  return s;
}

MisbehaviourPlan::MisbehaviourPlan(std::vector<Misbehaviour> list, std::uint64_t seed)
    : list_(std::move(list)), matched_(list_.size(), 0), applied_(list_.size(), false), random_(seed) {}

std::optional<Misbehaviour> MisbehaviourPlan::next_line(std::string_view text) {
  ++lines_;
  const std::string line = normalised(text);
  std::optional<std::size_t> fixed, random;
  for (std::size_t i = 0; i < list_.size(); ++i) {
    const Misbehaviour& m = list_[i];
    if (m.at_line > 0 && !m.command.empty()) {
      // Armed once the entry before it has applied; counts the lines that start with its command.
      if ((i == 0 || applied_[i - 1]) && line.starts_with(m.command) && ++matched_[i] == m.at_line && !fixed) {
        fixed = i;
      }
      continue;
    }
    if (m.at_line > 0) {
      if (m.at_line == lines_ && !fixed) fixed = i;
      continue;
    }
    // One draw per random entry per line, whether or not an earlier entry already applies.
    // 53 random bits as a double in [0, 1): the same on every standard library (distributions are not).
    const double u = static_cast<double>(random_() >> 11) * 0x1.0p-53;
    if (u < m.probability && !random) random = i;
  }
  const std::optional<std::size_t> chosen = fixed ? fixed : random;
  if (!chosen) return std::nullopt;
  applied_[*chosen] = true;
  return list_[*chosen];
}

}  // namespace cellwright::emulate
