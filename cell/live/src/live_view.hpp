// The view-only parts of the live view's "cell" and "frame" messages (cell/live/live.hpp, docs/live-view.md): what
// the 3D page draws beside the robots and parts. Private to cellwright_cell_live; live.cpp's live_cell_json and
// live_frame_json add them to their messages.
//
//   cell  "cameras": [{"name", "pos":[x,y,z], "quat":[qw,qx,qy,qz] (MuJoCo's camera frame: it looks along its -z,
//                      y up), "fovy" (degrees, the image's height), "resolution":[w,h] (the cell description's)}]
//   frame "marks":   [{"kind":"fault"|"collision", "text" (the event-log line), "pos":[x,y,z]}] one per fault line
//                     (mark()): a collision at the contact point of its two bodies (or half-way between them when they
//                     no longer touch), a fault at its robot's tool (or at its workpiece, or at the origin when it
//                     names neither), where they are when mark() is called: FaultMarks (live.hpp) calls it within one
//                     control period of the event.
//         "gantt":   [{"robot" (program label), "command", "start", "end" (s; null while it runs), "ok"}] every
//                     command of the run so far, from the event log's command_start/command_end (the last 400); absent
//                     when the run's log keeps no lines (twin serve -o streams it to a file).
//
// Threads: as live_frame_json: on the simulation thread, or while the runtime's threads are parked or held.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "cellwright/cell/sim/run.hpp"
#include "cellwright/twin/scene.hpp"

namespace cellwright::cell::view {

// A geom's shape as the live view names it ("box", "cylinder", "sphere", "capsule", "plane"); null for the shapes it
// does not draw (meshes and the rest).
const char* shape_of(int mj_geom_type);
// The bodies of the robots' subtrees (by body id): the page draws them from the URDFs.
std::vector<bool> robot_bodies(const twin::Scene& scene);
// The bodies of the geoms the cell message lists, in id order: every body but the robots' with a drawn geom.
std::vector<int> sent_bodies(const twin::Scene& scene);
// Whether a body can move (it or an ancestor has a joint, or its root is a mocap body).
bool moves(const mjModel* m, int body);
std::string body_name(const mjModel* m, int body);

nlohmann::json cameras(ScenarioRun& run);
// The mark of one event-log line of a fault or collision; null for a line that does not decode.
nlohmann::json mark(ScenarioRun& run, const std::string& line);
// null when the log keeps no lines.
nlohmann::json gantt(ScenarioRun& run);

}  // namespace cellwright::cell::view
