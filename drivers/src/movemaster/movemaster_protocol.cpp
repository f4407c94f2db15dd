// The Movemaster EX language as text and its 5-axis pose convention (movemaster_protocol.hpp).
#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace cellwright::drivers::movemaster {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Half the last digit the controller is sent: a tool point closer than this to the z axis goes out as x = y = 0.
constexpr double kOnAxisMm = 0.05;

// An angle in degrees, in (-180, 180].
double wrap_deg(double deg) {
  double d = std::remainder(deg, 360.0);  // [-180, 180]
  if (d <= -180.0) d += 360.0;
  return d;
}

// The plane's outward direction u and normal w at azimuth theta (radians).
void plane_axes(double theta, Eigen::Vector3d* u, Eigen::Vector3d* w) {
  *u = Eigen::Vector3d(std::cos(theta), std::sin(theta), 0.0);
  *w = Eigen::Vector3d(-std::sin(theta), std::cos(theta), 0.0);
}

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

// A number as WH writes it: [+|-] digits [. digits], at least one digit; at most 15 digits (exact in a double).
std::optional<double> parse_number(std::string_view s) {
  s = trim(s);
  bool negative = false;
  if (!s.empty() && (s.front() == '+' || s.front() == '-')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  std::uint64_t mantissa = 0;
  int digits = 0, decimals = 0;
  bool point = false;
  for (const char c : s) {
    if (c == '.' && !point) {
      point = true;
    } else if (c >= '0' && c <= '9') {
      if (++digits > 15) return std::nullopt;
      mantissa = mantissa * 10 + static_cast<std::uint64_t>(c - '0');
      if (point) ++decimals;
    } else {
      return std::nullopt;
    }
  }
  if (digits == 0) return std::nullopt;
  const double v = static_cast<double>(mantissa) / std::pow(10.0, decimals);
  return negative ? -v : v;
}

}  // namespace

std::string_view line_end_text(LineEnd end) {
  switch (end) {
    case LineEnd::crlf:
      return "\r\n";
    case LineEnd::lf:
      return "\n";
    case LineEnd::cr:
      return "\r";
  }
  return "\r\n";
}

Eigen::Isometry3d to_pose(const Xyzpr& v) {
  const double theta = (v.x == 0.0 && v.y == 0.0) ? 0.0 : std::atan2(v.y, v.x);
  Eigen::Vector3d u, w;
  plane_axes(theta, &u, &w);
  const double p = v.p * kDeg;
  const Eigen::Vector3d a = std::cos(p) * u + std::sin(p) * Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d frame;
  frame << w.cross(a), w, a;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = frame * Eigen::AngleAxisd(v.r * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(v.x, v.y, v.z) / 1000.0;
  return pose;
}

std::optional<Xyzpr> to_xyzpr(const Eigen::Isometry3d& pose, double yaw_tolerance_deg, std::string* problem) {
  const Eigen::Vector3d t = pose.translation() * 1000.0;
  if (std::hypot(t.x(), t.y()) < kOnAxisMm) {
    *problem = fmt::format(
        "the tool point ({:.3f}, {:.3f}, {:.3f}) mm is on the base's z axis: a 5-axis arm has no azimuth there", t.x(),
        t.y(), t.z());
    return std::nullopt;
  }
  const double theta = std::atan2(t.y(), t.x());
  Eigen::Vector3d u, w;
  plane_axes(theta, &u, &w);
  const Eigen::Matrix3d rotation = pose.linear();
  const Eigen::Vector3d a = rotation.col(2);
  const double off = std::asin(std::clamp(a.dot(w), -1.0, 1.0)) / kDeg;
  Eigen::Vector3d in_plane = a - a.dot(w) * w;
  if (std::abs(off) > yaw_tolerance_deg || in_plane.norm() < 1e-9) {
    *problem = fmt::format(
        "the tool's approach axis leaves the arm's vertical plane (azimuth {:.2f} deg) by {:.2f} deg, more than the "
        "yaw tolerance {:.2f} deg: a 5-axis arm cannot turn its tool about that",
        theta / kDeg, off, yaw_tolerance_deg);
    return std::nullopt;
  }
  in_plane.normalize();
  Eigen::Matrix3d frame;
  frame << w.cross(in_plane), w, in_plane;
  const Eigen::Matrix3d roll = frame.transpose() * rotation;  // Rz(r), up to the projection
  Xyzpr v;
  v.x = t.x();
  v.y = t.y();
  v.z = t.z();
  v.p = wrap_deg(std::atan2(in_plane.z(), in_plane.dot(u)) / kDeg);
  v.r = wrap_deg(std::atan2(roll(1, 0), roll(0, 0)) / kDeg);
  return v;
}

Xyzpr with_angle_reading(const Xyzpr& v, double pitch_down_deg, int roll_sense) {
  Xyzpr out = v;
  if (pitch_down_deg > 0) out.p = -v.p;
  if (roll_sense < 0) out.r = -v.r;
  return out;
}

std::string number(double v) {
  const double tenths = std::round(v * 10.0);
  std::string s = fmt::format("{:.1f}", tenths / 10.0);
  if (s == "-0.0") s = "0.0";
  return s;
}

std::string format_mp(const Xyzpr& v) {
  return fmt::format("MP {},{},{},{},{}", number(v.x), number(v.y), number(v.z), number(v.p), number(v.r));
}

std::string format_pd(int slot, const Xyzpr& v) {
  return fmt::format("PD {},{},{},{},{},{}", slot, number(v.x), number(v.y), number(v.z), number(v.p), number(v.r));
}

std::string format_ms(int slot, int points, char letter) {
  return fmt::format("MS {},{},{}", slot, points, letter);
}

std::string format_sp(int level, Acceleration acceleration) {
  switch (acceleration) {
    case Acceleration::high:
      return fmt::format("SP {},H", level);
    case Acceleration::low:
      return fmt::format("SP {},L", level);
    case Acceleration::none:
      break;
  }
  return fmt::format("SP {}", level);
}

std::string format_gp(int start, int retained, int time) {
  return fmt::format("GP {},{},{}", start, retained, time);
}

std::string format_tl(double mm) {
  return "TL " + number(mm);
}

int speed_level(double speed) {
  return std::clamp(static_cast<int>(std::lround(speed * 9.0)), 0, 9);
}

int grip_force_level(double force, double max_force) {
  return std::clamp(static_cast<int>(std::lround(force / max_force * 15.0)), 0, 15);
}

int intermediate_points(double travel) {
  return std::clamp(static_cast<int>(std::lround(travel / 10.0)), 0, 99);
}

double travel_mm(const Xyzpr& from, const Xyzpr& to) {
  return std::sqrt((to.x - from.x) * (to.x - from.x) + (to.y - from.y) * (to.y - from.y) +
                   (to.z - from.z) * (to.z - from.z));
}

std::optional<int> parse_er(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  line = trim(line);
  if (line.empty() || line.size() > 2) return std::nullopt;
  int value = 0;
  for (const char c : line) {
    if (c < '0' || c > '9') return std::nullopt;
    value = value * 10 + (c - '0');
  }
  return value;
}

std::optional<Xyzpr> parse_wh(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::array<double, 5> values{};
  std::size_t n = 0;
  for (;;) {
    const std::size_t comma = line.find(',');
    if (n == values.size()) return std::nullopt;  // a sixth field
    const std::optional<double> v = parse_number(line.substr(0, comma));
    if (!v) return std::nullopt;
    values[n++] = *v;
    if (comma == std::string_view::npos) break;
    line.remove_prefix(comma + 1);
  }
  if (n != values.size()) return std::nullopt;
  return Xyzpr{values[0], values[1], values[2], values[3], values[4]};
}

}  // namespace cellwright::drivers::movemaster
