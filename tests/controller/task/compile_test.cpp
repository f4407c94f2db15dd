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

#include "controller/task/task_test_helpers.hpp"

namespace cellwright::task {
namespace {

const std::filesystem::path kScenes = std::filesystem::path(CW_SOURCE_DIR) / "scenes";

using test::compile_text;
using test::Failure;
using test::program_of;

std::vector<std::string> texts(const RobotProgram& prog) {
  std::vector<std::string> out;
  for (const Primitive& p : prog.primitives) out.push_back(to_string(p));
  return out;
}

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
  for (const RobotProgram& prog : c.programs) {
    std::size_t loops_closed = 0;
    for (std::size_t k = 0; k < prog.primitives.size(); ++k) {
      const Primitive& p = prog.primitives[k];
      if (p.kind != PrimitiveKind::kLoop) {
        EXPECT_EQ(p.loop, -1);
        continue;
      }
      // Each kLoop closes the next loop of the robot's list, which says so.
      ASSERT_EQ(p.loop, static_cast<int>(loops_closed)) << prog.robot << " primitive " << k;
      const Loop& loop = prog.loops[loops_closed++];
      EXPECT_EQ(loop.end, k);
      EXPECT_LT(loop.begin, loop.end);
      EXPECT_GE(loop.count, 1u);
      // Named after its repeat line; a follower of cooperating sequences after its leader's.
      if (!loop.paced || loop.leader == prog.robot) {
        EXPECT_EQ(loop.name, "loop" + std::to_string(loop.where.line));
      }
      EXPECT_EQ(p.where.line, loop.where.line);
      for (const std::string& f : loop.followers) {
        EXPECT_TRUE(events.count(loop_again_event(loop, f))) << loop.name;
        EXPECT_TRUE(events.count(loop_exit_event(loop, f))) << loop.name;
        if (loop.paced) {
          EXPECT_TRUE(events.count(loop_taken_event(loop, f))) << loop.name;
        }
      }
      if (loop.leader != prog.robot) {
        EXPECT_TRUE(loop.followers.empty());
      }
    }
    EXPECT_EQ(loops_closed, prog.loops.size()) << prog.robot;
    // Loops do not nest.
    for (std::size_t l = 1; l < prog.loops.size(); ++l) EXPECT_LT(prog.loops[l - 1].end, prog.loops[l].begin);
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

TEST(FormatListing, RobotWithAnEmptySequence) {
  EXPECT_EQ(format_listing(compile_text("robot r1\nsequence r1\nend\n")),
            "program t.task\nrobots: r1\nworkpieces: none\nlocations: none\n\nrobot r1: no primitives\n\n"
            "semaphores and events: none\n\nregions: none\n");
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
  for (const char* name : {"exchange.task", "pick_place.task", "deadlock.task", "regions.task", "pipeline.task",
                           "pipeline_shift.task"}) {
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

TEST(Compile, LoopsOfCooperatingSequencesAreOneLoopLedByTheFirstRobot) {
  // r2's sequence comes first in the file and names r1; r1, declared first, leads all the same.
  const std::string text = test::stand_relay("repeat 4 with r2", "repeat 4 with r1");
  const CompiledProgram c = compile(parse_program(text, "relay.task"));
  expect_well_formed(c);
  const Loop& lead = test::program_of(c, "r1").loops.at(0);
  const Loop& follow = test::program_of(c, "r2").loops.at(0);
  EXPECT_EQ(lead.name, "loop8");  // the leader's repeat line
  EXPECT_EQ(follow.name, "loop8");
  EXPECT_EQ(lead.leader, "r1");
  EXPECT_EQ(follow.leader, "r1");
  EXPECT_EQ(lead.followers, (std::vector<std::string>{"r2"}));
  EXPECT_TRUE(follow.followers.empty());
  EXPECT_TRUE(lead.paced && follow.paced);
  EXPECT_EQ(follow.where.line, 16);  // each robot's own repeat
  // The decision's events; the acknowledgement starts at 1.
  std::map<std::string, std::uint32_t> inserted;
  for (const Semaphore& s : c.semaphores) {
    if (s.inserted) inserted[s.name] = s.initial;
  }
  EXPECT_EQ(inserted, (std::map<std::string, std::uint32_t>{
                          {"loop8.r1>r2.again", 0}, {"loop8.r1>r2.exit", 0}, {"loop8.r2>r1.taken", 1}}));
  EXPECT_NE(format_listing(c).find("once each has taken the last"), std::string::npos) << format_listing(c);
  EXPECT_EQ(to_json(c)["programs"][1]["loops"][0]["paced"], true);
  // A loop without partners stays its own leader, unpaced.
  const CompiledProgram alone = compile(parse_program(test::stand_relay("repeat 4", "repeat 4"), "relay.task"));
  EXPECT_EQ(test::program_of(alone, "r2").loops.at(0).leader, "r2");
  EXPECT_FALSE(test::program_of(alone, "r2").loops.at(0).paced);
}

TEST(CompileErrors, LoopsOfCooperatingSequencesMustMatch) {
  // The partner's loop decides alone: no loop of r2 names r1.
  expect_failure(test::stand_relay("repeat 4 with r2", "repeat 4"), 8, 3,
                 "the loop of r1 runs with r2, but the sequence of r2 has no loop 'with r1' to run with it (r1 has "
                 "1): write 'repeat 4 with r1' in the sequence of r2");
  // Counts differ: reported at the follower's repeat.
  expect_failure(test::stand_relay("repeat 4 with r2", "repeat 5 with r1"), 16, 3,
                 "the loop of r2 repeats 5 times, but the loop of r1 it runs with (line 8) repeats 4 times: loops "
                 "with one decision run the same number of iterations");
  // Partners that are not sequences, not robots, or the robot itself: each reported at the name.
  const std::pair<const char*, const char*> partners[] = {
      {"r2", "robot 'r2' has no sequence for this loop to run with (a loop with partners joins the loops of their "
             "sequences)"},
      {"r9", "'r9' after 'with' is not a declared robot"},
      {"r1", "robot 'r1' names its own sequence after 'with'"},
  };
  for (const auto& [partner, problem] : partners) {
    expect_failure(std::string("robot r1 r2\nsemaphore s\nsequence r1\nrepeat 2 with ") + partner +
                       "\nsignal s\nend\nend\n",
                   4, 15, problem);
  }
}

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

// ---- loops and workpiece classes ---------------------------------------------------------------------------------

TEST(Compile, ShiftLoopEmitsTheBodyOnceClosedByTheLeadersDecision) {
  const CompiledProgram c = compile_file(kScenes / "pipeline_shift.task");
  expect_well_formed(c);
  EXPECT_TRUE(c.workpieces.empty());  // named workpieces only
  ASSERT_EQ(c.classes.size(), 1u);
  EXPECT_EQ(c.classes[0].name, "part");
  EXPECT_EQ(c.classes[0].from, "IN");
  EXPECT_EQ(c.classes[0].where.line, 8);
  ASSERT_NE(find_class(c, "part"), nullptr);
  EXPECT_EQ(find_class(c, "part")->from, "IN");
  EXPECT_EQ(find_class(c, "OUT"), nullptr);

  // r1 (the first column) leads: lines 16-17 once, the step-4 barrier, then its decision.
  const RobotProgram& r1 = program_of(c, "r1");
  const auto t1 = texts(r1);
  ASSERT_EQ(t1.size(), 29u);
  EXPECT_EQ(std::vector<std::string>(t1.begin() + 14, t1.end()),
            (std::vector<std::string>{"open", "move above(part)", "move at(part)", "close part", "move above(part)",
                                      "signal step3.r1>r2", "wait step3.r2>r1", "move handover(r2)",
                                      "signal put17.r1>r2.ready", "wait put17.r2>r1.gripped", "open part",
                                      "signal put17.r1>r2.released", "signal step4.r1>r2", "wait step4.r2>r1",
                                      "loop loop15"}));
  ASSERT_EQ(r1.loops.size(), 1u);
  const Loop& lead = r1.loops[0];
  EXPECT_EQ(lead.name, "loop15");
  EXPECT_EQ(lead.where.line, 15);
  EXPECT_EQ(lead.where.column, 1);
  EXPECT_EQ(lead.count, 9u);
  EXPECT_EQ(lead.begin, 14u);
  EXPECT_EQ(lead.end, 28u);
  EXPECT_EQ(lead.leader, "r1");
  EXPECT_EQ(lead.followers, (std::vector<std::string>{"r2"}));
  const Primitive& decide = r1.primitives[28];
  EXPECT_EQ(decide.kind, PrimitiveKind::kLoop);
  EXPECT_EQ(decide.loop, 0);
  EXPECT_EQ(decide.task, "repeat 9");
  EXPECT_EQ(decide.motion, "loop");
  EXPECT_EQ(decide.where.line, 15);
  EXPECT_EQ(decide.where.column, 1);

  // r2 follows; after the loop it places the last part.
  const RobotProgram& r2 = program_of(c, "r2");
  const auto t2 = texts(r2);
  ASSERT_EQ(t2.size(), 33u);
  EXPECT_EQ(t2[12], "move above(OUT)");
  EXPECT_EQ(t2[27], "wait step4.r1>r2");
  EXPECT_EQ(t2[28], "loop loop15");
  EXPECT_EQ(t2[29], "move above(OUT)");
  ASSERT_EQ(r2.loops.size(), 1u);
  EXPECT_EQ(r2.loops[0].name, "loop15");
  EXPECT_EQ(r2.loops[0].begin, 12u);
  EXPECT_EQ(r2.loops[0].end, 28u);
  EXPECT_EQ(r2.loops[0].leader, "r1");
  EXPECT_TRUE(r2.loops[0].followers.empty());
  EXPECT_EQ(r2.primitives[28].loop, 0);

  // The decision events come last, declared at the repeat line, like the other inserted events.
  ASSERT_EQ(c.semaphores.size(), 16u);
  EXPECT_EQ(c.semaphores[13].name, "step4.r2>r1");
  EXPECT_EQ(c.semaphores[14].name, "loop15.r1>r2.again");
  EXPECT_EQ(c.semaphores[15].name, "loop15.r1>r2.exit");
  EXPECT_EQ(loop_again_event(lead, "r2"), "loop15.r1>r2.again");
  EXPECT_EQ(loop_exit_event(lead, "r2"), "loop15.r1>r2.exit");
  for (std::size_t i = 14; i < 16; ++i) {
    EXPECT_EQ(c.semaphores[i].initial, 0u);
    EXPECT_TRUE(c.semaphores[i].inserted);
    EXPECT_FALSE(c.semaphores[i].region);
    EXPECT_EQ(c.semaphores[i].declared.line, 15);
  }
}

TEST(Compile, EveryTableRobotRunsTheLoopEvenIdleAndTheBarrierEndsTheBody) {
  // r3 idles in the whole body; the loop is the table's last thing, yet its last line ends with a barrier.
  const CompiledProgram c = compile_text(kDecl + "steps\nr1 | r2 | r3\nrepeat 2\nsignal s | wait s\nend\nend\n");
  expect_well_formed(c);
  EXPECT_EQ(texts(program_of(c, "r3")), (std::vector<std::string>{"signal step1.r3>r1", "signal step1.r3>r2",
                                                                   "wait step1.r1>r3", "wait step1.r2>r3",
                                                                   "loop loop8"}));
  EXPECT_EQ(texts(program_of(c, "r1")).back(), "loop loop8");
  EXPECT_EQ(texts(program_of(c, "r1"))[4], "wait step1.r3>r1");
  const Loop& lead = program_of(c, "r1").loops.at(0);
  EXPECT_EQ(lead.followers, (std::vector<std::string>{"r2", "r3"}));  // column order
  EXPECT_EQ(lead.count, 2u);
  EXPECT_EQ(program_of(c, "r3").loops.at(0).leader, "r1");
  std::vector<std::string> inserted;
  for (const Semaphore& sem : c.semaphores) {
    if (sem.name.rfind("loop", 0) == 0) inserted.push_back(sem.name);
  }
  EXPECT_EQ(inserted, (std::vector<std::string>{"loop8.r1>r2.again", "loop8.r1>r2.exit", "loop8.r1>r3.again",
                                                "loop8.r1>r3.exit"}));
}

TEST(Compile, OneColumnTableAndSequenceLoopsHaveNoFollowers) {
  const CompiledProgram table = compile_text(
      "robot r1\nworkpiece part from IN\nlocation IN OUT\nsteps\nr1\nrepeat 1000\nPick part\nPlace OUT\nend\nend\n");
  expect_well_formed(table);
  EXPECT_EQ(texts(program_of(table, "r1")),
            (std::vector<std::string>{"open", "move above(part)", "move at(part)", "close part", "move above(part)",
                                      "move above(OUT)", "move at(OUT)", "open part", "move above(OUT)",
                                      "loop loop6"}));
  const Loop& loop = program_of(table, "r1").loops.at(0);
  EXPECT_EQ(loop.leader, "r1");
  EXPECT_TRUE(loop.followers.empty());
  EXPECT_EQ(loop.begin, 0u);
  EXPECT_EQ(loop.end, 9u);
  EXPECT_TRUE(table.semaphores.empty());  // no barrier, no decision events

  // Two loops in a sequence, with a command between them; the robot leads its own loops.
  const CompiledProgram seq = compile_text(kDecl +
                                           "sequence r2\n  repeat 3\n    wait s\n  end\n  signal s\n"
                                           "  repeat 2\n    enter Z\n    leave Z\n  end\nend\n");
  expect_well_formed(seq);
  EXPECT_EQ(texts(program_of(seq, "r2")), (std::vector<std::string>{"wait s", "loop loop7", "signal s", "wait Z",
                                                                     "signal Z", "loop loop11"}));
  const auto& loops = program_of(seq, "r2").loops;
  ASSERT_EQ(loops.size(), 2u);
  EXPECT_EQ(loops[0].begin, 0u);
  EXPECT_EQ(loops[0].end, 1u);
  EXPECT_EQ(loops[1].begin, 3u);
  EXPECT_EQ(loops[1].end, 5u);
  EXPECT_EQ(loops[1].leader, "r2");
  EXPECT_EQ(seq.semaphores.size(), 2u);  // s and Z only
  // Region spans inside a body are indices within it.
  ASSERT_EQ(seq.regions.at(0).spans.size(), 1u);
  EXPECT_EQ(seq.regions[0].spans[0].begin, 4u);
  EXPECT_EQ(seq.regions[0].spans[0].end, 4u);
}

TEST(Compile, ClassesAreExemptFromTheCrossRobotHoldingCheck) {
  // Both robots hold a part at once: different parts of the class.
  const CompiledProgram c =
      compile_text("robot r1 r2\nworkpiece part from IN\nlocation IN OUT\nsteps\nr1 | r2\nPick part\n"
                   "Put r2 | Get r1\nPick part | Place OUT\nend\n");
  expect_well_formed(c);
  // A named workpiece is still checked, in a loop as elsewhere.
  expect_failure("robot r1 r2\nworkpiece A\nlocation IN OUT\nsteps\nr1 | r2\nPick A\nPut r2 | Get r1\nrepeat 3\n"
                 "Pick A | Place OUT\nPut r2 | Get r1\nend\n| Place OUT\nend\n",
                 9, 6, "r1 cannot pick A: robot r2 is holding it (since line 7)");
  // The per-robot checks apply to classes by name.
  expect_failure("robot r1\nworkpiece part from IN\nlocation IN\nsequence r1\nPick part\nPick part\nend\n", 6, 1,
                 "r1 cannot pick part: it is already holding part (since line 5)");
  expect_failure("robot r1 r2\nworkpiece part from IN\nlocation IN\nsteps\nr1 | r2\nPick part | Pick part\n"
                 "Put r2 | Get r1\nend\n",
                 7, 10, "r2 cannot Get from r1: it is already holding part (since line 6)");
}

TEST(CompileErrors, PlaceOnAClass) {
  expect_failure("robot r1\nworkpiece part from IN\nworkpiece A\nlocation IN\nsequence r1\nPick A\nPlace part\nend\n", 7,
                 7,
                 "r1 cannot place on part: it is a workpiece class (whichever part arrives at IN); place on a "
                 "location or a named workpiece");
}

TEST(CompileErrors, LoopBodyMustLeaveEachRobotAsItFoundIt) {
  // Holding: picked in the body, placed after it.
  expect_failure(kDecl + "sequence r1\n  repeat 2\n    Pick A\n  end\n  Place B\nend\n", 7, 3,
                 "r1 holds nothing at the start of the loop's body and A (since line 8) at its end: an iteration must "
                 "leave each robot holding what it held when the iteration began");
  // Holding another workpiece at the end than at the start; the robots are checked in column order.
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\nrepeat 2\nPut r2 | Get r1\nPick C\nend\nend\n", 9, 1,
                 "r1 holds A (since line 8) at the start of the loop's body and C (since line 11) at its end: an "
                 "iteration must leave each robot holding what it held when the iteration began");
  expect_failure(kDecl + "steps\nr1 | r2\nPick A\nrepeat 2\nPut r2 | Get r1\nend\nend\n", 9, 1,
                 "r1 holds A (since line 8) at the start of the loop's body and nothing at its end: an iteration "
                 "must leave each robot holding what it held when the iteration began");
  expect_failure(kDecl + "sequence r1\n  Pick A\n  repeat 2\n    Place B\n    Pick C\n  end\nend\n", 8, 3,
                 "r1 holds A (since line 7) at the start of the loop's body and C (since line 10) at its end: an "
                 "iteration must leave each robot holding what it held when the iteration began");
  // Regions: entered in the body and left after it, or the other way round.
  expect_failure(kDecl + "sequence r1\n  repeat 2\n    enter Z\n  end\n  leave Z\nend\n", 7, 3,
                 "r1 is inside no region at the start of the loop's body and inside region Z at its end: an iteration "
                 "must leave each robot in the regions it was in when the iteration began");
  expect_failure(kDecl + "region Y\nsequence r3\n  enter Z\n  enter Y\n  repeat 2\n    leave Z\n  end\n"
                         "  enter Z\n  leave Y\n  leave Z\nend\n",
                 10, 3,
                 "r3 is inside regions Y, Z at the start of the loop's body and inside region Y at its end: an "
                 "iteration must leave each robot in the regions it was in when the iteration began");
  // Balanced bodies compile, holding or inside across the loop.
  const CompiledProgram ok =
      compile_text(kDecl + "sequence r1\n  Pick A\n  enter Z\n  repeat 2\n    signal s\n  end\n  leave Z\n"
                           "  Place B\nend\n");
  expect_well_formed(ok);
  EXPECT_EQ(ok.regions[0].spans[0].begin, 6u);
  EXPECT_EQ(ok.regions[0].spans[0].end, 8u);  // the kLoop primitive (7) is inside too
}

TEST(FormatListing, ClassesAndLoops) {
  const std::string listing = format_listing(compile_file(kScenes / "pipeline_shift.task"));
  EXPECT_NE(listing.find("\nworkpieces: none\nworkpiece classes: part from IN\nlocations: IN OUT\n"),
            std::string::npos)
      << listing;
  EXPECT_NE(listing.find("\n  28  loop loop15                  # 15:1   repeat 9       loop\n"
                         "  loop15 (repeat 9): body [14, 28), 28 decides again or exit and tells r2\n\nrobot r2"),
            std::string::npos)
      << listing;
  EXPECT_NE(listing.find("  loop15 (repeat 9): body [12, 28), 28 waits for r1's decision\n"), std::string::npos)
      << listing;
  EXPECT_NE(listing.find("\n  loop15.r1>r2.again          0  event      15:1\n"), std::string::npos) << listing;
  const std::string seq = format_listing(
      compile_text("robot r1\nsemaphore s\nsequence r1\nrepeat 4\nsignal s\nend\nend\n"));
  EXPECT_NE(seq.find("  loop4 (repeat 4): body [0, 1), 1 decides again or exit\n"), std::string::npos) << seq;
  // Without classes the listing has no classes line.
  EXPECT_EQ(format_listing(compile_file(kScenes / "exchange.task")).find("classes"), std::string::npos);
}

TEST(ToJson, LoopsAndClassesRoundTrip) {
  const CompiledProgram c = compile_file(kScenes / "pipeline_shift.task");
  // Through text and back, as a tool reading `twin compile --json` would.
  const nlohmann::json j = nlohmann::json::parse(to_json(c).dump());
  EXPECT_TRUE(j["workpieces"].empty());
  ASSERT_EQ(j["classes"].size(), 1u);
  EXPECT_EQ(j["classes"][0]["name"], "part");
  EXPECT_EQ(j["classes"][0]["from"], "IN");
  EXPECT_EQ(j["classes"][0]["where"]["line"], 8);
  ASSERT_EQ(j["programs"].size(), c.programs.size());
  for (std::size_t r = 0; r < c.programs.size(); ++r) {
    const RobotProgram& prog = c.programs[r];
    const nlohmann::json& jp = j["programs"][r];
    ASSERT_EQ(jp["loops"].size(), prog.loops.size());
    for (std::size_t l = 0; l < prog.loops.size(); ++l) {
      const Loop& loop = prog.loops[l];
      const nlohmann::json& jl = jp["loops"][l];
      EXPECT_EQ(jl["name"], loop.name);
      EXPECT_EQ(jl["count"], loop.count);
      EXPECT_EQ(jl["begin"], loop.begin);
      EXPECT_EQ(jl["end"], loop.end);
      EXPECT_EQ(jl["leader"], loop.leader);
      EXPECT_EQ(jl["followers"].get<std::vector<std::string>>(), loop.followers);
      EXPECT_EQ(jl["where"]["line"], loop.where.line);
      EXPECT_EQ(jl["where"]["column"], loop.where.column);
    }
    ASSERT_EQ(jp["primitives"].size(), prog.primitives.size());
    for (std::size_t k = 0; k < prog.primitives.size(); ++k) {
      const Primitive& p = prog.primitives[k];
      const nlohmann::json& jk = jp["primitives"][k];
      EXPECT_EQ(jk["text"], to_string(p));
      EXPECT_EQ(jk["kind"], to_string(p.kind));
      EXPECT_EQ(jk.contains("loop"), p.kind == PrimitiveKind::kLoop) << k;
      if (p.kind == PrimitiveKind::kLoop) {
        EXPECT_EQ(jk["loop"], p.loop);
      }
    }
  }
  EXPECT_EQ(j["programs"][0]["primitives"][28]["text"], "loop loop15");
  EXPECT_EQ(j["programs"][0]["primitives"][28]["kind"], "loop");
  EXPECT_EQ(j["programs"][0]["primitives"][28]["task"], "repeat 9");
  EXPECT_EQ(j["programs"][1]["loops"][0]["followers"], nlohmann::json::array());
  EXPECT_EQ(j["semaphores"].back()["name"], "loop15.r1>r2.exit");
  // A program without loops or classes has them as empty lists.
  const nlohmann::json plain = to_json(compile_file(kScenes / "exchange.task"));
  EXPECT_EQ(plain["classes"], nlohmann::json::array());
  EXPECT_EQ(plain["programs"][0]["loops"], nlohmann::json::array());
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
                                                  "fixture",
                                                  "repeat",
                                                  "repeat 3",
                                                  "from",
                                                  "part",
                                                  "IN",
                                                  "OUT"};
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
  for (const char* name :
       {"exchange.task", "pick_place.task", "deadlock.task", "regions.task", "pipeline_shift.task"}) {
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
