#include "until_signal.hpp"

#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <exception>
#include <thread>

namespace cellwright::tools {

// Runs `work` on a thread of its own until it returns or SIGINT/SIGTERM arrives, then `stop` and joins it. The
// signals are blocked on every thread and taken with sigwait here, so no handler runs. Rethrows what `work` threw.
void run_until_signal(const std::function<void()>& work, const std::function<void()>& stop) {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);  // the worker's "I am done"
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  std::exception_ptr error;
  // "Done" goes to this thread alone (pthread_kill), never to the process: a thread the work started (a video's
  // encoder, say) may not block SIGUSR1, and a process-directed signal could land there and end the process.
  const pthread_t waiter = pthread_self();
  std::thread worker([&] {
    try {
      work();
    } catch (...) {
      error = std::current_exception();
    }
    pthread_kill(waiter, SIGUSR1);
  });
  int sig = 0;
  sigwait(&set, &sig);
  if (sig != SIGUSR1) {
    stop();
  }
  worker.join();
  if (sig != SIGUSR1) {  // the worker's "done", sent before join() returned, is pending: take it
    sigset_t done;
    sigemptyset(&done);
    sigaddset(&done, SIGUSR1);
    sigwait(&done, &sig);
  }
  if (error) std::rethrow_exception(error);
}

int run_check_until_signal(const char* what, const std::function<int(const std::atomic<bool>& stop)>& check) {
  std::atomic<bool> stop{false};
  int status = 0;
  run_until_signal([&] { status = check(stop); }, [&] { stop = true; });
  if (!stop) return status;
  std::fprintf(stderr, "%s: interrupted by the user; the verdict covers only what was explored\n", what);
  return kInterrupted;
}

void block_stop_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

}  // namespace cellwright::tools
