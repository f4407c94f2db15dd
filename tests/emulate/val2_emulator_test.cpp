// The VAL II monitor emulator over a real pseudo-terminal: the test opens the published path as a driver would (raw
// termios), types lines and reads the answers with deadlines; a PumaFakeArm stands behind the monitor.
#include "cellwright/emulate/val2_emulator.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <future>
#include <locale>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"
#include "emulate/val2_fake_arm.hpp"

namespace cellwright::emulate {
namespace {

using namespace std::chrono_literals;
using testing::PumaFakeArm;
using Clock = std::chrono::steady_clock;

constexpr auto kDeadline = 5s;
constexpr double kDeg = std::numbers::pi / 180.0;
const std::string kPrompt = "\r\n.";

// Waits until `done()` holds or the deadline passes, looking again every few milliseconds (for conditions on the
// file system, which nothing can wait on).
template <typename F>
bool eventually(F done, std::chrono::nanoseconds timeout = kDeadline) {
  const auto until = Clock::now() + timeout;
  while (!done()) {
    if (Clock::now() > until) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

// The host's side of the line: the published path opened as a serial port is.
class Terminal {
 public:
  explicit Terminal(const std::filesystem::path& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) throw std::runtime_error("cannot open " + path.string() + ": " + std::strerror(errno));
    termios t{};
    tcgetattr(fd_, &t);
    cfmakeraw(&t);
    tcsetattr(fd_, TCSANOW, &t);
  }
  ~Terminal() { ::close(fd_); }
  Terminal(const Terminal&) = delete;
  Terminal& operator=(const Terminal&) = delete;

  void send(const std::string& bytes) {
    ASSERT_EQ(::write(fd_, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
  }

  // Reads until what came since the last call has a beginning that satisfies `done` (or the line hangs up, or the
  // deadline), and returns that beginning (or all that came); the rest is kept for the next call.
  template <typename F>
  std::string until_that(F done, std::chrono::nanoseconds timeout = kDeadline) {
    const auto deadline = Clock::now() + timeout;
    std::string got = std::move(rest_);
    rest_.clear();
    for (std::size_t checked = 0;;) {
      for (; checked <= got.size(); ++checked) {
        if (checked > 0 && done(got.substr(0, checked))) {
          rest_ = got.substr(checked);
          got.resize(checked);
          seen_ += got;
          return got;
        }
      }
      --checked;
      if (!read_some(&got, deadline)) break;
    }
    seen_ += got;
    return got;
  }
  // Reads until what came ends with `tail`.
  std::string until(const std::string& tail, std::chrono::nanoseconds timeout = kDeadline) {
    return until_that([&](const std::string& got) { return got.ends_with(tail); }, timeout);
  }
  // Reads until the prompt: a `.` that starts a line (the line before it may have come in an earlier call).
  std::string until_prompt(std::chrono::nanoseconds timeout = kDeadline) {
    const std::string before = seen_.size() >= 2 ? seen_.substr(seen_.size() - 2) : "\r\n";
    return until_that([&](const std::string& got) { return (before + got).ends_with(kPrompt); }, timeout);
  }
  // Sends one line (CR) and returns everything up to the prompt.
  std::string command(const std::string& line) {
    send(line + "\r");
    return until_prompt();
  }
  // What arrives within `timeout`, without waiting for anything in particular.
  std::string within(std::chrono::nanoseconds timeout) {
    return until_that([](const std::string&) { return false; }, timeout);
  }
  // True when the line hangs up (end of file, or an error) before the deadline.
  bool hangs_up(std::chrono::nanoseconds timeout = kDeadline) {
    std::string ignored;
    const auto deadline = Clock::now() + timeout;
    while (read_some(&ignored, deadline)) {
    }
    return hung_up_;
  }

 private:
  // Appends what one read gives; false at the deadline or on a hang-up.
  bool read_some(std::string* got, Clock::time_point deadline) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
    char buffer[512];
    const ssize_t n = ::read(fd_, buffer, sizeof buffer);
    if (n > 0) {
      got->append(buffer, static_cast<std::size_t>(n));
      return true;
    }
    if (n < 0 && errno == EAGAIN) return true;
    hung_up_ = true;
    return false;
  }

  int fd_ = -1;
  bool hung_up_ = false;
  std::string rest_;  // read, not yet returned
  std::string seen_;  // returned so far
};

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  for (std::size_t at; (at = text.find("\r\n", start)) != std::string::npos; start = at + 2) {
    lines.push_back(text.substr(start, at - start));
  }
  lines.push_back(text.substr(start));
  return lines;
}

std::vector<double> numbers_of(const std::string& line) {
  std::istringstream in(line);
  in.imbue(std::locale::classic());
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  return v;
}

// A WHERE answer read back: the six world values and the hand, and the six joints.
struct Where {
  std::vector<double> world, joints;
};

Where parse_where(const std::string& answer, const std::string& echo = "WHERE") {
  const std::vector<std::string> lines = split_lines(answer);
  // echo, header, world, joints, prompt
  EXPECT_EQ(lines.size(), 5u) << answer;
  if (lines.size() != 5) return {};
  EXPECT_EQ(lines[0], echo);
  EXPECT_EQ(lines[1], "     X/JT1      Y/JT2      Z/JT3      O/JT4      A/JT5      T/JT6      HAND");
  EXPECT_EQ(lines[4], ".");
  return {numbers_of(lines[2]), numbers_of(lines[3])};
}

// WHERE's world values give `location` back (0.01 mm, 0.01°).
void expect_location(const Where& w, const std::array<double, 6>& location) {
  ASSERT_EQ(w.world.size(), 7u);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(w.world[i], location[i], 0.01) << "value " << i;
}

// `joints` (degrees) are `expected` to within `tolerance`.
void expect_joints(const std::vector<double>& joints, const std::vector<double>& expected, double tolerance) {
  ASSERT_EQ(joints.size(), 6u);
  for (std::size_t j = 0; j < 6; ++j) EXPECT_NEAR(joints[j], expected[j], tolerance) << "joint " << j + 1;
}

std::vector<double> in_degrees(std::vector<double> q) {
  for (double& v : q) v /= kDeg;
  return q;
}

// The doc's orientation convention, written here from docs/real-robots.md: R = Rz(O)·Ry(A)·Rz(T)·Rx(180°).
Eigen::Isometry3d doc_location(const std::array<double, 6>& l) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(l[0], l[1], l[2]) / 1000.0;
  t.linear() = (Eigen::AngleAxisd(l[3] * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(l[4] * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(l[5] * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return t;
}

std::string trans(const std::array<double, 6>& l) {
  return fmt::format("TRANS({},{},{},{},{},{})", l[0], l[1], l[2], l[3], l[4], l[5]);
}

class Val2EmulatorTest : public ::testing::Test {
 protected:
  Val2EmulatorTest() {
    dir_ = std::filesystem::temp_directory_path() /
           fmt::format("cw-val2-{}-{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    link_ = dir_ / "puma";
  }
  ~Val2EmulatorTest() override {
    stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  // Serves on a thread; returns when the link is published.
  void start(Val2EmulatorOptions options = {}) {
    emulator_ = std::make_unique<Val2Emulator>(arm_, std::move(options));
    served_ = std::async(std::launch::async, [this] { emulator_->serve(link_); });
    ASSERT_TRUE(eventually([&] { return std::filesystem::is_symlink(link_); })) << "no pseudo-terminal at " << link_;
  }
  // Opens the line and reads the first prompt.
  std::unique_ptr<Terminal> connect() {
    auto t = std::make_unique<Terminal>(link_);
    EXPECT_EQ(t->until_prompt(), kPrompt);
    return t;
  }
  // Stops the emulator; true when serve() returned within the deadline (its exceptions are rethrown).
  bool stop() {
    if (!emulator_) return true;
    emulator_->stop();
    if (!served_.valid()) return true;
    const bool returned = served_.wait_for(kDeadline) == std::future_status::ready;
    if (returned) served_.get();
    return returned;
  }

  std::filesystem::path dir_, link_;
  PumaFakeArm arm_;
  std::unique_ptr<Val2Emulator> emulator_;
  std::future<void> served_;
};

// ---- the line ----

TEST_F(Val2EmulatorTest, PrintsThePromptAtStartAndAfterAnEmptyLine) {
  start();
  auto t = connect();
  EXPECT_EQ(t->command(""), kPrompt);  // the echo of nothing (CR LF), then the prompt
  EXPECT_EQ(emulator_->stats().lines, 1u);
}

TEST_F(Val2EmulatorTest, EchoesEachLineBeforeItsAnswer) {
  start();
  auto t = connect();
  const std::string answer = t->command("DO READY");
  EXPECT_EQ(answer, "DO READY" + kPrompt);
  const Where w = parse_where(t->command("WHERE"));
  EXPECT_EQ(w.joints.size(), 6u);
}

TEST_F(Val2EmulatorTest, WithoutEchoTheAnswerStillStartsItsOwnLine) {
  Val2EmulatorOptions options;
  options.echo = false;
  start(options);
  auto t = connect();
  EXPECT_EQ(t->command("DO READY"), kPrompt);
  const std::vector<std::string> lines = split_lines(t->command("WHERE"));
  ASSERT_EQ(lines.size(), 5u);
  EXPECT_EQ(lines[0], "");  // the line the host typed on (after the prompt) is ended first
  EXPECT_EQ(lines[1].substr(0, 10), "     X/JT1");
  EXPECT_EQ(lines[4], ".");
  EXPECT_EQ(t->command("DO FLY"), "\r\n*Unknown instruction*" + kPrompt);
}

TEST_F(Val2EmulatorTest, ThePromptReturnsWhenTheMotionHasEnded) {
  start();
  auto t = connect();
  arm_.hold(true);
  t->send("DO READY\r");
  EXPECT_EQ(t->until("DO READY\r\n"), "DO READY\r\n");
  ASSERT_TRUE(arm_.in_motion_within(kDeadline));
  // Held by the arm, the monitor cannot have answered: no prompt is there to read.
  EXPECT_EQ(t->within(50ms), "");
  arm_.let_one_through();
  EXPECT_EQ(t->until_prompt(), ".");
  EXPECT_EQ(arm_.joints(), arm_.home());
}

// ---- motion ----

TEST_F(Val2EmulatorTest, ReadyMovesHomeAtTheMonitorSpeed) {
  start();
  auto t = connect();
  t->command("SPEED 40");
  t->command("DO READY");
  const auto moves = arm_.puma_moves();
  ASSERT_EQ(moves.size(), 1u);
  EXPECT_EQ(moves[0].target, arm_.home());
  EXPECT_DOUBLE_EQ(moves[0].speed, 0.4);
  EXPECT_FALSE(moves[0].linear);
  EXPECT_EQ(arm_.joints(), arm_.home());
}

TEST_F(Val2EmulatorTest, MoveTransThenWhereGivesTheLocationBack) {
  start();
  auto t = connect();
  // A general orientation, one with A negative (the other Z-Y-Z set), and one with A = 0 (O and T share one turn).
  const std::array<double, 6> locations[] = {
      {400, 150, 500, 30, 20, -15}, {450, 0, 700, 90, -90, 0}, {500, -100, 300, 25, 0, 10}};
  for (const auto& l : locations) {
    SCOPED_TRACE(trans(l));
    EXPECT_EQ(t->command("DO MOVE " + trans(l)), "DO MOVE " + trans(l) + kPrompt);
    const Where w = parse_where(t->command("WHERE"));
    expect_location(w, l);
    ASSERT_EQ(w.world.size(), 7u);
    EXPECT_NEAR(w.world[6], arm_.gripper_opening() * 1000, 0.001);
    // The arm stands where the doc's convention puts the location.
    const std::vector<double> q = arm_.joints();
    const Eigen::Isometry3d reached =
        arm_.chain().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
    const Eigen::Isometry3d wanted = doc_location(l);
    EXPECT_LT((reached.translation() - wanted.translation()).norm(), 1e-5);
    EXPECT_LT(Eigen::AngleAxisd(reached.linear().transpose() * wanted.linear()).angle(), 1e-5);
    expect_joints(w.joints, in_degrees(q), 0.0005);
    EXPECT_FALSE(arm_.puma_moves().back().linear);
  }
}

TEST_F(Val2EmulatorTest, MovesIsAStraightLineMove) {
  start();
  auto t = connect();
  const std::array<double, 6> l{300, 200, 400, -40, 35, 60};
  EXPECT_EQ(t->command("DO MOVES " + trans(l)), "DO MOVES " + trans(l) + kPrompt);
  ASSERT_EQ(arm_.puma_moves().size(), 1u);
  EXPECT_TRUE(arm_.puma_moves()[0].linear);
  expect_location(parse_where(t->command("WHERE")), l);
}

TEST_F(Val2EmulatorTest, PrecisionPointMovesTheJoints) {
  start();
  auto t = connect();
  const std::vector<double> j{10, 20, -30, 40, -50, 60};
  EXPECT_EQ(t->command("DO MOVE #PPOINT(10,20,-30,40,-50,60)"), "DO MOVE #PPOINT(10,20,-30,40,-50,60)" + kPrompt);
  expect_joints(in_degrees(arm_.joints()), j, 1e-9);
  expect_joints(parse_where(t->command("WHERE")).joints, j, 0.0005);
}

TEST_F(Val2EmulatorTest, HandOpensAndClosesAtOnce) {
  start();
  auto t = connect();
  EXPECT_EQ(t->command("DO CLOSEI"), "DO CLOSEI" + kPrompt);
  EXPECT_TRUE(arm_.gripper_closed());
  EXPECT_NEAR(parse_where(t->command("WHERE")).world.at(6), 0.0, 1e-9);
  EXPECT_EQ(t->command("DO OPENI"), "DO OPENI" + kPrompt);
  EXPECT_FALSE(arm_.gripper_closed());
  EXPECT_EQ(arm_.grips(), (std::vector<bool>{true, false}));
}

// ---- I/O ----

TEST_F(Val2EmulatorTest, SignalSetsAndClearsOutputs) {
  start();
  auto t = connect();
  t->command("DO SIGNAL 3");
  EXPECT_TRUE(arm_.output(3));
  t->command("DO SIGNAL -3, 32,1");
  EXPECT_FALSE(arm_.output(3));
  EXPECT_TRUE(arm_.output(32));
  EXPECT_TRUE(arm_.output(1));
  // One bad value refuses the whole instruction.
  EXPECT_EQ(t->command("DO SIGNAL -1,33"), "DO SIGNAL -1,33\r\n*Illegal value*" + kPrompt);
  EXPECT_TRUE(arm_.output(1));
}

TEST_F(Val2EmulatorTest, WaitSigReturnsWhenTheInputComes) {
  start();
  auto t = connect();
  t->send("DO WAIT SIG(1004)\r");
  EXPECT_EQ(t->until("\r\n"), "DO WAIT SIG(1004)\r\n");
  EXPECT_EQ(t->within(50ms), "");  // input 4 is off: no prompt
  arm_.set_input(4, true);
  EXPECT_EQ(t->until_prompt(), ".");

  t->send("DO WAIT SIG(-1004)\r");
  EXPECT_EQ(t->until("\r\n"), "DO WAIT SIG(-1004)\r\n");
  EXPECT_EQ(t->within(50ms), "");
  arm_.set_input(4, false);
  EXPECT_EQ(t->until_prompt(), ".");
  // Already at the level: at once.
  EXPECT_EQ(t->command("DO WAIT SIG(-1004)"), "DO WAIT SIG(-1004)" + kPrompt);
}

// ---- errors ----

TEST_F(Val2EmulatorTest, EachErrorIsOneStarLineBeforeThePromptAndNothingMoves) {
  start();
  auto t = connect();
  const std::pair<std::string, std::string> cases[] = {
      {"DO MOVE TRANS(3000,0,0,0,0,0)", "*Location out of range*"},
      {"DO MOVES TRANS(0,0,3000,0,0,0)", "*Location out of range*"},
      {"DO MOVE #PPOINT(0,0,0,0,120,0)", "*Joint 5 limit stop*"},
      {"DO MOVE #PPOINT(170,0,0,0,0,0)", "*Joint 1 limit stop*"},
      {"DO JUMP", "*Unknown instruction*"},
      {"FLY", "*Unknown instruction*"},
      {"DO MOV TRANS(400,150,500,30,20,-15)", "*Unknown instruction*"},  // MOVE, MOVES or MOVET
      {"DO OPEN", "*Unknown instruction*"},                              // a VAL II instruction not emulated
      {"EXECUTE pick", "*Undefined program*"},  // no program of that name was loaded
      {"S 50", "*Unknown instruction*"},  // SPEED or STORE
      {"DO", "*Invalid argument*"},
      {"DO MOVE TRANS(1,2,3,4,5)", "*Invalid argument*"},
      {"DO MOVE TRANS(1,2,3,4,5,6,7)", "*Invalid argument*"},
      {"DO MOVE P1", "*Invalid argument*"},
      {"DO MOVES #PPOINT(0,90,-90,0,0,0)", "*Invalid argument*"},
      {"DO MOVE TRANS(1,2,x,4,5,6)", "*Invalid argument*"},
      {"DO MOVE", "*Invalid argument*"},
      {"SPEED fast", "*Invalid argument*"},
      {"SPEED", "*Invalid argument*"},
      {"SPEED 50 ALWAYS", "*Invalid argument*"},
      {"DO READY 3", "*Invalid argument*"},
      {"WHERE 2", "*Invalid argument*"},
      {"DO WAIT 1001", "*Invalid argument*"},
      {"SPEED 0", "*Illegal value*"},
      {"SPEED 100.5", "*Illegal value*"},
      {"DO SIGNAL 0", "*Illegal value*"},
      {"DO SIGNAL 2.5", "*Illegal value*"},
      {"DO WAIT SIG(5)", "*Illegal value*"},
      {"DO WAIT SIG(1033)", "*Illegal value*"},
      {"DO MOVE TRANS(1,2,3,4,5,6", "*Syntax error*"},
      {"DO MOVE TRANS(1,,3,4,5,6)", "*Syntax error*"},
      {"DO MOVE TRANS 1,2,3,4,5,6", "*Syntax error*"},
      {"DO MOVE TRANS(1,2,3,4,5,6))", "*Syntax error*"},
      {"WHERE $", "*Syntax error*"},
      {std::string(300, 'W'), "*Syntax error*"},
  };
  for (const auto& [line, error] : cases) {
    EXPECT_EQ(t->command(line), line.substr(0, 255) + "\r\n" + error + kPrompt) << line;
  }
  EXPECT_TRUE(arm_.puma_moves().empty());
  EXPECT_EQ(emulator_->stats().errors, std::size(cases));
  EXPECT_EQ(emulator_->stats().last_error, "*Syntax error*");
  // The monitor goes on as usual.
  EXPECT_EQ(t->command("DO READY"), "DO READY" + kPrompt);
  EXPECT_EQ(arm_.joints(), arm_.home());
}

TEST_F(Val2EmulatorTest, AnArmThatCannotFinishIsAServoError) {
  start();
  auto t = connect();
  arm_.fail_with(ArmStatus::failed);
  EXPECT_EQ(t->command("DO READY"), "DO READY\r\n*Servo error*" + kPrompt);
  EXPECT_EQ(emulator_->stats().last_failure, "the PUMA fake was told to fail");
}

// ---- what a terminal user may type ----

TEST_F(Val2EmulatorTest, AcceptsAbbreviationsAnyCaseSpacesAndLineEnds) {
  start();
  auto t = connect();
  t->send("d rea\n");  // DO READY, LF only
  EXPECT_EQ(t->until_prompt(), "d rea" + kPrompt);
  EXPECT_EQ(arm_.joints(), arm_.home());

  t->send("Sp 25\r\n");
  EXPECT_EQ(t->until_prompt(), "Sp 25" + kPrompt);
  const std::array<double, 6> l{400, 150, 500, 30, 20, -15};
  t->send("  Do\tmoveS   trans ( 400 , +150.0 , 5e2 , 30 , 20,-15. )  \r\n");
  t->until_prompt();
  ASSERT_EQ(arm_.puma_moves().size(), 2u);
  EXPECT_TRUE(arm_.puma_moves()[1].linear);
  EXPECT_DOUBLE_EQ(arm_.puma_moves()[1].speed, 0.25);

  // CR LF is one line end: two commands give two answers, and the empty line after them is the third line.
  t->send("wh\r\nWhErE\r\n");
  expect_location(parse_where(t->until_prompt(), "wh"), l);
  parse_where(t->until_prompt(), "WhErE");
  EXPECT_EQ(t->command(""), kPrompt);
  EXPECT_EQ(emulator_->stats().lines, 6u);

  // Backspace and DEL erase, as on a terminal; the echo is the line as corrected.
  t->send(
      "DO SIGNX\bAL 7\x7f"
      "8\r");
  EXPECT_EQ(t->until_prompt(), "DO SIGNAL 8" + kPrompt);
  EXPECT_TRUE(arm_.output(8));
  EXPECT_FALSE(arm_.output(7));
  t->send("do move #ppoint(0,90,-90,0,0,0)\r");
  EXPECT_EQ(t->until_prompt(), "do move #ppoint(0,90,-90,0,0,0)" + kPrompt);
  EXPECT_EQ(arm_.puma_moves().size(), 3u);
  EXPECT_EQ(t->command("DO CLOSEI"), "DO CLOSEI" + kPrompt);
  EXPECT_EQ(t->command("do sig 1,2"), "do sig 1,2" + kPrompt);
  EXPECT_TRUE(arm_.output(2));
}

// ---- misbehaviours ----

class Val2MisbehaviourTest : public Val2EmulatorTest {
 protected:
  // Starts with `spec` (misbehaviour.hpp) and answers the first line normally.
  std::unique_ptr<Terminal> start_with(const std::string& spec, Val2EmulatorOptions options = {}) {
    options.misbehaviours.push_back(parse_misbehaviour(spec));
    start(options);
    auto t = connect();
    EXPECT_EQ(t->command(""), kPrompt);
    return t;
  }
};

TEST_F(Val2MisbehaviourTest, ErrorPrintsArmPowerOffInsteadOfDoingTheLine) {
  auto t = start_with("error@2");
  EXPECT_EQ(t->command("DO READY"), "DO READY\r\n*Arm power off*" + kPrompt);
  EXPECT_TRUE(arm_.puma_moves().empty());
  EXPECT_EQ(t->command("DO READY"), "DO READY" + kPrompt);
  EXPECT_EQ(arm_.puma_moves().size(), 1u);
  EXPECT_EQ(emulator_->stats().misbehaviours, 1u);
}

// Aimed at commands rather than lines, and scripted: the second WHERE fails, then the first DO READY after it prints
// an error the driver's list does not have; the position reads around them do not shift either.
TEST_F(Val2MisbehaviourTest, MisbehavioursAimedAtCommandsFollowEachOther) {
  Val2EmulatorOptions options;
  options.misbehaviours = {parse_misbehaviour("error@where#2"), parse_misbehaviour("unknown@ do ready #1")};
  EXPECT_EQ(to_string(options.misbehaviours[1]), "unknown@DOREADY#1");
  EXPECT_EQ(to_string(parse_misbehaviour(to_string(options.misbehaviours[1]))), "unknown@DOREADY#1");
  start(options);
  auto t = connect();
  EXPECT_EQ(t->command("DO READY"), "DO READY" + kPrompt);  // not armed yet
  EXPECT_EQ(t->command("where").find('*'), std::string::npos);
  EXPECT_EQ(t->command("WHERE"), "WHERE\r\n*Arm power off*" + kPrompt);
  EXPECT_EQ(t->command("WHERE").find('*'), std::string::npos);
  EXPECT_EQ(t->command("DO READY"), "DO READY\r\n*Invalid format*" + kPrompt);
  EXPECT_EQ(t->command("DO READY"), "DO READY" + kPrompt);
  EXPECT_EQ(emulator_->stats().misbehaviours, 2u);
}

TEST_F(Val2MisbehaviourTest, AMisbehaviourAimedAtNoCommandIsRefused) {
  EXPECT_THROW(parse_misbehaviour("error@#2"), InputError);
  EXPECT_THROW(parse_misbehaviour("error@where#0"), InputError);
  EXPECT_THROW(parse_misbehaviour("error~where#0.5"), InputError);
}

TEST_F(Val2MisbehaviourTest, UnreachablePrintsLocationOutOfRange) {
  auto t = start_with("unreachable@2");
  EXPECT_EQ(t->command("DO READY"), "DO READY\r\n*Location out of range*" + kPrompt);
  EXPECT_TRUE(arm_.puma_moves().empty());
}

TEST_F(Val2MisbehaviourTest, GarbageReplacesTheAnswerAndThePrompt) {
  auto t = start_with("garbage@2");
  t->send("WHERE\r");
  // The next line (an empty one, as a driver's reset sends) is answered as usual.
  t->send("\r");
  const std::string got = t->until_prompt();
  ASSERT_TRUE(got.starts_with("WHERE\r\n")) << got;
  ASSERT_TRUE(got.ends_with("\r\n\r\n.")) << got;  // garbage's CR LF, the empty line's echo, the prompt
  const std::string garbage = got.substr(7, got.size() - 7 - 5);
  ASSERT_FALSE(garbage.empty());
  for (const char c : garbage) {
    const auto b = static_cast<unsigned char>(c);
    EXPECT_TRUE(b >= 0x80 && b <= 0xFE) << "byte " << static_cast<int>(b);
  }
}

TEST_F(Val2MisbehaviourTest, GarbageStillCarriesTheLineOut) {
  auto t = start_with("garbage@2");
  t->send("DO READY\r\r");
  t->until_prompt();
  EXPECT_EQ(arm_.joints(), arm_.home());
}

TEST_F(Val2MisbehaviourTest, SilentSwallowsTheLine) {
  auto t = start_with("silent@2");
  t->send("DO READY\r");
  // The next line's answer comes first and alone: nothing was echoed, answered or done for the silent one.
  parse_where(t->command("WHERE"));
  EXPECT_TRUE(arm_.puma_moves().empty());
  EXPECT_EQ(emulator_->stats().lines, 3u);
}

TEST_F(Val2MisbehaviourTest, LateAnswersAfterTheDelay) {
  auto t = start_with("late@2:0.3");
  const auto sent = Clock::now();
  t->send("DO READY\r");
  EXPECT_EQ(t->until("DO READY\r\n"), "DO READY\r\n");  // the echo comes at once
  EXPECT_EQ(t->until_prompt(), ".");
  EXPECT_GE(Clock::now() - sent, 300ms);
  EXPECT_EQ(arm_.joints(), arm_.home());
}

TEST_F(Val2MisbehaviourTest, DropHangsUpAndANewLineAnswersAtThePath) {
  Val2EmulatorOptions options;
  options.reconnect_delay = 50ms;
  auto t = start_with("drop@3", options);
  EXPECT_EQ(t->command("DO MOVE #PPOINT(10,20,-30,40,-50,60)"), "DO MOVE #PPOINT(10,20,-30,40,-50,60)" + kPrompt);
  const std::filesystem::path first = std::filesystem::read_symlink(link_);
  t->send("DO READY\r");
  EXPECT_TRUE(t->hangs_up());
  t.reset();
  ASSERT_TRUE(eventually([&] {
    std::error_code ec;
    const auto now = std::filesystem::read_symlink(link_, ec);
    return !ec && now != first;
  }));
  auto again = connect();
  // The arm did not take the dropped line, and kept its place.
  EXPECT_EQ(arm_.puma_moves().size(), 1u);
  expect_joints(parse_where(again->command("WHERE")).joints, {10, 20, -30, 40, -50, 60}, 0.0005);
  EXPECT_EQ(emulator_->stats().connections, 2u);
  EXPECT_EQ(emulator_->stats().lines, 4u);  // the count goes on over the reconnection
}

// One run of lines under a random plan: per line '.' (answered), 'E' (*Arm power off*), 'U' (*Location out of
// range*), 'G' (garbage).
std::string random_run(std::uint64_t seed, int lines, const std::vector<Misbehaviour>& plan) {
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("cw-val2-random-{}-{}", ::getpid(), seed);
  std::filesystem::create_directories(dir);
  PumaFakeArm arm;
  Val2EmulatorOptions options;
  options.seed = seed;
  options.misbehaviours = plan;
  Val2Emulator emulator(arm, options);
  auto served = std::async(std::launch::async, [&] { emulator.serve(dir / "puma"); });
  std::string run;
  if (eventually([&] { return std::filesystem::is_symlink(dir / "puma"); })) {
    Terminal t(dir / "puma");
    t.until_prompt();
    for (int i = 0; i < lines; ++i) {
      t.send("\r");
      EXPECT_EQ(t.until("\r\n"), "\r\n");  // the echo
      // A line, or the prompt alone.
      const std::string answer =
          t.until_that([](const std::string& got) { return got == "." || got.ends_with("\r\n"); });
      if (answer == "*Arm power off*\r\n") {
        run += 'E';
      } else if (answer == "*Location out of range*\r\n") {
        run += 'U';
      } else if (answer.size() > 2 && static_cast<unsigned char>(answer[0]) >= 0x80) {
        run += 'G';
        continue;  // no prompt follows garbage
      } else {
        run += answer == "." ? '.' : '?';
        continue;
      }
      EXPECT_EQ(t.until("."), ".");
    }
  }
  emulator.stop();
  served.get();
  std::filesystem::remove_all(dir);
  return run;
}

TEST(Val2MisbehaviourPlan, TheSameSeedGivesTheSameLines) {
  const std::vector<Misbehaviour> plan = {parse_misbehaviour("error~0.2"), parse_misbehaviour("unreachable~0.2"),
                                          parse_misbehaviour("garbage~0.2")};
  const std::string first = random_run(7, 40, plan);
  EXPECT_EQ(first, random_run(7, 40, plan));
  // And they are the plan's: the emulator takes one decision per line.
  MisbehaviourPlan expected(plan, 7);
  std::string lines;
  for (int i = 0; i < 40; ++i) {
    const auto m = expected.next_line();
    lines += !m ? '.' : m->kind == MisbehaviourKind::error ? 'E' : m->kind == MisbehaviourKind::unreachable ? 'U' : 'G';
  }
  EXPECT_EQ(first, lines);
  EXPECT_NE(first.find_first_not_of('.'), std::string::npos);
  EXPECT_NE(random_run(8, 40, plan), first);
}

// ---- stopping ----

TEST_F(Val2EmulatorTest, StopEndsServeWhileIdleAndRemovesTheLink) {
  start();
  auto t = connect();
  EXPECT_TRUE(stop());
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(link_)));
}

TEST_F(Val2EmulatorTest, StopEndsServeDuringAMotion) {
  start();
  auto t = connect();
  arm_.hold(true);
  t->send("DO READY\r");
  ASSERT_TRUE(arm_.in_motion_within(kDeadline));
  EXPECT_TRUE(stop());
}

TEST_F(Val2EmulatorTest, StopEndsServeDuringAWait) {
  start();
  auto t = connect();
  t->send("DO WAIT SIG(1001)\r");
  t->until("\r\n");
  EXPECT_TRUE(stop());
  EXPECT_TRUE(arm_.interrupted());
}

TEST_F(Val2MisbehaviourTest, StopEndsServeWhileWaitingToReconnect) {
  Val2EmulatorOptions options;
  options.reconnect_delay = std::chrono::hours(1);
  auto t = start_with("drop@2", options);
  t->send("\r");
  EXPECT_TRUE(t->hangs_up());
  EXPECT_TRUE(stop());
}

TEST_F(Val2EmulatorTest, StopBeforeServeReturnsAtOnce) {
  Val2Emulator emulator(arm_, {});
  emulator.stop();
  auto served = std::async(std::launch::async, [&] { emulator.serve(link_); });
  EXPECT_EQ(served.wait_for(kDeadline), std::future_status::ready);
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(link_)));
}

TEST_F(Val2EmulatorTest, ServeThrowsWhenThePathCannotBePublished) {
  Val2Emulator emulator(arm_, {});
  EXPECT_THROW(emulator.serve(dir_ / "missing" / "puma"), InputError);
}

TEST(Val2EmulatorOptionsTest, RefusesASpeedOutsideOneToHundred) {
  PumaFakeArm arm;
  Val2EmulatorOptions options;
  options.speed = 0;
  EXPECT_THROW(Val2Emulator(arm, options), InputError);
}

}  // namespace
}  // namespace cellwright::emulate
