// Compilation of task-level programs to primitives: the expansions, the inserted synchronisation, workpiece and
// region tracking, every semantic error, the listing and JSON forms, the example programs in scenes/, and a seeded
// "garbage in" run that feeds mutated programs and accepts only success or InputError.
#include "cellwright/task/compile.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace cellwright::task {
namespace {

const std::filesystem::path kScenes = std::filesystem::path(CW_SOURCE_DIR) / "scenes";

CompiledProgram compile_text(const std::string& text) {
  return compile(parse_program(text, "t.task"));
}

std::vector<std::string> texts(const RobotProgram& prog) {
  std::vector<std::string> out;
  for (const Primitive& p : prog.primitives) out.push_back(to_string(p));
  return out;
}

const RobotProgram& program_of(const CompiledProgram& c, const std::string& robot) {
  for (const RobotProgram& p : c.programs) {
    if (p.robot == robot) return p;
  }
  throw std::runtime_error("no program for " + robot);
}

struct Failure {
  int line = 0;
  int column = 0;
  std::string problem;
};

Failure compile_failure(const std::string& text) {
  const Program program = parse_program(text, "t.task");  // must parse: these are semantic errors
  try {
    compile(program);
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "t.task");
    return {e.where().line, e.where().column, e.problem()};
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return {};
}

void expect_failure(const std::string& text, int line, int column, const std::string& problem) {
  const Failure f = compile_failure(text);
  EXPECT_EQ(f.line, line) << f.problem;
  EXPECT_EQ(f.column, column) << f.problem;
  EXPECT_EQ(f.problem, problem);
}

// Properties every compiled program has, whatever the source.
void expect_well_formed(const CompiledProgram& c) {
  ASSERT_EQ(c.programs.size(), c.robots.size());
  std::set<std::string> events;
  for (const Semaphore& s : c.semaphores) {
    EXPECT_TRUE(events.insert(s.name).second) << "semaphore twice: " << s.name;
  }
  for (std::size_t r = 0; r < c.robots.size(); ++r) {
    EXPECT_EQ(c.programs[r].robot, c.robots[r]);
    for (const Primitive& p : c.programs[r].primitives) {
      if (p.kind == PrimitiveKind::kSignal || p.kind == PrimitiveKind::kWait) {
        EXPECT_TRUE(events.count(p.event)) << "undeclared event " << p.event;
      }
      if (p.kind == PrimitiveKind::kClose) {
        EXPECT_FALSE(p.workpiece.empty());
      }
      EXPECT_GT(p.where.line, 0);
      EXPECT_FALSE(p.task.empty());
      EXPECT_FALSE(p.motion.empty());
    }
  }
  for (const RegionUse& region : c.regions) {
    for (const RegionSpan& s : region.spans) {
      const RobotProgram& prog = program_of(c, s.robot);
      ASSERT_GE(s.begin, 1u);
      ASSERT_LE(s.begin, s.end);
      ASSERT_LT(s.end, prog.primitives.size());
      EXPECT_EQ(to_string(prog.primitives[s.begin - 1]), "wait " + region.name);
      EXPECT_EQ(to_string(prog.primitives[s.end]), "signal " + region.name);
    }
  }
}

// ---- the paper's Table 1 -----------------------------------------------------------------------------------------

TEST(Compile, Table1ExchangeExpandsAsSpecified) {
  const CompiledProgram c = compile_file(kScenes / "exchange.task");
  expect_well_formed(c);
  EXPECT_EQ(c.robots, (std::vector<std::string>{"r1", "r2"}));
  EXPECT_EQ(c.workpieces, (std::vector<std::string>{"A"}));
  EXPECT_EQ(c.locations, (std::vector<std::string>{"B"}));
  EXPECT_EQ(texts(program_of(c, "r1")),
            (std::vector<std::string>{"open", "move above(A)", "move at(A)", "close A", "move above(A)",
                                      "signal step1.r1>r2", "wait step1.r2>r1", "move handover(r2)",
                                      "signal put9.r1>r2.ready", "wait put9.r2>r1.gripped", "open A",
                                      "signal put9.r1>r2.released", "signal step2.r1>r2", "wait step2.r2>r1"}));
  EXPECT_EQ(
      texts(program_of(c, "r2")),
      (std::vector<std::string>{"signal step1.r2>r1", "wait step1.r1>r2", "open", "move hand_approach(r1)",
                                "wait put9.r1>r2.ready", "move hand_grasp(r1)", "close A", "signal put9.r2>r1.gripped",
                                "wait put9.r1>r2.released", "move hand_approach(r1)", "signal step2.r2>r1",
                                "wait step2.r1>r2", "move above(B)", "move at(B)", "open A", "move above(B)"}));
  // Provenance of a few primitives.
  const Primitive& grasp = program_of(c, "r1").primitives[3];
  EXPECT_EQ(grasp.where.line, 8);
  EXPECT_EQ(grasp.where.column, 3);
  EXPECT_EQ(grasp.task, "Pick A");
  EXPECT_EQ(grasp.motion, "grasp A");
  const Primitive& barrier = program_of(c, "r2").primitives[10];
  EXPECT_EQ(barrier.where.line, 9);
  EXPECT_EQ(barrier.task, "end of step 2");
  EXPECT_EQ(barrier.motion, "barrier");
  const Primitive& release = program_of(c, "r2").primitives[14];
  EXPECT_EQ(release.where.line, 10);
  EXPECT_EQ(release.where.column, 14);
  EXPECT_EQ(release.motion, "release A");
  // Every inserted event starts at 0 and is marked as inserted.
  ASSERT_EQ(c.semaphores.size(), 7u);
  for (const Semaphore& s : c.semaphores) {
    EXPECT_EQ(s.initial, 0u) << s.name;
    EXPECT_TRUE(s.inserted) << s.name;
    EXPECT_FALSE(s.region) << s.name;
  }
  EXPECT_TRUE(c.regions.empty());
}

// The listing below was checked by reading it against the expansion rules in docs/task-language.md.
TEST(FormatListing, Table1Listing) {
  const CompiledProgram c = compile_file(kScenes / "exchange.task");
  std::string listing = format_listing(c);
  const std::string file_line = "program " + (kScenes / "exchange.task").string() + "\n";
  ASSERT_EQ(listing.rfind(file_line, 0), 0u) << listing;
  listing.erase(0, file_line.size());
  EXPECT_EQ(listing,
            "robots: r1 r2\n"
            "workpieces: A\n"
            "locations: B\n"
            "\n"
            "robot r1: 14 primitives\n"
            "   0  open                        # 8:3    Pick A         approach A\n"
            "   1  move above(A)               # 8:3    Pick A         approach A\n"
            "   2  move at(A)                  # 8:3    Pick A         grasp A\n"
            "   3  close A                     # 8:3    Pick A         grasp A\n"
            "   4  move above(A)               # 8:3    Pick A         lift up A\n"
            "   5  signal step1.r1>r2          # 8:3    end of step 1  barrier\n"
            "   6  wait step1.r2>r1            # 8:3    end of step 1  barrier\n"
            "   7  move handover(r2)           # 9:3    Put r2         move to hand-over r2\n"
            "   8  signal put9.r1>r2.ready     # 9:3    Put r2         hand over A\n"
            "   9  wait put9.r2>r1.gripped     # 9:3    Put r2         hand over A\n"
            "  10  open A                      # 9:3    Put r2         hand over A\n"
            "  11  signal put9.r1>r2.released  # 9:3    Put r2         hand over A\n"
            "  12  signal step2.r1>r2          # 9:3    end of step 2  barrier\n"
            "  13  wait step2.r2>r1            # 9:3    end of step 2  barrier\n"
            "\n"
            "robot r2: 16 primitives\n"
            "   0  signal step1.r2>r1          # 8:3    end of step 1  barrier\n"
            "   1  wait step1.r1>r2            # 8:3    end of step 1  barrier\n"
            "   2  open                        # 9:14   Get r1         approach hand r1\n"
            "   3  move hand_approach(r1)      # 9:14   Get r1         approach hand r1\n"
            "   4  wait put9.r1>r2.ready       # 9:14   Get r1         approach hand r1\n"
            "   5  move hand_grasp(r1)         # 9:14   Get r1         approach hand r1\n"
            "   6  close A                     # 9:14   Get r1         grasp A\n"
            "   7  signal put9.r2>r1.gripped   # 9:14   Get r1         grasp A\n"
            "   8  wait put9.r1>r2.released    # 9:14   Get r1         grasp A\n"
            "   9  move hand_approach(r1)      # 9:14   Get r1         depart r1\n"
            "  10  signal step2.r2>r1          # 9:3    end of step 2  barrier\n"
            "  11  wait step2.r1>r2            # 9:3    end of step 2  barrier\n"
            "  12  move above(B)               # 10:14  Place B        approach B\n"
            "  13  move at(B)                  # 10:14  Place B        put down A\n"
            "  14  open A                      # 10:14  Place B        release A\n"
            "  15  move above(B)               # 10:14  Place B        depart B\n"
            "\n"
            "semaphores and events\n"
            "  name                 initial  kind       source\n"
            "  step1.r1>r2                0  event      8:3\n"
            "  step1.r2>r1                0  event      8:3\n"
            "  put9.r1>r2.ready           0  event      9:3\n"
            "  put9.r2>r1.gripped         0  event      9:3\n"
            "  put9.r1>r2.released        0  event      9:3\n"
            "  step2.r1>r2                0  event      9:3\n"
            "  step2.r2>r1                0  event      9:3\n"
            "\n"
            "regions: none\n");
}

TEST(FormatListing, SemaphoresRegionsAndIdleRobots) {
  const CompiledProgram c = compile_text(
      "robot r1 r2 r3\nsemaphore s = 2\nregion Z Y\nsequence r1\n  enter Z\n  signal s\n  leave Z\nend\n"
      "sequence r2\n  wait s\nend\n");
  const std::string listing = format_listing(c);
  EXPECT_NE(listing.find("\nrobot r1: 3 primitives\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("\nrobot r2: 1 primitive\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("\nrobot r3: no primitives\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("  s           2  semaphore  2:11\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("  Z           1  region     3:8\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("  Z: r1 [1, 2)\n  Y: not used\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("  0  wait Z    # 5:3   enter Z   enter Z\n"), std::string::npos) << listing;
}

TEST(FormatListing, EmptyProgram) {
  EXPECT_EQ(format_listing(compile_text("")),
            "program t.task\nrobots: none\nworkpieces: none\nlocations: none\n\nsemaphores and events: none\n\n"
            "regions: none\n");
}

TEST(ToJson, CarriesEveryField) {
  const nlohmann::json j = to_json(compile_file(kScenes / "exchange.task"));
  EXPECT_EQ(j["robots"], nlohmann::json({"r1", "r2"}));
  EXPECT_EQ(j["workpieces"], nlohmann::json({"A"}));
  EXPECT_EQ(j["locations"], nlohmann::json({"B"}));
  ASSERT_EQ(j["programs"].size(), 2u);
  const nlohmann::json& r1 = j["programs"][0];
  EXPECT_EQ(r1["robot"], "r1");
  ASSERT_EQ(r1["primitives"].size(), 14u);
  const nlohmann::json& approach = r1["primitives"][1];
  EXPECT_EQ(approach["index"], 1);
  EXPECT_EQ(approach["kind"], "move");
  EXPECT_EQ(approach["text"], "move above(A)");
  EXPECT_EQ(approach["target"], nlohmann::json({{"kind", "above"}, {"object", "A"}}));
  EXPECT_EQ(approach["where"]["line"], 8);
  EXPECT_EQ(approach["where"]["column"], 3);
  EXPECT_EQ(approach["task"], "Pick A");
  EXPECT_EQ(approach["motion"], "approach A");
  EXPECT_FALSE(approach.contains("event"));
  EXPECT_EQ(r1["primitives"][3]["workpiece"], "A");
  EXPECT_EQ(r1["primitives"][8]["event"], "put9.r1>r2.ready");
  EXPECT_FALSE(r1["primitives"][8].contains("target"));
  ASSERT_EQ(j["semaphores"].size(), 7u);
  EXPECT_EQ(j["semaphores"][2]["name"], "put9.r1>r2.ready");
  EXPECT_EQ(j["semaphores"][2]["initial"], 0);
  EXPECT_EQ(j["semaphores"][2]["inserted"], true);
  EXPECT_EQ(j["semaphores"][2]["region"], false);
  EXPECT_EQ(j["semaphores"][2]["declared"]["line"], 9);
  EXPECT_TRUE(j["regions"].is_array());

  const nlohmann::json regions = to_json(compile_file(kScenes / "regions.task"));
  EXPECT_EQ(regions["regions"][0]["name"], "fixture");
  EXPECT_EQ(regions["regions"][0]["spans"][0], nlohmann::json({{"robot", "r1"}, {"begin", 7}, {"end", 11}}));
}

// ---- the example programs ----------------------------------------------------------------------------------------

TEST(Scenes, AllExamplesCompile) {
  for (const char* name : {"exchange.task", "pick_place.task", "deadlock.task", "regions.task"}) {
    SCOPED_TRACE(name);
    const CompiledProgram c = compile_file(kScenes / name);
    expect_well_formed(c);
    EXPECT_FALSE(c.robots.empty());
    for (const RobotProgram& p : c.programs) EXPECT_FALSE(p.primitives.empty()) << p.robot;
  }
}

TEST(Scenes, PickPlaceSingleRobotHasNoBarrier) {
  const CompiledProgram c = compile_file(kScenes / "pick_place.task");
  EXPECT_EQ(texts(program_of(c, "r1")),
            (std::vector<std::string>{"open", "move above(A)", "move at(A)", "close A", "move above(A)", "wait machine",
                                      "move above(B)", "move at(B)", "open A", "move above(B)", "signal machine"}));
  ASSERT_EQ(c.semaphores.size(), 1u);
  EXPECT_EQ(c.semaphores[0].name, "machine");
  EXPECT_EQ(c.semaphores[0].initial, 1u);
  EXPECT_TRUE(c.semaphores[0].region);
  EXPECT_FALSE(c.semaphores[0].inserted);
  ASSERT_EQ(c.regions.size(), 1u);
  ASSERT_EQ(c.regions[0].spans.size(), 1u);
  EXPECT_EQ(c.regions[0].spans[0].robot, "r1");
  EXPECT_EQ(c.regions[0].spans[0].begin, 6u);  // the Place's approach, right after "wait machine"
  EXPECT_EQ(c.regions[0].spans[0].end, 10u);   // "signal machine"
}

TEST(Scenes, DeadlockCompilesToCrossedWaits) {
  const CompiledProgram c = compile_file(kScenes / "deadlock.task");
  EXPECT_EQ(texts(program_of(c, "r1")), (std::vector<std::string>{"wait s1", "signal s2"}));
  EXPECT_EQ(texts(program_of(c, "r2")), (std::vector<std::string>{"wait s2", "signal s1"}));
  ASSERT_EQ(c.semaphores.size(), 2u);
  EXPECT_EQ(c.semaphores[0].initial, 0u);
  EXPECT_EQ(c.semaphores[1].initial, 0u);
}

TEST(Scenes, RegionsRecordsEverySpan) {
  const CompiledProgram c = compile_file(kScenes / "regions.task");
  ASSERT_EQ(c.regions.size(), 1u);
  const auto& spans = c.regions[0].spans;
  ASSERT_EQ(spans.size(), 4u);
  EXPECT_EQ(std::count_if(spans.begin(), spans.end(), [](const RegionSpan& s) { return s.robot == "r1"; }), 2);
  EXPECT_EQ(std::count_if(spans.begin(), spans.end(), [](const RegionSpan& s) { return s.robot == "r2"; }), 2);
  // The user's semaphore keeps its declared initial count.
  const auto free = std::find_if(c.semaphores.begin(), c.semaphores.end(),
                                 [](const Semaphore& s) { return s.name == "fixture_free"; });
  ASSERT_NE(free, c.semaphores.end());
  EXPECT_EQ(free->initial, 1u);
  EXPECT_FALSE(free->region);
}

// ---- expansions and synchronisation ------------------------------------------------------------------------------

TEST(Compile, BarrierWithThreeRobotsSignalsThenWaitsForEveryOther) {
  const CompiledProgram c = compile_text("robot a b c\nsemaphore s\nsteps\na | b | c\nsignal s\n| | wait s\nend\n");
  expect_well_formed(c);
  EXPECT_EQ(texts(program_of(c, "b")),
            (std::vector<std::string>{"signal step1.b>a", "signal step1.b>c", "wait step1.a>b", "wait step1.c>b"}));
  EXPECT_EQ(texts(program_of(c, "a")), (std::vector<std::string>{"signal s", "signal step1.a>b", "signal step1.a>c",
                                                                 "wait step1.b>a", "wait step1.c>a"}));
  EXPECT_EQ(texts(program_of(c, "c")), (std::vector<std::string>{"signal step1.c>a", "signal step1.c>b",
                                                                 "wait step1.a>c", "wait step1.b>c", "wait s"}));
  // The user's semaphore, then the 6 barrier events of step 1; no barrier after the last step.
  ASSERT_EQ(c.semaphores.size(), 7u);
  EXPECT_EQ(c.semaphores[1].name, "step1.a>b");
  EXPECT_EQ(c.semaphores[1].declared.line, 5);
}

TEST(Compile, RobotsOutsideTheTableAreNotInTheBarrier) {
  const CompiledProgram c =
      compile_text("robot r1 r2 r3\nsemaphore s\nsteps\nr1 | r2\nsignal s|\n|wait s\nend\nsequence r3\nwait s\nend\n");
  EXPECT_EQ(texts(program_of(c, "r3")), (std::vector<std::string>{"wait s"}));
  for (const Semaphore& s : c.semaphores) EXPECT_EQ(s.name.find("r3"), std::string::npos) << s.name;
}

TEST(Compile, RobotWithoutProgramGetsAnEmptyOne) {
  const CompiledProgram c = compile_text("robot r1 idle\nworkpiece A\nsequence r1\nPick A\nend\n");
  ASSERT_EQ(c.programs.size(), 2u);
  EXPECT_EQ(c.programs[1].robot, "idle");
  EXPECT_TRUE(c.programs[1].primitives.empty());
}

TEST(Compile, OwnershipFollowsTheHandOver) {
  // After the hand-over r2 holds A: it may place it, and r1 may pick it again once it is placed.
  const CompiledProgram c = compile_text(
      "robot r1 r2\nworkpiece A\nlocation B\nsteps\nr1 | r2\nPick A\nPut r2 | Get r1\n| Place B\nPick A\nend\n");
  const auto& r2 = program_of(c, "r2").primitives;
  const auto close =
      std::find_if(r2.begin(), r2.end(), [](const Primitive& p) { return p.kind == PrimitiveKind::kClose; });
  ASSERT_NE(close, r2.end());
  EXPECT_EQ(close->workpiece, "A");
  // The Get on the left of the Put compiles the same pair.
  const CompiledProgram swapped =
      compile_text("robot r1 r2\nworkpiece A\nsteps\nr2 | r1\n | Pick A\nGet r1 | Put r2\nend\n");
  EXPECT_EQ(texts(program_of(swapped, "r2"))[2], "open");
  EXPECT_EQ(texts(program_of(swapped, "r2"))[6], "close A");
  EXPECT_EQ(texts(program_of(swapped, "r1")).back(), "signal put6.r1>r2.released");
}

TEST(Compile, PlaceOnAWorkpieceStacks) {
  const CompiledProgram c = compile_text("robot r1\nworkpiece A C\nsequence r1\nPick C\nPlace A\nend\n");
  const auto t = texts(program_of(c, "r1"));
  EXPECT_EQ(std::vector<std::string>(t.begin() + 5, t.end()),
            (std::vector<std::string>{"move above(A)", "move at(A)", "open C", "move above(A)"}));
}

TEST(Compile, KeywordCaseDoesNotChangeTheResult) {
  const auto a = to_json(compile_text("robot r1\nworkpiece A\nlocation B\nsequence r1\nPick A\nPlace B\nend\n"));
  const auto b = to_json(compile_text("ROBOT r1\nworkpiece A\nLOCATION B\nSequence r1\npick A\nPLACE B\nEND\n"));
  EXPECT_EQ(a, b);
}

// ---- semantic errors ---------------------------------------------------------------------------------------------

const std::string kDecl = "robot r1 r2 r3\nworkpiece A C\nlocation B\nsemaphore s\nregion Z\n";  // 5 lines

TEST(CompileErrors, PickWhileHolding) {
  expect_failure(kDecl + "sequence r1\n  Pick A\n  Pick C\nend\n", 8, 3,
                 "r1 cannot pick C: it is already holding A (since line 7)");
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\n| Pick C\nPut r2 | Get r1\nend\n", 10, 10,
                 "r2 cannot Get from r1: it is already holding C (since line 9)");
}

TEST(CompileErrors, PlaceOrPutWhileEmpty) {
  expect_failure(kDecl + "sequence r1\n  Place B\nend\n", 7, 3, "r1 cannot place on B: it is holding nothing");
  expect_failure(kDecl + "steps\nr1 | r2\nPut r2 | Get r1\nend\n", 8, 1, "r1 cannot Put to r2: it is holding nothing");
  // Holding ends with the Place.
  expect_failure(kDecl + "sequence r1\n  Pick A\n  Place B\n  Place B\nend\n", 9, 3,
                 "r1 cannot place on B: it is holding nothing");
}

TEST(CompileErrors, PlaceOnItself) {
  expect_failure(kDecl + "sequence r1\n  Pick A\n  Place A\nend\n", 8, 9, "r1 cannot place A on itself");
}

TEST(CompileErrors, PickingAWorkpieceAnotherRobotHolds) {
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\n| Pick A\nend\n", 9, 8,
                 "r2 cannot pick A: robot r1 is holding it (since line 8)");
  // On the same line, too: the left column picks first.
  expect_failure(kDecl + "steps\nr1 | r2\nPick A | Pick A\nend\n", 8, 15,
                 "r2 cannot pick A: robot r1 is holding it (since line 8)");
  // After the hand-over the taker is the holder.
  expect_failure(kDecl + "steps\nr1 | r2 | r3\nPick A\nPut r2 | Get r1\n | | Pick A\nend\n", 10, 11,
                 "r3 cannot pick A: robot r2 is holding it (since line 9)");
}

TEST(CompileErrors, PutWithoutMatchingGet) {
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\nPut r2\nend\n", 9, 1,
                 "Put r2 needs 'Get r1' in r2's column on the same line, but r2's cell on this line is empty");
  expect_failure(kDecl + "steps\nr1 | r2\nPick A | Pick C\nPut r2 | Place B\nend\n", 9, 1,
                 "Put r2 needs 'Get r1' in r2's column on the same line, but r2's cell on this line is 'Place B'");
  expect_failure(kDecl + "steps\nr1 | r2 | r3\nPick A\nPut r2 | | Get r1\nend\n", 9, 1,
                 "Put r2 needs 'Get r1' in r2's column on the same line, but r2's cell on this line is empty");
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\nPut r3\nend\nsequence r3\nend\n", 9, 1,
                 "Put r3 needs 'Get r1' in r3's column on the same line, but r3 has no column in the steps table");
}

TEST(CompileErrors, GetWithoutMatchingPut) {
  expect_failure(kDecl + "steps\nr1 | r2\n| Get r1\nend\n", 8, 3,
                 "Get r1 needs 'Put r2' in r1's column on the same line, but r1's cell on this line is empty");
  // r1's Put pairs with r3's Get; r2's Get has no partner.
  expect_failure(kDecl + "steps\nr1 | r2 | r3\nPick A\nPut r3 | Get r1 | Get r1\nend\n", 9, 10,
                 "Get r1 needs 'Put r2' in r1's column on the same line, but r1's cell on this line is 'Put r3'");
  expect_failure(kDecl + "steps\nr2 | r1\nGet r1 | Pick A\nend\n", 8, 1,
                 "Get r1 needs 'Put r2' in r1's column on the same line, but r1's cell on this line is 'Pick A'");
}

TEST(CompileErrors, PutOrGetToItself) {
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\nPut r1\nend\n", 9, 5, "r1 cannot Put to itself");
  expect_failure(kDecl + "steps\nr1 | r2\n| Get r2\nend\n", 8, 7, "r2 cannot Get from itself");
}

TEST(CompileErrors, PutAndGetOnlyInTheTable) {
  expect_failure(kDecl + "sequence r1\n  Pick A\n  Put r2\nend\n", 8, 3,
                 "Put is only allowed in the steps table, where the matching Get stands on the same line");
  expect_failure(kDecl + "sequence r2\n  Get r1\nend\n", 7, 3,
                 "Get is only allowed in the steps table, where the matching Put stands on the same line");
}

TEST(CompileErrors, Regions) {
  expect_failure(kDecl + "sequence r1\n  enter Z\n  enter Z\nend\n", 8, 3,
                 "r1 is already inside region Z (entered on line 7)");
  expect_failure(kDecl + "sequence r1\n  leave Z\nend\n", 7, 3, "r1 cannot leave region Z: it is not inside it");
  expect_failure(kDecl + "sequence r1\n  enter Z\n  leave Z\n  leave Z\nend\n", 9, 3,
                 "r1 cannot leave region Z: it is not inside it");
  expect_failure(kDecl + "sequence r1\n  signal s\n  enter Z\nend\n", 8, 3,
                 "the program of r1 ends inside region Z (entered here): add 'leave Z'");
  expect_failure(kDecl + "steps\nr1 | r2\nenter Z\n| signal s\nend\n", 8, 1,
                 "the program of r1 ends inside region Z (entered here): add 'leave Z'");
  // Leaving on a later step line is fine; the region then spans the barrier.
  const CompiledProgram c = compile_text(kDecl + "steps\nr1 | r2\nenter Z\n| signal s\nleave Z\nend\n");
  expect_well_formed(c);
  ASSERT_EQ(c.regions[0].spans.size(), 1u);
  EXPECT_EQ(c.regions[0].spans[0].begin, 1u);
  EXPECT_EQ(c.regions[0].spans[0].end, 5u);  // after the barriers of steps 1 and 2 (primitives 1-4)
}

TEST(CompileErrors, SemanticErrorsHaveTheProgramFileInWhat) {
  try {
    compile(parse_program("robot r1\nlocation B\nsequence r1\nPlace B\nend\n", "cell/prog.task"));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "cell/prog.task:4:1: error: r1 cannot place on B: it is holding nothing");
  }
}

TEST(CompileErrors, HandMadeProgramBreakingTheParserInvariantsIsABug) {
  Program p;
  p.file = "made.task";
  p.sequences.push_back({"ghost", {"made.task", 1, 1}, {}, {}});  // no robot 'ghost' declared
  EXPECT_THROW(compile(p), InternalError);
}

// ---- garbage in --------------------------------------------------------------------------------------------------

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string join_lines(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  return out;
}

// One random edit of `text`: character-, token- or line-level.
std::string mutate(std::string text, std::mt19937& rng) {
  static const std::vector<std::string> kWords = {"Pick",
                                                  "Put",
                                                  "Get",
                                                  "Place",
                                                  "signal",
                                                  "wait",
                                                  "enter",
                                                  "leave",
                                                  "robot",
                                                  "workpiece",
                                                  "location",
                                                  "semaphore",
                                                  "region",
                                                  "steps",
                                                  "sequence",
                                                  "end",
                                                  "r1",
                                                  "r2",
                                                  "r3",
                                                  "A",
                                                  "B",
                                                  "C",
                                                  "s1",
                                                  "Z",
                                                  "|",
                                                  "#",
                                                  "=",
                                                  "0",
                                                  "7",
                                                  "-1",
                                                  "99999999999",
                                                  "",
                                                  "\t",
                                                  "\r",
                                                  "\n",
                                                  "\xff",
                                                  std::string(1, '\0'),
                                                  "loaded",
                                                  "fixture"};
  const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  if (text.empty()) return kWords[pick(kWords.size())];
  switch (pick(7)) {
    case 0:  // delete a few characters
      text.erase(pick(text.size()), 1 + pick(4));
      break;
    case 1:  // insert a word
      text.insert(pick(text.size() + 1), kWords[pick(kWords.size())] + (pick(2) ? " " : ""));
      break;
    case 2: {  // replace a word with another
      std::vector<std::size_t> starts;
      for (std::size_t i = 0; i < text.size(); ++i) {
        if (std::isalnum(static_cast<unsigned char>(text[i])) && (i == 0 || text[i - 1] == ' ')) starts.push_back(i);
      }
      if (starts.empty()) break;
      const std::size_t b = starts[pick(starts.size())];
      std::size_t e = b;
      while (e < text.size() && std::isalnum(static_cast<unsigned char>(text[e]))) ++e;
      text.replace(b, e - b, kWords[pick(kWords.size())]);
      break;
    }
    case 3: {  // delete a line
      auto lines = split_lines(text);
      if (!lines.empty()) lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(pick(lines.size())));
      text = join_lines(lines);
      break;
    }
    case 4: {  // duplicate a line
      auto lines = split_lines(text);
      if (!lines.empty()) {
        const std::size_t i = pick(lines.size());
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(pick(lines.size() + 1)), lines[i]);
      }
      text = join_lines(lines);
      break;
    }
    case 5: {  // swap two lines
      auto lines = split_lines(text);
      if (lines.size() > 1) std::swap(lines[pick(lines.size())], lines[pick(lines.size())]);
      text = join_lines(lines);
      break;
    }
    default:  // random byte
      text[pick(text.size())] = static_cast<char>(pick(256));
      break;
  }
  return text;
}

TEST(GarbageIn, MutatedExamplesEitherCompileOrFailWithInputError) {
  std::mt19937 rng(20240611);
  int compiled = 0;
  int rejected = 0;
  for (const char* name : {"exchange.task", "pick_place.task", "deadlock.task", "regions.task"}) {
    const std::string original = read_file(kScenes / name);
    ASSERT_FALSE(original.empty()) << name;
    for (int i = 0; i < 1500; ++i) {
      std::string text = original;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < edits; ++k) text = mutate(std::move(text), rng);
      try {
        const CompiledProgram c = compile(parse_program(text, "fuzz.task"));
        expect_well_formed(c);
        EXPECT_FALSE(format_listing(c).empty());
        EXPECT_FALSE(to_json(c).dump().empty());
        ++compiled;
      } catch (const InputError& e) {
        EXPECT_EQ(e.where().file, "fuzz.task");
        EXPECT_GE(e.where().line, 1) << e.what();
        EXPECT_FALSE(e.problem().empty());
        ++rejected;
      } catch (const std::exception& e) {
        ADD_FAILURE() << "not an InputError: " << e.what() << "\nfor input:\n" << text;
      }
      if (testing::Test::HasFailure()) return;
    }
  }
  // Both outcomes occur, so the mutations exercise the compiler as well as the parser.
  EXPECT_GT(compiled, 100);
  EXPECT_GT(rejected, 100);
  std::printf("garbage in: %d compiled, %d rejected\n", compiled, rejected);
}

}  // namespace
}  // namespace cellwright::task
