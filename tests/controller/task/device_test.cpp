// Devices in the task language (issue 26): machines, conveyors and photo-eyes declared and commanded by the robots'
// programs, compiled to device primitives bracketed by the devices' states, so that the Petri net's check before the
// run covers them (docs/task-language.md, "Devices").
#include <gtest/gtest.h>

#include <string>

#include "cellwright/petri/analysis.hpp"
#include "cellwright/petri/dot.hpp"
#include "cellwright/petri/pnml.hpp"
#include "cellwright/task/compile.hpp"
#include "cellwright/task/to_net.hpp"

namespace cellwright::task {
namespace {

// The mill tended by two robots: r1 lets the input belt accumulate, waits for the part at its stop, loads the mill,
// starts it and parks; r2 waits for the cycle, unloads the mill onto OUT and goes home. {START} and {RUN} are
// replaced by the tests that take a line out.
const std::string kMill = R"(robot r1 r2
workpiece A
location OUT
machine mill
conveyor IN
sensor in_stop on IN

sequence r1
  {RUN}
  wait in_stop
  Pick A
  Place mill
  {START}
  park
end

sequence r2
  wait mill
  Pick A from mill
  Place OUT
  home
end
)";

std::string mill(const std::string& run = "accumulate IN", const std::string& start = "start mill") {
  std::string text = kMill;
  text.replace(text.find("{RUN}"), 5, run);
  text.replace(text.find("{START}"), 7, start);
  return text;
}

CompiledProgram compile_text(const std::string& text) {
  return compile(parse_program(text, "mill.task"));
}

petri::AnalysisResult check(const CompiledProgram& c) {
  petri::AnalysisOptions o;
  o.reduction = petri::Reduction::kStubborn;
  return petri::analyze(to_net(c), o);
}

std::string parse_error(const std::string& text) {
  try {
    parse_program(text, "t.task");
  } catch (const InputError& e) {
    return fmt::format("{}:{}: {}", e.where().line, e.where().column, e.problem());
  }
  return "no error";
}

TEST(Devices, ParsedWithTheirConveyorAndCommands) {
  const Program p = parse_program(mill(), "mill.task");
  const Declaration* eye = find_declaration(p, "in_stop");
  ASSERT_NE(eye, nullptr);
  EXPECT_EQ(eye->kind, NameKind::kSensor);
  EXPECT_EQ(eye->from, "IN");
  EXPECT_EQ(find_declaration(p, "mill")->kind, NameKind::kMachine);
  EXPECT_EQ(find_declaration(p, "IN")->kind, NameKind::kConveyor);
  const Sequence& r2 = p.sequences[1];
  EXPECT_EQ(to_string(r2.commands[0]), "wait mill");
  EXPECT_EQ(r2.commands[0].argument_kind, NameKind::kMachine);
  EXPECT_EQ(to_string(r2.commands[1]), "Pick A from mill");
  EXPECT_EQ(to_string(r2.commands[3]), "home");
  EXPECT_EQ(to_string(p.sequences[0].commands.back()), "park");
}

TEST(Devices, WordsAreNotReservedSoOldProgramsStillRead) {
  // scenes/pick_place.task names a region `machine`; device words are only recognised by position.
  const Program p =
      parse_program("robot r1\nregion machine\nmachine mill\nsequence r1\n  enter machine\n  start mill\n  leave "
                    "machine\nend\n",
                    "t.task");
  EXPECT_EQ(find_declaration(p, "machine")->kind, NameKind::kRegion);
  EXPECT_EQ(p.sequences[0].commands[1].kind, CommandKind::kStart);
}

TEST(Devices, MisusedDevicesAreErrorsAtTheirToken) {
  const std::string head = "robot r1\nmachine mill\nconveyor IN\nlocation L\n";
  EXPECT_EQ(parse_error(head + "sensor eye\nsequence r1\nhome\nend\n"),
            "5:8: sensor 'eye' needs the conveyor whose parts it sees: 'sensor eye on CONVEYOR'");
  EXPECT_EQ(parse_error(head + "sensor eye on mill\nsequence r1\nhome\nend\n"),
            "5:15: sensor 'eye' sees the parts of a conveyor, but 'mill' is a machine (declared on line 2)");
  EXPECT_EQ(parse_error(head + "sequence r1\n  start IN\nend\n"),
            "6:9: start expects a machine, but 'IN' is a conveyor (declared on line 3)");
  EXPECT_EQ(parse_error(head + "sequence r1\n  run mill\nend\n"),
            "6:7: run expects a conveyor, but 'mill' is a machine (declared on line 2)");
  EXPECT_EQ(parse_error(head + "workpiece A\nsequence r1\n  Pick A from L\nend\n"),
            "7:15: Pick ... from expects a machine, but 'L' is a location (declared on line 4)");
  EXPECT_EQ(parse_error(head + "sequence r1\n  home L\nend\n"), "6:8: unexpected 'L' after 'home': home takes no argument");
  EXPECT_EQ(parse_error(head + "sequence r1\n  stop\nend\n"), "6:3: stop needs an argument: a conveyor name");
  EXPECT_EQ(parse_error(head + "sequence r1\n  start oven\nend\n"), "6:9: unknown machine 'oven'");
}

TEST(Devices, CompiledToDevicePrimitivesBetweenTheDeviceStates) {
  const CompiledProgram c = compile_text(mill());
  const std::string listing = format_listing(c);
  EXPECT_NE(listing.find("machines: mill\nconveyors: IN\nsensors: in_stop on IN\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("wait mill.loaded"), std::string::npos) << listing;
  EXPECT_NE(listing.find("device mill start"), std::string::npos) << listing;
  EXPECT_NE(listing.find("device in_stop await on"), std::string::npos) << listing;
  EXPECT_NE(listing.find("mill.idle          1  device"), std::string::npos) << listing;
  const auto& r2 = c.programs[1].primitives;
  ASSERT_GE(r2.size(), 4u);
  EXPECT_EQ(to_string(r2[0]), "wait mill.busy");
  EXPECT_EQ(to_string(r2[1]), "device mill await done");
  EXPECT_EQ(to_string(r2[2]), "signal mill.done");
  EXPECT_EQ(to_string(r2[3]), "wait mill.done");  // the unload waits for the finished cycle
  EXPECT_EQ(to_string(r2.back()), "move home");
  EXPECT_EQ(to_string(c.programs[0].primitives.back()), "move park");

  const nlohmann::json j = to_json(c);
  const nlohmann::json& start = j["programs"][0]["primitives"][18];
  EXPECT_EQ(start["kind"], "device");
  EXPECT_EQ(start["device"], "mill");
  EXPECT_EQ(start["op"], "start");
  EXPECT_EQ(j["sensors"][0]["conveyor"], "IN");
  EXPECT_EQ(j["semaphores"][0]["device"], "mill");
  // A program without devices has no device keys (its JSON is as before).
  EXPECT_FALSE(to_json(compile_text("robot r1\nsequence r1\nhome\nend\n")).contains("machines"));
}

TEST(Devices, AGoodProgramPassesTheCheck) {
  const petri::AnalysisResult r = check(compile_text(mill()));
  EXPECT_TRUE(r.ok()) << r.deadlocks;
  EXPECT_EQ(r.deadlocks, 0u);
}

TEST(Devices, UnloadingAMachineNeverStartedIsRefusedWithTheMachineNamed) {
  const CompiledProgram c = compile_text(mill("accumulate IN", "home"));
  const petri::Net net = to_net(c);
  const petri::AnalysisResult r = check(c);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.deadlocks, 1u);
  const std::string report = petri::format_report(net, r);
  EXPECT_NE(report.find("r2: waiting for device mill.busy (line 18 'wait mill')"), std::string::npos) << report;
}

TEST(Devices, WaitingForASensorNothingCanSetIsRefused) {
  // Nobody runs the belt: the photo-eye can never see a part.
  const CompiledProgram c = compile_text(mill("home", "start mill"));
  const petri::AnalysisResult r = check(c);
  EXPECT_FALSE(r.ok());
  const std::string report = petri::format_report(to_net(c), r);
  EXPECT_NE(report.find("r1: waiting for device IN.running (line 10 'wait in_stop')"), std::string::npos) << report;
}

TEST(Devices, UnloadingBeforeDoneIsImpossibleInTheNet) {
  // Without `wait mill`, the unload waits for a done the net never gives: refused, never run.
  std::string text = mill();
  text.replace(text.find("  wait mill\n"), 12, "");
  const CompiledProgram c = compile_text(text);
  const petri::Net net = to_net(c);
  // The unload's first step takes a token from the mill's done place, which only the end of a cycle puts there.
  const petri::Transition& unload = net.transitions()[*net.find_transition(transition_id("r2", 1))];
  const petri::PlaceId done = *net.find_place(event_place_id("mill.done"));
  bool takes_done = false;
  for (const petri::Arc& a : unload.inputs) takes_done = takes_done || a.place == done;
  EXPECT_TRUE(takes_done);
  const petri::AnalysisResult r = check(c);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(petri::format_report(net, r).find("r2: waiting for device mill.done"), std::string::npos);
}

TEST(Devices, RunningARunningBeltIsADeadlockNotAHang) {
  std::string text = mill("run IN");
  text.replace(text.find("  wait in_stop\n"), 15, "  wait in_stop\n  run IN\n");
  const CompiledProgram c = compile_text(text);
  const petri::AnalysisResult r = check(c);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(petri::format_report(to_net(c), r).find("waiting for device IN.stopped"), std::string::npos);
}

TEST(Devices, NetStillWrittenAsPnmlAndDot) {
  const petri::Net net = to_net(compile_text(mill()));
  const std::string pnml = petri::to_pnml(net);
  EXPECT_NE(pnml.find("mill.idle"), std::string::npos);
  const petri::Net back = petri::parse_pnml(pnml, "mill.pnml");
  EXPECT_EQ(back.num_places(), net.num_places());
  EXPECT_TRUE(petri::analyze(back).ok());
  EXPECT_NE(petri::to_dot(net).find("device mill.busy"), std::string::npos);
}

}  // namespace
}  // namespace cellwright::task
