// DriverCore against the contract of robot_driver.hpp, through a fake driver whose controller side the test drives by
// hand: the lifecycle table, ids and the one queue, cancellation behind a failure, retention, reads while moving, the
// clock, the hooks, and the notifier called with no lock held.
#include "cellwright/drivers/driver_core.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "cellwright/common/error.hpp"

namespace cellwright::drivers {
namespace {

using namespace std::chrono_literals;

Capabilities caps_of(bool reads_while_moving = false) {
  Capabilities caps;
  caps.joints = 2;
  caps.joint_control = true;
  caps.gripper = true;
  caps.digital_outputs = 2;
  caps.queue_depth = 4;
  caps.reads_joints = true;
  caps.reads_while_moving = reads_while_moving;
  return caps;
}

const MoveJoints kMove{{0.1, 0.2}, 1.0};

// A driver whose controller is the test: it calls the controller side directly, and sees which hooks ran.
class FakeDriver final : public DriverCore {
 public:
  explicit FakeDriver(Capabilities caps = caps_of(), RunningWhen when = RunningWhen::at_head) : DriverCore(when) {
    set_capabilities(std::move(caps));
  }

  // The controller side, for the test.
  using DriverCore::Controller;
  using DriverCore::RunningWhen;
  Controller session() { return controller(); }
  CommandId head() {
    Controller c = controller();
    return c.head() != nullptr ? c.head()->id : 0;
  }
  bool complete(CommandId id) { return controller().complete(id); }
  bool read(CommandId id, std::vector<double> joints, std::chrono::nanoseconds own) {
    Controller c = controller();
    PositionReading r;
    r.joints = std::move(joints);
    r.stamp = c.stamp(own);
    return c.complete(id, std::move(r));
  }
  bool fail(CommandId id, ErrorCode e, std::string message) { return controller().fail(id, e, std::move(message)); }
  void raise_fault(ErrorCode e, std::string message) { controller().raise_fault(e, std::move(message)); }
  bool start(CommandId id) { return controller().start(id); }
  std::size_t reads() { return controller().reads().size(); }
  // Whether the core's mutex is free, asked from another thread (a thread asking about a mutex it holds is UB).
  bool lock_is_free() const {
    bool free = false;
    std::thread([&] { free = lock(std::try_to_lock).owns_lock(); }).join();
    return free;
  }

  // Hooks.
  std::string connect_problem;
  ErrorCode connect_answer = ErrorCode::none;
  ErrorCode reset_answer = ErrorCode::none;
  std::optional<Refusal> refusal;
  int halts = 0, disconnects = 0;
  std::vector<CommandId> accepted;

 private:
  ErrorCode connect_hook() override {
    if (!connect_problem.empty()) throw InputError({"cell.yaml", 3, 5}, connect_problem);
    return connect_answer;
  }
  void disconnect_hook() override { ++disconnects; }
  Refusal check_hook(const Command&) override { return refusal.value_or(Refusal{}); }
  void accept_hook(Job& job) override { accepted.push_back(job.id); }
  void halt_hook() override { ++halts; }
  ErrorCode reset_hook() override { return reset_answer; }
};

// Brings a fresh driver into `state` through the interface and the controller side.
void bring_to(FakeDriver& d, DriverState state) {
  if (state == DriverState::disconnected) return;
  ASSERT_EQ(d.connect(), ErrorCode::none);
  if (state == DriverState::connected) return;
  if (state == DriverState::fault) {
    d.raise_fault(ErrorCode::hardware, "ER 1");
    return;
  }
  const Submitted h = d.home();
  ASSERT_TRUE(h.accepted());
  ASSERT_TRUE(d.complete(h.id));
  if (state == DriverState::homed) return;
  ASSERT_EQ(d.activate(), ErrorCode::none);
  if (state == DriverState::active) return;
  d.stop();
}

TEST(DriverCoreLifecycle, FollowsTheStateTableOfTheInterface) {
  using S = DriverState;
  struct Call {
    std::string name;
    std::function<ErrorCode(FakeDriver&)> call;
    std::set<S> allowed_in;
  };
  const std::vector<Call> calls = {
      {"connect", [](FakeDriver& d) { return d.connect(); }, {S::disconnected}},
      {"home", [](FakeDriver& d) { return d.home().error; }, {S::connected, S::homed, S::stopped}},
      {"activate", [](FakeDriver& d) { return d.activate(); }, {S::homed, S::stopped}},
      {"submit", [](FakeDriver& d) { return d.submit(kMove).error; }, {S::active}},
      {"request_position",
       [](FakeDriver& d) { return d.request_position().error; },
       {S::connected, S::homed, S::active, S::stopped}},
      {"reset", [](FakeDriver& d) { return d.reset(); }, {S::fault}},
  };
  for (const S state : {S::disconnected, S::connected, S::homed, S::active, S::stopped, S::fault}) {
    for (const Call& call : calls) {
      SCOPED_TRACE(std::string(to_string(state)) + " " + call.name);
      FakeDriver d;
      bring_to(d, state);
      ASSERT_EQ(d.state(), state);
      const ErrorCode e = call.call(d);
      EXPECT_EQ(e != ErrorCode::wrong_state, call.allowed_in.contains(state)) << to_string(e);
      if (e == ErrorCode::wrong_state) {
        EXPECT_EQ(d.state(), state) << "a refused call changed the state";
      }
    }
  }
}

TEST(DriverCoreLifecycle, StopAndDisconnectWorkInEveryStateAndHaltTheRobot) {
  using S = DriverState;
  for (const S state : {S::disconnected, S::connected, S::homed, S::active, S::stopped, S::fault}) {
    SCOPED_TRACE(to_string(state));
    FakeDriver d;
    bring_to(d, state);
    const int halts = d.halts;
    d.stop();
    EXPECT_EQ(d.state(), state == S::active ? S::stopped : state);
    d.disconnect();
    EXPECT_EQ(d.state(), S::disconnected);
    EXPECT_EQ(d.halts, halts + 2);
    EXPECT_EQ(d.disconnects, 1);
  }
}

TEST(DriverCoreLifecycle, ConnectAndResetAskTheDriver) {
  FakeDriver d;
  d.connect_problem = "serial port /dev/ttyS9 does not exist";
  EXPECT_THROW(d.connect(), InputError);
  EXPECT_EQ(d.state(), DriverState::disconnected);
  d.connect_problem.clear();
  d.connect_answer = ErrorCode::connection_lost;  // the controller does not answer
  EXPECT_EQ(d.connect(), ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::disconnected);
  d.connect_answer = ErrorCode::none;
  ASSERT_EQ(d.connect(), ErrorCode::none);
  d.raise_fault(ErrorCode::protocol, "reply 'E?' not understood");
  d.reset_answer = ErrorCode::connection_lost;  // the controller's error could not be cleared
  EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
  EXPECT_EQ(d.state(), DriverState::disconnected);
}

TEST(DriverCoreCommands, IdsAndOneQueueForHomeSubmitAndRequests) {
  FakeDriver d;
  bring_to(d, DriverState::homed);  // home was 1
  const Submitted read = d.request_position();
  ASSERT_EQ(d.activate(), ErrorCode::none);
  const Submitted move = d.submit(kMove);
  const Submitted grip = d.submit(Grip{});
  EXPECT_EQ(read.id, 2u);
  EXPECT_EQ(move.id, 3u);
  EXPECT_EQ(grip.id, 4u);
  EXPECT_EQ(d.accepted, (std::vector<CommandId>{1, 2, 3, 4}));
  EXPECT_EQ(d.poll(read.id).phase, CommandPhase::running);
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::pending);
  EXPECT_FALSE(d.complete(move.id)) << "only the head can complete";
  EXPECT_TRUE(d.read(read.id, {0.5, 0.6}, 7ms));
  EXPECT_EQ(d.last_position()->request, read.id);
  EXPECT_EQ(d.last_position()->stamp, 7ms);
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::running);
  EXPECT_EQ(d.head(), move.id);
  EXPECT_THROW(d.read(move.id, {}, 0ms), InternalError) << "a move completed with a reading is a driver bug";
}

TEST(DriverCoreCommands, RefusalsInTheOrderOfTheContract) {
  FakeDriver d;
  bring_to(d, DriverState::active);
  EXPECT_EQ(d.submit(MovePose{}).error, ErrorCode::unsupported);  // check_command()
  d.refusal = Refusal{ErrorCode::invalid_command, "output 2 is wired to the e-stop"};
  const Submitted s = d.submit(SetOutput{2, true});
  EXPECT_EQ(s.error, ErrorCode::invalid_command);
  EXPECT_EQ(s.message, "output 2 is wired to the e-stop");
  d.refusal.reset();
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(d.submit(kMove).accepted());
  const Submitted busy = d.submit(kMove);
  EXPECT_EQ(busy.error, ErrorCode::busy);
  EXPECT_EQ(busy.message, "4 command(s) already in flight (queue depth 4)");
  EXPECT_EQ(d.accepted.size(), 5u);  // home and the four moves; refusals get no id
}

TEST(DriverCoreCommands, AFailureCancelsEverythingQueuedBehindIt) {
  FakeDriver d;
  bring_to(d, DriverState::active);
  const Submitted a = d.submit(kMove), b = d.submit(Grip{}), c = d.submit(kMove);
  ASSERT_TRUE(d.fail(a.id, ErrorCode::unreachable, "MJ: position error (ER 2)"));
  EXPECT_EQ(d.poll(a.id).error, ErrorCode::unreachable);
  EXPECT_EQ(d.poll(a.id).message, "MJ: position error (ER 2)");
  for (const CommandId id : {b.id, c.id}) {
    EXPECT_EQ(d.poll(id).phase, CommandPhase::failed);
    EXPECT_EQ(d.poll(id).error, ErrorCode::cancelled);
    EXPECT_EQ(d.poll(id).message, "cancelled: command 2 before it failed");
  }
  EXPECT_EQ(d.state(), DriverState::active);
  EXPECT_FALSE(d.complete(b.id)) << "a report about a cancelled job is ignored";
  const Submitted next = d.submit(kMove);
  EXPECT_EQ(d.poll(next.id).phase, CommandPhase::running);
}

TEST(DriverCoreCommands, ControllerErrorsThatAreFaults) {
  {
    FakeDriver d;
    bring_to(d, DriverState::active);
    const Submitted a = d.submit(kMove), b = d.submit(kMove);
    ASSERT_TRUE(d.fail(a.id, ErrorCode::hardware, "ER 1"));
    EXPECT_EQ(d.poll(b.id).error, ErrorCode::cancelled);
    EXPECT_EQ(d.state(), DriverState::fault);
    EXPECT_EQ(d.reset(), ErrorCode::none);
    EXPECT_EQ(d.state(), DriverState::connected);
  }
  {
    FakeDriver d;
    bring_to(d, DriverState::active);
    const Submitted a = d.submit(kMove), b = d.submit(kMove);
    ASSERT_TRUE(d.fail(a.id, ErrorCode::connection_lost, "no reply to ER within 2 s"));
    EXPECT_EQ(d.poll(b.id).error, ErrorCode::connection_lost);
    EXPECT_EQ(d.state(), DriverState::fault);
    EXPECT_EQ(d.reset(), ErrorCode::connection_lost);
    EXPECT_EQ(d.state(), DriverState::disconnected);
  }
  {
    FakeDriver d;
    bring_to(d, DriverState::active);
    const Submitted a = d.submit(kMove);
    d.raise_fault(ErrorCode::protocol, "reply 'Q' not understood");
    EXPECT_EQ(d.poll(a.id).error, ErrorCode::protocol);
    EXPECT_EQ(d.state(), DriverState::fault);
    EXPECT_FALSE(d.complete(a.id));
  }
  FakeDriver d;
  bring_to(d, DriverState::active);
  const Submitted a = d.submit(kMove);
  EXPECT_THROW(d.fail(a.id, ErrorCode::cancelled, ""), InternalError) << "not an error a controller reports";
}

TEST(DriverCoreCommands, StopCancelsAndAStaleReportIsIgnored) {
  FakeDriver d;
  bring_to(d, DriverState::active);
  const Submitted a = d.submit(kMove);
  const CommandId taken = d.head();  // a communication thread took it, then stop() came
  d.stop();
  EXPECT_EQ(d.poll(a.id).message, "cancelled by stop()");
  EXPECT_FALSE(d.complete(taken));
  EXPECT_EQ(d.poll(a.id).error, ErrorCode::cancelled);
}

TEST(DriverCoreCommands, StatusesOfTheMostRecentCommandsAreRetained) {
  FakeDriver d;
  bring_to(d, DriverState::active);
  CommandId first = 0, last = 0;
  for (std::size_t i = 0; i < kStatusRetention + 10; ++i) {
    const Submitted s = d.submit(kMove);
    ASSERT_TRUE(s.accepted());
    ASSERT_TRUE(d.complete(s.id));
    if (first == 0) first = s.id;
    last = s.id;
  }
  EXPECT_EQ(d.poll(first).error, ErrorCode::unknown_command);
  EXPECT_EQ(d.poll(first).message, fmt::format("command {} was never issued or is no longer retained", first));
  EXPECT_EQ(d.poll(last).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(last - kStatusRetention + 1).phase, CommandPhase::done);
  EXPECT_EQ(d.poll(last - kStatusRetention).error, ErrorCode::unknown_command);
}

TEST(DriverCoreCommands, ARunningJobIsMarkedByTheControllerWhenItSaysSo) {
  FakeDriver d(caps_of(), FakeDriver::RunningWhen::started);
  bring_to(d, DriverState::active);
  const Submitted a = d.submit(kMove), b = d.submit(kMove);
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::pending);
  EXPECT_FALSE(d.start(b.id));
  EXPECT_TRUE(d.start(a.id));
  EXPECT_EQ(d.poll(a.id).phase, CommandPhase::running);
  ASSERT_TRUE(d.complete(a.id));
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::pending);
}

TEST(DriverCoreReads, WhileMovingARequestIsAnsweredOutOfTheQueue) {
  FakeDriver d(caps_of(true));
  bring_to(d, DriverState::active);
  const Submitted move = d.submit(kMove);
  const Submitted read = d.request_position();
  const Submitted grip = d.submit(Grip{});
  EXPECT_EQ(read.id, move.id + 1);  // ids keep their order ...
  EXPECT_EQ(d.poll(read.id).phase, CommandPhase::running);
  EXPECT_EQ(d.reads(), 1u);
  EXPECT_EQ(d.submit(kMove).error, ErrorCode::none);
  EXPECT_EQ(d.submit(kMove).error, ErrorCode::busy) << "reads count towards the queue depth";
  ASSERT_TRUE(d.read(read.id, {0.05, 0.1}, 3ms));  // ... but the read completes before the move
  EXPECT_EQ(d.poll(move.id).phase, CommandPhase::running);
  EXPECT_EQ(d.last_position()->joints, (std::vector<double>{0.05, 0.1}));
  // A failure of a command does not cancel a read: it was behind nothing.
  const Submitted read2 = d.request_position();
  ASSERT_TRUE(d.fail(move.id, ErrorCode::unreachable, "ER 2"));
  EXPECT_EQ(d.poll(grip.id).error, ErrorCode::cancelled);
  EXPECT_EQ(d.poll(read2.id).phase, CommandPhase::running);
  // A fault does.
  d.raise_fault(ErrorCode::hardware, "ER 1");
  EXPECT_EQ(d.poll(read2.id).error, ErrorCode::hardware);
  EXPECT_EQ(d.reads(), 0u);
}

TEST(DriverCoreReads, StopCancelsReadsToo) {
  FakeDriver d(caps_of(true));
  bring_to(d, DriverState::active);
  const Submitted read = d.request_position();
  d.stop();
  EXPECT_EQ(d.poll(read.id).message, "cancelled by stop()");
}

TEST(DriverCoreReads, StampsAreOnTheClockGivenToTheDriver) {
  FakeDriver d;
  bring_to(d, DriverState::homed);
  const Submitted own = d.request_position();
  ASSERT_TRUE(d.read(own.id, {0, 0}, 5ms));
  EXPECT_EQ(d.last_position()->stamp, 5ms);
  std::chrono::nanoseconds runtime_now = 1234ms;
  d.set_clock([&] { return runtime_now; });
  const Submitted clocked = d.request_position();
  ASSERT_TRUE(d.read(clocked.id, {0, 0}, 6ms));
  EXPECT_EQ(d.last_position()->stamp, 1234ms);
  d.set_clock({});
  const Submitted back = d.request_position();
  ASSERT_TRUE(d.read(back.id, {0, 0}, 7ms));
  EXPECT_EQ(d.last_position()->stamp, 7ms);
  EXPECT_EQ(d.calls().set_clock, 2);
}

TEST(DriverCoreNotifier, IsCalledWithNoLockHeldOncePerSessionThatFinishedSomething) {
  FakeDriver d;
  int calls = 0;
  bool always_free = true;
  d.set_notifier([&] {
    ++calls;
    always_free = always_free && d.lock_is_free();
  });
  bring_to(d, DriverState::active);  // the homing finished
  EXPECT_EQ(calls, 1);
  const Submitted a = d.submit(kMove), b = d.submit(kMove);
  EXPECT_EQ(d.poll(b.id).phase, CommandPhase::pending);
  EXPECT_EQ(calls, 1);  // accepting finishes nothing
  {
    FakeDriver::Controller c = d.session();  // one session, two completions: one call
    ASSERT_TRUE(c.complete(a.id));
    ASSERT_TRUE(c.complete(b.id));
    EXPECT_EQ(calls, 1) << "not while the session holds the lock";
  }
  EXPECT_EQ(calls, 2);
  d.stop();  // nothing to cancel: nothing to tell
  EXPECT_EQ(calls, 2);
  ASSERT_EQ(d.activate(), ErrorCode::none);
  d.submit(kMove);
  d.disconnect();
  EXPECT_EQ(calls, 3);
  ASSERT_EQ(d.connect(), ErrorCode::none);
  d.raise_fault(ErrorCode::hardware, "ER 1");  // a fault always tells
  EXPECT_EQ(calls, 4);
  EXPECT_TRUE(always_free);
}

// The pattern of a serial driver: a communication thread takes the head job in one session, executes it without the
// lock (here: at once), and reports it by id in another, while the owner submits and sleeps on the notifier.
TEST(DriverCoreThreads, ACommunicationThreadExecutesWhileTheOwnerWaits) {
  FakeDriver d;
  bring_to(d, DriverState::active);
  std::mutex m;
  std::condition_variable cv;
  std::uint64_t wakeups = 0;
  d.set_notifier([&] {
    {
      std::lock_guard lock(m);
      ++wakeups;
    }
    cv.notify_all();
  });
  std::atomic<bool> over{false};
  std::vector<CommandId> executed;  // the communication thread's own
  std::thread comm([&] {
    while (!over) {
      const CommandId id = d.head();
      if (id == 0) {
        std::this_thread::yield();
        continue;
      }
      executed.push_back(id);  // "sent to the controller", no lock held
      if (id % 7 == 0) {
        d.fail(id, ErrorCode::unreachable, "ER 2");
      } else {
        d.complete(id);
      }
    }
  });
  std::vector<CommandPhase> phases;
  for (int i = 0; i < 40; ++i) {
    const Submitted s = d.submit(kMove);
    ASSERT_TRUE(s.accepted());
    std::unique_lock lock(m);
    std::uint64_t seen = wakeups;
    for (;;) {
      lock.unlock();
      const CommandStatus st = d.poll(s.id);
      lock.lock();
      if (st.phase == CommandPhase::done || st.phase == CommandPhase::failed) {
        phases.push_back(st.phase);
        break;
      }
      cv.wait(lock, [&] { return wakeups != seen; });
      seen = wakeups;
    }
  }
  over = true;
  comm.join();
  ASSERT_EQ(phases.size(), 40u);
  ASSERT_EQ(executed.size(), 40u);
  for (std::size_t i = 0; i < executed.size(); ++i) {
    EXPECT_EQ(executed[i], i + 2);  // in order, each once (home was 1)
    EXPECT_EQ(phases[i], executed[i] % 7 == 0 ? CommandPhase::failed : CommandPhase::done);
  }
}

}  // namespace
}  // namespace cellwright::drivers
