// A named part relayed between robots (docs/scenarios.md, "Relaying a part between robots"): put down by one robot on
// a stand or a belt and taken up there by another. Preflight accepts it where it is physically sound (ordered by the
// program, the taker reaches the part where it lies, a belt's part taken where the belt stops it) and refuses it
// with the reason where it is not.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sim/sweep.hpp"

namespace cellwright::cell {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::Not;

const std::string kSource = CW_SOURCE_DIR;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void replace(std::string& text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
}

std::vector<std::string> needs_of(const Preflight& p) {
  std::vector<std::string> out;
  for (const ReachNeed& n : p.needs) out.push_back(n.robot + ": " + n.target);
  return out;
}

class Relay : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           fmt::format("relay_test_{}", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }
  // scenes/relay.yaml with the cell by absolute path, the program `program` (written here) and `edit` applied.
  fs::path stand_relay(const std::string& program, const std::vector<std::pair<std::string, std::string>>& edits = {}) {
    std::string text = slurp(kSource + "/scenes/relay.yaml");
    replace(text, "cell: cell.yaml", "cell: " + kSource + "/scenes/cell.yaml");
    replace(text, "program: relay.task", "program: prog.task");
    for (const auto& [from, to] : edits) replace(text, from, to);
    write("prog.task", program);
    return write("s.yaml", text);
  }
  // The three-robot cell of tests/data/relay, its robots' URDFs by absolute path, with `edit` applied.
  fs::path belt_cell(const std::pair<std::string, std::string>& edit) {
    std::string text = slurp(kSource + "/tests/data/relay/cell.yaml");
    for (std::string::size_type at = 0; (at = text.find("../../../models", at)) != std::string::npos;) {
      text.replace(at, 15, kSource + "/models");
    }
    replace(text, edit.first, edit.second);
    return write("cell.yaml", text);
  }

  fs::path dir_;
};

const std::string kShippedRelay = slurp(kSource + "/scenes/relay.task");

// The shipped scenario: the PUMA puts A on the stand, the MELFA takes it from there (it reaches the stand, the net
// orders its pick after the put-down, every move is planned and swept).
TEST_F(Relay, OverAStandPassesPreflightWithTheTakerGoingToThePartOnTheStand) {
  const Scenario s = load_scenario(kSource + "/scenes/relay.yaml");
  const models::LocationSpec* stand = s.cell.find_location("relay_stand");
  ASSERT_NE(stand, nullptr);
  ASSERT_TRUE(stand->stand.has_value());
  EXPECT_DOUBLE_EQ(stand->stand->x(), 0.1);
  const Preflight p = preflight(s, &twin_port());
  EXPECT_TRUE(p.ok()) << ::testing::PrintToString(p.problems);
  EXPECT_THAT(needs_of(p), ::testing::ElementsAre("puma: workpiece 'A' at location 'input_pick'",
                                                  "puma: location 'relay_stand'",
                                                  "melfa: workpiece 'A' on location 'relay_stand'",
                                                  "melfa: location 'output_drop'"));
  EXPECT_TRUE(p.collisions.empty()) << ::testing::PrintToString(p.collisions);
}

// Without the semaphore the MELFA may go for A before the PUMA has put it down: refused, naming both commands.
TEST_F(Relay, PickThatNothingOrdersAfterThePutDownIsRefusedNamingBoth) {
  std::string program = kShippedRelay;
  replace(program, "  wait down\n", "");
  replace(program, "  signal down\n", "");
  replace(program, "semaphore down\n", "");
  const Preflight p = preflight(load_scenario(stand_relay(program)), &twin_port());
  ASSERT_FALSE(p.ok());
  EXPECT_THAT(p.problems,
              Contains(AllOf(HasSubstr("robot 'melfa' goes to workpiece 'A' (prog.task:"), HasSubstr("'Pick A')"),
                             HasSubstr("that robot 'puma' lets go of (prog.task:"), HasSubstr("'Place S')"),
                             HasSubstr("nothing in the program orders the two"))));
  // Not the misleading reach check of the MELFA at the input conveyor, where a run might find A first.
  EXPECT_THAT(p.problems, Not(Contains(HasSubstr("input_pick"))));
}

// The steps table orders a relay by its lines: accepted, the same as with the semaphore.
TEST_F(Relay, StepsTableLinesOrderTheRelay) {
  const Preflight p = preflight(load_scenario(stand_relay("robot r1 r2\nworkpiece A\nlocation S OUT\n\nsteps\n"
                                                          "  r1      | r2\n  Pick A  |\n  Place S |\n  home    |\n"
                                                          "          | Pick A\n          | Place OUT\nend\n")),
                                &twin_port());
  EXPECT_TRUE(p.ok()) << ::testing::PrintToString(p.problems);
}

// A stand the PUMA reaches and the MELFA does not: refused, saying where A is and who put it there.
TEST_F(Relay, TakerThatCannotReachTheStandIsRefusedSayingWhoPutThePartThere) {
  const Preflight p = preflight(
      load_scenario(stand_relay(kShippedRelay, {{"xyz: [0.6, 0.2, 0.3]", "xyz: [0.3, -0.35, 0.3]"}})), &twin_port());
  ASSERT_FALSE(p.ok());
  EXPECT_THAT(p.problems, Contains(AllOf(HasSubstr("robot 'melfa' cannot reach workpiece 'A' on location "
                                                   "'relay_stand' (grasp), needed by prog.task:"),
                                         HasSubstr("'Pick A'"), HasSubstr("maximum reach"),
                                         HasSubstr("robot 'puma' put it there (prog.task:"))));
  EXPECT_THAT(p.problems, Not(Contains(HasSubstr("robot 'puma' cannot reach"))));
}

// A stand is read with its footprint; a bad one is refused at its line.
TEST_F(Relay, BadStandIsRefusedAtItsLine) {
  const auto expect_error = [&](const std::string& from, const std::string& to, const std::string& text) {
    const fs::path file = stand_relay(kShippedRelay, {{from, to}});
    try {
      load_scenario(file);
      ADD_FAILURE() << "no error; expected: " << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.where().file, file.string()) << e.what();
      EXPECT_EQ(e.where().line, 10) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  };
  expect_error("stand: [0.1, 0.1]", "stand: [0.1]", "must be a list of 2 sizes [x, y] in m");
  expect_error("stand: [0.1, 0.1]", "stand: [0.1, -1]", "stand");
  expect_error("xyz: [0.6, 0.2, 0.3]", "xyz: [0.6, 0.2, 0.0]", "a stand under it must be at least 0.01 m high");
}

// A named part relayed over two belts (tests/data/relay/relay_named.yaml): each taker goes to the part where the
// belt stops it, not where the giver let go of it (beyond its reach). Refused before: the reach was checked there.
TEST_F(Relay, OverABeltTheTakerGoesToThePartAtTheBeltsStop) {
  const Scenario s = load_scenario(kSource + "/tests/data/relay/relay_named.yaml");
  const Preflight p = preflight(s, &twin_port());
  EXPECT_TRUE(p.ok()) << ::testing::PrintToString(p.problems);
  EXPECT_THAT(needs_of(p), AllOf(Contains("p2: workpiece 'A' at the stop of conveyor 'c1'"),
                                 Contains("p3: workpiece 'A' at the stop of conveyor 'c2'")));
  EXPECT_THAT(needs_of(p), Not(Contains(HasSubstr("on location 'c1_put'"))));
}

// A belt without a stop bar carries the part off its end: the taker's pick is refused, saying so.
TEST_F(Relay, OverABeltWithoutAStopTheTakersPickIsRefused) {
  const fs::path cell = belt_cell(
      {"enter: 0.1, leave: 0.75, stop: true}\n  - {name: c2", "enter: 0.1, leave: 0.75, stop: false}\n  - {name: c2"});
  std::string scenario = slurp(kSource + "/tests/data/relay/relay_named.yaml");
  replace(scenario, "cell: cell.yaml", "cell: " + cell.string());
  replace(scenario, "program: relay_named.task", "program: " + kSource + "/tests/data/relay/relay_named.task");
  const Preflight p = preflight(load_scenario(write("s.yaml", scenario)), &twin_port());
  ASSERT_FALSE(p.ok());
  EXPECT_THAT(p.problems, Contains(AllOf(HasSubstr("robot 'p2' goes to workpiece 'A' (relay_named.task:13:16 'Pick "
                                                   "A'), but robot 'p1' lets go of it on conveyor 'c1'"),
                                         HasSubstr("which carries it off its end"))));
}

}  // namespace
}  // namespace cellwright::cell
