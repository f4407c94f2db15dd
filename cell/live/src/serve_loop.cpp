// `twin serve`'s run loop (live.hpp serve_scenario): the run, the viewers' messages, teaching, saving, the check.
#include <fmt/format.h>

#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "cellwright/cell/live/foxglove_scene.hpp"
#include "cellwright/cell/live/live.hpp"
#include "cellwright/cell/live/location_file.hpp"
#include "cellwright/cell/live/replay.hpp"
#include "cellwright/cell/live/teach.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/runtime/log_event.hpp"

namespace cellwright::cell {

namespace {

using nlohmann::json;

std::string error_json(const std::string& reason) { return json{{"type", "error"}, {"reason", reason}}.dump(); }

// A frame of a replay says so, and how far the counterexample has been replayed.
std::string with_replay(std::string frame, bool replay, std::uint64_t done) {
  if (replay && !frame.empty() && frame.back() == '}') {
    frame.pop_back();
    frame += fmt::format(",\"replay\":true,\"replay_index\":{}}}", done);
  }
  return frame;
}

// Sends a frame to the page's viewers and on the Foxglove frame channel (kept as its latest even when nobody
// subscribes: the text is built anyway), and, to the Foxglove clients that subscribed to it, the scene of the run now.
void publish_frame(serve::LiveServer& server, ScenarioRun& run, const FaultMarks& marks, const std::string& frame) {
  server.publish(frame);
  const std::uint64_t now = foxglove_now_ns();
  server.publish_channel(kFrameChannel, frame, now);
  if (server.subscribers(kSceneChannel) > 0) {
    server.publish_channel(kSceneChannel, foxglove_scene_json(run, false, marks, now), now);
  }
}

// How many watch: the page's viewers and the Foxglove subscriptions.
std::size_t watchers(const serve::LiveServer& server) {
  return server.viewers() + server.subscribers(kSceneChannel) + server.subscribers(kFrameChannel);
}

// Where to pause a run playing to a target ("run_to").
struct RunTo {
  std::optional<int> line;
  std::optional<runtime::SimDuration> time;
};

RunTo parse_run_to(const std::string& text, const petri::Net& net, const Scenario& s, runtime::SimDuration now) {
  const json j = json::parse(text, nullptr, false);
  RunTo to;
  if (const auto line = j.find("line"); line != j.end()) {
    if (!line->is_number_integer()) throw LiveRefusal("run_to's \"line\" is a program line number");
    const int n = line->get<int>();
    bool found = false;
    for (const petri::Transition& t : net.transitions()) found = found || t.origin.line == n;
    if (!found) {
      throw LiveRefusal(fmt::format("no command of {} is on line {}", s.program_file.filename().string(), n));
    }
    to.line = n;
  } else if (const auto time = j.find("time"); time != j.end()) {
    if (!time->is_number() || !std::isfinite(time->get<double>())) throw LiveRefusal("run_to's \"time\" is seconds");
    const double t = time->get<double>();
    const double at = std::chrono::duration<double>(now).count();
    if (t <= at) throw LiveRefusal(fmt::format("time {} s is not after now ({} s)", t, at));
    to.time = std::chrono::duration_cast<runtime::SimDuration>(std::chrono::duration<double>(t));
  } else {
    throw LiveRefusal("run_to needs \"line\" (a program line) or \"time\" (simulation seconds)");
  }
  return to;
}

// The file as the scenario names it (relative to the scenario's directory when it is under it).
std::string file_label(const Scenario& s) {
  const std::filesystem::path rel = s.cell_file.lexically_relative(s.source.parent_path());
  return rel.empty() || *rel.begin() == ".." ? s.cell_file.string() : rel.generic_string();
}

}  // namespace

int serve_scenario(const Scenario& scenario, const Preflight& preflight, const RunOptions& options,
                   serve::LiveServer& server, const ServeOptions& serve_options, const std::atomic<bool>& stop) {
  using namespace std::chrono_literals;
  const std::filesystem::path models = models_root(scenario);
  const Scenario* sc = &scenario;
  const Preflight* pf = &preflight;
  LiveScenario reloaded;  // owns sc and pf after a reload
  bool reload_pending = false;
  CheckOutcome check = check_outcome(pf->net, pf->analysis);  // the preflight's analysis, not run again
  server.advertise(foxglove_channels());
  if (!check.ok) server.set_greeting({check_json(pf->net, check)});
  int runs = 0;
  while (!stop) {
    if (reload_pending && serve_options.reload) {
      reload_pending = false;
      try {
        LiveScenario again = serve_options.reload();
        reloaded = std::move(again);
        sc = reloaded.scenario.get();
        pf = reloaded.preflight.get();
        check = check_outcome(pf->net, pf->analysis);
        server.set_greeting(check.ok ? std::vector<std::string>{} : std::vector<std::string>{check_json(pf->net, check)});
      } catch (const InputError& e) {
        server.broadcast(error_json(fmt::format("the scenario could not be loaded again (the run keeps the cell it "
                                                "had): {}",
                                                e.what())));
      }
    }
    const bool replay = !check.ok;
    // The faults and collisions, placed where they happened (the simulation thread, every control period), and, in
    // real time, the frames built there while the run goes. The run the observers read is set once it is built
    // (they are called only once it has started).
    auto marks = std::make_shared<FaultMarks>();
    auto shared_run = std::make_shared<ScenarioRun*>(nullptr);
    // Real time: the transitions fired since the last frame (from the log's observer, on whatever thread fires), so
    // that a frame names the latest firings, not only those of task control's last step (often none).
    struct Fired {
      std::mutex mutex;
      std::vector<std::string> since_frame, shown;
    };
    auto fired = std::make_shared<Fired>();
    RunOptions run_options = options;
    run_options.configure = [prev = options.configure, replay, order = check.counterexample, marks, shared_run, fired,
                             &server, hz = serve_options.frame_hz, speed = options.speed](runtime::RunConfig& c) {
      if (prev) prev(c);
      if (replay) c.firing_order = order;
      c.observers.push_back(
          {c.period, false, [marks, shared_run](const runtime::Observation&) { marks->place_new(**shared_run); }});
      if (c.mode != runtime::Mode::kRealtime) return;
      // Frames as the run goes: at most hz per second of wall time (speed simulation seconds per wall second).
      const auto every = std::max(
          c.period, std::chrono::duration_cast<runtime::SimDuration>(std::chrono::duration<double>(speed / hz)));
      const std::size_t script = order.size();
      c.observers.push_back(
          {every, true, [marks, shared_run, fired, &server, replay, script](const runtime::Observation& o) {
             if (watchers(server) == 0) return;  // nobody watches: no frame to build
             runtime::StepState st;
             st.time = o.time;
             st.task = o.task;
             st.robots = o.controls;
             {
               std::lock_guard lock(fired->mutex);
               if (!fired->since_frame.empty()) fired->shown = std::move(fired->since_frame);
               fired->since_frame.clear();
               st.task.last_fired = fired->shown;  // the latest firings, until newer ones
             }
             publish_frame(server, **shared_run, *marks,
                           with_replay(live_frame_json(**shared_run, LiveFrameState{"playing", &st}, *marks), replay,
                                       std::min<std::uint64_t>(o.task.firings, script)));
           }});
    };
    auto run = std::make_unique<ScenarioRun>(*sc, *pf, run_options);
    *shared_run = run.get();
    ++runs;
    const bool realtime = run->realtime();
    run->runtime().log().add_observer([marks, fired, realtime](const runtime::LogEvent& e) {
      if (const auto* f = std::get_if<runtime::events::Fire>(&e); f && realtime) {
        std::lock_guard lock(fired->mutex);
        if (fired->since_frame.size() < 200) fired->since_frame.push_back(f->transition);
        return;
      }
      const std::string_view type = runtime::type_of(e);
      if (type != "fault_injected" && type != "fault_detected" && type != "collision") return;
      marks->add(runtime::encode(e));
    });
    server.set_cell(live_cell_json(*run, models));
    const std::uint64_t started = foxglove_now_ns();
    server.set_channel_base(kSceneChannel, foxglove_scene_json(*run, true, *marks, started), started);
    Teacher teacher(*sc);
    bool playing = serve_options.play, ended = false, restart = false;
    bool going = false;  // real time: let go (Runtime::go), not yet seen held or ended
    std::optional<RunTo> run_to;
    std::optional<runtime::StepState> last;
    serve::FramePacer pacer(serve_options.frame_hz);
    std::uint64_t arrivals = server.arrivals();
    bool missed = false;  // a viewer missed the last frame sent (its socket was full)
    // The state now, built here: lock-step between steps, or real time while held, before it starts or ended.
    auto send = [&] {
      const LiveFrameState st{ended ? "ended" : playing ? "playing" : "paused", last ? &*last : nullptr};
      const serve::LiveServer::Counts before = server.counts();
      const std::uint64_t done = std::min<std::uint64_t>(last ? last->task.firings : 0, check.counterexample.size());
      publish_frame(server, *run, *marks, with_replay(live_frame_json(*run, st, *marks), replay, done));
      const serve::LiveServer::Counts after = server.counts();
      missed = after.dropped > before.dropped || after.messages_dropped > before.messages_dropped;
    };
    // Real time: lets the run go, to the next firing when stepping, replaying (whose end is seen at a firing) or
    // running to a line; to run_to's time; else to its end.
    auto let_go = [&] {
      runtime::HoldAt at;
      at.firing = !playing || replay || (run_to && run_to->line);
      if (run_to) at.time = run_to->time;
      run->runtime().go(at);
      going = true;
    };
    // After a step (lock-step) or a hold (real time): the replay's end, and where run_to stops.
    auto stepped = [&] {
      ended = last->ended;
      if (replay && !ended && check.property != "deadlock" && last->task.firings >= check.counterexample.size()) {
        // The counterexample's last marking is not dead: nothing more fires, so the replay ends there.
        run->runtime().request_stop(fmt::format("the counterexample ends here: {}", check.last_marking));
        last = realtime ? *run->runtime().wait_held(std::chrono::steady_clock::duration::max()) : run->runtime().step();
        ended = last->ended;
      }
      if (run_to) {
        bool reached = ended || (run_to->time && last->time >= *run_to->time);
        if (run_to->line) {
          for (const std::string& id : last->task.last_fired) {
            const auto t = pf->net.find_transition(id);
            reached = reached || (t && pf->net.transitions()[*t].origin.line == *run_to->line);
          }
        }
        if (reached) {
          run_to.reset();
          playing = false;
        }
      }
    };
    // One step of the run, lock-step (to the next firing, or to run_to's time).
    auto step = [&] {
      last = run->runtime().step(run_to ? run_to->time : std::nullopt);
      stepped();
    };
    // Real time: holds a run that goes, and waits for it (a control period at most).
    auto hold = [&] {
      if (!going) return;
      run->runtime().hold();
      last = *run->runtime().wait_held(std::chrono::steady_clock::duration::max());
      ended = last->ended;
      going = false;
    };
    auto handle = [&](const serve::Message& m) {
      if (m.type == "command") {
        switch (*m.command) {
          case serve::CommandKind::kPlay:
            playing = !ended;
            run_to.reset();
            if (realtime && playing) let_go();
            break;
          case serve::CommandKind::kPause:
            playing = false;
            run_to.reset();
            if (realtime) hold();
            break;
          case serve::CommandKind::kStep:
            playing = false;
            run_to.reset();
            if (ended) break;
            if (!realtime) {
              step();
            } else {
              hold();  // from where it is now
              if (!ended) let_go();
            }
            break;
          case serve::CommandKind::kRunTo: {
            if (ended) throw LiveRefusal("the run has ended: restart it first");
            const bool was_going = going;
            hold();  // a time is checked against the time it holds at
            RunTo to;
            try {
              to = parse_run_to(m.text, pf->net, *sc, last ? last->time : runtime::SimDuration{0});
            } catch (const LiveRefusal&) {
              if (was_going && !ended) let_go();  // refused: the run goes on as it went
              throw;
            }
            run_to = std::move(to);
            playing = !ended;
            if (realtime && playing) let_go();
            break;
          }
          case serve::CommandKind::kRestart: restart = true; break;
          case serve::CommandKind::kReplay:
            if (!replay) throw LiveRefusal("the program passes the check: there is no counterexample to replay");
            restart = true;
            break;
        }
        if (!restart && !going) send();  // a run that goes sends its own frames
      } else if (m.type == "teach") {
        const TeachRequest req = parse_teach(m.text);
        if (req.action == TeachAction::kBegin && playing && !ended) {
          throw LiveRefusal("the run is playing: pause it before teaching");
        }
        if (going) throw LiveRefusal("the run is going in real time: pause it before teaching");
        server.broadcast(teach_json(teacher.apply(req, run->world())));
      } else if (m.type == "save_location") {
        const json j = json::parse(m.text, nullptr, false);
        const std::string robot = teacher.robot_name(j.value("robot", ""));
        const std::string name = j.value("name", "");
        const TeachState* taught = robot.empty() ? nullptr : teacher.state(robot);
        if (!taught) {
          throw LiveRefusal(fmt::format("robot '{}' is not being taught: there is no pose to save",
                                        j.value("robot", "")));
        }
        const std::string label = file_label(*sc);
        const SavedLocation saved = save_location(sc->cell_file, label, name, robot, taught->tool);
        reload_pending = true;
        server.broadcast(json{{"type", "saved"},
                              {"file", label},
                              {"name", name},
                              {"robot", robot},
                              {"line", saved.line},
                              {"replaced", saved.replaced},
                              {"diff", saved.diff}}
                             .dump());
      } else if (m.type == "check") {
        server.send_to(m.viewer, check_json(pf->net, check));
      }
    };
    if (realtime && playing) let_go();
    send();
    while (!stop && !restart) {
      // Playing lock-step: take what came without waiting. A real-time run that goes: wait a little, then look whether
      // it holds. Else wait a little for a message (and notice new viewers).
      const bool stepping = !realtime && playing && !ended;
      const std::optional<serve::Message> m =
          stepping ? server.poll_message() : server.wait_message(going ? 10ms : 100ms);
      if (m) {
        try {
          handle(*m);
        } catch (const LiveRefusal& e) {
          server.send_to(m->viewer, error_json(e.what()));
        }
        continue;
      }
      if (stepping) {
        step();
        if (ended || !playing || pacer.due()) send();
      } else if (going) {
        if (std::optional<runtime::StepState> held = run->runtime().wait_held(std::chrono::milliseconds(0))) {
          last = std::move(held);
          going = false;
          stepped();
          if (playing && !ended) {
            let_go();  // replaying, or running to a line that has not fired yet: on to the next firing
          } else {
            send();
          }
        }
      } else if (const std::uint64_t a = server.arrivals(); a != arrivals || missed) {
        // A viewer (or a Foxglove subscription) that came while nothing moves gets the state now; one that missed the
        // last frame gets it again (at most every 100 ms while its socket stays full), so no viewer is left on an
        // older state.
        arrivals = a;
        send();
      }
    }
    // The restarted run starts with nothing taught: the viewers' ghosts go away.
    for (const std::string& robot : teacher.active()) {
      server.broadcast(teach_json(TeachState{robot, false, {}, Eigen::Isometry3d::Identity(), true, {}, "", {}}));
    }
  }
  return runs;
}

}  // namespace cellwright::cell
