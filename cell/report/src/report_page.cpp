// index.html (report_page.hpp): the report laid out as one self-contained HTML page, built as text with fmt; every
// user string through escape_html, every picture a data: URI.
#include "cellwright/cell/report_page.hpp"

#include <fmt/format.h>
#include <yaml-cpp/binary.h>

#include <algorithm>
#include <cmath>
#include <string_view>

#include "cellwright/common/xml.hpp"
#include "cellwright/cell/outputs.hpp"

namespace cellwright::cell {
namespace {

// The Gantt chart's colours (gantt.cpp), so that the robots' bars read like the chart.
constexpr const char* kStyle = R"(
:root { --ok: #1a7f37; --fail: #c62828; --busy: #0072b2; --grip: #e69f00; --wait: #c8c8c8; --blocked: #cc3c78;
        --line: #d0d7de; --muted: #57606a; }
* { box-sizing: border-box; -webkit-print-color-adjust: exact; print-color-adjust: exact; }
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", "DejaVu Sans", sans-serif; color: #1f2328;
       max-width: 1200px; margin: 0 auto; padding: 16px 24px 40px; }
h1 { font-size: 1.7em; margin: 0.2em 0 0; word-break: break-all; }
h2 { font-size: 1.2em; border-bottom: 1px solid var(--line); padding-bottom: 3px; margin: 1.6em 0 0.6em; }
code { font: 0.92em ui-monospace, "DejaVu Sans Mono", monospace; word-break: break-all; }
.meta { color: var(--muted); margin: 0.3em 0 1em; }
.verdict { border: 3px solid; border-radius: 8px; padding: 10px 18px; margin: 12px 0; }
.verdict.ok { border-color: var(--ok); background: #e9f7ee; }
.verdict.failed { border-color: var(--fail); background: #fdecea; }
.verdict .word { font-size: 2.6em; font-weight: 800; letter-spacing: 0.04em; line-height: 1.1; }
.verdict.ok .word { color: var(--ok); }
.verdict.failed .word { color: var(--fail); }
.verdict p { margin: 0.3em 0; }
.verdict ul { margin: 0.3em 0 0.2em; padding-left: 1.3em; }
table { border-collapse: collapse; margin: 0.4em 0; }
th, td { border: 1px solid var(--line); padding: 4px 9px; text-align: left; vertical-align: top; }
th { background: #f6f8fa; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.fail td { background: #fdecea; }
tr.ok td:first-child { border-left: 4px solid var(--ok); }
tr.fail td:first-child { border-left: 4px solid var(--fail); }
.badge { display: inline-block; padding: 0 6px; border-radius: 4px; font-size: 0.85em; font-weight: 600;
         background: #eaeef2; }
.badge.ok { background: #d1f0da; color: #0f5323; }
.badge.fail { background: #ffd8d3; color: #8a1c1c; }
.small { font-size: 0.86em; color: var(--muted); }
.none { color: var(--muted); font-style: italic; }
.bar { display: flex; width: 260px; height: 14px; border: 1px solid #999; background: #fff; }
.bar span { display: block; height: 100%; }
.bar .busy, .key.busy { background: var(--busy); }
.bar .waiting, .key.waiting { background: var(--wait); }
.bar .blocked, .key.blocked { background: var(--blocked); }
.key { display: inline-block; width: 12px; height: 12px; border: 1px solid #999; vertical-align: -1px;
       margin: 0 3px 0 10px; }
.key.idle { background: #fff; }
figure { margin: 0.5em 0; }
figure img, video { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { color: var(--muted); font-size: 0.9em; }
footer { margin-top: 2em; color: var(--muted); font-size: 0.9em; border-top: 1px solid var(--line); }
@media print {
  body { max-width: none; padding: 0; font-size: 11pt; }
  section, figure, tr { break-inside: avoid; }
  h2 { break-after: avoid; }
  video { display: none; }
}
)";

std::string esc(std::string_view s) { return escape_html(s); }

std::string seconds(double t) { return fmt::format("{:.2f}&nbsp;s", t); }
std::string seconds(const std::optional<double>& t) { return t ? seconds(*t) : std::string("&ndash;"); }

std::string position(const Eigen::Vector3d& p) { return fmt::format("({:.3f}, {:.3f}, {:.3f})&nbsp;m", p.x(), p.y(), p.z()); }

const char* none_cell() { return "<span class=\"none\">&ndash;</span>"; }

// How far the part is from the point of the cell location it is expected at: from its bottom centre (taken upright,
// as places_of does for the judgement) to the location's point. Nothing for other places (a conveyor's belt or a
// machine is a surface, not a point), parts without a final position, and the "lost" expectation.
std::optional<double> error_distance(const Scenario& s, const WorkpieceReport& w) {
  if (!w.expected || w.status == PartStatus::kNotArrived || w.final_location == "unknown" ||
      w.final_location == "not in the cell") {
    return std::nullopt;
  }
  const models::LocationSpec* loc = s.cell.find_location(*w.expected);
  const models::WorkpieceSpec* spec = s.cell.find_workpiece(w.name);
  if (loc == nullptr || spec == nullptr) return std::nullopt;
  const Eigen::Vector3d bottom = w.position - Eigen::Vector3d(0, 0, spec->size.z() / 2);
  return (bottom - loc->pose.xyz).norm();
}

std::string data_uri(const std::string& png) {
  return "data:image/png;base64," +
         YAML::EncodeBase64(reinterpret_cast<const unsigned char*>(png.data()), png.size());
}

void header(std::string& out, const Scenario& s, const Report& r) {
  const std::string name = s.source.filename().string();
  out += fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<meta name=\"generator\" content=\"cellwright twin\">\n"
      "<title>{} &ndash; {} &ndash; twin run report</title>\n<style>{}</style>\n</head>\n<body>\n",
      esc(name), r.ok() ? "OK" : "FAILED", kStyle);
  out += fmt::format("<header>\n<h1>{}</h1>\n", esc(name));
  // What the run used (the command line's overrides included), from the report, not from the scenario file.
  std::string drivers;
  for (const DriverUse& d : r.setup.drivers) drivers += (drivers.empty() ? "" : ", ") + esc(describe_driver(d));
  std::string faults;
  for (const std::string& f : r.setup.faults) faults += (faults.empty() ? "" : ", ") + fmt::format("<code>{}</code>", esc(f));
  if (drivers.empty()) drivers = "none";
  if (faults.empty()) faults = "none";
  out += fmt::format(
      "<p class=\"meta\">scenario <code>{}</code><br>program <code>{}</code> &middot; cell <code>{}</code>{} &middot; "
      "seed {} &middot; perception {}<br>drivers: {}<br>faults asked for: {}{}</p>\n</header>\n",
      esc(s.source.string()), esc(s.program_file.filename().string()), esc(s.cell_file.filename().string()),
      s.cell.name.empty() ? std::string() : fmt::format(" ({})", esc(s.cell.name)), s.seed, esc(r.setup.perception),
      drivers, faults,
      r.setup.parts_from_model ? "<br>parts: where " + esc(describe_parts_source(r.setup)) + " has them"
                               : std::string());
}

void verdict(std::string& out, const Report& r) {
  const bool ok = r.ok();
  out += fmt::format("<section class=\"verdict {}\" id=\"verdict\">\n<div class=\"word\">{}</div>\n",
                     ok ? "ok" : "failed", ok ? "OK" : "FAILED");
  out += fmt::format("<p>The run <b>{}</b> at t = {}, {} firings{}.</p>\n", esc(r.outcome), seconds(r.end_time),
                     r.firings, r.reason.empty() ? std::string() : fmt::format(": {}", esc(r.reason)));
  const auto expected = static_cast<std::size_t>(
      std::count_if(r.workpieces.begin(), r.workpieces.end(), [](const WorkpieceReport& w) { return w.ok; }));
  const auto holding = static_cast<std::size_t>(std::count_if(
      r.workpieces.begin(), r.workpieces.end(), [](const WorkpieceReport& w) { return w.ok && *w.ok; }));
  if (ok) {
    out += fmt::format("<p>Every expected outcome holds ({} of {}).</p>\n", holding, expected);
  } else {
    out += fmt::format("<p>{} of {} expected outcomes hold. Why it failed:</p>\n<ul class=\"why\">\n", holding,
                       expected);
    for (const std::string& f : r.failures) out += fmt::format("<li>{}</li>\n", esc(f));
    out += "</ul>\n";
  }
  const std::size_t unaccounted = r.unaccounted();
  if (!r.collisions.empty() || !r.faults.empty() || !r.unexplained.empty() || unaccounted > 0 || r.stopped_at) {
    std::string notes;
    if (!r.collisions.empty()) notes += fmt::format(" {} collision(s).", r.collisions.size());
    if (!r.faults.empty()) notes += fmt::format(" {} injected fault(s).", r.faults.size());
    if (!r.unexplained.empty()) notes += fmt::format(" {} unexplained fault(s).", r.unexplained.size());
    if (unaccounted > 0) notes += fmt::format(" {} part(s) unaccounted.", unaccounted);
    if (r.stopped_at) notes += fmt::format(" The cell was stopped at t = {}.", seconds(*r.stopped_at));
    out += fmt::format("<p class=\"small\">{}</p>\n", notes.substr(1));
  }
  out += "</section>\n";
}

void cycle(std::string& out, const Report& r) {
  out += "<section id=\"cycle\">\n<h2>Cycle time</h2>\n<table>\n";
  out += "<tr><th>estimated before the run</th><th>measured (the program's last firing)</th><th>difference</th></tr>\n";
  std::string diff = none_cell();
  if (r.estimated_cycle_time && r.finished_at && *r.estimated_cycle_time > 0) {
    const double pct = (*r.finished_at - *r.estimated_cycle_time) / *r.estimated_cycle_time * 100.0;
    diff = fmt::format("{:+.1f}&nbsp;% <span class=\"small\">(measured {} than estimated)</span>", pct,
                       pct >= 0 ? "longer" : "shorter");
  }
  out += fmt::format("<tr><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{}</td></tr>\n</table>\n",
                     seconds(r.estimated_cycle_time), seconds(r.finished_at), diff);
  if (r.parts_completed > 0) {
    out += fmt::format("<p>Parts completed: <b>{}</b>, throughput {} parts/min.</p>\n", r.parts_completed,
                       r.throughput ? fmt::format("{:.2f}", *r.throughput) : std::string("&ndash;"));
  }
  if (r.parts_fed > 0 || r.parts_delivered > 0 || r.steady_throughput) {
    out += fmt::format("<p>Flow: {} placed, {} fed, {} delivered.", r.placed_at.size(), r.parts_fed,
                       r.parts_delivered);
    if (r.steady_throughput && r.steady_cycle) {
      out += fmt::format(" Steady state from the 2nd placement: <b>{:.2f} parts/min</b>, {} per part.",
                         *r.steady_throughput, seconds(*r.steady_cycle));
    }
    out += "</p>\n";
  }
  out += "</section>\n";
}

// Coordinated blocks (only for a program with them, so that the other pages stay as they were): per segment when
// the master and the follower started and ended it, and the skews.
void coordination(std::string& out, const Report& r) {
  if (r.segments.empty()) return;
  const auto ms = [](const std::optional<double>& t) {
    return t ? fmt::format("{:.0f}&nbsp;ms", *t * 1000.0) : std::string("&ndash;");
  };
  out += "<section id=\"coordination\">\n<h2>Coordinated segments</h2>\n";
  out += fmt::format("<p>Start skew at most <b>{}</b>, end skew at most <b>{}</b> (the two robots' command starts and "
                     "ends).</p>\n",
                     ms(r.max_start_skew), ms(r.max_end_skew));
  out += "<table>\n<tr><th>segment</th><th>command</th><th class=\"num\">start (master, follower)</th>"
         "<th class=\"num\">end (master, follower)</th><th class=\"num\">start skew</th>"
         "<th class=\"num\">end skew</th></tr>\n";
  for (const SegmentTiming& g : r.segments) {
    out += fmt::format(
        "<tr><td>{} {}{}</td><td>{}</td><td class=\"num\">{}, {}</td><td class=\"num\">{}, {}</td>"
        "<td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
        esc(g.block), g.index, g.run > 0 ? fmt::format(" (run {})", g.run + 1) : std::string(), esc(g.command),
        seconds(g.master_start), seconds(g.follower_start), seconds(g.master_end), seconds(g.follower_end),
        ms(g.start_skew), ms(g.end_skew));
  }
  out += "</table>\n</section>\n";
}

std::string state_cell(const WorkpieceReport& w) {
  const bool good = w.status == PartStatus::kInPlace || (w.expected == kLostPlace && w.ok && *w.ok);
  std::string s = fmt::format("<span class=\"badge{}\">{}</span>",
                              good ? " ok" : (w.ok && !*w.ok ? " fail" : ""), to_string(w.status));
  if (w.unaccounted) s += " <span class=\"badge fail\">unaccounted</span>";
  if (w.lost) {
    s += fmt::format("<br><span class=\"small\">declared lost at t = {}{}; last seen {}</span>", seconds(w.lost->t),
                     w.lost->reason.empty() ? std::string() : " (" + esc(w.lost->reason) + ")",
                     w.lost->last_seen ? "at " + position(*w.lost->last_seen) : std::string("nowhere"));
  }
  return s;
}

void parts(std::string& out, const Scenario& s, const Report& r) {
  out += "<section id=\"parts\">\n<h2>Parts</h2>\n";
  if (r.workpieces.empty()) {
    out += "<p class=\"none\">The cell has no workpieces.</p>\n</section>\n";
    return;
  }
  out += "<table>\n<tr><th>part</th><th>expected</th><th>actual</th><th>state</th><th class=\"num\">error</th>"
         "<th class=\"num\">picked</th><th class=\"num\">placed</th><th class=\"num\">cycle</th></tr>\n";
  for (const WorkpieceReport& w : r.workpieces) {
    const char* row = !w.ok ? "" : (*w.ok ? " class=\"ok\"" : " class=\"fail\"");
    std::string part = esc(w.name);
    if (!w.label.empty() && w.label != w.name) part += fmt::format(" <span class=\"small\">({})</span>", esc(w.label));
    std::string expected = none_cell();
    if (w.expected) {
      expected = *w.expected == kLostPlace
                     ? std::string("declared lost")
                     : fmt::format("{} <span class=\"small\">within {:.3f}&nbsp;m</span>", esc(*w.expected),
                                   w.tolerance);
    }
    std::string actual = esc(w.final_location);
    if (w.at.size() > 1) {
      std::string also;
      for (std::size_t i = 1; i < w.at.size(); ++i) also += (i > 1 ? ", " : "") + esc(w.at[i]);
      actual += fmt::format(" <span class=\"small\">(also {})</span>", also);
    }
    if (w.final_location != "unknown" && w.final_location != "not in the cell") {
      actual += fmt::format("<br><span class=\"small\">centre {}</span>", position(w.position));
    }
    const std::optional<double> error = error_distance(s, w);
    out += fmt::format(
        "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
        "<td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
        row, part, expected, actual, state_cell(w),
        error ? fmt::format("{:.1f}&nbsp;mm", *error * 1000.0) : std::string(none_cell()), seconds(w.pick_start),
        seconds(w.place_end), seconds(w.cycle_time));
  }
  out += "</table>\n<p class=\"small\">error: from the part's bottom centre to the point of the cell location it is "
         "expected at. picked: the first command of its Pick; placed: the end of the Place that released it; "
         "cycle: placed minus picked.</p>\n</section>\n";
}

void robots(std::string& out, const Report& r) {
  out += "<section id=\"robots\">\n<h2>Robots</h2>\n";
  if (r.timeline.robots.empty()) {
    out += "<p class=\"none\">No robot timeline (the log has no run_start).</p>\n</section>\n";
    return;
  }
  const double span = std::max(r.timeline.end, 1e-9);
  out += "<table>\n<tr><th>robot</th><th class=\"num\">commands</th><th class=\"num\">busy</th>"
         "<th class=\"num\">waiting</th><th class=\"num\">blocked</th><th class=\"num\">idle</th><th>share of the "
         "run</th></tr>\n";
  for (const RobotTimeline& t : r.timeline.robots) {
    auto pct = [&](double v) { return std::clamp(v / span * 100.0, 0.0, 100.0); };
    out += fmt::format(
        "<tr><td>{} <span class=\"small\">({})</span></td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
        "<td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td><div class=\"bar\" "
        "title=\"busy {:.0f}%, waiting {:.0f}%, blocked {:.0f}%, idle {:.0f}%\"><span class=\"busy\" "
        "style=\"width:{:.2f}%\"></span><span class=\"waiting\" style=\"width:{:.2f}%\"></span><span "
        "class=\"blocked\" style=\"width:{:.2f}%\"></span></div></td></tr>\n",
        esc(t.robot), esc(t.cell), t.commands, seconds(t.busy), seconds(t.waiting), seconds(t.blocked),
        seconds(t.idle), pct(t.busy), pct(t.waiting), pct(t.blocked), pct(t.idle), pct(t.busy), pct(t.waiting),
        pct(t.blocked));
  }
  out += "</table>\n<p class=\"small\"><span class=\"key busy\"></span>busy (moving or gripping)"
         "<span class=\"key waiting\"></span>waiting for another robot's signal"
         "<span class=\"key blocked\"></span>blocked (done, its next transition not fired yet)"
         "<span class=\"key idle\"></span>idle (before its first command, after its last)</p>\n</section>\n";
}

// The devices (only for a log with device events, so that a page without them is what it was): the machines with
// their times, utilisation, cycles and the parts processed, then the conveyors and sensors; the bars in the Gantt
// chart's device colours (gantt.cpp), inline so that the page's style sheet stays as it was.
void devices(std::string& out, const Report& r) {
  if (r.timeline.devices.empty()) return;
  const double span = std::max(r.timeline.end, 1e-9);
  auto pct = [&](double v) { return std::clamp(v / span * 100.0, 0.0, 100.0); };
  out += "<section id=\"devices\">\n<h2>Devices</h2>\n";
  const bool machines = std::any_of(r.timeline.devices.begin(), r.timeline.devices.end(),
                                    [](const DeviceTimeline& d) { return d.kind == "machine"; });
  if (machines) {
    out += "<table>\n<tr><th>machine</th><th class=\"num\">busy</th><th class=\"num\">done, waiting</th>"
           "<th class=\"num\">idle</th><th class=\"num\">utilisation</th><th class=\"num\">cycles started</th>"
           "<th class=\"num\">cycles finished</th><th>parts processed</th><th>at the end</th><th>share of the run</th>"
           "</tr>\n";
    for (const DeviceTimeline& d : r.timeline.devices) {
      if (d.kind != "machine") continue;
      std::string parts;
      for (const std::string& p : d.processed) parts += (parts.empty() ? "" : ", ") + esc(p);
      std::string end = esc(d.state);
      if (d.state == "busy") {
        end = fmt::format("<span class=\"badge fail\">busy</span>{} (not processed)",
                          d.workpiece.empty() ? std::string() : " with " + esc(d.workpiece));
      } else if (!d.workpiece.empty()) {
        end += " with " + esc(d.workpiece);
      }
      out += fmt::format(
          "<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
          "<td class=\"num\">{:.0f}&nbsp;%</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{}</td>"
          "<td>{}</td><td><div class=\"bar\" title=\"busy {:.0f}%, done {:.0f}%, idle {:.0f}%\"><span "
          "style=\"width:{:.2f}%;background:#d55e00\"></span><span style=\"width:{:.2f}%;background:#009e73\">"
          "</span></div></td></tr>\n",
          esc(d.device), seconds(d.busy), seconds(d.done), seconds(d.idle), d.utilisation * 100.0, d.cycles_started,
          d.cycles_finished, parts.empty() ? std::string(none_cell()) : parts, end, pct(d.busy), pct(d.done),
          pct(d.idle), pct(d.busy), pct(d.done));
    }
    out += "</table>\n<p class=\"small\"><span class=\"key\" style=\"background:#d55e00\"></span>busy (its "
           "cycle runs)<span class=\"key\" style=\"background:#009e73\"></span>done (the processed part waits to "
           "be taken out)<span class=\"key idle\"></span>idle. A part is processed when the machine went from busy "
           "to done with it in.</p>\n";
  }
  if (!std::all_of(r.timeline.devices.begin(), r.timeline.devices.end(),
                   [](const DeviceTimeline& d) { return d.kind == "machine"; })) {
    out += "<table>\n<tr><th>device</th><th class=\"num\">running / on</th><th class=\"num\">stopped / off</th>"
           "<th class=\"num\">started / came on</th><th>at the end</th><th>share of the run</th></tr>\n";
    for (const DeviceTimeline& d : r.timeline.devices) {
      if (d.kind == "machine") continue;
      const bool conveyor = d.kind == "conveyor";
      const double active = conveyor ? d.running : d.on;
      const char* colour = conveyor ? "#56b4e9" : "#505050";
      out += fmt::format(
          "<tr><td>{} <span class=\"small\">({})</span></td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
          "<td class=\"num\">{}</td><td>{}</td><td><div class=\"bar\" title=\"{} {:.0f}%\"><span "
          "style=\"width:{:.2f}%;background:{}\"></span></div></td></tr>\n",
          esc(d.device), esc(d.kind), seconds(active), seconds(conveyor ? d.stopped : d.off), d.starts, esc(d.state),
          conveyor ? "running" : "on", pct(active), pct(active), colour);
    }
    out += "</table>\n";
  }
  out += "</section>\n";
}

void collisions(std::string& out, const Report& r) {
  out += fmt::format("<section id=\"collisions\">\n<h2>Collisions ({})</h2>\n", r.collisions.size());
  if (r.collisions.empty()) {
    out += "<p class=\"none\">No unintended contact.</p>\n</section>\n";
    return;
  }
  out += "<table>\n<tr><th class=\"num\">t</th><th>body</th><th>body</th><th class=\"num\">depth</th></tr>\n";
  for (const auto& c : r.collisions) {
    out += fmt::format("<tr><td class=\"num\">{:.3f}&nbsp;s</td><td>{}</td><td>{}</td><td class=\"num\">{:.1f}&nbsp;mm"
                       "</td></tr>\n",
                       c.t, esc(c.a), esc(c.b), c.depth * 1000.0);
  }
  out += "</table>\n</section>\n";
}

// The coordinated carries as the twin measured them; no section in a run without one.
void carries(std::string& out, const Report& r) {
  if (r.carries.empty()) return;
  out += fmt::format("<section id=\"carries\">\n<h2>Coordinated carries ({})</h2>\n", r.carries.size());
  out += "<p class=\"small\">Measured by the twin every control period while both hands hold the part: the internal "
         "(squeeze) force along it from the two wrist force sensors (&gt; 0 pushing the ends together), the relative "
         "tool error (the second robot's tool against the grasp transform taken when both held it) and the part's "
         "tilt from horizontal.</p>\n";
  out += "<table>\n<tr><th>part</th><th>robots</th><th class=\"num\">from</th><th class=\"num\">to</th>"
         "<th class=\"num\">peak squeeze</th><th class=\"num\">relative tool error</th><th class=\"num\">turn</th>"
         "<th class=\"num\">tilt</th></tr>\n";
  for (const CarryReport& c : r.carries) {
    out += fmt::format(
        "<tr><td>{}</td><td>{}, {}</td><td class=\"num\">{:.2f}&nbsp;s</td><td class=\"num\">{:.2f}&nbsp;s</td>"
        "<td class=\"num\">{:.1f}&nbsp;N at {:.2f}&nbsp;s</td><td class=\"num\">{:.1f}&nbsp;mm at {:.2f}&nbsp;s</td>"
        "<td class=\"num\">{:.2f}&deg;</td><td class=\"num\">{:.2f}&deg; at {:.2f}&nbsp;s</td></tr>\n",
        esc(c.workpiece), esc(c.a), esc(c.b), c.start, c.end, c.peak_squeeze, c.peak_squeeze_t, c.max_error,
        c.max_error_t, c.max_turn, c.max_tilt, c.max_tilt_t);
  }
  out += "</table>\n</section>\n";
}

void faults(std::string& out, const Report& r) {
  out += fmt::format("<section id=\"faults\">\n<h2>Faults ({} injected, {} unexplained, {} false alarms)</h2>\n",
                     r.faults.size(), r.unexplained.size(), r.false_alarms.size());
  if (r.faults.empty() && r.false_alarms.empty() && r.unexplained.empty()) {
    out += "<p class=\"none\">No fault injected, none detected.</p>\n</section>\n";
    return;
  }
  if (!r.faults.empty()) {
    out += "<table>\n<tr><th>fault</th><th class=\"num\">injected</th><th>detected</th><th>diagnosis</th>"
           "<th>recovered</th><th>stopped safely</th></tr>\n";
    for (const FaultReport& f : r.faults) {
      std::string what = "<b>" + esc(f.kind) + "</b>";
      if (!f.robot.empty()) what += " on " + esc(f.robot);
      if (!f.workpiece.empty()) what += " of " + esc(f.workpiece);
      if (!f.detail.empty()) what += fmt::format("<br><span class=\"small\">{}</span>", esc(f.detail));
      const std::string detected =
          f.detected ? fmt::format("<span class=\"badge ok\">yes</span> at t = {}: {}{}", seconds(f.detected_at),
                                   esc(f.symptom), f.detected_by.empty() ? "" : " by " + esc(f.detected_by))
                     : std::string("<span class=\"badge fail\">not detected</span>");
      const std::string diagnosis = f.cause.empty() && f.action.empty()
                                        ? std::string(none_cell())
                                        : fmt::format("cause {}, action {}", esc(f.cause), esc(f.action));
      const std::string recovered =
          f.recovered ? fmt::format("<span class=\"badge ok\">yes</span> in {}", seconds(f.recovery_time))
                      : std::string("no");
      out += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                         what, seconds(f.t), detected, diagnosis, recovered, f.stopped_safely ? "yes" : "no");
    }
    out += "</table>\n";
  }
  if (!r.unexplained.empty()) {
    out += "<h3>Unexplained faults</h3>\n<p class=\"small\">Detected by the controller, explained by no injected "
           "fault: something really went wrong.</p>\n<table>\n<tr><th class=\"num\">t</th><th>detected by</th>"
           "<th>symptom</th><th>detail</th><th>diagnosis</th><th>recovered</th></tr>\n";
    for (const Detection& d : r.unexplained) {
      out += fmt::format(
          "<tr class=\"fail\"><td class=\"num\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
          seconds(d.t), d.robot.empty() ? std::string("the cell") : esc(d.robot), esc(d.symptom), esc(d.detail),
          d.cause.empty() && d.action.empty() ? std::string(none_cell())
                                              : fmt::format("cause {}, action {}", esc(d.cause), esc(d.action)),
          d.recovered ? "<span class=\"badge ok\">yes</span>" : "no");
    }
    out += "</table>\n";
  }
  if (!r.false_alarms.empty()) {
    out += "<h3>False alarms</h3>\n<p class=\"small\">Detected by the controller while the twin's truth shows "
           "nothing physically wrong.</p>\n<table>\n<tr><th class=\"num\">t</th><th>robot</th><th>symptom</th>"
           "<th>detail</th><th>the twin's truth</th></tr>\n";
    for (const Detection& d : r.false_alarms) {
      out += fmt::format("<tr><td class=\"num\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                         seconds(d.t), d.robot.empty() ? std::string("the cell") : esc(d.robot), esc(d.symptom),
                         esc(d.detail), esc(d.truth));
    }
    out += "</table>\n";
  }
  out += "</section>\n";
}

void picture(std::string& out, const char* id, const char* title, const std::string& png, const char* alt,
             const char* caption, const char* file) {
  out += fmt::format("<section id=\"{}\">\n<h2>{}</h2>\n", id, title);
  if (png.empty()) {
    out += fmt::format("<p class=\"none\">No {} was made for this run.</p>\n</section>\n", alt);
    return;
  }
  out += fmt::format("<figure>\n<img src=\"{}\" alt=\"{}\">\n<figcaption>{} (<a href=\"{}\">{}</a>)</figcaption>\n"
                     "</figure>\n</section>\n",
                     data_uri(png), alt, caption, file, file);
}

void video(std::string& out, const std::optional<std::filesystem::path>& file) {
  if (!file) return;
  const std::string src = esc(file->generic_string());
  out += fmt::format(
      "<section id=\"video\">\n<h2>Video</h2>\n<video controls preload=\"metadata\" src=\"{}\">Your browser cannot "
      "play the video: <a href=\"{}\">{}</a></video>\n<p class=\"small\">The run as the overview camera saw it "
      "(<a href=\"{}\">{}</a>, beside this page).</p>\n</section>\n",
      src, src, src, src, src);
}

}  // namespace

std::string escape_html(std::string_view text) { return xml::Writer::escape_attribute(text); }

std::string render_report_page(const Scenario& scenario, const Report& report, const ReportPageMedia& media) {
  std::string out;
  out.reserve(32 * 1024 + (media.gantt_png.size() + media.final_png.size()) * 4 / 3);
  header(out, scenario, report);
  verdict(out, report);
  cycle(out, report);
  coordination(out, report);
  parts(out, scenario, report);
  robots(out, report);
  devices(out, report);
  carries(out, report);
  collisions(out, report);
  faults(out, report);
  std::string gantt_caption =
      "Each robot's commands over time: move (blue), grip (orange), wait for the part (yellow), wait for a "
      "signal (grey), blocked (red-purple); each workpiece's journey marked: picked (green), handed over "
      "(purple), placed (black)";
  if (!report.timeline.devices.empty()) {
    gantt_caption += "; below them a row per device: a machine busy (vermillion) and done (green), a conveyor running "
                     "(sky blue), a sensor on (dark grey)";
  }
  picture(out, "gantt", "Gantt chart", media.gantt_png, "Gantt chart", gantt_caption.c_str(), kGanttFile);
  picture(out, "final", "Final snapshot", media.final_png, "final snapshot",
          "The overview camera's view of the cell at the end of the run", kFinalFile);
  video(out, media.video);
  out += fmt::format("<footer>\n<p>Beside this page: <a href=\"{0}\">{0}</a> (every event of the run), "
                     "<a href=\"{1}\">{1}</a> (this report as data).</p>\n</footer>\n</body>\n</html>\n",
                     kEventsFile, kReportFile);
  return out;
}

}  // namespace cellwright::cell
