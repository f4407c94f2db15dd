// Running a command's work until it ends or the user stops it (SIGINT: Ctrl-C, or SIGTERM), for the `twin`
// subcommands that run for long: `twin emulate` (until stopped) and `twin run` (a stop ends the run as a cell stopped
// safely, and the outputs so far are written).
#pragma once

#include <atomic>
#include <functional>

namespace cellwright::tools {

// Runs `work` on a thread of its own until it returns or SIGINT/SIGTERM arrives, then `stop` and joins it. The
// signals are blocked on every thread and taken with sigwait here, so no handler runs. Rethrows what `work` threw.
void run_until_signal(const std::function<void()>& work, const std::function<void()>& stop);

// Exit status of a command the user interrupted (128 + SIGINT, as shells report it).
inline constexpr int kInterrupted = 130;

// Runs an analysis (`twin check`, `twin analyze`) that watches `stop` (petri::AnalysisOptions::stop) until it ends or
// SIGINT/SIGTERM arrives, which sets `stop`: the analysis then ends at its next check, prints what it found so far,
// and this prints "<what>: interrupted by the user; the verdict covers only what was explored" on stderr and returns
// kInterrupted. Otherwise returns what `check` returned.
int run_check_until_signal(const char* what, const std::function<int(const std::atomic<bool>& stop)>& check);

// Blocks SIGINT and SIGTERM on this thread (and the threads it starts) from now on: a stop that comes before
// run_until_signal() waits for it, pending, instead of killing the process.
void block_stop_signals();

}  // namespace cellwright::tools
