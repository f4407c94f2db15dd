// The YAML field reader: typed fields come out as written, and every kind of bad field is reported at its file, line
// and column with the offending value; garbage never crashes it.
#include "cellwright/models/yaml_fields.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>

namespace cellwright::models::yaml {
namespace {

using ::testing::HasSubstr;

// One record of a made-up format, read with every getter once.
struct Record {
  std::string name;
  std::string note;
  double size = 0;
  double ratio = 0;
  double gap = 0;
  bool on = false;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::vector<double> values;
  std::vector<std::pair<std::string, std::pair<YAML::Node, YAML::Node>>> tags;
};

Record read_record(std::string_view text, MissingField missing = MissingField::kPlain) {
  const Doc doc("rec.yaml", missing);
  const YAML::Node root = load(text, doc, "not valid YAML");
  const Fields f(doc, root, "record", {"name", "note", "size", "ratio", "gap", "on", "xyz", "values", "tags"}, true);
  Record r;
  r.name = f.word("name");
  r.note = f.has("note") ? f.text("note") : "";
  r.size = f.positive("size");
  r.ratio = f.number_or("ratio", 0.5);
  r.gap = f.non_negative_or("gap", 0.0);
  r.on = f.boolean_or("on", false);
  r.xyz = f.vec3("xyz");
  r.values = f.numbers("values");
  if (f.has("tags")) r.tags = f.word_map("tags");
  return r;
}

constexpr const char* kGood = R"(name: box
note: ""
size: 2.5
gap: 0
on: yes
xyz: [1, -2, 3e-1]
values: []
tags: {a: 1, b: two}
)";

// The error read_record throws for `text`.
InputError error_of(std::string_view text, MissingField missing = MissingField::kPlain) {
  try {
    (void)read_record(text, missing);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return InputError({}, "");
}

TEST(YamlFields, ReadsEveryTypeAsWritten) {
  const Record r = read_record(kGood);
  EXPECT_EQ(r.name, "box");
  EXPECT_EQ(r.note, "");
  EXPECT_EQ(r.size, 2.5);
  EXPECT_EQ(r.ratio, 0.5);  // not given: the fallback
  EXPECT_EQ(r.gap, 0.0);
  EXPECT_TRUE(r.on);
  EXPECT_EQ(r.xyz, Eigen::Vector3d(1, -2, 0.3));
  EXPECT_TRUE(r.values.empty());
  ASSERT_EQ(r.tags.size(), 2u);
  EXPECT_EQ(r.tags[0].first, "a");  // file order
  EXPECT_EQ(r.tags[1].first, "b");
  EXPECT_EQ(r.tags[1].second.second.Scalar(), "two");
}

TEST(YamlFields, UnknownFieldIsReportedAtItsKeyWithTheAllowedOnes) {
  const InputError e = error_of(std::string(kGood) + "colour: red\n");
  EXPECT_EQ(e.where().file, "rec.yaml");
  EXPECT_EQ(e.where().line, 9);
  EXPECT_EQ(e.where().column, 1);
  EXPECT_EQ(e.problem(),
            "unknown field 'colour' in record 'box' (expected one of: name, note, size, ratio, gap, on, xyz, values, "
            "tags)");
  EXPECT_THAT(e.what(), HasSubstr("rec.yaml:9:1: error: "));
}

TEST(YamlFields, RepeatedFieldNamesTheFirstLine) {
  const InputError e = error_of(std::string(kGood) + "size: 3\n");
  EXPECT_EQ(e.where().line, 9);
  EXPECT_EQ(e.problem(), "field 'size' of record 'box' is given twice (first on line 3)");
}

TEST(YamlFields, MissingRequiredFieldPointsAtTheMappingInTheFilesWording) {
  const std::string text = "name: box\nxyz: [0, 0, 0]\nvalues: [1]\n";
  EXPECT_EQ(error_of(text).problem(), "record 'box' has no field 'size'");
  const InputError e = error_of(text, MissingField::kSayRequired);
  EXPECT_EQ(e.problem(), "record 'box' has no field 'size' (it is required)");
  EXPECT_EQ(e.where().line, 1);
  EXPECT_EQ(e.where().column, 1);
}

TEST(YamlFields, UnnamedObjectIsCalledByItsKind) {
  EXPECT_EQ(error_of("size: 1\n").problem(), "a record has no field 'name'");
}

TEST(YamlFields, BadValuesAreReportedAtTheValueWithTheValue) {
  struct Case {
    std::string from, to, problem;
    int line, column;
  };
  const Case cases[] = {
      {"size: 2.5", "size: -1", "field 'size' of record 'box' must be greater than 0, got -1", 3, 7},
      {"size: 2.5", "size: big", "field 'size' of record 'box' must be a number, got 'big'", 3, 7},
      {"size: 2.5", "size: .inf", "field 'size' of record 'box' must be a finite number, got .inf", 3, 7},
      {"size: 2.5", "size: [1]", "field 'size' of record 'box' must be a number, got a list", 3, 7},
      {"gap: 0", "gap: -0.5", "field 'gap' of record 'box' must not be negative, got -0.5", 4, 6},
      {"on: yes", "on: maybe", "field 'on' of record 'box' must be true or false, got 'maybe'", 5, 5},
      {"xyz: [1, -2, 3e-1]", "xyz: [1, 2]", "field 'xyz' of record 'box' must have 3 numbers, got 2", 6, 6},
      {"xyz: [1, -2, 3e-1]", "xyz: [1, x, 3]", "field 'xyz' of record 'box' must be a number, got 'x'", 6, 10},
      {"values: []", "values: 7", "field 'values' of record 'box' must be a list of numbers, got '7'", 7, 9},
      {"name: box", "name: ''", "field 'name' of record '' must be a word, got ''", 1, 7},
      {"name: box", "name: {a: 1}", "field 'name' of a record must be a word, got a mapping", 1, 7},
      {"tags: {a: 1, b: two}", "tags: [a]", "field 'tags' of record 'box' must be a mapping of names, got a list", 8,
       7},
      {"tags: {a: 1, b: two}", "tags: {a: 1, a: 2}",
       "'a' is given twice in field 'tags' of record 'box' (first on line 8)", 8, 14},
  };
  for (const Case& c : cases) {
    std::string text = kGood;
    text.replace(text.find(c.from), c.from.size(), c.to);
    const InputError e = error_of(text);
    EXPECT_EQ(e.problem(), c.problem) << c.to;
    EXPECT_EQ(e.where().line, c.line) << c.to;
    EXPECT_EQ(e.where().column, c.column) << c.to;
  }
}

TEST(YamlFields, NotAMappingIsReported) {
  const InputError e = error_of("- 1\n- 2\n");
  EXPECT_EQ(e.problem(), "a record must be a mapping of fields, got a list");
  EXPECT_EQ(e.where().line, 1);
}

TEST(YamlFields, SyntaxErrorNamesLineAndColumn) {
  const InputError e = error_of("name: box\nsize: [1, 2\n");
  EXPECT_EQ(e.where().file, "rec.yaml");
  EXPECT_GT(e.where().line, 0);
  EXPECT_GT(e.where().column, 0);
  EXPECT_THAT(e.problem(), HasSubstr("not valid YAML: "));
}

TEST(YamlFields, KeyNodeOfAMissingFieldIsABugNotAnInputError) {
  const Doc doc("rec.yaml");
  const Fields f(doc, load("a: 1\n", doc, "not valid YAML"), "record", {"a", "b"});
  EXPECT_EQ(doc.at(f.key_node("a")).line, 1);
  EXPECT_THROW((void)f.key_node("b"), InternalError);
}

// Seeded garbage: the good record with bytes replaced, inserted and deleted (YAML's own punctuation is likely). The
// reader either reads it or throws an InputError naming the file, a line and a column; nothing else escapes.
TEST(YamlFields, GarbageInGivesAPositionedErrorNeverACrash) {
  const std::string alphabet = ":-[]{},#&*!|>'\"%@`? \n\t0123456789abcxyz.";
  std::mt19937_64 rng(20261123);
  const auto below = [&rng](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  int errors = 0;
  for (int round = 0; round < 2000; ++round) {
    std::string text = kGood;
    const std::size_t edits = 1 + below(6);
    for (std::size_t i = 0; i < edits && !text.empty(); ++i) {
      const std::size_t at = below(text.size());
      const char c = alphabet[below(alphabet.size())];
      switch (below(3)) {
        case 0:
          text[at] = c;
          break;
        case 1:
          text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), c);
          break;
        default:
          text.erase(at, 1);
      }
    }
    try {
      (void)read_record(text);
    } catch (const InputError& e) {
      ++errors;
      EXPECT_EQ(e.where().file, "rec.yaml") << text;
      EXPECT_GT(e.where().line, 0) << e.what() << "\n" << text;
      EXPECT_GT(e.where().column, 0) << e.what() << "\n" << text;
      EXPECT_FALSE(e.problem().empty());
    }
  }
  // Most edits break the record; a few keep it valid (e.g. a changed digit).
  EXPECT_GT(errors, 1000);
}

}  // namespace
}  // namespace cellwright::models::yaml
