// Running a command's work until it ends or the user stops it (SIGINT: Ctrl-C, or SIGTERM), for the `twin`
// subcommands that run for long: `twin emulate` (until stopped) and `twin run` (a stop ends the run as a cell stopped
// safely, and the outputs so far are written).
#pragma once

#include <atomic>
#include <functional>
#include <thread>

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

// Watches for SIGINT (Ctrl-C) and SIGTERM on a thread of its own while the caller goes on with its work, for `twin
// step`, which waits for commands on standard input meanwhile: the constructor blocks the signals on the calling thread
// (and so on the threads it starts afterwards); at each signal the watcher calls `on_stop` (on its own thread: it must
// be safe to call from any thread) and makes wake_fd() readable, to be polled beside the input. The destructor ends
// the watcher and joins it.
class StopWatcher {
 public:
  explicit StopWatcher(std::function<void()> on_stop);
  ~StopWatcher();
  StopWatcher(const StopWatcher&) = delete;
  StopWatcher& operator=(const StopWatcher&) = delete;

  int wake_fd() const { return pipe_[0]; }  // readable once a signal came
  bool stopped() const { return stopped_; }

 private:
  std::function<void()> on_stop_;
  int pipe_[2] = {-1, -1};
  std::atomic<bool> stopped_{false};
  std::thread thread_;
};

// Blocks SIGINT and SIGTERM on this thread (and the threads it starts) from now on: a stop that comes before
// run_until_signal() waits for it, pending, instead of killing the process.
void block_stop_signals();

}  // namespace cellwright::tools
