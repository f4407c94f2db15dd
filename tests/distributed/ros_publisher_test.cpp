// The cell as ROS 2 sees it (distributed/ros_publisher.hpp): a lock-step run of the exchange on the paper's cell
// (scripted arms, no MuJoCo) publishes while a subscriber in another process (dds_peer ros-listen) reads what a ROS 2
// tool would; the test checks what it read against the run.
#include "cellwright/distributed/ros_publisher.hpp"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cellwright/models/robot_model.hpp"
#include "controller/runtime/scripted_cell.hpp"

extern char** environ;

namespace cellwright::distributed {
namespace {

using namespace std::chrono_literals;

// dds_peer ros-listen DOMAIN, its standard output on a pipe.
class Listener {
 public:
  explicit Listener(int domain) {
    int fds[2];
    if (pipe(fds) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    std::string d = std::to_string(domain);
    std::string path = CW_DDS_PEER, mode = "ros-listen";
    char* argv[] = {path.data(), mode.data(), d.data(), nullptr};
    if (posix_spawn(&pid_, CW_DDS_PEER, &actions, nullptr, argv, environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    out_ = fdopen(fds[0], "r");
  }
  ~Listener() {
    if (out_ != nullptr) fclose(out_);
    if (pid_ > 0 && !waited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  // The next line of its output ("" at its end).
  std::string line() {
    std::string text;
    int c;
    while (out_ != nullptr && (c = fgetc(out_)) != EOF && c != '\n') text.push_back(static_cast<char>(c));
    return text;
  }
  int wait() {
    int status = 0;
    waitpid(pid_, &status, 0);
    waited_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

 private:
  pid_t pid_ = -1;
  bool waited_ = false;
  FILE* out_ = nullptr;
};

struct Frame {
  std::string parent;
  Eigen::Vector3d t;
  Eigen::Quaterniond q;
};

Frame read_frame(std::istringstream& in, std::string& child) {
  Frame f;
  double qx, qy, qz, qw;
  in >> f.parent >> child >> f.t.x() >> f.t.y() >> f.t.z() >> qx >> qy >> qz >> qw;
  f.q = Eigen::Quaterniond(qw, qx, qy, qz);
  return f;
}

void expect_pose(const Frame& f, const Eigen::Isometry3d& want, const std::string& what) {
  EXPECT_LT((f.t - want.translation()).norm(), 1e-12) << what;
  EXPECT_LT(f.q.angularDistance(Eigen::Quaterniond(want.linear())), 1e-9) << what;
}

TEST(RosPublisher, ASubscriberInAnotherProcessReadsJointStatesTfAndEventsOfALockstepRun) {
  const int domain = 20 + static_cast<int>(getpid() % 200);
  Listener listener(domain);
  Participant participant({.domain = domain}, "cell");
  testing::ScriptedCell cell;
  cell.config.limits.settle = 100ms;  // the arms at rest for the last observations
  std::optional<RosPublisher> publisher(std::in_place, participant, cell.config.cell);
  publisher->attach(cell.config);
  // The run's joints every control period, every robot's in the cell's order: what each joint_states must show at its
  // stamp (the observers are called in one turn of the simulation thread, so both see the same model).
  std::map<std::int64_t, std::vector<double>> joints_at;  // by simulation time, ns
  cell.config.observers.push_back({cell.config.period, false, [&](const runtime::Observation& o) {
                                     std::vector<double>& q = joints_at[o.time.count()];
                                     o.environment.read([&](const runtime::EnvironmentModel& m) {
                                       for (const auto& spec : cell.config.cell.robots) {
                                         const auto& j = m.find_robot(spec.name)->joints;
                                         q.insert(q.end(), j.begin(), j.end());
                                       }
                                     });
                                   }});
  runtime::Runtime run(cell.config);
  ASSERT_EQ(listener.line(), "ready");
  ASSERT_TRUE(publisher->wait_for_subscribers(20s));
  publisher->start();
  runtime::RunResult result = run.run();
  ASSERT_EQ(result.outcome, runtime::Outcome::kFinished) << result.reason;
  EXPECT_TRUE(publisher->stop(10s));
  RosCounts counts = publisher->counts();
  publisher.reset();  // the writers go: the listener prints what it read

  std::vector<std::string> names;
  std::vector<std::pair<std::int64_t, std::vector<double>>> joint_states;  // stamp (ns), positions
  std::map<std::string, Frame> frames, statics;
  std::vector<std::string> events;
  std::uint64_t n_tf = 0, n_clock = 0;
  std::int64_t clock_sec = -1, clock_ns = -1;
  for (std::string l = listener.line(); !l.empty(); l = listener.line()) {
    std::istringstream in(l);
    std::string kind, child;
    in >> kind;
    if (kind == "joint_states") {
      std::int64_t sec = 0, ns = 0;
      in >> sec >> ns;
      joint_states.emplace_back(sec * 1'000'000'000 + ns, std::vector<double>());
      for (double p; in >> p;) joint_states.back().second.push_back(p);
    } else if (kind == "joint") {
      names.emplace_back();
      in >> names.back();
    } else if (kind == "tf") {
      in >> n_tf;
    } else if (kind == "frame" || kind == "static") {
      Frame f = read_frame(in, child);
      (kind == "frame" ? frames : statics)[child] = f;
    } else if (kind == "clock") {
      in >> n_clock >> clock_sec >> clock_ns;
    } else if (kind == "event") {
      events.push_back(l.substr(6));
    }
  }
  ASSERT_EQ(listener.wait(), 0);

  // Every event of the run's log, in order, as its JSONL line.
  EXPECT_EQ(events, run.log().lines());
  EXPECT_EQ(counts.events, events.size());
  EXPECT_EQ(counts.events_dropped, 0u);
  // Every joint_states reached the reader (reliable, and the reader keeps up), each with the joints the run had at
  // its stamp (how many there are depends on the wall time the run took: at most 50 a second).
  ASSERT_GE(joint_states.size(), 1u);
  EXPECT_EQ(joint_states.size(), counts.joint_states);
  for (const auto& [stamp, positions] : joint_states) {
    ASSERT_TRUE(joints_at.count(stamp)) << "a joint_states stamped " << stamp << " ns, not a control period's";
    EXPECT_EQ(positions, joints_at[stamp]) << "at " << stamp << " ns";  // 17 digits: exact
  }
  EXPECT_EQ(n_tf, counts.tf);
  EXPECT_EQ(n_clock, counts.joint_states);
  EXPECT_EQ(clock_sec * 1'000'000'000 + clock_ns, joint_states.back().first);  // the last clock is the last stamp

  // The last joint_states: both robots' joints, named as their URDFs name them with the robot's prefix, at the
  // positions the run ended with.
  std::vector<std::string> want_names;
  std::vector<double> want_positions;
  for (const models::RobotSpec& spec : cell.config.cell.robots) {
    models::KinematicChain chain = models::robot_chain(spec);
    for (const std::string& j : chain.joint_names()) want_names.push_back(spec.name + "_" + j);
    const runtime::RobotState* r = result.environment.find_robot(spec.name);
    ASSERT_NE(r, nullptr);
    want_positions.insert(want_positions.end(), r->joints.begin(), r->joints.end());

    // tf: base -> flange -> tool, as forward kinematics of those joints puts them; tf_static: the base in the world.
    models::MountedRobot mounted = models::load_robot(spec);
    Eigen::VectorXd q =
        Eigen::Map<const Eigen::VectorXd>(r->joints.data(), static_cast<Eigen::Index>(r->joints.size()));
    Eigen::Isometry3d flange =
        models::KinematicChain::from_urdf(mounted.arm, spec.base_link, spec.flange_link).forward(q);
    const std::string base = spec.name + "_" + spec.base_link, flange_frame = spec.name + "_" + spec.flange_link,
                      tool = spec.name + "_" + spec.tool_link;
    ASSERT_TRUE(frames.count(flange_frame)) << flange_frame;
    ASSERT_TRUE(frames.count(tool)) << tool;
    EXPECT_EQ(frames[flange_frame].parent, base);
    expect_pose(frames[flange_frame], flange, flange_frame);
    EXPECT_EQ(frames[tool].parent, flange_frame);
    expect_pose(frames[tool], flange.inverse() * models::robot_chain(spec, mounted).forward(q), tool);
    ASSERT_TRUE(statics.count(base)) << base;
    EXPECT_EQ(statics[base].parent, "world");
    expect_pose(statics[base], spec.base.transform(), base);
  }
  EXPECT_EQ(names, want_names);
  EXPECT_EQ(joint_states.back().second, want_positions);  // the last one: where the run ended (the arms at rest)
  // The fixed frames of the cell and the parts.
  for (const auto& c : cell.config.cell.conveyors) EXPECT_TRUE(statics.count("conveyor_" + c.name)) << c.name;
  for (const auto& c : cell.config.cell.cameras) EXPECT_TRUE(statics.count("camera_" + c.name)) << c.name;
  const runtime::WorkpieceState* a = result.environment.find_workpiece("A");
  ASSERT_NE(a, nullptr);
  ASSERT_TRUE(frames.count("workpiece_A"));
  expect_pose(frames["workpiece_A"], a->pose, "workpiece_A");
}

}  // namespace
}  // namespace cellwright::distributed
