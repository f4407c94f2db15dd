// Typed YAML fields with positions in every error (yaml_fields.hpp).
#include "cellwright/models/yaml_fields.hpp"

#include <algorithm>
#include <cmath>

namespace cellwright::models::yaml {

SourceLocation Doc::at(const YAML::Node& n) const {
  const YAML::Mark m = n.Mark();
  if (m.is_null()) return {file_, 0, 0};
  return {file_, m.line + 1, m.column + 1};
}

void Doc::fail(const YAML::Node& n, std::string problem) const {
  throw InputError(at(n), std::move(problem));
}

void Doc::fail(const SourceLocation& where, std::string problem) const {
  throw InputError(where, std::move(problem));
}

YAML::Node load(std::string_view text, const Doc& doc, std::string_view problem) {
  try {
    return YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    throw InputError({doc.file(), e.mark.is_null() ? 0 : e.mark.line + 1, e.mark.is_null() ? 0 : e.mark.column + 1},
                     fmt::format("{}: {}", problem, e.msg));
  }
}

std::string describe(const YAML::Node& n) {
  if (n.IsScalar()) return fmt::format("'{}'", n.Scalar());
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

Fields::Fields(const Doc& doc, const YAML::Node& map, std::string what, std::initializer_list<std::string_view> allowed,
               bool named)
    : doc_(doc), map_(map), what_(std::move(what)) {
  if (named) {
    const YAML::Node name = map.IsMap() ? map["name"] : YAML::Node();
    what_ = name.IsDefined() && name.IsScalar() ? fmt::format("{} '{}'", what_, name.Scalar()) : "a " + what_;
  }
  if (!map.IsMap()) doc.fail(map, fmt::format("{} must be a mapping of fields, got {}", what_, describe(map)));
  for (const auto& kv : map) {
    if (!kv.first.IsScalar()) doc.fail(kv.first, fmt::format("{}: field names must be plain words", what_));
    const std::string key = kv.first.Scalar();
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      std::string list;
      for (auto a : allowed) list += fmt::format("{}{}", list.empty() ? "" : ", ", a);
      doc.fail(kv.first, fmt::format("unknown field '{}' in {} (expected one of: {})", key, what_, list));
    }
    if (fields_.count(key) != 0) {
      doc.fail(kv.first, fmt::format("field '{}' of {} is given twice (first on line {})", key, what_,
                                     doc.at(fields_.at(key).first).line));
    }
    fields_.emplace(key, std::make_pair(kv.first, kv.second));
  }
}

const YAML::Node& Fields::node(const std::string& key) const {
  auto it = fields_.find(key);
  if (it == fields_.end()) {
    doc_.fail(map_, fmt::format("{} has no field '{}'{}", what_, key,
                                doc_.missing_field() == MissingField::kSayRequired ? " (it is required)" : ""));
  }
  return it->second.second;
}

std::optional<YAML::Node> Fields::get(const std::string& key) const {
  auto it = fields_.find(key);
  if (it == fields_.end()) return std::nullopt;
  return it->second.second;
}

const YAML::Node& Fields::key_node(const std::string& key) const {
  auto it = fields_.find(key);
  CW_CHECK(it != fields_.end(), "key_node('{}') of {}, which has no such field", key, what_);
  return it->second.first;
}

std::string Fields::field(const std::string& key) const {
  return fmt::format("field '{}' of {}", key, what_);
}

double Fields::positive(const std::string& key) const {
  const double v = number(key);
  if (!(v > 0)) doc_.fail(node(key), fmt::format("{} must be greater than 0, got {}", field(key), v));
  return v;
}

double Fields::non_negative_or(const std::string& key, double fallback) const {
  if (!has(key)) return fallback;
  const double v = number(key);
  if (v < 0) doc_.fail(node(key), fmt::format("{} must not be negative, got {}", field(key), v));
  return v;
}

std::string Range::text() const {
  const std::string u = unit.empty() ? "" : fmt::format(" {}", unit);
  if (above) return fmt::format("greater than {} and at most {}{}", lo, hi, u);
  return fmt::format("within {}..{}{}", lo, hi, u);
}

double Fields::within_of(const YAML::Node& n, const std::string& name, const Range& range) const {
  const double v = number_of(n, name);
  if (!range.contains(v)) doc_.fail(n, fmt::format("{} must be {}, got {}", name, range.text(), n.Scalar()));
  return v;
}

Eigen::Vector3d Fields::vec3_within(const std::string& key, const Range& range) const {
  const Eigen::Vector3d v = vec3(key);
  const YAML::Node& n = node(key);
  for (std::size_t i = 0; i < 3; ++i) within_of(n[i], field(key), range);
  return v;
}

bool Fields::boolean_or(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  const YAML::Node& n = node(key);
  bool v = false;
  if (!n.IsScalar() || !YAML::convert<bool>::decode(n, v)) {
    doc_.fail(n, fmt::format("{} must be true or false, got {}", field(key), describe(n)));
  }
  return v;
}

std::vector<double> Fields::numbers(const std::string& key) const {
  const YAML::Node& n = node(key);
  if (!n.IsSequence()) doc_.fail(n, fmt::format("{} must be a list of numbers, got {}", field(key), describe(n)));
  std::vector<double> out;
  for (const auto& e : n) out.push_back(number_of(e, field(key)));
  return out;
}

std::vector<double> Fields::numbers(const std::string& key, std::size_t count) const {
  auto v = numbers(key);
  if (v.size() != count) {
    doc_.fail(node(key), fmt::format("{} must have {} numbers, got {}", field(key), count, v.size()));
  }
  return v;
}

Eigen::Vector3d Fields::vec3(const std::string& key) const {
  auto v = numbers(key, 3);
  return {v[0], v[1], v[2]};
}

std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> Fields::word_map(const std::string& key) const {
  const YAML::Node& n = node(key);
  if (!n.IsMap()) doc_.fail(n, fmt::format("{} must be a mapping of names, got {}", field(key), describe(n)));
  std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> out;
  std::map<std::string, int> seen;
  for (const auto& kv : n) {
    const std::string k = word_of(kv.first, fmt::format("a name in {}", field(key)));
    if (auto it = seen.find(k); it != seen.end()) {
      doc_.fail(kv.first, fmt::format("'{}' is given twice in {} (first on line {})", k, field(key), it->second));
    }
    seen.emplace(k, doc_.at(kv.first).line);
    out.push_back({k, {kv.first, kv.second}});
  }
  return out;
}

double Fields::number_of(const YAML::Node& n, const std::string& name) const {
  double v = 0;
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v)) {
    doc_.fail(n, fmt::format("{} must be a number, got {}", name, describe(n)));
  }
  if (!std::isfinite(v)) doc_.fail(n, fmt::format("{} must be a finite number, got {}", name, n.Scalar()));
  return v;
}

std::string Fields::text_of(const YAML::Node& n, const std::string& name) const {
  if (!n.IsScalar()) doc_.fail(n, fmt::format("{} must be a word, got {}", name, describe(n)));
  return n.Scalar();
}

std::string Fields::word_of(const YAML::Node& n, const std::string& name) const {
  if (!n.IsScalar() || n.Scalar().empty()) doc_.fail(n, fmt::format("{} must be a word, got {}", name, describe(n)));
  return n.Scalar();
}

}  // namespace cellwright::models::yaml
