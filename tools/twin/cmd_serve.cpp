// `twin serve <scenario.yaml> [--port P] [--bind ADDR] [--play] [--realtime [--speed X]]`: run a scenario on the twin,
// lock-step or in real time, and watch it in a browser, driven from the page (play, pause, step one firing, restart):
// docs/live-view.md. Loopback only unless --bind gives another address. Takes the options of `twin run` but --quiet
// and --dry (run_args.hpp). Runs until Ctrl-C or SIGTERM (exit 130); 2 on bad input.
#if CW_SIM
#include <atomic>
#include <cstdio>
#include <memory>
#include <optional>

#include "cellwright/cell/preflight.hpp"
#include "cellwright/cell/scenario.hpp"
#include "cellwright/cell/live/live.hpp"
#include "cellwright/cell/live/replay.hpp"
#include "cellwright/cell/sim/sweep.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/serve/live_server.hpp"
#include "commands.hpp"
#include "run_args.hpp"
#include "until_signal.hpp"

namespace cellwright::tools {

void add_serve(CLI::App& app, Command* run) {
  auto* cmd = app.add_subcommand("serve",
                                 "Run a scenario on the twin (lock-step, or --realtime) and watch it live in a browser "
                                 "(http://ADDR:PORT/): play, "
                                 "pause, step one firing, run to a line or a time, restart, teach and save locations "
                                 "from the page; a program that fails the check is served as its counterexample's "
                                 "replay. Runs until Ctrl-C (exit 130); 2 on bad input.");
  auto args = std::make_shared<RunArgs>();
  auto port = std::make_shared<int>(8029);
  auto bind = std::make_shared<std::string>("127.0.0.1");
  auto play = std::make_shared<bool>(false);
  auto realtime = std::make_shared<bool>(false);
  auto speed = std::make_shared<double>(1.0);
  add_run_options(*cmd, *args);
  cmd->add_flag("--realtime", *realtime,
                "run paced to the wall clock instead of lock-step (also when the scenario says realtime: true); pause "
                "freezes the twin");
  auto* speed_opt = cmd->add_option("--speed", *speed,
                                    "with --realtime: simulation seconds per wall-clock second (default 1)")
                        ->check(CLI::PositiveNumber);
  cmd->add_option("--port", *port, "TCP port of the page and its WebSocket (default 8029; 0: any free port)");
  cmd->add_option("--bind", *bind,
                  "address to listen on (default 127.0.0.1: this machine only; 0.0.0.0 opens it to the network)");
  cmd->add_flag("--play", *play, "start playing without waiting for the page's play");
  cmd->callback([run, args, port, bind, play, realtime, speed, speed_opt] {
    const bool speed_given = speed_opt->count() > 0;
    *run = [args, port, bind, play, realtime, speed, speed_given] {
      using namespace cellwright::cell;
      if (*port < 0 || *port > 65535) throw InputError({"--port", 0, 0}, fmt::format("{} is not a TCP port", *port));
      const Scenario s = load_scenario_with(*args);
      if (uses_real_drivers(s)) {
        throw InputError({"--driver", 0, 0}, "twin serve runs the program on the twin's simulated robots (pause "
                                             "freezes the twin; a real arm would not stop)");
      }
      Preflight pre = preflight(s, &twin_port());
      if (std::optional<Preflight> replay = counterexample_preflight(s, pre)) {
        // A program that fails the check is served as its counterexample's replay (docs/live-view.md).
        std::printf("%s: the program fails the check: serving its counterexample's replay\n", args->scenario.c_str());
        pre = std::move(*replay);
      } else if (!pre.ok(args->allow_collisions)) {
        std::fprintf(stderr, "%s: refused, nothing was run:\n", args->scenario.c_str());
        for (const std::string& p : pre.problems) std::fprintf(stderr, "  %s\n", p.c_str());
        return 2;
      }
      RunOptions options = run_options_for(*args, s);
      options.realtime = *realtime || s.options.realtime;
      if (speed_given && !*options.realtime) {
        throw InputError({"--speed", 0, 0}, "it paces a real-time run, and this one is lock-step: add --realtime");
      }
      options.speed = *speed;
      serve::ServerOptions so;
      so.bind = *bind;
      so.port = static_cast<std::uint16_t>(*port);
      so.www = CW_LIVE_WWW;
      so.models = models_root(s);
      block_stop_signals();
      serve::LiveServer server(so);
      const std::string mode = *options.realtime ? fmt::format("real time at speed {:g}", options.speed) : "lock-step";
      // Printed with the port taken (--port 0): the page's URL, and the same endpoint for Foxglove (docs/live-view.md).
      std::printf("%s: %s, serving the live view on http://%s:%u/ and Foxglove on ws://%s:%u/ (Ctrl-C stops)\n",
                  args->scenario.c_str(), mode.c_str(), bind->c_str(), static_cast<unsigned>(server.port()),
                  bind->c_str(), static_cast<unsigned>(server.port()));
      std::fflush(stdout);
      std::atomic<bool> stop{false};
      const StopWatcher watcher([&stop] { stop = true; });
      ServeOptions opts;
      opts.play = *play;
      // After a location is saved, a restart loads the scenario (and its cell file) again, with the same options.
      opts.reload = [args] {
        LiveScenario again;
        again.scenario = std::make_unique<Scenario>(load_scenario_with(*args));
        Preflight p = preflight(*again.scenario, &twin_port());
        if (std::optional<Preflight> replay = counterexample_preflight(*again.scenario, p)) {
          p = std::move(*replay);
        } else if (!p.ok(args->allow_collisions)) {
          throw InputError({args->scenario, 0, 0}, "refused by the preflight: " + p.problems.front());
        }
        again.preflight = std::make_unique<Preflight>(std::move(p));
        return again;
      };
      serve_scenario(s, pre, options, server, opts, stop);
      return kInterrupted;
    };
  });
}

}  // namespace cellwright::tools

#else

#include "simulator.hpp"

namespace cellwright::tools {

void add_serve(CLI::App& app, Command* run) { add_unavailable(app, run, "serve", "Watch a scenario live in a browser"); }

}  // namespace cellwright::tools

#endif  // CW_SIM
