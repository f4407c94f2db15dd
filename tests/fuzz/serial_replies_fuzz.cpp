// libFuzzer harness: the controllers' replies as the serial drivers read them (drivers/movemaster, drivers/val2).
// The first byte picks the controller, the rest is the bytes on the line, cut into lines as the drivers cut them (at
// LF, a CR before it dropped).
//  - Movemaster EX: every line as an answer to ER (parse_er) and to WH (parse_wh); an accepted WH answer has a finite
//    pose, and sent back as MP it reads as the same values to the text's tenth (up to 15 digits, the reader's bound).
//  - VAL II: the lines as an answer to WHERE (WhereParser, blank lines skipped, error lines classified, as the
//    driver's await does) and each line's numbers (parse_numbers); a complete answer converts to finite joints and a
//    finite pose under both orientation conventions.
// These readers refuse by returning nullopt or false (the driver's protocol fault); nothing may throw. Seeds: the
// answers of docs/real-robots.md and the emulators (emulate/).
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/drivers/movemaster/movemaster_protocol.hpp"
#include "cellwright/drivers/val2/val2_protocol.hpp"
#include "fuzz.hpp"

namespace {

std::vector<std::string_view> lines_of(std::string_view bytes) {
  std::vector<std::string_view> lines;
  for (std::size_t nl = bytes.find('\n'); nl != std::string_view::npos; nl = bytes.find('\n')) {
    std::string_view line = bytes.substr(0, nl);
    while (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    bytes.remove_prefix(nl + 1);
  }
  lines.push_back(bytes);  // the rest, as a reply without its line end
  return lines;
}

void movemaster(std::string_view bytes) {
  namespace mm = cellwright::drivers::movemaster;
  for (const std::string_view line : lines_of(bytes)) {
    if (const auto er = mm::parse_er(line)) CW_FUZZ_CHECK(*er >= 0 && *er <= 99);
    const auto wh = mm::parse_wh(line);
    if (!wh) continue;
    for (const double v : {wh->x, wh->y, wh->z, wh->p, wh->r}) CW_FUZZ_CHECK(std::isfinite(v));
    CW_FUZZ_CHECK(mm::to_pose(*wh).matrix().allFinite());
    // Sent back as MP (one decimal), a value reads as itself to the tenth, while its digits fit the reader's 15.
    if (std::abs(wh->x) >= 1e13 || std::abs(wh->y) >= 1e13 || std::abs(wh->z) >= 1e13 || std::abs(wh->p) >= 1e13 ||
        std::abs(wh->r) >= 1e13) {
      continue;
    }
    const std::string mp = mm::format_mp(*wh);
    const auto back = mm::parse_wh(std::string_view(mp).substr(3));
    CW_FUZZ_CHECK(back.has_value());
    for (const auto& [a, b] :
         {std::pair{back->x, wh->x}, {back->y, wh->y}, {back->z, wh->z}, {back->p, wh->p}, {back->r, wh->r}}) {
      CW_FUZZ_CHECK(std::abs(a - b) <= 0.05 + 1e-9 * std::abs(b));
    }
  }
}

void val2(std::string_view bytes) {
  namespace v2 = cellwright::drivers::val2;
  v2::WhereParser where;
  for (const std::string_view line : lines_of(bytes)) {
    if (const auto numbers = v2::parse_numbers(line)) {
      CW_FUZZ_CHECK(!numbers->empty());
      for (const double v : *numbers) CW_FUZZ_CHECK(std::isfinite(v));
    }
    std::size_t i = 0;
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i == line.size()) continue;
    if (line[i] == '*') {
      (void)v2::classify_error(line);
      continue;
    }
    (void)where.feed(line);
  }
  CW_FUZZ_CHECK(where.complete() == where.missing().empty());
  if (const auto reading = where.reading()) {
    CW_FUZZ_CHECK(reading->joints.size() == 6);
    for (const auto orientation : {v2::Orientation::tool_down, v2::Orientation::zyz}) {
      const cellwright::drivers::PositionReading r = v2::to_position_reading(*reading, orientation);
      for (const double j : r.joints) CW_FUZZ_CHECK(std::isfinite(j));
      CW_FUZZ_CHECK(r.tool_pose && r.tool_pose->matrix().allFinite());
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] % 2 == 0) {
    movemaster(bytes);
  } else {
    val2(bytes);
  }
  return 0;
}
