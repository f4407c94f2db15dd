// Reading and checking the cell description (cell.hpp; the format is documented in docs/cell-description.md).
#include "cellwright/models/cell.hpp"

#include <yaml-cpp/yaml.h>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/robot_model.hpp"
#include "cellwright/models/yaml_fields.hpp"
#include "cellwright/common/files.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

namespace cellwright::models {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Reading YAML with positions in every error: the project's one field reader (yaml_fields.hpp).
using yaml::describe;
using yaml::Doc;
using yaml::Fields;
using yaml::Range;

constexpr Range kCoordinate{-bounds::kPosition, bounds::kPosition, false, "m"};
constexpr Range kAngleDeg{-bounds::kAngle, bounds::kAngle, false, "degrees"};
constexpr Range kBodySize{bounds::kMinSize, bounds::kMaxSize, false, "m"};
constexpr Range kPartSize{bounds::kMinSize, bounds::kMaxPart, false, "m"};
constexpr Range kNear{-bounds::kMaxReach, bounds::kMaxReach, false, "m"};
constexpr Range kHeight{0, bounds::kMaxReach, false, "m"};

// Names become MuJoCo names and references: letters, digits, '_' and '-', starting with a letter or '_'.
bool valid_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  if (!(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'; });
}

// A name as an error shows it: at most 64 characters, bytes that are not printable ASCII as \xNN, so that a name of
// 100,000 characters or of bytes that are not UTF-8 neither floods the terminal nor garbles it.
std::string shown_name(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size() && i < 64; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    out += c >= 0x20 && c < 0x7f ? std::string(1, s[i]) : fmt::format("\\x{:02x}", c);
  }
  if (s.size() > 64) out += fmt::format("... ({} characters)", s.size());
  return out;
}

// Every object in the cell has a name unique in the whole cell, so that `on:`/`at:` references are unambiguous.
class Names {
 public:
  explicit Names(const Doc& doc) : doc_(doc) {}
  std::string take(const Fields& f, const std::string& kind) {
    const YAML::Node& n = f.node("name");
    const std::string name = f.text_of(n, fmt::format("field 'name' of a {}", kind));
    if (!valid_name(name)) {
      doc_.fail(n, fmt::format("{} name '{}' is not valid: use letters, digits, '_' and '-', starting with a letter "
                               "or '_', at most 64 characters",
                               kind, shown_name(name)));
    }
    // The scene names a robot's bodies, joints and sites "<robot>/<link>", and the others "conveyor/<name>",
    // "machine/<name>", "workpiece/<name>", "location/<name>", "handover/<name>": a robot named like one of those
    // prefixes could give two MJCF elements one name.
    static const std::set<std::string> kPrefixes = {"conveyor", "machine", "workpiece", "location", "handover"};
    if (kind == "robot" && kPrefixes.count(name) != 0) {
      doc_.fail(n, fmt::format("robot name '{}' is reserved: the scene's names of conveyors, machines, workpieces, "
                               "locations and the hand-over start with '{}/'; choose another",
                               name, name));
    }
    auto it = seen_.find(name);
    if (it != seen_.end()) {
      doc_.fail(n, fmt::format("duplicate name '{}': already used for the {} on line {}", name, it->second.first,
                               it->second.second));
    }
    seen_.emplace(name, std::make_pair(kind, doc_.at(n).line));
    return name;
  }
  // A name the reader made up (a default) or read from a node other than a `name` field: the same rule, at `at`.
  void take_text(const std::string& name, const YAML::Node& at, const std::string& kind) {
    if (!valid_name(name)) {
      doc_.fail(at, fmt::format("{} name '{}' is not valid: use letters, digits, '_' and '-', starting with a letter "
                                "or '_', at most 64 characters",
                                kind, shown_name(name)));
    }
    auto it = seen_.find(name);
    if (it != seen_.end()) {
      doc_.fail(at, fmt::format("duplicate name '{}': already used for the {} on line {}", name, it->second.first,
                                it->second.second));
    }
    seen_.emplace(name, std::make_pair(kind, doc_.at(at).line));
  }

 private:
  const Doc& doc_;
  std::map<std::string, std::pair<std::string, int>> seen_;
};

// A pose: {xyz: [x, y, z], rpy: [roll, pitch, yaw]} or {xyz: [...], yaw: deg}; angles in degrees.
Pose read_pose(const Doc& doc, const YAML::Node& n, const std::string& what) {
  Fields f(doc, n, what, {"xyz", "rpy", "yaw"});
  Pose p;
  p.xyz = f.vec3_within("xyz", kCoordinate);
  if (f.has("rpy") && f.has("yaw"))
    doc.fail(f.node("yaw"), fmt::format("{}: give either 'rpy' or 'yaw', not both", what));
  if (f.has("rpy")) p.rpy = f.vec3_within("rpy", kAngleDeg) * kDeg;
  if (f.has("yaw")) p.rpy = Eigen::Vector3d(0, 0, f.within("yaw", kAngleDeg) * kDeg);
  return p;
}

std::vector<YAML::Node> list_of(const Doc& doc, const Fields& top, const std::string& key) {
  std::vector<YAML::Node> out;
  auto n = top.get(key);
  if (!n || n->IsNull()) return out;
  if (!n->IsSequence()) doc.fail(*n, fmt::format("'{}' must be a list, got {}", key, describe(*n)));
  for (const auto& e : *n) out.push_back(e);
  return out;
}

// --- Sections ----------------------------------------------------------------------------------------------------

SerialSettings read_serial(const Doc& doc, const YAML::Node& n, const std::string& robot, DriverKind driver) {
  Fields f(doc, n, fmt::format("the serial settings of robot '{}'", robot),
           {"port", "baud", "data_bits", "parity", "stop_bits", "handshake"});
  SerialSettings s;
  // Movemaster EX defaults are the documented line settings (facts.md: 9600 baud, 7E2, RTS and XON/XOFF). No
  // source documents VAL II's line, so there every setting must be given.
  if (driver == DriverKind::kMovemaster) {
    s = SerialSettings{"", 9600, 7, Parity::kEven, 2, true, true};
  } else if (driver == DriverKind::kVal2) {
    for (const char* key : {"baud", "data_bits", "parity", "stop_bits"}) {
      if (!f.has(key)) {
        doc.fail(n, fmt::format("{} lack '{}': no default is documented for VAL II controllers", f.what(), key));
      }
    }
  }
  s.port = f.text("port");
  if (s.port.empty()) doc.fail(f.node("port"), fmt::format("{} must name a serial device", f.field("port")));
  if (f.has("baud")) {
    const double b = f.number("baud");
    static const std::set<int> kRates = {300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200};
    if (b != std::floor(b) || kRates.count(static_cast<int>(b)) == 0) {
      doc.fail(f.node("baud"), fmt::format("{} must be one of 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, "
                                           "57600, 115200, got {}",
                                           f.field("baud"), f.node("baud").Scalar()));
    }
    s.baud = static_cast<int>(b);
  }
  if (f.has("data_bits")) {
    const double d = f.number("data_bits");
    if (d != std::floor(d) || d < 5 || d > 8) {
      doc.fail(f.node("data_bits"), fmt::format("{} must be 5, 6, 7 or 8, got {}", f.field("data_bits"), d));
    }
    s.data_bits = static_cast<int>(d);
  }
  if (f.has("parity")) {
    const std::string p = f.text("parity");
    if (p == "none") {
      s.parity = Parity::kNone;
    } else if (p == "even") {
      s.parity = Parity::kEven;
    } else if (p == "odd") {
      s.parity = Parity::kOdd;
    } else {
      doc.fail(f.node("parity"), fmt::format("{} must be none, even or odd, got '{}'", f.field("parity"), p));
    }
  }
  if (f.has("stop_bits")) {
    const double sb = f.number("stop_bits");
    if (sb != 1 && sb != 2) {
      doc.fail(f.node("stop_bits"), fmt::format("{} must be 1 or 2, got {}", f.field("stop_bits"), sb));
    }
    s.stop_bits = static_cast<int>(sb);
  }
  if (f.has("handshake")) {
    const YAML::Node& h = f.node("handshake");
    std::vector<YAML::Node> items;
    if (h.IsSequence()) {
      for (const auto& e : h) items.push_back(e);
    } else {
      items.push_back(h);
    }
    s.rts_cts = false;
    s.xon_xoff = false;
    for (const auto& e : items) {
      const std::string v = f.text_of(e, f.field("handshake"));
      if (v == "rtscts") {
        s.rts_cts = true;
      } else if (v == "xonxoff") {
        s.xon_xoff = true;
      } else if (v != "none") {
        doc.fail(e,
                 fmt::format("{} must be none, rtscts, xonxoff or a list of them, got '{}'", f.field("handshake"), v));
      }
    }
  }
  return s;
}

// The fields that fit a robot as its maker publishes it to the cell: link names, gripper, meshes.
void read_robot_model_fields(const Doc& doc, const Fields& f, const std::filesystem::path& base_dir, RobotSpec& r) {
  if (f.has("base_link")) r.base_link = f.word("base_link");
  if (f.has("flange_link")) r.flange_link = f.word("flange_link");
  if (f.has("gripper")) {
    const std::string g = f.word("gripper");
    if (g == "own") {
      r.gripper = GripperKind::kOwn;
    } else if (g == "cellwright") {
      r.gripper = GripperKind::kCellwright;
    } else {
      doc.fail(f.node("gripper"), fmt::format("{} must be own (the URDF's) or cellwright (the project's gripper on "
                                              "the flange), got '{}'",
                                              f.field("gripper"), g));
    }
  }
  if (f.has("tool_link")) {
    if (r.gripper == GripperKind::kCellwright) {
      doc.fail(f.node("tool_link"), fmt::format("{}: with 'gripper: cellwright' the tool link is the gripper's tcp",
                                                f.field("tool_link")));
    }
    r.tool_link = f.word("tool_link");
  }
  if (f.has("package_path")) {
    const YAML::Node& list = f.node("package_path");
    if (!list.IsSequence()) {
      doc.fail(list, fmt::format("{} must be a list of directories, got {}", f.field("package_path"), describe(list)));
    }
    for (const auto& e : list) {
      const std::string dir = f.word_of(e, f.field("package_path"));
      std::filesystem::path p = std::filesystem::path(dir).is_absolute() ? std::filesystem::path(dir) : base_dir / dir;
      std::error_code ec;
      if (!std::filesystem::is_directory(p, ec)) {
        doc.fail(e, fmt::format("{}: '{}' is not a directory", f.field("package_path"), p.string()));
      }
      r.package_path.push_back(p.lexically_normal());
    }
  }
  if (f.has("meshes")) {
    const std::string m = f.word("meshes");
    if (m != "visual" && m != "collision") {
      doc.fail(f.node("meshes"), fmt::format("{} must be visual or collision (draw the collision geometry), got '{}'",
                                             f.field("meshes"), m));
    }
    r.draw_collision = m == "collision";
  }
}

// The word at `key` among `choices` (word, value); else "<field> must be a, b or c, got '<word>'".
template <typename T>
T choice_of(const Doc& doc, const Fields& f, const std::string& key,
            std::initializer_list<std::pair<std::string_view, T>> choices) {
  const std::string w = f.text(key);
  std::string names;
  std::size_t i = 0;
  for (const auto& [name, value] : choices) {
    if (w == name) return value;
    names += fmt::format("{}{}", i == 0 ? "" : i + 1 == choices.size() ? " or " : ", ", name);
    ++i;
  }
  doc.fail(f.node(key), fmt::format("{} must be {}, got '{}'", f.field(key), names, w));
}

LineEnd read_line_end(const Doc& doc, const Fields& f) {
  return choice_of<LineEnd>(doc, f, "line_end", {{"cr", LineEnd::kCr}, {"crlf", LineEnd::kCrLf}, {"lf", LineEnd::kLf}});
}

// The frame keys shared by `val2:` and `movemaster:` (ControllerFrames): offsets in mm within ±10 m, rotations in
// degrees within ±360 (bounds::kAngle).
constexpr Range kOffsetMm{-10000, 10000, false, "mm"};

ControllerFrames read_frames(const Fields& f) {
  const auto rotation = [](const Eigen::Vector3d& rpy_deg) {
    return Pose{Eigen::Vector3d::Zero(), rpy_deg * kDeg}.rotation();
  };
  ControllerFrames c;
  if (f.has("world_offset")) c.world.translation() = f.vec3_within("world_offset", kOffsetMm) / 1000.0;
  if (f.has("world_rotation")) c.world.linear() = rotation(f.vec3_within("world_rotation", kAngleDeg));
  if (f.has("tool_offset")) c.tool.translation() = f.vec3_within("tool_offset", kOffsetMm) / 1000.0;
  if (f.has("tool_rotation")) c.tool.linear() = rotation(f.vec3_within("tool_rotation", kAngleDeg));
  return c;
}

Val2Conventions read_val2(const Doc& doc, const YAML::Node& n, const std::string& robot) {
  Fields f(doc, n, fmt::format("the VAL II conventions of robot '{}'", robot),
           {"orientation", "line_end", "prompt", "where", "echo", "world_offset", "world_rotation", "tool_offset",
            "tool_rotation"});
  Val2Conventions c;
  using C = Val2Conventions;
  if (f.has("orientation")) {
    c.orientation = choice_of<C::Orientation>(
        doc, f, "orientation",
        {{"tool_down", C::Orientation::kToolDown}, {"zyz", C::Orientation::kZyz}, {"val", C::Orientation::kVal}});
  }
  c.frames = read_frames(f);
  if (f.has("line_end")) c.line_end = read_line_end(doc, f);
  if (f.has("prompt")) {
    c.prompt = f.text("prompt");
    const bool ok = !c.prompt.empty() &&
                    std::all_of(c.prompt.begin(), c.prompt.end(), [](char ch) { return ch > 0x20 && ch < 0x7f; });
    if (!ok) {
      doc.fail(f.node("prompt"), fmt::format("{} must be printable characters without spaces (\".\", \">\"), got '{}'",
                                             f.field("prompt"), c.prompt));
    }
  }
  if (f.has("where")) {
    c.where = choice_of<C::WhereLayout>(doc, f, "where",
                                        {{"val2", C::WhereLayout::kVal2}, {"as", C::WhereLayout::kAsTwoBlock}});
  }
  if (f.has("echo")) {
    c.echo = choice_of<C::Echo>(doc, f, "echo",
                                {{"maybe", C::Echo::kMaybe}, {"always", C::Echo::kAlways}, {"never", C::Echo::kNever}});
  }
  return c;
}

MovemasterConventions read_movemaster(const Doc& doc, const YAML::Node& n, const std::string& robot) {
  Fields f(doc, n, fmt::format("the Movemaster conventions of robot '{}'", robot),
           {"line_end", "completion", "ms_open_letter", "pitch_down", "roll", "world_offset", "world_rotation",
            "tool_offset", "tool_rotation"});
  MovemasterConventions c;
  using C = MovemasterConventions;
  c.frames = read_frames(f);
  if (f.has("pitch_down")) {
    c.pitch_down_deg = f.number("pitch_down");
    if (c.pitch_down_deg != -90 && c.pitch_down_deg != 90) {
      doc.fail(f.node("pitch_down"), fmt::format("{} must be -90 (the page's: p = -90 points the hand straight down) "
                                                 "or 90, got {}",
                                                 f.field("pitch_down"), c.pitch_down_deg));
    }
  }
  if (f.has("roll")) c.roll_sense = choice_of<int>(doc, f, "roll", {{"right_hand", 1}, {"left_hand", -1}});
  if (f.has("line_end")) c.line_end = read_line_end(doc, f);
  if (f.has("completion")) {
    c.completion =
        choice_of<C::Completion>(doc, f, "completion", {{"er", C::Completion::kEr}, {"poll", C::Completion::kPoll}});
  }
  if (f.has("ms_open_letter")) c.ms_open_letter = choice_of<char>(doc, f, "ms_open_letter", {{"O", 'O'}, {"C", 'C'}});
  return c;
}

RobotSpec read_robot(const Doc& doc, Names& names, const YAML::Node& n, const std::filesystem::path& base_dir) {
  Fields f(doc, n, "robot",
           {"name", "urdf", "base", "home", "park", "grip_force", "driver", "serial", "base_link", "flange_link", "tool_link",
            "gripper", "package_path", "meshes", "val2", "movemaster"},
           true);
  RobotSpec r;
  r.where = doc.at(n);
  r.name = names.take(f, "robot");
  const std::string urdf = f.text("urdf");
  r.urdf = std::filesystem::path(urdf).is_absolute() ? std::filesystem::path(urdf) : base_dir / urdf;
  r.urdf = r.urdf.lexically_normal();
  if (const std::string problem = not_a_file(r.urdf); !problem.empty()) {
    doc.fail(f.node("urdf"), fmt::format("unknown robot model for robot '{}': URDF file '{}' {}", r.name,
                                         r.urdf.string(), problem));
  }
  r.base = read_pose(doc, f.node("base"), f.field("base"));
  for (double deg : f.numbers("home")) r.home.push_back(deg * kDeg);
  if (f.has("park")) {
    for (double deg : f.numbers("park")) r.park.push_back(deg * kDeg);
  }
  read_robot_model_fields(doc, f, base_dir, r);
  if (f.has("grip_force")) {
    r.grip_force = f.positive("grip_force");
    if (r.grip_force > 200) {
      doc.fail(f.node("grip_force"),
               fmt::format("{} must be at most 200 N, got {}", f.field("grip_force"), r.grip_force));
    }
  }
  const std::string driver = f.has("driver") ? f.text("driver") : "sim";
  if (driver == "sim") {
    r.driver = DriverKind::kSim;
  } else if (driver == "movemaster") {
    r.driver = DriverKind::kMovemaster;
  } else if (driver == "val2") {
    r.driver = DriverKind::kVal2;
  } else {
    doc.fail(f.node("driver"), fmt::format("{} must be sim, movemaster or val2, got '{}'", f.field("driver"), driver));
  }
  if (f.has("serial")) {
    r.serial = read_serial(doc, f.node("serial"), r.name, r.driver);
  } else if (r.driver != DriverKind::kSim) {
    doc.fail(
        n, fmt::format("robot '{}' uses the {} driver and needs 'serial' settings (at least 'port')", r.name, driver));
  }
  if (f.has("val2")) r.val2 = read_val2(doc, f.node("val2"), r.name);
  if (f.has("movemaster")) r.movemaster = read_movemaster(doc, f.node("movemaster"), r.name);
  return r;
}

// A colour: [r, g, b] or [r, g, b, a], values 0..1.
Eigen::Vector4d read_rgba(const Doc& doc, const Fields& f, const std::string& key) {
  const auto rgba = f.numbers(key);
  if (rgba.size() != 3 && rgba.size() != 4) {
    doc.fail(f.node(key), fmt::format("{} must be [r, g, b] or [r, g, b, a] with values 0..1, got {} numbers",
                                      f.field(key), rgba.size()));
  }
  for (double c : rgba) {
    if (c < 0 || c > 1) doc.fail(f.node(key), fmt::format("{} must have values 0..1, got {}", f.field(key), c));
  }
  return {rgba[0], rgba[1], rgba[2], rgba.size() == 4 ? rgba[3] : 1.0};
}

// An address on the cell's I/O unit (a coil or a discrete input): a whole number 0..65535.
IoAddress read_io_address(const Doc& doc, const Fields& f, const std::string& key) {
  const double v = f.number(key);
  if (v != std::floor(v) || v < 0 || v > 65535) {
    doc.fail(f.node(key), fmt::format("{} must be an address of the cell's I/O unit, a whole number 0..65535, got {}",
                                      f.field(key), v));
  }
  return {static_cast<int>(v), doc.at(f.node(key))};
}

// A photo-eye's `name` (or `fallback`) and `io`, taken into the cell's name space.
void read_eye(const Doc& doc, Names& names, const Fields& f, const std::string& fallback, std::string& name,
              IoAddress& io) {
  name = f.has("name") ? f.text("name") : fallback;
  names.take_text(name, f.has("name") ? f.node("name") : f.map(), "sensor");
  if (f.has("io")) io = read_io_address(doc, f, "io");
}

// One of the cell's digital signals (a wire between the robot controllers and a sensor or a belt's drive): a whole
// number 1..kCellSignals.
int read_signal(const Doc& doc, const Fields& f, const char* key) {
  const double v = f.number(key);
  if (v != std::floor(v) || v < 1 || v > kCellSignals) {
    doc.fail(f.node(key), fmt::format("{} must be a whole number 1..{} (the cell's digital signals), got {}",
                                      f.field(key), kCellSignals, v));
  }
  return static_cast<int>(v);
}

ConveyorSpec read_conveyor(const Doc& doc, Names& names, const YAML::Node& n) {
  Fields f(doc, n, "conveyor",
           {"name", "pose", "length", "width", "height", "speed", "enter", "leave", "stop", "sensor", "drop_sensor",
            "accumulate", "guides", "io", "run_signal"},
           true);
  ConveyorSpec c;
  c.where = doc.at(n);
  c.name = names.take(f, "conveyor");
  c.pose = read_pose(doc, f.node("pose"), f.field("pose"));
  c.length = f.within("length", kBodySize);
  c.width = f.within("width", kBodySize);
  c.height = f.within("height", kBodySize);
  c.speed = f.number("speed");
  // The belt runs along +x of the conveyor's pose; a conveyor running the other way is turned by its yaw.
  if (c.speed < 0 || c.speed > 2.0) {
    doc.fail(f.node("speed"), fmt::format("{} must be within 0..2 m/s (the belt runs along the pose's +x axis; turn "
                                          "the pose to reverse it), got {}",
                                          f.field("speed"), c.speed));
  }
  c.enter = f.non_negative_or("enter", 0.1 * c.length);
  c.leave = f.non_negative_or("leave", 0.9 * c.length);
  for (const char* key : {"enter", "leave"}) {
    const double v = key == std::string("enter") ? c.enter : c.leave;
    if (v > c.length) {
      doc.fail(f.has(key) ? f.node(key) : n,
               fmt::format("{} must lie on the belt (0..{} m), got {}", f.field(key), c.length, v));
    }
  }
  if (c.leave <= c.enter) {
    doc.fail(f.has("leave") ? f.node("leave") : n,
             fmt::format("conveyor '{}': parts enter at {} m and must leave downstream of that, but leave at {} m",
                         c.name, c.enter, c.leave));
  }
  c.stop = f.boolean_or("stop", false);
  if (f.has("sensor")) {
    // The part-present photo-eye sits at the stop bar: without one no part ever rests at a fixed point.
    if (!c.stop) {
      doc.fail(f.node("sensor"),
               fmt::format("conveyor '{}': a part-present sensor sits at the stop bar; set 'stop: true'", c.name));
    }
    Fields sf(doc, f.node("sensor"), fmt::format("the sensor of conveyor '{}'", c.name), {"signal", "name", "io"});
    c.stop_eye = true;
    if (sf.has("signal")) {
      c.sensor = read_signal(doc, sf, "signal");
      c.sensor_where = doc.at(sf.node("signal"));
    }
    read_eye(doc, names, sf, c.name + "_stop", c.stop_eye_name, c.stop_eye_io);
  }
  if (f.has("drop_sensor")) {
    Fields df(doc, f.node("drop_sensor"), fmt::format("the drop sensor of conveyor '{}'", c.name), {"name", "io"});
    c.drop_eye = true;
    read_eye(doc, names, df, c.name + "_drop", c.drop_eye_name, c.drop_eye_io);
  }
  c.guides = f.non_negative_or("guides", 0.0);
  if (c.guides > 0.2) {
    doc.fail(f.node("guides"), fmt::format("{} is the guides' height above the belt, 0..0.2 m, got {}",
                                           f.field("guides"), c.guides));
  }
  // A belt that accumulates stops while its stop photo-eye is blocked: it needs one.
  c.accumulate = f.boolean_or("accumulate", c.stop_eye);
  if (c.accumulate && !c.stop_eye) {
    doc.fail(f.node("accumulate"),
             fmt::format("conveyor '{}' accumulates while a part blocks the photo-eye at its stop bar, and has none: "
                         "add 'sensor: {{}}' (with 'stop: true')",
                         c.name));
  }
  if (f.has("run_signal")) {
    c.run_signal = read_signal(doc, f, "run_signal");
    c.run_signal_where = doc.at(f.node("run_signal"));
  }
  if (f.has("io")) {
    Fields io(doc, f.node("io"), fmt::format("the io of conveyor '{}'", c.name), {"run"});
    if (io.has("run")) c.run_io = read_io_address(doc, io, "run");
  }
  return c;
}

MachineSpec read_machine(const Doc& doc, Names& names, const YAML::Node& n) {
  Fields f(doc, n, "machine", {"name", "pose", "size", "fixture", "process_time", "processed_colour", "io"}, true);
  MachineSpec m;
  m.where = doc.at(n);
  m.name = names.take(f, "machine");
  m.pose = read_pose(doc, f.node("pose"), f.field("pose"));
  m.size = f.vec3("size");
  if ((m.size.array() <= 0).any()) {
    doc.fail(f.node("size"), fmt::format("{} must be three sizes greater than 0", f.field("size")));
  }
  m.size = f.vec3_within("size", kBodySize);
  Fields fx(doc, f.node("fixture"), fmt::format("the fixture of machine '{}'", m.name), {"size"});
  m.fixture_size = fx.vec3("size");
  if ((m.fixture_size.array() <= 0).any()) {
    doc.fail(fx.node("size"), fmt::format("{} must be three sizes greater than 0", fx.field("size")));
  }
  m.fixture_size = fx.vec3_within("size", kBodySize);
  if (m.fixture_size.x() > m.size.x() || m.fixture_size.y() > m.size.y()) {
    doc.fail(fx.node("size"), fmt::format("the fixture of machine '{}' ({} x {} m) must fit on the machine's top "
                                          "({} x {} m)",
                                          m.name, m.fixture_size.x(), m.fixture_size.y(), m.size.x(), m.size.y()));
  }
  if (!f.has("process_time")) doc.fail(n, fmt::format("machine '{}' has no field 'process_time'", m.name));
  m.process_time = f.within("process_time", Range{0, bounds::kMaxTime, false, "s"});
  if (f.has("processed_colour")) m.processed_rgba = read_rgba(doc, f, "processed_colour");
  if (f.has("io")) {
    Fields io(doc, f.node("io"), fmt::format("the io of machine '{}'", m.name), {"start", "busy", "done"});
    if (io.has("start")) m.start_io = read_io_address(doc, io, "start");
    if (io.has("busy")) m.busy_io = read_io_address(doc, io, "busy");
    if (io.has("done")) m.done_io = read_io_address(doc, io, "done");
  }
  return m;
}

std::vector<std::string> read_names(const Doc& doc, const Fields& f, const std::string& key) {
  const YAML::Node& n = f.node(key);
  if (!n.IsSequence()) doc.fail(n, fmt::format("{} must be a list of names, got {}", f.field(key), describe(n)));
  std::vector<std::string> out;
  for (const auto& e : n) out.push_back(f.text_of(e, f.field(key)));
  return out;
}

// The node a reference came from, so that "unknown reference" errors point at it.
struct Ref {
  std::string name;
  YAML::Node node;
};

struct PendingLocation {
  LocationSpec spec;
  std::optional<Ref> at;  // "<conveyor>.enter", "<conveyor>.leave" or "<machine>.fixture"
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  std::vector<YAML::Node> reach_nodes;
};

PendingLocation read_location(const Doc& doc, Names& names, const YAML::Node& n) {
  Fields f(doc, n, "location", {"name", "pose", "at", "offset", "yaw", "reach", "grasp_height", "approach_height"},
           true);
  PendingLocation p;
  p.spec.where = doc.at(n);
  p.spec.name = names.take(f, "location");
  if (f.has("pose") == f.has("at")) {
    doc.fail(n, fmt::format("location '{}' needs exactly one of 'pose' (world) or 'at' (e.g. input.leave, "
                            "machine.fixture)",
                            p.spec.name));
  }
  if (f.has("pose")) {
    if (f.has("offset") || f.has("yaw")) {
      doc.fail(f.has("offset") ? f.node("offset") : f.node("yaw"),
               fmt::format("location '{}': 'offset' and 'yaw' go with 'at', not with 'pose'", p.spec.name));
    }
    p.spec.pose = read_pose(doc, f.node("pose"), f.field("pose"));
  } else {
    p.at = Ref{f.text("at"), f.node("at")};
    if (f.has("offset")) p.offset = f.vec3_within("offset", kCoordinate);
    if (f.has("yaw")) p.spec.pose.rpy.z() = f.within("yaw", kAngleDeg) * kDeg;
  }
  if (f.has("reach")) {
    p.spec.reach = read_names(doc, f, "reach");
    for (const auto& e : f.node("reach")) p.reach_nodes.push_back(e);
  }
  p.spec.grasp_height = f.within_or("grasp_height", p.spec.grasp_height, kHeight);
  p.spec.approach_height = f.within_or("approach_height", p.spec.approach_height, kHeight);
  return p;
}

struct PendingWorkpiece {
  WorkpieceSpec spec;
  std::optional<Ref> on;
};

PendingWorkpiece read_workpiece(const Doc& doc, Names& names, const YAML::Node& n) {
  Fields f(doc, n, "workpiece", {"name", "shape", "size", "mass", "colour", "pose", "on"}, true);
  PendingWorkpiece p;
  WorkpieceSpec& w = p.spec;
  w.where = doc.at(n);
  w.name = names.take(f, "workpiece");
  const std::string shape = f.text("shape");
  if (shape == "box") {
    w.shape = Shape::kBox;
    w.size = f.vec3("size");
  } else if (shape == "cylinder") {
    w.shape = Shape::kCylinder;
    auto v = f.numbers("size");
    if (v.size() != 2) {
      doc.fail(f.node("size"),
               fmt::format("{} of a cylinder must be [diameter, height], got {} numbers", f.field("size"), v.size()));
    }
    w.size = {v[0], v[0], v[1]};
  } else {
    doc.fail(f.node("shape"), fmt::format("{} must be box or cylinder, got '{}'", f.field("shape"), shape));
  }
  if ((w.size.array() <= 0).any()) {
    doc.fail(f.node("size"), fmt::format("{} must be greater than 0 in every dimension", f.field("size")));
  }
  for (const auto& e : f.node("size")) f.within_of(e, f.field("size"), kPartSize);
  w.mass = f.within("mass", Range{bounds::kMinMass, bounds::kMaxMass, false, "kg"});
  w.rgba = read_rgba(doc, f, "colour");
  if (f.has("pose") == f.has("on")) {
    doc.fail(n, fmt::format("workpiece '{}' needs exactly one of 'pose' (its centre in the world) or 'on' (a "
                            "conveyor or location)",
                            w.name));
  }
  if (f.has("pose")) {
    w.pose = read_pose(doc, f.node("pose"), f.field("pose"));
    // Its lowest point: the centre less the half extents along z of its turned box (a cylinder: its end's rim).
    const Eigen::Matrix3d r = w.pose.rotation();
    double below = 0;
    for (int i = 0; i < 3; ++i) below += std::abs(r(2, i)) * w.size[i] / 2;
    if (w.shape == Shape::kCylinder) {
      below = std::abs(r(2, 2)) * w.size.z() / 2 + std::hypot(r(2, 0), r(2, 1)) * w.size.x() / 2;
    }
    if (w.pose.xyz.z() - below < -bounds::kOverlap) {
      doc.fail(f.node("pose"), fmt::format("workpiece '{}' reaches below the floor: its centre is at z = {} m and "
                                           "its lowest point at z = {:.4f} m",
                                           w.name, w.pose.xyz.z(), w.pose.xyz.z() - below));
    }
  } else {
    p.on = Ref{f.text("on"), f.node("on")};
  }
  return p;
}

Eigen::Vector3d rpy_of(const Eigen::Matrix3d& r);

// Rotation whose -z axis looks from `from` to `to` and whose +y axis (image up) is as close to `up` as possible.
// Looking straight along `up`, image up is the world +y axis instead.
Eigen::Vector3d look_at_rpy(const Eigen::Vector3d& from, const Eigen::Vector3d& to, Eigen::Vector3d up) {
  const Eigen::Vector3d z = (from - to).normalized();
  if (up.cross(z).norm() < 1e-6) up = Eigen::Vector3d::UnitY();
  if (up.cross(z).norm() < 1e-6) up = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = up.cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return rpy_of(r);
}

// Roll, pitch and yaw (radians) of a rotation R = Rz(yaw) * Ry(pitch) * Rx(roll).
Eigen::Vector3d rpy_of(const Eigen::Matrix3d& r) {
  const double pitch = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  double roll = 0, yaw = 0;
  if (std::abs(std::cos(pitch)) > 1e-9) {
    roll = std::atan2(r(2, 1), r(2, 2));
    yaw = std::atan2(r(1, 0), r(0, 0));
  } else {
    yaw = std::atan2(-r(0, 1), r(1, 1));
  }
  return {roll, pitch, yaw};
}

// A file named in field `key` of `f`, relative to the cell's directory: absolute; InputError at the field when it is
// not a file.
std::filesystem::path file_field(const Doc& doc, const Fields& f, const std::string& key,
                                 const std::filesystem::path& base_dir, const std::string& what) {
  const std::string text = f.text(key);
  std::filesystem::path p = std::filesystem::path(text).is_absolute() ? std::filesystem::path(text) : base_dir / text;
  p = p.lexically_normal();
  if (const std::string problem = not_a_file(p); !problem.empty()) {
    doc.fail(f.node(key), fmt::format("{} '{}' {}", what, p.string(), problem));
  }
  return p;
}

CameraSpec read_camera(const Doc& doc, Names& names, const YAML::Node& n, const std::filesystem::path& base_dir) {
  Fields f(doc, n, "camera",
           {"name", "pose", "position", "look_at", "up", "resolution", "fovy", "intrinsics", "calibration"}, true);
  CameraSpec c;
  c.where = doc.at(n);
  c.name = names.take(f, "camera");
  if (f.has("pose") == f.has("position")) {
    doc.fail(n, fmt::format("camera '{}' needs exactly one of 'pose' or 'position' with 'look_at'", c.name));
  }
  if (f.has("pose")) {
    if (f.has("look_at"))
      doc.fail(f.node("look_at"), fmt::format("camera '{}': 'look_at' goes with 'position'", c.name));
    c.pose = read_pose(doc, f.node("pose"), f.field("pose"));
  } else {
    if (!f.has("look_at")) doc.fail(n, fmt::format("camera '{}' has 'position' but no 'look_at'", c.name));
    c.pose.xyz = f.vec3_within("position", kCoordinate);
    const Eigen::Vector3d target = f.vec3_within("look_at", kCoordinate);
    if ((target - c.pose.xyz).norm() < 1e-6) {
      doc.fail(f.node("look_at"), fmt::format("camera '{}' looks at its own position", c.name));
    }
    Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    if (f.has("up")) {
      up = f.vec3_within("up", kCoordinate);
      if (up.norm() < 1e-9) doc.fail(f.node("up"), fmt::format("{} must not be zero", f.field("up")));
      up.normalize();
    }
    c.pose.rpy = look_at_rpy(c.pose.xyz, target, up);
  }
  const auto res = f.numbers("resolution", 2);
  for (double v : res) {
    if (v != std::floor(v) || v < 16 || v > 4096) {
      doc.fail(f.node("resolution"),
               fmt::format("{} must be two whole numbers of pixels 16..4096, got {}", f.field("resolution"), v));
    }
  }
  c.width = static_cast<int>(res[0]);
  c.height = static_cast<int>(res[1]);
  const double fovy = f.number("fovy");
  if (!(fovy > 0 && fovy < 180)) {
    doc.fail(f.node("fovy"), fmt::format("{} must be between 0 and 180 degrees, got {}", f.field("fovy"), fovy));
  }
  c.fovy = fovy * kDeg;
  c.nominal = c.pose;
  if (f.has("intrinsics")) {
    c.intrinsics = file_field(doc, f, "intrinsics", base_dir, fmt::format("camera '{}': intrinsics file", c.name));
  }
  if (f.has("calibration")) {
    c.calibration = file_field(doc, f, "calibration", base_dir, fmt::format("camera '{}': calibration file", c.name));
    c.pose = read_camera_calibration(c.calibration, c.name);
  }
  return c;
}

LightSpec read_light(const Doc& doc, Names& names, const YAML::Node& n) {
  Fields f(doc, n, "light", {"name", "position", "direction", "look_at", "directional", "cast_shadow", "diffuse"},
           true);
  LightSpec l;
  l.where = doc.at(n);
  l.name = names.take(f, "light");
  l.position = f.vec3_within("position", kCoordinate);
  if (f.has("direction") && f.has("look_at")) {
    doc.fail(f.node("look_at"), fmt::format("light '{}': give 'direction' or 'look_at', not both", l.name));
  }
  if (f.has("direction")) l.direction = f.vec3_within("direction", kCoordinate);
  if (f.has("look_at")) l.direction = f.vec3_within("look_at", kCoordinate) - l.position;
  if (l.direction.norm() < 1e-9) {
    doc.fail(f.has("direction") ? f.node("direction") : f.node("look_at"),
             fmt::format("light '{}' has no direction (zero vector)", l.name));
  }
  l.direction.normalize();
  l.directional = f.boolean_or("directional", false);
  l.cast_shadow = f.boolean_or("cast_shadow", true);
  if (f.has("diffuse")) {
    l.diffuse = f.vec3("diffuse");
    if ((l.diffuse.array() < 0).any() || (l.diffuse.array() > 1).any()) {
      doc.fail(f.node("diffuse"), fmt::format("{} must have values 0..1", f.field("diffuse")));
    }
  }
  return l;
}

HandoverSpec read_handover(const Doc& doc, Names& names, const YAML::Node& n, std::vector<YAML::Node>& robot_nodes) {
  Fields f(doc, n, "the hand-over", {"name", "pose", "grasps"});
  HandoverSpec h;
  h.where = doc.at(n);
  if (f.has("name")) {
    h.name = names.take(f, "hand-over");
  } else {
    h.name = "handover";
  }
  h.pose = read_pose(doc, f.node("pose"), f.field("pose"));
  const YAML::Node& g = f.node("grasps");
  if (!g.IsSequence() || g.size() < 2) {
    doc.fail(g, fmt::format("{} must list at least two robots' grasps, e.g. - {{robot: puma, approach: down}}",
                            f.field("grasps")));
  }
  for (const auto& e : g) {
    Fields gf(doc, e, "a hand-over grasp", {"robot", "approach", "offset"});
    HandoverGrasp grasp;
    grasp.robot = gf.text("robot");
    robot_nodes.push_back(gf.node("robot"));
    const std::string approach = gf.has("approach") ? gf.text("approach") : "down";
    if (approach == "down") {
      grasp.approach = Approach::kDown;
    } else if (approach == "side") {
      grasp.approach = Approach::kSide;
    } else {
      doc.fail(gf.node("approach"), fmt::format("{} must be down or side, got '{}'", gf.field("approach"), approach));
    }
    if (gf.has("offset")) grasp.offset = gf.vec3_within("offset", kNear);
    for (const auto& other : h.grasps) {
      if (other.robot == grasp.robot) {
        doc.fail(gf.node("robot"), fmt::format("robot '{}' is listed twice in the hand-over", grasp.robot));
      }
    }
    h.grasps.push_back(grasp);
  }
  return h;
}

}  // namespace

// --- Public -------------------------------------------------------------------------------------------------------

Eigen::Matrix3d Pose::rotation() const {
  return (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Isometry3d Pose::transform() const {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = rotation();
  t.translation() = xyz;
  return t;
}

Eigen::Vector3d ConveyorSpec::belt_point(double s) const {
  return pose.transform() * Eigen::Vector3d(s - length / 2, 0, height);
}

Pose MachineSpec::fixture_top() const {
  Pose p;
  p.xyz = pose.transform() * Eigen::Vector3d(0, 0, size.z() + fixture_size.z());
  p.rpy = Eigen::Vector3d(0, 0, pose.rpy.z());
  return p;
}

namespace {
template <typename T>
const T* find_named(const std::vector<T>& v, std::string_view name) {
  for (const auto& e : v) {
    if (e.name == name) return &e;
  }
  return nullptr;
}
}  // namespace

const RobotSpec* CellDescription::find_robot(std::string_view n) const {
  return find_named(robots, n);
}
const ConveyorSpec* CellDescription::find_conveyor(std::string_view n) const {
  return find_named(conveyors, n);
}
const MachineSpec* CellDescription::find_machine(std::string_view n) const {
  return find_named(machines, n);
}
const LocationSpec* CellDescription::fixture_location(const MachineSpec& m) const {
  const Eigen::Vector3d top = m.fixture_top().xyz;
  const LocationSpec* found = nullptr;
  for (const LocationSpec& l : locations) {
    if ((l.pose.xyz - top).norm() < 1e-3) found = &l;
  }
  return found;
}
const WorkpieceSpec* CellDescription::find_workpiece(std::string_view n) const {
  return find_named(workpieces, n);
}
const LocationSpec* CellDescription::find_location(std::string_view n) const {
  return find_named(locations, n);
}
const CameraSpec* CellDescription::find_camera(std::string_view n) const {
  return find_named(cameras, n);
}

// The cell's I/O list is one list: no two outputs share a coil, no two inputs a discrete input.
void check_io_addresses(const CellDescription& cell) {
  struct Use {
    std::string what;
    int line;
  };
  std::map<int, Use> coils, inputs;
  auto add = [&](std::map<int, Use>& used, const char* kind, const IoAddress& io, const std::string& what) {
    if (!io.wired()) return;
    const int address = io.address;
    auto [it, fresh] = used.emplace(address, Use{what, io.where.line});
    if (!fresh) {
      throw InputError(io.where, fmt::format("{} {} is wired to {} and already to {} (line {}): each signal of the "
                                          "cell's I/O unit has one address",
                                          kind, address, what, it->second.what, it->second.line));
    }
  };
  for (const auto& c : cell.conveyors) {
    add(coils, "coil", c.run_io, fmt::format("the run of conveyor '{}'", c.name));
    add(inputs, "discrete input", c.stop_eye_io, fmt::format("sensor '{}'", c.stop_eye_name));
    add(inputs, "discrete input", c.drop_eye_io, fmt::format("sensor '{}'", c.drop_eye_name));
  }
  for (const auto& m : cell.machines) {
    add(coils, "coil", m.start_io, fmt::format("the start of machine '{}'", m.name));
    add(inputs, "discrete input", m.busy_io, fmt::format("the busy signal of machine '{}'", m.name));
    add(inputs, "discrete input", m.done_io, fmt::format("the done signal of machine '{}'", m.name));
  }
}

CellDescription parse_cell(std::string_view yaml_text, const std::filesystem::path& source) {
  const Doc doc(source.string());
  const YAML::Node root = yaml::load(yaml_text, doc, "not valid YAML");
  if (!root.IsDefined() || root.IsNull()) throw InputError({source.string(), 0, 0}, "the cell description is empty");
  Fields top(doc, root, "the cell description",
             {"name", "timestep", "robots", "conveyors", "machines", "handover", "workpieces", "locations", "cameras",
              "lights"});
  CellDescription cell;
  cell.source = source;
  cell.name = top.has("name") ? top.text("name") : source.stem().string();
  // The cell's name becomes the MJCF model's name and goes on the report page: the rule of every other name.
  if (top.has("name") && !valid_name(cell.name)) {
    doc.fail(top.node("name"), fmt::format("the cell's name '{}' is not valid: use letters, digits, '_' and '-', "
                                           "starting with a letter or '_', at most 64 characters",
                                           shown_name(cell.name)));
  }
  cell.timestep = top.number_or("timestep", cell.timestep);
  if (!(cell.timestep >= 1e-4 && cell.timestep <= 0.01)) {
    doc.fail(top.node("timestep"), fmt::format("'timestep' must be within 0.0001..0.01 s, got {}", cell.timestep));
  }
  Names names(doc);
  const std::filesystem::path base_dir = source.parent_path();

  for (const auto& n : list_of(doc, top, "robots")) cell.robots.push_back(read_robot(doc, names, n, base_dir));
  if (cell.robots.empty()) doc.fail(root, "the cell has no robots: 'robots' must list at least one");
  for (const auto& n : list_of(doc, top, "conveyors")) {
    cell.conveyors.push_back(read_conveyor(doc, names, n));
    const ConveyorSpec& c = cell.conveyors.back();
    for (std::size_t i = 0; c.sensor != 0 && i + 1 < cell.conveyors.size(); ++i) {
      if (cell.conveyors[i].sensor == c.sensor) {
        doc.fail(c.sensor_where,
                 fmt::format("conveyor '{}': signal {} is already the sensor of conveyor '{}' "
                             "(line {}); each sensor needs its own input",
                             c.name, c.sensor, cell.conveyors[i].name, cell.conveyors[i].sensor_where.line));
      }
    }
    // A belt's run wire is its own: no sensor drives it, no other belt shares it.
    for (std::size_t i = 0; i < cell.conveyors.size(); ++i) {
      const ConveyorSpec& o = cell.conveyors[i];
      const bool self = i + 1 == cell.conveyors.size();
      if (c.run_signal != 0 && c.run_signal == o.sensor) {
        doc.fail(c.run_signal_where, fmt::format("conveyor '{}': signal {} is the sensor of conveyor '{}' (line {}); a "
                                                 "belt's run_signal needs a wire of its own",
                                                 c.name, c.run_signal, o.name, o.sensor_where.line));
      }
      if (!self && o.run_signal != 0 && (o.run_signal == c.run_signal || o.run_signal == c.sensor)) {
        const bool run = o.run_signal == c.run_signal;
        doc.fail(run ? c.run_signal_where : c.sensor_where,
                 fmt::format("conveyor '{}': signal {} is already the run_signal of conveyor '{}' (line {}); each "
                             "wire has one use",
                             c.name, o.run_signal, o.name, o.run_signal_where.line));
      }
    }
  }
  for (const auto& n : list_of(doc, top, "machines")) cell.machines.push_back(read_machine(doc, names, n));
  check_io_addresses(cell);

  auto check_robot_ref = [&](const std::string& robot, const YAML::Node& node, const std::string& user) {
    if (cell.find_robot(robot) == nullptr) {
      std::string known;
      for (const auto& r : cell.robots) known += fmt::format("{}{}", known.empty() ? "" : ", ", r.name);
      doc.fail(node, fmt::format("unknown robot '{}' in {} (robots: {})", robot, user, known));
    }
  };

  if (auto h = top.get("handover")) {
    std::vector<YAML::Node> robot_nodes;
    cell.handover = read_handover(doc, names, *h, robot_nodes);
    for (std::size_t i = 0; i < cell.handover->grasps.size(); ++i) {
      check_robot_ref(cell.handover->grasps[i].robot, robot_nodes[i], "the hand-over");
    }
  }

  // Locations first: workpieces may rest on them.
  for (const auto& n : list_of(doc, top, "locations")) {
    PendingLocation p = read_location(doc, names, n);
    for (std::size_t i = 0; i < p.spec.reach.size(); ++i) {
      check_robot_ref(p.spec.reach[i], p.reach_nodes[i], fmt::format("the 'reach' of location '{}'", p.spec.name));
    }
    if (p.at) {
      const std::string& ref = p.at->name;
      const auto dot = ref.rfind('.');
      const std::string object = dot == std::string::npos ? ref : ref.substr(0, dot);
      const std::string point = dot == std::string::npos ? "" : ref.substr(dot + 1);
      const double yaw = p.spec.pose.rpy.z();
      if (const ConveyorSpec* c = cell.find_conveyor(object)) {
        if (point != "enter" && point != "leave") {
          doc.fail(p.at->node, fmt::format("location '{}': a conveyor point is '{}.enter' or '{}.leave', got '{}'",
                                           p.spec.name, object, object, ref));
        }
        p.spec.pose.xyz = c->belt_point(point == "enter" ? c->enter : c->leave);
        p.spec.pose.rpy = Eigen::Vector3d(0, 0, c->pose.rpy.z() + yaw);
      } else if (const MachineSpec* m = cell.find_machine(object)) {
        if (point != "fixture") {
          doc.fail(p.at->node,
                   fmt::format("location '{}': a machine point is '{}.fixture', got '{}'", p.spec.name, object, ref));
        }
        p.spec.pose = m->fixture_top();
        p.spec.pose.rpy.z() += yaw;
      } else {
        doc.fail(p.at->node, fmt::format("unknown reference '{}' in location '{}': expected <conveyor>.enter, "
                                         "<conveyor>.leave or <machine>.fixture",
                                         ref, p.spec.name));
      }
      p.spec.pose.xyz += p.offset;
    }
    cell.locations.push_back(p.spec);
  }

  // Parts put on a conveyor stand in a row from its entry point downstream, 2 cm apart, in reverse order of listing:
  // the first listed is furthest along and reaches the end of the belt (and the robot) first.
  std::map<std::string, std::vector<std::pair<std::size_t, YAML::Node>>> rows;  // conveyor -> (part, `on` node)
  for (const auto& n : list_of(doc, top, "workpieces")) {
    PendingWorkpiece p = read_workpiece(doc, names, n);
    WorkpieceSpec& w = p.spec;
    if (p.on) {
      w.on = p.on->name;
      if (const ConveyorSpec* c = cell.find_conveyor(w.on)) {
        rows[c->name].emplace_back(cell.workpieces.size(), p.on->node);
        w.pose.rpy = Eigen::Vector3d(0, 0, c->pose.rpy.z());
      } else if (const LocationSpec* l = cell.find_location(w.on)) {
        w.pose.xyz = l->pose.xyz + Eigen::Vector3d(0, 0, w.size.z() / 2);
        w.pose.rpy = Eigen::Vector3d(0, 0, l->pose.rpy.z());
      } else {
        doc.fail(p.on->node, fmt::format("unknown reference '{}' in workpiece '{}': 'on' names a conveyor or a "
                                         "location",
                                         w.on, w.name));
      }
    }
    cell.workpieces.push_back(w);
  }
  constexpr double kRowGap = 0.02;
  for (const auto& [conveyor, row] : rows) {
    const ConveyorSpec& c = *cell.find_conveyor(conveyor);
    const double limit = c.stop ? c.leave : c.length;
    double s = c.enter;  // centre of the next part, walking downstream from the last listed
    for (auto it = row.rbegin(); it != row.rend(); ++it) {
      WorkpieceSpec& w = cell.workpieces[it->first];
      if (it != row.rbegin()) s += w.size.x() / 2;
      if (s + w.size.x() / 2 > limit + 1e-9) {
        doc.fail(row.back().second,
                 fmt::format("the {} parts put on conveyor '{}' do not fit on it: standing in a row from its entry "
                             "point ({} m) they reach past {} m, where {}",
                             row.size(), c.name, c.enter, limit, c.stop ? "its stop is" : "the belt ends"));
      }
      w.pose.xyz = c.belt_point(s) + Eigen::Vector3d(0, 0, w.size.z() / 2);
      s += w.size.x() / 2 + kRowGap;
    }
  }
  // Nothing may start inside something else (a part inside the machine, a machine over a conveyor).
  if (const std::vector<Overlap> overlaps = check_overlaps(cell); !overlaps.empty()) {
    const Overlap& o = overlaps.front();
    doc.fail(o.where, fmt::format("{} overlaps {} by {:.1f} mm at the start: bodies may touch but not overlap (by more "
                                  "than {} mm)",
                                  o.body, o.other, o.depth * 1000, bounds::kOverlap * 1000));
  }
  for (const auto& n : list_of(doc, top, "cameras")) cell.cameras.push_back(read_camera(doc, names, n, base_dir));
  for (const auto& n : list_of(doc, top, "lights")) cell.lights.push_back(read_light(doc, names, n));

  // The robots' models: home configurations must fit them, and every location and the hand-over must be reachable.
  for (std::size_t i = 0; i < cell.robots.size(); ++i) {
    const RobotSpec& r = cell.robots[i];
    const YAML::Node robot_node = list_of(doc, top, "robots")[i];
    std::optional<models::KinematicChain> loaded;
    try {
      loaded = models::robot_chain(r);
    } catch (const InputError& e) {
      // Point at the robot's `urdf` field, and keep the URDF's own file and line in the message.
      doc.fail(robot_node["urdf"], fmt::format("robot '{}': its URDF cannot be used: {}", r.name, e.what()));
    }
    const models::KinematicChain& chain = *loaded;
    const YAML::Node home = robot_node["home"];
    if (r.home.size() != chain.dof()) {
      doc.fail(home, fmt::format("robot '{}': 'home' has {} angles but {} has {} joints from {} to {} ({})", r.name,
                                 r.home.size(), r.urdf.filename().string(), chain.dof(), chain.base_link(),
                                 chain.tip_link(),
                                 fmt::join(chain.joint_names(), ", ")));
    }
    for (std::size_t j = 0; j < r.home.size(); ++j) {
      const models::JointLimit lim = chain.limits()[j];
      if (r.home[j] < lim.lower - 1e-9 || r.home[j] > lim.upper + 1e-9) {
        doc.fail(home[j],
                 fmt::format("robot '{}': home angle of {} is {:.2f} deg, outside its limits {:.2f}..{:.2f} "
                             "deg",
                             r.name, chain.joint_names()[j], r.home[j] / kDeg, lim.lower / kDeg, lim.upper / kDeg));
      }
    }
    // The park pose, if any, by the same rules as home.
    const YAML::Node park = robot_node["park"];
    if (!r.park.empty() && r.park.size() != chain.dof()) {
      doc.fail(park, fmt::format("robot '{}': 'park' has {} angles but {} has {} joints", r.name, r.park.size(),
                                 r.urdf.filename().string(), chain.dof()));
    }
    for (std::size_t j = 0; j < r.park.size(); ++j) {
      const models::JointLimit lim = chain.limits()[j];
      if (r.park[j] < lim.lower - 1e-9 || r.park[j] > lim.upper + 1e-9) {
        doc.fail(park[j], fmt::format("robot '{}': park angle of {} is {:.2f} deg, outside its limits {:.2f}..{:.2f} "
                                      "deg",
                                      r.name, chain.joint_names()[j], r.park[j] / kDeg, lim.lower / kDeg,
                                      lim.upper / kDeg));
      }
    }
  }
  for (const ReachCheck& c : check_reach(cell)) {
    if (c.reachable) continue;
    std::string why;
    if (c.distance > c.max_reach) {
      why = fmt::format("it is {:.3f} m from the robot's first joint, beyond its maximum reach of {:.3f} m", c.distance,
                        c.max_reach);
    } else {
      why = fmt::format(
          "it is {:.3f} m from the robot's first joint (maximum reach {:.3f} m) but no joint "
          "configuration within the limits puts the gripper there ({})",
          c.distance, c.max_reach, c.reason);
    }
    doc.fail(c.where,
             fmt::format("{} is out of reach of robot '{}' at its base ({:.3f}, {:.3f}, {:.3f}): {}; "
                         "target ({:.3f}, {:.3f}, {:.3f})",
                         c.target, c.robot, cell.find_robot(c.robot)->base.xyz.x(),
                         cell.find_robot(c.robot)->base.xyz.y(), cell.find_robot(c.robot)->base.xyz.z(), why,
                         c.tcp_world.translation().x(), c.tcp_world.translation().y(), c.tcp_world.translation().z()));
  }
  return cell;
}

CellDescription load_cell(const std::filesystem::path& yaml_file) {
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(yaml_file, ec).lexically_normal();
  std::string text;
  try {
    text = read_file(abs);
  } catch (const InputError& e) {
    throw InputError({yaml_file.string(), 0, 0}, fmt::format("cannot read the cell description: {}", e.problem()));
  }
  return parse_cell(text, abs);
}

namespace {

// One robot's reach test: the IK from home, and if that fails from the other solutions the solver's restarts find.
// A parallel gripper is symmetric under half a turn about its approach axis, so both finger orientations count.
ReachCheck reach_one(const models::KinematicChain& chain, const RobotSpec& robot, std::string target,
                     const std::vector<Eigen::Isometry3d>& candidates, SourceLocation where) {
  ReachCheck c;
  c.target = std::move(target);
  c.robot = robot.name;
  c.where = std::move(where);
  c.max_reach = chain.max_reach();
  const Eigen::Isometry3d base = robot.base.transform();
  const Eigen::VectorXd seed =
      Eigen::Map<const Eigen::VectorXd>(robot.home.data(), static_cast<Eigen::Index>(robot.home.size()));
  for (const Eigen::Isometry3d& world : candidates) {
    const Eigen::Isometry3d local = base.inverse() * world;
    const models::IkResult ik = chain.inverse(local, seed);
    if (c.reason.empty() || ik.status == models::IkStatus::kOk) {
      c.tcp_world = world;
      c.distance = (local.translation() - chain.first_joint_origin()).norm();
      c.reason = ik.reason;
    }
    if (ik.status == models::IkStatus::kOk) {
      c.reachable = true;
      c.q.assign(ik.q.data(), ik.q.data() + ik.q.size());
      c.reason.clear();
      return c;
    }
  }
  return c;
}

}  // namespace

std::vector<ReachCheck> check_reach(const CellDescription& cell) {
  std::map<std::string, models::KinematicChain> chains;
  for (const auto& r : cell.robots) {
    chains.emplace(r.name, models::robot_chain(r));
  }
  std::vector<ReachCheck> out;
  for (const auto& l : cell.locations) {
    for (const auto& name : l.reach) {
      const RobotSpec& r = *cell.find_robot(name);
      const Eigen::Isometry3d base = r.base.transform();
      for (const bool approach : {false, true}) {
        const Eigen::Vector3d point =
            l.pose.xyz + Eigen::Vector3d(0, 0, l.grasp_height + (approach ? l.approach_height : 0.0));
        const double yaw = l.pose.rpy.z();
        out.push_back(reach_one(chains.at(name), r,
                                fmt::format("location '{}' ({})", l.name, approach ? "approach" : "grasp"),
                                {grasp_pose(point, Approach::kDown, yaw, base),
                                 grasp_pose(point, Approach::kDown, yaw + std::numbers::pi, base)},
                                l.where));
      }
    }
  }
  if (cell.handover) {
    const HandoverSpec& h = *cell.handover;
    for (const auto& g : h.grasps) {
      const RobotSpec& r = *cell.find_robot(g.robot);
      const Eigen::Isometry3d base = r.base.transform();
      const Eigen::Vector3d point = h.pose.xyz + g.offset;
      const double yaw = h.pose.rpy.z();
      Eigen::Isometry3d turned = grasp_pose(point, g.approach, yaw, base);
      turned.linear() = turned.linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
      out.push_back(reach_one(chains.at(g.robot), r, fmt::format("the hand-over '{}'", h.name),
                              {grasp_pose(point, g.approach, yaw, base), turned}, h.where));
    }
  }
  return out;
}

Eigen::Isometry3d grasp_pose(const Eigen::Vector3d& point, Approach approach, double yaw,
                             const Eigen::Isometry3d& robot_base) {
  Eigen::Matrix3d r;
  if (approach == Approach::kDown) {
    const Eigen::Vector3d z(0, 0, -1);
    const Eigen::Vector3d y(std::cos(yaw), std::sin(yaw), 0);
    r.col(0) = y.cross(z);
    r.col(1) = y;
    r.col(2) = z;
  } else {
    Eigen::Vector3d d = point - robot_base.translation();
    d.z() = 0;
    if (d.norm() < 1e-6) d = robot_base.linear().col(0);
    d.z() = 0;
    d.normalize();
    const Eigen::Vector3d z = d;
    const Eigen::Vector3d y(-d.y(), d.x(), 0);
    r.col(0) = y.cross(z);
    r.col(1) = y;
    r.col(2) = z;
  }
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = point;
  return t;
}

std::string format_camera_calibration(const std::string& camera, const Eigen::Isometry3d& pose,
                                      const std::string& comment) {
  std::string out;
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) out += line.empty() ? "#\n" : "# " + line + "\n";
  const Eigen::Vector3d p = pose.translation();
  const Eigen::Vector3d rpy = rpy_of(pose.rotation()) / kDeg;
  out += fmt::format("camera: {}\npose: {{xyz: [{:.6f}, {:.6f}, {:.6f}], rpy: [{:.5f}, {:.5f}, {:.5f}]}}\n", camera,
                     p.x(), p.y(), p.z(), rpy.x(), rpy.y(), rpy.z());
  return out;
}

Pose read_camera_calibration(const std::filesystem::path& file, const std::string& camera) {
  const Doc doc(file.string());
  const YAML::Node root = yaml::load(read_file(file), doc, "not valid YAML");
  if (!root.IsDefined() || root.IsNull()) throw InputError({file.string(), 0, 0}, "the camera calibration is empty");
  Fields f(doc, root, "the camera calibration", {"camera", "pose"});
  if (const std::string name = f.text("camera"); name != camera) {
    doc.fail(f.node("camera"), fmt::format("this calibration is of camera '{}', and it is named by camera '{}'",
                                           name, camera));
  }
  return read_pose(doc, f.node("pose"), f.field("pose"));
}

}  // namespace cellwright::models
