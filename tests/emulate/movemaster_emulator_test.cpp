// The Movemaster EX emulator over a real pseudo-terminal: the test opens the published path as a host would (raw
// termios), writes command lines and reads the answers with deadlines. The arm is a FakeArm.
#include "cellwright/emulate/movemaster_emulator.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <future>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "emulate/fake_arm.hpp"

namespace cellwright::emulate {
namespace {

using namespace std::chrono_literals;
using testing::FakeArm;

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr auto kDeadline = 10s;  // for answers that must come; generous for loaded machines

// The host's side of the line: the published path opened as a driver opens a serial port.
class Host {
 public:
  explicit Host(const std::filesystem::path& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      ADD_FAILURE() << "cannot open " << path << ": " << std::strerror(errno);
      return;
    }
    termios t{};
    ::tcgetattr(fd_, &t);
    ::cfmakeraw(&t);
    ::tcsetattr(fd_, TCSANOW, &t);
  }
  ~Host() {
    if (fd_ >= 0) ::close(fd_);
  }
  Host(const Host&) = delete;
  Host& operator=(const Host&) = delete;

  void send(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
      if (n > 0) {
        bytes.remove_prefix(static_cast<std::size_t>(n));
      } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
        ADD_FAILURE() << "write: " << std::strerror(errno);
        return;
      } else {
        pollfd p{fd_, POLLOUT, 0};
        ::poll(&p, 1, 100);
      }
    }
  }

  // The next answer line with its end (up to and including LF), or nullopt if none came within `timeout`.
  std::optional<std::string> line(std::chrono::milliseconds timeout = kDeadline) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const std::size_t lf = buffer_.find('\n');
      if (lf != std::string::npos) {
        std::string l = buffer_.substr(0, lf + 1);
        buffer_.erase(0, lf + 1);
        return l;
      }
      if (!fill(end)) return std::nullopt;
    }
  }

  // True if nothing has arrived by now (the emulator cannot have answered yet when it is inside a held motion).
  bool nothing_yet() {
    char c;
    return buffer_.empty() && ::read(fd_, &c, 1) < 0 && errno == EAGAIN;
  }

  // Waits until the emulator hangs up (the read side reports end-of-file or an error); false at the deadline.
  bool wait_hang_up(std::chrono::milliseconds timeout = kDeadline) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0) return false;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char bytes[64];
      const ssize_t n = ::read(fd_, bytes, sizeof bytes);
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) return true;
    }
  }

 private:
  // Reads what is there, waiting until `end`; false when nothing came.
  bool fill(std::chrono::steady_clock::time_point end) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
    char bytes[256];
    const ssize_t n = ::read(fd_, bytes, sizeof bytes);
    if (n > 0) buffer_.append(bytes, static_cast<std::size_t>(n));
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) return false;  // hung up
    return true;
  }

  int fd_ = -1;
  std::string buffer_;
};

// An emulator serving a fresh path on its own thread, a FakeArm behind it and a host on the line.
class Session {
 public:
  explicit Session(MovemasterEmulatorOptions options = {}) {
    static std::atomic<int> serial{0};
    dir_ = std::filesystem::path(::testing::TempDir()) / fmt::format("cw-movemaster-{}-{}", ::getpid(), ++serial);
    std::filesystem::create_directories(dir_);
    link = dir_ / "melfa";
    emulator = std::make_unique<MovemasterEmulator>(arm, std::move(options));
    served_ = served_promise_.get_future();
    thread_ = std::thread([this] {
      try {
        emulator->serve(link);
      } catch (const std::exception& e) {
        ADD_FAILURE() << "serve() threw: " << e.what();
      }
      served_promise_.set_value();
    });
    EXPECT_TRUE(emulator->wait_published(1, kDeadline));
    host = std::make_unique<Host>(link);
  }
  ~Session() {
    host.reset();
    emulator->stop();
    thread_.join();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  // Sends one command line (CR LF).
  void tell(std::string_view command) { host->send(std::string(command) + "\r\n"); }
  // Sends one command line and returns its answer, with its line end; "(none)" if no answer came in time.
  std::string ask(std::string_view command) {
    tell(command);
    return host->line().value_or("(none)");
  }
  // True if serve() has returned within `timeout`.
  bool served_within(std::chrono::milliseconds timeout) {
    return served_.wait_for(timeout) == std::future_status::ready;
  }

  FakeArm arm;
  std::filesystem::path link;
  std::unique_ptr<MovemasterEmulator> emulator;
  std::unique_ptr<Host> host;

 private:
  std::filesystem::path dir_;
  std::promise<void> served_promise_;
  std::future<void> served_;
  std::thread thread_;
};

struct Pose {
  double x, y, z, p, r;
};

// Five signed numbers with one decimal, comma-separated, ended by CR LF (checked by hand: GCC 12's <regex> warns
// falsely under ASan).
bool wh_form(const std::string& a) {
  if (a.size() < 2 || a.compare(a.size() - 2, 2, "\r\n") != 0) return false;
  std::size_t i = 0;
  for (int field = 0; field < 5; ++field) {
    if (field > 0 && (i >= a.size() || a[i++] != ',')) return false;
    if (i >= a.size() || (a[i] != '+' && a[i] != '-')) return false;
    ++i;
    const std::size_t digits = i;
    while (i < a.size() && std::isdigit(static_cast<unsigned char>(a[i])) != 0) ++i;
    if (i == digits || i + 1 >= a.size() || a[i] != '.' || std::isdigit(static_cast<unsigned char>(a[i + 1])) == 0) {
      return false;
    }
    i += 2;
  }
  return i == a.size() - 2;
}

// WH's answer as numbers; fails the test when it is not five signed numbers with one decimal, ended by CR LF.
Pose parse_where(const std::string& answer) {
  EXPECT_TRUE(wh_form(answer)) << "WH answered '" << answer << "'";
  double v[5] = {};
  std::size_t at = 0;
  for (double& value : v) {
    if (at >= answer.size()) break;
    if (answer[at] == '+') ++at;
    const auto [ptr, ec] = std::from_chars(answer.data() + at, answer.data() + answer.size(), value);
    at = static_cast<std::size_t>(ptr - answer.data()) + 1;
  }
  return {v[0], v[1], v[2], v[3], v[4]};
}

void expect_near(const Pose& got, const Pose& want, double mm, double deg) {
  EXPECT_NEAR(got.x, want.x, mm);
  EXPECT_NEAR(got.y, want.y, mm);
  EXPECT_NEAR(got.z, want.z, mm);
  EXPECT_NEAR(got.p, want.p, deg);
  EXPECT_NEAR(got.r, want.r, deg);
}

std::string mp(const Pose& p) {
  return fmt::format("MP {:.1f},{:.1f},{:.1f},{:.1f},{:.1f}", p.x, p.y, p.z, p.p, p.r);
}

// The arm's tool frame (the chain's tcp) where it stands.
Eigen::Isometry3d tcp(const FakeArm& arm) {
  const std::vector<double> q = arm.joints();
  return arm.chain().forward(Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size())));
}

// Reachable poses of the MELFA (tool point in mm, pitch, roll in degrees).
constexpr Pose kDown{300, 100, 200, -90, 0};
constexpr Pose kTilted{350, -50, 350, -45, 30};
constexpr Pose kSideways{0, 400, 350, 0, 90};

TEST(MovemasterEmulatorTest, NestMoveAndWhereRoundTrip) {
  Session s;
  s.tell("NT");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  ASSERT_EQ(s.arm.move_count(), 1u);
  EXPECT_EQ(s.arm.moves()[0].target, s.arm.home());
  EXPECT_FALSE(s.arm.moves()[0].linear);
  for (const Pose& p : {kDown, kTilted, kSideways}) {
    s.tell(mp(p));
    EXPECT_EQ(s.ask("ER"), "0\r\n") << mp(p);
    EXPECT_FALSE(s.arm.moves().back().linear) << "MP is joint-interpolated";
    expect_near(parse_where(s.ask("WH")), p, 0.1, 0.1);
  }
  const MovemasterEmulator::Stats st = s.emulator->stats();
  EXPECT_EQ(st.lines, 11u);
  EXPECT_EQ(st.executed, 11u);
  EXPECT_EQ(st.er_answers[0], 4u);
  EXPECT_EQ(st.format_errors, 0u);
}

// The 5-axis rule as the doc writes it: the tool frame the arm reaches, checked column by column.
TEST(MovemasterEmulatorTest, PoseFollowsTheFiveAxisRule) {
  Session s;
  s.tell(mp({300, 0, 200, -90, 0}));  // azimuth 0, straight down: x = w × a = (−1, 0, 0), y = w = (0, 1, 0)
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  Eigen::Isometry3d t = tcp(s.arm);
  EXPECT_LT((t.translation() - Eigen::Vector3d(0.3, 0, 0.2)).norm(), 1e-4);
  EXPECT_LT((t.linear().col(0) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-3);
  EXPECT_LT((t.linear().col(1) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-3);
  EXPECT_LT((t.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-3);

  s.tell(mp(kSideways));  // azimuth 90, horizontal outward (a = +y), rolled 90: x = w = (−1, 0, 0), y = −(w × a) = +z
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  t = tcp(s.arm);
  EXPECT_LT((t.translation() - Eigen::Vector3d(0, 0.4, 0.35)).norm(), 1e-4);
  EXPECT_LT((t.linear().col(0) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-3);
  EXPECT_LT((t.linear().col(1) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-3);
  EXPECT_LT((t.linear().col(2) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-3);
}

TEST(MovemasterEmulatorTest, UnreachablePoseAnswersTwoMovesNothingAndResetClears) {
  Session s;
  const std::string home_where = s.ask("WH");
  for (const char* line : {"MP 900,0,300,0,0", "MP 0,0,500,-90,0"}) {
    s.tell(line);  // out of reach; on the z axis (no azimuth)
    EXPECT_EQ(s.ask("ER"), "2\r\n") << line;
    EXPECT_EQ(s.ask("ER"), "2\r\n") << "ER does not clear the register";
    s.tell("RS");
    EXPECT_EQ(s.ask("ER"), "0\r\n");
  }
  EXPECT_EQ(s.arm.move_count(), 0u);
  EXPECT_EQ(s.ask("WH"), home_where);
  EXPECT_EQ(s.emulator->stats().er_answers[2], 4u);
}

TEST(MovemasterEmulatorTest, FormatErrorsAnswerTwoAndDoNothing) {
  Session s;
  const std::vector<std::string> bad = {"XX",
                                        "MV 1,2,3,4,5",
                                        "MP 300,100,200,-90",
                                        "MP 300,100,200,-90,0,0",
                                        "MP 300,a,200,-90,0",
                                        "MP 3e2,100,200,-90,0",
                                        "MP 300,1.0.0,200,-90,0",
                                        "MP 300,,200,-90,0",
                                        "MP 300,100,200,-90,0,",
                                        "MP +-3,1,2,3,4",
                                        "MP .,1,2,3,4",
                                        "PD 0,300,100,200,-90,0",
                                        "PD 630,300,100,200,-90,0",
                                        "PD 5.5,300,100,200,-90,0",
                                        "MS 1,100,O",
                                        "MS 1,2,X",
                                        "MS 1",
                                        "SP 10",
                                        "SP -1",
                                        "SP 4,X",
                                        "SP 4,H,1",
                                        "GP 16,0,0",
                                        "GP 0,0,100",
                                        "GP 1,2",
                                        "TL -1",
                                        "TL 301",
                                        "NT 5",
                                        "GO,",
                                        "ER 1",
                                        "WH 0",
                                        "M P 1,2,3,4,5",
                                        "\x01NT",
                                        std::string(300, 'N')};  // longer than a line may be
  for (const std::string& line : bad) {
    s.tell(line);
    EXPECT_EQ(s.ask("ER"), "2\r\n") << "'" << line << "'";
    s.tell("RS");
  }
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.move_count(), 0u);
  EXPECT_TRUE(s.arm.grips().empty());
  EXPECT_EQ(s.emulator->stats().format_errors, bad.size());
}

TEST(MovemasterEmulatorTest, AcceptsEveryLineEndCaseSpacingAndNumberForm) {
  Session s;
  s.host->send("nt\n");
  s.host->send(" Mp  +300.0 , 0100,200.00,-90, .0 \r");  // CR only
  s.host->send("\r\n  \r\n\n\r");                        // blank lines: skipped
  s.host->send("Er \r\n");
  EXPECT_EQ(s.host->line(), "0\r\n") << "nothing answers before ER";
  s.host->send("er\r");  // the CR LF of this line arrives in two writes: one line end, one answer
  EXPECT_EQ(s.host->line(), "0\r\n");
  s.host->send("\nwh\n");
  expect_near(parse_where(s.host->line().value_or("")), kDown, 0.1, 0.1);
  s.tell("sp 9 , l");
  s.tell("tL 0");
  s.tell("mP 350.,-50,350,-45.0,+30");
  EXPECT_EQ(s.ask("eR"), "0\r\n");
  expect_near(parse_where(s.ask("Wh")), kTilted, 0.1, 0.1);
  EXPECT_EQ(s.emulator->stats().lines, 10u) << "blank lines are not counted";
  EXPECT_EQ(s.emulator->stats().format_errors, 0u);
}

TEST(MovemasterEmulatorTest, AnswersEndWithTheConfiguredLineEnd) {
  MovemasterEmulatorOptions o;
  o.reply_line_end = "\n";
  Session s(o);
  EXPECT_EQ(s.ask("ER"), "0\n");
  MovemasterEmulatorOptions cr_only;
  cr_only.reply_line_end = "\r";
  EXPECT_THROW(MovemasterEmulator(s.arm, cr_only), InputError);
  MovemasterEmulatorOptions too_fast;
  too_fast.speed_level = 10;
  EXPECT_THROW(MovemasterEmulator(s.arm, too_fast), InputError);
}

TEST(MovemasterEmulatorTest, StoredPositionMovesStraightWithTheGripperLetter) {
  Session s;
  s.tell(
      fmt::format("PD 629,{:.1f},{:.1f},{:.1f},{:.1f},{:.1f}", kTilted.x, kTilted.y, kTilted.z, kTilted.p, kTilted.r));
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.move_count(), 0u) << "PD only stores";
  s.tell("MS 629,12,C");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  ASSERT_EQ(s.arm.move_count(), 1u);
  EXPECT_TRUE(s.arm.moves()[0].linear);
  EXPECT_EQ(s.arm.grips(), std::vector<bool>{true});
  expect_near(parse_where(s.ask("WH")), kTilted, 0.1, 0.1);

  s.tell("PD 1,300,100,200,-90,0");
  s.tell("MS 1,0,C");  // closed already: the hand stays
  s.tell("MS 629,5,O");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.grips(), (std::vector<bool>{true, false}));
  EXPECT_FALSE(s.arm.gripper_closed());
  EXPECT_EQ(s.arm.move_count(), 3u);

  s.tell("MS 2,0,O");  // never defined
  EXPECT_EQ(s.ask("ER"), "2\r\n");
  s.tell("RS");
  s.tell("PD 3,900,0,300,0,0");  // stored, but out of reach
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  s.tell("MS 3,0,C");
  EXPECT_EQ(s.ask("ER"), "2\r\n");
  EXPECT_EQ(s.arm.move_count(), 3u);
  EXPECT_EQ(s.arm.grips().size(), 2u) << "an unreachable MS leaves the hand alone";
}

TEST(MovemasterEmulatorTest, GripperCommands) {
  Session s;
  s.tell("GC");
  s.tell("GO");
  s.tell("GP 10,5,30");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.grips(), (std::vector<bool>{true, false}));
}

TEST(MovemasterEmulatorTest, ToolLengthMovesTheToolPointAlongTheApproachAxis) {
  MovemasterEmulatorOptions o;
  o.nominal_tool_length_mm = 90;
  Session s(o);
  s.tell(mp(kTilted));
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  const Pose before = parse_where(s.ask("WH"));
  s.tell("TL 140");
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  const Pose after = parse_where(s.ask("WH"));
  // 50 mm further along a = cos p · u + sin p · z.
  const double theta = std::atan2(before.y, before.x);
  const double reach = 50 * std::cos(before.p * kDeg);
  expect_near(after,
              {before.x + reach * std::cos(theta), before.y + reach * std::sin(theta),
               before.z + 50 * std::sin(before.p * kDeg), before.p, before.r},
              0.2, 0.1);
  EXPECT_EQ(s.arm.move_count(), 1u) << "TL moves nothing";

  // MP now places the tool point: the chain's tcp stands 50 mm back along the approach axis.
  s.tell(mp(kDown));
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  expect_near(parse_where(s.ask("WH")), kDown, 0.1, 0.1);
  EXPECT_LT((tcp(s.arm).translation() - Eigen::Vector3d(0.3, 0.1, 0.25)).norm(), 1e-4);
}

TEST(MovemasterEmulatorTest, SpeedLevelSetsTheMotionSpeed) {
  MovemasterEmulatorOptions o;
  o.speed_level = 4;
  Session s(o);
  const std::vector<double> start = s.arm.joints();
  // The same motion from the same place, after `settings`.
  const auto move_after = [&](std::initializer_list<const char*> settings) {
    s.arm.place(start);
    for (const char* line : settings) s.tell(line);
    s.tell(mp(kDown));
    EXPECT_EQ(s.ask("ER"), "0\r\n");
    return s.arm.moves().back();
  };
  EXPECT_DOUBLE_EQ(move_after({}).speed, 0.5) << "level 4 at power-on";
  const FakeArm::Move slow = move_after({"SP 0"});
  EXPECT_DOUBLE_EQ(slow.speed, 0.1);
  const FakeArm::Move fast = move_after({"SP 9,H"});
  EXPECT_DOUBLE_EQ(fast.speed, 1.0);
  EXPECT_DOUBLE_EQ(move_after({"SP 2,L"}).speed, 0.3);
  EXPECT_EQ(fast.target, slow.target);
  EXPECT_GT(fast.seconds(), 0.0);
  EXPECT_NEAR(slow.seconds() / fast.seconds(), 10.0, 1e-9);
  s.tell("SP 9");
  s.tell("NT");
  ASSERT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_DOUBLE_EQ(s.arm.moves().back().speed, 1.0) << "NT runs at the set level too";
}

TEST(MovemasterEmulatorTest, ErAfterAMotionIsAnsweredAtItsEnd) {
  Session s;
  s.arm.hold_moves(true);
  s.tell(mp(kDown));
  s.tell("ER");
  ASSERT_TRUE(s.arm.wait_until_moving(kDeadline));
  EXPECT_TRUE(s.host->nothing_yet()) << "ER answered during the motion";
  s.arm.release_move();
  EXPECT_EQ(s.host->line(), "0\r\n");
}

TEST(MovemasterEmulatorTest, ArmFailureIsAHardwareErrorThatHaltsUntilReset) {
  Session s;
  s.arm.fail_moves(ArmStatus::failed);
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "1\r\n");
  s.arm.fail_moves();
  s.tell(mp(kDown));  // halted: ignored
  s.tell("GC");
  s.tell("MP 900,0,0,0,0");  // a position error does not hide the hardware error
  EXPECT_EQ(s.ask("ER"), "1\r\n");
  EXPECT_EQ(s.arm.move_count(), 1u);
  EXPECT_TRUE(s.arm.grips().empty());
  parse_where(s.ask("WH"));  // WH still answers
  s.tell("RS");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.move_count(), 2u);
  EXPECT_EQ(s.emulator->stats().er_answers[1], 2u);
}

MovemasterEmulatorOptions misbehaving(const std::string& spec) {
  MovemasterEmulatorOptions o;
  o.misbehaviours = {parse_misbehaviour(spec)};
  return o;
}

TEST(MovemasterEmulatorTest, MisbehaviourErrorAtALine) {
  Session s(misbehaving("er1@2"));
  s.tell("NT");
  s.tell(mp(kDown));  // line 2: not executed, register 1
  EXPECT_EQ(s.ask("ER"), "1\r\n");
  EXPECT_EQ(s.arm.move_count(), 1u);
  s.tell("RS");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.emulator->stats().misbehaviours[static_cast<int>(MisbehaviourKind::error)], 1u);
}

TEST(MovemasterEmulatorTest, MisbehaviourErrorOnAnErLineAnswersIt) {
  Session s(misbehaving("error@1"));
  EXPECT_EQ(s.ask("ER"), "1\r\n");
}

TEST(MovemasterEmulatorTest, MisbehaviourUnreachableAtALine) {
  Session s(misbehaving("unreachable@1"));
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "2\r\n");
  EXPECT_EQ(s.arm.move_count(), 0u);
  s.tell("RS");
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.move_count(), 1u);
}

// An error the manual does not list: the register answers 9 (the driver's `unknown`).
TEST(MovemasterEmulatorTest, MisbehaviourUnknownAnswersACodeTheManualDoesNotList) {
  Session s(misbehaving("unknown@mp#1"));
  s.tell("NT");
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "9\r\n");
  EXPECT_EQ(s.arm.move_count(), 1u);  // the homing only
  s.tell("RS");
  EXPECT_EQ(s.ask("ER"), "0\r\n");
}

TEST(MovemasterEmulatorTest, MisbehaviourGarbageReplacesTheAnswer) {
  Session s(misbehaving("garbage@1"));
  const std::string garbage = std::string(MovemasterEmulator::kGarbage) + "\r\n";
  EXPECT_EQ(s.ask("WH"), garbage);
  parse_where(s.ask("WH"));  // only that line
}

TEST(MovemasterEmulatorTest, MisbehaviourGarbageOnASilentCommandGarblesTheNextAnswer) {
  Session s(misbehaving("garbage@1"));
  const std::string garbage = std::string(MovemasterEmulator::kGarbage) + "\r\n";
  s.tell("NT");  // executed; it has no answer of its own
  EXPECT_EQ(s.ask("ER"), garbage);
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.arm.move_count(), 1u);
}

TEST(MovemasterEmulatorTest, MisbehaviourSilentDropsTheLine) {
  Session s(misbehaving("silent@1"));
  s.tell("WH");  // neither executed nor answered: the first answer is ER's
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_EQ(s.emulator->stats().executed, 1u);
  EXPECT_EQ(s.emulator->stats().lines, 2u);
}

TEST(MovemasterEmulatorTest, MisbehaviourLateDelaysTheAnswer) {
  Session s(misbehaving("late@2:0.3"));
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  EXPECT_GE(std::chrono::steady_clock::now() - start, 300ms);
}

TEST(MovemasterEmulatorTest, MisbehaviourDropHangsUpAndPublishesAFreshTerminal) {
  MovemasterEmulatorOptions o = misbehaving("drop@3");
  o.reconnect_delay = 50ms;
  Session s(o);
  s.tell(mp(kDown));
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  s.tell("ER");  // line 3: the line is hung up
  EXPECT_TRUE(s.host->wait_hang_up());
  ASSERT_TRUE(s.emulator->wait_published(2, kDeadline));
  s.host = std::make_unique<Host>(s.link);
  EXPECT_EQ(s.ask("ER"), "0\r\n");
  expect_near(parse_where(s.ask("WH")), kDown, 0.1, 0.1);  // the arm's state persists
  const MovemasterEmulator::Stats st = s.emulator->stats();
  EXPECT_EQ(st.publications, 2u);
  EXPECT_EQ(st.misbehaviours[static_cast<int>(MisbehaviourKind::drop)], 1u);
}

// The answers to `pairs` of ER, RS lines under random misbehaviour with `seed`.
std::vector<std::string> transcript(std::uint64_t seed, int pairs, MovemasterEmulator::Stats* stats) {
  MovemasterEmulatorOptions o;
  o.seed = seed;
  o.misbehaviours = {parse_misbehaviour("garbage~0.2"), parse_misbehaviour("er2~0.15"),
                     parse_misbehaviour("late~0.1:0.001")};
  Session s(o);
  std::vector<std::string> answers;
  for (int i = 0; i < pairs; ++i) {
    answers.push_back(s.ask("ER"));
    s.tell("RS");
  }
  answers.push_back(s.ask("ER"));  // all lines are served when it answers
  *stats = s.emulator->stats();
  return answers;
}

TEST(MovemasterEmulatorTest, SeededRandomMisbehaviourIsReproducible) {
  MovemasterEmulator::Stats a, b, c;
  const std::vector<std::string> first = transcript(7, 40, &a);
  const std::vector<std::string> again = transcript(7, 40, &b);
  const std::vector<std::string> other = transcript(8, 40, &c);
  EXPECT_EQ(first, again);
  EXPECT_EQ(a.misbehaviours, b.misbehaviours);
  EXPECT_NE(first, other);
  // The counts are the plan's, drawn with the same seed.
  MisbehaviourPlan plan(
      {parse_misbehaviour("garbage~0.2"), parse_misbehaviour("er2~0.15"), parse_misbehaviour("late~0.1:0.001")}, 7);
  std::array<std::uint64_t, 7> expected{};
  for (int i = 0; i < 81; ++i) {
    if (const auto m = plan.next_line()) ++expected[static_cast<std::size_t>(m->kind)];
  }
  EXPECT_EQ(a.misbehaviours, expected);
  EXPECT_GT(expected[static_cast<int>(MisbehaviourKind::garbage)], 0u);
  EXPECT_GT(expected[static_cast<int>(MisbehaviourKind::unreachable)], 0u);
}

TEST(MovemasterEmulatorTest, StopEndsServePromptly) {
  {
    Session idle;  // waiting for a line
    idle.emulator->stop();
    EXPECT_TRUE(idle.served_within(kDeadline));
    EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(idle.link))) << "the path is removed";
  }
  {
    Session moving;  // inside a motion
    moving.arm.hold_moves(true);
    moving.tell(mp(kDown));
    ASSERT_TRUE(moving.arm.wait_until_moving(kDeadline));
    moving.emulator->stop();
    EXPECT_TRUE(moving.served_within(kDeadline));
    EXPECT_TRUE(moving.arm.interrupted());
  }
  {
    // Inside a late answer's wait: the log says the line misbehaves just before it.
    std::promise<void> misbehaving_line;
    std::atomic<bool> seen{false};
    MovemasterEmulatorOptions o = misbehaving("late@1:600");
    o.log = [&](std::string_view text) {
      if (text.find("misbehaving") != std::string_view::npos && !seen.exchange(true)) misbehaving_line.set_value();
    };
    Session late(o);
    late.tell("ER");
    ASSERT_EQ(misbehaving_line.get_future().wait_for(kDeadline), std::future_status::ready);
    late.emulator->stop();
    EXPECT_TRUE(late.served_within(kDeadline));
  }
  {
    FakeArm arm;
    MovemasterEmulator before(arm, {});
    before.stop();
    before.serve(std::filesystem::path(::testing::TempDir()) / "never-published");  // returns at once
    EXPECT_EQ(before.stats().publications, 0u);
  }
}

}  // namespace
}  // namespace cellwright::emulate
