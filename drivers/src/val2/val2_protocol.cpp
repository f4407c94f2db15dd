// The VAL II monitor's language (val2_protocol.hpp): locations, WHERE, error lines.
#include "cellwright/drivers/val2/val2_protocol.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <numbers>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers::val2 {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Below this sin(A) the two Z turns are one: T is set to 0 (the error it leaves is of this order, far below the
// 0.001° the numbers are sent with).
constexpr double kSingular = 1e-9;

Eigen::Matrix3d rz(double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

Eigen::Matrix3d ry(double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

// The tool-down frame's half turn about x (its own inverse).
Eigen::Matrix3d tool_down_turn() {
  Eigen::Matrix3d m;
  m << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  return m;
}

// An angle in degrees moved into (−180, 180].
double wrap_degrees(double degrees) {
  double d = std::remainder(degrees, 360.0);
  if (d <= -180.0) d += 360.0;
  return d;
}

// VAL's tool axes at O = A = T = 0 (Orientation::val): columns x = −Z, y = +X, z = −Y.
Eigen::Matrix3d val_zero() {
  Eigen::Matrix3d r;
  r << 0, 1, 0,  //
      0, 0, -1,  //
      -1, 0, 0;
  return r;
}

// O, A, T (degrees) of `r` in VAL's convention. m = r · R0ᵀ = Rz(O)·Rx(A)·Ry(B) with B = −T: its third row is
// (−cos A sin B, sin A, cos A cos B), its second column (−sin O cos A, cos O cos A, sin A). A is taken in [−90, 90].
std::array<double, 3> val_angles(const Eigen::Matrix3d& r) {
  const Eigen::Matrix3d m = r * val_zero().transpose();
  const double cos_a = std::hypot(m(0, 1), m(1, 1));
  const double a = std::atan2(m(2, 1), cos_a);
  double o = 0.0;
  double b = 0.0;
  if (cos_a > kSingular) {
    o = std::atan2(-m(0, 1), m(1, 1));
    b = std::atan2(-m(2, 0), m(2, 2));
  } else {
    // A = ±90: m = Rz(O ∓ T)·Rx(±90); T is 0 and O takes the turn, read from m·Rx(∓90) = Rz(O).
    const Eigen::Matrix3d n = m * Eigen::AngleAxisd(-a, Eigen::Vector3d::UnitX()).toRotationMatrix();
    o = std::atan2(n(1, 0), n(0, 0));
  }
  return {wrap_degrees(o / kDeg), a / kDeg, wrap_degrees(-b / kDeg)};
}

bool is_space(char c) {
  return c == ' ' || c == '\t';
}

std::string lower(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(), [](char c) { return c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c; });
  return out;
}

bool contains(std::string_view text, std::string_view part) {
  return text.find(part) != std::string_view::npos;
}

}  // namespace

std::string format_number(double value) {
  CW_CHECK(std::isfinite(value), "a VAL II number must be finite, not {}", value);
  std::string s = fmt::format("{:.3f}", value);  // fmt ignores the locale unless asked
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  if (s == "-0") return std::string("0");  // (returned, not assigned: GCC 12 warns falsely on the assignment)
  return s;
}

Eigen::Matrix3d oat_rotation(double o, double a, double t, Orientation orientation) {
  if (orientation == Orientation::val) return rz(o * kDeg) * val_zero() * ry(a * kDeg) * rz(t * kDeg);
  Eigen::Matrix3d r = rz(o * kDeg) * ry(a * kDeg) * rz(t * kDeg);
  if (orientation == Orientation::tool_down) r = r * tool_down_turn();
  return r;
}

Location to_location(const Eigen::Isometry3d& pose, Orientation orientation) {
  Location l;
  l.x = pose.translation().x() * 1000.0;
  l.y = pose.translation().y() * 1000.0;
  l.z = pose.translation().z() * 1000.0;
  if (orientation == Orientation::val) {
    const std::array<double, 3> oat = val_angles(pose.rotation());
    l.o = oat[0];
    l.a = oat[1];
    l.t = oat[2];
    return l;
  }
  Eigen::Matrix3d m = pose.rotation();
  if (orientation == Orientation::tool_down) m = m * tool_down_turn();
  // m = Rz(O) Ry(A) Rz(T): its third column is (cos O sin A, sin O sin A, cos A), its third row
  // (−sin A cos T, sin A sin T, cos A).
  const double sin_a = std::hypot(m(0, 2), m(1, 2));
  const double a = std::atan2(sin_a, m(2, 2));
  double o = 0.0;
  double t = 0.0;
  if (sin_a > kSingular) {
    o = std::atan2(m(1, 2), m(0, 2));
    t = std::atan2(m(2, 1), -m(2, 0));
  } else if (m(2, 2) > 0.0) {
    o = std::atan2(m(1, 0), m(0, 0));  // A = 0: m = Rz(O + T)
  } else {
    o = std::atan2(-m(0, 1), m(1, 1));  // A = 180: m = Rz(O − T) Ry(180°)
  }
  l.o = wrap_degrees(o / kDeg);
  l.a = a / kDeg;
  l.t = wrap_degrees(t / kDeg);
  return l;
}

Eigen::Isometry3d to_pose(const Location& location, Orientation orientation) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = oat_rotation(location.o, location.a, location.t, orientation);
  pose.translation() = Eigen::Vector3d(location.x, location.y, location.z) / 1000.0;
  return pose;
}

std::string trans_text(const Location& l) {
  return fmt::format("TRANS({},{},{},{},{},{})", format_number(l.x), format_number(l.y), format_number(l.z),
                     format_number(l.o), format_number(l.a), format_number(l.t));
}

std::string ppoint_text(const std::vector<double>& joints) {
  std::string s = "#PPOINT(";
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (i > 0) s += ',';
    s += format_number(joints[i] / kDeg);
  }
  s += ')';
  return s;
}

std::optional<std::vector<double>> parse_numbers(std::string_view line) {
  std::vector<double> values;
  std::size_t i = 0;
  for (;;) {
    while (i < line.size() && is_space(line[i])) ++i;
    if (i == line.size()) break;
    std::size_t end = i;
    while (end < line.size() && !is_space(line[end])) ++end;
    std::string_view token = line.substr(i, end - i);
    i = end;
    if (token.front() == '+') {  // from_chars takes a minus sign only
      token.remove_prefix(1);
      if (token.empty() || token.front() == '-') return std::nullopt;
    }
    double v = 0.0;
    const auto [stop, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc() || stop != token.data() + token.size() || !std::isfinite(v)) return std::nullopt;
    values.push_back(v);
  }
  if (values.empty()) return std::nullopt;
  return values;
}

namespace {

// The first word of `line` starts with `prefix` (whatever its case).
bool first_word_starts(std::string_view line, std::string_view prefix) {
  std::size_t i = 0;
  while (i < line.size() && is_space(line[i])) ++i;
  return lower(line.substr(i)).starts_with(prefix);
}

Location world_of(const std::vector<double>& n) {
  return {n[0], n[1], n[2], n[3], n[4], n[5]};
}

}  // namespace

bool WhereParser::feed(std::string_view line) {
  const std::optional<std::vector<double>> numbers = parse_numbers(line);
  return layout_ == WhereLayout::val2 ? feed_val2(line, numbers) : feed_as(line, numbers);
}

bool WhereParser::feed_val2(std::string_view line, const std::optional<std::vector<double>>& numbers) {
  switch (stage_) {
    case Stage::start:
      if (!numbers) {
        if (!first_word_starts(line, "x")) return false;
        stage_ = Stage::header;
        return true;
      }
      [[fallthrough]];
    case Stage::header:
      if (!numbers || (numbers->size() != 6 && numbers->size() != 7)) return false;
      reading_.world = world_of(*numbers);
      if (numbers->size() == 7) reading_.hand = (*numbers)[6];
      stage_ = Stage::world;
      return true;
    case Stage::world:
      if (!numbers || numbers->size() != 6) return false;
      reading_.joints = *numbers;
      stage_ = Stage::done;
      return true;
    default:
      return false;
  }
}

bool WhereParser::feed_as(std::string_view line, const std::optional<std::vector<double>>& numbers) {
  const bool six = numbers && numbers->size() == 6;
  switch (stage_) {
    case Stage::start:
      if (numbers || !first_word_starts(line, "jt")) return false;
      stage_ = Stage::joint_header;
      return true;
    case Stage::joint_header:
      if (!six) return false;
      reading_.joints = *numbers;
      stage_ = Stage::joints;
      return true;
    case Stage::joints:
      if (numbers || !first_word_starts(line, "x")) return false;
      stage_ = Stage::world_header;
      return true;
    case Stage::world_header:
      if (!six) return false;
      reading_.world = world_of(*numbers);
      stage_ = Stage::done;
      return true;
    default:
      return false;
  }
}

bool WhereParser::complete() const {
  return stage_ == Stage::done || (layout_ == WhereLayout::val2 && stage_ == Stage::world);
}

std::string_view WhereParser::missing() const {
  if (complete()) return "";
  if (layout_ == WhereLayout::val2) return "the world values";
  switch (stage_) {
    case Stage::start:
    case Stage::joint_header:
      return "the joint angles and the world values";
    default:
      return "the world values";
  }
}

std::optional<WhereParser::Reading> WhereParser::reading() const {
  if (!complete()) return std::nullopt;
  return reading_;
}

bool is_prompt(std::string_view pending, std::string_view prompt) {
  std::string text = without_bells(pending);
  while (!text.empty() && is_space(text.back())) text.pop_back();
  return !text.empty() && text == prompt;
}

std::string without_bells(std::string_view line) {
  std::string out;
  out.reserve(line.size());
  for (const char c : line) {
    if (c != '\a') out += c;
  }
  return out;
}

PositionReading to_position_reading(const WhereParser::Reading& where, Orientation orientation) {
  PositionReading r;
  r.joints.reserve(where.joints.size());
  for (const double j : where.joints) r.joints.push_back(j * kDeg);  // none when the monitor printed none
  r.tool_pose = to_pose(where.world, orientation);
  return r;
}

ErrorCode classify_error(std::string_view line) {
  const std::string words = lower(line);
  if (contains(words, "location out of range") || contains(words, "location too close") ||
      contains(words, "position out of range") || (contains(words, "joint") && contains(words, "limit stop"))) {
    return ErrorCode::unreachable;
  }
  if (contains(words, "unknown instruction") || contains(words, "invalid argument") ||
      contains(words, "illegal value") || contains(words, "syntax error")) {
    return ErrorCode::protocol;
  }
  if (contains(words, "arm power off") || contains(words, "servo error") || contains(words, "emergency stop")) {
    return ErrorCode::hardware;
  }
  return ErrorCode::unknown;
}

}  // namespace cellwright::drivers::val2
