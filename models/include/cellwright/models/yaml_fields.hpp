// Reading typed fields of a user's YAML file, with the file, line and column of the offending node in every error.
// Used by every YAML reader of the project (the cell description, scenarios) so that they check fields the same way
// and word their errors the same way.
//
// Every error is a cellwright::InputError at the node concerned ("file:line:column: error: problem"); the messages
// below show the problem part, with <what> the name a reader gives the mapping ("the cell description", "robot
// 'puma'") and <field> "field '<key>' of <what>". Nothing here is tied to a thread: a Doc and its Fields are used by
// the one thread that reads the file.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cellwright/common/error.hpp"

#include <Eigen/Core>

namespace cellwright::models::yaml {

// How the missing-field error of one file's readers ends (each file format keeps its own established wording).
enum class MissingField {
  kPlain,        // "<what> has no field '<key>'"
  kSayRequired,  // "<what> has no field '<key>' (it is required)"
};

// The values a number may take: lo..hi in `unit` (empty, "m", "s", "kg", "deg"), lo itself excluded when `above`.
struct Range {
  double lo = 0;
  double hi = 0;
  bool above = false;       // lo is excluded ("greater than lo")
  std::string_view unit;    // printed after hi
  // "within lo..hi unit" or "greater than lo and at most hi unit".
  std::string text() const;
  bool contains(double v) const { return (above ? v > lo : v >= lo) && v <= hi; }
};

// One YAML file being read: its name, for the positions in errors.
class Doc {
 public:
  explicit Doc(std::string file, MissingField missing = MissingField::kPlain)
      : file_(std::move(file)), missing_(missing) {}

  // Where `n` is: {file, line, column}, 1-based; {file, 0, 0} for a node without a position (e.g. one that is not
  // in the file).
  SourceLocation at(const YAML::Node& n) const;
  // Throws InputError(at(n), problem).
  [[noreturn]] void fail(const YAML::Node& n, std::string problem) const;
  // Throws InputError(where, problem).
  [[noreturn]] void fail(const SourceLocation& where, std::string problem) const;

  const std::string& file() const { return file_; }
  MissingField missing_field() const { return missing_; }

 private:
  std::string file_;
  MissingField missing_;
};

// Parses `text` as one YAML document. A syntax error throws InputError at the line and column yaml-cpp reports (0 if
// it reports none): "<problem>: <yaml-cpp's message>", e.g. problem = "not valid YAML". An empty text gives a null
// node; the caller decides whether that is an error.
YAML::Node load(std::string_view text, const Doc& doc, std::string_view problem);

// A node for error messages: "'<scalar>'", "a list", "a mapping" or "nothing".
std::string describe(const YAML::Node& n);

// The fields of one YAML mapping. The constructor checks the mapping itself:
//  - not a mapping: "<what> must be a mapping of fields, got <describe>", at the node;
//  - a key that is not a scalar: "<what>: field names must be plain words";
//  - a key not in `allowed` (typos must not be silently ignored): "unknown field '<key>' in <what> (expected one of:
//    <allowed, comma-separated>)", at the key;
//  - a key given twice: "field '<key>' of <what> is given twice (first on line <n>)", at the second key.
// The getters then read one field each; those without a fallback require the field, and a missing one throws at the
// mapping "<what> has no field '<key>'" (with " (it is required)" if the Doc says so).
class Fields {
 public:
  // `what` names the mapping in errors. A named object passes its kind ("workpiece") with named = true: `what` is
  // then "workpiece 'A'" if the mapping has a scalar field `name: A`, else "a workpiece".
  Fields(const Doc& doc, const YAML::Node& map, std::string what, std::initializer_list<std::string_view> allowed,
         bool named = false);

  bool has(const std::string& key) const { return fields_.count(key) != 0; }
  // The value of a required field.
  const YAML::Node& node(const std::string& key) const;
  // The value of a field, or nothing if it is not given.
  std::optional<YAML::Node> get(const std::string& key) const;
  // The key node of a field that is given (its position is the start of the field's line); CW_CHECK that it is.
  const YAML::Node& key_node(const std::string& key) const;
  const YAML::Node& map() const { return map_; }
  const std::string& what() const { return what_; }
  // "field '<key>' of <what>", the name of a field in messages.
  std::string field(const std::string& key) const;

  // A finite number: "<field> must be a number, got <describe>" or "<field> must be a finite number, got <scalar>".
  double number(const std::string& key) const { return number_of(node(key), field(key)); }
  double number_or(const std::string& key, double fallback) const { return has(key) ? number(key) : fallback; }
  // A number > 0: "<field> must be greater than 0, got <value>".
  double positive(const std::string& key) const;
  double positive_or(const std::string& key, double fallback) const { return has(key) ? positive(key) : fallback; }
  // A number >= 0: "<field> must not be negative, got <value>".
  double non_negative_or(const std::string& key, double fallback) const;
  // A number within `range`: "<field> must be <range.text()>, got <value>" (e.g. "must be greater than 0 and at
  // most 3600 s, got 1e+300"). The bounds say what a real cell cannot exceed: values outside are typos or unit
  // mistakes, and some would overflow the simulation's clock or break its physics.
  double within(const std::string& key, const Range& range) const { return within_of(node(key), field(key), range); }
  double within_or(const std::string& key, double fallback, const Range& range) const {
    return has(key) ? within(key, range) : fallback;
  }
  // As vec3(key), each number within `range`.
  Eigen::Vector3d vec3_within(const std::string& key, const Range& range) const;
  // Any scalar, possibly empty: "<field> must be a word, got <describe>".
  std::string text(const std::string& key) const { return text_of(node(key), field(key)); }
  // A non-empty scalar: "<field> must be a word, got <describe>".
  std::string word(const std::string& key) const { return word_of(node(key), field(key)); }
  // true/false (and YAML's other spellings): "<field> must be true or false, got <describe>".
  bool boolean_or(const std::string& key, bool fallback) const;
  // A list of finite numbers: "<field> must be a list of numbers, got <describe>", then each as number().
  std::vector<double> numbers(const std::string& key) const;
  // As numbers(key), of exactly `count`: "<field> must have <count> numbers, got <size>".
  std::vector<double> numbers(const std::string& key, std::size_t count) const;
  // As numbers(key, 3).
  Eigen::Vector3d vec3(const std::string& key) const;
  // A mapping of word -> anything, in file order, each as {word, {key node, value node}}: "<field> must be a mapping
  // of names, got <describe>"; a key as word_of("a name in <field>"); a key given twice: "'<key>' is given twice in
  // <field> (first on line <n>)".
  std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> word_map(const std::string& key) const;

  // The same checks for a node that is not a field of this mapping (a list entry); `name` replaces <field>.
  double number_of(const YAML::Node& n, const std::string& name) const;
  double within_of(const YAML::Node& n, const std::string& name, const Range& range) const;
  std::string text_of(const YAML::Node& n, const std::string& name) const;
  std::string word_of(const YAML::Node& n, const std::string& name) const;

 private:
  const Doc& doc_;
  YAML::Node map_;
  std::string what_;
  std::map<std::string, std::pair<YAML::Node, YAML::Node>> fields_;  // key -> {key node, value node}
};

}  // namespace cellwright::models::yaml
