// Command -> status latency of a robot whose robot control is in another process (docs/distributed.md, "Figures"),
// against the same exchange between two threads of one process, and the CPU an agent takes at rest.
//
// Each mode sends --commands commands one at a time (after --warmup unmeasured ones) and times each from its push into
// the robot's command queue to the pop of its status from the status queue, as task control sees it; the robot's side
// answers every command at once (an echo: robot control's own time is not in the figure):
//   in-process   the command queue and status queue between two threads (how a local robot's robot control talks)
//   dds          a RemoteRobot here, an AgentEndpoint in a child process (this program, re-executed as the agent),
//                over UDP on the loopback (Fast DDS 2.9, shared memory off as in a run)
// Printed per mode: p50, p99 and the largest, in microseconds. Then --rest seconds with the agent connected and
// idle: its CPU use from /proc/<pid>/stat (user + system time over wall time).
//
// Reproduce (pinned to one CPU, so both processes share it as on a loaded cell PC; drop taskset for two):
//   taskset -c 0 build/tools/dds_latency_bench [--commands 2000] [--warmup 200] [--rest 10] [--domain 150]
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include "cellwright/distributed/link.hpp"
#include "cellwright/runtime/message_queue.hpp"
#include "cellwright/task/compile.hpp"

extern char** environ;

namespace {

namespace d = cellwright::distributed;
namespace rt = cellwright::runtime;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

const std::string kProgram = std::string(CW_SOURCE_DIR) + "/scenes/exchange.task";

// The robot's side: every command answered done at once, until the queue closes or `stop` is set.
void echo(rt::MessageQueue<rt::MotionCommand>& commands, rt::MessageQueue<rt::RobotStatus>& statuses,
          const volatile sig_atomic_t* stop) {
  for (;;) {
    rt::MotionCommand c;
    rt::QueueStatus got = commands.pop_for(c, 100ms);
    if (got == rt::QueueStatus::closed || (stop != nullptr && *stop)) return;
    if (got != rt::QueueStatus::ok) continue;
    rt::RobotStatus s;
    s.robot = c.robot;
    s.index = c.index;
    s.outcome = rt::CommandOutcome::kDone;
    s.time = c.sent;
    statuses.push(s);
  }
}

volatile sig_atomic_t g_stop = 0;

// The agent process: `dds_latency_bench agent DOMAIN`, until SIGTERM.
int agent(int domain) {
  signal(SIGTERM, [](int) { g_stop = 1; });
  auto program = cellwright::task::compile_file(kProgram);
  d::Participant participant({.domain = domain}, "bench_agent");
  rt::MessageQueue<rt::MotionCommand> commands(4);
  rt::MessageQueue<rt::RobotStatus> statuses(16);
  d::AgentEndpoint endpoint(participant, "puma", 0, program, commands, statuses);
  endpoint.start();
  echo(commands, statuses, &g_stop);
  endpoint.stop();
  return 0;
}

struct Figures {
  double p50 = 0, p99 = 0, max = 0;  // microseconds
};

Figures figures(std::vector<double> us) {
  std::sort(us.begin(), us.end());
  auto at = [&](double q) { return us[static_cast<std::size_t>(q * static_cast<double>(us.size() - 1))]; };
  return {at(0.5), at(0.99), us.back()};
}

// Sends warmup + n commands one at a time; the latencies of the last n.
std::vector<double> measure(rt::MessageQueue<rt::MotionCommand>& commands, rt::MessageQueue<rt::RobotStatus>& statuses,
                            const cellwright::task::CompiledProgram& program, int warmup, int n) {
  std::vector<double> us;
  for (int k = 0; k < warmup + n; ++k) {
    rt::MotionCommand c;
    c.robot = 0;
    c.index = 0;
    c.primitive = program.programs[0].primitives[0];
    c.sent = std::chrono::milliseconds(k);
    auto t0 = Clock::now();
    commands.push(c);
    rt::RobotStatus s;
    if (statuses.pop_for(s, 10s) != rt::QueueStatus::ok) {
      std::fprintf(stderr, "no status for command %d within 10 s\n", k);
      std::exit(1);
    }
    if (k >= warmup) us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  }
  return us;
}

// user + system CPU seconds of process `pid` so far.
double cpu_seconds(pid_t pid) {
  std::ifstream in(fmt::format("/proc/{}/stat", pid));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(text.substr(text.rfind(')') + 2));  // after "pid (comm) "
  std::string f;
  double utime = 0, stime = 0;
  for (int k = 3; fields >> f; ++k) {  // field 3 is the state
    if (k == 14) utime = std::stod(f);
    if (k == 15) {
      stime = std::stod(f);
      break;
    }
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

int arg(int argc, char** argv, const char* name, int fallback) {
  for (int k = 1; k + 1 < argc; ++k) {
    if (std::string(argv[k]) == name) return std::atoi(argv[k + 1]);
  }
  return fallback;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "agent") return agent(std::atoi(argv[2]));
  const int n = arg(argc, argv, "--commands", 2000), warmup = arg(argc, argv, "--warmup", 200);
  const int rest = arg(argc, argv, "--rest", 10), domain = arg(argc, argv, "--domain", 150);
  auto program = cellwright::task::compile_file(kProgram);

  // In process: two threads and the two queues.
  Figures local;
  {
    rt::MessageQueue<rt::MotionCommand> commands(4);
    rt::MessageQueue<rt::RobotStatus> statuses(16);
    std::thread robot([&] { echo(commands, statuses, nullptr); });
    local = figures(measure(commands, statuses, program, warmup, n));
    commands.close();
    robot.join();
  }

  // Across processes: this program again as the agent.
  std::string self = "/proc/self/exe", mode = "agent", dom = std::to_string(domain);
  char* child_argv[] = {self.data(), mode.data(), dom.data(), nullptr};
  pid_t child = -1;
  if (posix_spawn(&child, "/proc/self/exe", nullptr, nullptr, child_argv, environ) != 0) {
    std::fprintf(stderr, "cannot start the agent process\n");
    return 1;
  }
  Figures remote;
  double cpu_percent = 0;
  {
    d::Participant participant({.domain = domain}, "bench_task_control");
    rt::MessageQueue<rt::MotionCommand> commands(4);
    rt::MessageQueue<rt::RobotStatus> statuses(16);
    d::RemoteRobot link(participant, "puma", 0, commands, statuses);
    if (!link.wait_for_agent(20s)) {
      std::fprintf(stderr, "no agent within 20 s on domain %d\n", domain);
      kill(child, SIGKILL);
      waitpid(child, nullptr, 0);
      return 1;
    }
    link.start();
    remote = figures(measure(commands, statuses, program, warmup, n));
    // At rest: connected, nothing sent.
    const double cpu0 = cpu_seconds(child);
    const auto t0 = Clock::now();
    std::this_thread::sleep_for(std::chrono::seconds(rest));  // the measurement's interval, not a wait for a result
    cpu_percent = 100.0 * (cpu_seconds(child) - cpu0) / std::chrono::duration<double>(Clock::now() - t0).count();
    link.stop();
  }
  kill(child, SIGTERM);
  waitpid(child, nullptr, 0);

  std::printf("command -> status latency, %d commands one at a time (after %d unmeasured), microseconds:\n", n, warmup);
  std::printf("  %-28s p50 %8.1f  p99 %8.1f  max %8.1f\n", "in process (two threads)", local.p50, local.p99, local.max);
  std::printf("  %-28s p50 %8.1f  p99 %8.1f  max %8.1f\n", "agent process (DDS, UDP)", remote.p50, remote.p99,
              remote.max);
  std::printf("  ratio of the medians: %.0fx\n", remote.p50 / local.p50);
  std::printf("agent at rest for %d s: %.2f %% of one CPU\n", rest, cpu_percent);
  return 0;
}
