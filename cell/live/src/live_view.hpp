// The view-only parts of the live view's "cell" and "frame" messages (cell/live/live.hpp, docs/live-view.md): what
// the 3D page draws beside the robots and parts. Private to cellwright_cell_live; live.cpp's live_cell_json and
// live_frame_json add them to their messages.
//
//   cell  "cameras": [{"name", "pos":[x,y,z], "quat":[qw,qx,qy,qz] (MuJoCo's camera frame: it looks along its -z,
//                      y up), "fovy" (degrees, the image's height), "resolution":[w,h] (the cell description's)}]
//   frame "marks":   [{"kind":"fault"|"collision", "text" (the event-log line), "pos":[x,y,z]}] one per fault line
//                     given: a collision at the contact point of its two bodies (or half-way between them when they no
//                     longer touch), a fault at its robot's tool (or at its workpiece, or at the origin when it
//                     names neither). Where it is in this frame: the page keeps the first position it saw.
//         "gantt":   [{"robot" (program label), "command", "start", "end" (s; null while it runs), "ok"}] every
//                     command of the run so far, from the event log's command_start/command_end (the last 400); absent
//                     when the run's log keeps no lines (twin serve -o streams it to a file).
//
// Threads: as live_frame_json: only while the runtime's threads are parked.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cellwright/cell/sim/run.hpp"

namespace cellwright::cell::view {

nlohmann::json cameras(ScenarioRun& run);
nlohmann::json marks(ScenarioRun& run, const std::vector<std::string>& faults);
// null when the log keeps no lines.
nlohmann::json gantt(ScenarioRun& run);

}  // namespace cellwright::cell::view
