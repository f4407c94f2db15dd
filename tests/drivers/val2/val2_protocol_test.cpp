// The VAL II language (val2_protocol.hpp): numbers, locations, WHERE, error lines.
#include "cellwright/drivers/val2/val2_protocol.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <clocale>
#include <cmath>
#include <locale>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "common/garbage_in.hpp"

namespace cellwright::drivers::val2 {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// The page's definition, written out independently: R = Rz(O) · Ry(A) · Rz(T) · Rx(180°).
Eigen::Matrix3d page_rotation(double o, double a, double t) {
  using Eigen::AngleAxisd;
  using Eigen::Vector3d;
  return (AngleAxisd(o * kDeg, Vector3d::UnitZ()) * AngleAxisd(a * kDeg, Vector3d::UnitY()) *
          AngleAxisd(t * kDeg, Vector3d::UnitZ()) * AngleAxisd(std::numbers::pi, Vector3d::UnitX()))
      .toRotationMatrix();
}

double angle_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

// The numbers of "TRANS(x,y,z,o,a,t)" as the monitor would read them.
std::vector<double> trans_numbers(const std::string& text) {
  EXPECT_TRUE(text.starts_with("TRANS(") && text.ends_with(")")) << text;
  std::string inner = text.substr(6, text.size() - 7);
  std::replace(inner.begin(), inner.end(), ',', ' ');
  const auto numbers = parse_numbers(inner);
  EXPECT_TRUE(numbers.has_value()) << text;
  return numbers.value_or(std::vector<double>{});
}

TEST(Val2Protocol, NumbersHaveAtMostThreeDecimalsAndAPoint) {
  EXPECT_EQ(format_number(12.5), "12.5");
  EXPECT_EQ(format_number(-0.001), "-0.001");
  EXPECT_EQ(format_number(3.0), "3");
  EXPECT_EQ(format_number(1.23456), "1.235");
  EXPECT_EQ(format_number(-1.23449), "-1.234");
  EXPECT_EQ(format_number(431.8), "431.8");
  EXPECT_EQ(format_number(-0.0004), "0");  // never "-0"
  EXPECT_EQ(format_number(0.0), "0");
  EXPECT_EQ(format_number(100.0), "100");
  EXPECT_EQ(format_number(-250.04), "-250.04");
}

TEST(Val2Protocol, NumbersIgnoreTheHostLocale) {
  const char* names[] = {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", "fr_FR.utf8"};
  const char* found = nullptr;
  for (const char* n : names) {
    if (std::setlocale(LC_ALL, n) != nullptr) {
      found = n;
      break;
    }
  }
  if (found == nullptr) GTEST_SKIP() << "no locale with a decimal comma is installed here";
  std::locale::global(std::locale(found));
  const std::string text = format_number(12.5);
  const auto parsed = parse_numbers("12.25 -.5");
  std::locale::global(std::locale::classic());
  std::setlocale(LC_ALL, "C");
  EXPECT_EQ(text, "12.5");
  ASSERT_TRUE(parsed.has_value());
  EXPECT_EQ(*parsed, (std::vector<double>{12.25, -0.5}));
}

TEST(Val2Protocol, AllZeroPointsTheToolDownWithItsYAxisAlongMinusY) {
  const Eigen::Matrix3d r = oat_rotation(0, 0, 0, Orientation::tool_down);
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12)) << r;
  EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12)) << r;
  EXPECT_TRUE(r.col(0).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12)) << r;
  // The plain convention leaves the base frame.
  EXPECT_TRUE(oat_rotation(0, 0, 0, Orientation::zyz).isApprox(Eigen::Matrix3d::Identity(), 1e-12));
}

TEST(Val2Protocol, OatFollowsThePagesFormula) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> angle(-180.0, 180.0);
  for (int i = 0; i < 200; ++i) {
    const double o = angle(rng), a = angle(rng), t = angle(rng);
    EXPECT_LT(angle_between(oat_rotation(o, a, t, Orientation::tool_down), page_rotation(o, a, t)), 1e-12)
        << o << " " << a << " " << t;
  }
  // A = 90: the approach axis points along −x.
  EXPECT_TRUE(oat_rotation(0, 90, 0, Orientation::tool_down).col(2).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
}

// Rotations to try: seeded random ones, and the near-singular ones where A is 0 or 180 or just off them.
std::vector<Eigen::Matrix3d> rotations() {
  std::vector<Eigen::Matrix3d> out;
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
    out.push_back(q.normalized().toRotationMatrix());
  }
  std::uniform_real_distribution<double> angle(-180.0, 180.0);
  for (const double a : {0.0, 180.0, 1e-7, 180.0 - 1e-7, 1e-4, 179.9999, -1e-7, 0.0005}) {
    for (int i = 0; i < 20; ++i) out.push_back(page_rotation(angle(rng), a, angle(rng)));
  }
  return out;
}

TEST(Val2Protocol, PoseToTransAndBackKeepsThePose) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-0.9, 0.9);
  for (const Orientation orientation : {Orientation::tool_down, Orientation::zyz}) {
    for (const Eigen::Matrix3d& r : rotations()) {
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.linear() = r;
      pose.translation() = Eigen::Vector3d(coordinate(rng), coordinate(rng), coordinate(rng));

      const Location l = to_location(pose, orientation);
      EXPECT_GE(l.a, 0.0);
      EXPECT_LE(l.a, 180.0);
      EXPECT_GT(l.o, -180.0);
      EXPECT_LE(l.o, 180.0);
      EXPECT_GT(l.t, -180.0);
      EXPECT_LE(l.t, 180.0);
      // Exactly (before the text's rounding).
      const Eigen::Isometry3d exact = to_pose(l, orientation);
      EXPECT_LT(angle_between(exact.linear(), r), 1e-8);
      EXPECT_LT((exact.translation() - pose.translation()).norm(), 1e-12);

      // Through the text: 0.001 mm and 0.001° per number at most.
      const std::vector<double> v = trans_numbers(trans_text(l));
      ASSERT_EQ(v.size(), 6U);
      const Eigen::Isometry3d back = to_pose(Location{v[0], v[1], v[2], v[3], v[4], v[5]}, orientation);
      EXPECT_LT(angle_between(back.linear(), r), 3 * 0.0005 * kDeg + 1e-8);
      EXPECT_LT((back.translation() - pose.translation()).norm(), 1e-6);
    }
  }
}

TEST(Val2Protocol, EquivalentAnglesGiveTheSameRotation) {
  // The page's WHERE example has A = −90; the driver reads it as given and would send the equivalent A = 90.
  const Eigen::Matrix3d r = oat_rotation(90, -90, 0, Orientation::tool_down);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = r;
  const Location l = to_location(pose, Orientation::tool_down);
  EXPECT_NEAR(l.a, 90.0, 1e-9);
  EXPECT_LT(angle_between(oat_rotation(l.o, l.a, l.t, Orientation::tool_down), r), 1e-9);
}

TEST(Val2Protocol, TransAndPpointText) {
  Eigen::Isometry3d pose = to_pose(Location{431.8, -149.09, 433.07, 90, 0, 0}, Orientation::tool_down);
  EXPECT_EQ(trans_text(to_location(pose, Orientation::tool_down)), "TRANS(431.8,-149.09,433.07,90,0,0)");
  pose = to_pose(Location{-12.5, 600, 0.25, -30, 120, 45}, Orientation::tool_down);
  EXPECT_EQ(trans_text(to_location(pose, Orientation::tool_down)), "TRANS(-12.5,600,0.25,-30,120,45)");
  const std::vector<double> joints = {0, -90 * kDeg, 180 * kDeg, 0, 45.5 * kDeg, -0.25 * kDeg};
  EXPECT_EQ(ppoint_text(joints), "#PPOINT(0,-90,180,0,45.5,-0.25)");
}

TEST(Val2Protocol, NumbersParseWithSignsLeadingPointsAndAnySpacing) {
  EXPECT_EQ(parse_numbers("  +.5 -0.5\t12   12.25  "), (std::vector<double>{0.5, -0.5, 12, 12.25}));
  EXPECT_EQ(parse_numbers("-.25"), (std::vector<double>{-0.25}));
  EXPECT_EQ(parse_numbers("1e3 5."), (std::vector<double>{1000, 5}));
  for (const char* bad : {"", "   ", "1,2", "abc", "+-1", "--1", "1.2.3", "+", "-", "nan", "inf", "12 x", "1e999"}) {
    EXPECT_FALSE(parse_numbers(bad).has_value()) << "'" << bad << "'";
  }
}

void expect_example(const WhereParser& p, bool hand) {
  ASSERT_TRUE(p.complete());
  const auto r = p.reading();
  ASSERT_TRUE(r.has_value());
  EXPECT_DOUBLE_EQ(r->world.x, 431.8);
  EXPECT_DOUBLE_EQ(r->world.y, -149.09);
  EXPECT_DOUBLE_EQ(r->world.z, 433.07);
  EXPECT_DOUBLE_EQ(r->world.o, 90);
  EXPECT_DOUBLE_EQ(r->world.a, -90);
  EXPECT_DOUBLE_EQ(r->world.t, 0);
  EXPECT_EQ(r->hand.has_value(), hand);
  if (hand) {
    EXPECT_DOUBLE_EQ(*r->hand, 50);
  }
  EXPECT_EQ(r->joints, (std::vector<double>{0, -90, 180, 0, 0.5, 0}));
}

TEST(Val2Protocol, WhereThePagesLayout) {
  WhereParser p;
  EXPECT_EQ(p.missing(), "the world values");
  EXPECT_FALSE(p.reading().has_value());
  EXPECT_TRUE(p.feed("     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND"));
  EXPECT_TRUE(p.feed("    431.80    -149.09     433.07     90.000    -90.000      0.000     50.000"));
  EXPECT_FALSE(p.finished());  // the joint row may follow
  EXPECT_TRUE(p.feed("     0.000    -90.000    180.000      0.000      0.500      0.000"));
  EXPECT_TRUE(p.finished());
  EXPECT_EQ(p.missing(), "");
  expect_example(p, true);
}

TEST(Val2Protocol, WhereWithoutTheJointRowIsAPoseWithoutJoints) {
  WhereParser p;
  EXPECT_TRUE(p.feed("     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6"));
  EXPECT_TRUE(p.feed("    431.80    -149.09     433.07     90.000    -90.000      0.000"));
  ASSERT_TRUE(p.complete());
  EXPECT_FALSE(p.finished());
  EXPECT_EQ(p.missing(), "");
  const PositionReading r = to_position_reading(*p.reading(), Orientation::tool_down);
  EXPECT_TRUE(r.joints.empty());
  ASSERT_TRUE(r.tool_pose.has_value());
  EXPECT_TRUE(r.tool_pose->translation().isApprox(Eigen::Vector3d(0.4318, -0.14909, 0.43307), 1e-12));
}

// Kawasaki AS prints the joints first, then the location, each under its own header (the layout quoted by public
// host programs, ../shared/reference/facts.md).
TEST(Val2Protocol, WhereTwoBlocksOfKawasakiAS) {
  WhereParser p(WhereLayout::as_two_block);
  EXPECT_EQ(p.missing(), "the joint angles and the world values");
  EXPECT_TRUE(p.feed("     JT1       JT2       JT3       JT4       JT5       JT6  "));
  EXPECT_TRUE(p.feed("     0.000   -90.000   180.000     0.000     0.500     0.000"));
  EXPECT_FALSE(p.complete());
  EXPECT_EQ(p.missing(), "the world values");
  EXPECT_TRUE(p.feed("    X[mm]     Y[mm]     Z[mm]     O[deg]    A[deg]    T[deg]"));
  EXPECT_FALSE(p.complete());
  EXPECT_TRUE(p.feed("   431.800  -149.090   433.070    90.000   -90.000     0.000"));
  EXPECT_TRUE(p.finished());
  expect_example(p, false);
}

TEST(Val2Protocol, WhereTwoBlocksRefuseLinesOutOfOrder) {
  WhereParser p(WhereLayout::as_two_block);
  EXPECT_FALSE(p.feed("431.8 -149.09 433.07 90 -90 0"));           // numbers before the joint header
  EXPECT_FALSE(p.feed("X[mm] Y[mm] Z[mm] O[deg] A[deg] T[deg]"));  // the world header first
  EXPECT_TRUE(p.feed("JT1 JT2 JT3 JT4 JT5 JT6"));
  EXPECT_FALSE(p.feed("0 -90 180 0 0.5 0 50"));  // seven joints
  EXPECT_TRUE(p.feed("0 -90 180 0 0.5 0"));
  EXPECT_FALSE(p.feed("431.8 -149.09 433.07 90 -90 0"));  // the world values without their header
  EXPECT_TRUE(p.feed("X[mm] Y[mm] Z[mm] O[deg] A[deg] T[deg]"));
  EXPECT_FALSE(p.feed("431.8 -149.09 433.07 90 -90 0 50"));  // no hand value in this layout
  EXPECT_TRUE(p.feed("431.8 -149.09 433.07 90 -90 0"));
  EXPECT_FALSE(p.feed("0 0 0 0 0 0"));  // anything after
  // The page's layout does not read it.
  WhereParser val2;
  EXPECT_FALSE(val2.feed("JT1 JT2 JT3 JT4 JT5 JT6"));
}

TEST(Val2Protocol, PromptsWithTrailingSpacesAndBells) {
  EXPECT_TRUE(is_prompt(".", "."));
  EXPECT_TRUE(is_prompt(". ", "."));
  EXPECT_TRUE(is_prompt(".\t ", "."));
  EXPECT_TRUE(is_prompt("\a.", "."));
  EXPECT_TRUE(is_prompt(">", ">"));
  EXPECT_FALSE(is_prompt(" .", "."));  // not at the start of the line
  EXPECT_FALSE(is_prompt(".5", "."));
  EXPECT_FALSE(is_prompt("", "."));
  EXPECT_FALSE(is_prompt(".", ">"));
  EXPECT_EQ(without_bells("\a\a*Servo error*\a"), "*Servo error*");
}

TEST(Val2Protocol, WhereVariants) {
  {
    WhereParser p;  // no hand value, tight spacing, tabs, signs, leading points
    EXPECT_TRUE(p.feed("x/jt1 y/jt2"));
    EXPECT_TRUE(p.feed("+431.8 -149.09 +433.07\t90 -90 .0"));
    EXPECT_TRUE(p.feed(".000 -90 180 -0 +.5 0"));
    expect_example(p, false);
  }
  {
    WhereParser p;  // no header
    EXPECT_TRUE(p.feed("431.80 -149.09 433.07 90 -90 0 50"));
    EXPECT_TRUE(p.feed("0 -90 180 0 0.5 0"));
    expect_example(p, true);
  }
}

TEST(Val2Protocol, WhereRejectsLinesThatDoNotFit) {
  WhereParser p;
  EXPECT_FALSE(p.feed("HELLO"));            // not a header
  EXPECT_FALSE(p.feed("1 2 3 4 5"));        // five world values
  EXPECT_FALSE(p.feed("1 2 3 4 5 6 7 8"));  // eight
  EXPECT_FALSE(p.feed("1 2 3 4 5 6,7"));    // not numbers
  EXPECT_TRUE(p.feed("X Y Z O A T"));
  EXPECT_FALSE(p.feed("X Y Z O A T"));  // a second header
  EXPECT_TRUE(p.feed("1 2 3 4 5 6"));
  EXPECT_FALSE(p.feed("1 2 3 4 5 6 7"));  // seven joints
  EXPECT_FALSE(p.feed("1 2 3 4 5"));      // five
  EXPECT_TRUE(p.feed("1 2 3 4 5 6"));
  EXPECT_FALSE(p.feed("1 2 3 4 5 6"));  // anything after the joints
}

TEST(Val2Protocol, WhereReadingInRadiansAndMetres) {
  WhereParser p;
  ASSERT_TRUE(p.feed("431.80 -149.09 433.07 90 -90 0 50"));
  ASSERT_TRUE(p.feed("0 -90 180 0 0.5 0"));
  const PositionReading r = to_position_reading(*p.reading(), Orientation::tool_down);
  ASSERT_EQ(r.joints.size(), 6U);
  EXPECT_NEAR(r.joints[1], -std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(r.joints[2], std::numbers::pi, 1e-12);
  EXPECT_NEAR(r.joints[4], 0.5 * kDeg, 1e-12);
  ASSERT_TRUE(r.tool_pose.has_value());
  EXPECT_TRUE(r.tool_pose->translation().isApprox(Eigen::Vector3d(0.4318, -0.14909, 0.43307), 1e-12));
  EXPECT_LT(angle_between(r.tool_pose->linear(), page_rotation(90, -90, 0)), 1e-12);
}

TEST(Val2Protocol, ErrorLinesByTheirWords) {
  for (const char* line : {"*Location out of range*", "*Location too close*", "*Joint 3 limit stop*",
                           "*Position out of range*", "*JOINT 6 LIMIT STOP*"}) {
    EXPECT_EQ(classify_error(line), ErrorCode::unreachable) << line;
  }
  for (const char* line :
       {"*Unknown instruction*", "*Invalid argument*", "*Illegal value*", "*Syntax error*", "*syntax ERROR*"}) {
    EXPECT_EQ(classify_error(line), ErrorCode::protocol) << line;
  }
  for (const char* line : {"*Arm power off*", "*Servo error*", "*Emergency stop*", "*EMERGENCY STOP*"}) {
    EXPECT_EQ(classify_error(line), ErrorCode::hardware) << line;
  }
  // Words outside the driver's lists are not taken for a hardware error: unknown.
  for (const char* line : {"*Unknown command*", "*Invalid format*", "*Out of range*", "*", "*Error 42*"}) {
    EXPECT_EQ(classify_error(line), ErrorCode::unknown) << line;
  }
}

// Seeded garbage in: WHERE answers with random edits are taken line by line as the driver does; the parser accepts
// a line or leaves it (the driver's protocol fault), a complete answer converts to finite joints and a finite pose,
// and nothing throws.
TEST(Val2ProtocolGarbageIn, MutatedWhereAnswersAreReadOrRefusedNeverThrown) {
  const std::string answer =
      "     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND\n"
      "    431.80    -149.09     433.07     90.000    -90.000      0.000     50.000\n"
      "     0.000    -90.000    180.000      0.000      0.000      0.000\n";
  std::mt19937_64 rng(20261124);
  int complete = 0, incomplete = 0;
  for (int round = 0; round < 5000; ++round) {
    std::string text = answer;
    for (int e = 0, n = 1 + static_cast<int>(rng() % 4); e < n; ++e) {
      text = cellwright::testing::mutate(std::move(text), rng, "0123456789+-. \t\neEinfaX*");
    }
    WhereParser where;
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
      if (const auto numbers = parse_numbers(line)) {
        for (const double v : *numbers) EXPECT_TRUE(std::isfinite(v)) << line;
      }
      (void)where.feed(line);
    }
    EXPECT_EQ(where.complete(), where.missing().empty());
    const std::optional<WhereParser::Reading> reading = where.reading();
    if (!reading) {
      ++incomplete;
      continue;
    }
    ++complete;
    ASSERT_TRUE(reading->joints.empty() || reading->joints.size() == 6U) << text;
    const PositionReading r = to_position_reading(*reading, Orientation::tool_down);
    for (const double j : r.joints) EXPECT_TRUE(std::isfinite(j)) << text;
    EXPECT_TRUE(r.tool_pose && r.tool_pose->matrix().allFinite()) << text;
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GT(complete, 500);
  EXPECT_GT(incomplete, 500);
}

}  // namespace
}  // namespace cellwright::drivers::val2
