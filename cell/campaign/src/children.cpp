// Child processes of `twin campaign` and `twin test`: start, wait with a limit, tell done/crash/hang (children.hpp).
#include "cellwright/cell/children.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/cell/outputs.hpp"
#include "cellwright/cell/report_json.hpp"

extern char** environ;

namespace cellwright::cell {

const char* to_string(RunStatus st) {
  switch (st) {
    case RunStatus::kDone:
      return "done";
    case RunStatus::kCrash:
      return "crash";
    case RunStatus::kHang:
      return "hang";
  }
  return "?";
}

namespace {

// The first line of a child's stderr that says something (an InputError's message, a parse error), at most 200
// characters.
std::string first_line(const std::string& text) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.find_first_not_of(" \t=-") == std::string::npos) continue;
    return line.size() > 200 ? line.substr(0, 200) + "..." : line;
  }
  return std::string();
}

std::string slurp_or_empty(const std::filesystem::path& p) {
  try {
    return read_file(p);
  } catch (const InputError&) {
    return std::string();
  }
}

pid_t spawn(const std::filesystem::path& executable, const ChildSpec& child) {
  std::vector<std::string> args = {executable.string()};
  args.insert(args.end(), child.args.begin(), child.args.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  const std::string out = (child.dir / kChildStdout).string(), err = (child.dir / kChildStderr).string();
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, executable.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    throw InputError({executable.string(), 0, 0},
                     fmt::format("cannot start it for {}: {}", child.dir.string(), std::strerror(rc)));
  }
  return pid;
}

// Tells apart how a child ended from its wait status and what it left in `dir`.
ChildEnd finish(const std::filesystem::path& dir, int raw, bool killed, double wall_time) {
  ChildEnd end;
  end.wall_time = wall_time;
  if (WIFEXITED(raw)) end.exit_code = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) end.signal = WTERMSIG(raw);
  end.first_error = first_line(slurp_or_empty(dir / kChildStderr));
  if (killed) {
    end.status = RunStatus::kHang;
    end.problem = fmt::format("still running after {:.0f} s: killed", wall_time);
    return end;
  }
  if (WIFSIGNALED(raw)) {
    end.status = RunStatus::kCrash;
    end.problem = fmt::format("killed by signal {} ({})", end.signal, strsignal(end.signal));
    return end;
  }
  std::error_code ec;
  if (!std::filesystem::exists(dir / kReportFile, ec)) {
    end.status = RunStatus::kCrash;
    end.problem = fmt::format("exit {} without {}{}", end.exit_code, kReportFile,
                              end.first_error.empty() ? std::string() : ": " + end.first_error);
    return end;
  }
  try {
    end.report = read_report(dir / kReportFile);
  } catch (const InputError& e) {  // not JSON, or a field missing or mistyped: named, never taken as a result
    end.status = RunStatus::kCrash;
    end.problem = fmt::format("exit {} with an unreadable {}: {}", end.exit_code, kReportFile, e.what());
    return end;
  }
  end.status = RunStatus::kDone;
  return end;
}

struct Running {
  pid_t pid = -1;
  std::size_t index = 0;
  std::chrono::steady_clock::time_point start;
  bool killed = false;
};

}  // namespace

std::vector<ChildEnd> run_children(const std::filesystem::path& executable, const std::vector<ChildSpec>& children,
                                   std::size_t jobs, const ChildCallbacks& callbacks) {
  namespace fs = std::filesystem;
  using Clock = std::chrono::steady_clock;
  std::vector<ChildEnd> ends(children.size());
  jobs = std::max<std::size_t>(1, jobs);
  std::vector<Running> running;
  auto kill_all = [&running] {
    for (const Running& c : running) {
      ::kill(c.pid, SIGKILL);
      ::waitpid(c.pid, nullptr, 0);
    }
  };
  std::size_t next = 0;
  try {
    while (next < children.size() || !running.empty()) {
      bool changed = false;
      while (running.size() < jobs && next < children.size()) {
        const ChildSpec& spec = children[next];
        std::error_code ec;
        fs::remove_all(spec.dir, ec);
        make_output_directory(spec.dir);  // marked as Cellwright's: the child's `-o` is its own
        Running c;
        c.index = next;
        c.start = Clock::now();
        c.pid = spawn(executable, spec);
        running.push_back(c);
        ++next;
        if (callbacks.started) callbacks.started(c.index);
        changed = true;
      }
      const auto now = Clock::now();
      for (auto it = running.begin(); it != running.end();) {
        const ChildSpec& spec = children[it->index];
        const double elapsed = std::chrono::duration<double>(now - it->start).count();
        int raw = 0;
        const pid_t r = ::waitpid(it->pid, &raw, WNOHANG);
        if (r == it->pid) {
          ends[it->index] = finish(spec.dir, raw, it->killed, elapsed);
          const std::size_t index = it->index;
          it = running.erase(it);
          if (callbacks.ended) callbacks.ended(index, ends[index]);
          changed = true;
          continue;
        }
        if (!it->killed && elapsed > spec.timeout) {
          ::kill(it->pid, SIGKILL);
          it->killed = true;
        }
        ++it;
      }
      if (!changed) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  } catch (...) {
    kill_all();  // an error (or a callback's exception): no child outlives the caller
    throw;
  }
  return ends;
}

}  // namespace cellwright::cell
