// Runs the built `twin` executable as a user would, for the end-to-end CLI tests.
#pragma once

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <vector>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace cellwright::testing {

struct Outcome {
  int status = -1;  // exit status, -1 if killed by a signal (a crash)
  std::string out;
  std::string err;
};

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ostringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

// A scratch directory per test, removed afterwards, and a runner for `twin <args>` inside it.
class TwinCli {
 public:
  explicit TwinCli(const std::string& tag) {
    dir_ = std::filesystem::temp_directory_path() / (tag + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~TwinCli() { std::filesystem::remove_all(dir_); }
  TwinCli(const TwinCli&) = delete;
  TwinCli& operator=(const TwinCli&) = delete;

  const std::filesystem::path& dir() const { return dir_; }

  // `args` is shell text (quote paths with shell_quote). stdin is /dev/null unless `stdin_text` is given.
  Outcome run(const std::string& args, const std::string* stdin_text = nullptr) const {
    const auto out = dir_ / ".stdout", err = dir_ / ".stderr", in = dir_ / ".stdin";
    std::string cmd = shell_quote(CW_TWIN_EXE) + " " + args + " >" + shell_quote(out.string()) + " 2>" +
                      shell_quote(err.string());
    if (stdin_text) {
      std::ofstream(in, std::ios::binary) << *stdin_text;
      cmd += " <" + shell_quote(in.string());
    } else {
      cmd += " </dev/null";
    }
    const int raw = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

 private:
  std::filesystem::path dir_;
};

// `twin <args...>` started in the background (e.g. `twin emulate`), its standard output read through a pipe; with
// `with_stdin`, its standard input a pipe that send() writes to (kept open until it ends), else the test's. With a
// `prefix`, `prefix... twin <args...>` (a program that runs twin in its own process, as `ip netns exec NAME` does). The
// destructor stops it (SIGTERM) and reaps it.
class BackgroundTwin {
 public:
  explicit BackgroundTwin(const std::vector<std::string>& args, bool with_stdin = false,
                          const std::vector<std::string>& prefix = {}) {
    int fds[2];
    if (::pipe(fds) != 0) return;
    int in[2] = {-1, -1};
    if (with_stdin && ::pipe(in) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::dup2(fds[1], STDERR_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
      if (with_stdin) {
        ::dup2(in[0], STDIN_FILENO);
        ::close(in[0]);
        ::close(in[1]);
      }
      std::vector<std::string> copy = prefix;
      copy.push_back(CW_TWIN_EXE);
      copy.insert(copy.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (std::string& a : copy) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execvp(argv[0], argv.data());
      ::_exit(127);
    }
    ::close(fds[1]);
    out_ = fds[0];
    if (with_stdin) {
      ::close(in[0]);
      in_ = in[1];
    }
  }
  ~BackgroundTwin() {
    stop();
    if (out_ >= 0) ::close(out_);
    if (in_ >= 0) ::close(in_);
  }

  // Writes `text` to its standard input (with_stdin); false if it could not.
  bool send(const std::string& text) {
    return in_ >= 0 && ::write(in_, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  }
  BackgroundTwin(const BackgroundTwin&) = delete;
  BackgroundTwin& operator=(const BackgroundTwin&) = delete;

  // Reads its output until `text` appears or `timeout` passes; true if it appeared.
  bool wait_for(const std::string& text, std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (output_.find(text) == std::string::npos) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now());
      if (left.count() <= 0 || out_ < 0) return false;
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char buf[4096];
      const ssize_t n = ::read(out_, buf, sizeof buf);
      if (n <= 0) return output_.find(text) != std::string::npos;
      output_.append(buf, static_cast<std::size_t>(n));
    }
    return true;
  }
  // Sends `sig` (SIGTERM; SIGINT is Ctrl-C), waits for the exit and reads the rest of the output; the exit status (-1
  // if killed by a signal).
  int stop(int sig = SIGTERM) {
    if (pid_ <= 0) return status_;
    ::kill(pid_, sig);
    char buf[4096];
    ssize_t n;
    while (out_ >= 0 && (n = ::read(out_, buf, sizeof buf)) > 0) output_.append(buf, static_cast<std::size_t>(n));
    int raw = 0;
    ::waitpid(pid_, &raw, 0);
    pid_ = -1;
    status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    return status_;
  }
  // Waits at most `timeout` for it to exit by itself (reading its output meanwhile); its exit status (-1 if killed by
  // a signal, or SIGTERM'd at the timeout: stop()).
  int wait_exit(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return status_;
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      int raw = 0;
      if (::waitpid(pid_, &raw, WNOHANG) == pid_) {
        pid_ = -1;
        char buf[4096];
        ssize_t n;
        while (out_ >= 0 && (n = ::read(out_, buf, sizeof buf)) > 0) output_.append(buf, static_cast<std::size_t>(n));
        status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
        return status_;
      }
      (void)wait_for("\x01never", std::chrono::milliseconds(50));  // drains the pipe meanwhile
    }
    stop();
    return -1;
  }
  const std::string& output() const { return output_; }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int in_ = -1;
  int status_ = -1;
  std::string output_;
};

inline std::string source_path(const std::string& relative) { return std::string(CW_SOURCE_DIR) + "/" + relative; }

}  // namespace cellwright::testing
