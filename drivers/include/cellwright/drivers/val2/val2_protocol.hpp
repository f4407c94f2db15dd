// The VAL II monitor's language as the Val2Driver speaks it (docs/real-robots.md, "VAL II"): locations as text,
// the WHERE answer, and the monitor's error lines. Pure functions and one small parser, no I/O: the driver
// (val2_driver.hpp) uses them on its communication thread, the tests check them directly.
//
// Units: a Location is the monitor's (mm and degrees); everything else here is the driver interface's (metres,
// radians), as robot_driver.hpp says.
//
// Threads: no shared state; any thread.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/drivers/robot_driver.hpp"

namespace cellwright::drivers::val2 {

// How O, A, T describe the tool's rotation in the base frame.
enum class Orientation : std::uint8_t {
  // The page's assumption: Z-Y-Z Euler angles applied to a tool pointing straight down,
  // R = Rz(O) · Ry(A) · Rz(T) · Rx(180°). O = A = T = 0: the approach axis points along −z, the tool's y axis along −y.
  tool_down,
  // Plain Z-Y-Z Euler angles, R = Rz(O) · Ry(A) · Rz(T) (O = A = T = 0: the tool frame is the base frame), for a
  // controller whose locations are not taken relative to a downward tool.
  zyz,
  // VAL's published convention (Unimation's VAL instruction set, 1977: "with all three angles zero, the hand points in
  // the negative Y direction with the fingers in a horizontal plane; the orientation vector, from one finger tip to
  // the other, is aligned along the X axis; O turns the orientation vector about a vertical direction"). The tool's
  // axes at O = A = T = 0 are R0 = [x: −z, y: +x, z: −y] (approach z along −Y, the fingers' line y along +X); then
  // R = Rz(O) · R0 · Ry(A) · Rz(T): O about the world's vertical, A about the tool's finger line (A = 90: the hand
  // points straight down; this sense is assumed), T about the approach axis. Equivalently R = Rz(O)·Rx(A)·Ry(−T)·R0.
  val,
};

// A VAL II location: X, Y, Z in mm and O, A, T in degrees.
struct Location {
  double x = 0, y = 0, z = 0;
  double o = 0, a = 0, t = 0;
};

// A number as the monitor is sent it: at most three decimals, trailing zeros and a trailing point dropped, a point
// whatever the host's locale, never "-0" ("12.5", "-0.001", "3"). `value` must be finite.
std::string format_number(double value);

// The rotation that O, A, T (degrees) stand for under `orientation`.
Eigen::Matrix3d oat_rotation(double o, double a, double t, Orientation orientation);

// A pose (metres, base frame) as a location. O and T are in (−180, 180], A in [0, 180] (val: A in [−90, 90]). Where A
// is 0 or 180 (val: ±90; within 1e-9 rad: O and T then turn about the same axis) T is 0 and O carries the whole turn.
Location to_location(const Eigen::Isometry3d& pose, Orientation orientation);
// A location as a pose (metres, base frame).
Eigen::Isometry3d to_pose(const Location& location, Orientation orientation);

// "TRANS(x,y,z,o,a,t)" with format_number's numbers.
std::string trans_text(const Location& location);
// "#PPOINT(j1,...,jn)": joint angles given in radians, sent in degrees with format_number.
std::string ppoint_text(const std::vector<double>& joints);

// The numbers of a line separated by spaces or tabs (any amount, leading and trailing too), each with or without a
// sign, with or without a leading zero ("+.5", "-0.5", "12", "12.25", "1e3"), parsed whatever the host's locale.
// nullopt when a token is not such a number (or is not finite) or the line has none.
std::optional<std::vector<double>> parse_numbers(std::string_view line);

// How the monitor lays out its answer to WHERE (docs/real-robots.md, "WHERE"; a setting of the robot's cell entry).
enum class WhereLayout : std::uint8_t {
  // The page's (assumed) VAL II layout: an optional header line (its first word starts with X, as "X/JT1"), a line of
  // six world values (X, Y, Z mm; O, A, T degrees) with or without a seventh, the hand opening (mm), then a line of
  // six joint angles (degrees), which a monitor may leave out.
  val2,
  // VAL's descendants (Kawasaki AS): two blocks, each a header and a line of six numbers: "JT1 ... JT6" and the
  // joint angles (degrees), then "X[mm] Y[mm] Z[mm] O[deg] A[deg] T[deg]" and the world values. Both are needed.
  as_two_block,
};

// The answer to WHERE, line by line, in `layout`. Blank lines are the caller's to skip.
class WhereParser {
 public:
  struct Reading {
    Location world;
    std::optional<double> hand;  // mm, when the monitor printed it
    std::vector<double> joints;  // degrees, six; empty when the monitor left the joint row out
  };

  explicit WhereParser(WhereLayout layout = WhereLayout::val2) : layout_(layout) {}

  // Takes the next line of the answer. false when it does not fit here (the caller's garbage); the parser is then
  // unchanged.
  bool feed(std::string_view line);
  // Every line the layout needs has come (val2: the world values; as_two_block: both blocks).
  bool complete() const;
  // Nothing more can come (val2: the joint row came too). A prompt that might be the start of a number line (".5")
  // is waited on only while this is false.
  bool finished() const { return stage_ == Stage::done; }
  // What is still missing, for messages ("the world values", "the joint angles"); "" when complete.
  std::string_view missing() const;
  // The reading, once complete() (else nullopt).
  std::optional<Reading> reading() const;

 private:
  enum class Stage : std::uint8_t { start, header, world, joint_header, joints, world_header, done };
  bool feed_val2(std::string_view line, const std::optional<std::vector<double>>& numbers);
  bool feed_as(std::string_view line, const std::optional<std::vector<double>>& numbers);
  WhereLayout layout_;
  Stage stage_ = Stage::start;
  Reading reading_;
};

// Whether `pending`, the bytes received after the last line end, is the monitor's prompt `prompt` ("." for VAL II,
// ">" for Kawasaki AS): equal to it once spaces and tabs after it (a prompt ". ") and BEL bytes are dropped.
bool is_prompt(std::string_view pending, std::string_view prompt);

// `line` without its BEL bytes (0x07: a terminal's bell, which a monitor may ring before an error line).
std::string without_bells(std::string_view line);

// The readings of a complete WHERE answer, converted: joints in radians, the tool pose in metres in the base frame.
PositionReading to_position_reading(const WhereParser::Reading& where, Orientation orientation);

// What an error line ("*Location out of range*") means (docs/real-robots.md, "Errors"), by its words, whatever their
// case: unreachable (location out of range or too close, joint n limit stop, position out of range), protocol (the
// monitor did not understand: unknown instruction, invalid argument, illegal value, syntax error), hardware (arm
// power off, servo error, emergency stop) or unknown (any other: "*Unknown command*", "*Invalid format*", words this
// driver has no list for).
ErrorCode classify_error(std::string_view line);

}  // namespace cellwright::drivers::val2
