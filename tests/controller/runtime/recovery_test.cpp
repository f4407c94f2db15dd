// The decision tree of fault diagnosis (recovery.hpp, docs/faults.md section 3): the built-in tree is the shipped
// scenes/recovery.yaml, diagnose() walks a symptom's tree asking the questions it meets, and a tree file with a mistake
// is refused with an InputError that says where and what.
#include "cellwright/runtime/recovery.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"
#include "common/garbage_in.hpp"

namespace cellwright::runtime {
namespace {

using ::testing::HasSubstr;

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::string& shipped_path() {
  static const std::string path = std::string(CW_SOURCE_DIR) + "/scenes/recovery.yaml";
  return path;
}

// Answers from a table (a question not in it: no), recording what was asked, in order.
struct Answers {
  std::map<Question, bool> table;
  std::vector<Question> asked;
  std::function<bool(Question)> fn() {
    return [this](Question q) {
      asked.push_back(q);
      const auto it = table.find(q);
      return it != table.end() && it->second;
    };
  }
};

// parse() of `text` as "test.yaml" must throw; returns what() (empty if nothing was thrown).
std::string parse_error(const std::string& text) {
  try {
    (void)DecisionTree::parse(text, "test.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError for:\n" << text;
  return "";
}

// ---- The built-in tree ----

TEST(RuntimeRecovery, TheBuiltInTreeIsTheShippedFileByteForByte) {
  const std::string file = read_text(shipped_path());
  ASSERT_FALSE(file.empty()) << "cannot read " << shipped_path();
  EXPECT_EQ(std::string(DecisionTree::standard_text()), file);
}

TEST(RuntimeRecovery, TheBuiltInTreeHasATreeForEverySymptom) {
  const DecisionTree& tree = DecisionTree::standard();
  for (std::size_t i = 0; i < kSymptoms; ++i) {
    const auto s = static_cast<Symptom>(i);
    EXPECT_TRUE(tree.has(s)) << to_string(s);
    // The names go both ways.
    EXPECT_EQ(symptom_from(to_string(s)), s) << to_string(s);
  }
  EXPECT_EQ(symptom_from("no_such_symptom"), std::nullopt);
}

TEST(RuntimeRecovery, TheShippedFileLoadsToTheSameDiagnosesAsTheBuiltInTree) {
  const DecisionTree loaded = DecisionTree::load(shipped_path());
  const DecisionTree& standard = DecisionTree::standard();
  // Every symptom under every combination of answers to the questions (9 questions: 512 combinations).
  for (std::size_t i = 0; i < kSymptoms; ++i) {
    const auto s = static_cast<Symptom>(i);
    EXPECT_TRUE(loaded.has(s)) << to_string(s);
    for (unsigned bits = 0; bits < 512; ++bits) {
      const auto answer = [bits](Question q) { return ((bits >> static_cast<unsigned>(q)) & 1u) != 0; };
      const Diagnosis a = loaded.diagnose(s, answer);
      const Diagnosis b = standard.diagnose(s, answer);
      ASSERT_EQ(a.cause, b.cause) << to_string(s) << " " << bits;
      ASSERT_EQ(a.action, b.action) << to_string(s) << " " << bits;
      ASSERT_EQ(a.path, b.path) << to_string(s) << " " << bits;
    }
  }
}

// A tree file saved with a UTF-8 byte-order mark reads as the same tree.
TEST(RuntimeRecovery, ByteOrderMarkIsAccepted) {
  const DecisionTree tree = DecisionTree::parse(
      "\xEF\xBB\xBF" + read_text(shipped_path()), "bom.yaml");
  for (std::size_t i = 0; i < kSymptoms; ++i) EXPECT_TRUE(tree.has(static_cast<Symptom>(i)));
}

TEST(RuntimeRecovery, QuestionAndActionNamesGoBothWays) {
  for (std::size_t i = 0; i < 9; ++i) {
    const auto q = static_cast<Question>(i);
    EXPECT_EQ(question_from(to_string(q)), q) << to_string(q);
    const auto a = static_cast<Action>(i);
    EXPECT_EQ(action_from(to_string(a)), a) << to_string(a);
  }
  EXPECT_EQ(to_string(Question::signal_fired), "signal_fired");
  EXPECT_EQ(to_string(Action::stop_cell), "stop_cell");
  EXPECT_EQ(question_from("part_gone"), std::nullopt);
  EXPECT_EQ(action_from("pray"), std::nullopt);
}

// ---- diagnose() ----

TEST(RuntimeRecovery, DiagnoseWalksTheTreeAndReportsTheAnswersOnTheWay) {
  const DecisionTree& tree = DecisionTree::standard();
  Answers answers;
  answers.table = {{Question::driver_in_fault, false}, {Question::motion_blocked, false}, {Question::retries_left, true}};
  const Diagnosis d = tree.diagnose(Symptom::driver_timeout, answers.fn());
  EXPECT_EQ(d.symptom, Symptom::driver_timeout);
  EXPECT_EQ(d.cause, "controller_timeout");
  EXPECT_EQ(d.action, Action::retry);
  EXPECT_EQ(d.path, "driver_in_fault=no motion_blocked=no retries_left=yes");
  EXPECT_EQ(answers.asked,
            (std::vector<Question>{Question::driver_in_fault, Question::motion_blocked, Question::retries_left}));
}

TEST(RuntimeRecovery, DiagnoseAsksOnlyTheQuestionsOnItsPath) {
  const DecisionTree& tree = DecisionTree::standard();
  Answers answers;
  answers.table = {{Question::part_seen, true}, {Question::retries_left, true}, {Question::part_reachable, false}};
  const Diagnosis d = tree.diagnose(Symptom::grip_lost, answers.fn());
  EXPECT_EQ(d.cause, "dropped_out_of_reach");
  EXPECT_EQ(d.action, Action::set_aside);
  EXPECT_EQ(d.path, "part_seen=yes retries_left=yes part_reachable=no");

  Answers unseen;  // everything no
  const Diagnosis u = tree.diagnose(Symptom::grip_lost, unseen.fn());
  EXPECT_EQ(u.cause, "dropped_unseen");
  EXPECT_EQ(u.action, Action::set_aside);
  EXPECT_EQ(u.path, "part_seen=no");
  EXPECT_EQ(unseen.asked, std::vector<Question>{Question::part_seen});
}

TEST(RuntimeRecovery, ALeafAtTheRootAsksNothing) {
  const DecisionTree tree =
      DecisionTree::parse("closed_on_wrong_part: {cause: wrong_part_in_the_way, action: stop_cell}\n", "mine.yaml");
  Answers answers;
  const Diagnosis d = tree.diagnose(Symptom::closed_on_wrong_part, answers.fn());
  EXPECT_EQ(d.cause, "wrong_part_in_the_way");
  EXPECT_EQ(d.action, Action::stop_cell);
  EXPECT_EQ(d.path, "");
  EXPECT_TRUE(answers.asked.empty());
}

TEST(RuntimeRecovery, TheStandardTreeGivesUpWhenNoRetriesAreLeft) {
  const DecisionTree& tree = DecisionTree::standard();
  for (const Symptom s : {Symptom::driver_fault, Symptom::link_lost, Symptom::position_refused,
                          Symptom::position_missed}) {
    Answers with;
    with.table = {{Question::retries_left, true}};
    EXPECT_NE(tree.diagnose(s, with.fn()).action, Action::stop_cell) << to_string(s);
    Answers without;
    const Diagnosis d = tree.diagnose(s, without.fn());
    EXPECT_EQ(d.action, Action::stop_cell) << to_string(s);
    EXPECT_EQ(d.path, "retries_left=no") << to_string(s);
  }
}

TEST(RuntimeRecovery, ASymptomWithoutATreeIsAnUnknownCauseThatStopsTheCell) {
  const DecisionTree tree = DecisionTree::parse("frame_lost: {cause: camera_dropout, action: go_on}\n", "mine.yaml");
  EXPECT_TRUE(tree.has(Symptom::frame_lost));
  EXPECT_FALSE(tree.has(Symptom::grip_lost));
  Answers answers;
  const Diagnosis d = tree.diagnose(Symptom::grip_lost, answers.fn());
  EXPECT_EQ(d.symptom, Symptom::grip_lost);
  EXPECT_EQ(d.cause, "unknown");
  EXPECT_EQ(d.action, Action::stop_cell);
  EXPECT_EQ(d.path, "");
  EXPECT_TRUE(answers.asked.empty());
}

TEST(RuntimeRecovery, AnEmptyTreeHasNoSymptoms) {
  const DecisionTree tree = DecisionTree::parse("{}\n", "empty.yaml");
  for (std::size_t i = 0; i < kSymptoms; ++i) EXPECT_FALSE(tree.has(static_cast<Symptom>(i)));
}

TEST(RuntimeRecovery, ACustomTreeIsWalkedAsWritten) {
  const DecisionTree tree = DecisionTree::parse(
      "closed_on_nothing:\n"
      "  ask: part_seen\n"
      "  yes:\n"
      "    ask: part_upright\n"
      "    yes: {cause: a, action: pick_again}\n"
      "    no: {cause: b, action: set_aside}\n"
      "  no: {cause: c, action: stop_cell}\n",
      "mine.yaml");
  Answers answers;
  answers.table = {{Question::part_seen, true}, {Question::part_upright, false}};
  const Diagnosis d = tree.diagnose(Symptom::closed_on_nothing, answers.fn());
  EXPECT_EQ(d.cause, "b");
  EXPECT_EQ(d.action, Action::set_aside);
  EXPECT_EQ(d.path, "part_seen=yes part_upright=no");
}

// ---- Mistakes in a tree file ----

TEST(RuntimeRecovery, TextThatIsNotYamlIsRefused) {
  const std::string e = parse_error("grip_lost:\n  ask: [part_seen\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:"));
  EXPECT_THAT(e, HasSubstr("the decision tree is not valid YAML"));
}

TEST(RuntimeRecovery, ATreeThatIsNotAMappingIsRefused) {
  const std::string e = parse_error("- grip_lost\n- frame_lost\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:1"));
  EXPECT_THAT(e, HasSubstr("a decision tree must be a mapping of symptoms, got a list"));
}

TEST(RuntimeRecovery, AnUnknownSymptomIsRefusedNamingIt) {
  const std::string e = parse_error(
      "frame_lost: {cause: camera_dropout, action: go_on}\n"
      "gripper_on_fire: {cause: fire, action: stop_cell}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:2:1: error: "));
  EXPECT_THAT(e, HasSubstr("unknown symptom 'gripper_on_fire'"));
  EXPECT_THAT(e, HasSubstr("grip_lost"));  // the symptoms it could have been
}

TEST(RuntimeRecovery, AnUnknownQuestionIsRefusedNamingIt) {
  const std::string e = parse_error(
      "grip_lost:\n"
      "  ask: part_seen\n"
      "  yes:\n"
      "    ask: part_happy\n"
      "    yes: {cause: a, action: retry}\n"
      "    no: {cause: b, action: retry}\n"
      "  no: {cause: c, action: retry}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:4:"));
  EXPECT_THAT(e, HasSubstr("unknown question 'part_happy'"));
  EXPECT_THAT(e, HasSubstr("the 'yes' of 'part_seen'"));
}

TEST(RuntimeRecovery, AnUnknownActionIsRefusedNamingIt) {
  const std::string e = parse_error(
      "link_lost:\n"
      "  ask: retries_left\n"
      "  yes: {cause: dropped, action: reset_rehome}\n"
      "  no: {cause: down, action: pray}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:4:"));
  EXPECT_THAT(e, HasSubstr("unknown action 'pray'"));
  EXPECT_THAT(e, HasSubstr("the 'no' of 'retries_left'"));
  EXPECT_THAT(e, HasSubstr("stop_cell"));  // the actions it could have been
}

TEST(RuntimeRecovery, AnInnerNodeWithoutNoIsRefused) {
  const std::string e = parse_error(
      "frame_lost: {cause: camera_dropout, action: go_on}\n"
      "link_lost:\n"
      "  ask: retries_left\n"
      "  yes: {cause: dropped, action: reset_rehome}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:3:"));
  EXPECT_THAT(e, HasSubstr("symptom 'link_lost' asks 'retries_left' but lacks 'no'"));
}

TEST(RuntimeRecovery, AnInnerNodeWithoutYesIsRefused) {
  const std::string e = parse_error(
      "link_lost:\n"
      "  ask: retries_left\n"
      "  no: {cause: down, action: stop_cell}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:2:"));
  EXPECT_THAT(e, HasSubstr("asks 'retries_left' but lacks 'yes'"));
}

TEST(RuntimeRecovery, ALeafWithoutAnActionIsRefused) {
  const std::string e = parse_error(
      "frame_lost: {cause: camera_dropout, action: go_on}\n"
      "part_not_arrived: {cause: missing}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:2:"));
  EXPECT_THAT(e, HasSubstr("symptom 'part_not_arrived' has no field 'action'"));
}

TEST(RuntimeRecovery, AnUnknownFieldIsRefused) {
  const std::string e = parse_error(
      "frame_lost: {cause: camera_dropout, action: go_on}\n"
      "part_not_arrived: {cause: missing, action: set_aside, priority: 3}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:2:"));
  EXPECT_THAT(e, HasSubstr("unknown field 'priority' in symptom 'part_not_arrived'"));
}

TEST(RuntimeRecovery, AnUnknownFieldInAnInnerNodeIsRefused) {
  const std::string e = parse_error(
      "link_lost:\n"
      "  ask: retries_left\n"
      "  yes: {cause: dropped, action: reset_rehome}\n"
      "  no: {cause: down, action: stop_cell}\n"
      "  maybe: {cause: unsure, action: retry}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:5:"));
  EXPECT_THAT(e, HasSubstr("unknown field 'maybe' in symptom 'link_lost'"));
}

TEST(RuntimeRecovery, ASymptomGivenTwiceIsRefused) {
  const std::string e = parse_error(
      "frame_lost: {cause: camera_dropout, action: go_on}\n"
      "link_lost: {cause: down, action: stop_cell}\n"
      "frame_lost: {cause: again, action: stop_cell}\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:3:1: error: "));
  EXPECT_THAT(e, HasSubstr("symptom 'frame_lost' is given twice"));
}

TEST(RuntimeRecovery, ANodeThatIsNotAMappingIsRefused) {
  const std::string e = parse_error("frame_lost: go_on\n");
  EXPECT_THAT(e, HasSubstr("test.yaml:1:"));
  EXPECT_THAT(e, HasSubstr("symptom 'frame_lost' must be {ask, yes, no} or {cause, action}, got 'go_on'"));
}

TEST(RuntimeRecovery, LoadingAMissingFileIsRefusedNamingIt) {
  const std::string path = std::string(CW_SOURCE_DIR) + "/scenes/no_such_recovery.yaml";
  try {
    (void)DecisionTree::load(path);
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(path));
    EXPECT_THAT(e.what(), HasSubstr("cannot read the decision tree file"));
    EXPECT_EQ(e.where().file, path);
  }
}

TEST(RuntimeRecovery, ErrorsOfALoadedFileNameTheFile) {
  const std::string path = ::testing::TempDir() + "/cw_recovery_test_bad.yaml";
  {
    std::ofstream out(path);
    out << "frame_lost: {cause: camera_dropout, action: go_on}\nlink_lost: {cause: down}\n";
  }
  try {
    (void)DecisionTree::load(path);
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(path + ":2:"));
    EXPECT_THAT(e.what(), HasSubstr("has no field 'action'"));
  }
  std::remove(path.c_str());
}

// Seeded garbage in: the shipped tree with random edits is read (and every symptom's walk ends at a leaf) or refused
// with an InputError naming the file; nothing else escapes.
TEST(RuntimeRecovery, MutatedTreesAreReadOrRefusedWithAnInputError) {
  const auto counts = cellwright::testing::feed_garbage(
      {read_text(shipped_path())}, 3000, 20261124, ":-[]{},#&*!|>'\"%@`? \n\t0123456789abcxyz_.", "mutant.yaml",
      [](const std::string& text) {
        const DecisionTree tree = DecisionTree::parse(text, "mutant.yaml");
        for (std::size_t s = 0; s < kSymptoms; ++s) {
          bool yes = false;
          const Diagnosis d = tree.diagnose(static_cast<Symptom>(s), [&](Question) { return yes = !yes; });
          EXPECT_FALSE(d.cause.empty()) << text;
        }
      });
  EXPECT_GT(counts.accepted, 100);
  EXPECT_GT(counts.refused, 1000);
}

}  // namespace
}  // namespace cellwright::runtime
