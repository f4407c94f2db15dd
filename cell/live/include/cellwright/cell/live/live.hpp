// `twin serve`'s run loop (docs/live-view.md): a scenario run lock-step on the twin, watched from a browser through the
// live view's server (serve/live_server.hpp), and driven from there: play, pause, step one firing, run to a line or
// a time, restart; teaching, saving locations and the check's counterexample replay (teach.hpp, location_file.hpp,
// replay.hpp).
//
// What the viewers are sent (JSON, the protocol of serve/live_server.hpp):
//   cell    {"type":"cell", "name", "scenario", "program",
//            "robots":[{"name", "label", "urdf":"/models/...", "packages":{PACKAGE:"/models/..."},
//                       "base_link", "base":[x,y,z,qw,qx,qy,qz], "joints":[URDF joint names, base to tip]}],
//            "bodies":[{"id", "name", "pose":[x,y,z,qw,qx,qy,qz]}],        every body of the geoms below
//            "geoms":[{"body", "shape":"box"|"cylinder"|"sphere"|"capsule"|"plane", "size":[MuJoCo's half-sizes],
//                      "pos":[x,y,z], "quat":[qw,qx,qy,qz] (in its body), "rgba":[r,g,b,a], "role"}]}
//            The geoms are the cell's but the robots' (drawn from their URDFs) and meshes: conveyors, stands,
//            machines, parts, obstacles, the floor.
//            "cameras":[{"name", "pos", "quat" (MuJoCo's camera frame: looks along -z, y up), "fovy" (deg),
//                        "resolution":[w,h]}]
//   frame   {"type":"frame", "t" (simulation s), "firings", "state":"paused"|"playing"|"ended", "outcome", "reason",
//            "marking" (the Petri net's, as text), "fired":[transitions of the last step, described],
//            "robots":[{"name", "label", "joints":[rad], "fingers" (m open), "activity", "command", "phase",
//                       "detail"}],
//            "bodies":[[id,x,y,z,qw,qx,qy,qz] for each body of "bodies" that moves],
//            "faults":[event log lines: fault_injected, fault_detected, collision, since the run began],
//            "marks":[{"kind":"fault"|"collision", "text" (the line), "pos":[x,y,z]}] (one per fault line),
//            "gantt":[{"robot", "command", "start", "end" (null while running), "ok"}] (the commands so far, when
//                     the log keeps its lines)}
//            (cell/live/src/live_view.hpp says where the marks are and how the Gantt is read.)
//
// Layering: this is an application above the simulated rig (cell/sim) and the live view's server (serve/); neither
// of them knows it (the walls test: cellwright_cell_sim does not link cellwright_serve).
//
// Threads: serve_scenario runs on the caller's thread and is the only one that touches the run (built, stepped and
// read there, with the runtime's threads parked between steps: lock-step); the server's thread only moves texts
// (serve/live_server.hpp). A viewer's command waits in the server's queue until the loop takes it, between steps.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/sim/run.hpp"
#include "cellwright/serve/live_server.hpp"

namespace cellwright::cell {

// The directory the page loads the robots' models from (served as /models/): the deepest directory holding every
// robot's URDF and mesh packages of the scenario's cell. InputError when there is none but the root.
std::filesystem::path models_root(const Scenario& scenario);

// The "cell" message of a run (see the top), with URLs under /models/ relative to `models`.
std::string live_cell_json(ScenarioRun& run, const std::filesystem::path& models);

struct LiveFrameState {
  const char* state = "paused";  // "paused", "playing" or "ended"
  const runtime::StepState* step = nullptr;  // the last step's state, or none before the first
};
// The "frame" message of a run now (see the top). Only while the runtime's threads are parked (lock-step, between
// steps). `faults` are the lines to send as "faults".
std::string live_frame_json(ScenarioRun& run, const LiveFrameState& state, const std::vector<std::string>& faults);

// A scenario and its preflight, loaded again (ServeOptions::reload).
struct LiveScenario {
  std::unique_ptr<Scenario> scenario;
  std::unique_ptr<Preflight> preflight;
};

struct ServeOptions {
  double frame_hz = 30;  // frames to the viewers at most this often (wall time)
  bool play = false;     // start playing without waiting for a viewer's "play"
  // Loads the scenario and its preflight again (as `twin serve` loaded them first): called at the first restart
  // after a location was saved, so that the restarted run has the cell as the file now says. InputError: the viewers
  // are told ("error") and the run goes on with the scenario it had. Empty: never reloaded.
  std::function<LiveScenario()> reload;
};

// Runs `scenario` lock-step, built with `options` (a fresh ScenarioRun at each restart), sending its cell and frames
// to `server`'s viewers and obeying their messages (docs/live-view.md has the protocol), until `stop` is set.
// `preflight` passed, or refused the scenario only because its program fails the check: then each run is the replay
// of the check's counterexample (replay.hpp): the "check" message greets every viewer after the cell, task control
// fires the counterexample's transitions in its order, and frames carry "replay" and "replay_index".
// Paused at first (unless ServeOptions::play): each "step" runs to the next firing, "play" runs on (a frame at most
// every 1/frame_hz of wall time, the run never waiting for a viewer), "run_to" plays until a transition of a program
// line fires or the simulation time is reached, "pause" stops between two steps, "restart" (and "replay") builds the
// run again. A run that has ended stays on its last frame until "restart". While nothing moves, a viewer that
// connects, or that missed the last frame (its socket full), is sent the state again. "teach" messages jog teach
// poses (teach.hpp: never the run's) and are answered to every viewer; "save_location" writes the teach pose into
// the cell description file (location_file.hpp) and tells every viewer ("saved"); "check" is answered to its
// sender. A message that cannot be carried out is answered to its sender alone ("error"). Returns the number of
// runs built.
int serve_scenario(const Scenario& scenario, const Preflight& preflight, const RunOptions& options,
                   serve::LiveServer& server, const ServeOptions& serve_options, const std::atomic<bool>& stop);

}  // namespace cellwright::cell
