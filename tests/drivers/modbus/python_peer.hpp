// A Modbus TCP peer that is not Cellwright's code, for the tests of our Modbus client (drivers_tests) and server
// (emulate_tests): tests/data/modbus/peer.py run by Debian's /usr/bin/python3 with python3-pymodbus (never the
// `python3` on PATH, which may be another Python without it). The peer runs as a child process with its standard input
// and output on pipes: it prints "port N" (a server, listening on a free loopback port) or "ready" (a client), then
// answers each command line with one line (peer.py's docstring lists them).
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <string>
#include <vector>

namespace cellwright::testing {

inline constexpr const char* kSystemPython = "/usr/bin/python3";

// Empty when /usr/bin/python3 can import pymodbus; otherwise why not, for GTEST_SKIP.
inline std::string pymodbus_missing() {
  static const std::string reason = [] {
    const std::string cmd = std::string(kSystemPython) + " -c 'import pymodbus' >/dev/null 2>&1";
    return std::system(cmd.c_str()) == 0
               ? std::string()
               : std::string(kSystemPython) + " cannot import pymodbus (install Debian's python3-pymodbus)";
  }();
  return reason;
}

class PythonPeer {
 public:
  // Starts `peer.py args...`; the first line it prints is read at once (port() has the port of a server).
  explicit PythonPeer(const std::vector<std::string>& args) {
    // Everything the child needs is made before the fork: it only redirects and execs (the test may run threads).
    std::vector<std::string> argv_s{kSystemPython, "-u", std::string(CW_SOURCE_DIR) + "/tests/data/modbus/peer.py"};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    int out[2], in[2];
    if (::pipe2(out, O_CLOEXEC) != 0 || ::pipe2(in, O_CLOEXEC) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(in[0], STDIN_FILENO);
      ::dup2(out[1], STDOUT_FILENO);
      ::execv(kSystemPython, argv.data());
      ::_exit(127);
    }
    ::close(out[1]);
    ::close(in[0]);
    out_ = out[0];
    in_ = in[1];
    first_ = line();
    if (first_.rfind("port ", 0) == 0) port_ = std::atoi(first_.c_str() + 5);
  }
  ~PythonPeer() {
    if (in_ >= 0) ::close(in_);  // the peer ends when its input closes
    if (pid_ > 0) {
      // Give it a moment to end by itself, then make sure.
      for (int i = 0; i < 100 && ::waitpid(pid_, nullptr, WNOHANG) == 0; ++i) ::usleep(20000);
      if (::kill(pid_, SIGKILL) == 0) ::waitpid(pid_, nullptr, 0);
    }
    if (out_ >= 0) ::close(out_);
  }
  PythonPeer(const PythonPeer&) = delete;
  PythonPeer& operator=(const PythonPeer&) = delete;

  int port() const { return port_; }
  // The first line it printed ("port N", "ready", or why it could not start).
  const std::string& first_line() const { return first_; }

  // The next line it prints, without the newline; "" when it printed nothing within `timeout` or ended.
  std::string line(std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      if (const std::size_t nl = buffer_.find('\n'); nl != std::string::npos) {
        std::string l = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return l;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now());
      if (out_ < 0) return {};
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(std::max<long>(0, left.count()))) <= 0) {
        if (left.count() <= 0) return {};  // looked once more, nothing
        continue;
      }
      char buf[4096];
      const ssize_t n = ::read(out_, buf, sizeof buf);
      if (n <= 0) return {};
      buffer_.append(buf, static_cast<std::size_t>(n));
    }
  }

  // Sends one command line and returns its answer line.
  std::string ask(const std::string& command) {
    send(command);
    return line();
  }
  void send(const std::string& command) {
    const std::string l = command + "\n";
    if (in_ >= 0 && ::write(in_, l.data(), l.size()) != static_cast<ssize_t>(l.size())) {
      ::close(in_);
      in_ = -1;
    }
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int in_ = -1;
  int port_ = 0;
  std::string first_;
  std::string buffer_;
};

}  // namespace cellwright::testing
