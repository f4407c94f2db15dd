// What a sweep for collisions found, told (sweep.hpp).
#include "cellwright/cell/sweep.hpp"

#include <fmt/format.h>

namespace cellwright::cell {

namespace {

std::string where_on(const SweepParty& p) {
  if (p.samples <= 1) return "at rest";
  return fmt::format("{:.0f}% of the way (sample {} of {})",
                     100.0 * static_cast<double>(p.sample) / static_cast<double>(p.samples - 1), p.sample + 1,
                     p.samples);
}

std::string during(const SweepParty& p) {
  return p.source.empty() ? p.command : fmt::format("'{}' ({})", p.command, p.source);
}

}  // namespace

std::string PredictedCollision::text() const {
  const std::string more =
      bodies.size() > 1 ? fmt::format(" ({} pairs of bodies in contact in all)", bodies.size()) : std::string();
  if (b.robot.empty()) {
    return fmt::format("robot '{}' hits {} during {}, from {}: its {} {:.0f} mm deep{}", a.robot, b.body, during(a),
                       where_on(a), a.body, depth * 1000, more);
  }
  return fmt::format(
      "robots '{}' and '{}' collide: '{}' during {}, from {}, and '{}' during {}, {}; the net lets the two commands "
      "run at the same time; {} {} and {} {} {:.0f} mm deep{}",
      a.robot, b.robot, a.robot, during(a), where_on(a), b.robot, during(b), where_on(b), a.robot, a.body, b.robot,
      b.body, depth * 1000, more);
}

}  // namespace cellwright::cell
