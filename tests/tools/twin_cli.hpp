// Runs the built `twin` executable as a user would, for the end-to-end CLI tests.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

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

inline std::string source_path(const std::string& relative) { return std::string(CW_SOURCE_DIR) + "/" + relative; }

}  // namespace cellwright::testing
