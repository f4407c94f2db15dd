// Fault specifications (faults.hpp; docs/faults.md, docs/scenarios.md).
#include "cellwright/twin/faults.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cellwright::twin {

namespace {

using models::yaml::describe;
using models::yaml::Doc;
using models::yaml::Fields;

constexpr std::array<std::string_view, kFaultKinds> kKindNames = {
    "drop",    "slip",     "misplace", "unreachable", "missing",     "obstacle",   "timeout",
    "garbage", "hardware", "position", "link_lost",   "lost_signal", "frame_lost", "detection_noise"};

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const std::string& s : v) out += fmt::format("{}{}", out.empty() ? "" : ", ", s);
  return out.empty() ? std::string("none") : out;
}

template <typename T>
std::vector<std::string> names_of(const std::vector<T>& items) {
  std::vector<std::string> out;
  for (const auto& i : items) out.push_back(i.name);
  return out;
}

// A whole number >= 1.
std::uint64_t count_of(const Doc& doc, const YAML::Node& n, const std::string& field) {
  std::uint64_t v = 0;
  if (!n.IsScalar() || n.Scalar().starts_with("-") || !YAML::convert<std::uint64_t>::decode(n, v) || v == 0) {
    doc.fail(n, fmt::format("{} must be a whole number from 1 up, got {}", field, describe(n)));
  }
  return v;
}

}  // namespace

std::string_view to_string(FaultKind kind) {
  return kKindNames.at(static_cast<std::size_t>(kind));
}

std::optional<FaultKind> fault_kind(std::string_view name) {
  for (std::size_t i = 0; i < kKindNames.size(); ++i) {
    if (kKindNames[i] == name) return static_cast<FaultKind>(i);
  }
  return std::nullopt;
}

std::string fault_kind_names() {
  std::string out;
  for (std::string_view k : kKindNames) out += fmt::format("{}{}", out.empty() ? "" : ", ", k);
  return out;
}

std::string_view to_string(FaultCommand command) {
  return command == FaultCommand::move ? "move" : "grip";
}

FaultTarget target_of(FaultKind kind) {
  switch (kind) {
    case FaultKind::misplace:
    case FaultKind::unreachable:
    case FaultKind::missing:
      return FaultTarget::workpiece;
    case FaultKind::lost_signal:
    case FaultKind::frame_lost:
    case FaultKind::detection_noise:
      return FaultTarget::none;
    default:
      return FaultTarget::robot;
  }
}

bool is_driver_fault(FaultKind kind) {
  return kind == FaultKind::timeout || kind == FaultKind::garbage || kind == FaultKind::hardware ||
         kind == FaultKind::position || kind == FaultKind::link_lost;
}

bool needs_vision(FaultKind kind) {
  return kind == FaultKind::frame_lost || kind == FaultKind::detection_noise;
}

FaultSpec FaultSpec::defaults(FaultKind kind) {
  FaultSpec f;
  f.kind = kind;
  if (kind == FaultKind::unreachable) f.distance = 0.6;
  if (kind == FaultKind::detection_noise) f.duration = 4;
  return f;
}

bool FaultSpec::operator==(const FaultSpec& o) const {
  return kind == o.kind && robot == o.robot && workpiece == o.workpiece && carry == o.carry && every == o.every &&
         after == o.after &&
         distance == o.distance && offset == o.offset && yaw == o.yaw && size == o.size && ahead == o.ahead &&
         duration == o.duration && time == o.time && command == o.command && n == o.n && count == o.count &&
         sigma == o.sigma && sigma_yaw == o.sigma_yaw;
}

const std::vector<std::string>& fault_fields(FaultKind kind) {
  static const std::array<std::vector<std::string>, kFaultKinds> fields = [] {
    std::array<std::vector<std::string>, kFaultKinds> f;
    const std::vector<std::string> driver{"robot", "command", "n"};
    f[static_cast<std::size_t>(FaultKind::drop)] = {"robot", "carry", "every", "after"};
    f[static_cast<std::size_t>(FaultKind::slip)] = {"robot", "carry", "every", "after", "distance"};
    f[static_cast<std::size_t>(FaultKind::misplace)] = {"workpiece", "offset", "yaw"};
    f[static_cast<std::size_t>(FaultKind::unreachable)] = {"workpiece", "distance"};
    f[static_cast<std::size_t>(FaultKind::missing)] = {"workpiece"};
    f[static_cast<std::size_t>(FaultKind::obstacle)] = {"robot", "time", "size", "ahead", "duration"};
    for (FaultKind k : {FaultKind::timeout, FaultKind::garbage, FaultKind::hardware, FaultKind::position,
                        FaultKind::link_lost}) {
      f[static_cast<std::size_t>(k)] = driver;
    }
    f[static_cast<std::size_t>(FaultKind::lost_signal)] = {"n"};
    f[static_cast<std::size_t>(FaultKind::frame_lost)] = {"time", "count"};
    f[static_cast<std::size_t>(FaultKind::detection_noise)] = {"time", "duration", "sigma", "sigma_yaw"};
    return f;
  }();
  return fields.at(static_cast<std::size_t>(kind));
}

FaultSpec parse_fault(const Doc& doc, const YAML::Node& entry, const models::CellDescription& cell) {
  if (!entry.IsMap()) {
    doc.fail(entry, fmt::format("a fault must be a mapping of fields with a 'kind', got {}", describe(entry)));
  }
  // The kind first: it decides which fields the entry may have.
  const YAML::Node kind_node = entry["kind"];
  if (!kind_node.IsDefined()) doc.fail(entry, "a fault has no field 'kind' (it is required)");
  if (!kind_node.IsScalar()) {
    doc.fail(kind_node, fmt::format("field 'kind' of a fault must be a word, got {}", describe(kind_node)));
  }
  const std::optional<FaultKind> kind = fault_kind(kind_node.Scalar());
  if (!kind) {
    doc.fail(kind_node, fmt::format("field 'kind' of a fault must be one of {}, got '{}'", fault_kind_names(),
                                    kind_node.Scalar()));
  }
  const std::vector<std::string>& takes = fault_fields(*kind);
  const std::string what = fmt::format("the {} fault", to_string(*kind));
  for (const auto& kv : entry) {
    if (!kv.first.IsScalar()) doc.fail(kv.first, fmt::format("{}: field names must be plain words", what));
    const std::string& key = kv.first.Scalar();
    if (key != "kind" && std::find(takes.begin(), takes.end(), key) == takes.end()) {
      doc.fail(kv.first, fmt::format("unknown field '{}' in {} (a {} fault takes: kind, {})", key, what,
                                     to_string(*kind), join(takes)));
    }
  }
  // Every field of every kind: the check above has already refused those this kind does not take.
  const Fields f(doc, entry, what,
                 {"kind", "robot", "workpiece", "carry", "every", "after", "distance", "offset", "yaw", "size", "ahead",
                  "duration", "time", "command", "n", "count", "sigma", "sigma_yaw"});
  FaultSpec s = FaultSpec::defaults(*kind);
  s.where = doc.at(entry);

  switch (target_of(*kind)) {
    case FaultTarget::robot:
      s.robot = f.word("robot");
      if (cell.find_robot(s.robot) == nullptr) {
        doc.fail(f.node("robot"), fmt::format("{} names robot '{}', which is not a robot of the cell (robots: {})",
                                              f.field("robot"), s.robot, join(names_of(cell.robots))));
      }
      break;
    case FaultTarget::workpiece:
      s.workpiece = f.word("workpiece");
      if (cell.find_workpiece(s.workpiece) == nullptr) {
        doc.fail(f.node("workpiece"),
                 fmt::format("{} names workpiece '{}', which is not a workpiece of the cell (workpieces: {})",
                             f.field("workpiece"), s.workpiece, join(names_of(cell.workpieces))));
      }
      break;
    case FaultTarget::none:
      break;
  }
  const auto count = [&](const char* key, std::uint64_t fallback) {
    return f.has(key) ? count_of(doc, f.node(key), f.field(key)) : fallback;
  };
  s.carry = count("carry", s.carry);
  s.every = count("every", s.every);
  s.n = count("n", s.n);
  s.count = count("count", s.count);
  // Bounds as the scenario's (docs/scenarios.md): times up to 1e6 s, lengths up to 2 m.
  using models::yaml::Range;
  s.after = f.within_or("after", s.after, Range{0, 1e6, false, "s"});
  s.time = f.within_or("time", s.time, Range{0, 1e6, false, "s"});
  s.distance = f.within_or("distance", s.distance, Range{0, 2, true, "m"});
  s.size = f.within_or("size", s.size, Range{0, 2, true, "m"});
  s.ahead = f.within_or("ahead", s.ahead, Range{0, 2, true, "m"});
  s.duration = f.within_or("duration", s.duration, Range{0, 1e6, true, "s"});
  s.sigma = f.within_or("sigma", s.sigma, Range{0, 2, false, "m"});
  s.sigma_yaw = f.within_or("sigma_yaw", s.sigma_yaw, Range{0, 180, false, "degrees"});
  if (f.has("yaw")) {
    s.yaw = f.number("yaw");
    if (s.yaw < 0 || s.yaw > 180) {
      doc.fail(f.node("yaw"), fmt::format("{} must be from 0 to 180 (degrees), got {}", f.field("yaw"), s.yaw));
    }
  }
  if (f.has("offset")) {
    const std::vector<double> v = f.numbers("offset", 2);
    for (std::size_t i = 0; i < 2; ++i) {
      if (v[i] < 0 || v[i] > 0.5) {
        doc.fail(f.node("offset"), fmt::format("{} must hold 2 numbers from 0 to 0.5 (m), got {}", f.field("offset"),
                                               v[i]));
      }
      s.offset[i] = v[i];
    }
  }
  if (s.kind == FaultKind::slip && s.distance > 0.03) {
    doc.fail(f.node("distance"), fmt::format("{} must be at most 0.03 m: a part that slides further is no longer "
                                             "held (use a drop), got {}",
                                             f.field("distance"), s.distance));
  }
  if (s.kind == FaultKind::obstacle && s.size > 0.5) {
    doc.fail(f.node("size"), fmt::format("{} must be at most 0.5 m, got {}", f.field("size"), s.size));
  }
  if (f.has("command")) {
    const std::string c = f.word("command");
    if (c == "move") {
      s.command = FaultCommand::move;
    } else if (c == "grip") {
      s.command = FaultCommand::grip;
    } else {
      doc.fail(f.node("command"), fmt::format("{} must be move or grip, got '{}'", f.field("command"), c));
    }
  }
  return s;
}

FaultSpec parse_fault_text(std::string_view text, const models::CellDescription& cell, std::string_view option) {
  const std::string spec(text);
  const SourceLocation where{std::string(option), 0, 0};
  const auto fail = [&](const std::string& problem) -> FaultSpec {
    throw InputError(where, fmt::format("'{}': {} (write KIND:key=value,key=value with a list as a/b, e.g. "
                                        "drop:robot=puma,carry=1)",
                                        spec, problem));
  };
  const std::size_t colon = spec.find(':');
  // The same fields as a YAML entry, read by the same reader: one set of checks and defaults.
  YAML::Node entry(YAML::NodeType::Map);
  entry["kind"] = spec.substr(0, colon);
  const std::string rest = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
  const YAML::Node& given = entry;
  for (std::size_t start = 0; !rest.empty();) {
    const std::size_t comma = rest.find(',', start);
    const std::string item = rest.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      return fail(item.empty() ? std::string("an empty key=value") : fmt::format("'{}' is not key=value", item));
    }
    const std::string key = item.substr(0, eq);
    const std::string value = item.substr(eq + 1);
    if (given[key].IsDefined()) return fail(fmt::format("'{}' is given twice", key));
    if (value.find('/') != std::string::npos) {
      YAML::Node list(YAML::NodeType::Sequence);
      for (std::size_t from = 0;;) {
        const std::size_t slash = value.find('/', from);
        list.push_back(value.substr(from, slash == std::string::npos ? std::string::npos : slash - from));
        if (slash == std::string::npos) break;
        from = slash + 1;
      }
      entry[key] = list;
    } else {
      entry[key] = value;
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  const Doc doc(std::string(option), models::yaml::MissingField::kSayRequired);
  try {
    FaultSpec s = parse_fault(doc, entry, cell);
    s.where = where;
    return s;
  } catch (const InputError& e) {
    return fail(e.problem());
  }
}

std::string to_text(const FaultSpec& f) {
  std::string out(to_string(f.kind));
  char sep = ':';
  const auto add = [&](const std::string& key, const std::string& value) {
    out += fmt::format("{}{}={}", sep, key, value);
    sep = ',';
  };
  for (const std::string& key : fault_fields(f.kind)) {
    if (key == "robot") add(key, f.robot);
    if (key == "workpiece") add(key, f.workpiece);
    if (key == "carry") add(key, fmt::format("{}", f.carry));
    if (key == "every" && f.every > 0) add(key, fmt::format("{}", f.every));  // absent: once only
    if (key == "after") add(key, fmt::format("{}", f.after));
    if (key == "distance") add(key, fmt::format("{}", f.distance));
    if (key == "offset") add(key, fmt::format("{}/{}", f.offset[0], f.offset[1]));
    if (key == "yaw") add(key, fmt::format("{}", f.yaw));
    if (key == "size") add(key, fmt::format("{}", f.size));
    if (key == "ahead") add(key, fmt::format("{}", f.ahead));
    if (key == "duration") add(key, fmt::format("{}", f.duration));
    if (key == "time") add(key, fmt::format("{}", f.time));
    if (key == "command") add(key, std::string(to_string(f.command)));
    if (key == "n") add(key, fmt::format("{}", f.n));
    if (key == "count") add(key, fmt::format("{}", f.count));
    if (key == "sigma") add(key, fmt::format("{}", f.sigma));
    if (key == "sigma_yaw") add(key, fmt::format("{}", f.sigma_yaw));
  }
  return out;
}

}  // namespace cellwright::twin
