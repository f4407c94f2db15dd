// The Movemaster EX command language as text, and its pose convention: free functions with no port and no state,
// shared by MovemasterDriver (movemaster_driver.hpp) and its tests. docs/real-robots.md ("Movemaster EX") is the
// specification; each function names the part it implements.
//
// Units: the controller speaks mm and degrees; the driver interface metres and radians. The conversions are here.
// Numbers go out with one decimal and a point whatever the host's locale (fmt does not use the locale), and a value
// that rounds to zero prints as "0.0", never "-0.0".
//
// Threads: every function is pure; any thread.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace cellwright::drivers::movemaster {

// A pose as the controller writes it: the tool centre point in the base frame in mm, pitch and roll in degrees
// (`MP x,y,z,p,r`, the answer to `WH`).
struct Xyzpr {
  double x = 0.0, y = 0.0, z = 0.0, p = 0.0, r = 0.0;
  bool operator==(const Xyzpr&) const = default;
};

// How the host ends the lines it sends (the controller's replies may end with LF or CR LF either way).
enum class LineEnd : std::uint8_t { crlf, lf, cr };
std::string_view line_end_text(LineEnd end);  // "\r\n", "\n", "\r"

// The acceleration suffix of `SP`: none sends `SP n`, high `SP n,H`, low `SP n,L`.
enum class Acceleration : std::uint8_t { none, high, low };

// ---- The 5-axis rule ("Pose convention") --------------------------------------------------------------------------
// θ = atan2(y, x); u = (cos θ, sin θ, 0); w = (−sin θ, cos θ, 0); the approach axis a = cos p · u + sin p · ẑ; the
// tool rotation R = [w × a, w, a] · Rz(r).

// The tool pose (metres, base frame) of `v`. A point on the base's z axis (x = y = 0) has no azimuth; θ = 0 is taken
// there, so that every answer of `WH` has a pose.
Eigen::Isometry3d to_pose(const Xyzpr& v);

// `pose` (metres, base frame) as x, y, z, p, r (not rounded; p and r in (−180, 180]). Returns nullopt and says why in
// *problem when the pose cannot be expressed: its tool point is within 0.05 mm (half the last digit sent) of the
// base's z axis, or its approach axis leaves the vertical plane through the tool point by more than
// `yaw_tolerance_deg`. Within the tolerance, the approach axis is projected onto the plane.
std::optional<Xyzpr> to_xyzpr(const Eigen::Isometry3d& pose, double yaw_tolerance_deg, std::string* problem);

// The page's p and r (above) as a controller that reads them otherwise writes them, and back (the same map both ways):
// p is negated when `pitch_down_deg` is 90 (the hand points straight down at p = +90 there, at −90 on the page), r is
// multiplied by `roll_sense` (+1: right-handed about the approach axis, the page's; −1: the other way). x, y, z stay.
Xyzpr with_angle_reading(const Xyzpr& v, double pitch_down_deg, int roll_sense);

// ---- Host to controller (without the line end) --------------------------------------------------------------------

// One decimal (to the nearest tenth, halves away from zero), a point, no "-0.0": 12.25 -> "12.3", -0.04 -> "0.0".
std::string number(double v);
std::string format_mp(const Xyzpr& v);                        // "MP x,y,z,p,r"
std::string format_pd(int slot, const Xyzpr& v);              // "PD n,x,y,z,p,r"
std::string format_ms(int slot, int points, char letter);     // "MS n,k,O" (the letter as given)
std::string format_sp(int level, Acceleration acceleration);  // "SP n", "SP n,H", "SP n,L"
std::string format_gp(int start, int retained, int time);     // "GP s,r,t"
std::string format_tl(double mm);                             // "TL l"

// The speed level for the driver's fraction `speed` in (0, 1]: round(speed × 9), within 0..9 ("Speed").
int speed_level(double speed);
// The grip force level for `force` of `max_force` newtons: round(force / max_force × 15), within 0..15 ("Grip force").
int grip_force_level(double force, double max_force);
// The intermediate points of `MS` for a straight line of `travel` mm: one per 10 mm (rounded), within 0..99
// ("Straight lines").
int intermediate_points(double travel);
// The distance between the tool points of two poses, mm.
double travel_mm(const Xyzpr& from, const Xyzpr& to);

// ---- Controller to host (one line, its line end already removed) ---------------------------------------------------

// The answer to `ER`: a number of one or two digits, with spaces (or tabs) around it allowed; nullopt for anything
// else. The manual's codes are 0, 1 and 2 (facts.md); the driver takes any other number for an error code it does not
// know (ErrorCode::unknown).
std::optional<int> parse_er(std::string_view line);
// The answer to `WH`: five comma-separated numbers, each with or without a sign and a leading zero ("+.5", "-0.5",
// "12", "12.25"), spaces (or tabs) around each allowed; a CR left at the end is ignored. nullopt for anything else
// (four or six numbers, an exponent, "inf", a letter, an empty field, a number of more than 15 digits).
std::optional<Xyzpr> parse_wh(std::string_view line);

}  // namespace cellwright::drivers::movemaster
