#include "until_signal.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

namespace cellwright::tools {

namespace {

// Blocks SIGINT, SIGTERM and SIGUSR1 (a thread's "done" or "end", sent to one thread) on this thread and the threads
// it starts from now on; returns them as a set for sigwait.
sigset_t block_stop_and_end() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  return set;
}

}  // namespace

// Runs `work` on a thread of its own until it returns or SIGINT/SIGTERM arrives, then `stop` and joins it. The
// signals are blocked on every thread and taken with sigwait here, so no handler runs. Rethrows what `work` threw.
void run_until_signal(const std::function<void()>& work, const std::function<void()>& stop) {
  sigset_t set = block_stop_and_end();  // SIGUSR1: the worker's "I am done"
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

StopWatcher::StopWatcher(std::function<void()> on_stop) : on_stop_(std::move(on_stop)) {
  if (::pipe2(pipe_, O_CLOEXEC) != 0) {
    throw std::runtime_error(std::string("cannot make a pipe to watch for Ctrl-C: ") + std::strerror(errno));
  }
  const sigset_t set = block_stop_and_end();  // SIGUSR1: the destructor's "end"
  thread_ = std::thread([this, set] {
    for (;;) {
      int sig = 0;
      if (sigwait(&set, &sig) != 0 || sig == SIGUSR1) return;
      stopped_ = true;
      on_stop_();
      const char byte = 's';
      while (::write(pipe_[1], &byte, 1) < 0 && errno == EINTR) {
      }
    }
  });
}

StopWatcher::~StopWatcher() {
  // "End" goes to the watcher alone (pthread_kill), never to the process (as run_until_signal's "done").
  pthread_kill(thread_.native_handle(), SIGUSR1);
  thread_.join();
  ::close(pipe_[0]);
  ::close(pipe_[1]);
}

void block_stop_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

}  // namespace cellwright::tools
