// report.json read back into a Report, every field required and typed (report_json.hpp).
#include "cellwright/cell/report_json.hpp"

#include <fmt/format.h>

#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"

namespace cellwright::cell {

namespace {

using nlohmann::json;

// The fields of one JSON object of the file, each read with its type or refused naming the file and the field's path
// from the top ("faults[2].detected").
class Fields {
 public:
  Fields(const json& object, const std::string& file, std::string path)
      : j_(object), file_(file), path_(std::move(path)) {
    if (!j_.is_object()) fail(path_.empty() ? "the report" : path_, "must be a JSON object", j_);
  }

  [[noreturn]] void fail(const std::string& field, const std::string& problem, const json& value) const {
    std::string shown = value.dump();
    if (shown.size() > 60) shown = shown.substr(0, 57) + "...";
    throw InputError({file_, 0, 0}, fmt::format("\"{}\" {}, not {}", field, problem, shown));
  }
  [[noreturn]] void fail(const std::string& field, const std::string& problem) const {
    throw InputError({file_, 0, 0}, fmt::format("\"{}\" {}", field, problem));
  }
  std::string path_of(const char* key) const { return path_.empty() ? key : path_ + "." + key; }

  const json& at(const char* key) const {
    const auto it = j_.find(key);
    if (it == j_.end()) fail(path_of(key), "is missing");
    return *it;
  }

  std::string str(const char* key) const {
    const json& v = at(key);
    if (!v.is_string()) fail(path_of(key), "must be a string", v);
    return v.get<std::string>();
  }
  bool boolean(const char* key) const {
    const json& v = at(key);
    if (!v.is_boolean()) fail(path_of(key), "must be true or false", v);
    return v.get<bool>();
  }
  double number(const char* key) const { return number_in(at(key), path_of(key)); }
  double number_in(const json& v, const std::string& field) const {
    if (!v.is_number()) fail(field, "must be a number", v);
    return v.get<double>();
  }
  std::uint64_t count(const char* key) const {
    const json& v = at(key);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0)) {
      fail(path_of(key), "must be a whole number >= 0", v);
    }
    return v.get<std::uint64_t>();
  }
  int integer(const char* key) const {
    const json& v = at(key);
    if (!v.is_number_integer() || v.get<std::int64_t>() < std::numeric_limits<int>::min() ||
        v.get<std::int64_t>() > std::numeric_limits<int>::max()) {
      fail(path_of(key), "must be a whole number", v);
    }
    return static_cast<int>(v.get<std::int64_t>());
  }
  // null: none.
  std::optional<double> opt_number(const char* key) const {
    const json& v = at(key);
    if (v.is_null()) return std::nullopt;
    return number(key);
  }
  std::optional<std::string> opt_str(const char* key) const {
    const json& v = at(key);
    if (v.is_null()) return std::nullopt;
    return str(key);
  }
  std::optional<bool> opt_boolean(const char* key) const {
    const json& v = at(key);
    if (v.is_null()) return std::nullopt;
    return boolean(key);
  }
  const json& array(const char* key) const {
    const json& v = at(key);
    if (!v.is_array()) fail(path_of(key), "must be a list", v);
    return v;
  }
  std::vector<std::string> strings(const char* key) const {
    std::vector<std::string> out;
    const json& list = array(key);
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (!list[i].is_string()) fail(fmt::format("{}[{}]", path_of(key), i), "must be a string", list[i]);
      out.push_back(list[i].get<std::string>());
    }
    return out;
  }
  // A list of `n` numbers ([x, y, z]).
  std::vector<double> numbers(const char* key, std::size_t n) const {
    const json& list = array(key);
    if (list.size() != n) fail(path_of(key), fmt::format("must be a list of {} numbers", n), list);
    std::vector<double> out;
    for (std::size_t i = 0; i < n; ++i) out.push_back(number_in(list[i], fmt::format("{}[{}]", path_of(key), i)));
    return out;
  }
  Fields object(const char* key) const { return Fields(at(key), file_, path_of(key)); }
  // Each element of a list of objects, in order.
  std::vector<Fields> objects(const char* key) const {
    std::vector<Fields> out;
    const json& list = array(key);
    for (std::size_t i = 0; i < list.size(); ++i)
      out.emplace_back(list[i], file_, fmt::format("{}[{}]", path_of(key), i));
    return out;
  }
  bool is_null(const char* key) const { return at(key).is_null(); }

 private:
  const json& j_;
  const std::string& file_;
  std::string path_;
};

Eigen::Vector3d vector3(const Fields& f, const char* key) {
  const std::vector<double> v = f.numbers(key, 3);
  return {v[0], v[1], v[2]};
}

PartStatus part_status(const Fields& f, const char* key) {
  const std::string s = f.str(key);
  for (PartStatus st : {PartStatus::kInPlace, PartStatus::kElsewhere, PartStatus::kHeld, PartStatus::kLost,
                        PartStatus::kNotArrived, PartStatus::kScrapped}) {
    if (s == to_string(st)) return st;
  }
  f.fail(f.path_of(key), "must be one of in_place, elsewhere, held, lost, not_arrived, scrapped", json(s));
}

WorkpieceReport workpiece(const Fields& f) {
  WorkpieceReport w;
  w.name = f.str("name");
  w.label = f.opt_str("label").value_or(std::string());
  w.final_location = f.str("final_location");
  w.at = f.strings("at");
  w.position = vector3(f, "position");
  w.expected = f.opt_str("expected");
  w.tolerance = f.number("tolerance");
  w.ok = f.opt_boolean("ok");
  if (w.expected && !w.ok) f.fail(f.path_of("ok"), "is null for a workpiece with an expectation");
  w.pick_start = f.opt_number("pick_start");
  w.place_end = f.opt_number("place_end");
  w.cycle_time = f.opt_number("cycle_time");
  w.completed = f.boolean("completed");
  return w;
}

// The account's entry of `w` (the same workpiece, the same expectation).
void account(const Fields& a, WorkpieceReport& w) {
  if (a.str("workpiece") != w.name) {
    a.fail(a.path_of("workpiece"), fmt::format("must be {} (the workpieces' entry at its index)", json(w.name).dump()),
           json(a.str("workpiece")));
  }
  if (a.opt_str("expected") != w.expected) {
    a.fail(a.path_of("expected"), "must be the workpieces' expectation of it",
           a.is_null("expected") ? json() : json(a.str("expected")));
  }
  w.status = part_status(a, "status");
  w.where = a.str("where");
  w.unaccounted = a.boolean("unaccounted");
  if (!a.is_null("lost")) {
    const Fields l = a.object("lost");
    LostPart lost;
    lost.t = l.number("t");
    lost.reason = l.str("reason");
    if (!l.is_null("last_seen")) lost.last_seen = vector3(l, "last_seen");
    w.lost = lost;
  }
}

FaultReport fault(const Fields& f) {
  FaultReport r;
  r.kind = f.str("kind");
  r.t = f.number("t");
  r.robot = f.str("robot");
  r.workpiece = f.str("workpiece");
  r.detail = f.str("detail");
  r.detected = f.boolean("detected");
  r.detected_at = f.opt_number("detected_at");
  if (r.detected && !r.detected_at) f.fail(f.path_of("detected_at"), "is null for a detected fault");
  r.detected_by = f.str("detected_by");
  r.symptom = f.str("symptom");
  r.cause = f.str("cause");
  r.action = f.str("action");
  r.recovered = f.boolean("recovered");
  r.recovery_time = f.opt_number("recovery_time");
  if (r.recovered && !r.recovery_time) f.fail(f.path_of("recovery_time"), "is null for a recovered fault");
  r.stopped_safely = f.boolean("stopped_safely");
  return r;
}

Detection detection(const Fields& f) {
  Detection d;
  d.t = f.number("t");
  d.robot = f.str("robot");
  d.primitive = f.integer("primitive");
  d.symptom = f.str("symptom");
  d.detail = f.str("detail");
  d.cause = f.str("cause");
  d.action = f.str("action");
  d.recovered = f.boolean("recovered");
  d.truth = f.str("truth");
  return d;
}

RobotTimeline robot(const Fields& f) {
  RobotTimeline t;
  t.robot = f.str("robot");
  t.cell = f.str("cell");
  t.commands = f.count("commands");
  t.busy = f.number("busy");
  t.waiting = f.number("waiting");
  t.waiting_for_part = f.number("waiting_for_part");
  t.blocked = f.number("blocked");
  t.idle = f.number("idle");
  return t;
}

DeviceTimeline device(const Fields& f) {
  DeviceTimeline d;
  d.device = f.str("device");
  d.kind = f.str("kind");
  d.state = f.str("state");
  if (d.kind == "machine") {
    d.workpiece = f.str("workpiece");
    d.busy = f.number("busy");
    d.done = f.number("done_waiting");
    d.idle = f.number("idle");
    d.utilisation = f.number("utilisation");
    d.cycles_started = f.count("cycles_started");
    d.cycles_finished = f.count("cycles_finished");
    d.processed = f.strings("processed");
  } else if (d.kind == "conveyor") {
    d.running = f.number("running");
    d.stopped = f.number("stopped");
    d.starts = f.count("starts");
  } else if (d.kind == "sensor") {
    d.on = f.number("on");
    d.off = f.number("off");
    d.starts = f.count("times_on");
  } else {
    f.fail(f.path_of("kind"), "must be one of machine, conveyor, sensor", json(d.kind));
  }
  return d;
}

void flow(const Fields& f, Report& r) {
  const json& placed_at = f.array("placed_at");
  for (std::size_t i = 0; i < placed_at.size(); ++i) {
    r.placed_at.push_back(f.number_in(placed_at[i], fmt::format("{}[{}]", f.path_of("placed_at"), i)));
  }
  if (f.count("placed") != r.placed_at.size()) {
    f.fail(f.path_of("placed"), fmt::format("must be {}, the length of flow.placed_at", r.placed_at.size()),
           f.at("placed"));
  }
  r.parts_fed = f.count("fed");
  r.parts_delivered = f.count("delivered");
  r.steady_throughput = f.opt_number("steady_throughput_parts_per_min");
  r.steady_cycle = f.opt_number("steady_cycle_s");
  if (r.steady_throughput.has_value() != r.steady_cycle.has_value()) {
    f.fail(f.path_of("steady_cycle_s"), "and flow.steady_throughput_parts_per_min must be both null or both numbers");
  }
}

}  // namespace

Report from_json(const json& j, const std::string& file) {
  const Fields f(j, file, "");
  // What ran: checked, not kept (the Report is the run's result; the scenario is the caller's).
  (void)f.str("scenario");
  (void)f.str("program");
  (void)f.str("cell");
  (void)f.count("seed");

  Report r;
  // What the run used.
  r.setup.perception = f.str("perception");
  if (r.setup.perception != "truth" && r.setup.perception != "vision" && r.setup.perception != "cad") {
    f.fail("perception", "must be one of truth, vision, cad", json(r.setup.perception));
  }
  for (const Fields& d : f.objects("drivers")) {
    r.setup.drivers.push_back({d.str("robot"), d.str("kind"), d.str("port"), d.boolean("emulated")});
  }
  r.setup.faults = f.strings("requested_faults");
  // Written only by a run without the twin (report.hpp, RunSetup::parts_from_model); absent: the twin's truth.
  if (j.contains("parts_from")) {
    const std::string from = f.str("parts_from");
    if (from != "controller_model") f.fail("parts_from", "must be \"controller_model\" when given", json(from));
    r.setup.parts_from_model = true;
  }
  r.failures = f.strings("failures");
  const std::string result = f.str("result");
  if (result != (r.ok() ? "ok" : "failed")) {
    f.fail("result", fmt::format("must be \"{}\" with {} failures", r.ok() ? "ok" : "failed", r.failures.size()),
           json(result));
  }
  r.outcome = f.str("outcome");
  r.reason = f.str("reason");
  r.end_time = f.number("end_time");
  r.timeline.end = r.end_time;
  r.firings = f.count("firings");
  const Fields cycle = f.object("cycle_time");
  r.estimated_cycle_time = cycle.opt_number("estimated");
  r.finished_at = cycle.opt_number("measured");
  r.throughput = f.opt_number("throughput_parts_per_min");
  r.parts_completed = f.count("parts_completed");
  flow(f.object("flow"), r);

  for (const Fields& w : f.objects("workpieces")) r.workpieces.push_back(workpiece(w));
  const std::vector<Fields> accounts = f.objects("account");
  if (accounts.size() != r.workpieces.size()) {
    f.fail("account", fmt::format("must have {} entries, one per workpiece", r.workpieces.size()), f.at("account"));
  }
  for (std::size_t i = 0; i < accounts.size(); ++i) account(accounts[i], r.workpieces[i]);
  if (f.count("unaccounted") != r.unaccounted()) {
    f.fail("unaccounted", fmt::format("must be {}, the account's unaccounted parts", r.unaccounted()),
           f.at("unaccounted"));
  }

  for (const Fields& t : f.objects("robots")) r.timeline.robots.push_back(robot(t));
  // Written only for a log with device events; absent: none.
  if (j.contains("devices")) {
    for (const Fields& d : f.objects("devices")) r.timeline.devices.push_back(device(d));
  }
  for (const Fields& c : f.objects("collisions")) {
    r.collisions.push_back({c.number("t"), c.str("a"), c.str("b"), c.number("depth")});
  }
  // Written only for a run with coordinated carries; absent: none.
  if (j.contains("carries")) {
    for (const Fields& c : f.objects("carries")) {
      r.carries.push_back({c.str("workpiece"), c.str("a"), c.str("b"), c.number("start"), c.number("end"),
                           c.count("samples"), c.number("peak_squeeze"), c.number("peak_squeeze_t"),
                           c.number("max_error"), c.number("max_error_t"), c.number("max_turn"), c.number("max_tilt"),
                           c.number("max_tilt_t")});
    }
  }
  r.stopped_at = f.opt_number("stopped_at");
  for (const Fields& x : f.objects("faults")) r.faults.push_back(fault(x));
  for (const Fields& d : f.objects("unexplained_faults")) r.unexplained.push_back(detection(d));
  for (const Fields& d : f.objects("false_alarm_detections")) r.false_alarms.push_back(detection(d));
  if (f.count("false_alarms") != r.false_alarms.size()) {
    f.fail("false_alarms", fmt::format("must be {}, the length of false_alarm_detections", r.false_alarms.size()),
           f.at("false_alarms"));
  }
  return r;
}

Report read_report(const std::filesystem::path& file) {
  const std::string text = read_file(file);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    throw InputError({file.string(), 0, 0}, fmt::format("not JSON: {}", e.what()));
  }
  return from_json(j, file.string());
}

}  // namespace cellwright::cell
