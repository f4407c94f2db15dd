// The live view as Foxglove's channels (docs/live-view.md, "Foxglove"): the same run that `twin serve` shows on its
// page, for a Foxglove or Lichtblick client connected to the same endpoint (serve/live_server.hpp, "Foxglove").
//
//   channel 1  /cellwright/scene  foxglove.SceneUpdate (JSON; the schema of @foxglove/schemas, serve/
//              foxglove_schemas.hpp): the cell in the frame "world". One entity a body ("body/NAME"), its geoms as
//              cubes, cylinders and spheres at their poses in the world (a capsule is a cylinder and two spheres, a
//              plane a thin cube 10 m square when MuJoCo's is infinite); meshes are not drawn. The entity "marks":
//              a sphere and a label at each fault and collision (FaultMarks: where it happened).
//              Its base (LiveServer::set_channel_base, at each run's start) deletes every entity of the run before
//              and holds every body; each later message holds the bodies that can move (robots, parts) and the marks.
//   channel 2  /cellwright/frame  cellwright.Frame (JSON): the live view's "frame" message as the page gets it
//              (live.hpp): time, marking, each robot's joints and command, faults, the Gantt. For Foxglove's Raw
//              Message, State Transitions and Plot panels (e.g. /cellwright/frame.robots[0].joints[1]).
//
// Threads: as live_frame_json (live.hpp): on the simulation thread, or while the runtime's threads are parked (lock-
// step, between steps) or the run is held or ended (real time).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cellwright/cell/live/live.hpp"
#include "cellwright/serve/live_server.hpp"

namespace cellwright::cell {

inline constexpr std::uint32_t kSceneChannel = 1;
inline constexpr std::uint32_t kFrameChannel = 2;

// The two channels above, with their schemas.
std::vector<serve::Channel> foxglove_channels();

// A foxglove.SceneUpdate of the run now, stamped `time_ns` (ns since the epoch): `whole` for a run's base (every
// body, after a deletion of every entity), else the bodies that can move. With the marks of `marks`.
std::string foxglove_scene_json(ScenarioRun& run, bool whole, const FaultMarks& marks, std::uint64_t time_ns);

// Nanoseconds since the epoch now (the channels' timestamps: Foxglove shows a live source on the wall clock).
std::uint64_t foxglove_now_ns();

}  // namespace cellwright::cell
