// `twin serve`'s run loop (docs/live-view.md): a scenario run on the twin, lock-step or in real time, watched from a
// browser through the live view's server (serve/live_server.hpp), and driven from there: play, pause, step one firing,
// run to a line or a time, restart; teaching, saving locations and the check's counterexample replay (teach.hpp,
// location_file.hpp, replay.hpp).
//
// What the viewers are sent (JSON, the protocol of serve/live_server.hpp):
//   cell    {"type":"cell", "name", "scenario", "program", "mode" ("lock-step" or "real time"),
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
//            "marks":[{"kind":"fault"|"collision", "text" (the line), "pos":[x,y,z]}] (one per fault line, where it
//                     happened: FaultMarks),
//            "gantt":[{"robot", "command", "start", "end" (null while running), "ok"}] (the commands so far, when
//                     the log keeps its lines)}
//            (cell/live/src/live_view.hpp says where the marks are and how the Gantt is read.)
//
// Layering: this is an application above the simulated rig (cell/sim) and the live view's server (serve/); neither
// of them knows it (the walls test: cellwright_cell_sim does not link cellwright_serve).
//
// Threads: serve_scenario runs on the caller's thread. It builds the run and drives it. Lock-step, it is the only
// thread that reads the run (stepped and read there, the runtime's threads parked between steps). In real time, it
// reads the run only while it is held or ended (Runtime::go/hold/wait_held); while the run goes, the frames are built
// on the runtime's simulation thread (a RunObserver), which owns the world then. The marks are placed by another
// RunObserver, every control period, in both modes. The server's thread only moves texts (serve/live_server.hpp). A
// viewer's command waits in the server's queue until the loop takes it.
#pragma once

#include <array>
#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
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

// The faults and collisions of a run (their event-log lines, the frames' "faults") and where each happened (the
// frames' "marks"). A line is added as it is logged (add(): the event log's typed observer, on whatever thread logs
// it); place_new() reads the world for the lines added since its last call: called every control period by a
// RunObserver (the simulation thread), a mark stands where its two bodies touched, or where its robot's tool was,
// within one control period of the event, not where they are when a page first sees it. At most 200 lines are kept.
// Threads: add() and lines() from any thread; place_new() on the simulation thread or while the runtime's threads
// are parked or held.
class FaultMarks {
 public:
  struct Mark {
    std::string line;
    std::string kind;                  // "fault" or "collision" (placed)
    std::optional<std::array<double, 3>> pos;  // where it happened; none until placed
  };
  void add(std::string line);
  void place_new(ScenarioRun& run);
  std::vector<Mark> marks() const;

 private:
  mutable std::mutex mutex_;
  std::vector<Mark> marks_;
};

// The "frame" message of a run now (see the top), with the faults and marks of `marks` (a mark not placed yet is
// placed where things are now). On the simulation thread (a RunObserver), or while the runtime's threads are parked
// (lock-step, between steps) or the run is held or ended (real time).
std::string live_frame_json(ScenarioRun& run, const LiveFrameState& state, const FaultMarks& marks);

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

// Runs `scenario` built with `options` (a fresh ScenarioRun at each restart), lock-step or in real time as
// options.realtime (or the scenario) says, sending its cell and frames
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
// In real time (docs/live-view.md, "Real time") the run goes at options.speed simulation seconds per wall-clock
// second, with frames built on its simulation thread every 1/frame_hz of wall time, and "pause" holds it
// (Runtime::hold: the twin frozen, its clock stopped); "step" lets it go to the first control period after a firing,
// "run_to" to the firing of that line or that time, where it holds. Teaching is refused while it goes (the teach pose
// starts from the world, which is the simulation thread's then).
int serve_scenario(const Scenario& scenario, const Preflight& preflight, const RunOptions& options,
                   serve::LiveServer& server, const ServeOptions& serve_options, const std::atomic<bool>& stop);

}  // namespace cellwright::cell
