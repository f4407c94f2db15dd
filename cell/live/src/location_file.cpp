#include "cellwright/cell/live/location_file.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>
#include <vector>

#include "cellwright/cell/live/teach.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/models/cell.hpp"

namespace cellwright::cell {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

// The file's lines, each with its line break ('\n'), the last one without if the file does not end with one.
std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t nl = text.find('\n', start);
    const std::size_t end = nl == std::string::npos ? text.size() : nl + 1;
    out.push_back(text.substr(start, end - start));
    start = end;
  }
  return out;
}

std::string join(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& l : lines) out += l;
  return out;
}

// The end (one past) of the flow collection that starts at `at` in `line`, or nullopt if it does not end there.
std::optional<std::size_t> flow_end(const std::string& line, std::size_t at) {
  int depth = 0;
  char quote = 0;
  for (std::size_t i = at; i < line.size(); ++i) {
    const char c = line[i];
    if (quote) {
      if (c == quote) quote = 0;
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '{' || c == '[') {
      ++depth;
    } else if (c == '}' || c == ']') {
      if (--depth == 0) return i + 1;
    } else if (c == '#' && depth == 0) {
      break;
    }
  }
  return std::nullopt;
}

std::size_t indent_of(const std::string& line) {
  const std::size_t i = line.find_first_not_of(' ');
  return i == std::string::npos ? line.size() : i;
}

bool blank(const std::string& line) {
  const std::size_t i = line.find_first_not_of(" \t\r\n");
  return i == std::string::npos;
}

bool identifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  }
  return true;
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw LiveRefusal(fmt::format("{}: cannot be read", file.string()));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_atomically(const std::filesystem::path& file, const std::string& text) {
  const std::filesystem::path tmp = file.parent_path() / ("." + file.filename().string() + ".teach-tmp");
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw LiveRefusal(fmt::format("{}: cannot write {}", file.string(), tmp.string()));
    }
  }
  std::error_code ec;
  std::filesystem::permissions(tmp, std::filesystem::status(file, ec).permissions(), ec);
  std::filesystem::rename(tmp, file, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw LiveRefusal(fmt::format("{}: cannot be replaced: {}", file.string(), ec.message()));
  }
}

}  // namespace

namespace {

// A taught location's values as YAML flow texts: its pose ("{xyz: [x, y, z], yaw: Y}") and reach ("[robot]").
struct TaughtFields {
  std::string pose, reach;
};

TaughtFields taught_fields(const std::string& robot, const Eigen::Isometry3d& tool) {
  const Eigen::Vector3d z = tool.linear().col(2);
  const double tilt = std::acos(std::clamp(-z.z(), -1.0, 1.0)) / kDeg;
  if (tilt > kDownToleranceDeg) {
    throw LiveRefusal(fmt::format(
        "the tool points {:.1f} degrees away from straight down: a location is grasped from above (within {} degree); "
        "jog the wrist until the tool points down",
        tilt, kDownToleranceDeg));
  }
  const Eigen::Vector3d y = tool.linear().col(1);
  const double yaw = std::atan2(y.y(), y.x()) / kDeg;
  const Eigen::Vector3d p = tool.translation() - Eigen::Vector3d(0, 0, models::LocationSpec{}.grasp_height);
  auto num = [](double v, int digits) {
    std::string s = fmt::format("{:.{}f}", v, digits);
    while (s.find('.') != std::string::npos && (s.back() == '0' || s.back() == '.')) {
      const bool dot = s.back() == '.';
      s.pop_back();
      if (dot) break;
    }
    return s == "-0" ? std::string("0") : s;
  };
  return {fmt::format("{{xyz: [{}, {}, {}], yaw: {}}}", num(p.x(), 4), num(p.y(), 4), num(p.z(), 4), num(yaw, 3)),
          fmt::format("[{}]", robot)};
}

}  // namespace

std::string taught_location_entry(const std::string& name, const std::string& robot, const Eigen::Isometry3d& tool) {
  const TaughtFields f = taught_fields(robot, tool);
  return fmt::format("{{name: {}, pose: {}, reach: {}}}", name, f.pose, f.reach);
}

std::string unified_diff(const std::string& before, const std::string& after, const std::string& label) {
  if (before == after) return {};
  const std::vector<std::string> a = split_lines(before), b = split_lines(after);
  std::size_t head = 0;
  while (head < a.size() && head < b.size() && a[head] == b[head]) ++head;
  std::size_t tail = 0;
  while (tail < a.size() - head && tail < b.size() - head && a[a.size() - 1 - tail] == b[b.size() - 1 - tail]) ++tail;
  const std::size_t context = 3;
  const std::size_t from = head > context ? head - context : 0;
  const std::size_t a_to = std::min(a.size(), a.size() - tail + context);
  const std::size_t b_to = std::min(b.size(), b.size() - tail + context);
  auto line = [](const std::string& l) { return l.empty() || l.back() != '\n' ? l + "\n\\ No newline at end of file\n" : l; };
  auto range = [](std::size_t start, std::size_t count) {
    return count == 1 ? fmt::format("{}", start + 1) : fmt::format("{},{}", count == 0 ? start : start + 1, count);
  };
  std::string out = fmt::format("--- {}\n+++ {}\n@@ -{} +{} @@\n", label, label, range(from, a_to - from),
                                range(from, b_to - from));
  for (std::size_t i = from; i < head; ++i) out += " " + line(a[i]);
  for (std::size_t i = head; i < a.size() - tail; ++i) out += "-" + line(a[i]);
  for (std::size_t i = head; i < b.size() - tail; ++i) out += "+" + line(b[i]);
  for (std::size_t i = a.size() - tail; i < a_to; ++i) out += " " + line(a[i]);
  return out;
}

SavedLocation save_location(const std::filesystem::path& cell_file, const std::string& label, const std::string& name,
                            const std::string& robot, const Eigen::Isometry3d& tool) {
  if (!identifier(name)) {
    throw LiveRefusal(fmt::format("'{}' is not a location name (letters, digits and _, not starting with a digit)",
                                  name));
  }
  const std::string entry = taught_location_entry(name, robot, tool);
  const std::string before = read_text(cell_file);
  YAML::Node root;
  try {
    root = YAML::Load(before);
  } catch (const YAML::Exception& e) {
    throw LiveRefusal(fmt::format("{}:{}:{}: not YAML ({}): nothing was written", label, e.mark.line + 1,
                                  e.mark.column + 1, e.msg));
  }
  if (!root.IsMap()) throw LiveRefusal(fmt::format("{}: not a cell description (a mapping): nothing was written", label));
  std::vector<std::string> lines = split_lines(before);
  if (!lines.empty() && lines.back().back() != '\n') lines.back() += '\n';  // a line to add goes after a line break
  SavedLocation saved;
  std::optional<YAML::Mark> key_mark;
  YAML::Node seq;
  for (auto it = root.begin(); it != root.end(); ++it) {
    if (it->first.IsScalar() && it->first.Scalar() == "locations") {
      key_mark = it->first.Mark();
      seq = it->second;
    }
  }
  if (!key_mark) {
    lines.push_back("\nlocations:\n");
    lines.push_back("  - " + entry + "\n");
    saved.line = static_cast<int>(split_lines(join(lines)).size());
  } else if (seq.IsNull()) {
    const auto at = static_cast<std::size_t>(key_mark->line) + 1;
    lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(at), "  - " + entry + "\n");
    saved.line = static_cast<int>(at) + 1;
  } else if (!seq.IsSequence() || seq.Style() == YAML::EmitterStyle::Flow) {
    throw LiveRefusal(fmt::format("{}:{}: `locations:` is not a list written one item a line (- ...): nothing was "
                                  "written",
                                  label, key_mark->line + 1));
  } else {
    std::optional<std::size_t> replace;
    for (std::size_t i = 0; i < seq.size(); ++i) {
      const YAML::Node item = seq[i];
      if (item.IsMap() && item["name"] && item["name"].IsScalar() && item["name"].Scalar() == name) replace = i;
    }
    if (replace) {
      const YAML::Mark m = seq[*replace].Mark();
      std::string& l = lines[static_cast<std::size_t>(m.line)];
      const auto col = static_cast<std::size_t>(m.column);
      const std::optional<std::size_t> end = l[col] == '{' ? flow_end(l, col) : std::nullopt;
      const std::size_t dash = l.substr(0, col).find('-');
      if (end) {
        l = l.substr(0, col) + entry + l.substr(*end);
      } else if (l[col] != '{' && dash != std::string::npos) {
        // A block mapping ("- name: ..." then its keys on their own lines): replaced by one in the same style, its
        // keys at the item's column; the comment lines inside it are kept, after the new keys.
        const auto first = static_cast<std::size_t>(m.line);
        std::size_t last = first;
        std::vector<std::string> comments;
        for (std::size_t k = first + 1; k < lines.size(); ++k) {
          if (blank(lines[k])) continue;
          if (indent_of(lines[k]) <= dash) break;
          last = k;
        }
        for (std::size_t k = first + 1; k <= last; ++k) {
          if (!blank(lines[k]) && lines[k][indent_of(lines[k])] == '#') comments.push_back(lines[k]);
        }
        const TaughtFields f = taught_fields(robot, tool);
        const std::string keys(col, ' ');
        std::vector<std::string> item = {l.substr(0, col) + "name: " + name + "\n", keys + "pose: " + f.pose + "\n",
                                         keys + "reach: " + f.reach + "\n"};
        item.insert(item.end(), comments.begin(), comments.end());
        lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(first),
                    lines.begin() + static_cast<std::ptrdiff_t>(last + 1));
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(first), item.begin(), item.end());
      } else {
        throw LiveRefusal(fmt::format("{}:{}: location '{}' is written in a way this cannot replace (a flow mapping "
                                      "over several lines, or its keys below a bare dash): edit it by hand (nothing "
                                      "was written)",
                                      label, m.line + 1, name));
      }
      saved.replaced = true;
      saved.line = m.line + 1;
    } else {
      const YAML::Mark m = seq[seq.size() - 1].Mark();
      const auto first = static_cast<std::size_t>(m.line);
      const std::string prefix = lines[first].substr(0, static_cast<std::size_t>(m.column));
      const std::size_t dash = prefix.find('-') == std::string::npos ? indent_of(prefix) : prefix.find('-');
      std::size_t last = first;  // the last line of the last item: more indented than its dash
      const bool one_line = lines[first][static_cast<std::size_t>(m.column)] == '{' &&
                            flow_end(lines[first], static_cast<std::size_t>(m.column));
      if (!one_line) {
        for (std::size_t k = first + 1; k < lines.size(); ++k) {
          if (blank(lines[k])) continue;
          if (indent_of(lines[k]) <= dash) break;
          last = k;
        }
      }
      std::string indent = prefix;
      for (char& c : indent) {
        if (c != ' ' && c != '-') c = ' ';
      }
      lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(last + 1), indent + entry + "\n");
      saved.line = static_cast<int>(last) + 2;
    }
  }
  const std::string after = join(lines);
  try {
    const models::CellDescription cell = models::parse_cell(after, cell_file);
    const models::LocationSpec* loc = cell.find_location(name);
    if (!loc) throw LiveRefusal(fmt::format("{}: the new location '{}' was not read back: nothing was written", label, name));
  } catch (const InputError& e) {
    throw LiveRefusal(fmt::format("with location '{}' the cell would not load: {} (nothing was written)", name,
                                  e.what()));
  }
  write_atomically(cell_file, after);
  saved.diff = unified_diff(before, after, label);
  return saved;
}

}  // namespace cellwright::cell
