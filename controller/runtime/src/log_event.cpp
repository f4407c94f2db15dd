// The events' one JSON Lines codec (log_event.hpp). Each type lists its keys once (fields() below); the writer and
// the reader both walk that list, so what is written and what is read back cannot disagree.
#include "cellwright/runtime/log_event.hpp"

#include <fmt/format.h>

#include <cmath>
#include <concepts>
#include <istream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <type_traits>
#include <utility>

#include "cellwright/common/error.hpp"

namespace cellwright::runtime {

std::string format_sim_time(SimDuration t) {
  // Integer rounding on the nanosecond count: a double would print 0.00005 s differently depending on its bits.
  const std::int64_t ns = t.count();
  const std::int64_t magnitude = ns < 0 ? -ns : ns;
  const std::int64_t ticks = (magnitude + 50'000) / 100'000;  // units of 0.1 ms, rounded half away from zero
  return fmt::format("{}{}.{:04}", ns < 0 && ticks != 0 ? "-" : "", ticks / 10'000, ticks % 10'000);
}

namespace {

using nlohmann::json;

// --- How a field is written: wrappers for the numbers whose form the type alone does not fix ------------------------

// A length or ratio with `decimals` decimals. V is double or const double (writing and reading share the lists).
template <class V>
struct Fixed {
  V& value;
  int decimals;
};
// An angle kept in radians, written in degrees; null when absent.
template <class V>
struct Degrees {
  V& radians;  // std::optional<double>, possibly const
  int decimals;
};
// A position as three keys "x", "y", "z" (4 decimals); P is Eigen::Vector3d or std::optional of it (all null when
// absent), possibly const.
template <class P>
struct Point {
  P& value;
};

template <class V>
Fixed<V> fixed(V& v, int decimals) {
  return {v, decimals};
}
template <class V>
Degrees<V> degrees(V& v, int decimals) {
  return {v, decimals};
}
template <class P>
Point<P> point(P& p) {
  return {p};
}

template <class E, class T>
concept Is = std::same_as<std::remove_const_t<E>, T>;

// --- Each type's keys after "t" and "type", in the log's order -------------------------------------------------------

template <class F, Is<events::RobotName> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("cell", e.cell);
}
template <class F, Is<events::RunStart> E>
void fields(F& f, E& e) {
  f("program", e.program);
  f("cell", e.cell);
  f("mode", e.mode);
  f("period", e.period);
  f("robots", e.robots);
}
template <class F, Is<events::Fire> E>
void fields(F& f, E& e) {
  f("transition", e.transition);
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("line", e.line);
  f("task", e.task);
  f("motion", e.motion);
}
template <class F, Is<events::CommandStart> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("command", e.command);
  f("task", e.task);
  f("motion", e.motion);
  f("detail", e.detail);
}
template <class F, Is<events::CommandEnd> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("command", e.command);
  f("ok", e.ok);
  f("reason", e.reason);
}
template <class F, Is<events::Sensor> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("condition", e.condition);
  f("workpiece", e.workpiece);
}
template <class F, Is<events::Collision> E>
void fields(F& f, E& e) {
  f("a", e.a);
  f("b", e.b);
  f("depth", fixed(e.depth, 6));
}
template <class F, class E>
requires Is<E, events::WorkpieceArrived> || Is<E, events::WorkpieceLeft>
void fields(F& f, E& e) {
  f("workpiece", e.workpiece);
  f("where", e.where);
}
template <class F, Is<events::Seen> E>
void fields(F& f, E& e) {
  f("workpiece", e.workpiece);
  f("", point(e.position));
  f("yaw", degrees(e.yaw, 2));
  f("confidence", fixed(e.confidence, 3));
}
template <class F, Is<events::Vision> E>
void fields(F& f, E& e) {
  f("frame", e.frame);
  f("seen", e.seen);
  f("not_seen", e.not_seen);
  f("rejected", e.rejected);
  f("problem", e.problem);
}
template <class F, Is<events::FaultInjected> E>
void fields(F& f, E& e) {
  f("kind", e.kind);
  f("robot", e.robot);
  f("workpiece", e.workpiece);
  f("detail", e.detail);
}
template <class F, Is<events::FaultDetected> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("symptom", e.symptom);
  f("detail", e.detail);
}
template <class F, Is<events::Diagnosis> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("symptom", e.symptom);
  f("cause", e.cause);
  f("action", e.action);
  f("path", e.path);
}
template <class F, Is<events::RecoveryEnd> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("cause", e.cause);
  f("action", e.action);
  f("ok", e.ok);
  f("detail", e.detail);
  f("duration", e.duration);
}
template <class F, Is<events::ProtectiveStop> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("reason", e.reason);
}
template <class F, Is<events::ProtectiveRelease> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
}
template <class F, Is<events::WorkpieceLost> E>
void fields(F& f, E& e) {
  f("workpiece", e.workpiece);
  f("reason", e.reason);
  f("", point(e.last_seen));
}
template <class F, Is<events::Skipped> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("primitive", e.primitive);
  f("command", e.command);
  f("reason", e.reason);
}
template <class F, Is<events::CellStopped> E>
void fields(F& f, E& e) {
  f("reason", e.reason);
}
template <class F, Is<events::Device> E>
void fields(F& f, E& e) {
  f("device", e.device);
  f("kind", e.kind);
  f("state", e.state);
  f("workpiece", e.workpiece);
}
template <class F, Is<events::Held> E>
void fields(F& f, E& e) {
  f("robot", e.robot);
  f("workpiece", e.workpiece);
}
template <class F, Is<events::Physical> E>
void fields(F& f, E& e) {
  f("held", e.held);
  f("obstacles", e.obstacles);
}
template <class F, Is<events::Carry> E>
void fields(F& f, E& e) {
  f("workpiece", e.workpiece);
  f("a", e.a);
  f("b", e.b);
  f("squeeze", fixed(e.squeeze, 2));
  f("error", fixed(e.error, 2));
  f("turn", fixed(e.turn, 3));
  f("tilt", fixed(e.tilt, 3));
}
template <class F, Is<events::RunEnd> E>
void fields(F& f, E& e) {
  f("outcome", e.outcome);
  f("reason", e.reason);
  f("firings", e.firings);
}

constexpr const char* kAxes[3] = {"x", "y", "z"};

// --- Writing ---------------------------------------------------------------------------------------------------------

// A JSON string literal. Invalid UTF-8 is replaced rather than thrown on: a log line must always be written.
void put_string(std::string& out, std::string_view s) {
  out += json(std::string(s)).dump(-1, ' ', false, json::error_handler_t::replace);
}

// Fixed decimals; a number that prints as zero has no minus sign, so the same numbers give the same bytes.
void put_fixed(std::string& out, double v, int decimals, std::string_view type, std::string_view key) {
  CW_CHECK(std::isfinite(v), "{} event: \"{}\" is {}", type, key, v);
  const std::size_t at = out.size();
  fmt::format_to(std::back_inserter(out), "{:.{}f}", v, decimals);
  if (out[at] == '-' && out.find_first_not_of("0.", at + 1) == std::string::npos) out.erase(at, 1);
}

class Writer {
 public:
  // `after_key`: `out` already ends with a key's value (the fields follow with a comma).
  Writer(std::string& out, std::string_view type, bool after_key) : out_(out), type_(type), first_(!after_key) {}

  void operator()(const char* key, const std::string& v) {
    this->key(key);
    put_string(out_, v);
  }
  void operator()(const char* key, SimDuration v) {
    this->key(key);
    out_ += format_sim_time(v);
  }
  void operator()(const char* key, bool v) {
    this->key(key);
    out_ += v ? "true" : "false";
  }
  template <std::integral I>
  void operator()(const char* key, I v) {
    this->key(key);
    fmt::format_to(std::back_inserter(out_), "{}", v);
  }
  void operator()(const char* key, Fixed<const double> v) {
    this->key(key);
    put_fixed(out_, v.value, v.decimals, type_, key);
  }
  void operator()(const char* key, Degrees<const std::optional<double>> v) {
    this->key(key);
    if (v.radians) {
      put_fixed(out_, *v.radians * 180.0 / std::numbers::pi, v.decimals, type_, key);
    } else {
      out_ += "null";
    }
  }
  void operator()(const char*, Point<const Eigen::Vector3d> p) {
    for (int i = 0; i < 3; ++i) (*this)(kAxes[i], fixed(p.value[i], 4));
  }
  void operator()(const char*, Point<const std::optional<Eigen::Vector3d>> p) {
    for (int i = 0; i < 3; ++i) {
      if (p.value) {
        (*this)(kAxes[i], fixed((*p.value)[i], 4));
      } else {
        this->key(kAxes[i]);
        out_ += "null";
      }
    }
  }
  void operator()(const char* key, const std::vector<std::string>& list) {
    this->key(key);
    out_ += '[';
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (i > 0) out_ += ',';
      put_string(out_, list[i]);
    }
    out_ += ']';
  }
  template <class T>
  void operator()(const char* key, const std::vector<T>& list) {
    this->key(key);
    out_ += '[';
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (i > 0) out_ += ',';
      object(list[i]);
    }
    out_ += ']';
  }

  template <class T>
  void object(const T& value) {
    out_ += '{';
    first_ = true;
    fields(*this, value);
    out_ += '}';
    first_ = false;
  }

  void key(std::string_view k) {
    if (!first_) out_ += ',';
    first_ = false;
    out_ += '"';
    out_ += k;
    out_ += "\":";
  }

 private:
  std::string& out_;
  std::string_view type_;
  bool first_;
};

// --- Reading ---------------------------------------------------------------------------------------------------------

// "a string", "a number", ...: what a JSON value is, for errors.
const char* kind_of(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::object:
      return "an object";
    case json::value_t::array:
      return "a list";
    case json::value_t::string:
      return "a string";
    case json::value_t::boolean:
      return "true/false";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
      return "an integer";
    case json::value_t::number_float:
      return "a number";
    default:
      return "not a value";
  }
}

// Seconds as written -> nanoseconds (exact for the log's 4 decimals).
SimDuration to_duration(double seconds) {
  return SimDuration(std::llround(seconds * 1e9));
}

class Reader {
 public:
  Reader(const std::string& file, int line, std::string_view type) : file_(file), line_(line), type_(type) {}

  [[noreturn]] void fail(const std::string& problem) const { throw InputError({file_, line_, 0}, problem); }

  // The value of `key` of `obj`; a missing key is an error.
  const json& at(const json& obj, std::string_view key) {
    const auto it = obj.find(key);
    if (it == obj.end()) fail(fmt::format("{} event has no \"{}{}\"", type_, path_, key));
    return *it;
  }
  [[noreturn]] void wrong(std::string_view key, const json& v, std::string_view expected) const {
    const std::string text = v.dump(-1, ' ', false, json::error_handler_t::replace);
    fail(fmt::format("{} event: \"{}{}\" is {} ({}), not {}", type_, path_, key, kind_of(v),
                     text.size() > 40 ? text.substr(0, 40) + "..." : text, expected));
  }

  void operator()(const char* key, std::string& v) {
    const json& j = at(*obj_, key);
    if (!j.is_string()) wrong(key, j, "a string");
    v = j.get_ref<const std::string&>();
  }
  void operator()(const char* key, SimDuration& v) { v = time(*obj_, key); }
  void operator()(const char* key, bool& v) {
    const json& j = at(*obj_, key);
    if (!j.is_boolean()) wrong(key, j, "true or false");
    v = j.get<bool>();
  }
  template <std::signed_integral I>
  void operator()(const char* key, I& v) {
    const json& j = at(*obj_, key);
    if (!j.is_number_integer()) wrong(key, j, "an integer");
    if (j.is_number_unsigned() ? j.get<std::uint64_t>() > static_cast<std::uint64_t>(std::numeric_limits<I>::max())
                               : j.get<std::int64_t>() < std::numeric_limits<I>::min() ||
                                     j.get<std::int64_t>() > std::numeric_limits<I>::max()) {
      wrong(key, j, "an integer in range");
    }
    v = j.is_number_unsigned() ? static_cast<I>(j.get<std::uint64_t>()) : static_cast<I>(j.get<std::int64_t>());
  }
  template <std::unsigned_integral I>
  requires(!std::same_as<I, bool>) void operator()(const char* key, I& v) {
    const json& j = at(*obj_, key);
    if (!j.is_number_unsigned()) wrong(key, j, "a count (an integer >= 0)");
    const auto u = j.get<std::uint64_t>();
    if (u > std::numeric_limits<I>::max()) wrong(key, j, "a count in range");
    v = static_cast<I>(u);
  }
  void operator()(const char* key, Fixed<double> v) { v.value = number(at(*obj_, key), key); }
  void operator()(const char* key, Degrees<std::optional<double>> v) {
    const json& j = at(*obj_, key);
    if (j.is_null()) {
      v.radians.reset();
    } else {
      v.radians = number(j, key) * std::numbers::pi / 180.0;
    }
  }
  void operator()(const char*, Point<Eigen::Vector3d> p) {
    for (int i = 0; i < 3; ++i) p.value[i] = number(at(*obj_, kAxes[i]), kAxes[i]);
  }
  void operator()(const char*, Point<std::optional<Eigen::Vector3d>> p) {
    const json* axes[3];
    int nulls = 0;
    for (int i = 0; i < 3; ++i) {
      axes[i] = &at(*obj_, kAxes[i]);
      if (axes[i]->is_null()) ++nulls;
    }
    if (nulls == 3) {
      p.value.reset();
      return;
    }
    if (nulls != 0) {
      fail(fmt::format("{} event: \"{}x\", \"y\" and \"z\" must be all numbers or all null (nowhere), not {}, {}, {}",
                       type_, path_, axes[0]->dump(), axes[1]->dump(), axes[2]->dump()));
    }
    p.value = Eigen::Vector3d(number(*axes[0], "x"), number(*axes[1], "y"), number(*axes[2], "z"));
  }
  void operator()(const char* key, std::vector<std::string>& list) {
    const json& j = at(*obj_, key);
    if (!j.is_array()) wrong(key, j, "a list of strings");
    list.clear();
    list.reserve(j.size());
    for (std::size_t i = 0; i < j.size(); ++i) {
      if (!j[i].is_string()) wrong(fmt::format("{}[{}]", key, i), j[i], "a string");
      list.push_back(j[i].get<std::string>());
    }
  }
  template <class T>
  void operator()(const char* key, std::vector<T>& list) {
    const json& j = at(*obj_, key);
    if (!j.is_array()) wrong(key, j, "a list of objects");
    list.assign(j.size(), T{});
    const json* outer = obj_;
    const std::string outer_path = path_;
    for (std::size_t i = 0; i < j.size(); ++i) {
      path_ = fmt::format("{}{}[{}].", outer_path, key, i);
      if (!j[i].is_object()) {
        path_ = outer_path;
        wrong(fmt::format("{}[{}]", key, i), j[i], "an object");
      }
      obj_ = &j[i];
      fields(*this, list[i]);
    }
    obj_ = outer;
    path_ = outer_path;
  }

  template <class T>
  void object(const json& obj, T& value) {
    obj_ = &obj;
    fields(*this, value);
  }

  SimDuration time(const json& obj, std::string_view key) {
    const json& j = at(obj, key);
    const double s = number(j, key);
    if (std::abs(s) > 9.0e9) wrong(key, j, "a time in seconds within 9e9 s");
    return to_duration(s);
  }

 private:
  double number(const json& j, std::string_view key) const {
    if (!j.is_number()) wrong(key, j, "a number");
    return j.get<double>();
  }

  const std::string& file_;
  int line_;
  std::string_view type_;
  const json* obj_ = nullptr;
  std::string path_;  // "robots[1]." inside a list's object
};

// The alternative of LogEvent whose kType is `type`, read from `obj`; false when no type is called so.
template <std::size_t I = 0>
bool read_as(std::string_view type, const json& obj, Reader& r, SimDuration t, LogEvent& out) {
  if constexpr (I == std::variant_size_v<LogEvent>) {
    return false;
  } else {
    using T = std::variant_alternative_t<I, LogEvent>;
    if (type != T::kType) return read_as<I + 1>(type, obj, r, t, out);
    T value;
    value.t = t;
    r.object(obj, value);
    out = std::move(value);
    return true;
  }
}

bool blank(std::string_view line) {
  return line.find_first_not_of(" \t\r") == std::string_view::npos;
}

}  // namespace

SimDuration time_of(const LogEvent& e) {
  return std::visit([](const auto& v) { return v.t; }, e);
}

std::string_view type_of(const LogEvent& e) {
  return std::visit([](const auto& v) { return std::remove_cvref_t<decltype(v)>::kType; }, e);
}

std::string encode(const LogEvent& e) {
  return std::visit(
      [](const auto& v) {
        using T = std::remove_cvref_t<decltype(v)>;
        std::string out;
        out.reserve(160);
        out += "{\"t\":";
        out += format_sim_time(v.t);
        out += ",\"type\":\"";
        out += T::kType;
        out += '"';
        Writer w(out, T::kType, true);
        fields(w, v);
        out += '}';
        return out;
      },
      e);
}

LogEvent decode(std::string_view line, const std::string& file, int line_no) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  const json j = json::parse(line, nullptr, false);
  const SourceLocation where{file, line_no, 0};
  if (j.is_discarded()) throw InputError(where, "not a JSON value (each line of an event log is one JSON object)");
  if (!j.is_object()) throw InputError(where, fmt::format("an event must be a JSON object, not {}", kind_of(j)));
  const auto type = j.find("type");
  if (type == j.end()) throw InputError(where, "the event has no \"type\"");
  if (!type->is_string())
    throw InputError(where, fmt::format("the event's \"type\" is {}, not a string", kind_of(*type)));
  const std::string& name = type->get_ref<const std::string&>();
  Reader r(file, line_no, name);
  const SimDuration t = r.time(j, "t");
  LogEvent out;
  if (!read_as(name, j, r, t, out)) throw InputError(where, fmt::format("unknown event type \"{}\"", name));
  return out;
}

std::vector<LoggedEvent> decode_log(std::string_view jsonl, const std::string& file) {
  std::vector<LoggedEvent> out;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < jsonl.size()) {
    std::size_t end = jsonl.find('\n', pos);
    if (end == std::string_view::npos) end = jsonl.size();
    const std::string_view line = jsonl.substr(pos, end - pos);
    ++line_no;
    if (!blank(line)) out.push_back({line_no, decode(line, file, line_no)});
    pos = end + 1;
  }
  return out;
}

void read_log(std::istream& jsonl, const std::string& file, const std::function<void(const LoggedEvent&)>& each) {
  std::string line;
  int line_no = 0;
  while (std::getline(jsonl, line)) {
    ++line_no;
    if (!blank(line)) each({line_no, decode(line, file, line_no)});
  }
  if (jsonl.bad()) throw InputError({file, line_no, 0}, "the event log could not be read");
}

}  // namespace cellwright::runtime
