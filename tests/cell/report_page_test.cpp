// The report page (index.html): what it shows of a report, that every user string is escaped, the pictures embedded
// as data: URIs that decode to the given bytes, the video as a link beside the page. The page in a browser is
// tests/tools/report_page_cli_test.cpp.
#include "cellwright/cell/report_page.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <yaml-cpp/binary.h>

#include <opencv2/core.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "cellwright/common/files.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cell/report_files.hpp"

namespace cellwright::cell {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

const std::string kScenes = std::string(CW_SOURCE_DIR) + "/scenes";

// The text between the first `from` and the next `to` after it ("" when absent).
std::string between(const std::string& text, const std::string& from, const std::string& to) {
  const auto a = text.find(from);
  if (a == std::string::npos) return "";
  const auto b = text.find(to, a + from.size());
  return text.substr(a + from.size(), b == std::string::npos ? std::string::npos : b - a - from.size());
}

// The single arm's scenario (A expected at mill_side, a location of the scenario) and a report of a run that placed
// A 4 mm off the location's point, with two robots' times, a collision and a recovered fault.
class ReportPageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scenario_ = load_scenario(kScenes + "/single.yaml");
    const models::LocationSpec* side = scenario_.cell.find_location("mill_side");
    ASSERT_NE(side, nullptr);
    report_.outcome = "finished";
    report_.end_time = 31.5;
    report_.finished_at = 30.5;
    report_.estimated_cycle_time = 29.0;
    report_.firings = 24;
    report_.parts_completed = 1;
    report_.throughput = 2.5;
    WorkpieceReport a;
    a.name = "A";
    a.label = "A";
    a.expected = "mill_side";
    a.tolerance = 0.03;
    a.ok = true;
    a.status = PartStatus::kInPlace;
    a.where = "mill_side";
    a.final_location = "mill_side";
    a.at = {"mill_side", "mill"};
    // Centre 30 mm above the bottom (a 60 mm part), bottom 4 mm off the location's point along x.
    a.position = side->pose.xyz + Eigen::Vector3d(0.004, 0, 0.03);
    a.pick_start = 3.25;
    a.place_end = 27.75;
    a.cycle_time = 24.5;
    report_.workpieces.push_back(a);
    WorkpieceReport b;
    b.name = "B";
    b.final_location = "input";
    b.at = {"input"};
    b.status = PartStatus::kElsewhere;
    b.where = "input";
    report_.workpieces.push_back(b);
    RobotTimeline r1;
    r1.robot = "r1";
    r1.cell = "puma";
    r1.commands = 12;
    r1.busy = 15.75;
    r1.waiting = 3.15;
    r1.blocked = 6.3;
    r1.idle = 6.3;
    report_.timeline.end = 31.5;
    report_.timeline.robots.push_back(r1);
    report_.collisions.push_back({12.5, "puma/link5", "melfa/base", 0.0021});
    FaultReport f;
    f.kind = "drop";
    f.t = 8.0;
    f.robot = "puma";
    f.workpiece = "A";
    f.detail = "released 0.10 s into the move";
    f.detected = true;
    f.detected_at = 8.2;
    f.detected_by = "r1";
    f.symptom = "part_lost_in_transit";
    f.cause = "dropped";
    f.action = "pick_again";
    f.recovered = true;
    f.recovery_time = 6.5;
    report_.faults.push_back(f);
  }

  std::string page(const ReportPageMedia& media = {}) const { return render_report_page(scenario_, report_, media); }

  Scenario scenario_;
  Report report_;
};

TEST_F(ReportPageTest, IsOneHtmlDocumentWithNothingLoadedFromElsewhere) {
  const std::string html = page();
  EXPECT_EQ(html.rfind("<!DOCTYPE html>\n", 0), 0u);
  EXPECT_THAT(html, HasSubstr("<meta charset=\"utf-8\">"));
  EXPECT_THAT(html, HasSubstr("<title>single.yaml &ndash; OK &ndash; twin run report</title>"));
  EXPECT_EQ(html.substr(html.size() - 8), "</html>\n");
  EXPECT_THAT(html, Not(HasSubstr("<script")));
  EXPECT_THAT(html, Not(HasSubstr("http:")));
  EXPECT_THAT(html, Not(HasSubstr("https:")));
  EXPECT_THAT(html, Not(HasSubstr("<link")));
  // Every section opened is closed (the page is not cut short).
  const std::regex open("<section"), close("</section>");
  const auto count = [&](const std::regex& re) {
    return std::distance(std::sregex_iterator(html.begin(), html.end(), re), std::sregex_iterator());
  };
  EXPECT_EQ(count(open), count(close));
  EXPECT_GE(count(open), 7);
  EXPECT_EQ(page(), html) << "the same report gives the same bytes";
}

TEST_F(ReportPageTest, ShowsTheScenarioAndAGreenVerdictWithWhy) {
  const std::string html = page();
  EXPECT_THAT(html, HasSubstr("<h1>single.yaml</h1>"));
  EXPECT_THAT(html, HasSubstr("<code>" + scenario_.source.string() + "</code>"));
  EXPECT_THAT(html, HasSubstr("program <code>single.task</code>"));
  EXPECT_THAT(html, HasSubstr("cell <code>cell.yaml</code>"));
  EXPECT_THAT(html, HasSubstr("seed 1"));
  const std::string verdict = between(html, "<section class=\"verdict ", "</section>");
  EXPECT_THAT(verdict, HasSubstr("ok\" id=\"verdict\">\n<div class=\"word\">OK</div>"));
  EXPECT_THAT(verdict, HasSubstr("The run <b>finished</b> at t = 31.50&nbsp;s, 24 firings."));
  EXPECT_THAT(verdict, HasSubstr("Every expected outcome holds (1 of 1)."));
  EXPECT_THAT(verdict, HasSubstr("1 collision(s). 1 injected fault(s)."));
}

TEST_F(ReportPageTest, AFailedRunIsRedAndListsEveryFailure) {
  report_.outcome = "timeout";
  report_.reason = "sim time limit 120 s reached";
  report_.workpieces[0].ok = false;
  report_.workpieces[0].status = PartStatus::kElsewhere;
  report_.failures = {"the run did not finish: timeout", "workpiece A must end at mill_side (within 0.03 m) but is "
                                                         "elsewhere at (0.100, 0.200, 0.300)"};
  const std::string html = page();
  const std::string verdict = between(html, "<section class=\"verdict ", "</section>");
  EXPECT_THAT(verdict, HasSubstr("failed\" id=\"verdict\">\n<div class=\"word\">FAILED</div>"));
  EXPECT_THAT(verdict, HasSubstr("The run <b>timeout</b> at t = 31.50&nbsp;s, 24 firings: sim time limit 120 s "
                                 "reached."));
  EXPECT_THAT(verdict, HasSubstr("0 of 1 expected outcomes hold. Why it failed:"));
  EXPECT_THAT(verdict, HasSubstr("<li>the run did not finish: timeout</li>"));
  EXPECT_THAT(verdict, HasSubstr("<li>workpiece A must end at mill_side (within 0.03 m) but is elsewhere"));
  EXPECT_THAT(html, HasSubstr("<title>single.yaml &ndash; FAILED &ndash; twin run report</title>"));
  EXPECT_THAT(between(html, "<section id=\"parts\">", "</section>"), HasSubstr("<tr class=\"fail\"><td>A</td>"));
}

TEST_F(ReportPageTest, ComparesTheEstimateWithTheMeasuredCycleTimeInPerCent) {
  const std::string cycle = between(page(), "<section id=\"cycle\">", "</section>");
  EXPECT_THAT(cycle, HasSubstr("<td class=\"num\">29.00&nbsp;s</td><td class=\"num\">30.50&nbsp;s</td>"));
  // (30.5 - 29) / 29 = 5.17 %
  EXPECT_THAT(cycle, HasSubstr("+5.2&nbsp;% <span class=\"small\">(measured longer than estimated)</span>"));
  EXPECT_THAT(cycle, HasSubstr("Parts completed: <b>1</b>, throughput 2.50 parts/min."));
  EXPECT_THAT(cycle, Not(HasSubstr("Flow:"))) << "no flow of parts in this run";

  report_.finished_at = 27.55;
  EXPECT_THAT(page(), HasSubstr("-5.0&nbsp;% <span class=\"small\">(measured shorter than estimated)</span>"));
  report_.estimated_cycle_time.reset();
  const std::string without = between(page(), "<section id=\"cycle\">", "</section>");
  EXPECT_THAT(without, HasSubstr("<td class=\"num\">&ndash;</td><td class=\"num\">27.55&nbsp;s</td>"));
  EXPECT_THAT(without, Not(HasSubstr("&nbsp;%")));
}

TEST_F(ReportPageTest, ShowsTheFlowAndTheSteadyStateOfAShift) {
  report_.placed_at = {10, 20, 30, 40};
  report_.parts_fed = 5;
  report_.parts_delivered = 3;
  report_.steady_throughput = 6.0;
  report_.steady_cycle = 10.0;
  EXPECT_THAT(between(page(), "<section id=\"cycle\">", "</section>"),
              HasSubstr("Flow: 4 placed, 5 fed, 3 delivered. Steady state from the 2nd placement: <b>6.00 "
                        "parts/min</b>, 10.00&nbsp;s per part."));
}

TEST_F(ReportPageTest, ThepartsTableHasExpectedAgainstActualStateErrorAndTimes) {
  const std::string parts = between(page(), "<section id=\"parts\">", "</section>");
  const std::string a = between(parts, "<tr class=\"ok\"><td>A</td>", "</tr>");
  ASSERT_FALSE(a.empty()) << parts;
  EXPECT_THAT(a, HasSubstr("<td>mill_side <span class=\"small\">within 0.030&nbsp;m</span></td>"));
  EXPECT_THAT(a, HasSubstr("<td>mill_side <span class=\"small\">(also mill)</span><br><span class=\"small\">centre ("));
  EXPECT_THAT(a, HasSubstr("<span class=\"badge ok\">in_place</span>"));
  EXPECT_THAT(a, HasSubstr("<td class=\"num\">4.0&nbsp;mm</td>"));
  EXPECT_THAT(a, HasSubstr("<td class=\"num\">3.25&nbsp;s</td><td class=\"num\">27.75&nbsp;s</td>"
                           "<td class=\"num\">24.50&nbsp;s</td>"));
  // B has no expectation: no verdict colour, no error, no times.
  const std::string b = between(parts, "<tr><td>B</td>", "</tr>");
  ASSERT_FALSE(b.empty()) << parts;
  EXPECT_THAT(b, HasSubstr("<span class=\"badge\">elsewhere</span>"));
  EXPECT_THAT(b, Not(HasSubstr("mm</td>")));
}

TEST_F(ReportPageTest, ALostPartShowsWhenWhyAndWhereItWasLastSeen) {
  WorkpieceReport& a = report_.workpieces[0];
  a.ok = false;
  a.status = PartStatus::kLost;
  a.unaccounted = false;
  a.lost = LostPart{9.5, "not found after 2 re-grasps", Eigen::Vector3d(0.5, -0.25, 0.03)};
  const std::string parts = between(page(), "<section id=\"parts\">", "</section>");
  EXPECT_THAT(parts, HasSubstr("<span class=\"badge fail\">lost</span><br><span class=\"small\">declared lost at t = "
                               "9.50&nbsp;s (not found after 2 re-grasps); last seen at (0.500, -0.250, 0.030)"
                               "&nbsp;m</span>"));
  a.unaccounted = true;
  EXPECT_THAT(page(), HasSubstr("<span class=\"badge fail\">unaccounted</span>"));
}

TEST_F(ReportPageTest, RobotsShowBusyWaitingBlockedAndABarOfTheirShares) {
  const std::string robots = between(page(), "<section id=\"robots\">", "</section>");
  EXPECT_THAT(robots, HasSubstr("<td>r1 <span class=\"small\">(puma)</span></td><td class=\"num\">12</td>"
                                "<td class=\"num\">15.75&nbsp;s</td><td class=\"num\">3.15&nbsp;s</td>"
                                "<td class=\"num\">6.30&nbsp;s</td><td class=\"num\">6.30&nbsp;s</td>"));
  // 15.75 / 31.5 = 50 %, 3.15 / 31.5 = 10 %, 6.3 / 31.5 = 20 %.
  EXPECT_THAT(robots, HasSubstr("<span class=\"busy\" style=\"width:50.00%\"></span><span class=\"waiting\" "
                                "style=\"width:10.00%\"></span><span class=\"blocked\" style=\"width:20.00%\">"));
}

// A run with device events has a Devices section: the mill's busy / done / idle time, utilisation, cycles and the
// parts processed, a mill still busy at the end said so with its part not processed; the conveyors and sensors with
// their running / on time. A run without them has no such section.
TEST_F(ReportPageTest, DevicesShowTheMillsTimesUtilisationAndThePartsProcessed) {
  EXPECT_THAT(page(), Not(HasSubstr("id=\"devices\"")));
  const DeviceTimeline mill = test_reports::machine_figures("mill", 12.6, 3.15, 15.75, true, "idle");
  const DeviceTimeline belt = test_reports::switch_figures("input", "conveyor", 15.75, 15.75, 1, "stopped");
  report_.timeline.devices = {mill, belt};
  const std::string devices = between(page(), "<section id=\"devices\">", "</section>");
  EXPECT_THAT(devices, HasSubstr("<tr><td>mill</td><td class=\"num\">12.60&nbsp;s</td><td class=\"num\">3.15&nbsp;s"
                                 "</td><td class=\"num\">15.75&nbsp;s</td><td class=\"num\">40&nbsp;%</td>"
                                 "<td class=\"num\">1</td><td class=\"num\">1</td><td>A</td><td>idle</td>"));
  EXPECT_THAT(devices, HasSubstr("<td>input <span class=\"small\">(conveyor)</span></td><td class=\"num\">15.75&nbsp;s"
                                 "</td><td class=\"num\">15.75&nbsp;s</td><td class=\"num\">1</td><td>stopped</td>"));
  EXPECT_THAT(devices, HasSubstr("style=\"width:50.00%;background:#56b4e9\""));
  report_.timeline.devices[0].state = "busy";
  report_.timeline.devices[0].workpiece = "B";
  EXPECT_THAT(page(), HasSubstr("<span class=\"badge fail\">busy</span> with B (not processed)"));
}

TEST_F(ReportPageTest, CollisionsAndFaultsAreListedAndTheirAbsenceSaid) {
  std::string html = page();
  const std::string collisions = between(html, "<section id=\"collisions\">", "</section>");
  EXPECT_THAT(collisions, HasSubstr("<h2>Collisions (1)</h2>"));
  EXPECT_THAT(collisions, HasSubstr("<td class=\"num\">12.500&nbsp;s</td><td>puma/link5</td><td>melfa/base</td>"
                                    "<td class=\"num\">2.1&nbsp;mm</td>"));
  const std::string faults = between(html, "<section id=\"faults\">", "</section>");
  EXPECT_THAT(faults, HasSubstr("<h2>Faults (1 injected, 0 unexplained, 0 false alarms)</h2>"));
  EXPECT_THAT(faults, HasSubstr("<td><b>drop</b> on puma of A<br><span class=\"small\">released 0.10 s into the "
                                "move</span></td><td class=\"num\">8.00&nbsp;s</td>"));
  EXPECT_THAT(faults, HasSubstr("<span class=\"badge ok\">yes</span> at t = 8.20&nbsp;s: part_lost_in_transit by r1"));
  EXPECT_THAT(faults, HasSubstr("<td>cause dropped, action pick_again</td>"));
  EXPECT_THAT(faults, HasSubstr("<span class=\"badge ok\">yes</span> in 6.50&nbsp;s</td><td>no</td>"));

  report_.faults[0].detected = false;
  report_.faults[0].recovered = false;
  report_.faults[0].stopped_safely = true;
  Detection alarm;
  alarm.t = 14.0;
  alarm.robot = "r1";
  alarm.primitive = 3;
  alarm.symptom = "grip_lost";
  alarm.detail = "no part between the fingers";
  alarm.truth = "the twin has A between the fingers of puma";
  report_.false_alarms.push_back(alarm);
  html = page();
  EXPECT_THAT(html, HasSubstr("<span class=\"badge fail\">not detected</span>"));
  EXPECT_THAT(html, HasSubstr("<td>no</td><td>yes</td></tr>"));
  EXPECT_THAT(html, HasSubstr("<td class=\"num\">14.00&nbsp;s</td><td>r1</td><td>grip_lost</td><td>no part between the "
                              "fingers</td><td>the twin has A between the fingers of puma</td>"));

  report_.collisions.clear();
  report_.faults.clear();
  report_.false_alarms.clear();
  html = page();
  EXPECT_THAT(html, HasSubstr("<h2>Collisions (0)</h2>\n<p class=\"none\">No unintended contact.</p>"));
  EXPECT_THAT(html, HasSubstr("<p class=\"none\">No fault injected, none detected.</p>"));
}

// A fault the controller detected that no injection explains is listed as such, with its diagnosis: not a false alarm.
TEST_F(ReportPageTest, UnexplainedFaultsAreListedWithTheirDiagnosis) {
  Detection d;
  d.t = 21.0;
  d.robot = "r1";
  d.symptom = "driver_fault";
  d.detail = "the link closed";
  d.cause = "controller_fault";
  d.action = "reset_rehome";
  report_.unexplained.push_back(d);
  const std::string html = page();
  const std::string faults = between(html, "<section id=\"faults\">", "</section>");
  EXPECT_THAT(faults, HasSubstr("<h2>Faults (1 injected, 1 unexplained, 0 false alarms)</h2>"));
  EXPECT_THAT(faults, HasSubstr("<h3>Unexplained faults</h3>"));
  EXPECT_THAT(faults, HasSubstr("<td class=\"num\">21.00&nbsp;s</td><td>r1</td><td>driver_fault</td><td>the link "
                                "closed</td><td>cause controller_fault, action reset_rehome</td><td>no</td>"));
  EXPECT_THAT(faults, Not(HasSubstr("False alarms")));
  EXPECT_THAT(between(html, "<section class=\"verdict ", "</section>"), HasSubstr("1 unexplained fault(s)."));
}

// The header says what the run used (the report's setup: --perception and --driver included), not what the scenario
// file says: single.yaml's perception is truth.
TEST_F(ReportPageTest, ShowsThePerceptionDriversAndFaultsTheRunUsed) {
  report_.setup.perception = "cad";
  report_.setup.drivers = {{"puma", "val2", "/dev/ttyUSB1", false}};
  report_.setup.faults = {"drop:robot=puma,carry=1,after=0.3"};
  const std::string header = between(page(), "<header>", "</header>");
  EXPECT_THAT(header, HasSubstr("perception cad"));
  EXPECT_THAT(header, Not(HasSubstr("perception truth")));
  EXPECT_THAT(header, HasSubstr("drivers: puma real val2 on /dev/ttyUSB1"));
  EXPECT_THAT(header, HasSubstr("faults asked for: <code>drop:robot=puma,carry=1,after=0.3</code>"));
  report_.setup.drivers = {{"puma", "movemaster", "/tmp/link", true}};
  report_.setup.faults.clear();
  const std::string emulated = between(page(), "<header>", "</header>");
  EXPECT_THAT(emulated, HasSubstr("drivers: puma emulated movemaster on /tmp/link"));
  EXPECT_THAT(emulated, HasSubstr("faults asked for: none"));
}

TEST_F(ReportPageTest, EscapesEveryNameAndMessageFromTheUsersFiles) {
  const std::string evil = "<b>\"x\" & 'y'<b>";  // no '/': it is also a file name
  const std::string escaped = "&lt;b&gt;&quot;x&quot; &amp; 'y'&lt;b&gt;";
  scenario_.source = "/tmp/" + evil + ".yaml";
  scenario_.cell.name = evil;
  report_.reason = evil;
  report_.failures = {"workpiece " + evil + " is elsewhere"};
  report_.workpieces[0].name = evil;
  report_.workpieces[0].label = evil + "2";
  report_.workpieces[0].expected = evil;
  report_.workpieces[0].final_location = evil;
  report_.workpieces[0].at = {evil, evil};
  report_.workpieces[0].lost = LostPart{1.0, evil, std::nullopt};
  report_.timeline.robots[0].robot = evil;
  report_.timeline.robots[0].cell = evil;
  report_.collisions[0].a = evil;
  report_.faults[0].detail = evil;
  report_.faults[0].symptom = evil;
  report_.faults[0].cause = evil;
  report_.false_alarms.push_back({14.0, evil, 3, evil, evil, "", "", false, evil});
  ReportPageMedia media;
  media.video = "run " + evil + ".mp4";
  const std::string html = page(media);
  EXPECT_THAT(html, Not(HasSubstr(evil)));
  EXPECT_THAT(html, Not(HasSubstr("<b>\"x\"")));
  EXPECT_THAT(html, Not(HasSubstr("\"x\"")));
  EXPECT_THAT(html, HasSubstr("<h1>" + escaped + ".yaml</h1>"));
  EXPECT_THAT(html, HasSubstr("<li>workpiece " + escaped + " is elsewhere</li>"));
  EXPECT_THAT(html, HasSubstr("<video controls preload=\"metadata\" src=\"run " + escaped + ".mp4\">"));
  // Each escaped occurrence: the source (title, heading, path), cell name, reason, failure, part name, label,
  // expected, actual twice, lost reason, robot, its cell, collision, fault detail, symptom, cause, false alarm's
  // robot, symptom, detail and the twin's truth, the video's src, its fallback link (href and text), the link below it (href and text).
  std::size_t n = 0;
  for (auto at = html.find(escaped); at != std::string::npos; at = html.find(escaped, at + 1)) ++n;
  EXPECT_EQ(n, 27u);
  EXPECT_EQ(escape_html("a<b>&\"c\"\n"), "a&lt;b&gt;&amp;&quot;c&quot;&#10;");
}

TEST_F(ReportPageTest, EmbedsThePicturesAsDataUrisOfTheirBytes) {
  ReportPageMedia media;
  // Any bytes (the page does not decode them): all 256 byte values, and an odd length for base64's padding.
  for (int i = 0; i < 256; ++i) media.gantt_png += static_cast<char>(i);
  media.final_png = "\x89PNG\r\n\x1a\nfinal";
  const std::string html = page(media);
  const std::string gantt = between(html, "<section id=\"gantt\">", "</section>");
  const std::string gantt64 = between(gantt, "<img src=\"data:image/png;base64,", "\"");
  ASSERT_FALSE(gantt64.empty()) << gantt;
  const std::vector<unsigned char> gantt_bytes = YAML::DecodeBase64(gantt64);
  EXPECT_EQ(std::string(gantt_bytes.begin(), gantt_bytes.end()), media.gantt_png);
  EXPECT_THAT(gantt, HasSubstr("alt=\"Gantt chart\""));
  EXPECT_THAT(gantt, HasSubstr("<a href=\"gantt.png\">gantt.png</a>"));
  const std::string final64 =
      between(between(html, "<section id=\"final\">", "</section>"), "<img src=\"data:image/png;base64,", "\"");
  const std::vector<unsigned char> final_bytes = YAML::DecodeBase64(final64);
  EXPECT_EQ(std::string(final_bytes.begin(), final_bytes.end()), media.final_png);
  EXPECT_EQ(final64.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/="),
            std::string::npos)
      << "no line breaks or other characters inside the URI";
  EXPECT_THAT(html, Not(HasSubstr("<video"))) << "no video recorded";

  const std::string bare = page();
  EXPECT_THAT(bare, Not(HasSubstr("<img")));
  EXPECT_THAT(bare, HasSubstr("<p class=\"none\">No Gantt chart was made for this run.</p>"));
  EXPECT_THAT(bare, HasSubstr("<p class=\"none\">No final snapshot was made for this run.</p>"));
}

TEST_F(ReportPageTest, TheVideoPlaysFromItsFileBesideThePage) {
  ReportPageMedia media;
  media.video = std::filesystem::path("video") / "run.mp4";
  const std::string video = between(page(media), "<section id=\"video\">", "</section>");
  EXPECT_THAT(video, HasSubstr("<video controls preload=\"metadata\" src=\"video/run.mp4\">"));
  EXPECT_THAT(video, HasSubstr("<a href=\"video/run.mp4\">video/run.mp4</a>"));
  EXPECT_THAT(video, Not(HasSubstr("data:")));
}

// write_report_outputs (run.hpp) writes index.html beside the other files, with their very bytes in it.
TEST_F(ReportPageTest, TheOutputDirectoryGetsThePageWithThePicturesWrittenBesideIt) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("cw-report-page-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const cv::Mat final_image(60, 80, CV_8UC3, cv::Scalar(40, 120, 200));
  write_report_outputs(dir, scenario_, report_, final_image, std::filesystem::path("run.mp4"));
  const std::string html = read_file(dir / kPageFile);
  EXPECT_EQ(html, render_report_page(scenario_, report_,
                                     {read_file(dir / kGanttFile), read_file(dir / kFinalFile), "run.mp4"}));
  const std::vector<unsigned char> final_bytes = YAML::DecodeBase64(
      between(between(html, "<section id=\"final\">", "</section>"), "<img src=\"data:image/png;base64,", "\""));
  EXPECT_EQ(std::string(final_bytes.begin(), final_bytes.end()), read_file(dir / kFinalFile));
  EXPECT_THAT(html, HasSubstr("src=\"run.mp4\""));
  // No temporary file left behind.
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path().filename().string());
  // ... and the marker that makes the directory Cellwright's (outputs.hpp), written first.
  EXPECT_THAT(files, ::testing::UnorderedElementsAre(kMarkerFile, "report.json", "gantt.png", "final.png", "index.html"));

  // Without a snapshot the page says so (and an old final.png is not shown).
  write_report_outputs(dir, scenario_, report_, cv::Mat());
  const std::string bare = read_file(dir / kPageFile);
  EXPECT_THAT(bare, HasSubstr("No final snapshot was made for this run."));
  EXPECT_THAT(bare, Not(HasSubstr("<video")));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cellwright::cell
