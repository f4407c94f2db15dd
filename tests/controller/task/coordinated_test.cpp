// Coordinated blocks (issue 27, "two arms carry one beam"): parsing and its errors, the compiled segments with their
// barrier pairs, the listing and JSON, and the Petri net check that refuses a block only one robot reaches.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/firing.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"
#include "controller/task/task_test_helpers.hpp"

namespace cellwright::task {
namespace {

const std::filesystem::path kScenes = std::filesystem::path(CW_SOURCE_DIR) / "scenes";

// Declarations and the block; the robots' programs are appended by each test.
const std::string kHead =
    "robot left right other\n"    // 1
    "workpiece beam A\n"          // 2
    "location FIX MID\n"          // 3
    "semaphore s\n"               // 4
    "coordinated carry master left follower right\n"  // 5
    "  Pick beam\n"               // 6
    "  via MID\n"                 // 7
    "  Place FIX\n"               // 8
    "end\n";                      // 9

using test::compile_text;
using test::Failure;
using test::program_of;

// The InputError that parsing (and then compiling) `text` throws.
Failure failure(const std::string& text) {
  try {
    compile(parse_program(text, "t.task"));
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "t.task");
    return {e.where().line, e.where().column, e.problem()};
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return {};
}

void expect_failure(const std::string& text, int line, int column, const std::string& start) {
  const Failure f = failure(text);
  EXPECT_EQ(f.line, line) << f.problem;
  EXPECT_EQ(f.column, column) << f.problem;
  EXPECT_EQ(f.problem.rfind(start, 0), 0u) << "got: " << f.problem << "\nexpected it to start with: " << start;
}

petri::AnalysisResult check(const std::string& text) {
  return petri::analyze(to_net(compile_text(text)));
}

TEST(Coordinated, ParsesTheBlockWithItsRobotsAndBody) {
  const Program p = parse_program(kHead + "sequence left\n  coordinate carry\nend\nsequence right\n  coordinate carry\n"
                                          "end\n",
                                  "t.task");
  ASSERT_EQ(p.blocks.size(), 1u);
  const CoordinatedBlock& b = p.blocks.front();
  EXPECT_EQ(b.name, "carry");
  EXPECT_EQ(b.where.line, 5);
  EXPECT_EQ(b.where.column, 13);
  EXPECT_EQ(b.master, "left");
  EXPECT_EQ(b.follower, "right");
  ASSERT_EQ(b.body.size(), 3u);
  EXPECT_EQ(b.body[0].kind, CommandKind::kPick);
  EXPECT_EQ(b.body[1].kind, CommandKind::kVia);
  EXPECT_EQ(b.body[1].argument, "MID");
  EXPECT_EQ(b.body[2].kind, CommandKind::kPlace);
  EXPECT_EQ(b.end_where.line, 9);
  ASSERT_NE(find_declaration(p, "carry"), nullptr);
  EXPECT_EQ(find_declaration(p, "carry")->kind, NameKind::kBlock);
  EXPECT_EQ(p.sequences[0].commands[0].kind, CommandKind::kCoordinate);
  EXPECT_EQ(p.sequences[0].commands[0].argument_kind, NameKind::kBlock);
  // Not reserved: the words are recognised by position, so older programs may still use them as names.
  EXPECT_NO_THROW(parse_program("robot coordinated via master\nsequence via\n  home\nend\n", "t.task"));
}

TEST(Coordinated, EverySegmentIsBetweenBarrierPairsOnBothRobots) {
  const CompiledProgram c = compile_text(kHead + "sequence left\n  coordinate carry\n  home\nend\n"
                                                 "sequence right\n  coordinate carry\nend\n");
  ASSERT_EQ(c.coordinated.size(), 1u);
  const CoordinatedUse& use = c.coordinated.front();
  const std::vector<std::string> segments{"open for beam", "approach beam", "grasp beam",  "grasp beam",
                                          "lift up beam",  "carry beam via MID", "approach FIX", "put down beam",
                                          "release beam",  "depart FIX"};
  EXPECT_EQ(use.segments, segments);
  EXPECT_EQ(use.workpiece, "beam");
  const int n = static_cast<int>(segments.size());
  for (const std::string& robot : {std::string("left"), std::string("right")}) {
    const std::string partner = robot == "left" ? "right" : "left";
    const RobotProgram& prog = program_of(c, robot);
    // Per segment: signal, wait, the segment; then the last barrier.
    ASSERT_GE(prog.primitives.size(), static_cast<std::size_t>(3 * n + 2)) << robot;
    for (int k = 1; k <= n + 1; ++k) {
      const Primitive& sig = prog.primitives[static_cast<std::size_t>(3 * (k - 1))];
      const Primitive& wait = prog.primitives[static_cast<std::size_t>(3 * (k - 1) + 1)];
      EXPECT_EQ(sig.kind, PrimitiveKind::kSignal);
      EXPECT_EQ(sig.event, segment_event("carry", k, n, robot, partner));
      EXPECT_EQ(wait.kind, PrimitiveKind::kWait);
      EXPECT_EQ(wait.event, segment_event("carry", k, n, partner, robot));
      EXPECT_FALSE(sig.segment.has_value());
      EXPECT_EQ(sig.task, "coordinate carry");
      if (k > n) break;
      const Primitive& seg = prog.primitives[static_cast<std::size_t>(3 * (k - 1) + 2)];
      ASSERT_TRUE(seg.segment.has_value()) << robot << " segment " << k;
      EXPECT_EQ(seg.segment->index, k);
      EXPECT_EQ(seg.segment->count, n);
      EXPECT_EQ(seg.segment->master, "left");
      EXPECT_EQ(seg.segment->follower, "right");
      EXPECT_EQ(seg.motion, segments[static_cast<std::size_t>(k - 1)]);
    }
    ASSERT_EQ(use.runs.size(), 2u);
  }
  // Both robots carry the master's symbolic targets (the follower's follow from them at run time).
  const auto& l = program_of(c, "left").primitives;
  const auto& r = program_of(c, "right").primitives;
  for (std::size_t i = 0; i < static_cast<std::size_t>(3 * n + 2); ++i) {
    EXPECT_EQ(l[i].kind, r[i].kind) << i;
    if (l[i].kind == PrimitiveKind::kMove) {
      EXPECT_EQ(to_string(l[i].target), to_string(r[i].target)) << i;
    }
  }
  EXPECT_EQ(to_string(l[5]), "move above(beam) [carry 2/10: right follows left]");
  EXPECT_EQ(to_string(l[11]), "close beam [carry 4/10: right follows left]");
  EXPECT_EQ(use.runs[0].robot, "left");
  EXPECT_EQ(use.runs[0].begin, 0u);
  EXPECT_EQ(use.runs[0].end, static_cast<std::size_t>(3 * n + 2));
  EXPECT_EQ(program_of(c, "left").primitives.back().task, "home");
  // The block's events, once each, marked inserted.
  std::size_t events = 0;
  for (const Semaphore& s : c.semaphores) {
    if (s.name.rfind("carry.", 0) == 0) {
      ++events;
      EXPECT_TRUE(s.inserted);
      EXPECT_EQ(s.declared.line, 5);
    }
  }
  EXPECT_EQ(events, static_cast<std::size_t>(2 * (n + 1)));
}

TEST(Coordinated, ListingAndJsonShowTheBlock) {
  const CompiledProgram c = compile_text(kHead + "sequence left\n  coordinate carry\nend\n"
                                                 "sequence right\n  coordinate carry\nend\n");
  const std::string listing = format_listing(c);
  EXPECT_NE(listing.find("coordinated blocks"), std::string::npos) << listing;
  EXPECT_NE(listing.find("carry (5:13): master left, follower right, carrying beam, 10 segments: left [0, 32) line "
                         "11, right [0, 32) line 14"),
            std::string::npos)
      << listing;
  EXPECT_NE(listing.find(" 6. carry beam via MID"), std::string::npos) << listing;
  EXPECT_NE(listing.find("signal carry.s1.left>right"), std::string::npos) << listing;
  EXPECT_NE(listing.find("wait carry.end.left>right"), std::string::npos) << listing;

  const nlohmann::json j = to_json(c);
  ASSERT_TRUE(j.contains("coordinated"));
  const auto& b = j["coordinated"][0];
  EXPECT_EQ(b["name"], "carry");
  EXPECT_EQ(b["master"], "left");
  EXPECT_EQ(b["follower"], "right");
  EXPECT_EQ(b["workpiece"], "beam");
  EXPECT_EQ(b["segments"].size(), 10u);
  EXPECT_EQ(b["runs"][1]["robot"], "right");
  EXPECT_EQ(b["runs"][1]["where"]["line"], 14);
  const auto& p2 = j["programs"][1]["primitives"][2];
  EXPECT_EQ(p2["segment"]["block"], "carry");
  EXPECT_EQ(p2["segment"]["index"], 1);
  EXPECT_EQ(p2["kind"], "open");
  // A program without blocks has no key (its JSON is as before).
  EXPECT_FALSE(to_json(compile_text("robot r1\nsequence r1\n  home\nend\n")).contains("coordinated"));
}

TEST(Coordinated, TheCheckPassesWhenBothRobotsRunTheBlock) {
  // In sequences, with other work around it.
  const auto seq = check(kHead + "sequence left\n  signal s\n  coordinate carry\n  home\nend\n"
                                 "sequence right\n  wait s\n  coordinate carry\n  park\nend\n");
  EXPECT_TRUE(seq.complete);
  EXPECT_EQ(seq.deadlocks, 0u);
  EXPECT_TRUE(seq.ok());
  // In the steps table on one line, and in a loop both robots run.
  const auto table = check(kHead + "steps\nleft | right | other\n| | Pick A\n"
                                   "| coordinate carry | Place MID\ncoordinate carry\nend\n");
  EXPECT_FALSE(table.ok());  // left runs the block a line after right: both wait for each other
  const auto same_line = check(kHead + "steps\nleft | right | other\n| | Pick A\n"
                                       "coordinate carry | coordinate carry | Place MID\nend\n");
  EXPECT_TRUE(same_line.complete);
  EXPECT_TRUE(same_line.ok()) << same_line.deadlocks;
  const auto looped = check(kHead + "steps\nleft | right\nrepeat 5\ncoordinate carry | coordinate carry\nend\nend\n");
  EXPECT_TRUE(looped.ok());
}

// The case: a block only one robot reaches is refused before the run, with the firing sequence.
TEST(Coordinated, ABlockOnlyOneRobotReachesIsADeadlockWithACounterexample) {
  const std::vector<std::string> programs{
      // right never runs it
      "sequence left\n  coordinate carry\nend\nsequence right\n  home\nend\n",
      // right runs it only after a signal that left gives after the block
      "sequence left\n  coordinate carry\n  signal s\nend\nsequence right\n  wait s\n  coordinate carry\nend\n",
      // left repeats it, right runs it once
      "sequence left\n  repeat 2\n  coordinate carry\n  end\nend\nsequence right\n  coordinate carry\nend\n",
  };
  for (const std::string& tail : programs) {
    const petri::Net net = to_net(compile_text(kHead + tail));
    const auto r = petri::analyze(net);
    EXPECT_TRUE(r.complete) << tail;
    EXPECT_GE(r.deadlocks, 1u) << tail;
    EXPECT_FALSE(r.ok()) << tail;
    ASSERT_FALSE(r.deadlock_examples.empty()) << tail;
    // Replaying the counterexample reaches a dead marking in which a robot waits at a barrier of the block.
    petri::Marking m = net.initial_marking();
    for (auto t : r.deadlock_examples.front().path) petri::fire_in_place(net, m, t);
    EXPECT_TRUE(petri::enabled(net, m).empty()) << tail;
    EXPECT_FALSE(net.is_final(m)) << tail;
    const std::string stuck = petri::describe_marking(net, m);
    EXPECT_NE(stuck.find("carry."), std::string::npos) << stuck;
    EXPECT_NE(petri::format_report(net, r).find("coordinate carry"), std::string::npos) << petri::format_report(net, r);
  }
}

TEST(Coordinated, MalformedBlocksAreRefusedWithFileLineAndColumn) {
  const std::string robots = "robot a b c\nworkpiece W\nworkpiece part from IN\nlocation IN X\nmachine mill\n";
  const std::string runs = "sequence a\n  coordinate k\nend\nsequence b\n  coordinate k\nend\n";
  // The header.
  expect_failure(robots + "coordinated\n", 6, 1, "'coordinated' needs a name and its two robots");
  expect_failure(robots + "coordinated k a b\n", 6, 15, "coordinated block 'k' needs its master robot");
  expect_failure(robots + "coordinated k master a\n", 6, 22, "coordinated block 'k' needs its follower robot");
  expect_failure(robots + "coordinated k master a follower\n", 6, 24, "'follower' in coordinated block 'k' needs a "
                                                                       "robot name");
  expect_failure(robots + "coordinated k master a follower b c\n", 6, 35, "unexpected 'c' after the follower robot");
  expect_failure(robots + "coordinated end master a follower b\n", 6, 13, "'end' is a keyword");
  expect_failure(robots + "coordinated W master a follower b\nPick W\nPlace X\nend\n" + runs, 6, 13,
                 "'W' is already declared as a workpiece on line 2");
  expect_failure(robots + "coordinated k master a follower a\nPick W\nPlace X\nend\n" + runs, 6, 33,
                 "coordinated block 'k' needs two robots, but its master and follower are both 'a'");
  expect_failure(robots + "coordinated k master a follower zz\nPick W\nPlace X\nend\n" + runs, 6, 33,
                 "unknown robot 'zz'");
  expect_failure(robots + "coordinated k master X follower b\nPick W\nPlace X\nend\n" + runs, 6, 22,
                 "expected a robot, but 'X' is a location");
  // The body.
  expect_failure(robots + "coordinated k master a follower b\nend\n" + runs, 7, 1,
                 "coordinated block 'k' (line 6) ends with an empty body");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nend\n" + runs, 8, 1,
                 "coordinated block 'k' (line 6) ends without a Place");
  expect_failure(robots + "coordinated k master a follower b\nPlace X\nend\n" + runs, 7, 1,
                 "Place before the block's Pick");
  expect_failure(robots + "coordinated k master a follower b\nvia X\nPick W\nPlace X\nend\n" + runs, 7, 1,
                 "via before the block's Pick");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nPick W\nPlace X\nend\n" + runs, 8, 1,
                 "a second Pick");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nPlace X\nvia X\nend\n" + runs, 9, 1,
                 "via after the block's Place");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nsignal s\nPlace X\nend\n" + runs, 8, 1,
                 "'signal s' is not allowed in a coordinated block");
  expect_failure(robots + "coordinated k master a follower b\nPick W from mill\nPlace X\nend\n" + runs, 7, 8,
                 "'Pick ... from MACHINE' is not allowed in a coordinated block");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nvia\nPlace X\nend\n" + runs, 8, 1,
                 "via needs an argument: a location name");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nvia X X\nPlace X\nend\n" + runs, 8, 7,
                 "extra argument 'X' after 'via X'");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nvia W\nPlace X\nend\n" + runs, 8, 5,
                 "via expects a location, but 'W' is a workpiece");
  expect_failure(robots + "coordinated k master a follower b\nPick part\nPlace X\nend\n" + runs, 7, 6,
                 "coordinated block 'k' carries one named workpiece, but 'part' is a workpiece class");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nPlace mill\nend\n" + runs, 8, 7,
                 "coordinated block 'k' cannot place into machine 'mill'");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nPlace W\nend\n" + runs, 8, 7,
                 "coordinated block 'k' cannot place W on itself");
  expect_failure(robots + "coordinated k master a follower b\nrepeat 2\n", 7, 1,
                 "a coordinated block has no loops");
  expect_failure(robots + "coordinated k master a follower b\nPick W | Place X\n", 7, 8, "'|' separates the columns");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nPlace X\n", 6, 1,
                 "the coordinated block opened here has no matching 'end'");
  expect_failure(robots + "coordinated k master a follower b\nPick W\nsequence a\n", 8, 1,
                 "'sequence' inside the coordinated block opened on line 6: is its 'end' missing?");
  expect_failure(robots + "via X\n", 6, 1, "'via' stands in the body of a coordinated block");
  expect_failure(robots + "sequence a\n  via X\nend\n", 7, 3, "unknown command 'via'");
  // Running it.
  const std::string block = robots + "coordinated k master a follower b\nPick W\nPlace X\nend\n";  // lines 6-9
  expect_failure(block + "sequence a\n  coordinate zz\nend\n", 11, 14, "unknown coordinated block 'zz'");
  expect_failure(block + "sequence a\n  coordinate X\nend\n", 11, 14,
                 "coordinate expects a coordinated block, but 'X' is a location");
  expect_failure(block + "sequence a\n  coordinate\nend\n", 11, 3, "coordinate needs an argument");
  expect_failure(block + "sequence c\n  coordinate k\nend\n", 11, 14,
                 "c cannot run coordinated block k: its robots are a (master) and b (follower)");
  expect_failure(block + "sequence a\n  coordinate k\n  coordinate k\nend\n", 12, 3,
                 "a already runs coordinated block k on line 11");
  expect_failure(block + "sequence a\n  Pick W\n  coordinate k\nend\n", 12, 3,
                 "a cannot run coordinated block k: it is holding W (since line 11)");
  expect_failure(block + "steps\nc | a\nPick W |\n| coordinate k\nend\n", 13, 3,
                 "a cannot run coordinated block k: robot c is holding W (since line 12)");
  expect_failure(block + "coordinate k\n", 10, 1, "'coordinate' must stand inside a steps or sequence block");
}

TEST(Coordinated, AfterTheBlockNeitherRobotHoldsTheWorkpiece) {
  // Placing after the block: nothing held.
  const Failure f = failure(kHead + "sequence left\n  coordinate carry\n  Place FIX\nend\nsequence right\n"
                                    "  coordinate carry\nend\n");
  EXPECT_EQ(f.line, 12);
  EXPECT_EQ(f.problem, "left cannot place on FIX: it is holding nothing");
  // Picking it again after the block is fine.
  EXPECT_NO_THROW(compile_text(kHead + "sequence left\n  coordinate carry\n  Pick beam\n  Place MID\nend\n"
                                       "sequence right\n  coordinate carry\nend\n"));
}

TEST(Coordinated, TheShippedBeamProgramPassesTheCheck) {
  const CompiledProgram c = compile_file(kScenes / "beam.task");
  ASSERT_EQ(c.coordinated.size(), 1u);
  EXPECT_EQ(c.coordinated.front().runs.size(), 2u);
  const auto r = petri::analyze(to_net(c));
  EXPECT_TRUE(r.complete);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.final_states, 1u);
}

}  // namespace
}  // namespace cellwright::task
