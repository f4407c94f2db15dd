// The task-level language parser: what it accepts, what it builds, and every error it reports (with its location).
#include "cellwright/task/program.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace cellwright::task {
namespace {

const std::string kExchange = R"(# Table 1 of the paper
robot r1 r2
workpiece A
location B

steps
  r1       | r2
  Pick A   |
  Put r2   | Get r1
           | Place B
end
)";

struct Failure {
  int line = 0;
  int column = 0;
  std::string problem;
};

// Parses `text` expecting an InputError; returns where and what.
Failure parse_failure(const std::string& text) {
  try {
    parse_program(text, "t.task");
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "t.task");
    return {e.where().line, e.where().column, e.problem()};
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return {};
}

void expect_failure(const std::string& text, int line, int column, const std::string& problem) {
  const Failure f = parse_failure(text);
  EXPECT_EQ(f.line, line) << f.problem;
  EXPECT_EQ(f.column, column) << f.problem;
  EXPECT_EQ(f.problem, problem);
}

TEST(ParseProgram, ReadsTable1AsPrinted) {
  const Program p = parse_program(kExchange, "exchange.task");
  EXPECT_EQ(p.file, "exchange.task");
  EXPECT_EQ(declared_names(p, NameKind::kRobot), (std::vector<std::string>{"r1", "r2"}));
  EXPECT_EQ(declared_names(p, NameKind::kWorkpiece), (std::vector<std::string>{"A"}));
  EXPECT_EQ(declared_names(p, NameKind::kLocation), (std::vector<std::string>{"B"}));
  ASSERT_TRUE(p.steps.has_value());
  const StepTable& t = *p.steps;
  EXPECT_EQ(t.where.line, 6);
  EXPECT_EQ(t.robots, (std::vector<std::string>{"r1", "r2"}));
  EXPECT_EQ(t.robot_where[1].line, 7);
  EXPECT_EQ(t.robot_where[1].column, 14);
  ASSERT_EQ(t.lines.size(), 3u);
  // Step 1: r1 picks, r2 idles.
  EXPECT_EQ(t.lines[0].step, 1);
  EXPECT_EQ(t.lines[0].where.line, 8);
  ASSERT_EQ(t.lines[0].cells.size(), 2u);
  ASSERT_TRUE(t.lines[0].cells[0].has_value());
  EXPECT_EQ(to_string(*t.lines[0].cells[0]), "Pick A");
  EXPECT_EQ(t.lines[0].cells[0]->where.column, 3);
  EXPECT_EQ(t.lines[0].cells[0]->argument_where.column, 8);
  EXPECT_EQ(t.lines[0].cells[0]->argument_kind, NameKind::kWorkpiece);
  EXPECT_FALSE(t.lines[0].cells[1].has_value());
  // Step 2: Put and Get on the same line.
  EXPECT_EQ(t.lines[1].cells[0]->kind, CommandKind::kPut);
  EXPECT_EQ(t.lines[1].cells[0]->argument, "r2");
  EXPECT_EQ(t.lines[1].cells[1]->kind, CommandKind::kGet);
  EXPECT_EQ(t.lines[1].cells[1]->where.column, 14);
  // Step 3: the line starts with '|': r1 idles.
  EXPECT_FALSE(t.lines[2].cells[0].has_value());
  EXPECT_EQ(to_string(*t.lines[2].cells[1]), "Place B");
  EXPECT_EQ(t.lines[2].cells[1]->argument_kind, NameKind::kLocation);
  EXPECT_TRUE(p.sequences.empty());
}

TEST(ParseProgram, KeywordsAreCaseInsensitiveNamesAreNot) {
  const Program p = parse_program("ROBOT r1 R1\nWorkpiece A a\nSTEPS\nr1 | R1\nPICK A | pick a\nEnd\n", "t.task");
  EXPECT_EQ(declared_names(p, NameKind::kRobot), (std::vector<std::string>{"r1", "R1"}));
  const auto& cells = p.steps->lines[0].cells;
  EXPECT_EQ(to_string(*cells[0]), "Pick A");  // canonical keyword spelling
  EXPECT_EQ(to_string(*cells[1]), "Pick a");
}

TEST(ParseProgram, FewerCellsMeanTheRestIdle) {
  const Program p = parse_program("robot r1 r2 r3\nworkpiece A\nsteps\nr1|r2|r3\nPick A\n| | Pick A\nend\n", "t");
  ASSERT_EQ(p.steps->lines.size(), 2u);
  EXPECT_EQ(p.steps->lines[0].cells.size(), 3u);
  EXPECT_TRUE(p.steps->lines[0].cells[0].has_value());
  EXPECT_FALSE(p.steps->lines[0].cells[1].has_value());
  EXPECT_FALSE(p.steps->lines[0].cells[2].has_value());
  EXPECT_TRUE(p.steps->lines[1].cells[2].has_value());
  // A line of empty cells is a step in which no robot acts.
  const Program idle = parse_program("robot r1 r2\nsteps\nr1|r2\n |\nend\n", "t");
  ASSERT_EQ(idle.steps->lines.size(), 1u);
  EXPECT_FALSE(idle.steps->lines[0].cells[0].has_value());
  EXPECT_FALSE(idle.steps->lines[0].cells[1].has_value());
}

TEST(ParseProgram, DeclarationsSemaphoresRegionsAndSequences) {
  const Program p = parse_program(
      "robot r1 r2\r\n"
      "semaphore s\n"
      "semaphore t = 3 u=2 v\n"
      "region Z   # the machine\n"
      "\n"
      "sequence r1\n"
      "  wait s\n"
      "  enter Z\n"
      "  leave Z\n"
      "end\n"
      "sequence r2   # second\n"
      "  signal s\n"
      "end",
      "t.task");
  ASSERT_EQ(p.declarations.size(), 7u);
  EXPECT_EQ(p.declarations[3].name, "t");
  EXPECT_EQ(p.declarations[3].initial, 3u);
  EXPECT_EQ(p.declarations[4].initial, 2u);
  EXPECT_EQ(p.declarations[5].initial, 0u);
  EXPECT_EQ(p.declarations[6].kind, NameKind::kRegion);
  EXPECT_EQ(p.declarations[6].where.line, 4);
  EXPECT_EQ(p.declarations[6].where.column, 8);
  ASSERT_EQ(p.sequences.size(), 2u);
  EXPECT_EQ(p.sequences[0].robot, "r1");
  ASSERT_EQ(p.sequences[0].commands.size(), 3u);
  EXPECT_EQ(p.sequences[0].commands[1].kind, CommandKind::kEnter);
  EXPECT_EQ(p.sequences[0].commands[1].where.line, 8);
  EXPECT_EQ(p.sequences[1].commands[0].kind, CommandKind::kSignal);
  EXPECT_FALSE(p.steps.has_value());
  ASSERT_NE(find_declaration(p, "Z"), nullptr);
  EXPECT_EQ(find_declaration(p, "Z")->kind, NameKind::kRegion);
  EXPECT_EQ(find_declaration(p, "nope"), nullptr);
}

TEST(ParseProgram, NamesMayBeUsedBeforeTheirDeclaration) {
  const Program p = parse_program("sequence r1\nPick A\nend\nrobot r1\nworkpiece A\n", "t");
  EXPECT_EQ(p.sequences[0].commands[0].argument_kind, NameKind::kWorkpiece);
}

TEST(ParseProgram, EmptyTable) {
  const Program p = parse_program("robot r1\nsteps\nr1\nend\n", "t");
  EXPECT_TRUE(p.steps->lines.empty());
}

// A program that gives no robot anything to do is an input error naming the file, not a net dead from the start.
TEST(ParseErrors, EmptyProgram) {
  for (const char* text : {"", "# nothing\n\n", "\n  \t\n# only comments\n", "\xEF\xBB\xBF"}) {
    const Failure f = parse_failure(text);
    EXPECT_EQ(f.line, 1) << text;
    EXPECT_EQ(f.problem.rfind("the program is empty: it has no statements", 0), 0u) << f.problem;
  }
  const Failure declared = parse_failure("# robots\nrobot r1 r2\nworkpiece A\n");
  EXPECT_EQ(declared.line, 2);
  EXPECT_EQ(declared.column, 7);
  EXPECT_EQ(declared.problem.rfind("the program declares names but says nothing for any robot to do", 0), 0u)
      << declared.problem;
}

// An editor's UTF-8 byte-order mark before the first statement is skipped: the program and its columns are as
// without it.
TEST(ParseProgram, ByteOrderMarkIsSkipped) {
  const Program p = parse_program("\xEF\xBB\xBF" + kExchange, "t");
  ASSERT_TRUE(p.steps);
  EXPECT_EQ(p.steps->lines.size(), 3u);
  const Failure f = parse_failure("\xEF\xBB\xBFrobot r1 r1\nsequence r1\nend\n");
  EXPECT_EQ(f.line, 1);
  EXPECT_EQ(f.column, 10);  // the second r1, counted without the mark
  // Elsewhere the bytes are still no part of the language.
  EXPECT_EQ(parse_failure("robot r1\n\xEF\xBB\xBFsequence r1\nend\n").line, 2);
}

// ---- loops and workpiece classes ---------------------------------------------------------------------------------

const std::string kShift = R"(robot r1 r2
workpiece part from IN
location IN OUT
steps
  r1        | r2
  Pick part |
  Put r2    | Get r1
repeat 9
  Pick part | Place OUT
  Put r2    | Get r1
end
            | Place OUT
end
)";

TEST(ParseProgram, LoopInTheTableCoversItsLinesAndStepsKeepCounting) {
  const Program p = parse_program(kShift, "shift.task");
  const StepTable& t = *p.steps;
  ASSERT_EQ(t.lines.size(), 5u);
  // Step numbers count the table lines in source order; the repeat and end lines are not steps.
  for (std::size_t i = 0; i < t.lines.size(); ++i) EXPECT_EQ(t.lines[i].step, static_cast<int>(i) + 1);
  EXPECT_EQ(t.lines[2].where.line, 9);
  EXPECT_EQ(t.lines[4].where.line, 12);
  ASSERT_EQ(t.loops.size(), 1u);
  EXPECT_EQ(t.loops[0].where.line, 8);
  EXPECT_EQ(t.loops[0].where.column, 1);
  EXPECT_EQ(t.loops[0].count, 9u);
  EXPECT_EQ(t.loops[0].begin, 2u);  // "Pick part | Place OUT"
  EXPECT_EQ(t.loops[0].end, 4u);    // up to, not including, "| Place OUT"
}

TEST(ParseProgram, WorkpieceClassNamesTheLocationItsPartsArriveAt) {
  const Program p = parse_program(kShift, "shift.task");
  const Declaration* part = find_declaration(p, "part");
  ASSERT_NE(part, nullptr);
  EXPECT_EQ(part->kind, NameKind::kWorkpiece);
  EXPECT_EQ(part->from, "IN");
  EXPECT_EQ(part->where.line, 2);
  EXPECT_EQ(part->where.column, 11);
  EXPECT_EQ(part->from_where.line, 2);
  EXPECT_EQ(part->from_where.column, 21);
  // A class is used like a workpiece.
  EXPECT_EQ(p.steps->lines[0].cells[0]->argument_kind, NameKind::kWorkpiece);
  // Named workpieces have no `from`; the keyword is case-insensitive, and the location may come later in the file.
  const Program q = parse_program("workpiece A B\nWorkpiece box FROM belt\nlocation belt\nrobot r1\nsequence r1\nend\n", "t");
  EXPECT_TRUE(find_declaration(q, "A")->from.empty());
  EXPECT_TRUE(find_declaration(q, "B")->from.empty());
  EXPECT_EQ(find_declaration(q, "box")->from, "belt");
  EXPECT_EQ(declared_names(q, NameKind::kWorkpiece), (std::vector<std::string>{"A", "B", "box"}));
}

TEST(ParseProgram, LoopsInASequence) {
  const Program p = parse_program(
      "robot r1\nworkpiece part from IN\nlocation IN OUT\nsemaphore s\n"
      "sequence r1\n"
      "  wait s\n"
      "  REPEAT 3   # case-insensitive, like every keyword\n"
      "    Pick part\n"
      "    Place OUT\n"
      "  end\n"
      "  repeat 1\n"
      "    signal s\n"
      "  End\n"
      "end\n",
      "t.task");
  const Sequence& seq = p.sequences.at(0);
  ASSERT_EQ(seq.commands.size(), 4u);
  ASSERT_EQ(seq.loops.size(), 2u);
  EXPECT_EQ(seq.loops[0].where.line, 7);
  EXPECT_EQ(seq.loops[0].where.column, 3);
  EXPECT_EQ(seq.loops[0].count, 3u);
  EXPECT_EQ(seq.loops[0].begin, 1u);
  EXPECT_EQ(seq.loops[0].end, 3u);
  EXPECT_EQ(seq.loops[1].count, 1u);
  EXPECT_EQ(seq.loops[1].begin, 3u);
  EXPECT_EQ(seq.loops[1].end, 4u);
  // The largest count there is.
  const Program big = parse_program("robot r1\nsemaphore s\nsequence r1\nrepeat 4294967295\nsignal s\nend\nend\n", "t");
  EXPECT_EQ(big.sequences[0].loops[0].count, 4294967295u);
}

TEST(ParseErrors, LoopCounts) {
  const std::string head = "robot r1\nsemaphore s\nsequence r1\n";
  expect_failure(head + "repeat\nsignal s\nend\nend\n", 4, 1,
                 "'repeat' needs the number of iterations (a number 1 or more)");
  expect_failure(head + "repeat 0\nsignal s\nend\nend\n", 4, 8, "the number of iterations must be 1 or more, not 0");
  expect_failure(head + "repeat 000\nsignal s\nend\nend\n", 4, 8,
                 "the number of iterations must be 1 or more, not 000");
  expect_failure(head + "repeat -2\nsignal s\nend\nend\n", 4, 8,
                 "the number of iterations must be 1 or more, not -2");
  expect_failure(head + "repeat 4294967296\nsignal s\nend\nend\n", 4, 8,
                 "the number of iterations is too large: 4294967296 (at most 4294967295)");
  expect_failure(head + "repeat s\nsignal s\nend\nend\n", 4, 8,
                 "expected the number of iterations after 'repeat', found 's'");
  expect_failure(head + "repeat 3 4\nsignal s\nend\nend\n", 4, 10,
                 "unexpected '4' after 'repeat 3': the line that opens a loop holds nothing else (or 'with' and "
                 "the robots whose sequences loop together with this one)");
  expect_failure("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nrepeat 3 | signal s\n| wait s\nend\nend\n", 5, 10,
                 "unexpected '|' after 'repeat 3': the line that opens a loop holds nothing else (or 'with' and "
                 "the robots whose sequences loop together with this one)");
}

TEST(ParseProgram, LoopWithPartners) {
  const Program p = parse_program("robot r1 r2 r3\nsemaphore s\nsequence r1\nrepeat 5 with r2 r3\nsignal s\nend\n"
                                  "end\n",
                                  "t");
  const LoopBlock& loop = p.sequences[0].loops[0];
  EXPECT_EQ(loop.count, 5u);
  EXPECT_EQ(loop.partners, (std::vector<std::string>{"r2", "r3"}));
  ASSERT_EQ(loop.partner_where.size(), 2u);
  EXPECT_EQ(loop.partner_where[1].line, 4);
  EXPECT_EQ(loop.partner_where[1].column, 18);
  // Without 'with' a loop has no partners.
  EXPECT_TRUE(parse_program("robot r1\nsemaphore s\nsequence r1\nrepeat 5\nsignal s\nend\nend\n", "t")
                  .sequences[0]
                  .loops[0]
                  .partners.empty());
}

TEST(ParseErrors, LoopWithPartners) {
  const std::string head = "robot r1 r2\nsemaphore s\nsequence r1\n";
  expect_failure(head + "repeat 3 with\nsignal s\nend\nend\n", 4, 10,
                 "'repeat 3 with' needs the robots whose sequences loop together with this one");
  expect_failure(head + "repeat 3 with 4\nsignal s\nend\nend\n", 4, 15, "expected a robot name after 'with', found '4'");
  expect_failure(head + "repeat 3 with r2 r2\nsignal s\nend\nend\n", 4, 18, "robot 'r2' is named twice after 'with'");
  expect_failure("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nrepeat 3 with r2\nsignal s | wait s\nend\nend\n", 5, 10,
                 "'with' names the sequences a loop runs together with; a loop of the steps table already runs with "
                 "every robot of the table (write 'repeat 3')");
}

TEST(ParseErrors, LoopStructure) {
  // Loops do not nest: the message names the outer loop's line.
  expect_failure("robot r1\nsemaphore s\nsequence r1\nrepeat 2\nrepeat 3\nsignal s\nend\nend\nend\n", 5, 1,
                 "loops do not nest: the loop opened on line 4 is still open (close it with 'end' first)");
  // An empty body.
  expect_failure("robot r1\nsequence r1\n  repeat 2\n  end\nend\n", 4, 3,
                 "the loop opened on line 3 has an empty body: put the commands it repeats between 'repeat 2' and "
                 "'end'");
  expect_failure("robot r1\nsteps\nr1\nrepeat 5\nend\nend\n", 5, 1,
                 "the loop opened on line 4 has an empty body: put the step lines it repeats between 'repeat 5' and "
                 "'end'");
  // A missing loop end is reported at the repeat: at the end of the file, or when a top-level statement comes.
  expect_failure("robot r1\nsemaphore s\nsequence r1\n  repeat 2\n  signal s\n", 4, 3,
                 "the loop opened here has no matching 'end' before the end of the file");
  expect_failure("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nrepeat 2\nsignal s | wait s\nsequence r2\nend\n", 5, 1,
                 "the loop opened here has no matching 'end' before 'sequence' on line 7");
  expect_failure("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nrepeat 2\nsignal s | wait s\nend\nsequence r2\nend\n",
                 8, 1,
                 "'sequence' inside the steps block opened on line 3: is its 'end' missing? (the 'end' on line 7 "
                 "closed the loop opened on line 5)");
  // With one 'end' in the file, it closes the loop; the block's message says so.
  expect_failure("robot r1\nsemaphore s\nsequence r1\n  repeat 2\n  signal s\n  end\n", 3, 1,
                 "the sequence block opened here has no matching 'end' before the end of the file (the 'end' on line "
                 "6 closed the loop opened on line 4)");
  // repeat stands on a line of its own, inside a block, after the header.
  expect_failure("robot r1\nrepeat 2\n", 2, 1, "'repeat' must stand inside a steps or sequence block");
  expect_failure("robot r1\nsteps\nrepeat 2\nend\n", 3, 1,
                 "the first line of a steps block is its header naming the robot columns (like 'r1 | r2'), found "
                 "'repeat': a loop opens after the header");
  expect_failure("robot r1 r2\nsemaphore s\nsteps\nr1 | r2\nsignal s | repeat 2\nend\n", 5, 12,
                 "'repeat' opens a loop on a line of its own ('repeat N'), not in a table cell");
}

TEST(ParseErrors, WorkpieceClasses) {
  expect_failure("location IN\nworkpiece from IN\n", 2, 11,
                 "'workpiece from' needs the class name before 'from': 'workpiece NAME from LOCATION'");
  expect_failure("location IN\nworkpiece a b from IN\n", 2, 13,
                 "a workpiece class is declared alone ('workpiece NAME from LOCATION'), but 2 names stand before "
                 "'from'; declare each class on a line of its own");
  expect_failure("location IN\nworkpiece a from\n", 2, 13,
                 "'from' after workpiece class 'a' needs the location its parts arrive at");
  expect_failure("location IN\nworkpiece a from 3\n", 2, 18, "expected a location name after 'from', found '3'");
  expect_failure("location IN X\nworkpiece a from IN X\n", 2, 21,
                 "unexpected 'X' after 'workpiece a from IN': a class takes its parts from one location");
  expect_failure("location IN\nworkpiece steps from IN\n", 2, 11, "'steps' is a keyword and cannot be used as a name");
  expect_failure("location IN\nworkpiece a from IN\nworkpiece a\n", 3, 11,
                 "'a' is already declared as a workpiece on line 2");
  // The location is resolved after the whole file: unknown, or not a location.
  expect_failure("workpiece a from IN\n", 1, 18, "unknown location 'IN'");
  expect_failure("robot r1\nworkpiece a from r1\n", 2, 18,
                 "workpiece class 'a' takes its parts from a location, but 'r1' is a robot (declared on line 1)");
  // Errors come in source order: the class on line 1 before the sequence on line 2.
  expect_failure("workpiece a from IN\nsequence r9\nend\n", 1, 18, "unknown location 'IN'");
  expect_failure("sequence r9\nend\nworkpiece a from IN\n", 1, 10, "unknown robot 'r9'");
  expect_failure("from IN\n", 1, 1, "'from' stands in a workpiece class declaration: 'workpiece NAME from LOCATION'");
}

TEST(ParseErrors, RepeatAndFromAreKeywords) {
  expect_failure("robot r1 repeat\n", 1, 10, "'repeat' is a keyword and cannot be used as a name");
  expect_failure("location FROM\n", 1, 10, "'FROM' is a keyword and cannot be used as a name");
  expect_failure("robot r1\nsteps\nr1 | repeat\nend\n", 3, 6, "'repeat' is a keyword and cannot be used as a name");
}

// ---- errors ------------------------------------------------------------------------------------------------------

TEST(ParseErrors, UnknownNamesSayWhichKindWasExpected) {
  expect_failure("robot r1\nsteps\nr1 | r3\nend\n", 3, 6, "unknown robot 'r3'");
  expect_failure("robot r1\nsequence r9\nend\n", 2, 10, "unknown robot 'r9'");
  expect_failure("robot r1\nsequence r1\n  Pick X\nend\n", 3, 8, "unknown workpiece 'X'");
  expect_failure("robot r1\nsequence r1\n  Put r2\nend\n", 3, 7, "unknown robot 'r2'");
  expect_failure("robot r1\nsequence r1\n  Place Q\nend\n", 3, 9, "unknown workpiece or location 'Q'");
  expect_failure("robot r1\nsequence r1\n  wait s\nend\n", 3, 8, "unknown semaphore 's'");
  expect_failure("robot r1\nsequence r1\n  signal s\nend\n", 3, 10, "unknown semaphore 's'");
  expect_failure("robot r1\nsequence r1\n  enter Z\nend\n", 3, 9, "unknown region 'Z'");
  expect_failure("robot r1\nsequence r1\n  leave Z\nend\n", 3, 9, "unknown region 'Z'");
}

TEST(ParseErrors, NamesOfTheWrongKind) {
  expect_failure("robot r1\nlocation B\nsequence r1\nPick B\nend\n", 4, 6,
                 "Pick expects a workpiece, but 'B' is a location (declared on line 2)");
  expect_failure("robot r1\nworkpiece A\nsteps\nA\nend\n", 4, 1,
                 "expected a robot, but 'A' is a workpiece (declared on line 2)");
  expect_failure("robot r1\nregion Z\nsequence r1\nwait Z\nend\n", 4, 6,
                 "wait expects a semaphore, but 'Z' is a region (declared on line 2); use enter/leave for regions");
  expect_failure("robot r1\nsemaphore s\nsequence r1\nenter s\nend\n", 4, 7,
                 "enter expects a region, but 's' is a semaphore (declared on line 2); use signal/wait for semaphores");
  expect_failure("robot r1\nsemaphore s\nsequence r1\nPlace s\nend\n", 4, 7,
                 "Place expects a workpiece or location, but 's' is a semaphore (declared on line 2)");
  expect_failure("robot r1\nworkpiece A\nsequence r1\nGet A\nend\n", 4, 5,
                 "Get expects a robot, but 'A' is a workpiece (declared on line 2)");
}

TEST(ParseErrors, DuplicateDeclarations) {
  expect_failure("robot r1 r2 r1\n", 1, 13, "'r1' is already declared as a robot on line 1");
  expect_failure("workpiece A\nlocation B A\n", 2, 12, "'A' is already declared as a workpiece on line 1");
  expect_failure("robot r1\nsemaphore s\nregion s\n", 3, 8, "'s' is already declared as a semaphore on line 2");
}

TEST(ParseErrors, KeywordsAreNotNames) {
  expect_failure("robot r1 pick\n", 1, 10, "'pick' is a keyword and cannot be used as a name");
  expect_failure("workpiece End\n", 1, 11, "'End' is a keyword and cannot be used as a name");
}

TEST(ParseErrors, TwoCommandsForOneRobotOnALine) {
  expect_failure("robot r1 r2\nworkpiece A\nlocation B\nsteps\nr1 | r2\nPick A Place B | \nend\n", 6, 8,
                 "two commands for robot 'r1' on line 6 ('Pick A' and 'Place'): the steps table allows one command "
                 "per robot on a line");
  expect_failure("robot r1\nworkpiece A\nlocation B\nsequence r1\n  Pick A place B\nend\n", 5, 10,
                 "two commands for robot 'r1' on line 5 ('Pick A' and 'place'): the sequence allows one command per "
                 "robot on a line");
  expect_failure("robot r1 r2\nsteps\nr1 | r2 | r1\nend\n", 3, 11,
                 "robot 'r1' is named twice in the steps header (columns 1 and 3): it would get two commands on one "
                 "line");
}

TEST(ParseErrors, TooManyCells) {
  expect_failure("robot r1 r2\nworkpiece A\nsteps\nr1 | r2\nPick A | | Pick A\nend\n", 5, 10,
                 "this line has 3 cells but the steps header (line 4) names 2 robots");
  expect_failure("robot r1\nworkpiece A\nsteps\nr1\nPick A |\nend\n", 5, 8,
                 "this line has 2 cells but the steps header (line 4) names 1 robot");
}

TEST(ParseErrors, MissingEnd) {
  expect_failure("robot r1\nworkpiece A\nsteps\nr1\nPick A\n", 3, 1,
                 "the steps block opened here has no matching 'end' before the end of the file");
  expect_failure("robot r1\nsequence r1\n", 2, 1,
                 "the sequence block opened here has no matching 'end' before the end of the file");
  expect_failure("robot r1 r2\nworkpiece A\nsequence r1\nPick A\nsequence r2\nend\n", 5, 1,
                 "'sequence' inside the sequence block opened on line 3: is its 'end' missing?");
  expect_failure("robot r1\nsteps\nr1\nworkpiece A\nend\n", 4, 1,
                 "'workpiece' inside the steps block opened on line 2: is its 'end' missing?");
}

TEST(ParseErrors, StatementsOutOfPlace) {
  expect_failure("robot r1\nend\n", 2, 1, "'end' without an open steps or sequence block");
  expect_failure("robot r1\nworkpiece A\n  Pick A\n", 3, 3, "'Pick' must stand inside a steps or sequence block");
  expect_failure("robots r1\n", 1, 1,
                 "unknown statement 'robots' (expected robot, workpiece, location, semaphore, region, machine, "
                 "conveyor, sensor, steps, sequence or coordinated)");
  expect_failure("| r1\n", 1, 1,
                 "expected a statement (robot, workpiece, location, semaphore, region, machine, conveyor, sensor, "
                 "steps, sequence or coordinated), found '|'");
  expect_failure("robot r1\nsteps\nr1\nend\nsteps\nr1\nend\n", 5, 1,
                 "only one steps block is allowed; the first is on line 2");
  expect_failure("robot r1\nsteps now\n", 2, 7, "unexpected 'now' after 'steps'");
  expect_failure("robot r1\nsequence r1\nend here\n", 3, 5, "unexpected 'here' after 'end'");
  expect_failure("robot\n", 1, 1, "'robot' needs at least one name");
  expect_failure("semaphore\n", 1, 1, "'semaphore' needs at least one name");
  expect_failure("robot r1 | r2\n", 1, 10, "expected a robot name, found '|'");
}

TEST(ParseErrors, UnknownCommand) {
  expect_failure("robot r1\nworkpiece A\nsequence r1\n  Pik A\nend\n", 4, 3,
                 "unknown command 'Pik' (expected Pick, Put, Get, Place, signal, wait, enter, leave, start, run, stop, accumulate, home, park or "
                 "coordinate)");
  expect_failure("robot r1 r2\nsteps\nr1 | r2\n | 7\nend\n", 4, 4,
                 "expected a command (Pick, Put, Get, Place, signal, wait, enter, leave, start, run, stop, accumulate, "
                 "home, park or coordinate), found '7'");
}

TEST(ParseErrors, MissingOrExtraArguments) {
  expect_failure("robot r1\nsequence r1\n  Pick\nend\n", 3, 3, "Pick needs an argument: a workpiece name");
  expect_failure("robot r1 r2\nsteps\nr1 | r2\nPut | \nend\n", 4, 1, "Put needs an argument: a robot name");
  expect_failure("robot r1\nsequence r1\n  Place\nend\n", 3, 3,
                 "Place needs an argument: a workpiece or location name");
  expect_failure("robot r1\nsequence r1\n  wait =\nend\n", 3, 8, "wait needs a semaphore name, found '='");
  expect_failure("robot r1\nworkpiece A B\nsequence r1\n  Pick A B\nend\n", 4, 10,
                 "extra argument 'B' after 'Pick A': Pick takes one argument (or 'Pick W from MACHINE')");
  expect_failure("robot r1\nsequence\n", 2, 1, "'sequence' needs the name of the robot it programs");
  expect_failure("robot r1 r2\nsequence r1 r2\nend\n", 2, 13,
                 "unexpected 'r2' after 'sequence r1': a sequence programs one robot");
  expect_failure("robot r1\nsequence 1\nend\n", 2, 10, "expected a robot name, found '1'");
}

TEST(ParseErrors, HeaderProblems) {
  expect_failure("robot r1\nsteps\nend\n", 3, 1, "the steps block has no header line naming its robot columns");
  expect_failure("robot r1 r2\nsteps\nr1 | | r2\nend\n", 3, 6,
                 "column 2 of the steps header is empty: the header names one robot per column");
  expect_failure("robot r1 r2\nsteps\nr1 |\nend\n", 3, 4,
                 "column 2 of the steps header is empty: the header names one robot per column");
  expect_failure("robot r1 r2\nsteps\nr1 r2\nend\n", 3, 4,
                 "unexpected 'r2' after robot 'r1': separate the header's robot columns with '|'");
  expect_failure("robot r1\nworkpiece A\nsteps\nPick A\nend\n", 4, 1,
                 "the first line of a steps block is its header naming the robot columns (like 'r1 | r2'), found "
                 "the command 'Pick'");
}

TEST(ParseErrors, RobotInTableAndSequenceOrInTwoSequences) {
  expect_failure("robot r1 r2\nsteps\nr1 | r2\nend\nsequence r2\nend\n", 5, 10,
                 "robot 'r2' has a column in the steps table (line 2); a robot is programmed either in the steps "
                 "table or in one sequence, not both");
  expect_failure("robot r1\nsequence r1\nend\nsequence r1\nend\n", 4, 10,
                 "robot 'r1' already has a sequence (line 2); a robot has one sequence at most");
  expect_failure("robot r1\nsemaphore s\nsequence r1\n  signal s | wait s\nend\n", 4, 12,
                 "'|' separates the columns of the steps table; a sequence has one command per line");
}

TEST(ParseErrors, LexicalProblems) {
  expect_failure("robot r1 r$\n", 1, 11, "unexpected character '$'");
  expect_failure("robot r1\n\x01", 2, 1, "unexpected byte 0x01");
  expect_failure(std::string("robot r\xc3\xa9\n"), 1, 8, "unexpected byte 0xc3");
  expect_failure(std::string("robot r1\0", 9), 1, 9, "unexpected byte 0x00");
  expect_failure("robot 2a\n", 1, 7,
                 "'2a' is not a valid name or number: names start with a letter or '_', numbers have only digits");
  expect_failure("robot 1\n", 1, 7, "expected a robot name, found '1'");
  expect_failure("semaphore s = -1\n", 1, 15, "the initial count of semaphore 's' must be 0 or more, not -1");
  expect_failure("semaphore s = 4294967296\n", 1, 15,
                 "the initial count of semaphore 's' is too large: 4294967296 (at most 4294967295)");
  expect_failure("semaphore s =\n", 1, 13, "'=' after semaphore 's' needs its initial count (a number 0 or more)");
  expect_failure("semaphore s = t\n", 1, 15, "'=' after semaphore 's' needs its initial count (a number 0 or more)");
  EXPECT_EQ(parse_program("semaphore s = 4294967295\nrobot r1\nsequence r1\nend\n", "t").declarations[0].initial,
            4294967295u);
}

TEST(LoadProgram, ReadsAFileAndNamesItInErrors) {
  const auto dir = std::filesystem::temp_directory_path() / "cellwright_program_test";
  std::filesystem::create_directories(dir);
  const auto good = dir / "good.task";
  std::ofstream(good) << kExchange;
  const Program p = load_program(good);
  EXPECT_EQ(p.file, good.string());
  EXPECT_EQ(p.steps->lines.size(), 3u);
  EXPECT_EQ(p.steps->lines[0].where.file, good.string());

  const auto bad = dir / "bad.task";
  std::ofstream(bad) << "robot r1\nsequence r1\n  Pick Z\nend\n";
  try {
    load_program(bad);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), bad.string() + ":3:8: error: unknown workpiece 'Z'");
  }
  std::filesystem::remove_all(dir);
}

TEST(LoadProgram, MissingFileAndDirectory) {
  const auto missing = std::filesystem::temp_directory_path() / "cellwright_no_such_dir" / "none.task";
  try {
    load_program(missing);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, missing.string());
    EXPECT_EQ(e.problem(), "cannot read the program: no such file");
  }
  try {
    load_program(std::filesystem::temp_directory_path());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.problem(), "cannot read the program: is a directory, not a file");
  }
}

}  // namespace
}  // namespace cellwright::task
